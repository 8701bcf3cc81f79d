"""Memory and time of ``gaitlog compare``'s offline chain: streamed a block at a time against the whole array.

``compare`` turns a recording's codes into g and runs the offline chain on them. It used to hold the ``(n, 3)``
float array and run the whole-array chain (:func:`gaitlog.host.studies.compare.offline_step_table`); it now feeds
:func:`gaitlog.host.studies.compare.streamed_offline_table` a block of 65,536 samples at a time. Both are run here
on the same 10-bit codes of a synthetic walk at 50 Hz (changing cadence, standing still, short gaps and a gap
longer than a block), at 64K and 1M samples: the CPU time per sample and the peak memory traced by
``tracemalloc`` (numpy's allocations) of each, the whole-array run being the baseline of the same run; the two
tables must be equal, column by column.

Run: ``python benchmarks/bench_compare_streamed.py [--quick]`` (``--quick``: 64K only).
"""

from __future__ import annotations

import os
import sys
import time
import tracemalloc
import warnings
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")    # as the gaitlog command runs it
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from gaitlog.host.studies.compare import offline_step_table, streamed_offline_table  # noqa: E402
from gaitlog.protocol.header import CalibrationSlot  # noqa: E402

RATE_HZ = 50.0
CAL = CalibrationSlot(np.array([511.3, 514.8, 509.1]),
                      np.array([[0.00392, 0.00004, -0.00002], [-0.00003, 0.00389, 0.00005],
                                [0.00001, 0.00002, 0.00395]]), valid=True)
KW = dict(sampling_rate_hz=RATE_HZ, leg_length_m=0.9, foot_length_m=0.26)


def walk_codes(n: int, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    phase = 2 * np.pi * np.cumsum(1.8 + 0.3 * np.sin(2 * np.pi * t / 97.0)) / RATE_HZ
    amp = 0.25 * (1.0 + 0.6 * np.sin(2 * np.pi * t / 41.0))
    g = np.stack([0.1 + 0.15 * np.sin(phase + 0.3), -0.2 + 0.1 * np.sin(phase / 2),
                  0.97 + amp * np.cos(phase) + 0.08 * np.cos(2 * phase + 0.5)], axis=1)
    g[n // 5:n // 5 + 3_000] = [0.1, -0.2, 0.97]
    codes = np.clip(np.round(512 + 256 * g + rng.normal(0, 0.7, g.shape)), 0, 1023).astype(np.uint16)
    valid = np.ones(n, bool)
    for s in rng.integers(50, n - 100, size=n // 2_000):
        valid[s:s + rng.integers(1, 12)] = False
    valid[n // 2:n // 2 + 2_345] = False
    return codes, valid


def whole(codes: np.ndarray, valid: np.ndarray):
    acc = np.asarray(CAL.apply(codes.astype(np.float64)), np.float64)
    acc[~valid] = np.nan
    return offline_step_table(acc, valid=valid, **KW)


def measure(f) -> tuple[object, float, int]:
    tracemalloc.start()
    t = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = f()
    cpu = time.process_time() - t
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return table, cpu, peak


def main() -> int:
    sizes = (1 << 16,) if "--quick" in sys.argv else (1 << 16, 1 << 20)
    print(f"compare's offline chain on codes (10-bit, 50 Hz walk with gaps); load average {os.getloadavg()[0]:.1f}")
    ok = True
    for n in sizes:
        codes, valid = walk_codes(n)
        ref, cpu_w, peak_w = measure(lambda: whole(codes, valid))
        got, cpu_s, peak_s = measure(lambda: streamed_offline_table(codes, valid, CAL, **KW))
        ca, cb = ref.columns(), got.columns()
        same = list(ca) == list(cb) and all(
            np.array_equal(np.asarray(ca[c]), np.asarray(cb[c]), equal_nan=np.asarray(ca[c]).dtype.kind == "f")
            for c in ca)
        ok &= same
        print(f"  {n:>9} samples, {got.n_steps} steps: streamed {cpu_s / n * 1e6:.2f} us/sample CPU, peak "
              f"{peak_s / 2**20:.0f} MB ({peak_s / n:.0f} B/sample); baseline whole array {cpu_w / n * 1e6:.2f} "
              f"us/sample, {peak_w / 2**20:.0f} MB ({peak_w / n:.0f} B/sample); tables equal: {same}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
