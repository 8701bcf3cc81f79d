"""gaitlog.host.files.decode: images, raw dumps and wire captures -> exact samples, every gap reported, bad input refused.

Truth is built here by hand (P32 words packed with plain integer arithmetic, ring slots computed from the
spec's rule), never from the decoder's own output.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.host.files.decode import decode_bytes, decode_file
from gaitlog.host.link.transports.protocol_emu import LineFaults
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import encode_frame
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.header import DeviceHeader as _Header
from gaitlog.protocol.image import build_image as _build_current_image
from gaitlog.protocol.image import image_version_for


def build_image(header, memory, missing_blocks=(), block_size=1024, **kw) -> bytes:
    """The image of version 1 or 2 (the layout these tests damage at known offsets; version 3 is damaged by
    ``tests/protocol/test_corruption_campaign.py``)."""
    h = header if isinstance(header, _Header) else _Header.from_bytes(bytes(header))
    return _build_current_image(header, memory, missing_blocks, block_size, image_version=image_version_for(h), **kw)

CAP = 65536
T_HEADER, T_DATA, T_DUMP_END = 0x86, 0x87, 0x88


def make_memory(n_written: int, *, seed: int = 0, capacity: int = CAP, overwrite: bool | None = None):
    """Sample memory and header for ``n_written`` samples; returns (header, memory bytes, truth codes,
    truth flags, truth sample numbers) with the truth in ring order (oldest first)."""
    rng = np.random.default_rng(seed)
    codes_all = rng.integers(0, 1024, size=(n_written, 3)).astype(np.int64)
    flags_all = rng.integers(0, 4, size=n_written).astype(np.int64)
    words_all = codes_all[:, 0] | (codes_all[:, 1] << 10) | (codes_all[:, 2] << 20) | (flags_all << 30)
    wrapped = n_written > capacity
    if overwrite is None:
        overwrite = wrapped
    memory = np.full(capacity, 0xFFFFFFFF, dtype="<u4")
    slots = np.arange(n_written) % capacity  # sample k goes to slot k mod capacity
    memory[slots] = words_all  # later samples overwrite older ones, as in the ring
    n = min(n_written, capacity)
    flags = (0x01 if overwrite else 0) | (0x02 if wrapped else 0)
    header = DeviceHeader(device_id=42, samples_written=n_written, write_index=n_written % capacity,
                          capacity_samples=capacity, flags=flags, start_time_s=1_700_000_000)
    keep = slice(n_written - n, n_written)
    return (header, memory.tobytes(), codes_all[keep], flags_all[keep],
            np.arange(n_written - n, n_written, dtype=np.int64))


def assert_exact_or_missing(rec, codes, flags, sample_numbers):
    """Every valid row equals the truth; every invalid row is inside exactly one reported gap."""
    np.testing.assert_array_equal(rec.sample_numbers, sample_numbers)
    v = rec.valid
    np.testing.assert_array_equal(rec.codes[v], codes[v])
    np.testing.assert_array_equal(rec.flags[v], flags[v])
    covered = np.zeros(len(v), dtype=np.int64)
    for g in rec.gaps:
        assert g.first_sample_number <= g.last_sample_number
        covered[g.first_sample_number - sample_numbers[0]: g.last_sample_number - sample_numbers[0] + 1] += 1
    np.testing.assert_array_equal(covered, (~v).astype(np.int64))


# ------------------------------------------------------------------------------------------------ images
@pytest.mark.parametrize("n_written", [0, 1, 1000, CAP, CAP + 12345, 3 * CAP + 7])
def test_image_round_trip_plain_and_wrapped(n_written):
    header, memory, codes, flags, sn = make_memory(n_written, seed=n_written)
    rec = decode_bytes(build_image(header.to_bytes(), memory), source="mem.glimg")
    assert rec.valid.all() and rec.gaps == []
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)
    np.testing.assert_array_equal(rec.sample_numbers, sn)
    assert rec.sampling_rate_hz == 50.0


@settings(max_examples=30, deadline=None)
@given(n_written=st.integers(0, 3 * CAP), seed=st.integers(0, 2**31), missing=st.sets(st.integers(0, 255),
                                                                                         max_size=8))
def test_image_decode_property(n_written, seed, missing):
    header, memory, codes, flags, sn = make_memory(n_written, seed=seed)
    data = build_image(header.to_bytes(), memory, missing_blocks=sorted(missing))
    rec = decode_bytes(data)
    assert_exact_or_missing(rec, codes, flags, sn)
    # exactly the samples in missing blocks are invalid
    slots = sn % CAP
    np.testing.assert_array_equal(~rec.valid, np.isin(slots // 256, sorted(missing)))


def _image_offsets(data: bytes) -> int:
    """Offset of the sample memory in an image (PROTOCOL.md section 6)."""
    n_blocks = int.from_bytes(data[12:16], "little")
    return 16 + 5 * n_blocks + 4 + 256


@pytest.mark.parametrize("kind", ["flip", "drop", "insert", "truncate", "mixed"])
def test_damaged_image_gives_only_exact_samples(kind):
    rng = np.random.default_rng(7)
    header, memory, codes, flags, sn = make_memory(CAP + 5000, seed=3)
    data = bytearray(build_image(header.to_bytes(), memory))
    base = _image_offsets(bytes(data))
    touched_slots: set[int] = set()
    if kind in ("flip", "mixed"):
        for pos in rng.integers(base, len(data), 20):
            data[pos] ^= 1 << int(rng.integers(0, 8))
            touched_slots.add((int(pos) - base) // 4)
    if kind in ("drop", "mixed"):
        for pos in sorted(rng.integers(base, len(data) - 100, 3), reverse=True):
            del data[pos]
    if kind in ("insert", "mixed"):
        for pos in sorted(rng.integers(base, len(data) - 100, 3), reverse=True):
            data[pos:pos] = bytes([int(rng.integers(0, 256))])
    if kind == "truncate":
        del data[base + 100_000:]
    rec = decode_bytes(bytes(data), source="damaged.glimg")
    assert_exact_or_missing(rec, codes, flags, sn)
    assert rec.n_missing > 0
    if kind == "flip":
        slot_of_row = sn % CAP
        assert not rec.valid[np.isin(slot_of_row, sorted(touched_slots))].any()
    if kind == "truncate":
        slot_of_row = sn % CAP
        assert not rec.valid[slot_of_row >= 25_000].any()
        assert rec.valid[slot_of_row < 24_000].all()


# ------------------------------------------------------------------------------------------------ raw dumps
def test_raw_dump_and_truncated_raw_dump():
    header, memory, codes, flags, sn = make_memory(5000, seed=5)
    used = memory[: 4 * 5000]
    raw = header.to_bytes() + used
    raw += b"\x1a" * (-len(raw) % 1024)  # no check trailer (older firmware): nothing verifies these bytes
    with pytest.warns(UserWarning, match="5000 samples present cannot be verified and are reported missing"):
        refused = decode_bytes(raw, source="rx.bin")
    assert not refused.valid.any() and "without its check trailer" in refused.gaps[0].reason
    with pytest.warns(UserWarning, match="5000 samples and 0 step records UNVERIFIED"):
        rec = decode_bytes(raw, source="rx.bin", accept_unverified=True)
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    with pytest.warns(UserWarning, match="UNVERIFIED"):
        cut = decode_bytes(raw[: 256 + 4 * 3000 + 2], source="rx.bin", accept_unverified=True)
    assert_exact_or_missing(cut, codes, flags, sn)
    assert cut.n_valid == 3000
    assert cut.gaps[0].first_sample_number == 3000 and cut.gaps[0].last_sample_number == 4999
    assert "truncated" in cut.gaps[0].reason


# ------------------------------------------------------------------------------------------------ captures
def capture_bytes(header, memory: bytes, chunk: int = 2048, stored_end: int | None = None) -> bytes:
    """Device->host bytes of READ_HEADER + DUMP, built from the spec's frame layout."""
    end = len(memory) if stored_end is None else stored_end
    out = [encode_frame(T_HEADER, 1, header.to_bytes())]
    k = 0
    for a in range(0, end, chunk):
        piece = memory[a: min(a + chunk, end)]
        out.append(encode_frame(T_DATA, k & 0xFF, a.to_bytes(4, "little") + piece))
        k += 1
    out.append(encode_frame(T_DUMP_END, 2, (0).to_bytes(4, "little") + end.to_bytes(4, "little")
                            + (k & 0xFFFF).to_bytes(2, "little")))
    return b"".join(out)


