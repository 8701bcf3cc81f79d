"""``gaitlog evaluate ipol DIR``: the paper's evaluation on IPOL lower-back recordings through the emulator."""

from __future__ import annotations

import argparse

HELP = "evaluate M1-M5 on a folder of IPOL lower-back trials replayed through the emulated logger"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", choices=["ipol"], help="dataset layout (ipol: Voisard et al. 2023)")
    parser.add_argument("folder", metavar="DIR", help="folder holding GaitData/<s>-<t>_lb.txt and .json")
    parser.add_argument("--out", required=True, metavar="CSV", help="one row per trial and estimator")
    parser.add_argument("--figure", metavar="PNG", help="box plot (default: CSV name with .png)")
    parser.add_argument("--rate", type=float, default=50.0, metavar="HZ", help="logger sample rate (50)")
    parser.add_argument("--bits", type=int, default=10, help="ADC bits, 1-10 (10)")
    parser.add_argument("--uturn", choices=["exclude", "include"], default="exclude",
                        help="steps inside UTurnBoundaries: left out of the distance (default) or summed")
    parser.add_argument("--arithmetic", choices=["float", "fixed", "both"], default="both",
                        help="float host chain, the PIC's fixed-point chain on the same codes, or both (default)")


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from host.errors import HostError
    from host.ipol_evaluation import CSV_COLUMNS, evaluate_folder, summarise
    from protocol.atomic_write import atomic_write, atomic_write_text

    if not 1 <= args.bits <= 10:
        raise HostError(f"--bits must be 1..10, got {args.bits}")
    if not args.rate > 0:
        raise HostError(f"--rate must be positive, got {args.rate}")
    show = sys.stderr.isatty()
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # skips are listed below
        arith = ("float", "fixed") if args.arithmetic == "both" else (args.arithmetic,)
        res = evaluate_folder(args.folder, rate_hz=args.rate, bits=args.bits, uturn=args.uturn, arithmetic=arith,
                              progress=(lambda name: print(f"  {name:<16}", file=sys.stderr, end="\r"))
                              if show else None)
    lines = [",".join(CSV_COLUMNS)]
    for r in res.rows:
        lines.append(f"{r['subject']},{r['trial']},{r['estimator']},{r['arithmetic']},{r['distance_m']:.4f},"
                     f"{r['ratio']:.5f},{r['steps']},{r['reference_steps']}")
    summary = summarise(res.rows, arithmetic=arith[0])
    fig_path = Path(args.figure) if args.figure else Path(args.out).with_suffix(".png")
    # figure first (it can fail on a broken matplotlib); the CSV is written last, both atomically
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.0))
    names = [s["estimator"] for s in summary]
    data = [[r["ratio"] for r in res.rows if r["estimator"] == n and r["arithmetic"] == arith[0]] for n in names]
    ax.boxplot(data, whis=(0, 100))
    ax.set_xticks(range(1, len(names) + 1), [n + (" (no K)" if n == "M3" else "") for n in names])
    ax.axhline(1.0, color="grey", lw=0.8, ls="--")
    ax.set_ylabel("estimated / real distance (20 m)")
    ax.set_title(f"IPOL lower back, {args.rate:g} Hz, {args.bits} bits, {arith[0]}, K from trial 1 "
                 f"({'emulated logger' if res.emulated else 'ideal sampling'})", fontsize=9)
    with atomic_write(fig_path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=120, bbox_inches="tight")
    plt.close(fig)
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    n_subjects = max(len(res.calibrations), len(res.calibrations_fixed))
    print(f"{n_subjects} subjects, {res.n_trials} evaluated trials, {args.rate:g} Hz, {args.bits} bits, "
          f"U-turn {args.uturn}d, {'emulated logger' if res.emulated else 'ideal sampling (no emulator)'}")
    for a in arith:
        print(f"arithmetic = {a}")
        print(f"{'estimator':<10}{'n':>4}{'median':>8}{'q1':>8}{'q3':>8}{'IQR':>7}{'min':>8}{'max':>8}"
              f"{'steps|err|%':>13}")
        for s in summarise(res.rows, arithmetic=a):
            if not s.get("n"):
                print(f"{s['estimator']:<10}{0:>4}")
                continue
            print(f"{s['estimator']:<10}{s['n']:>4}{s['median']:>8.3f}{s['q1']:>8.3f}{s['q3']:>8.3f}{s['iqr']:>7.3f}"
                  f"{s['min']:>8.3f}{s['max']:>8.3f}{s['step_error_median_pct']:>13.2f}")
    if len(arith) == 2:
        import numpy as np

        key = {(r["subject"], r["trial"], r["estimator"], r["arithmetic"]): r["ratio"] for r in res.rows}
        diff = {n: [abs(key[k[:3] + ("fixed",)] - v) for k, v in key.items() if k[2] == n and k[3] == "float"]
                for n in names}
        print("fixed - float ratio per trial: " + ", ".join(f"{n} median |d| {np.median(d):.5f}"
                                                            for n, d in diff.items()))
    if "fixed" in arith:
        print("fixed-point saturation/wrap: " + ("; ".join(res.saturation) if res.saturation else "none"))
    for msg in res.skipped:
        print(f"skipped: {msg}")
    print(f"written: {args.out}, {fig_path}")
    return 0
