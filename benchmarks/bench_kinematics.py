"""Benchmark: strapdown integration, and Morris' analysis of a 60 s recording.

1. Strapdown integration of 65,536 angular-rate samples into direction-cosine matrices. Target (issue 3):
   <= 50 ms. Baselines measured in the same run: a per-sample Python loop (numpy 3x3 products) and scipy
   ``Rotation`` composition, both doing the same trapezoidal incremental rotations.
2. Morris (issue 16): a 60 s recording of the five-accelerometer platform at 100 Hz (40 dB noise, 53 gait
   cycles) read from its CSV file and analysed -- foot-flat detection, the integration constant of every
   cycle, direction cosines, translation. Target <= 1 s. Baseline in the same run: the same analysis with the
   integration constant solved cycle by cycle (the batch over cycles and Jacobian perturbations switched
   off); both must give the same orientations.
3. The same 60 s recorded by the emulated logger (five accelerometers on its analog inputs, PROTOCOL.md 2.6,
   sensor noise, offsets and drift on): memory image decoded and analysed, target <= 1 s; every gait cycle of
   the simulated walk must be found, as from the CSV.

Prints each number, its target and the speed-up; exits 1 if a target is missed or the results disagree.

Run: ``python benchmarks/bench_kinematics.py``
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from gaitlog.host.files.decode import decode_file
from gaitlog.host.kinematics.logger_instruments import record_instrument, sensor_recording
from gaitlog.host.kinematics.morris_analysis import MorrisAnalysis, analyse_morris_recording
from gaitlog.host.kinematics.orientation import (
    geodesic_distance_rad,
    integrate_dcm,
    rotation_increments,
)
from gaitlog.host.kinematics.platform_description import MorrisPlatform
from gaitlog.host.kinematics.sensor_csv import read_sensor_csv
from gaitlog.host.kinematics.simulated_instruments import simulate_morris, write_instrument

N_SAMPLES = 65_536
RATE_HZ = 1_000.0
TARGET_MS = 50.0
MORRIS_DURATION_S = 60.0
MORRIS_TARGET_MS = 1000.0


def _best_ms(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, (time.perf_counter() - t0) * 1e3)
    return best, out


def _loop_numpy(w: np.ndarray) -> np.ndarray:
    phi = 0.5 * (w[:-1] + w[1:]) / RATE_HZ
    out = np.empty((w.shape[0], 3, 3))
    lam = np.eye(3)
    out[0] = lam
    for k in range(phi.shape[0]):
        lam = lam @ rotation_increments(phi[k])
        out[k + 1] = lam
    return out


def _loop_scipy(w: np.ndarray) -> np.ndarray:
    incs = Rotation.from_rotvec(0.5 * (w[:-1] + w[1:]) / RATE_HZ)
    r = Rotation.identity()
    out = [r.as_matrix()]
    for k in range(len(incs)):
        r = r * incs[k]
        out.append(r.as_matrix())
    return np.array(out)


def _morris_cycle_by_cycle(csv: Path, platform_json: Path) -> list:
    rec = read_sensor_csv(csv)
    plat = MorrisPlatform.load(platform_json)
    readings = rec.columns(plat.sensors, "specific force")
    an = MorrisAnalysis(positions_m=plat.positions_m, axes=plat.axes, origin_from_pivot_m=plat.origin_from_pivot_m,
                        assume_zero_rate_axes=plat.assume_zero_rate_axes)
    cycles = an.find_cycles(readings, rec.sampling_rate_hz)
    return [an.analyse_cycle(readings, rec.sampling_rate_hz, s, e, rec.t_s) for s, e in cycles]


def bench_morris() -> bool:
    """Part 2 (module notes); returns whether the target is met and the results agree."""
    with tempfile.TemporaryDirectory() as d:
        write_instrument(simulate_morris(duration_s=MORRIS_DURATION_S), d, "m")
        csv, plat = Path(d) / "m.csv", Path(d) / "m_platform.json"

        def ours() -> list:
            return analyse_morris_recording(read_sensor_csv(csv), MorrisPlatform.load(plat))

        ours()  # warm-up
        ours_ms, cycles = _best_ms(ours, 5)
        base_ms, base = _best_ms(lambda: _morris_cycle_by_cycle(csv, plat), 1)
    agree = max(float(geodesic_distance_rad(a.dcm, b.dcm).max()) for a, b in zip(cycles, base, strict=True))
    ok = ours_ms <= MORRIS_TARGET_MS and len(cycles) == len(base) and agree < 1e-6
    print(f"Morris, {MORRIS_DURATION_S:g} s at 100 Hz, 5 accelerometers, {len(cycles)} cycles, CSV read + analysed: "
          f"{ours_ms:8.1f} ms  (target <= {MORRIS_TARGET_MS:.0f} ms)")
    print(f"baseline, integration constant cycle by cycle:                          {base_ms:8.1f} ms  "
          f"speed-up x{base_ms / ours_ms:.1f}")
    print(f"max orientation disagreement: {agree:.2e} rad (must be < 1e-6)")
    return ok and bench_morris_logged(len(cycles))


def bench_morris_logged(n_cycles: int) -> bool:
    """Part 3 (module notes): ``n_cycles`` found from the CSV must be found from the logger's image too."""
    li = record_instrument("morris", duration_s=MORRIS_DURATION_S, seed=0)
    with tempfile.TemporaryDirectory() as d:
        image = li.logger.save_image(Path(d) / "m.glimg")

        def ours() -> list:
            return analyse_morris_recording(sensor_recording(decode_file(image)), li.platform)

        ours()  # warm-up
        ms, cycles = _best_ms(ours, 5)
    print(f"Morris, the same {MORRIS_DURATION_S:g} s through the logger ({li.n_frames} frames), image decoded + "
          f"analysed, {len(cycles)} cycles: {ms:8.1f} ms  (target <= {MORRIS_TARGET_MS:.0f} ms)")
    return ms <= MORRIS_TARGET_MS and len(cycles) == n_cycles