@pytest.mark.parametrize("n_written", [1234, CAP + 999])
def test_clean_capture_round_trip(n_written):
    header, memory, codes, flags, sn = make_memory(n_written, seed=11)
    end = CAP * 4 if n_written > CAP else 4 * n_written
    rec = decode_bytes(capture_bytes(header, memory, stored_end=end), source="cap.bin")
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)


@pytest.mark.parametrize("faults", [dict(corrupt=1e-4), dict(drop=5e-5), dict(insert=5e-5),
                                    dict(corrupt=1e-4, drop=2e-5, insert=2e-5), dict(cut_after=150_000)])
def test_damaged_capture_gives_only_exact_samples(faults):
    header, memory, codes, flags, sn = make_memory(CAP + 100, seed=13)
    wire = capture_bytes(header, memory, chunk=512)
    # keep the HEADER frame intact: damage starts after it
    damaged = wire[:264] + LineFaults(seed=5, **faults).apply(wire[264:])
    rec = decode_bytes(damaged, source="cap.bin")
    assert_exact_or_missing(rec, codes, flags, sn)
    assert 0 < rec.n_missing < rec.n_samples
    assert all("not received" in g.reason for g in rec.gaps)


def test_capture_without_header_is_refused():
    header, memory, *_ = make_memory(100)
    wire = capture_bytes(header, memory, stored_end=400)[264:]
    with pytest.raises(ProtocolError, match="no intact HEADER frame"):
        decode_bytes(wire, source="cap.bin")


