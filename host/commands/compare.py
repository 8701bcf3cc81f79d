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

from gaitlog.atomic_write import atomic_write_text
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
    print_json,
    printer,
    verbosity,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import HostError, UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

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
    from gaitlog.firmware_sim.algorithms.steps import columns_csv_text
    from gaitlog.host.studies.compare import (
        BUDGET_COLUMNS,
        bootstrap_budget,
        format_budget,
        format_segments,
        format_step_diffs,
        pool_step_diffs,
        pooled_step_columns,
        rows_csv_text,
    )
    from gaitlog.host.studies.simulation import simulate_comparisons

    if args.simulate < 1:
        raise UsageError(f"--simulate must be >= 1, got {args.simulate}")
    args.logger_rate = logger_rate_hz(args)
    if args.resamples < 1:
        raise UsageError(f"--resamples must be >= 1, got {args.resamples}")
    say, detail = printer(args), printer(args, 1)
    if args.out:
        check_outputs({"--out": args.out}, {}, force=args.force)
    with progress_bar(args, args.simulate, "subject") as tick:
        results = simulate_comparisons(args.simulate, seed=args.seed, adc_bits=args.adc_bits,
                                       sampling_rate_hz=args.logger_rate, workers=args.workers, progress=tick,
                                       population=args.population)
    say(f"{len(results)} simulated subject(s) ('{args.population}'), {args.adc_bits}-bit ADC at {args.logger_rate:g} Hz; one K per mode, "
        "fitted on the offline chain, used by every chain (multi-speed for the per-step rows)")
    for r in results:
        detail(f"  {r.subject_id}: {r.steps['step'].size} steps (offline chain), step durations off by "
               f"{r.timing['rms_ms']:.1f} ms rms; saturation/wrap: {r.saturation or 'none'}")
    all_diffs = [d | {"subject": r.subject_id} for r in results for d in r.step_diffs]
    say(format_step_diffs(pool_step_diffs(all_diffs)))
    say()
    say(format_segments(results))
    say()
    budget = bootstrap_budget(results, n_resamples=args.resamples, seed=args.seed)
    say(format_budget(budget, n_resamples=args.resamples, seed=args.seed))
    sat = [f"{r.subject_id}: {r.saturation}" for r in results if r.saturation]
    say("saturation/wrap in the fixed-point runs: " + ("; ".join(sat) if sat else "none"))
    if args.out:
        atomic_write_text(args.out, columns_csv_text(pooled_step_columns(results)))
        seg, split, bud = _beside(args.out, "_segments"), _beside(args.out, "_split"), _beside(args.out, "_budget")
        atomic_write_text(seg, rows_csv_text([s for r in results for s in r.segments]))
        atomic_write_text(split, rows_csv_text(all_diffs))
        atomic_write_text(bud, rows_csv_text(budget, BUDGET_COLUMNS))
        say(f"written: {args.out}, {seg}, {split}, {bud}")
    if args.json:
        print_json({"step_differences": pool_step_diffs(all_diffs),
                    "segments": [s for r in results for s in r.segments],
                    "budget": budget, "saturation": {r.subject_id: r.saturation for r in results}})
    return 0


