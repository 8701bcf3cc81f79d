"""Decode, calibrate and estimate every recording in a folder (``gaitlog batch``), one at a time, each on its
own: a file that cannot be read or analysed is listed with its error and the batch goes on.

Per recording ``NAME`` the output folder receives ``NAME.steps.csv`` (the offline chain's per-step table, as
``gaitlog estimate --out``) and then ``NAME.json`` (its summary: samples, steps, distance per estimator, and
what it was computed from). ``NAME.json`` is written last, atomically, so its presence means the recording is
finished: a re-run skips it when the input file and the settings (calibration, K file, lengths) are unchanged
(the JSON keeps their SHA-256), and recomputes it otherwise. Failed recordings leave no output, so a re-run
retries them.

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

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.inputs import AccelerationInput, input_losses, read_acceleration
from gaitlog.host.files.losses import MissingSamplesWarning
from gaitlog.host.gait.anthropometry import AnatomyChoice
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.atomic_write import atomic_write_text

__all__ = ["BatchResult", "batch_inputs", "run_batch", "SUMMARY_COLUMNS"]

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
              lengths: Callable[[AccelerationInput], AnatomyChoice]) -> tuple[dict, str]:
    """The summary row and the per-step CSV text of one recording."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = read_acceleration(path, calibration=calibration)
        choice = lengths(data)
        pipe = StepPipeline(leg_length_m=choice.leg_length_m, foot_length_m=choice.foot_length_m,
                            calibration=k).run(data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
    notes = list(dict.fromkeys(str(w.message) for w in caught if not issubclass(w.category, MissingSamplesWarning)))
    notes += list(pipe.notes_)
    losses = input_losses(data)
    steps = pipe.steps_
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
    return row, steps.to_csv_text()


def run_batch(paths: list[Path], out: str | Path, *, calibration: AccCalibration | None = None,
              calibration_file: str | Path | None = None, k: Any = None, k_file: str | Path | None = None, lengths: Callable[[AccelerationInput], AnatomyChoice],
              settings: dict | None = None, progress: Callable[[], object] | None = None) -> list[BatchResult]:
    """Estimate every path (module notes); returns one :class:`BatchResult` per path, in order.

    Parameters
    ----------
    calibration, calibration_file
        Accelerometer calibration (``gaitlog calibrate``) applied to every recording (default: each file's own)
        and the file it came from.
    k, k_file
        Per-subject constants (:class:`gaitlog.host.gait.k_calibration.KFit`) and the file they came from.
    lengths
        Leg and foot length for a recording read (e.g. the command's anatomy flags).
    settings
        Anything else the results depend on (kept in each ``NAME.json``; a change recomputes).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cal = calibration
    fixed = {"calibration_sha256": _sha256(Path(calibration_file)) if calibration_file else None,
             "k_file_sha256": _sha256(Path(k_file)) if k_file else None, "settings": settings or {}}
    results = []
    for path in paths:
        done = out / f"{path.name}.json"
        try:
            stamp = fixed | {"input_sha256": _sha256(path)}
            if done.is_file():
                try:
                    old = json.loads(done.read_text(encoding="utf-8"))
                except (OSError, json.JSONDecodeError):
                    old = {}
                if old.get("stamp") == stamp:
                    results.append(BatchResult(path, "skipped", old["summary"] | {"status": "skipped"}))
                    if progress is not None:
                        progress()
                    continue
            row, steps_csv = _estimate(path, cal, k, lengths)
            atomic_write_text(out / f"{path.name}.steps.csv", steps_csv)
            atomic_write_text(done, json.dumps({"input": str(path), "stamp": stamp, "summary": row}, indent=2) + "\n")
            results.append(BatchResult(path, row["status"], row))
        except Exception as err:  # noqa: BLE001 -- one bad file never stops the batch; its error is listed
            text = str(err) if isinstance(err, (HostError, OSError)) else f"{type(err).__name__}: {err}"
            text = text.splitlines()[0] if text else type(err).__name__
            done.unlink(missing_ok=True)
            results.append(BatchResult(path, "failed", {"recording": path.name, "status": "failed", "error": text},
                                       text))
        if progress is not None:
            progress()
    return results
