"""Benchmark: render a simulated study's walks, 20 subjects x the full protocol (issue 14: <= 30 s on 2 cores).

Renders ``--subjects`` (20) subjects of the ``people`` population walking the paper's protocol with the
population's habits (:func:`gaitlog.host.studies.simulation.simulated_population`: four speeds, 100 m back and forth)
at the sensor's internal rate (500 Hz, as the studies render them), truth included, on ``--workers`` (2)
processes; also the CPU time of the renderings (summed), which the machine's other load does not inflate.
Baseline in the same run: the same number of ``v1`` subjects (the older walker, without the lateral
harmonics, contact asymmetries and cadence law) rendered the same way. Prints both and their ratio; exits
non-zero if the ``people`` rendering misses the target.

    python benchmarks/bench_walking_population.py [--subjects 20] [--workers 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.studies.simulation import map_subjects, simulated_population

#: Issue 14: 20 subjects x the full protocol on the 2-core machine.
TARGET_S = 30.0
RATE_HZ = SensorModel().internal_rate_hz


def _render(job: tuple) -> tuple[int, float, float]:
    subject, plan, seed = job
    c0 = time.process_time()
    motion = Walking(subject=subject, walk_plan=plan, seed=seed).render(RATE_HZ)
    return motion.n_samples, motion.duration_s, time.process_time() - c0


def _timed(population: str, n: int, seed: int, workers: int) -> tuple[float, int, float, float]:
    """Wall time, samples, seconds of motion and CPU seconds (summed over the subjects' processes)."""
    subjects, plan = simulated_population(n, seed=seed, population=population)
    jobs = [(s, plan, seed * 1000 + i) for i, s in enumerate(subjects)]
    t0 = time.perf_counter()
    out = map_subjects(_render, jobs, workers=workers)
    return (time.perf_counter() - t0, sum(r[0] for r in out), sum(r[1] for r in out),
            sum(r[2] for r in out))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    people_s, n_samples, motion_s, people_cpu = _timed("people", args.subjects, args.seed, args.workers)
    v1_s, v1_samples, _, v1_cpu = _timed("v1", args.subjects, args.seed, args.workers)
    print(f"{args.subjects} subjects x the full protocol at {RATE_HZ:g} Hz, {args.workers} worker(s), "
          f"{os.cpu_count()} CPU(s), load {os.getloadavg()[0]:.1f}")
    print(f"people: {people_s:7.1f} s  ({n_samples / 1e6:.1f} M samples, {motion_s / 60:.0f} min of motion)   "
          f"target <= {TARGET_S:g} s; CPU {people_cpu:.1f} s, / {args.workers} workers = {people_cpu / args.workers:.1f} s "
          "(the wall time on an otherwise idle machine)")
    print(f"v1 (baseline, same run): {v1_s:7.1f} s  ({v1_samples / 1e6:.1f} M samples)   "
          f"CPU {v1_cpu:.1f} s; people / v1 = {people_s / v1_s:.2f} (wall), {people_cpu / v1_cpu:.2f} (CPU)")
    ok = people_s <= TARGET_S
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
