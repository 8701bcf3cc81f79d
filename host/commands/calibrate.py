"""``gaitlog calibrate``: fit an accelerometer calibration to the static holds of a recording."""

from __future__ import annotations

import argparse
import io
import json
import sys
from pathlib import Path
from typing import Any

from gaitlog.host.commands._input_options import INPUT_HELP, add_input_options, read_input
from gaitlog.host.commands._options import (
    add_force_option,
    add_json_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    number,
    out_path,
    print_json,
    verbosity,
)
from gaitlog.host.errors import HostError, UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = "Fit offsets, scales and axis angles to the static poses of a recording (logger file, .npz or CSV); write JSON."
#: Shown under "examples:" by ``gaitlog calibrate --help``.
EXAMPLES = (
    "gaitlog calibrate poses.npz --out cal.json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``gaitlog calibrate``."""
    parser.add_argument("input", type=Path, metavar="INPUT", help=f"static poses: {INPUT_HELP}")
    parser.add_argument("--out", type=Path, required=True, metavar="CAL.json", help="calibration file to write")
    parser.add_argument("--model", choices=("9-param", "6-param"), default="9-param",
                        help="9-param: offsets, scales and 3 axis angles (default); 6-param: orthogonal axes")
    add_input_options(parser)
    parser.add_argument("--zero-counts", type=number(), metavar="C",
                        help="nominal 0 g code of a CSV in counts, for rest detection (default: estimated from the "
                             "holds)")
    parser.add_argument("--counts-per-g", type=number(above=0), metavar="K",
                        help="nominal counts per g of a CSV in counts, for rest detection (default: estimated)")
    add_force_option(parser)
    add_json_option(parser, "the fitted calibration")
    add_verbosity_options(parser)
    det = parser.add_argument_group("rest detection")
    det.add_argument("--hold", type=number(above=0, maximum=3600, unit="s"), default=3.0, metavar="S", help="minimum hold, seconds (default 3)")
    det.add_argument("--sd-factor", type=number(above=0, maximum=1000), default=1.3, metavar="F",
                     help="moving-SD threshold as a multiple of the noise floor (default 1.3)")
    det.add_argument("--min-angle", type=number(minimum=0, maximum=180, unit="deg"), default=10.0, metavar="DEG",
                     help="holds closer than this to a longer hold are near-duplicates (default 10)")


def _fmt(v: Any, spec: str = "+10.4f") -> str:
    return " ".join(format(float(x), spec) for x in v)


def run(args: argparse.Namespace) -> int:
    """Detect the static holds, fit the model, print a summary and write the JSON atomically."""
    from gaitlog.host.accelerometer.calibration import ANGLE_NAMES
    from gaitlog.host.accelerometer.fit import AccCalibrator

    args.out = out_path(args.out, f"{input_stem(args.input)}_cal.json")
    path: Path = args.input
    if args.calibration:
        raise UsageError("--calibration: calibrate fits a calibration; it does not take one")
    check_outputs({"--out": args.out}, {"INPUT": path}, force=args.force)
    data = read_input(args, path)
    zero: Any = args.zero_counts
    per_g: Any = args.counts_per_g
    valid_range = None
    rate = data.sampling_rate_hz
    if data.counts is not None:
        acc, unit = data.counts, "counts"
        if data.adc_bits is not None:
            span = 2 ** data.adc_bits
            zero = span / 2 if zero is None else zero
            per_g = span / 4 if per_g is None else per_g
            valid_range = (0.0, float(span - 1))
    else:
        acc, unit = data.g(), "g"
        if zero is not None or per_g is not None:
            raise HostError("--zero-counts / --counts-per-g: the input is acceleration in g, not counts")
        zero, per_g = 0.0, 1.0
    bits = f", {data.adc_bits}-bit" if data.adc_bits is not None else ""
    source = (f"{path} ({data.n_samples - data.n_missing} valid samples of {data.n_samples}, {rate:g} Hz, {unit}"
              f"{bits})")
    cal_run = AccCalibrator(model=args.model, hold_s=args.hold, sd_factor=args.sd_factor,
                            min_angle_deg=args.min_angle)
    cal_run.calibrate(acc, sampling_rate_hz=rate, input_unit=unit, zero=zero, unit_per_g=per_g,
                      valid_range=valid_range)
    cal = cal_run.calibration_
    det = cal_run.detector_
    out = sys.stdout if verbosity(args) >= 0 and not args.json else io.StringIO()
    print(f"input: {source}", file=out)
    print(f"static poses: {cal.n_poses} used, {len(det.rejected_)} holds rejected "
          f"(hold >= {args.hold:g} s, noise floor {_fmt(det.noise_floor_, '.3g')} {unit})", file=out)
    chi2 = "n/a" if cal.chi2_per_dof is None else f"{cal.chi2_per_dof:.3g}"
    print(f"model: {cal.model}; |a| - 1 g over the poses: rms {cal.residual_rms_g * 1e3:.3f} mg, "
          f"max {cal.residual_max_g * 1e3:.3f} mg; chi2/dof {chi2}; direction coverage "
          f"{cal.min_direction_sv:.3f} (0.577 ideal)", file=out)
    print(f"offset ({unit}):        {_fmt(cal.offset)}", file=out)
    print(f"scale ({unit} per g):   {_fmt(cal.scale_per_g)}", file=out)
    print("angles (deg):         " + "  ".join(f"{n} {a:+.4f}" for n, a in zip(ANGLE_NAMES, cal.angles_deg,
                                                                                 strict=True)), file=out)
    print(f"calibrated_g = M @ (raw - offset), M (g per {unit}):", file=out)
    for row in cal.matrix:
        print(f"    {_fmt(row, '+.8e')}", file=out)
    print(f"pose  samples          mean ({unit})                       |a|-1 (mg)", file=out)
    for i, (w, r) in enumerate(zip(cal_run.windows_, cal.pose_residuals_g, strict=True)):
        print(f"{i + 1:4d}  {w.start:>7d}-{w.stop:<7d}  {_fmt(w.mean, '+10.4f')}   {r * 1e3:+8.3f}", file=out)
    for w, reason in det.rejected_:
        print(f"rejected samples {w.start}-{w.stop}: {reason}", file=out)
    cal.save(args.out)
    print(f"wrote {args.out}", file=out)
    if args.json:                                  # the file as written, with the poses behind it
        print_json({"out": str(args.out), "calibration": json.loads(Path(args.out).read_text()),
                    "poses": [{"start_sample": w.start, "stop_sample": w.stop, "mean": w.mean, "residual_g": r}
                              for w, r in zip(cal_run.windows_, cal.pose_residuals_g, strict=True)],
                    "rejected": [{"start_sample": w.start, "stop_sample": w.stop, "reason": reason}
                                 for w, reason in det.rejected_]})
    return 0
