"""``gaitlog calibrate-k``: fit K (M1, M2, M4) and the M5 line from walking over a known distance."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gaitlog.host.commands._anatomy_options import add_anatomy_options, given_anatomy_flags, lengths_from_args
from gaitlog.host.commands._input_options import INPUT_HELP, add_input_options, read_input
from gaitlog.host.commands._options import (
    POSITIVE_M,
    add_force_option,
    add_json_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    out_path,
    print_json,
    verbosity,
)
from gaitlog.host.errors import UsageError

# The offline chain loads numpy and scipy: run imports it, so that `gaitlog --help` stays light
# (tests/host/commands/test_cli_startup.py).

HELP = "fit the per-subject constants K and the M5 line from recordings with a known distance"
#: Shown under "examples:" by ``gaitlog calibrate-k --help``.
EXAMPLES = (
    "gaitlog calibrate-k walk.npz --distance 40 --out K.json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help=f"recording(s): {INPUT_HELP}; several inputs = several speeds")
    how = parser.add_mutually_exclusive_group(required=True)
    how.add_argument("--distance", type=POSITIVE_M, action="append", metavar="M",
                     help="distance walked, m: once for all inputs, or repeated once per input in order")
    how.add_argument("--lap-marks", type=POSITIVE_M, metavar="M",
                     help="distance between consecutive MARK flags, m: every lap between marks is one section")
    parser.add_argument("--out", required=True, metavar="K.json", help="write the calibration here (JSON)")
    parser.add_argument("--subject", default="", help="label stored in the file")
    parser.add_argument("--prior", choices=("none", "lower-back"), default="none",
                        help="shrink K of M1, M2 and M4 toward a population K, the more the shorter the calibration "
                             "walk: 'lower-back' = learned on the IPOL lower-back subjects (logger at L3-L5; "
                             "'gaitlog evaluate ipol' scores it leave-one-subject-out); 'none' (default) = the "
                             "paper's K, fitted on these walks alone")
    add_anatomy_options(parser)
    add_input_options(parser)
    add_force_option(parser)
    add_json_option(parser, "the fitted calibration")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    args.out = out_path(args.out, f"{input_stem(args.inputs[0])}_K.json")
    if args.distance is not None and len(args.distance) not in (1, len(args.inputs)):
        raise UsageError(f"--distance: give one value or one per input ({len(args.inputs)}), "
                        f"got {len(args.distance)}")
    if args.lap_marks is not None and not args.lap_marks > 0:
        raise UsageError(f"--lap-marks must be a positive distance, got {args.lap_marks}")
    check_outputs({"--out": args.out}, {**{f"INPUT {i + 1}": path for i, path in enumerate(args.inputs)},
                                        "--calibration": args.calibration}, force=args.force)
    inputs = [read_input(args, path) for path in args.inputs]
    from gaitlog.host.gait.k_walks import fit_k_on_walks

    report = fit_k_on_walks(args.inputs, inputs, lengths_for=lambda data: lengths_from_args(args, data=data),
                            anatomy_given=bool(given_anatomy_flags(args)), distance_m=args.distance,
                            lap_m=args.lap_marks, subject=args.subject, prior=args.prior)
    report.k.save(args.out)
    if args.json:                                  # the file as written
        print_json({"out": str(args.out), "k": json.loads(Path(args.out).read_text()), "notes": report.notes})
    elif verbosity(args) >= 0:
        print(report.format_table())
        for note in report.warnings:
            print(f"gaitlog calibrate-k: warning: {note}", file=sys.stderr)
        print(f"written: {args.out}")
    return 0
