"""Fuzz the loaders of every file and wire format: mutated frames, device headers, memory images, raw dumps,
wire captures, recording NPZs and calibration / K JSON files. A loader may only refuse an input with the
project's documented errors (:class:`gaitlog.protocol.errors.ProtocolError`, :class:`gaitlog.host.errors.HostError`); anything else
escaping is a crash, counted and shown (target, exception, the input's first bytes).

    PYTHONPATH=. python benchmarks/fuzz_loaders.py --inputs 1000000 --seconds 1800   # the long job
    PYTHONPATH=. python benchmarks/fuzz_loaders.py --inputs 20000                   # a quick look

The inputs are valid seeds of each format put through 1-3 random mutations (bit flips, random or boundary
bytes, inserted / dropped / duplicated spans, truncation, splices of two seeds) and, for the NPZ and JSON
loaders, structure-aware ones (an array replaced by one of another dtype or shape; a JSON value replaced by a
nested, ragged, huge, NaN or wrongly typed one). ``tests/host/files/test_fuzz_loaders.py`` runs the same targets
under hypothesis with a few thousand examples.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import random
import sys
import tempfile
import time
import warnings
import zipfile
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_bytes
from gaitlog.host.files.recording import Recording
from gaitlog.host.gait.k_calibration import KFit
from gaitlog.protocol.crc import crc32
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import FrameType, encode_frame, parse_payload, parse_stream
from gaitlog.protocol.header import DeviceHeader, HeaderFlag
from gaitlog.protocol.image import build_image, image_memory_bytes
from gaitlog.protocol.raw_dump import raw_dump_bytes

#: The only exceptions a loader may raise on bad bytes.
DOCUMENTED_ERRORS = (ProtocolError, HostError)


# ------------------------------------------------------------------------------------------------------ seeds
def _headers() -> list[DeviceHeader]:
    wrapped = int(HeaderFlag.WRAPPED | HeaderFlag.OVERWRITE)
    return [DeviceHeader(capacity_samples=256, samples_written=200, write_index=200),
            DeviceHeader(capacity_samples=256, samples_written=300, write_index=300 % 256, flags=wrapped),
            DeviceHeader(capacity_samples=64, samples_written=0, write_index=0)]


def _recording_npz(header: DeviceHeader, memory: bytes) -> bytes:
    rec = decode_bytes(build_image(header.to_bytes(), memory, block_size=64))
    with tempfile.TemporaryDirectory() as d:
        rec.save_npz(Path(d) / "r.npz")
        return (Path(d) / "r.npz").read_bytes()


def _capture(header: DeviceHeader, memory: bytes, checked: bool) -> bytes:
    """A wire capture: HEADER, then DATA frames of 256 bytes (each followed by its DATA_CRC when ``checked``)."""
    out = [encode_frame(FrameType.HEADER, 1, header.to_bytes())]
    for k, a in enumerate(range(0, header.used_bytes, 256)):
        piece = memory[a: min(a + 256, header.used_bytes)]
        out.append(encode_frame(FrameType.DATA, k % 256, a.to_bytes(4, "little") + piece))
        if checked:
            out.append(encode_frame(FrameType.DATA_CRC, k % 256, a.to_bytes(4, "little")
                                    + crc32(piece).to_bytes(4, "little")))
    return b"".join(out)


def seeds() -> dict[str, list[bytes]]:
    """Valid inputs of each format (small, so that a million mutations take minutes)."""
    rng = np.random.default_rng(13)
    out: dict[str, list[bytes]] = {"frames": [], "header": [], "image": [], "raw": [], "capture": [], "npz": [],
                                   "json": []}
    for h in _headers():
        memory = rng.integers(0, 256, image_memory_bytes(h), dtype=np.uint8).tobytes()
        out["header"].append(h.to_bytes())
        out["image"] += [build_image(h.to_bytes(), memory, block_size=bs) for bs in (64, 256)]
        out["raw"].append(raw_dump_bytes(h.to_bytes(), memory[:h.n_stored * h.memory_bytes // h.capacity_samples]))
        out["npz"].append(_recording_npz(h, memory))
        out["capture"].append(_capture(h, memory, checked=h.samples_written % 2 == 0))
    for seq, t in enumerate(FrameType):
        payload = rng.integers(0, 256, int(rng.integers(0, 40)), dtype=np.uint8).tobytes()
        out["frames"].append(encode_frame(int(t), seq % 256, payload))
    out["frames"].append(b"".join(out["frames"]))
    out["frames"].append(encode_frame(int(FrameType.HEADER), 3, out["header"][0]))
    cal = AccCalibration(model="9-param", input_unit="counts", offset=np.array([512.0, 511.0, 513.0]),
                         matrix=np.eye(3) / 256.0, scale_per_g=np.full(3, 256.0), angles_deg=np.zeros(3),
                         residual_rms_g=0.001, residual_max_g=0.002, n_poses=24, pose_residuals_g=np.zeros(24),
                         chi2_per_dof=1.0, min_direction_sv=0.5)
    k = KFit(k_m1=1.1, k_m2=1.4, k_m4=0.5, k1_m5_m_s=0.37, k2_m5_m=0.0, mode="single-speed", m5_fallback=True,
             leg_length_m=0.9, foot_length_m=0.19, n_sections=1, n_steps=60, distance_m=40.0, subject="s",
             notes=["n"])
    out["json"] += [cal.to_json().encode(), k.to_json().encode()]
    return out


# --------------------------------------------------------------------------------------------------- mutations
_BOUNDARY = (b"\x00", b"\xff", b"\x7f", b"\x80", b"\x00\x00", b"\xff\xff", b"\xff\xff\xff\xff", b"\x00\x00\x00\x80",
             b"\xff\xff\xff\x7f")


def mutate(data: bytes, rnd: random.Random, corpus: list[bytes]) -> bytes:
    """``data`` through 1-3 random byte-level mutations."""
    b = bytearray(data)
    for _ in range(rnd.randint(1, 3)):
        op = rnd.randrange(9)
        n = len(b)
        pos = rnd.randrange(n + 1)
        if op == 0 and n:                                 # flip bits
            for _ in range(rnd.randint(1, 8)):
                i = rnd.randrange(n)
                b[i] ^= 1 << rnd.randrange(8)
        elif op == 1 and n:                               # random bytes
            for _ in range(rnd.randint(1, 8)):
                b[rnd.randrange(n)] = rnd.randrange(256)
        elif op == 2:                                     # insert
            b[pos:pos] = rnd.randbytes(rnd.choice((1, 2, 4, rnd.randint(1, 300))))
        elif op == 3 and n:                               # drop a span
            del b[pos:pos + rnd.choice((1, 2, 4, rnd.randint(1, 300)))]
        elif op == 4:                                     # truncate
            del b[pos:]
        elif op == 5 and n:                               # duplicate a span
            span = b[pos:pos + rnd.randint(1, 300)]
            b[pos:pos] = span
        elif op == 6:                                     # boundary values
            v = rnd.choice(_BOUNDARY)
            b[pos:pos + len(v)] = v
        elif op == 7:                                     # splice with another seed
            other = rnd.choice(corpus)
            cut = rnd.randrange(len(other) + 1)
            b = b[:pos] + bytearray(other[cut:])
        else:                                             # rarely: random bytes
            if rnd.random() < 0.1:
                b = bytearray(rnd.randbytes(rnd.randint(0, 2000)))
    return bytes(b)


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=False)
    return buf.getvalue()


def mutate_npz(data: bytes, rnd: random.Random) -> bytes:
    """A member of the NPZ replaced by an array of another dtype, shape or content."""
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    name = rnd.choice(sorted(members))
    shape = rnd.choice(((), (0,), (1,), (7,), (3, 3), (256, 3), (256, 2), (2, 256), (300,), (256,)))
    dtype = rnd.choice(("u1", "u2", "<i8", "<f8", "?", "<U5", "<i2", ">u2", "<c16"))
    if rnd.random() < 0.5 and name == "metadata_json.npy":
        meta = json.loads(str(np.load(io.BytesIO(members[name]))))
        key = rnd.choice(sorted(meta))
        meta[key] = _json_value(rnd)
        members[name] = _npy(np.array(json.dumps(meta)))
    else:
        size = int(np.prod(shape))
        if np.dtype(dtype).kind == "U":
            arr = np.array([rnd.choice(["", "x", "{}", "[]"]) for _ in range(size)], dtype=dtype).reshape(shape)
        else:
            arr = np.frombuffer(rnd.randbytes(size * np.dtype(dtype).itemsize), dtype=dtype).reshape(shape)
        members[name] = _npy(arr)
    if rnd.random() < 0.2:
        members.pop(rnd.choice(sorted(members)))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for n, v in members.items():
            zf.writestr(n, v)
    return buf.getvalue()


def _json_value(rnd: random.Random, depth: int = 0) -> object:
    r = rnd.randrange(12)
    if r == 0 and depth < 4:
        return [_json_value(rnd, depth + 1) for _ in range(rnd.randint(0, 4))]
    if r == 1 and depth < 4:
        return {rnd.choice(["a", "offset", "matrix", "k_m1"]): _json_value(rnd, depth + 1)}
    return rnd.choice([None, True, False, 0, -1, 1e308, -1e308, math.nan, math.inf, "", "x", 2**70, 1.5, [[1], [2, 3]],
                       [1, 2, 3], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[[[1]]]], "9-param", "counts", "g"])


def mutate_json(data: bytes, rnd: random.Random) -> bytes:
    """One key of a calibration / K file given another value (or removed, or a key added)."""
    doc = json.loads(data)
    key = rnd.choice(sorted(doc))
    r = rnd.random()
    if r < 0.1:
        doc.pop(key)
    elif r < 0.15:
        doc[rnd.choice(["extra", "k_m9", "x"])] = _json_value(rnd)
    else:
        doc[key] = _json_value(rnd)
    return json.dumps(doc).encode()


# ------------------------------------------------------------------------------------------------------ targets
def _frames(data: bytes) -> None:
    frames, _errors = parse_stream(data)
    for frame in frames:
        try:
            parse_payload(frame)
        except ProtocolError:
            pass


def _json(data: bytes) -> None:
    text = data.decode("utf-8", errors="replace")
    for cls in (AccCalibration, KFit):
        try:
            cls.from_json(text, source="fuzz.json")
        except HostError:
            pass


class _NpzTarget:
    """Recording.load on a file in a temporary folder (the loader takes a path)."""

    def __init__(self) -> None:
        self._dir = tempfile.TemporaryDirectory(prefix="gaitlog-fuzz-")
        self.path = Path(self._dir.name) / "fuzz.npz"

    def __call__(self, data: bytes) -> None:
        self.path.write_bytes(data)
        Recording.load(self.path)


def targets() -> dict[str, Callable[[bytes], object]]:
    """Name -> loader of one input."""
    return {"frames": _frames, "header": lambda d: DeviceHeader.from_bytes(d, source="fuzz"),
            "image": lambda d: decode_bytes(d, source="fuzz.glimg"), "raw": lambda d: decode_bytes(d, source="fuzz.raw"),
            "capture": lambda d: decode_bytes(d, source="fuzz.cap"),
            "npz": _NpzTarget(), "json": _json}


def fuzz_input(name: str, corpus: list[bytes], rnd: random.Random) -> bytes:
    """One fuzzed input for ``name``."""
    seed = rnd.choice(corpus)
    if name == "npz" and rnd.random() < 0.5:
        return mutate_npz(seed, rnd)
    if name == "json" and rnd.random() < 0.5:
        return mutate_json(seed, rnd)
    return mutate(seed, rnd, corpus)


def run_one(target: Callable[[bytes], object], data: bytes) -> BaseException | None:
    """Run ``target`` on ``data``; the exception when it is not a documented one, else None."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            target(data)
    except DOCUMENTED_ERRORS:
        return None
    except Exception as exc:  # noqa: BLE001 - what is counted
        return exc
    return None