def _recording(args: argparse.Namespace) -> int:
    import numpy as np

    from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, columns_csv_text
    from gaitlog.host.files.replay import run_starts, verify_step_records
    from gaitlog.host.gait.k_calibration import KFit
    from gaitlog.host.studies.compare import compare_recording, format_step_diffs, rows_csv_text

    say = printer(args)
    p = Path(args.input)
    if args.out:
        check_outputs({"--out": args.out, "--out (_segments)": _beside(args.out, "_segments"),
                       "--out (_split)": _beside(args.out, "_split")},
                      {"INPUT": p, "--k-file": args.k_file, "--calibration": args.calibration}, force=args.force)
    data = read_input(args, p)
    rec = data.recording
    if rec is None:
        raise HostError(f"{p}: compare runs the on-line algorithm on ADC codes: give a logger recording (memory "
                        "image, raw dump, wire capture or decoded .npz), not acceleration in g")
    # the device's own records first: a device that does not compute what the host replays is an error
    check = verify_step_records(rec)
    if check is not None and check.differs:
        raise HostError(check.error_message(p))
    cal, note = rec.default_calibration()
    if args.calibration:
        from gaitlog.host.accelerometer.calibration import AccCalibration

        acc_cal = AccCalibration.load(args.calibration)
        try:
            cal = acc_cal.to_header_calibration()
        except HostError as err:
            raise HostError(f"{args.calibration}: {err}") from None
        note = f"g from {args.calibration}"
    k = KFit.load(args.k_file) if args.k_file else None
    lengths = lengths_from_args(args, k=k, data=data)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    flags = np.asarray(rec.flags)
    marks = data.mark_index
    starts = run_starts(rec.valid, flags)
    t = rec.time_s
    res = compare_recording(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=leg,
                            foot_length_m=foot, adc_calibration=cal, adc_bits=int(rec.adc_bits), valid=rec.valid,
                            calibration=k, mark_times_s=t[marks] if marks.size >= 2 else None, lap_m=args.lap_m,
                            t0_s=float(t[0]) if t.size else 0.0, run_starts=starts)
    say(f"{p}: {rec.n_samples} samples at {rec.sampling_rate_hz:g} Hz ({rec.n_missing} missing); {note}")
    say(check.summary() if check is not None else "device step records: none in this recording")
    printer(args, 1)(f"{starts.size} run(s) of contiguous samples (the on-line algorithm restarts after each gap), "
                     f"{marks.size} MARK flag(s)")
    say(f"leg length {leg:.3f} m, foot length {foot:.3f} m"
        + (f" ({lengths.note})" if lengths.note and not lengths.assumed else "") + "; K file: {args.k_file or 'none (K = 1, M4/M5 n/a)'}"
          " (the same K for every chain)")
    tb = res.tables
    say("steps: " + ", ".join(f"{c} {tb[c].n_steps}" for c in tb) + "; " + "; ".join(
        f"{s}: matched {m.n_matched}, different events {int(np.count_nonzero(~m.same_events))}, "
        f"found by one chain only {m.only_a.size + m.only_b.size}" for s, m in res.matches.items()))
    say(format_step_diffs(res.step_diffs))
    say(f"segments: {res.segment_source}; alg = online-float - offline, arith = online-fixed - online-float")
    say(f"{'seg':>4}{'t0 s':>8}{'t1 s':>8}" + "".join(f"{e + ' offline m':>13}{'alg mm':>9}{'arith mm':>9}"
                                                    for e in ESTIMATORS))
    for i in sorted({r["section"] for r in res.segments}):
        rs = {r["estimator"]: r for r in res.segments if r["section"] == i}
        r0 = rs["M1"]
        say(f"{i:>4}{r0['t_start_s']:>8.1f}{r0['t_end_s']:>8.1f}" + "".join(
            f"{rs[e]['offline_m']:>13.3f}{1e3 * rs[e]['algorithm_m']:>9.2f}{1e3 * rs[e]['arithmetic_m']:>9.2f}"
            for e in ESTIMATORS))
    say(f"saturation/wrap in the fixed-point run: {res.saturation or 'none'}; "
        f"PIC cycles per sample {res.cycles_per_sample:.0f} (mean)")
    if lengths.assumed and verbosity(args) >= 0:
        print(f"gaitlog compare: warning: {lengths.note}", file=sys.stderr)
    if args.out:
        atomic_write_text(args.out, columns_csv_text(res.steps))
        seg, split = _beside(args.out, "_segments"), _beside(args.out, "_split")
        atomic_write_text(seg, rows_csv_text(res.segments))
        atomic_write_text(split, rows_csv_text(res.step_diffs))
        say(f"written: {args.out}, {seg}, {split}")
    if args.json:
        print_json({"input": str(p), "steps": {c: t.n_steps for c, t in tb.items()}, "step_differences": res.step_diffs,
                    "segments": res.segments, "saturation": res.saturation, "cycles_per_sample": res.cycles_per_sample})
    return 0
