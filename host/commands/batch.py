"""``gaitlog batch``: decode, calibrate and estimate every recording in a folder (:mod:`gaitlog.host.studies.batch`).

Per recording: ``OUT/NAME.steps.csv`` and ``OUT/NAME.json`` (its summary); for the batch: ``OUT/batch.csv`` (one
row per recording, failures included with their error). A file that fails is listed and the batch goes on;
the exit code is 1 when any recording failed. A re-run skips the recordings already finished with the same
input and settings, and retries the failed ones.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

from gaitlog.host.commands._anatomy_options import add_anatomy_options, k_fit_from_args, lengths_from_args
from gaitlog.host.commands._options import (
    add_json_option,
    add_max_missing_option,
    add_verbosity_options,
    check_output_folder,
    print_json,
    printer,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import HostError, UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib, and of
# the few standard modules that `gaitlog --help` does without (tempfile, dataclasses): it imports every
# command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = "estimate every recording in a folder (per-recording outputs, summary table, failures listed; resumable)"
#: Shown under "examples:" by ``gaitlog batch --help``.
EXAMPLES = (
    "gaitlog batch recordings/ --out results/ --k-file K.json",
    "gaitlog batch recordings/ --out results/ --workers 4",
    "gaitlog batch recordings/ --out results/ --scheduler scheduler.json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", metavar="FOLDER", help="folder of memory images, raw dumps, wire captures or "
                        "decoded .npz files")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    parser.add_argument("--pattern", default="*", help="file-name pattern of the inputs (default: every file but "
                        ".json/.csv/.txt/.md)")
    parser.add_argument("--calibration", metavar="CAL.json",
                        help="accelerometer calibration (from 'gaitlog calibrate') for every recording "
                             "(default: each file's own)")
    parser.add_argument("--k-file", metavar="K.json", help="per-subject constants from 'gaitlog calibrate-k' "
                        "(without it M1/M2 use K = 1 and M4/M5 are not computed)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="compute the recordings on an existing Dask "
                        "scheduler: its address or the scheduler file it wrote (dask scheduler --scheduler-file FILE); "
                        "the outputs are written here as each recording finishes, the same as one after the other")
    parser.add_argument("--workers", type=whole(minimum=1, maximum=256), metavar="N",
                        help="compute the recordings on a local Dask cluster of N worker processes (default: one "
                             "after the other in this process)")
    add_anatomy_options(parser)
    add_max_missing_option(parser)
    add_json_option(parser, "the summary table")
    add_verbosity_options(parser)


def recording_lengths(flags: argparse.Namespace, k, data) -> object:
    """Leg and foot length of one recording from the anatomy flags (module-level: it travels to Dask workers)."""
    return lengths_from_args(flags, k=k, data=data)


def _dask_runner(args: argparse.Namespace):
    """``--scheduler``/``--workers`` checked, and Dask's runner when one is given (else None: in this process)."""
    if args.scheduler and args.workers:
        raise UsageError("--scheduler and --workers exclude each other (the scheduler's cluster has its own workers)")
    if not (args.scheduler or args.workers):
        return None
    from gaitlog.host.commands.sweep import _check_scheduler
    from gaitlog.host.studies.dask_runner import run_on_dask

    if args.scheduler:
        _check_scheduler(args.scheduler)
    return run_on_dask


