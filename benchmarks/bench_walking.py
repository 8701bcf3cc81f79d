"""Benchmark: render the full 4-speed walking protocol for one subject at 500 Hz (the sensor's rate).

Prints each measured number, its target and the ratio against a baseline measured in the same run: the
same kinematics evaluated sample by sample (a per-sample Python loop over ``Walking._kinematics``, timed on
a 2 s slice and scaled to the protocol's length). Exits non-zero if a target is missed.

    python benchmarks/bench_walking.py
"""

from __future__ import annotations

import sys
import time

import numpy as np

from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walking import Walking

RATE_HZ = 500.0
#: Target for the whole protocol (~16 min of motion, ~410k samples, truth included) on a 2-core CI box.
TARGET_RENDER_S = 10.0
#: Vectorised evaluation must beat the per-sample loop by at least this factor.
TARGET_SPEEDUP = 50.0


def main() -> int:
    walking = Walking(subject=Subject(), seed=0)
    t0 = time.perf_counter()
    motion = walking.render(RATE_HZ)
    render_s = time.perf_counter() - t0

    # Baseline: per-sample evaluation of the same kinematics on a 2 s walking slice.
    segments = walking._segments()
    seg = next(s for s in segments if s.plan is not None)
    t_slice = seg.t_a + 20.0 + np.arange(int(2.0 * RATE_HZ)) / RATE_HZ
    t1 = time.perf_counter()
    loop = np.array([walking._kinematics(seg, np.array([t]))["acc_g"][0] for t in t_slice])
    loop_s = (time.perf_counter() - t1) * motion.n_samples / t_slice.size
    t2 = time.perf_counter()
    vec = walking._kinematics(seg, t_slice)["acc_g"]
    vec_s = (time.perf_counter() - t2) * motion.n_samples / t_slice.size
    agree = float(np.max(np.abs(vec - loop)))
    speedup = loop_s / vec_s

    print(f"samples rendered: {motion.n_samples} ({motion.duration_s:.0f} s at {RATE_HZ:g} Hz, "
          f"{motion.truth['steps']['length_m'].size} steps)")
    print(f"render + truth:          {render_s:8.2f} s   target <= {TARGET_RENDER_S:g} s   "
          f"(baseline per-sample loop, extrapolated: {loop_s:8.1f} s; ratio {loop_s / render_s:6.1f}x)")
    print(f"kinematics only (2 s slice, scaled): vectorised {vec_s:6.2f} s vs loop {loop_s:8.1f} s: "
          f"{speedup:6.1f}x   target >= {TARGET_SPEEDUP:g}x   (max |difference| {agree:.1e} g)")
    ok = render_s <= TARGET_RENDER_S and speedup >= TARGET_SPEEDUP and agree < 1e-12
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
