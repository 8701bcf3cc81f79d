"""Decode, calibrate and estimate every recording in a folder (``gaitlog batch``), one at a time, each on its
own: a file that cannot be read or analysed is listed with its error and the batch goes on.

Per recording ``NAME`` the output folder receives ``NAME.steps.csv`` (the offline chain's per-step table, as
``gaitlog estimate --out``) and then ``NAME.json`` (its summary: samples, steps, distance per estimator, and
what it was computed from). ``NAME.json`` is written last, atomically, so its presence means the recording is
finished: a re-run skips it when the input file and the settings (calibration, K file, lengths) are unchanged
(the JSON keeps their SHA-256), and recomputes it otherwise. Failed recordings leave no output, so a re-run
retries them.

With a scheduler or workers (``gaitlog batch --scheduler/--workers``) the recordings are computed on Dask, each a
task (:class:`BatchJob` on a :class:`BatchTask`); this process writes each one's outputs as it arrives, so the
workers need no shared file system for the outputs (they read the inputs by path). A bad file is a failed row
either way, and the outputs are the same as one after the other here.

Inputs are every regular file of the folder matching the pattern but hidden files and the sidecars and
outputs of other commands (``.json``, ``.csv``, ``.txt``, ``.md``): memory images, raw dumps, wire captures,
decoded ``.npz``.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import AccelerationInput, input_losses
from gaitlog.host.files.inputs import read_acceleration
from gaitlog.host.files.losses import MissingSamplesWarning
from gaitlog.host.gait.anthropometry import AnatomyChoice
from gaitlog.host.studies.estimate import float_steps, write_table_csv
from gaitlog.atomic_write import atomic_write_text

__all__ = ["BatchJob", "BatchResult", "BatchTask", "batch_inputs", "run_batch", "SUMMARY_COLUMNS"]

#: Suffixes that are never inputs (sidecars, outputs of other commands).
NOT_INPUTS = (".json", ".csv", ".txt", ".md")
#: Columns of the batch summary table.
SUMMARY_COLUMNS = (("recording", "status", "n_samples", "n_missing", "missing_percent", "sampling_rate_hz", "n_steps", "n_bouts",
                    "leg_length_m", "foot_length_m") + tuple(f"distance_{e.lower()}_m" for e in ESTIMATORS)
                   + ("warnings", "error"))


@dataclass(frozen=True)
class BatchResult:
    """One recording of a batch: ``status`` is ``done`` (computed now), ``partial`` (computed now from a recording
    with missing samples: ``summary["missing_percent"]``, and ``summary["missing_line"]`` the line that says
    them), ``skipped`` (finished before, unchanged) or ``failed`` (``error`` says why); ``summary`` the row of
    :data:`SUMMARY_COLUMNS`."""

    path: Path
    status: str
    summary: dict
    error: str = ""


def batch_inputs(folder: str | Path, pattern: str = "*") -> list[Path]:
    """The input files of ``folder`` (module notes), sorted by name."""
    p = Path(folder)
    if not p.is_dir():
        raise HostError(f"{p}: not a folder")
    return sorted(f for f in p.glob(pattern) if f.is_file() and not f.name.startswith(".")
                  and f.suffix.lower() not in NOT_INPUTS)


def _sha256(path: Path | None) -> str | None:
    if path is None:
        return None
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _estimate(path: Path, calibration: AccCalibration | None, k: Any,
              lengths: Callable[[AccelerationInput], AnatomyChoice]) -> tuple[dict, StepTable]:
    """The summary row and the per-step table of one recording (the streaming chain: bounded memory)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = read_acceleration(path, calibration=calibration, arrays=False)
        choice = lengths(data)
        steps, chain_notes = float_steps(data, choice, k)
    notes = list(dict.fromkeys(str(w.message) for w in caught if not issubclass(w.category, MissingSamplesWarning)))
    notes += chain_notes
    losses = input_losses(data)
    row: dict[str, Any] = {"recording": path.name, "status": "partial" if losses.ranges else "done",
                           "n_samples": int(data.n_samples), "n_missing": int(data.n_missing),
                           "missing_percent": round(losses.percent, 3), "missing_line": losses.line(),
                           "sampling_rate_hz": float(data.sampling_rate_hz),
                           "n_steps": int(steps.n_steps),
                           "n_bouts": int(np.unique(steps.bout).size) if steps.n_steps else 0,
                           "leg_length_m": float(choice.leg_length_m), "foot_length_m": float(choice.foot_length_m)}
    for e in ESTIMATORS:
        d = steps.distance_m(e)[0] if e in steps.length_m else math.nan
        row[f"distance_{e.lower()}_m"] = float(d) if math.isfinite(d) else None
    row["warnings"] = "; ".join(notes)
    row["error"] = ""
    return row, steps


@dataclass(frozen=True)
class BatchTask:
    """One recording to compute (picklable: it travels to a Dask worker); ``key`` names it uniquely."""

    key: str
    path: Path


