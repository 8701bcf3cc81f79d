"""``gaitlog estimate``: a recording (any input) -> per-step table CSV and the distance per estimator.

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

from gaitlog.atomic_write import atomic_write_text
from gaitlog.host.commands._anatomy_options import add_anatomy_options, lengths_from_args
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
    from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
    from gaitlog.host.gait.anthropometry import LENGTH_MODEL
    from gaitlog.host.gait.k_calibration import KFit

    args.out = out_path(args.out, f"{input_stem(args.input)}_steps.csv")
    if args.out:
        out = Path(args.out)
        fixed = {"--out (_fixed)": out.with_name(out.stem + "_fixed.csv")} if args.arithmetic == "both" else {}
        check_outputs({"--out": out, **fixed},
                      {"INPUT": args.input, "--k-file": args.k_file, "--calibration": args.calibration},
                      force=args.force)
    data = read_input(args, args.input)
    from gaitlog.host.files.inputs import input_losses

    losses = input_losses(data)
    over = losses.above(args.max_missing)
    if args.arithmetic != "float" and data.recording is None:
        raise HostError(f"{args.input}: --arithmetic {args.arithmetic} needs ADC codes: give a logger file or a "
                        "decoded recording (.npz from 'gaitlog decode'), not acceleration in g")
    k = KFit.load(args.k_file) if args.k_file else None
    lengths = lengths_from_args(args, k=k, data=data)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    notes = [lengths.note] if lengths.assumed else []
    tables = {}
    fixed_report = ""
    if args.arithmetic in ("float", "both"):
        from gaitlog.host.gait.pipeline import StepPipeline

        pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot, calibration=k).run(
            data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
        tables["float"] = pipe.steps_
        notes += pipe.notes_
    if args.arithmetic in ("fixed", "both"):
        tables["fixed"], fixed_report = _fixed_steps(data, args.calibration, leg, foot, k)
    outs = {}
    if args.out:
        out = Path(args.out)
        first = next(iter(tables))
        outs[first] = out
        if len(tables) == 2:
            outs["fixed"] = out.with_name(out.stem + "_fixed.csv")
        written = []
        try:                                  # both tables or neither (each file is itself atomic)
            for arith, path in outs.items():
                atomic_write_text(path, _csv_text(tables[arith], lengths.source, k))
                written.append(path)
        except BaseException:
            for path in written:
                path.unlink(missing_ok=True)
            raise
    summary = _summary(tables, ESTIMATORS, k)
    for arith, s in summary.items():        # K extrapolated: said on stderr too, not only in the column
        out_k = {e: v["steps_outside_k_range"] for e, v in s["estimators"].items() if v["steps_outside_k_range"]}
        if out_k:
            notes.append(f"{'fixed point: ' if arith == 'fixed' else ''}steps outside the range K was calibrated on "
                         f"(K extrapolated; column outside_k_range): " + ", ".join(
                             f"{e} {n} of {s['n_steps']}" for e, n in out_k.items()))
    if args.json:
        doc = {"input": str(args.input), "source": data.source, "n_samples": data.n_samples,
               "n_missing": data.n_missing, "sampling_rate_hz": data.sampling_rate_hz, "leg_length_m": leg,
               "foot_length_m": foot, "lengths_from": lengths.note, "lengths_source": lengths.source,
               "height_known": not lengths.assumed, "length_model": LENGTH_MODEL, "k_file": args.k_file,
               "k_calibrated_range": k.calibrated_range if k is not None else None, "arithmetic": summary,
               "fixed_point_saturation": fixed_report if "fixed" in tables else None,
               "per_step_tables": {a: str(p) for a, p in outs.items()}, "notes": notes,
               "missing_percent": round(losses.percent, 3), "max_missing_percent": args.max_missing,
               "above_max_missing": over}
        print(json.dumps(doc, indent=2, allow_nan=False))
    elif verbosity(args) >= 0:
        print(f"{args.input}: {data.n_samples} samples at {data.sampling_rate_hz:g} Hz "
              f"({data.n_missing} missing, {losses.percent:.1f} %"
              + (f", above --max-missing {args.max_missing:g} %" if over else "") + f"); {data.source}")
        print(f"leg length {leg:.3f} m, foot length {foot:.3f} m, from: {lengths.source}"
              + (f" ({lengths.note})" if lengths.note and not lengths.assumed else "")
              + f"; K file: {args.k_file or 'none'}")
        if lengths.source in ("height", "subject-height", "assumed-height"):
            print(f"length model: {LENGTH_MODEL}")
        if k is not None:
            print(f"K {k.describe_range()}")
        for arith, s in summary.items():
            print((f"arithmetic = {arith}: " if args.arithmetic != "float" else "")
                  + f"{s['n_steps']} steps in {s['n_bouts']} walking bout(s)"
                  + (" (the on-line algorithm in fixed point)" if arith == "fixed" else "")
                  + (f"; fixed-point saturation/wrap: {fixed_report or 'none'}" if arith == "fixed" else ""))
            print(f"{'estimator':<10}{'distance_m':>12}{'median_step_m':>15}{'steps_filled':>14}"
                  + (f"{'outside_K_range':>16}" if k is not None else ""))
            for name, e in s["estimators"].items():
                dtxt = "n/a" if e["distance_m"] is None else f"{e['distance_m']:.2f}"
                mtxt = "n/a" if e["median_step_m"] is None else f"{e['median_step_m']:.3f}"
                out_k = "" if e["steps_outside_k_range"] is None else f"{e['steps_outside_k_range']:>16}"
                print(f"{name:<10}{dtxt:>12}{mtxt:>15}{e['steps_filled']:>14}{out_k}")
            if verbosity(args) > 0:                 # -v: how many steps had each gait event found
                print("events: " + ", ".join(f"{k} {v}" for k, v in tables[arith].event_counts().items()))
        if outs:
            print("per-step table: " + ", ".join(f"{p} ({a})" if len(outs) > 1 else str(p) for a, p in outs.items()))
    if verbosity(args) >= 0:
        for note in notes:
            print(f"gaitlog estimate: warning: {note}", file=sys.stderr)
    if over:
        raise HostError(losses.limit_text(args.max_missing) + ("; the results above are printed and "
                        + (f"{', '.join(str(p) for p in outs.values())} written " if outs else "")
                        + "all the same, from the samples there are"))
    return 0


def _csv_text(table, lengths_source: str, k) -> str:
    """The step table's CSV with ``lengths_source`` and ``outside_k_range`` (module notes)."""
    from gaitlog.firmware_sim.algorithms.steps import columns_csv_text
    from gaitlog.host.gait.k_calibration import RANGE_QUANTITIES

    n = table.n_steps
    if k is not None:
        out = k.outside_range(table)
        flags = ["+".join(q for q in RANGE_QUANTITIES if out[q][i]) for i in range(n)]
    else:
        flags = [""] * n
    return columns_csv_text({**table.columns(), "lengths_source": [lengths_source] * n, "outside_k_range": flags})


