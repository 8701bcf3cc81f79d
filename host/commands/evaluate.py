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
import sys

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
    number,
    out_path,
    verbosity,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import UsageError

# The studies load numpy, numba and matplotlib: _run_sim and run import them, so that `gaitlog --help` does not.

#: The options of ``evaluate sim`` alone and their defaults (None on the command line: ``evaluate ipol`` refuses
#: any of them given).
SIM_DEFAULTS = {"subjects": 4, "seed": 0, "workers": 1, "population": "people"}

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
    parser.add_argument("--subjects", type=whole(minimum=1, maximum=1000), default=None, help="sim: number of simulated subjects (4)")
    parser.add_argument("--seed", type=SEED, default=None, help="sim: seed of the subjects and devices (0)")
    parser.add_argument("--workers", type=whole(minimum=1, maximum=256), default=None, help="sim: processes to use (1)")
    parser.add_argument("--population", choices=["v1", "people"], default=None,
                        help="sim: simulated population: people (default; tuned to real lower-back walking) or v1")
    parser.add_argument("--protocol", choices=["paper", "compact"], default=None,
                        help="sim: paper (default: Alvarez's protocol as run: 5-minute rests with the logger stopped, "
                        "subjects 1.68-1.86 m) or compact (60 s rests logged, the population's heights)")
    parser.add_argument("--laps", choices=["stopwatch", "mark"], default=None,
                        help="sim: who times the 20 m laps: an observer's stopwatch (default, the paper's; needs "
                        "--protocol paper) or the logger's MARK button (exact)")
    parser.add_argument("--resamples", type=whole(minimum=0, maximum=1_000_000), default=2000,
                        help="bootstrap resamples of the subjects for the intervals (default 2000; 0: none, and ipol "
                        "scores no choice)")
    parser.add_argument("--figure", metavar="PNG", help="ipol: box plot (default: CSV name with .png)")
    add_logger_rate_option(parser)
    add_adc_bits_option(parser, stored=True, what="of the emulated logger")
    parser.add_argument("--uturn", choices=["exclude", "include"], default=None,
                        help="ipol: steps inside UTurnBoundaries: summed (default: the distance walked includes the "
                        "turn) or left out of the distance, in the main tables (the offline chain is reported with both)")
    parser.add_argument("--arithmetic", choices=["offline", "online-float", "online-fixed", "all"], default=None,
                        help="ipol: the offline float chain, the on-line algorithm in float or in fixed point (the "
                        "logger's), or all three (default); one K (the offline chain's) for every one")
    parser.add_argument("--distance-m", metavar="D", type=number(above=0, unit="m"), default=None,
                        help="ipol: the distance walked between each trial's boundaries, m; K is fitted on it and "
                        "every trial scored against it (default: the IPOL protocol's 20 m; a trial JSON's "
                        "WalkedDistance_m overrides it for that trial)")
    add_force_option(parser)
    add_json_option(parser)
    add_verbosity_options(parser)


def _run_sim(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.evaluation import SimulatedEvaluation

    for name, default in SIM_DEFAULTS.items():
        if getattr(args, name) is None:
            setattr(args, name, default)

    out = args.out or args.folder
    if out is None:
        raise UsageError("evaluate sim: give the output folder as DIR or --out DIR")
    check_output_folder("--out" if args.out else "DIR", out, force=args.force)
    unhonoured = [f for f, v in (("--arithmetic", args.arithmetic), ("--figure", args.figure),
                                 ("--uturn", args.uturn), ("--distance-m", args.distance_m)) if v is not None]
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
        print(ev.to_json(out, paths))
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
    sim_only = [f"--{name}" for name in (*SIM_DEFAULTS, "protocol", "laps") if getattr(args, name) is not None]
    if sim_only:
        raise UsageError(f"{', '.join(sim_only)}: only for 'evaluate sim' (evaluate ipol scores the recorded trials "
                         "of DIR)")
    from gaitlog.host.studies.ipol_report import IpolOutputs, evaluate_ipol, list_trials

    outputs = IpolOutputs.beside(out_path(args.out, "ipol_evaluation.csv"), args.figure)
    args.logger_rate = logger_rate_hz(args)
    check_outputs({"--out": outputs.out, "--figure": outputs.figure, "--out (_steps)": outputs.steps,
                   "--out (_events)": outputs.events}, {"DIR": args.folder}, force=args.force)
    with progress_bar(args, len(list_trials(args.folder)), "trial") as tick:   # skips and saturation: in the report
        report = evaluate_ipol(args.folder, outputs, sampling_rate_hz=args.logger_rate, adc_bits=args.adc_bits,
                               uturn=args.uturn or "include", arithmetic=args.arithmetic or "all",
                               n_resamples=args.resamples, progress=tick,
                               **({} if args.distance_m is None else {"distance_m": args.distance_m}))
    report.write_outputs()
    for msg in report.result.skipped:                # on stderr too, even with -q: data left out is never silent
        print(f"gaitlog evaluate ipol: skipped: {msg}", file=sys.stderr)
    if args.json:
        print(report.to_json())
    elif verbosity(args) >= 0:
        print(report.format_table())
    return 0
