"""``gaitlog evaluate ipol DIR`` and ``gaitlog evaluate sim``: the paper's evaluation of M1-M5.

``ipol``: every trial of a folder in the IPOL lower-back layout replayed through the emulated logger, K fitted
on each subject's first trial. ``sim``: simulated subjects walking Alvarez's protocol (100 m out and back at four
speeds, 20 m lap marks) through the emulated logger, K calibrated single- and multi-speed, every 20 m section
scored against the truth (Figs 5-6).
"""

from __future__ import annotations

import argparse

HELP = "evaluate M1-M5: IPOL lower-back trials (ipol DIR) or simulated subjects (sim) through the emulated logger"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", choices=["ipol", "sim"],
                        help="ipol: a folder in the layout of Voisard et al. 2023; sim: simulated subjects")
    parser.add_argument("folder", metavar="DIR", nargs="?",
                        help="ipol: folder holding GaitData/<s>-<t>_lb.txt and .json; sim: output folder")
    parser.add_argument("--out", metavar="CSV",
                        help="ipol: one row per trial and estimator (required); sim: output folder (or DIR)")
    parser.add_argument("--subjects", type=int, default=4, help="sim: number of simulated subjects (4)")
    parser.add_argument("--seed", type=int, default=0, help="sim: seed of the subjects and devices (0)")
    parser.add_argument("--workers", type=int, default=1, help="sim: processes to use (1)")
    parser.add_argument("--figure", metavar="PNG", help="box plot (default: CSV name with .png)")
    parser.add_argument("--rate", type=float, default=50.0, metavar="HZ", help="logger sample rate (50)")
    parser.add_argument("--bits", type=int, default=10, help="ADC bits, 1-10 (10)")
    parser.add_argument("--uturn", choices=["exclude", "include"], default="exclude",
                        help="steps inside UTurnBoundaries: left out of the distance (default) or summed")
    parser.add_argument("--arithmetic", choices=["float", "fixed", "both"], default="both",
                        help="float host chain, the PIC's fixed-point chain on the same codes, or both (default)")


def _run_sim(args: argparse.Namespace) -> int:
    from host.errors import HostError
    from host.evaluation import SimulatedEvaluation

    out = args.out or args.folder
    if out is None:
        raise HostError("evaluate sim: give the output folder as DIR or --out DIR")
    if args.subjects < 1 or args.workers < 1:
        raise HostError(f"--subjects and --workers must be >= 1, got {args.subjects} and {args.workers}")
    if args.bits != 10 and not 1 <= args.bits <= 10:
        raise HostError(f"--bits must be 1..10, got {args.bits}")
    ev = SimulatedEvaluation(n_subjects=args.subjects, seed=args.seed, rate_hz=args.rate, bits=args.bits,
                             workers=args.workers).run()
    paths = ev.write_outputs(out)
    print(f"{args.subjects} simulated subjects (seed {args.seed}), {args.rate:g} Hz, {args.bits} bits, "
          f"emulated logger calibrated on a pose session; 20 m sections, ratio estimated / real")
    print(ev.format_table())
    print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from host.errors import HostError

    if args.dataset == "sim":
        return _run_sim(args)
    if args.folder is None or args.out is None:
        raise HostError("evaluate ipol: give the folder (DIR) and --out CSV")
    from host.ipol_evaluation import CSV_COLUMNS, evaluate_folder, summarise
    from protocol.atomic_write import atomic_write, atomic_write_text, require_folder

    if not 1 <= args.bits <= 10:
        raise HostError(f"--bits must be 1..10, got {args.bits}")
    if not args.rate > 0:
        raise HostError(f"--rate must be positive, got {args.rate}")
    fig_path = Path(args.figure) if args.figure else Path(args.out).with_suffix(".png")
    require_folder(args.out)
    require_folder(fig_path)
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