def run(args: argparse.Namespace) -> int:
    from gaitlog.atomic_write import atomic_write_text
    from gaitlog.host.accelerometer.calibration import AccCalibration
    from gaitlog.host.studies.batch import SUMMARY_COLUMNS, batch_inputs, run_batch
    from gaitlog.host.studies.compare import rows_csv_text

    run_on_dask = _dask_runner(args)
    out = Path(args.out)
    folder = Path(args.folder)
    check_output_folder("--out", out)
    if folder.is_dir() and out.resolve() == folder.resolve():
        raise HostError(f"--out {out}: is the input FOLDER; give an output folder other than the input folder")
    cal = AccCalibration.load(args.calibration) if args.calibration else None
    k = k_fit_from_args(args)
    try:
        paths = batch_inputs(folder, args.pattern)
    except (ValueError, NotImplementedError) as err:
        raise UsageError(f"--pattern {args.pattern!r}: {err}") from None
    if not paths:
        raise HostError(f"{folder}: no input file matches --pattern {args.pattern!r}")
    say = printer(args)
    settings = {"leg_length_m": args.leg_length, "foot_length_m": args.foot_length, "height_m": args.height}
    t = time.perf_counter()
    with progress_bar(args, len(paths), "recording") as tick:
        results = run_batch(paths, out, calibration=cal, calibration_file=args.calibration, k=k, k_file=args.k_file,
                            lengths=functools.partial(recording_lengths, argparse.Namespace(
                                leg_length=args.leg_length, foot_length=args.foot_length, height=args.height,
                                k_file=args.k_file), k), settings=settings, progress=tick,
                            scheduler=args.scheduler, workers=args.workers, run_on_dask=run_on_dask)
    rows = [r.summary for r in results]
    atomic_write_text(out / "batch.csv", rows_csv_text([{k: ("" if v is None else v) for k, v in r.items()}
                                                        for r in rows], SUMMARY_COLUMNS))
    n = {s: sum(r.status == s for r in results) for s in ("done", "partial", "skipped", "failed")}
    over = [r for r in results if r.status != "failed" and (r.summary.get("missing_percent") or 0) > args.max_missing]
    if args.json:
        print_json({"out": str(out), "recordings": rows})
    say(f"batch: {len(results)} recording(s) in {time.perf_counter() - t:.1f} s: {n['done'] + n['partial']} computed, "
        f"{n['skipped']} finished before (skipped), {n['failed']} failed"
        + (f"; {n['partial']} partial (samples missing)" if n["partial"] else ""))
    _print_rows(say, rows)
    _print_notes(say, results)
    say(f"written: {out}/batch.csv and per recording NAME.steps.csv, NAME.json")
    for r in over:
        print(f"gaitlog batch: error: {r.path}: {r.summary['missing_percent']:.1f} % of the samples missing, above "
              f"--max-missing {args.max_missing:g} % (its outputs are written, status partial)", file=sys.stderr)
    return 1 if n["failed"] or over else 0


def _print_rows(say, rows: list[dict]) -> None:
    """The table of the recordings computed or skipped."""
    say(f"{'recording':<28}{'status':<15}{'samples':>9}{'Hz':>6}{'steps':>7}{'M1 m':>9}{'M2 m':>9}{'M3 m':>9}")
    for r in rows:
        if r["status"] == "failed":
            continue
        dist = "".join(f"{r[k]:>9.2f}" if r[k] is not None else f"{'n/a':>9}"
                       for k in ("distance_m1_m", "distance_m2_m", "distance_m3_m"))
        status = f"partial {r['missing_percent']:.1f}%" if r["status"] == "partial" else r["status"]
        say(f"{r['recording']:<28}{status:<15}{r['n_samples']:>9}{r['sampling_rate_hz']:>6g}{r['n_steps']:>7}{dist}")


def _print_notes(say, results: list) -> None:
    """Failures, missing samples and the chain's warnings, on stderr."""
    for r in results:
        if r.status == "failed":
            print(f"gaitlog batch: failed: {r.error if str(r.path) in r.error else f'{r.path}: {r.error}'}",
                  file=sys.stderr)
            continue
        if r.status == "partial":  # the missing samples are always said, -q or not
            print(f"gaitlog batch: warning: {r.summary['missing_line']}", file=sys.stderr)
        if r.summary.get("warnings") and r.status in ("done", "partial") and say is print:
            print(f"gaitlog batch: warning: {r.summary['warnings']}", file=sys.stderr)