# ------------------------------------------------------------------------------------------------ bad input
def _image(n=100) -> bytes:
    header, memory, *_ = make_memory(n)
    return build_image(header.to_bytes(), memory)


def test_bad_inputs_name_file_and_offset(tmp_path):
    good = _image()
    hdr_at = 16 + 5 * 256 + 4
    cases = {
        "magic.glimg": b"XXXX" + good[4:],
        "empty.glimg": b"",
        "short.glimg": good[:10],
    }
    # wrong magic of the device header inside a raw dump
    header, memory, *_ = make_memory(100)
    raw_bad = bytearray(header.to_bytes() + memory[:400])
    raw_bad[0:4] = b"GLOX"
    cases["rawmagic.bin"] = bytes(raw_bad)
    for name, data in cases.items():
        p = tmp_path / name
        p.write_bytes(data)
        with pytest.raises(ProtocolError) as info:
            decode_file(p)
        assert name in str(info.value)
        assert info.value.offset is not None, name
    assert hdr_at > 0


def test_unknown_version_names_both_versions(tmp_path):
    header, memory, *_ = make_memory(100)
    hb = bytearray(header.to_bytes())
    hb[5] = 7  # protocol_version
    from gaitlog.protocol.crc import crc16_xmodem

    from gaitlog.protocol.header import crc_span

    hb[254:256] = crc16_xmodem(crc_span(bytes(hb[:254]))).to_bytes(2, "big")
    p = tmp_path / "v7.bin"
    p.write_bytes(bytes(hb) + memory[:400])
    with pytest.raises(ProtocolError, match="version 7") as info:
        decode_file(p)
    assert info.value.offset == 5 and "v7.bin" in str(info.value)


def test_absurd_length_fields_do_not_allocate(tmp_path):
    good = bytearray(_image())
    good[8:12] = (0xFFFFFFFF).to_bytes(4, "little")  # memory_bytes
    good[12:16] = (0x7FFFFFFF).to_bytes(4, "little")  # n_blocks
    p = tmp_path / "huge.glimg"
    p.write_bytes(bytes(good))
    with pytest.raises(ProtocolError) as info:
        decode_file(p)
    assert "huge.glimg" in str(info.value) and info.value.offset is not None
    # a capture whose frames claim 65535-byte payloads: framing errors, no allocation, no samples
    wire = b"".join(b"\xa5\x5a\x87\x00\xff\xff" + bytes(10) for _ in range(100))
    with pytest.raises(ProtocolError, match="junk.cap"):
        decode_bytes(wire, source="junk.cap")


@settings(max_examples=25, deadline=None)
@given(n_written=st.integers(1, 2 * CAP), seed=st.integers(0, 2**31), chunk=st.integers(4, 4096),
       drop_frames=st.sets(st.integers(0, 400), max_size=5))
def test_capture_decode_property(n_written, seed, chunk, drop_frames):
    header, memory, codes, flags, sn = make_memory(n_written, seed=seed)
    end = 4 * CAP if n_written > CAP else 4 * n_written
    frames = [encode_frame(T_HEADER, 1, header.to_bytes())]
    lost = np.zeros(CAP, bool)
    for k, a in enumerate(range(0, end, chunk)):
        stop = min(a + chunk, end)
        if k in drop_frames:
            lost[a // 4: -(-stop // 4)] = True
            continue
        frames.append(encode_frame(T_DATA, k & 0xFF, a.to_bytes(4, "little") + memory[a:stop]))
    rec = decode_bytes(b"".join(frames))
    assert_exact_or_missing(rec, codes, flags, sn)
    np.testing.assert_array_equal(~rec.valid, lost[sn % CAP])
