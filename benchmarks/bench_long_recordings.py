"""Linear time on long recordings: the offline float chain at 64K, 256K, 1M and 4M samples.

The chain (:class:`gaitlog.host.gait.pipeline.StepPipeline`: gaps, tilt correction, events, M1-M5) on a
synthetic walk at 50 Hz: a sum of sines at step frequency (1.8 steps/s) and its harmonic, gravity on z with a
tilt, noise, and a few short and long gaps. For each length: the best time of a few runs per sample, and the
peak memory traced by ``tracemalloc`` (numpy's allocations) in a separate run, per sample. The baseline is the
64K run of the same process: each row gives its per-sample time as a ratio to it. The load average is printed
(the machine is shared; a ratio is comparable across loads, an absolute time is not).

Exit status 1 when the 4M per-sample time exceeds ``LIMIT`` (1.3) times the 64K one.

Run: ``python benchmarks/bench_long_recordings.py [--quick]`` (``--quick``: up to 1M samples, no verdict).
"""

from __future__ import annotations

import os
import sys
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
from _timing import best_of

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.host.gait.pipeline import StepPipeline  # noqa: E402

RATE_HZ = 50.0
SIZES = (65_536, 262_144, 1_048_576, 4_194_304)
#: Largest allowed ratio of the 4M run's per-sample time to the 64K run's.
LIMIT = 1.3


def synthetic_walk(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 3)`` acceleration in g and its validity mask: sines at step frequency, gravity on z, gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    f = 1.8
    acc = np.empty((n, 3))
    acc[:, 0] = 0.1 + 0.15 * np.sin(2 * np.pi * f * t + 0.3)
    acc[:, 1] = -0.2 + 0.1 * np.sin(np.pi * f * t)
    acc[:, 2] = 0.97 + 0.25 * np.cos(2 * np.pi * f * t) + 0.08 * np.cos(4 * np.pi * f * t + 0.5)
    acc += 0.02 * rng.standard_normal((n, 3))
    valid = np.ones(n, bool)
    for s in rng.integers(0, n - 100, size=n // 5_000):
        valid[s:s + rng.integers(1, 40)] = False
    acc[~valid] = np.nan
    return acc, valid


def measure(n: int) -> tuple[float, int, int]:
    """Best seconds of the chain on ``n`` samples, its traced peak bytes, and the number of steps."""
    acc, valid = synthetic_walk(n)
    pipe = StepPipeline(leg_length_m=0.9, foot_length_m=0.26)

    def run() -> None:
        pipe.run(acc, sampling_rate_hz=RATE_HZ, valid=valid)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seconds = best_of(run, repeat=5 if n <= 262_144 else 3, warmup=n <= 262_144)
        tracemalloc.start()
        run()
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return seconds, peak, pipe.steps_.n_steps


def main(argv: list[str]) -> int:
    sizes = SIZES[:3] if "--quick" in argv else SIZES
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"offline float chain (StepPipeline) on a synthetic walk at {RATE_HZ:g} Hz; "
          f"load average {load:.1f} on {os.cpu_count()} CPUs; baseline: the 64K run")
    print(f"{'samples':>9} {'steps':>7} {'time s':>8} {'us/sample':>10} {'ratio':>6} {'peak MB':>8} {'B/sample':>9}")
    base = None
    per_sample = {}
    for n in sizes:
        seconds, peak, steps = measure(n)
        per_sample[n] = us = seconds / n * 1e6
        base = us if base is None else base
        print(f"{n:>9} {steps:>7} {seconds:>8.3f} {us:>10.3f} {us / base:>6.2f} {peak / 2 ** 20:>8.0f} "
              f"{peak / n:>9.0f}", flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average at the end {load:.1f}")
    if SIZES[-1] not in per_sample:
        return 0
    ratio = per_sample[SIZES[-1]] / per_sample[SIZES[0]]
    ok = ratio <= LIMIT
    print(f"4M per-sample time {ratio:.2f}x the 64K one (limit {LIMIT}x): {'ok' if ok else 'MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
