"""Speed of the gpsim harness: every PIC16 assembly kernel on its edge cases + 10,000 random vectors (issue 15).

Run: ``python benchmarks/bench_gpsim.py`` (needs gputils and gpsim). Times ``gaitlog.firmware_sim.pic.gpsim_bench.measure``
-- assemble, 12 kernels x ~10,300 vectors in gpsim processes of 1,000 vectors, two at a time, every result
compared with ``fixedpoint.py`` -- once (target <= 60 s wall on the 2-core machine), with its CPU time (this
process and the gpsim children). Baseline in the same run: the Python definitions of ``fixedpoint.py``
alone on the same vectors (what the comparison costs), and gpsim's share per vector. Exits 1 if a kernel
differs or the target is missed.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.firmware_sim.pic.gpsim_bench import KERNELS, measure, missing_tools, vectors  # noqa: E402

TARGET_S = 60.0


def main() -> int:
    reason = missing_tools()
    if reason:
        print(f"bench_gpsim: {reason}", file=sys.stderr)
        return 1
    t0, c0 = time.perf_counter(), os.times()
    runs, words = measure()
    wall, c1 = time.perf_counter() - t0, os.times()
    cpu = (c1.user - c0.user) + (c1.system - c0.system) + (c1.children_user - c0.children_user) \
        + (c1.children_system - c0.children_system)
    n = sum(len(r.operands) for r in runs.values())
    bad = {k: len(r.mismatches) for k, r in runs.items() if r.mismatches}

    t0 = time.perf_counter()
    for name, k in KERNELS.items():
        for ops in vectors(name):
            k.reference(*ops)
    python_s = time.perf_counter() - t0

    print(f"gpsim harness: {len(runs)} kernels, {n:,} vectors, {words} program words")
    print(f"  wall        {wall:8.1f} s   (target <= {TARGET_S:g} s; {1e6 * wall / n:.0f} us per vector)")
    print(f"  CPU         {cpu:8.1f} s   (this process + gpsim children; {os.cpu_count()} CPUs)")
    print(f"  baseline: fixedpoint.py's Python definitions on the same vectors {python_s:.2f} s "
          f"(the harness is {wall / python_s:.0f}x that)")
    for r in runs.values():
        s = r.summary()
        print(f"  {s['kernel']:<9s} {s['vectors']:6,d} vectors, {s['mismatches']} differ, cycles "
              f"{s['cycles_min']} / {s['cycles_mean']:g} / {s['cycles_max']}")
    failed = bool(bad) or wall > TARGET_S
    if bad:
        print(f"FAILED: kernels differ from fixedpoint.py: {bad}")
    if wall > TARGET_S:
        print(f"FAILED: {wall:.1f} s > {TARGET_S:g} s")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
