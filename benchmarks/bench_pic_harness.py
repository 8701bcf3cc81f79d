"""Speed of the PIC firmware harness (``gaitlog pic verify`` and the records-only check): a 25 s walk at 50 Hz, as a
multiple of real time.

Run: ``python benchmarks/bench_pic_harness.py`` (needs gputils and gpsim). A simulated subject's walk (1,250
samples, 25 s at 50 Hz: its first 20 m) goes through:

* :func:`gaitlog.firmware_sim.pic.gpsim_logger.verify` -- assemble the test build, run gpsim with the codes as
  analog stimuli on the ADC inputs through every cycle of every sample period with its full write log, parse the
  log, run the model, compare every stage -- timed end to end;
* :func:`gaitlog.firmware_sim.pic.gpsim_logger.verify_records` -- the same test build and stimuli with the lean
  records-only log, the model's records from the kernel fed the run whole (what the CI check of every IPOL trial
  runs).

Baselines in the same run: gpsim alone on the production build for the same 1,250 periods with no input and nothing
logged (its raw speed on idle inputs: no step is ever found), and gpsim alone on the test build with the walk's
stimuli and nothing logged (the same work as the harness's runs, the floor for any harness). Each line gives wall seconds, the multiple of real time, and the CPU seconds of the child processes
(gpasm, gpsim), which a loaded machine changes less than the wall time. Target: the full verification at least 5x
real time. Exits 1 if a sample differs or the target is missed.
"""

from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q  # noqa: E402
from gaitlog.firmware_sim.pic.gpsim_logger import PicLogger, missing_tools, verify, verify_records  # noqa: E402
from gaitlog.protocol.packing import FLAG_SESSION_START  # noqa: E402

N_SAMPLES = 1250
RATE_HZ = 50.0
TARGET_REALTIME = 5.0


def _walk_codes() -> np.ndarray:
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walking import Walking

    subject = random_subjects(1, seed=3)[0]
    codes = Logger(device_id=4).record(Walking(subject=subject, seed=3)).codes.astype(np.int64)
    return codes[:N_SAMPLES]


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed(fn):
    cpu, t0 = _children_cpu_s(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0, _children_cpu_s() - cpu


def main() -> int:
    reason = missing_tools()
    if reason:
        print(f"bench_pic_harness: {reason}", file=sys.stderr)
        return 1
    codes = _walk_codes()
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    cal = nominal_calibration_q()
    verify(codes[:64], flags[:64], cal)                  # warm-up: the model's probes and kernel compile
    verify_records(codes[:64], flags[:64], cal)
    harness = PicLogger(sampling_rate_hz=RATE_HZ)
    seconds = N_SAMPLES / RATE_HZ
    (cycles, raw_s), _, raw_cpu = _timed(lambda: harness.raw_speed(N_SAMPLES))
    (_, floor_s), _, floor_cpu = _timed(lambda: harness.raw_speed(N_SAMPLES, codes=codes, calibration=cal))
    full, full_s, full_cpu = _timed(lambda: verify(codes, flags, cal, harness=harness))
    lean, lean_s, lean_cpu = _timed(lambda: verify_records(codes, flags, cal, harness=harness))
    print(f"PIC harness: {N_SAMPLES:,} samples ({seconds:g} s at {RATE_HZ:g} Hz, a simulated walk)")
    print(f"  baseline, gpsim alone (production build, nothing logged): {raw_s:.2f} s = {seconds / raw_s:.1f}x real "
          f"time, {cycles / raw_s / 1e6:.0f} M cycles/s; CPU {raw_cpu:.2f} s")
    print(f"  baseline, gpsim alone on the walk (test build, stimuli, nothing logged): {floor_s:.2f} s = "
          f"{seconds / floor_s:.1f}x real time; CPU {floor_cpu:.2f} s")
    print(f"  pic verify (every stage; gpsim with its full log {full.gpsim_s:.2f} s): {full_s:.2f} s = "
          f"{seconds / full_s:.1f}x real time (target >= {TARGET_REALTIME:g}x), {floor_s / full_s:.0%} of gpsim's "
          f"speed on the walk; CPU of gpasm and gpsim {full_cpu:.2f} s")
    print(f"  records only (lean log; gpsim {lean.gpsim_s:.2f} s): {lean_s:.2f} s = {seconds / lean_s:.1f}x real "
          f"time, {floor_s / lean_s:.0%} of gpsim's speed on the walk; CPU {lean_cpu:.2f} s")
    for s in full.stages:
        print(f"  {s.name}: {s.n_identical:,} of {s.n_compared:,} identical")
    print(f"  records only: {lean.records.n_identical:,} of {lean.records.n_compared:,} records identical")
    realtime = seconds / full_s
    failed = not (full.identical and lean.identical) or realtime < TARGET_REALTIME
    if failed:
        why = "a sample differs" if not (full.identical and lean.identical) else \
            f"{realtime:.1f}x < {TARGET_REALTIME:g}x"
        print(f"FAILED: {why}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