#: Share of the inputs per target (the slow ones get fewer: a header parse takes ~0.6 ms, a frame ~20 us).
WEIGHTS = {"frames": 0.3, "json": 0.18, "header": 0.1, "image": 0.11, "raw": 0.11, "capture": 0.1, "npz": 0.1}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=1_000_000, help="inputs in all (default 10^6)")
    parser.add_argument("--seconds", type=float, default=3600.0, help="stop after this long (default 3600)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--targets", default=",".join(WEIGHTS), help=f"comma-separated subset of {','.join(WEIGHTS)}")
    args = parser.parse_args(argv)
    rnd = random.Random(args.seed)
    corpus, loaders = seeds(), targets()
    counts: Counter[str] = Counter()
    crashes: Counter[tuple[str, str]] = Counter()
    examples: dict[tuple[str, str], bytes] = {}
    names = [n for n in WEIGHTS if n in args.targets.split(",")]
    weights = [WEIGHTS[n] for n in names]
    t0 = time.perf_counter()
    done = 0
    while done < args.inputs and time.perf_counter() - t0 < args.seconds:
        name = rnd.choices(names, weights)[0]
        data = fuzz_input(name, corpus[name], rnd)
        exc = run_one(loaders[name], data)
        counts[name] += 1
        done += 1
        if exc is not None:
            key = (name, f"{type(exc).__name__}: {str(exc)[:120]}")
            crashes[key] += 1
            examples.setdefault(key, data)
        if done % 100_000 == 0:
            print(f"{done} inputs, {time.perf_counter() - t0:.0f} s, {sum(crashes.values())} crashes", flush=True)
    elapsed = time.perf_counter() - t0
    print(f"{done} inputs in {elapsed:.0f} s ({done / elapsed:.0f}/s): "
          + ", ".join(f"{n} {counts[n]}" for n in names))
    print(f"crashes outside the documented errors: {sum(crashes.values())} ({len(crashes)} kinds)")
    for (name, what), n in crashes.most_common():
        print(f"  {name}: {n} x {what}; input starts {examples[(name, what)][:48].hex()}")
    return 1 if crashes else 0


if __name__ == "__main__":
    sys.exit(main())
