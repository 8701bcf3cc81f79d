"""Speed of the protocol decoders, each against a baseline measured in the same run.

Run: ``python benchmarks/bench_protocol.py``. Prints, per measurement, the best-of-N time, its target, the
baseline time and the speed-up; exits 1 if a target is missed.

- unpack 65,536 P32 words: ``gaitlog.protocol.packing.unpack_words`` (numpy) vs construct ``Array(Int32ul)`` plus
  per-record bit masks in Python (the construct-per-record approach the notes measured).
- parse a DUMP stream of 128 DATA frames of 2048 data bytes: ``gaitlog.protocol.frames.parse_stream`` +
  ``parse_payload`` vs ``FRAME_STRUCT.parse`` (construct with ``Checksum``) frame by frame.
- decode a full memory image (65,536 samples): ``parse_image`` of the version-3 file (framed blocks, what a
  host writes) + ring order + ``unpack_words`` vs a construct struct of the same memory's version-1 file (the
  unframed layout, the one a fixed struct can declare) with ``Array(Int32ul)`` memory and per-record masks.
- pack and unpack a full step store (3,276 per-step records with their CRC-16):
  ``gaitlog.protocol.steps.pack_step_records`` / ``unpack_step_records`` (numpy, row-wise CRC) vs
  ``STEP_RECORD_STRUCT`` (construct with ``Checksum``) record by record.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import construct as cs  # noqa: E402
import numpy as np  # noqa: E402
from _timing import best_of  # noqa: E402

from gaitlog.protocol.crc import crc32  # noqa: E402
from gaitlog.protocol.frames import (  # noqa: E402
    FRAME_STRUCT,
    FrameType,
    build_payload,
    encode_frame,
    parse_payload,
    parse_stream,
)
from gaitlog.protocol.header import CAPACITY_SAMPLES, DeviceHeader, HeaderFlag  # noqa: E402
from gaitlog.protocol.image import build_image, image_version_for, parse_image  # noqa: E402
from gaitlog.protocol.packing import pack_words, unpack_words, words_to_bytes  # noqa: E402
from gaitlog.protocol.steps import (  # noqa: E402
    STEP_CAPACITY_RECORDS,
    STEP_RECORD_STRUCT,
    empty_step_records,
    pack_step_records,
    unpack_step_records,
)


def main() -> int:
    rng = np.random.default_rng(0)
    n = CAPACITY_SAMPLES
    codes = rng.integers(0, 1024, (n, 3))
    flags = rng.integers(0, 4, n)
    memory = words_to_bytes(pack_words(codes, flags))

    # -- 1. unpack 65,536 words
    words_array = cs.Array(n, cs.Int32ul)

    def baseline_unpack() -> list:
        return [(w & 1023, (w >> 10) & 1023, (w >> 20) & 1023, w >> 30) for w in words_array.parse(memory)]

    def ours_unpack() -> tuple:
        return unpack_words(memory)

    c, f = ours_unpack()
    assert np.array_equal(c, codes) and np.array_equal(f, flags)
    assert baseline_unpack()[5] == (*codes[5].tolist(), int(flags[5]))

    # -- 2. DUMP stream: 128 DATA frames of 2048 bytes
    chunk = 2048
    stream = b"".join(
        encode_frame(FrameType.DATA, i % 256, build_payload(FrameType.DATA, address=i * chunk,
                                                            data=memory[i * chunk : (i + 1) * chunk]))
        for i in range(len(memory) // chunk)
    )
    frame_len = chunk + 4 + 8

    def baseline_frames() -> bytes:
        out = bytearray(len(memory))
        for k in range(0, len(stream), frame_len):
            fr = FRAME_STRUCT.parse(stream[k : k + frame_len])
            payload = fr.body.value.payload
            addr = int.from_bytes(payload[:4], "little")
            out[addr : addr + len(payload) - 4] = payload[4:]
        return bytes(out)

    def ours_frames() -> bytes:
        frames, errors = parse_stream(stream)
        out = bytearray(len(memory))
        for fr in frames:
            p = parse_payload(fr)
            out[p["address"] : p["address"] + len(p["data"])] = p["data"]
        return bytes(out)

    assert ours_frames() == memory == baseline_frames()

    # -- 3. full memory image, wrapped ring buffer
    sw = 3 * n + 12345
    header = DeviceHeader(capacity_samples=n, samples_written=sw, write_index=sw % n,
                          flags=int(HeaderFlag.WRAPPED | HeaderFlag.OVERWRITE))
    image = build_image(header, memory)                       # version 3: framed blocks (what a host writes)
    # the baseline declares the unframed version-1 layout in construct (a framed file has no fixed struct)
    image_v1 = build_image(header, memory, image_version=image_version_for(header))
    nb = n * 4 // 1024
    image_struct = cs.Struct(
        "magic" / cs.Const(b"GLIM"), "image_version" / cs.Int8ul, cs.Padding(1), "block_size" / cs.Int16ul,
        "memory_bytes" / cs.Int32ul, "n_blocks" / cs.Int32ul,
        "block_crc32" / cs.Array(cs.this.n_blocks, cs.Int32ul), "block_state" / cs.Array(cs.this.n_blocks, cs.Int8ul),
        "table_crc32" / cs.Int32ul, "header" / cs.Bytes(256), "memory" / cs.RawCopy(cs.Array(n, cs.Int32ul)),
    )

    def baseline_image() -> list:
        img = image_struct.parse(image_v1)
        raw = img.memory.data
        ok = [crc32(raw[i * 1024 : (i + 1) * 1024]) == img.block_crc32[i] for i in range(nb)]
        h = DeviceHeader.from_bytes(img.header)
        words = img.memory.value
        first = h.first_slot
        ordered = [words[(first + i) % n] for i in range(h.n_stored)]
        return [((w & 1023, (w >> 10) & 1023, (w >> 20) & 1023), w >> 30, ok[((first + i) % n) // 256])
                for i, w in enumerate(ordered)]

    def ours_image() -> tuple:
        contents = parse_image(image)
        h = contents.header
        slots = h.stored_slots()
        words = contents.memory.view("<u4")
        c, f = unpack_words(words[slots])
        valid = contents.block_ok[slots // (contents.block_size // 4)]
        return c, f, valid

    c, f, valid = ours_image()
    first = sw % n
    assert np.array_equal(c[0], codes[first]) and valid.all()
    assert baseline_image()[0][0] == tuple(codes[first].tolist())

    # -- 4. a full step store: 3,276 records
    rec = empty_step_records(STEP_CAPACITY_RECORDS)
    rec["end_sample"] = np.cumsum(rng.integers(20, 40, STEP_CAPACITY_RECORDS))
    rec["length_m1_q14"] = rng.integers(0, 20000, STEP_CAPACITY_RECORDS)
    names = [n for n in rec.dtype.names if n != "record_crc"]
    store = pack_step_records(rec)

    def baseline_steps() -> list:
        raw = b"".join(STEP_RECORD_STRUCT.build(dict(body=dict(value={n: int(r[n]) for n in names}))) for r in rec)
        return [STEP_RECORD_STRUCT.parse(raw[20 * i : 20 * i + 20]).body.value for i in range(len(rec))]

    def ours_steps() -> tuple:
        return unpack_step_records(pack_step_records(rec))

    back, crc_ok = ours_steps()
    assert crc_ok.all() and np.array_equal(back["end_sample"], rec["end_sample"])
    assert baseline_steps()[7].end_sample == int(rec["end_sample"][7]) and len(store) == 65520

    rows = [
        ("unpack 65,536 P32 words", best_of(ours_unpack, 50, warmup=True), 2e-3,
         best_of(baseline_unpack, 3, warmup=True), "construct Array(Int32ul) + per-record masks"),
        ("parse 128 DATA frames of 2048 B", best_of(ours_frames, 20, warmup=True), 5e-3,
         best_of(baseline_frames, 5, warmup=True), "construct FRAME_STRUCT (Checksum) per frame"),
        ("decode full .glimg (65,536 samples, wrapped)", best_of(ours_image, 20, warmup=True), 10e-3,
         best_of(baseline_image, 3, warmup=True), "construct struct of the v1 file + per-record masks"),
        ("pack + unpack 3,276 step records", best_of(ours_steps, 20, warmup=True), 10e-3,
         best_of(baseline_steps, 3, warmup=True), "construct STEP_RECORD_STRUCT (Checksum) per record"),
    ]
    failed = False
    print(f"{'measurement':46s} {'ours':>10s} {'target':>10s} {'baseline':>11s} {'speed-up':>9s}  baseline")
    for name, ours, target, base, what in rows:
        ok = ours <= target
        failed |= not ok
        print(f"{name:46s} {ours * 1e3:8.3f}ms {target * 1e3:8.1f}ms {base * 1e3:9.2f}ms {base / ours:8.0f}x  {what}"
              + ("" if ok else "  TARGET MISSED"))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
