"""``gaitlog compare``: the offline float chain vs the on-line algorithm in float and in fixed point (vs truth
on simulated subjects). One K per calibration mode, fitted on the offline chain, for every chain.

* ``gaitlog compare REC.npz``: a decoded recording's codes through the offline chain and the on-line
  algorithm in both arithmetics (with ``--k-file``'s K, else K = 1); per-step table, per-20 m segment table
  (between MARK flags, ``--lap-m`` apart; else every 20 m of M3's distance), the per-step difference
  summary and the saturation report. A recording carrying the device's own step records is first checked
  against the host's replay, bit for bit: a difference is an error (exit 1).
* ``gaitlog compare --simulate N``: N simulated subjects through the paper's protocol (ideal, offline,
  online-float, online-fixed vs the world's truth, :mod:`gaitlog.host.studies.compare`), the error split ADC / algorithm /
  arithmetic and its 95 % bootstrap intervals over the subjects.

The ADC width x rate sweep and the M5 question are ``gaitlog sweep``'s (:mod:`gaitlog.host.studies.sweep_grid`):
``compare --sweep`` is a usage error that names the ``gaitlog sweep`` command line giving the same grid.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gaitlog.host.commands._anatomy_options import add_anatomy_options, lengths_from_args
from gaitlog.host.commands._input_options import add_input_options, given_input_flags, read_input
from gaitlog.host.commands._options import (
    POSITIVE_M,
    SEED,
    add_adc_bits_option,
    add_force_option,
    add_json_option,
    add_logger_rate_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    logger_rate_hz,
    out_path,
    verbosity,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import UsageError

# The comparisons load numpy and numba: imported inside _simulate and _recording, so that `gaitlog --help`
# stays light (tests/host/commands/test_cli_startup.py).

HELP = "compare the offline chain with the on-line algorithm in float and fixed point (and truth): per step, 20 m"
#: Shown under "examples:" by ``gaitlog compare --help``.
EXAMPLES = (
    "gaitlog compare walk.npz --k-file K.json",
    "gaitlog compare --simulate 4 --adc-bits 12 --out sim.csv",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", nargs="?",
                        help="logger recording: memory image, raw dump, wire capture or decoded .npz (the on-line "
                        "algorithm needs the ADC codes)")
    parser.add_argument("--simulate", type=whole(minimum=1, maximum=1000), metavar="N", help="compare on N simulated subjects instead")
    # moved to `gaitlog sweep`: still parsed, only to name the command line that replaces it
    parser.add_argument("--sweep", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--subjects", type=whole(minimum=1, maximum=1000), default=4, help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the simulated subjects (default 0)")
    parser.add_argument("--population", choices=["v1", "people"], default=None,
                        help="simulated population of --simulate: people (default; tuned to real "
                        "lower-back walking) or v1")
    add_adc_bits_option(parser, stored=False, what="of --simulate")
    add_logger_rate_option(parser, "for --simulate")
    parser.add_argument("--workers", type=whole(minimum=1, maximum=256), default=2,
                        help="processes for --simulate (default 2)")
    parser.add_argument("--out", metavar="CSV", help="per-step table (recording, --simulate); segments, split and "
                        "budget go beside it (_segments.csv, _split.csv, _budget.csv)")
    parser.add_argument("--resamples", type=whole(minimum=1, maximum=1_000_000), default=2000,
                        help="bootstrap resamples of the subjects for --simulate's intervals (default 2000)")
    parser.add_argument("--k-file", metavar="K.json", help="per-subject constants for a recording (M4/M5 need it)")
    parser.add_argument("--lap-m", type=POSITIVE_M, default=20.0, metavar="M", help="distance between MARK flags (20)")
    add_anatomy_options(parser)
    add_input_options(parser)
    add_force_option(parser)
    add_json_option(parser)
    add_verbosity_options(parser)


def _beside(out: str, suffix: str) -> str:
    """The CSV written beside ``out``: ``<stem><suffix>.csv``."""
    p = Path(out)
    return str(p.with_name(p.stem + suffix + ".csv"))


def run(args: argparse.Namespace) -> int:
    if args.sweep:
        raise UsageError(f"--sweep: moved to gaitlog sweep; the same grid (ADC 8/10/12 bits x 25/50/100 Hz) is "
                         f"`{_sweep_command_line(args)}`")
    name = f"{input_stem(args.input)}_compare.csv" if args.input else "simulate.csv"
    args.out = out_path(args.out, name)
    if (args.input is None) == (args.simulate is None):
        raise UsageError("give exactly one of INPUT or --simulate N")
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    if args.input is None:
        extra = given_input_flags(args) + [f"--{n.replace('_', '-')}" for n in ("k_file", "leg_length", "foot_length",
                                                                                 "height") if getattr(args, n)]
        if extra:
            raise UsageError(f"{', '.join(extra)}: only for a recording INPUT, not with --simulate")
    elif args.logger_rate is not None:
        raise UsageError("--logger-rate: only with --simulate (a recording states its own rate)")
    elif args.population is not None:
        raise UsageError("--population: only with --simulate (a recording is its own walker)")
    args.population = args.population or "people"
    return _simulate(args) if args.simulate is not None else _recording(args)


def _sweep_command_line(args: argparse.Namespace) -> str:
    """The ``gaitlog sweep`` command line of what ``compare --sweep`` ran (its subjects, seed, population and
    workers; the results folder named after ``--out``)."""
    out = Path(args.out).with_suffix("") if args.out else Path("sweep-out")
    return (f"gaitlog sweep --out {out} --subjects {args.subjects} --seeds {args.seed} "
            f"--population {args.population or 'people'} --workers {args.workers}")


def _simulate(args: argparse.Namespace) -> int:
    if args.simulate < 1:
        raise UsageError(f"--simulate must be >= 1, got {args.simulate}")
    args.logger_rate = logger_rate_hz(args)
    if args.resamples < 1:
        raise UsageError(f"--resamples must be >= 1, got {args.resamples}")
    if args.out:
        check_outputs({"--out": args.out}, {}, force=args.force)
    from gaitlog.host.studies.compare_report import compare_simulated

    with progress_bar(args, args.simulate, "subject") as tick:
        report = compare_simulated(args.simulate, seed=args.seed, adc_bits=args.adc_bits,
                                   sampling_rate_hz=args.logger_rate, workers=args.workers,
                                   population=args.population, n_resamples=args.resamples, progress=tick)
    _print(args, report, ("_segments", "_split", "_budget"))
    return 0


def _recording(args: argparse.Namespace) -> int:
    p = Path(args.input)
    if args.out:
        check_outputs({"--out": args.out, "--out (_segments)": _beside(args.out, "_segments"),
                       "--out (_split)": _beside(args.out, "_split")},
                      {"INPUT": p, "--k-file": args.k_file, "--calibration": args.calibration}, force=args.force)
    data = read_input(args, p)
    from gaitlog.host.studies.compare_report import compare_input

    report = compare_input(data, p, calibration_file=args.calibration, k_file=args.k_file, lap_m=args.lap_m,
                           lengths_for=lambda k: lengths_from_args(args, k=k, data=data))
    _print(args, report, ("_segments", "_split"))
    if report.warning and verbosity(args) >= 0:
        print(f"gaitlog compare: warning: {report.warning}", file=sys.stderr)
    return 0


def _print(args: argparse.Namespace, report, suffixes: tuple[str, ...]) -> None:
    """The report's files (``--out`` and the ones beside it, named by ``suffixes``), its text (``-v``: with its
    detail lines) and, with ``--json``, its document."""
    written = [args.out] + [_beside(args.out, s) for s in suffixes] if args.out else []
    if written:
        report.write_outputs(*written)
    if verbosity(args) >= 0 and not args.json:
        print(report.format_table(verbosity(args)))
        if written:
            print(f"written: {', '.join(written)}")
    if args.json:
        print(report.to_json())