def _summary(tables: dict, estimators: tuple[str, ...], k=None) -> dict[str, dict]:
    """Per arithmetic: steps, bouts and per estimator distance / median step / filled steps / steps outside
    K's calibrated range (None for n/a)."""
    import numpy as np

    out: dict[str, dict] = {}
    for arith, steps in tables.items():
        outside = k.outside_range(steps) if k is not None and k.calibrated_range is not None else None
        est = {}
        for name in estimators:
            d, filled = steps.distance_m(name)
            lengths = steps.length_m[name]
            med = float(np.nanmedian(lengths)) if np.isfinite(lengths).any() else float("nan")
            est[name] = {"distance_m": float(d) if np.isfinite(d) else None,
                         "median_step_m": med if np.isfinite(med) else None, "steps_filled": int(filled),
                         "steps_outside_k_range": int(outside[name].sum()) if outside is not None and name in outside
                         else None}
        out[arith] = {"n_steps": int(steps.n_steps),
                      "steps_outside_k_range": int(outside["any"].sum()) if outside is not None else None,
                      "n_bouts": int(np.unique(steps.bout).size) if steps.n_steps else 0, "estimators": est}
    return out


def _fixed_steps(data, calibration: str | None, leg: float, foot: float, k):
    """The on-line algorithm in fixed point (the logger's) on the codes of a logger recording, with the same
    K as the float chain -> (StepTable, saturation report)."""
    import numpy as np

    from gaitlog.host.files.replay import online_step_table, run_starts

    rec = data.recording
    adc_cal = rec.default_calibration()[0]
    if calibration:
        from gaitlog.host.accelerometer.calibration import AccCalibration

        try:
            adc_cal = AccCalibration.load(calibration).to_header_calibration()
        except HostError as err:
            raise HostError(f"{calibration}: {err}") from None
    valid = np.asarray(rec.valid, bool)
    starts = run_starts(valid, rec.flags)
    table, alg = online_step_table(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=leg,
                                   foot_length_m=foot, calibration=k, adc_calibration=adc_cal,
                                   adc_bits=int(rec.adc_bits), arithmetic="fixed", valid=valid, run_starts=starts)
    return table, alg.arithmetic_context().report()
