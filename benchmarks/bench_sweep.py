"""Benchmark: the 9-configuration ADC x rate sweep (``gaitlog sweep``'s default grid), and the peak memory and
time of ``gaitlog demo``.

Targets: the sweep of 9 configurations (ADC 8/10/12 bits x 25/50/100 Hz) over a 4-subject simulated
protocol in <= 60 s (issue 5); peak memory of ``gaitlog demo`` <= 400 MB and its time <= 60 s. (The memory
target was 250 MB before the device ran its on-line step algorithm: numba, LLVM and the two compiled
kernels now take ~125 MB of the floor, and the demo records its walk twice, once with K on the device.)

Baselines measured in the same run:

* sweep: the naive way, one full emulated-logger pass per subject and configuration (render the walk,
  ``Logger.record``, the offline chain twice and the on-line algorithm in both arithmetics, its compiled
  kernels loaded before the clock starts) -- one such pass is timed and multiplied by the 36 passes the
  sweep would need (the sweep itself renders each subject once and re-samples the analog output);
* demo memory: a Python process that only imports what the demo imports (numpy, scipy, matplotlib and
  the package) and loads the compiled kernels of both arithmetics, i.e. the floor the demo's data add to.

Run: ``python benchmarks/bench_sweep.py`` (exit status 1 when a target is missed).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SWEEP_TARGET_S = 60.0
DEMO_MEMORY_TARGET_MB = 400.0
DEMO_TIME_TARGET_S = 60.0


def child_peak_mb(code: str) -> tuple[float, float]:
    """Peak RSS (MB) and wall time of ``code`` run in a fresh interpreter (measured by a wrapper process)."""
    wrapper = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
               f"r = subprocess.run([sys.executable, '-c', {code!r}], stdout=subprocess.DEVNULL); "
               "dt = time.perf_counter() - t; "
               "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0, dt, r.returncode)")
    out = subprocess.run([sys.executable, "-c", wrapper], capture_output=True, text=True, cwd=ROOT, check=True)
    peak, dt, rc = out.stdout.split()
    if int(rc) != 0:
        raise SystemExit(f"child failed ({rc}): {code}")
    return float(peak), float(dt)


def naive_pass_s() -> float:
    """One subject, one configuration, the naive way (render + emulated logger + every chain)."""
    import numpy as np

    from gaitlog.firmware_sim.adc import Adc
    from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walking import Walking
    from gaitlog.host.files.replay import online_step_table
    from gaitlog.host.studies.compare import offline_step_table
    from gaitlog.protocol.header import CalibrationSlot
    from gaitlog.protocol.steps import StepConfig

    s = random_subjects(1, seed=0)[0]
    cfg = StepConfig(step_format=1, leg_length_m=s.leg_length_m, foot_length_m=s.foot_length_m)
    for arithmetic in ("float", "fixed"):                                   # compiled kernels loaded, untimed
        OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg, arithmetic=arithmetic).run(
            np.full((1000, 3), 512, np.int64))
    t = time.perf_counter()
    res = Logger(adc=Adc(adc_bits=10, sampling_rate_hz=50.0)).record(Walking(subject=s, seed=0))
    codes = np.asarray(res.codes, np.int64)
    kw = dict(sampling_rate_hz=50.0, leg_length_m=s.leg_length_m, foot_length_m=s.foot_length_m)
    offline_step_table(CalibrationSlot.nominal(10).apply(codes), **kw)
    offline_step_table(CalibrationSlot.nominal(10).apply(codes + 0.5), **kw)     # the "ideal" pass
    for arithmetic in ("float", "fixed"):
        online_step_table(codes, arithmetic=arithmetic, **kw)
    return time.perf_counter() - t


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from gaitlog.host.cli import main as gaitlog
    from gaitlog.host.studies.sweep_grid import SweepGrid, m5_rate_answer
    from gaitlog.host.studies.task_store import TaskStore

    ok = True
    workers = min(2, os.cpu_count() or 1)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sweep"
        t = time.perf_counter()         # `gaitlog sweep`'s default grid, on a local Dask cluster (its start included)
        if gaitlog(["sweep", "--out", str(out), "-q", "--subjects", "4", "--seeds", "0", "--workers", str(workers)]):
            raise SystemExit("gaitlog sweep failed")
        sweep_s = time.perf_counter() - t
        results = TaskStore(out).collect(SweepGrid(subjects=4, seeds=(0,)).tasks())
    naive = naive_pass_s()
    naive_total = naive * 4 * 9
    print(f"gaitlog sweep, 9 configurations x 4 subjects ({workers} workers): {sweep_s:.1f} s  "
          f"(target <= {SWEEP_TARGET_S:.0f} s)"
          f"  baseline naive {naive:.1f} s per pass x 36 = {naive_total:.0f} s  ratio {naive_total / sweep_s:.1f}x")
    ok &= sweep_s <= SWEEP_TARGET_S
    print("M5 and the rate: " + m5_rate_answer([r for res in results for r in res["sections"]])["verdict"])

    with tempfile.TemporaryDirectory() as tmp:
        demo_code = ("import sys; sys.argv = ['gaitlog', 'demo', '--quiet', '--out', " + repr(tmp) + "]; "
                     "from gaitlog.host.cli import main; raise SystemExit(main(sys.argv[1:]))")
        base_code = ("import numpy, scipy.signal, scipy.interpolate, matplotlib.pyplot, gaitlog.host.cli, gaitlog.host.studies.compare; "
                     "from gaitlog.firmware_sim.algorithms.online import load_kernels; load_kernels(('fixed', 'float'))")
        base_mb, _ = child_peak_mb(base_code)
        demo_mb, demo_s = child_peak_mb(demo_code)
    print(f"gaitlog demo peak memory: {demo_mb:.0f} MB  (target <= {DEMO_MEMORY_TARGET_MB:.0f} MB)  "
          f"baseline imports + compiled kernels {base_mb:.0f} MB  (the demo's own data {demo_mb - base_mb:.0f} MB)")
    print(f"gaitlog demo wall time: {demo_s:.1f} s  (target <= {DEMO_TIME_TARGET_S:.0f} s)")
    ok &= demo_mb <= DEMO_MEMORY_TARGET_MB and demo_s <= DEMO_TIME_TARGET_S
    print("PASS" if ok else "FAIL: a target was missed")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
