"""``gaitlog plot``: a recording's acceleration, gaps, lap marks, gait events and per-step lengths as a PNG."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from gaitlog.host.commands._anatomy_options import add_anatomy_options, lengths_from_args
from gaitlog.host.commands._options import (
    add_force_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    number,
    out_path,
    printer,
)
from gaitlog.host.errors import HostError, UsageError

# The overview loads numpy, scipy and matplotlib: run imports it, so that `gaitlog --help` stays light
# (tests/host/commands/test_cli_startup.py).

HELP = ("draw a recording's acceleration (gaps shaded, lap marks), the detected gait events and each step's "
        "length per estimator to a PNG")
#: Shown under "examples:" by ``gaitlog plot --help``.
EXAMPLES = (
    "gaitlog plot walk.npz --out walk.png",
    "gaitlog plot walk.npz --start 10 --duration 5 --estimators M1,M5",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="RECORDING",
                        help="decoded recording (.npz from 'gaitlog decode') or a memory image / dump it decodes")
    parser.add_argument("--out", metavar="PNG", help="the figure (default: RECORDING with .png)")
    parser.add_argument("--start", type=number(minimum=0, unit="s"), default=0.0, metavar="S",
                        help="start of the window, s since the first sample (default 0)")
    parser.add_argument("--duration", type=number(above=0, unit="s"), metavar="S", help="length of the window, s (default: to the end)")
    parser.add_argument("--estimators", default="M1,M2,M3,M4,M5", metavar="LIST",
                        help="step-length estimators to draw, comma-separated (default M1,M2,M3,M4,M5; M4/M5 "
                        "need --k-file or a device that had K)")
    parser.add_argument("--k-file", metavar="K.json", help="per-subject constants from 'gaitlog calibrate-k'")
    parser.add_argument("--size", default="1400x700", metavar="WxH", help="figure size in pixels (default 1400x700)")
    add_anatomy_options(parser)
    add_force_option(parser)
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.plots import ESTIMATORS, plot_recording

    src = Path(args.input)
    out = Path(out_path(args.out, f"{input_stem(src)}.png") or src.with_suffix(".png"))
    size = re.fullmatch(r"(\d+)x(\d+)", args.size)
    if not size or not (100 <= int(size[1]) <= 10000 and 100 <= int(size[2]) <= 10000):
        raise UsageError(f"--size {args.size}: give WIDTHxHEIGHT in pixels, 100 to 10000 each (e.g. 1400x700)")
    estimators = [e.strip().upper() for e in args.estimators.split(",") if e.strip()]
    unknown = [e for e in estimators if e not in ESTIMATORS]
    if unknown or not estimators:
        raise UsageError(f"--estimators {args.estimators!r}: unknown {', '.join(unknown) or '(none given)'}; choose "
                         f"from {','.join(ESTIMATORS)}")
    check_outputs({"--out": out}, {"RECORDING": src, "--k-file": args.k_file}, force=args.force)
    if not src.is_file():
        raise HostError(f"{src}: no such file")
    line = plot_recording(src, out, k_file=args.k_file, lengths_for=lambda k, data: lengths_from_args(args, k=k, data=data),
                          start_s=args.start, duration_s=args.duration, estimators=estimators,
                          size_px=(int(size[1]), int(size[2])))
    printer(args)(line)
    return 0
