"""Soak test of the dump over a damaged line: many consecutive full-memory dumps, 0 wrong samples allowed.

Each dump runs `gaitlog.host.link.memory_dump.dump_memory` through the in-process emulated line (``emu://``) with
byte faults in **both** directions: every byte is corrupted, dropped, or preceded by an inserted random byte
with probability ``--error-rate / 3`` each (so ``--error-rate`` is the total byte error rate of a direction),
a fresh fault seed per dump. The device holds a full, wrapped memory (65,536 samples of random codes). A dump
counts as good when it completes and its image decodes to exactly the device's samples; any sample that
decodes as valid but differs is a *wrong sample* (the target is 0), a missing one an *incomplete* dump.

Run ``python benchmarks/soak_link_dump.py`` (100 dumps at 1e-3, about 6 minutes on one CPU) or e.g.
``--dumps 10 --error-rate 1e-2``. Prints one line per dump and a summary (dumps, wrong samples, incomplete
dumps, time per dump against a clean dump measured in the same run); exits 1 on a wrong sample or an
incomplete dump. Not run by CI (too long); ``tests/host/link/test_link_noisy.py`` runs a small memory at 1e-2.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.files.decode import decode_file  # noqa: E402
from gaitlog.host.link.logger_link import LoggerLink  # noqa: E402
from gaitlog.host.link.memory_dump import dump_memory  # noqa: E402
from gaitlog.protocol.header import DeviceHeader  # noqa: E402
from gaitlog.protocol.image import build_image  # noqa: E402

CAP = 65536


def full_image(seed: int) -> tuple[bytes, np.ndarray]:
    """A full, wrapped memory of random samples, and the codes in ring order (oldest first)."""
    rng = np.random.default_rng(seed)
    n_written = CAP + 777
    codes = rng.integers(0, 1024, size=(CAP, 3)).astype(np.uint32)
    words = codes[:, 0] | codes[:, 1] << 10 | codes[:, 2] << 20
    write_index = n_written % CAP
    memory = np.empty(CAP, "<u4")
    memory[(write_index + np.arange(CAP)) % CAP] = words
    header = DeviceHeader(samples_written=n_written, write_index=write_index, flags=0x03, start_time_s=1_700_000_000)
    return build_image(header.to_bytes(), memory.tobytes()), codes


def fault_query(error_rate: float, seed: int) -> str:
    """``emu://`` options: the total byte error rate split evenly over corrupt, drop and insert, both ways."""
    p = error_rate / 3
    kinds = ("corrupt", "drop", "insert")
    return "&".join([f"{k}={p:g}" for k in kinds] + [f"h2d_{k}={p:g}" for k in kinds] + [f"seed={seed}"])


def one_dump(image: Path, out: Path, codes: np.ndarray, query: str) -> tuple[float, bool, int, int, dict]:
    """(seconds, complete, wrong samples, missing samples, metadata) of one dump."""
    t0 = time.perf_counter()
    with LoggerLink(f"emu://{image}?{query}", timeout_s=0.5) as link:
        dump = dump_memory(link, out, progress=False)
    seconds = time.perf_counter() - t0
    rec = decode_file(out)
    valid = np.asarray(rec.valid)
    wrong = int(np.count_nonzero(valid & np.any(np.asarray(rec.codes) != codes, axis=1)))
    return seconds, dump.complete_, wrong, int(np.count_nonzero(~valid)), dump.metadata_


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dumps", type=int, default=100, help="consecutive dumps (default 100)")
    parser.add_argument("--error-rate", type=float, default=1e-3,
                        help="total byte error rate of each direction (default 1e-3)")
    parser.add_argument("--seed", type=int, default=0, help="first fault seed (default 0)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        data, codes = full_image(args.seed)
        image = tmp / "device.glimg"
        image.write_bytes(data)
        clean_s, clean_ok, *_ = one_dump(image, tmp / "clean.glimg", codes, "")
        assert clean_ok, "the clean dump is incomplete"
        print(f"clean dump of a full memory (262,144 B): {clean_s:.2f} s")
        times, wrong_total, incomplete, mismatches = [], 0, 0, 0
        for k in range(args.dumps):
            seconds, complete, wrong, missing, meta = one_dump(image, tmp / "d.glimg", codes,
                                                               fault_query(args.error_rate, args.seed + 1 + k))
            times.append(seconds)
            wrong_total += wrong
            incomplete += not complete
            mismatches += meta["crc32_mismatches"]
            print(f"dump {k + 1:3d}: {seconds:6.2f} s  complete={complete}  wrong={wrong}  missing={missing}  "
                  f"received {meta['bytes_received']} B, {meta['frames_damaged']} damaged frames, "
                  f"{meta['passes']} passes, last chunk {meta['last_chunk_bytes']} B, "
                  f"{meta['crc32_mismatches']} CRC-32 rejections", flush=True)
    t = np.array(times)
    ok = wrong_total == 0 and incomplete == 0
    print(f"{args.dumps} full dumps at byte error rate {args.error_rate:g} both ways (corrupt/drop/insert): "
          f"{wrong_total} wrong samples, {incomplete} incomplete; time per dump median {np.median(t):.2f} s, "
          f"max {t.max():.2f} s ({np.median(t) / clean_s:.1f}x the clean dump); {mismatches} DATA frames with "
          f"a good CRC-16 rejected by the CRC-32  [{'ok' if ok else 'FAILED'}]")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
