"""Report: does the simulated walker look like people?  Simulated IPOL trials against the real ones.

Writes ``--subjects`` (20) simulated subjects' IPOL lower-back trials (``gaitlog simulate --ipol-out``: stand,
10 m, U-turn, 10 m back, stop), runs ``../shared/tools/walking_stats.py`` on them and on the real IPOL trials
(``../shared/data/ipol-lowerback-dev/GaitData``, the figures of ``ipol-lowerback-dev-walking-stats.md``) in the
same call, and prints for every statistic the simulated median next to the real median and 5-95 % band.

A statistic passes when the simulated median lies inside the real 5-95 % band *and* within ±20 % of the real
median (issue 14's criterion, :mod:`gaitlog.host.studies.realism`). The statistics the issue names are checked; the
others (the sensor's standing noise and scale, counts and durations that follow from the checked ones) are
printed for information. Exits non-zero when a checked statistic fails, 2 when ``../shared`` is absent.

    python benchmarks/bench_walking_realism.py [--subjects 20] [--seed 0] [--keep DIR]
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.studies.realism import MEDIAN_TOLERANCE, STATISTICS, judge  # noqa: E402
from gaitlog.host.studies.simulation import export_ipol  # noqa: E402

SHARED = ROOT.parent / "shared"
STATS_TOOL = SHARED / "tools" / "walking_stats.py"
REAL = SHARED / "data" / "ipol-lowerback-dev" / "GaitData"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--population", default="people", choices=("people", "v1"),
                    help="population of the simulated subjects (default people)")
    ap.add_argument("--keep", metavar="DIR", help="write the simulated trials and the statistics here")
    args = ap.parse_args()
    if not (STATS_TOOL.is_file() and REAL.is_dir()):
        print(f"skipped: {STATS_TOOL} or {REAL} not found (../shared beside the repository)")
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        sim_dir, out_dir = work / "sim" / "GaitData", work / "stats"
        t0 = time.perf_counter()
        export_ipol(sim_dir, args.subjects, seed=args.seed, population=args.population)
        export_s = time.perf_counter() - t0
        subprocess.run([sys.executable, str(STATS_TOOL), str(out_dir), f"sim={sim_dir}", f"real={REAL}"],
                       check=True, capture_output=True)
        with open(out_dir / "real_walking_stats.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
    col = {s: {k: np.array([float(r[k]) for r in rows if r["set"] == s]) for k, _, _ in STATISTICS}
           for s in ("sim", "real")}
    n_real = col["real"]["rms_v"].size
    print(f"{args.subjects} simulated subjects ('{args.population}' population, seed {args.seed}, written in {export_s:.1f} s) vs {n_real} real "
          f"IPOL trials; pass = simulated median inside the real 5-95 % band and within ±{MEDIAN_TOLERANCE:.0%} "
          "of the real median")
    print(f"{'statistic':42s} {'sim median':>10s} {'real median':>11s} {'real 5-95 %':>17s} {'sim/real':>8s}  result")
    failed = []
    for key, label, checked in STATISTICS:
        v = judge(col["sim"][key], col["real"][key])
        med, rmed, p5, p95, ok = v.sim_median, v.real_median, v.real_p5, v.real_p95, v.passes
        ratio = med / rmed if rmed else float("nan")
        verdict = ("pass" if ok else "FAIL") if checked else ("(in)" if ok else "(out)") + " info"
        print(f"{label:42s} {med:10.3g} {rmed:11.3g} {f'[{p5:.3g}, {p95:.3g}]':>17s} {ratio:8.2f}  {verdict}")
        if checked and not ok:
            failed.append(label)
    for s in ("sim", "real"):
        r = col[s]["fdom_ml_over_stride_freq"]
        print(f"ML spectral peak ({s}): at 1x stride {np.mean(np.abs(r - 1) < 0.25):.0%}, at 3x "
              f"{np.mean(np.abs(r - 3) < 0.25):.0%} of trials (the median of this bimodal statistic flips with the "
              "draw)")
    n_checked = sum(1 for *_, c in STATISTICS if c)
    print(f"checked statistics passing: {n_checked - len(failed)}/{n_checked}"
          + (f"; failing: {', '.join(failed)}" if failed else ""))
    print("PASS" if not failed else "FAIL")
    return 0 if not failed else 1


if __name__ == "__main__":
    sys.exit(main())