@dataclass(frozen=True)
class BatchJob:
    """What every recording is computed with; calling it on a :class:`BatchTask` returns ``{"row", "steps",
    "error"}``: the summary row and the step table, or the one-line error (a worker never raises, so a bad file
    is reported as in a serial run). ``lengths`` must be picklable (a module-level function or a partial of one)
    to run on Dask."""

    calibration: AccCalibration | None
    k: Any
    lengths: Callable[[AccelerationInput], AnatomyChoice]

    def __call__(self, task: BatchTask) -> dict:
        try:
            row, steps = _estimate(task.path, self.calibration, self.k, self.lengths)
        except Exception as err:  # noqa: BLE001 -- one bad file never stops the batch; its error is listed
            text = str(err) if isinstance(err, (HostError, OSError)) else f"{type(err).__name__}: {err}"
            return {"row": None, "steps": None, "error": text.splitlines()[0] if text else type(err).__name__}
        return {"row": row, "steps": steps, "error": ""}


class _Outputs:
    """The batch's side of :func:`gaitlog.host.studies.dask_runner.run_on_dask`'s store: writes a recording's outputs
    (``NAME.steps.csv`` a block of rows at a time, then ``NAME.json``) as its result arrives, in this process."""

    def __init__(self, out: Path, stamps: dict[str, dict]) -> None:
        self.out, self.stamps = out, stamps
        self.results: dict[str, BatchResult] = {}

    def pending(self, tasks: list[BatchTask]) -> list[BatchTask]:
        return list(tasks)

    def write(self, task: BatchTask, result: dict) -> None:
        path = task.path
        done = self.out / f"{path.name}.json"
        try:
            if result["error"]:
                raise HostError(result["error"])
            row = result["row"]
            write_table_csv(self.out / f"{path.name}.steps.csv", result["steps"].columns())
            atomic_write_text(done, json.dumps({"input": str(path), "stamp": self.stamps[task.key], "summary": row},
                                               indent=2) + "\n")
            self.results[task.key] = BatchResult(path, row["status"], row)
        except (HostError, OSError) as err:
            text = str(err).splitlines()[0] if str(err) else type(err).__name__
            done.unlink(missing_ok=True)
            self.results[task.key] = BatchResult(path, "failed", {"recording": path.name, "status": "failed",
                                                                  "error": text}, text)


def run_batch(paths: list[Path], out: str | Path, *, calibration: AccCalibration | None = None,
              calibration_file: str | Path | None = None, k: Any = None, k_file: str | Path | None = None,
              lengths: Callable[[AccelerationInput], AnatomyChoice], settings: dict | None = None,
              progress: Callable[[], object] | None = None, scheduler: str | None = None,
              workers: int | None = None, run_on_dask: Callable[..., int] | None = None) -> list[BatchResult]:
    """Estimate every path (module notes); returns one :class:`BatchResult` per path, in order.

    Parameters
    ----------
    calibration, calibration_file
        Accelerometer calibration (``gaitlog calibrate``) applied to every recording (default: each file's own)
        and the file it came from.
    k, k_file
        Per-subject constants (:class:`gaitlog.host.gait.k_calibration.KFit`) and the file they came from.
    lengths
        Leg and foot length for a recording read (e.g. the command's anatomy flags); picklable for Dask.
    settings
        Anything else the results depend on (kept in each ``NAME.json``; a change recomputes).
    scheduler, workers, run_on_dask
        Run the recordings on Dask with ``run_on_dask`` (:func:`gaitlog.host.studies.dask_runner.run_on_dask`,
        given by the caller: importing Dask costs 0.5 s): an existing scheduler (address or scheduler file), or a
        local cluster of ``workers`` processes; scheduler and workers None: one after the other in this process.
        The results are the same either way.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fixed = {"calibration_sha256": _sha256(Path(calibration_file)) if calibration_file else None,
             "k_file_sha256": _sha256(Path(k_file)) if k_file else None, "settings": settings or {}}
    earlier: dict[str, BatchResult] = {}
    stamps: dict[str, dict] = {}
    tasks = []
    for i, path in enumerate(paths):
        key = f"{i:06d}"
        try:
            stamps[key] = fixed | {"input_sha256": _sha256(path)}
        except OSError as err:
            text = f"{path}: cannot read: {err.strerror or err}"
            earlier[key] = BatchResult(path, "failed", {"recording": path.name, "status": "failed", "error": text},
                                       text)
            continue
        old = _finished(out / f"{path.name}.json")
        if old.get("stamp") == stamps[key]:
            earlier[key] = BatchResult(path, "skipped", old["summary"] | {"status": "skipped"})
            if progress is not None:
                progress()
            continue
        tasks.append(BatchTask(key, path))
    outputs = _Outputs(out, stamps)
    job = BatchJob(calibration, k, lengths)
    if scheduler is None and workers is None:
        for task in tasks:
            outputs.write(task, job(task))
            if progress is not None:
                progress()
    elif tasks:
        if run_on_dask is None:
            raise ValueError("scheduler or workers given without run_on_dask")
        run_on_dask(job, tasks, outputs, scheduler=scheduler, workers=workers or 2, progress=progress)
    results = earlier | outputs.results
    return [results[f"{i:06d}"] for i in range(len(paths))]


def _finished(done: Path) -> dict:
    """The ``NAME.json`` of a recording finished before, or {}."""
    if not done.is_file():
        return {}
    try:
        old = json.loads(done.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    return old if isinstance(old, dict) else {}
