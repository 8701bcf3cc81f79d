"""One recording -> its step tables and distances (``gaitlog estimate``), in bounded memory.

:func:`estimate_recording` runs the offline float chain block by block
(:class:`gaitlog.host.gait.streaming.StreamingStepPipeline`: the whole-array results bit for bit) and the logger's
on-line algorithm in fixed point on the codes (fed a block at a time), and returns an :class:`EstimateResult`: the
tables, the per-estimator summary, the notes for the user and the JSON document of ``--json``. Its
:meth:`~EstimateResult.write` writes the tables' CSVs a block of rows at a time, both or neither. With both
arithmetics the fixed-point chain runs in a worker thread beside the float chain (the on-line kernel releases the
GIL): on two free CPUs the time of the longer chain, not of both.

Beside the step table's own columns, the CSV says where the leg and foot length came from (``lengths_source``:
:data:`gaitlog.host.gait.anthropometry.LENGTH_SOURCES`) and, with a K file, which of the step's quantities lie
outside the range K was calibrated on (``outside_k_range``: names from
:data:`gaitlog.host.gait.k_calibration.RANGE_QUANTITIES` joined by ``+``, empty when inside).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.atomic_write import atomic_write
from gaitlog.firmware_sim.algorithms.aot_kernel import entry_points
from gaitlog.firmware_sim.algorithms.online import load_kernels
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable, columns_csv_text, distinct, nan_median
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import AccelerationInput, input_losses
from gaitlog.host.files.losses import SampleLosses
from gaitlog.host.gait.anthropometry import LENGTH_MODEL, AnatomyChoice
from gaitlog.host.files.replay import online_step_table, run_starts
from gaitlog.host.gait.k_calibration import RANGE_QUANTITIES, KFit
from gaitlog.host.gait.streaming import StreamingStepPipeline, bound_heap, give_back_memory

__all__ = ["ARITHMETICS", "EstimateResult", "estimate_recording", "float_steps", "summarise", "write_table_csv"]

#: ``--arithmetic`` choices: the offline float chain, the logger's on-line algorithm, both.
ARITHMETICS = ("float", "fixed", "both")
#: Samples fed to the chains, and rows written to a CSV, at a time.
BLOCK_SAMPLES = 1 << 16
#: Rows of a step table formatted at a time (their cells are Python strings: ~1 kB a row).
CSV_ROWS = 4096


@dataclass(frozen=True, eq=False)
class EstimateResult:
    """What ``gaitlog estimate`` computed from one recording.

    Attributes
    ----------
    data
        The input read (:class:`~gaitlog.host.files.acceleration.AccelerationInput`).
    lengths, k
        The leg and foot length used and where they came from; the K file's constants or None.
    tables
        ``{"float": StepTable, "fixed": StepTable}``, the arithmetics asked for, in that order.
    fixed_report
        The fixed-point run's saturation/wrap report ("" when none, or no fixed run).
    summary
        Per arithmetic (:func:`summarise`).
    losses
        The missing samples (:class:`~gaitlog.host.files.losses.SampleLosses`).
    notes
        Warnings for the user (assumed lengths, the chain's notes, K extrapolated).
    """

    data: AccelerationInput
    lengths: AnatomyChoice
    k: KFit | None
    tables: dict[str, StepTable]
    fixed_report: str
    summary: dict[str, dict]
    losses: SampleLosses
    notes: list[str] = field(default_factory=list)

    def csv_blocks(self, arithmetic: str, rows: int = CSV_ROWS):
        """The CSV text of one table (module notes), ``rows`` rows at a time, the header in the first."""
        table = self.tables[arithmetic]
        cols = table.columns()
        n = table.n_steps
        out = self.k.outside_range(table) if self.k is not None else None
        for lo in range(0, max(n, 1), rows):
            hi = min(n, lo + rows)
            flags = (["+".join(q for q in RANGE_QUANTITIES if out[q][i]) for i in range(lo, hi)]
                     if out is not None else [""] * (hi - lo))
            text = columns_csv_text({**{c: np.asarray(v)[lo:hi] for c, v in cols.items()},
                                     "lengths_source": [self.lengths.source] * (hi - lo), "outside_k_range": flags})
            yield text if lo == 0 else text.split("\n", 1)[1]

    def write(self, outs: dict[str, Path]) -> None:
        """Write the tables (``{arithmetic: path}``): both or neither (each file is itself atomic)."""
        written: list[Path] = []
        try:
            for arith, path in outs.items():
                _write_blocks(path, self.csv_blocks(arith))
                written.append(path)
        except BaseException:
            for path in written:
                path.unlink(missing_ok=True)
            raise

    def document(self, input_name: str, k_file: str | None, outs: dict[str, Path], max_missing: float) -> dict:
        """The ``--json`` document."""
        data, lengths, k = self.data, self.lengths, self.k
        return {"input": str(input_name), "source": data.source, "n_samples": data.n_samples,
                "n_missing": data.n_missing, "sampling_rate_hz": data.sampling_rate_hz,
                "leg_length_m": lengths.leg_length_m, "foot_length_m": lengths.foot_length_m,
                "lengths_from": lengths.note, "lengths_source": lengths.source, "height_known": not lengths.assumed,
                "length_model": LENGTH_MODEL, "k_file": k_file,
                "k_calibrated_range": k.calibrated_range if k is not None else None, "arithmetic": self.summary,
                "fixed_point_saturation": self.fixed_report if "fixed" in self.tables else None,
                "per_step_tables": {a: str(p) for a, p in outs.items()}, "notes": self.notes,
                "missing_percent": round(self.losses.percent, 3), "max_missing_percent": max_missing,
                "above_max_missing": self.losses.above(max_missing)}


def write_table_csv(path: Path, columns: dict, rows: int = CSV_ROWS) -> None:
    """Write named equal-length columns as CSV (:func:`~gaitlog.firmware_sim.algorithms.steps.columns_csv_text`,
    the same text), ``rows`` rows formatted at a time, atomically."""
    n = len(next(iter(columns.values()))) if columns else 0

    def blocks():
        for lo in range(0, max(n, 1), rows):
            text = columns_csv_text({c: np.asarray(v)[lo:lo + rows] for c, v in columns.items()})
            yield text if lo == 0 else text.split("\n", 1)[1]

    _write_blocks(path, blocks())


def _write_blocks(path: Path, blocks) -> None:
    with atomic_write(path, "w", encoding="utf-8", newline="") as fh:
        for text in blocks:
            fh.write(text)


def estimate_recording(data: AccelerationInput, *, arithmetic: str, lengths: AnatomyChoice, k: KFit | None = None,
                       adc_calibration_file: str | None = None, input_name: str = "") -> EstimateResult:
    """Estimate every step of ``data`` with the arithmetics asked for (:data:`ARITHMETICS`).

    ``adc_calibration_file``: the accelerometer calibration (``gaitlog calibrate``) the fixed-point run converts
    with (default: the recording's own). Raises :class:`HostError` when ``fixed``/``both`` is asked of an input
    without ADC codes.
    """
    if arithmetic not in ARITHMETICS:
        raise ValueError(f"arithmetic must be one of {ARITHMETICS}, got {arithmetic!r}")
    if arithmetic != "float" and data.recording is None:
        raise HostError(f"{input_name or data.source}: --arithmetic {arithmetic} needs ADC codes: give a logger "
                        "file or a decoded recording (.npz from 'gaitlog decode'), not acceleration in g")
    bound_heap()                              # block-sized temporaries from mmap: no heap growth on long inputs
    notes = [lengths.note] if lengths.assumed else []
    tables: dict[str, StepTable] = {}
    report = ""
    fixed = None
    if arithmetic == "both":
        (fixed, report), (tables["float"], chain_notes) = _both_chains(data, adc_calibration_file, lengths, k)
        notes += chain_notes
    elif arithmetic == "fixed":
        fixed, report = fixed_steps(data, adc_calibration_file, lengths, k)
        give_back_memory()
    else:
        tables["float"], chain_notes = float_steps(data, lengths, k)
        notes += chain_notes
    if fixed is not None:
        tables["fixed"] = fixed
    summary = summarise(tables, k)
    notes += _k_notes(summary)
    return EstimateResult(data, lengths, k, tables, report, summary, input_losses(data), notes)


def _both_chains(data: AccelerationInput, calibration_file: str | None, lengths: AnatomyChoice, k: KFit | None
                 ) -> tuple[tuple[StepTable, str], tuple[StepTable, list[str]]]:
    """:func:`fixed_steps` in a worker thread beside :func:`float_steps` in this one: the on-line kernel releases
    the GIL while it runs (:mod:`gaitlog.firmware_sim.algorithms.aot_kernel`), so the two chains share the time of
    the longer. The same results as one after the other, and the same error first: the fixed chain's. The kernel
    is loaded (or built) here first, numba's JIT compiled (or loaded from its cache) when it runs instead, so that
    the thread only runs it."""
    if entry_points("fixed")[1] != "aot":
        load_kernels(("fixed",))
    done: dict[str, Any] = {}

    def run_fixed() -> None:
        try:
            done["fixed"] = fixed_steps(data, calibration_file, lengths, k)
        except BaseException as exc:  # noqa: BLE001 - raised in the caller's thread, below
            done["error"] = exc

    worker = threading.Thread(target=run_fixed, name="gaitlog estimate: fixed point")
    worker.start()
    try:
        floated = float_steps(data, lengths, k)
    except BaseException:
        worker.join()
        if "error" in done:
            raise done["error"] from None
        raise
    worker.join()
    if "error" in done:
        raise done["error"]
    give_back_memory()
    return done["fixed"], floated


def float_steps(data: AccelerationInput, lengths: AnatomyChoice, k: KFit | None,
                block: int = BLOCK_SAMPLES) -> tuple[StepTable, list[str]]:
    """The offline chain on ``data``, fed ``block`` samples at a time -> (table, notes)."""
    pipe = StreamingStepPipeline(leg_length_m=lengths.leg_length_m, foot_length_m=lengths.foot_length_m,
                                 sampling_rate_hz=data.sampling_rate_hz, k_fit=k)
    for g, valid in data.blocks(block):
        pipe.feed(g, valid)
    pipe.finish()
    return pipe.steps_, list(pipe.notes_)


def fixed_steps(data: AccelerationInput, calibration_file: str | None, lengths: AnatomyChoice,
                k: KFit | None) -> tuple[StepTable, str]:
    """The on-line algorithm in fixed point (the logger's) on the codes of a logger recording, with the same K as
    the float chain -> (table, saturation report)."""
    rec = data.recording
    adc_cal = rec.default_calibration()[0]
    if calibration_file:
        try:
            adc_cal = AccCalibration.load(calibration_file).to_header_calibration()
        except HostError as err:
            raise HostError(f"{calibration_file}: {err}") from None
    valid = np.asarray(rec.valid, bool)
    table, alg = online_step_table(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz,
                                   leg_length_m=lengths.leg_length_m, foot_length_m=lengths.foot_length_m,
                                   k_fit=k, adc_calibration=adc_cal, adc_bits=int(rec.adc_bits),
                                   arithmetic="fixed", valid=valid, run_starts=run_starts(valid, rec.flags))
    return table, alg.arithmetic_context().report()


def summarise(tables: dict[str, StepTable], k: KFit | None = None) -> dict[str, dict]:
    """Per arithmetic: steps, bouts and per estimator distance / median step / filled steps / steps outside
    K's calibrated range (None for n/a)."""
    out: dict[str, dict] = {}
    for arith, steps in tables.items():
        outside = k.outside_range(steps) if k is not None and k.calibrated_range is not None else None
        est = {}
        for name in ESTIMATORS:
            d, filled = steps.distance_m(name)
            lengths = steps.length_m[name]
            med = nan_median(lengths) if np.isfinite(lengths).any() else float("nan")
            est[name] = {"distance_m": float(d) if np.isfinite(d) else None,
                         "median_step_m": med if np.isfinite(med) else None, "steps_filled": int(filled),
                         "steps_outside_k_range": int(outside[name].sum()) if outside is not None and name in outside
                         else None}
        out[arith] = {"n_steps": int(steps.n_steps),
                      "steps_outside_k_range": int(outside["any"].sum()) if outside is not None else None,
                      "n_bouts": int(distinct(steps.bout).size) if steps.n_steps else 0, "estimators": est}
    return out


def _k_notes(summary: dict[str, dict[str, Any]]) -> list[str]:
    """K extrapolated: said on stderr too, not only in the column."""
    notes = []
    for arith, s in summary.items():
        out_k = {e: v["steps_outside_k_range"] for e, v in s["estimators"].items() if v["steps_outside_k_range"]}
        if out_k:
            notes.append(f"{'fixed point: ' if arith == 'fixed' else ''}steps outside the range K was calibrated on "
                         f"(K extrapolated; column outside_k_range): " + ", ".join(
                             f"{e} {n} of {s['n_steps']}" for e, n in out_k.items()))
    return notes
