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
from gaitlog.host.errors import HostError, UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

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
    from gaitlog.host.gait.k_calibration import calibrate
    from gaitlog.host.gait.k_prior import PRIORS
    from gaitlog.host.gait.pipeline import StepPipeline
    from gaitlog.host.gait.sections import pool_steps, sections_from_marks

    args.out = out_path(args.out, f"{input_stem(args.inputs[0])}_K.json")
    if args.distance is not None and len(args.distance) not in (1, len(args.inputs)):
        raise UsageError(f"--distance: give one value or one per input ({len(args.inputs)}), "
                        f"got {len(args.distance)}")
    if args.lap_marks is not None and not args.lap_marks > 0:
        raise UsageError(f"--lap-marks must be a positive distance, got {args.lap_marks}")
    check_outputs({"--out": args.out}, {**{f"INPUT {i + 1}": path for i, path in enumerate(args.inputs)},
                                        "--calibration": args.calibration}, force=args.force)
    inputs = [read_input(args, path) for path in args.inputs]
    heights = {d.ipol_trial.height_m for d in inputs if d.ipol_trial is not None and d.ipol_trial.height_m}
    if len(heights) > 1 and not given_anatomy_flags(args):
        raise HostError(f"the inputs are IPOL trials of subjects of different heights ("
                        f"{', '.join(f'{h:.2f}' for h in sorted(heights))} m) and K is per subject; give --height")
    configs = {(c.leg_length_m, c.foot_length_m) for c in (d.recording.step_config for d in inputs
                                                           if d.recording is not None) if c is not None and c.step_format}
    if len(configs) > 1 and not given_anatomy_flags(args):
        raise HostError("the inputs are logger recordings with different leg/foot lengths in their step "
                        "configurations and K is per subject; give --height (or --leg-length and --foot-length)")
    described = [d for d in inputs if d.ipol_trial is not None] + [d for d in inputs if d.recording is not None]
    lengths = lengths_from_args(args, data=described[0] if described else None)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    notes = [lengths.note] if lengths.assumed else []
    sections = []
    for i, (path, data) in enumerate(zip(args.inputs, inputs)):
        pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
            data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
        steps = pipe.steps_
        notes += [f"{path}: {n}" for n in pipe.notes_]
        if args.distance is not None:
            dist = args.distance[0] if len(args.distance) == 1 else args.distance[i]
            sections.append((steps, float(dist)))
            continue
        marks = data.mark_index
        if marks.size < 2:
            raise HostError(f"{path}: --lap-marks needs at least two MARK flags, found {marks.size}")
        laps = sections_from_marks(steps.time_s(marks), lap_m=float(args.lap_marks),
                                   sampling_rate_hz=data.sampling_rate_hz)
        sections += [pool for pool in (pool_steps(steps, [lap]) for lap in laps) if pool[0].n_steps]
    k = calibrate(sections, leg_length_m=leg, foot_length_m=foot, subject=args.subject)
    if args.prior != "none":
        k = PRIORS[args.prior].shrink(k)
    k.save(args.out)
    if args.json:                                  # the file as written
        print_json({"out": str(args.out), "k": json.loads(Path(args.out).read_text()), "notes": notes})
    elif verbosity(args) >= 0:
        print(f"{len(sections)} section(s), {k.n_steps} steps, {k.distance_m:g} m ({k.mode}); leg length "
              f"{leg:.3f} m, foot length {foot:.3f} m, from: {lengths.source}" + (f" ({lengths.note})" if lengths.note and not lengths.assumed
                                                          else ""))
        print(f"K  M1 {k.k_m1:.4f}  M2 {k.k_m2:.4f}  M4 {k.k_m4:.4f} m/(m/s^2)^{k.m4_exponent:g}")
        if k.shrinkage is not None:
            sh = k.shrinkage
            print(f"   shrunk toward the population K ({sh['source']}): fitted " + ", ".join(
                f"{e} {sh['fitted'][e]:.4f} (weight {sh['weight'][e]:.2f}), population {sh['population'][e]:.4f}"
                for e in sh["fitted"]))
        print(f"M5 S = {k.k1_m5_m_s:.4f} / T + {k.k2_m5_m:.4f} m"
              + ("  (walk-ratio fallback)" if k.m5_fallback else ""))
        print(f"K {k.describe_range()} (stored: 'gaitlog estimate' flags the steps outside it)")
        for note in notes + list(k.notes):
            print(f"gaitlog calibrate-k: warning: {note}", file=sys.stderr)
        print(f"written: {args.out}")
    return 0
