"""``gaitlog estimate``: a recording (any input) -> per-step table CSV and the distance per estimator
(:func:`gaitlog.host.studies.estimate.estimate_recording`, in bounded memory).

Beside the step table's own columns, the CSV says where the leg and foot length came from
(``lengths_source``: :data:`gaitlog.host.gait.anthropometry.LENGTH_SOURCES`; ``assumed-height`` when nothing about the
wearer was known, also warned on stderr) and, with a K file, which of the step's quantities lie outside the
range K was calibrated on (``outside_k_range``: names from :data:`gaitlog.host.gait.k_calibration.RANGE_QUANTITIES`
joined by ``+``, empty when inside; :meth:`gaitlog.host.gait.k_calibration.KFit.outside_range`); the summary counts
those steps per estimator.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gaitlog.host.commands._anatomy_options import add_anatomy_options, k_fit_from_args, lengths_from_args
from gaitlog.host.commands._input_options import INPUT_HELP, add_input_options, read_input
from gaitlog.host.commands._options import (
    add_force_option,
    add_max_missing_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    out_path,
    verbosity,
)
from gaitlog.host.errors import HostError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = "estimate every step's length and the distance walked (M1-M5) from a recording (logger file, .npz, IPOL, CSV)"
#: Shown under "examples:" by ``gaitlog estimate --help``.
EXAMPLES = (
    "gaitlog estimate walk.npz --height 1.75",
    "gaitlog estimate walk.npz --k-file K.json --out steps.csv --arithmetic both",
    "gaitlog estimate walk.npz --json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help=INPUT_HELP)
    parser.add_argument("--out", metavar="STEPS.csv", help="write the per-step table here")
    parser.add_argument("--k-file", metavar="K.json", help="per-subject constants from 'gaitlog calibrate-k' "
                        "(without it M1/M2 use K = 1 and M4/M5 are not computed)")
    parser.add_argument("--arithmetic", choices=["float", "fixed", "both"], default="float",
                        help="float: the offline host chain (default); fixed: the logger's on-line algorithm in "
                        "the PIC's fixed point on the ADC codes (a logger file or .npz input); both (the fixed table "
                        "goes to <out>_fixed.csv); the same K for both")
    parser.add_argument("--json", action="store_true",
                        help="print the summary as one JSON document on stdout instead of the table")
    add_anatomy_options(parser)
    add_input_options(parser)
    add_max_missing_option(parser)
    add_force_option(parser)
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.estimate import estimate_recording

    args.out = out_path(args.out, f"{input_stem(args.input)}_steps.csv")
    outs = {}
    if args.out:
        out = Path(args.out)
        outs = {"float" if args.arithmetic != "fixed" else "fixed": out}
        if args.arithmetic == "both":
            outs["fixed"] = out.with_name(out.stem + "_fixed.csv")
        check_outputs({"--out": out, **({"--out (_fixed)": outs["fixed"]} if len(outs) == 2 else {})},
                      {"INPUT": args.input, "--k-file": args.k_file, "--calibration": args.calibration},
                      force=args.force)
    data = read_input(args, args.input, arrays=False)
    k = k_fit_from_args(args)
    result = estimate_recording(data, arithmetic=args.arithmetic, k=k, adc_calibration_file=args.calibration,
                                lengths=lengths_from_args(args, k=k, data=data), input_name=args.input)
    if outs:
        result.write(outs)
    if args.json:
        print(json.dumps(result.document(args.input, args.k_file, outs, args.max_missing), indent=2,
                         allow_nan=False))
    elif verbosity(args) >= 0:
        _print(args, result, outs)
    if verbosity(args) >= 0:
        for note in result.notes:
            print(f"gaitlog estimate: warning: {note}", file=sys.stderr)
    if result.losses.above(args.max_missing):
        raise HostError(result.losses.limit_text(args.max_missing) + ("; the results above are printed and "
                        + (f"{', '.join(str(p) for p in outs.values())} written " if outs else "")
                        + "all the same, from the samples there are"))
    return 0


def _print(args: argparse.Namespace, result, outs: dict) -> None:
    """The text report: input, lengths, K, and per arithmetic the estimators' table."""
    from gaitlog.host.gait.anthropometry import LENGTH_MODEL

    data, lengths, losses, k = result.data, result.lengths, result.losses, result.k
    over = losses.above(args.max_missing)
    print(f"{args.input}: {data.n_samples} samples at {data.sampling_rate_hz:g} Hz "
          f"({data.n_missing} missing, {losses.percent:.1f} %"
          + (f", above --max-missing {args.max_missing:g} %" if over else "") + f"); {data.source}")
    print(f"leg length {lengths.leg_length_m:.3f} m, foot length {lengths.foot_length_m:.3f} m, from: "
          f"{lengths.source}" + (f" ({lengths.note})" if lengths.note and not lengths.assumed else "")
          + f"; K file: {args.k_file or 'none'}")
    if lengths.source in ("height", "subject-height", "assumed-height"):
        print(f"length model: {LENGTH_MODEL}")
    if k is not None:
        print(f"K {k.describe_range()}")
    for arith, s in result.summary.items():
        _print_arithmetic(args, result, arith, s)
    if outs:
        print("per-step table: " + ", ".join(f"{p} ({a})" if len(outs) > 1 else str(p) for a, p in outs.items()))


def _print_arithmetic(args: argparse.Namespace, result, arith: str, s: dict) -> None:
    """One arithmetic's lines of the text report."""
    fixed = arith == "fixed"
    print((f"arithmetic = {arith}: " if args.arithmetic != "float" else "")
          + f"{s['n_steps']} steps in {s['n_bouts']} walking bout(s)"
          + (" (the on-line algorithm in fixed point)" if fixed else "")
          + (f"; fixed-point saturation/wrap: {result.fixed_report or 'none'}" if fixed else ""))
    print(f"{'estimator':<10}{'distance_m':>12}{'median_step_m':>15}{'steps_filled':>14}"
          + (f"{'outside_K_range':>16}" if result.k is not None else ""))
    for name, e in s["estimators"].items():
        dtxt = "n/a" if e["distance_m"] is None else f"{e['distance_m']:.2f}"
        mtxt = "n/a" if e["median_step_m"] is None else f"{e['median_step_m']:.3f}"
        out_k = "" if e["steps_outside_k_range"] is None else f"{e['steps_outside_k_range']:>16}"
        print(f"{name:<10}{dtxt:>12}{mtxt:>15}{e['steps_filled']:>14}{out_k}")
    if verbosity(args) > 0:                 # -v: how many steps had each gait event found
        print("events: " + ", ".join(f"{k} {v}" for k, v in result.tables[arith].event_counts().items()))
