"""``gaitlog evaluate ipol DIR`` and ``gaitlog evaluate sim``: the paper's evaluation of M1-M5.

``ipol``: every trial of a folder in the IPOL lower-back layout replayed through the emulated logger with its
on-line step algorithm on; the device's records checked against the host's replay; the offline chain and the
on-line algorithm in float and in fixed point, with one K per subject fitted on its first trial with the
offline chain (and, labelled apart, the on-line algorithm with its own K). It also prints the constants tuned on
these recordings as chosen leave-one-subject-out (and which figures are therefore cross-validated), the events
against the foot sensors, per trial the steps with each event found and filled, the offline chain with the
other U-turn rule and with the height unknown (a 1.70 m adult assumed for everyone), and the steps outside K's
calibrated range; the per-trial events go to ``<CSV>_events.csv``. ``sim``: simulated subjects walking
Alvarez's protocol (100 m out and back at four speeds, 20 m lap marks) through the emulated logger, K
calibrated single- and multi-speed, every 20 m section scored against the truth (Figs 5-6); by default the
protocol as run (5-minute rests with the logger stopped, laps by an observer's stopwatch, subjects 1.68-1.86 m),
with bootstrap intervals over subjects, the paper's stated figures side by side and M5 against the generating
heel-strike intervals.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text
from gaitlog.host.commands._options import (
    SEED,
    add_adc_bits_option,
    add_force_option,
    add_json_option,
    add_logger_rate_option,
    add_verbosity_options,
    check_output_folder,
    check_outputs,
    logger_rate_hz,
    out_path,
    print_json,
    verbosity,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import UsageError

HELP = "evaluate M1-M5: IPOL lower-back trials (ipol DIR) or simulated subjects (sim) through the emulated logger"
#: Shown under "examples:" by ``gaitlog evaluate --help``.
EXAMPLES = (
    "gaitlog evaluate ipol GaitData --out ipol.csv",
    "gaitlog evaluate sim --subjects 4 --out eval-sim",
)


def configure(parser: argparse.ArgumentParser) -> None:

    parser.add_argument("dataset", choices=["ipol", "sim"],
                        help="ipol: a folder in the layout of Voisard et al. 2023; sim: simulated subjects")
    parser.add_argument("folder", metavar="DIR", nargs="?",
                        help="ipol: folder holding GaitData/<s>-<t>_lb.txt and .json; sim: output folder")
    parser.add_argument("--out", metavar="CSV",
                        help="ipol: one row per trial, estimator and arithmetic (required; per-step pairs go to "
                        "<CSV>_steps.csv); sim: output folder (or DIR)")
    parser.add_argument("--subjects", type=whole(minimum=1, maximum=1000), default=4, help="sim: number of simulated subjects (4)")
    parser.add_argument("--seed", type=SEED, default=0, help="sim: seed of the subjects and devices (0)")
    parser.add_argument("--workers", type=whole(minimum=1, maximum=256), default=1, help="sim: processes to use (1)")
    parser.add_argument("--population", choices=["v1", "people"], default="people",
                        help="sim: simulated population: people (default; tuned to real lower-back walking) or v1")
    parser.add_argument("--protocol", choices=["paper", "compact"], default=None,
                        help="sim: paper (default: Alvarez's protocol as run: 5-minute rests with the logger stopped, "
                        "subjects 1.68-1.86 m) or compact (60 s rests logged, the population's heights)")
    parser.add_argument("--laps", choices=["stopwatch", "mark"], default=None,
                        help="sim: who times the 20 m laps: an observer's stopwatch (default, the paper's; needs "
                        "--protocol paper) or the logger's MARK button (exact)")
    parser.add_argument("--resamples", type=whole(minimum=0, maximum=1_000_000), default=2000,
                        help="sim: bootstrap resamples of the subjects for the intervals (default 2000; 0: none)")
    parser.add_argument("--figure", metavar="PNG", help="ipol: box plot (default: CSV name with .png)")
    add_logger_rate_option(parser)
    add_adc_bits_option(parser, stored=True, what="of the emulated logger")
    parser.add_argument("--uturn", choices=["exclude", "include"], default=None,
                        help="ipol: steps inside UTurnBoundaries: summed (default: the 20 m walked include the "
                        "turn) or left out of the distance, in the main tables (the offline chain is reported with both)")
    parser.add_argument("--arithmetic", choices=["offline", "online-float", "online-fixed", "all"], default=None,
                        help="ipol: the offline float chain, the on-line algorithm in float or in fixed point (the "
                        "logger's), or all three (default); one K (the offline chain's) for every one")
    add_force_option(parser)
    add_json_option(parser)
    add_verbosity_options(parser)


def _run_sim(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.evaluation import SimulatedEvaluation

    out = args.out or args.folder
    if out is None:
        raise UsageError("evaluate sim: give the output folder as DIR or --out DIR")
    check_output_folder("--out" if args.out else "DIR", out, force=args.force)
    unhonoured = [f for f, v in (("--arithmetic", args.arithmetic), ("--figure", args.figure),
                                 ("--uturn", args.uturn)) if v is not None]
    args.protocol = args.protocol or "paper"
    args.laps = args.laps or ("stopwatch" if args.protocol == "paper" else "mark")
    if args.laps == "stopwatch" and args.protocol != "paper":
        raise UsageError("--laps stopwatch: only with --protocol paper (the host anchors the stopwatch at the "
                        "set-off of each logging run; the compact protocol logs through its rests)")
    if unhonoured:
        raise UsageError(f"{', '.join(unhonoured)}: only for 'evaluate ipol' (evaluate sim scores the offline chain "
                        "on 20 m sections without U-turns, and writes its figures into the output folder)")
    if args.subjects < 1 or args.workers < 1:
        raise UsageError(f"--subjects and --workers must be >= 1, got {args.subjects} and {args.workers}")
    args.logger_rate = logger_rate_hz(args)
    with progress_bar(args, args.subjects, "subject") as tick:
        ev = SimulatedEvaluation(n_subjects=args.subjects, seed=args.seed, sampling_rate_hz=args.logger_rate, adc_bits=args.adc_bits,
                                 workers=args.workers, population=args.population, protocol=args.protocol,
                                 laps=args.laps, n_resamples=args.resamples).run(progress=tick)
    paths = ev.write_outputs(out)
    if args.json:
        print_json({"out": str(out), "summary": ev.summary_, "intervals": ev.bootstrap_, "files": paths})
        return 0
    if verbosity(args) < 0:
        return 0
    protocol = ("the paper's protocol (5-minute rests, logger stopped during them; heights 1.68-1.86 m)"
                if args.protocol == "paper" else "the compact protocol (60 s rests logged)")
    print(f"{args.subjects} simulated subjects ('{args.population}' population, seed {args.seed}), {args.logger_rate:g} Hz, {args.adc_bits} bits, "
          f"emulated logger calibrated on a pose session; {protocol}; 20 m laps by "
          f"{'an observer with a stopwatch' if args.laps == 'stopwatch' else 'the MARK button'}; ratio estimated / real")
    print(ev.format_table())
    print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def run(args: argparse.Namespace) -> int:


    if args.dataset == "sim":
        return _run_sim(args)
    if args.folder is None or args.out is None:
        raise UsageError("evaluate ipol: give the folder (DIR) and --out CSV")

    args.out = out_path(args.out, "ipol_evaluation.csv")
    from gaitlog.host.studies.compare import rows_csv_text
    from gaitlog.host.studies.ipol_evaluation import (
        ARITHMETICS,
        CSV_COLUMNS,
        EVENT_COLUMNS,
        K_PRIOR_IN_MAIN,
        STEP_COLUMNS,
        done_figures,
        evaluate_folder,
        choice_gains,
        count_gains,
        format_choices,
        format_done,
        format_events,
        format_tuning,
        main_rows,
        summarise,
    )

    args.logger_rate = logger_rate_hz(args)
    args.uturn = args.uturn or "include"
    args.arithmetic = args.arithmetic or "all"
    out = Path(args.out)
    fig_path = Path(args.figure) if args.figure else out.with_suffix(".png")
    steps_path = out.with_name(out.stem + "_steps.csv")
    events_path = out.with_name(out.stem + "_events.csv")
    check_outputs({"--out": out, "--figure": fig_path, "--out (_steps)": steps_path, "--out (_events)": events_path},
                  {"DIR": args.folder}, force=args.force)
    from gaitlog.host.files.ipol import list_trials
    from gaitlog.host.gait.anthropometry import LENGTH_MODEL

    with progress_bar(args, len(list_trials(args.folder)), "trial") as tick:   # skips and saturation: res, below
        arith = ARITHMETICS if args.arithmetic == "all" else (args.arithmetic,)
        res = evaluate_folder(args.folder, sampling_rate_hz=args.logger_rate, adc_bits=args.adc_bits, uturn=args.uturn,
                              arithmetic=arith, progress=tick)
    rows = [{**{c: str(r[c]) for c in CSV_COLUMNS},
             "distance_m": f"{r['distance_m']:.4f}", "ratio": f"{r['ratio']:.5f}",
             "steps_outside_k_range": "" if r["steps_outside_k_range"] is None else str(r["steps_outside_k_range"])}
            for r in res.rows]
    # figure first (it can fail on a broken matplotlib); the CSVs are written last, all atomically
    from gaitlog.host.studies.plots import render_chain_boxplots_png

    png = render_chain_boxplots_png(main_rows(res.rows), arith, title=f"IPOL lower back, {args.logger_rate:g} Hz, {args.adc_bits} bits, "
                                    "K from trial 1 (offline chain) for every chain")
    atomic_write_bytes(fig_path, png)
    atomic_write_text(out, rows_csv_text(rows, CSV_COLUMNS))
    if res.step_rows:
        atomic_write_text(steps_path, rows_csv_text(res.step_rows, STEP_COLUMNS))
    if res.trial_events:
        atomic_write_text(events_path, rows_csv_text(res.trial_events, EVENT_COLUMNS))
    if args.json:
        print_json({"out": str(out), "rows": res.rows, "trial_events": res.trial_events})
        return 0
    if verbosity(args) < 0:
        return 0
    print(f"{len(res.calibrations)} subjects, {res.n_trials} evaluated trials, {args.logger_rate:g} Hz, {args.adc_bits} bits, "
          f"U-turn {args.uturn}d, emulated logger with its on-line algorithm on; one K per subject, fitted on "
          "trial 1 with the offline chain, for every arithmetic"
          + (" and shrunk toward the other subjects' K (the K prior)" if K_PRIOR_IN_MAIN else "")
          + "; lengths from each subject's height ("
          + ", ".join(f"{n} trials {src}" for src, n in _count(r["lengths_source"] for r in main_rows(res.rows)
                                                                 if r["estimator"] == "M1" and r["arithmetic"] == arith[0]
                                                                 and r["k_from"] == "offline").items())
          + f"): {LENGTH_MODEL}")
    print(format_tuning(res))
    tables = [(a, "offline", f"arithmetic = {a}") for a in arith]
    if "online-fixed" in arith:
        tables.append(("online-fixed", "own", "on-line fixed with its OWN K (fitted on its own records of trial 1; "
                       "the device as it would be used -- a different K, not a comparison)"))
    for a, k_from, title in tables:
        _print_table(title, summarise(res.rows, arithmetic=a, k_from=k_from, intervals=True))
    if "offline" in arith:
        other = next(u for u in ("exclude", "include") if u != args.uturn)
        _print_table(f"arithmetic = offline, U-turn {other}d (the other rule; K fitted with it)",
                     summarise(res.rows, arithmetic="offline", variant=f"uturn-{other}", intervals=True))
        _print_table("arithmetic = offline, height UNKNOWN: a 1.70 m adult assumed for every subject (K fitted with "
                     "those lengths; M3 has no K to absorb them)",
                     summarise(res.rows, arithmetic="offline", variant="height-unknown", intervals=True))
        _print_table("arithmetic = offline, M4 with the exponent chosen per fold (K refitted with it; M4 row only)",
                     [x for x in summarise(res.rows, arithmetic="offline", variant="m4-per-fold", intervals=True)
                      if x["estimator"] == "M4"])
        _print_table("baseline, the recipe (host/gait/recipe.py: gaps interpolated, gravity from the first second, "
                     "steps between the peaks of the 3 Hz zero-phase low-pass, M2 h with v and x zero at both ends, "
                     "M4 range^(1/4), K = 20 m / first trial's sum)",
                     [x for x in summarise(res.rows, arithmetic="offline", variant="baseline", intervals=True)
                      if x["estimator"] in ("M2", "M4")])
        if any(r["variant"] == "no-prior" for r in res.rows):
            _print_table("arithmetic = offline, NO K prior: K from trial 1 alone (the paper's K)",
                         summarise(res.rows, arithmetic="offline", variant="no-prior", intervals=True))
        if any(r["variant"] == "k-prior" for r in res.rows):
            _print_table("arithmetic = offline, with the K prior: K from trial 1 shrunk toward the other subjects' K "
                         "(not kept: its gain's interval includes zero)",
                         summarise(res.rows, arithmetic="offline", variant="k-prior", intervals=True))
    if "offline" in arith:
        print(format_choices(choice_gains(res) + count_gains(res)))
    print("steps|err|: median over trials of |detected - reference steps| (% and steps); signed: median of detected"
          " - reference; outside K: steps outside the range K was calibrated on (duration, the estimator's input "
          "or length), of the steps in the trials")
    print(format_events(res))
    if set(arith) == set(ARITHMETICS):
        print(format_done(done_figures(res)))
    else:
        chk = res.replay_checks
        same = sum(c["n_identical"] == c["n_compared"] for c in chk)
        print(f"device step records = host replay, byte for byte: {same} of {len(chk)} trials, "
              f"{sum(c['n_identical'] for c in chk)} of {sum(c['n_compared'] for c in chk)} records")
    print("fixed-point saturation/wrap: " + ("; ".join(res.saturation) if res.saturation else "none"))
    for msg in res.skipped:
        print(f"skipped: {msg}")
    print(f"written: {out}" + (f", {steps_path}" if res.step_rows else "")
          + (f", {events_path}" if res.trial_events else "") + f", {fig_path}")
    return 0


def _count(values) -> dict:
    out: dict = {}
    for v in values:
        out[v] = out.get(v, 0) + 1
    return out


def _ci(interval) -> str:
    return "" if interval is None else f"[{interval[0]:.3f}, {interval[1]:.3f}]"


def _print_table(title: str, summary: list[dict]) -> None:
    """One summary table (:func:`gaitlog.host.studies.ipol_evaluation.summarise`)."""
    print(title)
    print(f"{'estimator':<10}{'n':>4}{'median':>8}{'q1':>8}{'q3':>8}{'IQR':>7}{'min':>8}{'max':>8}"
          f"{'median 95% CI':>16}{'IQR 95% CI':>16}{'steps|err|%':>13}{'|err|':>6}{'signed':>7}{'outside K':>14}")
    for s in summary:
        if not s.get("n"):
            print(f"{s['estimator']:<10}{0:>4}")
            continue
        out_k = "-" if s["steps_outside_k_range"] is None else f"{s['steps_outside_k_range']}/{s['steps_total']}"
        print(f"{s['estimator']:<10}{s['n']:>4}{s['median']:>8.3f}{s['q1']:>8.3f}{s['q3']:>8.3f}{s['iqr']:>7.3f}"
              f"{s['min']:>8.3f}{s['max']:>8.3f}{_ci(s.get('median_ci')):>16}{_ci(s.get('iqr_ci')):>16}"
              f"{s['step_error_median_pct']:>13.2f}"
              f"{s['step_error_median_abs']:>6.1f}{s['step_error_median_signed']:>+7.1f}{out_k:>14}")

