"""``gaitlog estimate``: a decoded recording (or CSV) -> per-step table CSV and the distance per estimator."""

from __future__ import annotations

import argparse

HELP = "estimate every step's length and the distance walked (M1-M5) from a decoded recording or CSV"


def configure(parser: argparse.ArgumentParser) -> None:
    from host.commands._gait_input import add_anatomy_options

    parser.add_argument("input", metavar="INPUT", help="decoded recording (.npz from 'gaitlog decode') or CSV in g")
    parser.add_argument("--out", metavar="STEPS.csv", help="write the per-step table here")
    parser.add_argument("--k-file", metavar="K.json", help="per-subject constants from 'gaitlog calibrate-k' "
                        "(without it M1/M2 use K = 1 and M4/M5 are not computed)")
    parser.add_argument("--arithmetic", choices=["float", "fixed", "both"], default="float",
                        help="float: the offline host chain (default); fixed: the logger's on-line algorithm in "
                        "the PIC's fixed point on the ADC codes (a decoded .npz input); both (the fixed table goes "
                        "to <out>_fixed.csv); the same K for both")
    add_anatomy_options(parser)


def run(args: argparse.Namespace) -> int:
    import warnings

    import numpy as np

    from firmware_sim.algorithms.steps import ESTIMATORS
    from host.commands._gait_input import load_input
    from host.gait.anthropometry import anatomical_lengths
    from host.gait.k_calibration import KCalibration
    from host.gait.pipeline import StepPipeline

    data = load_input(args.input, rate_hz=args.rate, calibration=args.calibration)
    cal = KCalibration.load(args.k_file) if args.k_file else None
    leg_arg, foot_arg = args.leg_length, args.foot_length
    if cal is not None and leg_arg is None and args.height is None:
        leg_arg = cal.leg_length_m
    if cal is not None and foot_arg is None and args.height is None:
        foot_arg = cal.foot_length_m
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        leg, foot = anatomical_lengths(leg_length_m=leg_arg, foot_length_m=foot_arg, height_m=args.height)
        pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot, calibration=cal).run(
            data.acc_g, sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
    steps = pipe.steps_
    tables = {"float": steps}
    fixed_report = ""
    if args.arithmetic != "float":
        tables["fixed"], fixed_report = _fixed_steps(args, leg, foot, cal)
        if args.arithmetic == "fixed":
            tables.pop("float")
            steps = tables["fixed"]
    fixed_out = None
    if args.out:
        from pathlib import Path

        steps.to_csv(args.out)
        if len(tables) == 2:
            fixed_out = Path(args.out).with_name(Path(args.out).stem + "_fixed.csv")
            tables["fixed"].to_csv(fixed_out)
    print(f"{args.input}: {data.acc_g.shape[0]} samples at {data.sampling_rate_hz:g} Hz "
          f"({int((~data.valid).sum())} missing); {data.note}")
    print(f"leg length {leg:.3f} m, foot length {foot:.3f} m; K file: {args.k_file or 'none'}")
    for arith, steps in tables.items():
        n_bouts = int(np.unique(steps.bout).size) if steps.n_steps else 0
        print((f"arithmetic = {arith}: " if args.arithmetic != "float" else "")
              + f"{steps.n_steps} steps in {n_bouts} walking bout(s)"
              + (" (the on-line algorithm in fixed point)" if arith == "fixed" else "")
              + (f"; fixed-point saturation/wrap: {fixed_report or 'none'}" if arith == "fixed" else ""))
        print(f"{'estimator':<10}{'distance_m':>12}{'median_step_m':>15}{'steps_filled':>14}")
        for name in ESTIMATORS:
            d, filled = steps.distance_m(name)
            med = (float(np.nanmedian(steps.length_m[name])) if np.isfinite(steps.length_m[name]).any()
                   else float("nan"))
            dtxt = f"{d:.2f}" if np.isfinite(d) else "n/a"
            mtxt = f"{med:.3f}" if np.isfinite(med) else "n/a"
            print(f"{name:<10}{dtxt:>12}{mtxt:>15}{filled:>14}")
    for c in caught:
        print(f"warning: {c.message}")
    if args.out:
        print(f"per-step table: {args.out}" + (f" (float), {fixed_out} (fixed)" if fixed_out else ""))
    return 0


def _fixed_steps(args: argparse.Namespace, leg: float, foot: float, cal):
    """The on-line algorithm in fixed point (the logger's) on the codes of a decoded recording, with the same
    K as the float chain -> (StepTable, saturation report)."""
    from pathlib import Path

    import numpy as np

    from host.errors import HostError
    from host.files.recording import Recording
    from host.files.replay import run_starts
    from host.studies.compare import online_step_table

    if Path(args.input).suffix.lower() != ".npz":
        raise HostError(f"{args.input}: --arithmetic {args.arithmetic} needs ADC codes: give a decoded recording "
                        "(.npz from 'gaitlog decode'), not acceleration in g")
    rec = Recording.load(args.input)
    adc_cal = rec.default_calibration()[0]
    if args.calibration:
        from host.accelerometer.calibration import AccCalibration

        acc_cal = AccCalibration.load(args.calibration)
        try:
            adc_cal = acc_cal.to_header_calibration()
        except HostError as err:
            raise HostError(f"{args.calibration}: {err}") from None
    valid = np.asarray(rec.valid, bool)
    starts = run_starts(valid, rec.flags)
    table, alg = online_step_table(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=leg,
                                   foot_length_m=foot, calibration=cal, adc_calibration=adc_cal,
                                   code_bits=int(rec.adc_bits), arithmetic="fixed", valid=valid, run_starts=starts)
    return table, alg.arithmetic_context().report()