def main() -> int:
    rng = np.random.default_rng(0)
    t = np.arange(N_SAMPLES) / RATE_HZ
    w = np.stack([np.sin(2 * np.pi * 0.9 * t), 3 * np.cos(2 * np.pi * 1.1 * t), 0.5 * np.sin(2 * np.pi * 2.3 * t)], 1)
    w += 0.05 * rng.normal(size=w.shape)
    integrate_dcm(w[:1000], RATE_HZ)  # warm-up
    ours_ms, ours = _best_ms(lambda: integrate_dcm(w, RATE_HZ), 15)
    heun_ms, _ = _best_ms(lambda: integrate_dcm(w, RATE_HZ, method="heun"), 7)
    loop_ms, loop = _best_ms(lambda: _loop_numpy(w), 1)
    scipy_ms, ref = _best_ms(lambda: _loop_scipy(w), 1)
    agree = float(geodesic_distance_rad(ours, ref).max())
    agree_loop = float(geodesic_distance_rad(ours, loop).max())
    ok = ours_ms <= TARGET_MS and agree < 1e-10 and agree_loop < 1e-10
    print(f"integrate_dcm (Rodrigues, quaternion scan), {N_SAMPLES} samples: {ours_ms:8.1f} ms  (target <= {TARGET_MS:.0f} ms)")
    print(f"integrate_dcm (Heun), {N_SAMPLES} samples:                    {heun_ms:8.1f} ms  (no target)")
    print(f"baseline per-sample numpy loop:                          {loop_ms:8.1f} ms  speed-up x{loop_ms / ours_ms:.1f}")
    print(f"baseline scipy Rotation composition loop:                {scipy_ms:8.1f} ms  speed-up x{scipy_ms / ours_ms:.1f}")
    print(f"max disagreement vs scipy composition: {agree:.2e} rad, vs numpy loop: {agree_loop:.2e} rad (must be < 1e-10)")
    ok = bench_morris() and ok
    print(f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs: timings scale with machine load)")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
