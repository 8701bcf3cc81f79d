"""Speed of the PIC firmware harness (``gaitlog pic verify``): a 25 s walk at 50 Hz, as a multiple of real time.

Run: ``python benchmarks/bench_pic_harness.py`` (needs gputils and gpsim). A simulated subject's walk (the
first 1,250 samples, 25 s at 50 Hz: a 20 m trial) goes through
:func:`gaitlog.firmware_sim.pic.gpsim_logger.verify` -- assemble the test build, run gpsim with the codes as
analog stimuli on the ADC inputs through every cycle of every sample period with its write log on, parse the
log, run the model, compare -- timed end to end. Baseline in the same run: gpsim alone on the production build for the
same 1,250 periods, nothing logged (its raw speed, cycles per second). Target: the whole verification at
least 5x real time (25 s of recording in at most 5 s). Exits 1 if a sample differs or the target is missed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q  # noqa: E402
from gaitlog.firmware_sim.pic.gpsim_logger import PicLogger, missing_tools, verify  # noqa: E402
from gaitlog.protocol.packing import FLAG_SESSION_START  # noqa: E402

N_SAMPLES = 1250
RATE_HZ = 50.0
TARGET_REALTIME = 5.0


def _walk_codes() -> np.ndarray:
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walking import Walking

    subject = random_subjects(1, seed=3)[0]
    return Logger(device_id=4).record(Walking(subject=subject, seed=3)).codes.astype(np.int64)[:N_SAMPLES]


def main() -> int:
    reason = missing_tools()
    if reason:
        print(f"bench_pic_harness: {reason}", file=sys.stderr)
        return 1
    codes = _walk_codes()
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    verify(codes[:64], flags[:64], nominal_calibration_q())          # warm-up: the model's probe compiles
    harness = PicLogger(sampling_rate_hz=RATE_HZ)
    cycles, raw_s = harness.raw_speed(N_SAMPLES)
    r = verify(codes, flags, nominal_calibration_q(), harness=harness)
    seconds = N_SAMPLES / RATE_HZ
    print(f"PIC harness: {N_SAMPLES:,} samples ({seconds:g} s at {RATE_HZ:g} Hz, a simulated walk)")
    print(f"  baseline: gpsim alone, production build, nothing logged: {raw_s:.2f} s for {cycles / 1e6:.1f} M cycles "
          f"= {cycles / raw_s / 1e6:.0f} M cycles/s, {seconds / raw_s:.1f}x real time")
    print(f"  harness (gpsim with its write log): {r.gpsim_s:.2f} s")
    print(f"  verify end to end (assemble, gpsim, parse, model, compare): {r.wall_s:.2f} s = "
          f"{r.realtime_factor:.1f}x real time (target >= {TARGET_REALTIME:g}x)")
    for s in r.stages:
        print(f"  {s.name}: {s.n_identical:,} of {s.n_compared:,} samples identical")
    failed = not r.identical or r.realtime_factor < TARGET_REALTIME
    if failed:
        why = "a sample differs" if not r.identical else f"{r.realtime_factor:.1f}x < {TARGET_REALTIME:g}x"
        print(f"FAILED: {why}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
