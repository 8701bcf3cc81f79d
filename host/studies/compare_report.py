"""The reports of ``gaitlog compare``: the three chains on a logger recording (:func:`compare_input`) or on
simulated subjects (:func:`compare_simulated`), each a report that writes its CSVs (``write_outputs``), renders
its printed text (``format_table``; lines of level 1 only with ``-v``) and its JSON document (``to_json``).

The comparisons themselves are :mod:`gaitlog.host.studies.compare`'s.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.atomic_write import atomic_write_text
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, columns_csv_text
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import AccelerationInput
from gaitlog.host.files.replay import run_starts, verify_step_records
from gaitlog.host.gait.k_calibration import KFit
from gaitlog.host.storage.json_text import json_text
from gaitlog.host.studies.compare import (
    BUDGET_COLUMNS,
    bootstrap_budget,
    compare_recording,
    format_budget,
    format_segments,
    format_step_diffs,
    pool_step_diffs,
    pooled_step_columns,
    rows_csv_text,
)
from gaitlog.host.studies.simulation import simulate_comparisons

__all__ = ["RecordingComparisonReport", "ReportLines", "SimulatedComparisonReport", "compare_input", "compare_simulated"]


@dataclass
class ReportLines:
    """Printed lines, each with the verbosity it needs (0: the summary, 1: ``-v``)."""

    lines: list[tuple[int, str]] = field(default_factory=list)

    def say(self, text: str = "", level: int = 0) -> None:
        self.lines.append((level, text))

    def format_table(self, verbosity: int = 0) -> str:
        """The lines of level ``verbosity`` and below."""
        return "\n".join(text for level, text in self.lines if level <= verbosity)


@dataclass
class SimulatedComparisonReport(ReportLines):
    """``compare --simulate``: the comparisons of the simulated subjects and the bootstrapped error budget."""

    results: list = field(default_factory=list)
    budget: list[dict] = field(default_factory=list)

    @property
    def step_diffs(self) -> list[dict]:
        """Every subject's per-step differences, with its ``subject``."""
        return [d | {"subject": r.subject_id} for r in self.results for d in r.step_diffs]

    def write_outputs(self, out: str | Path, seg: str | Path, split: str | Path, bud: str | Path) -> None:
        """The per-step table (``out``), the segments (``seg``), the error split (``split``) and the budget
        (``bud``)."""
        atomic_write_text(out, columns_csv_text(pooled_step_columns(self.results)))
        atomic_write_text(seg, rows_csv_text([s for r in self.results for s in r.segments]))
        atomic_write_text(split, rows_csv_text(self.step_diffs))
        atomic_write_text(bud, rows_csv_text(self.budget, BUDGET_COLUMNS))

    def to_json(self) -> str:
        return json_text({"step_differences": pool_step_diffs(self.step_diffs),
                          "segments": [s for r in self.results for s in r.segments],
                          "budget": self.budget, "saturation": {r.subject_id: r.saturation for r in self.results}})


def compare_simulated(n_subjects: int, *, seed: int, adc_bits: int, sampling_rate_hz: float, workers: int,
                      population: str, n_resamples: int,
                      progress: Callable[[str], object] | None = None) -> SimulatedComparisonReport:
    """``n_subjects`` simulated subjects through the four chains
    (:func:`gaitlog.host.studies.simulation.simulate_comparisons`) and the error budget with bootstrap intervals
    over them (``n_resamples``)."""
    results = simulate_comparisons(n_subjects, seed=seed, adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz,
                                   workers=workers, progress=progress, population=population)
    report = SimulatedComparisonReport(results=results)
    say = report.say
    say(f"{len(results)} simulated subject(s) ('{population}'), {adc_bits}-bit ADC at {sampling_rate_hz:g} Hz; one K "
        "per mode, fitted on the offline chain, used by every chain (multi-speed for the per-step rows)")
    for r in results:
        say(f"  {r.subject_id}: {r.steps['step'].size} steps (offline chain), step durations off by "
            f"{r.timing['rms_ms']:.1f} ms rms; saturation/wrap: {r.saturation or 'none'}", 1)
    say(format_step_diffs(pool_step_diffs(report.step_diffs)))
    say()
    say(format_segments(results))
    say()
    report.budget = bootstrap_budget(results, n_resamples=n_resamples, seed=seed)
    say(format_budget(report.budget, n_resamples=n_resamples, seed=seed))
    sat = [f"{r.subject_id}: {r.saturation}" for r in results if r.saturation]
    say("saturation/wrap in the fixed-point runs: " + ("; ".join(sat) if sat else "none"))
    return report


@dataclass
class RecordingComparisonReport(ReportLines):
    """``compare RECORDING``: the comparison (:class:`gaitlog.host.studies.compare.RecordingComparison`) and the
    note on assumed lengths (``warning``: a line for standard error, or None)."""

    source: str = ""
    comparison: Any = None
    warning: str | None = None

    def write_outputs(self, out: str | Path, seg: str | Path, split: str | Path) -> None:
        """The per-step table (``out``), the segments (``seg``) and the differences per step (``split``)."""
        res = self.comparison
        atomic_write_text(out, columns_csv_text(res.steps))
        atomic_write_text(seg, rows_csv_text(res.segments))
        atomic_write_text(split, rows_csv_text(res.step_diffs))

    def to_json(self) -> str:
        res = self.comparison
        return json_text({"input": self.source, "steps": {c: t.n_steps for c, t in res.tables.items()},
                          "step_differences": res.step_diffs, "segments": res.segments,
                          "saturation": res.saturation, "cycles_per_sample": res.cycles_per_sample})


def compare_input(data: AccelerationInput, source: Path, *, calibration_file: str | None, k_file: str | None,
                  lengths_for: Callable[[KFit | None], Any], lap_m: float) -> RecordingComparisonReport:
    """The recording of ``data`` (read from ``source``) through the offline chain and the on-line algorithm in
    both arithmetics (:func:`gaitlog.host.studies.compare.compare_recording`), after the device's own step
    records are checked against the host's replay. ``calibration_file``: an accelerometer calibration instead of
    the recording's; ``k_file``: K (else K = 1); ``lengths_for(k)``: the leg and foot lengths
    (:func:`gaitlog.host.gait.anthropometry.choose_lengths`'s result).

    Raises
    ------
    HostError
        ``data`` is acceleration in g (no ADC codes), the device's records differ from the replay, or the
        calibration does not fit the header.
    """
    rec = data.recording
    if rec is None:
        raise HostError(f"{source}: compare runs the on-line algorithm on ADC codes: give a logger recording (memory "
                        "image, raw dump, wire capture or decoded .npz), not acceleration in g")
    # the device's own records first: a device that does not compute what the host replays is an error
    check = verify_step_records(rec)
    if check is not None and check.differs:
        raise HostError(check.error_message(source))
    cal, note = _header_calibration(rec, calibration_file)
    k = KFit.load(k_file) if k_file else None
    lengths = lengths_for(k)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    marks = data.mark_index
    starts = run_starts(rec.valid, np.asarray(rec.flags))
    t = rec.time_s
    res = compare_recording(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=leg,
                            foot_length_m=foot, adc_calibration=cal, adc_bits=int(rec.adc_bits), valid=rec.valid,
                            k_fit=k, mark_times_s=t[marks] if marks.size >= 2 else None, lap_m=lap_m,
                            t0_s=float(t[0]) if t.size else 0.0, run_starts=starts)
    report = RecordingComparisonReport(source=str(source), comparison=res,
                                       warning=lengths.note if lengths.assumed else None)
    say = report.say
    say(f"{source}: {rec.n_samples} samples at {rec.sampling_rate_hz:g} Hz ({rec.n_missing} missing); {note}")
    say(check.summary() if check is not None else "device step records: none in this recording")
    say(f"{starts.size} run(s) of contiguous samples (the on-line algorithm restarts after each gap), "
        f"{marks.size} MARK flag(s)", 1)
    say(f"leg length {leg:.3f} m, foot length {foot:.3f} m"
        + (f" ({lengths.note})" if lengths.note and not lengths.assumed else "")
        + f"; K file: {k_file or 'none (K = 1, M4/M5 n/a)'} (the same K for every chain)")
    tb = res.tables
    say("steps: " + ", ".join(f"{c} {tb[c].n_steps}" for c in tb) + "; " + "; ".join(
        f"{s}: matched {m.n_matched}, different events {int(np.count_nonzero(~m.same_events))}, "
        f"found by one chain only {m.only_a.size + m.only_b.size}" for s, m in res.matches.items()))
    say(format_step_diffs(res.step_diffs))
    report.lines += [(0, line) for line in _segment_lines(res)]
    say(f"saturation/wrap in the fixed-point run: {res.saturation or 'none'}; "
        f"PIC cycles per sample {res.cycles_per_sample:.0f} (mean)")
    return report


def _header_calibration(rec, calibration_file: str | None) -> tuple[Any, str]:
    """The header calibration the chains use and the note that says where it is from."""
    if not calibration_file:
        return rec.default_calibration()
    acc_calibration = AccCalibration.load(calibration_file)
    try:
        cal = acc_calibration.to_header_calibration()
    except HostError as err:
        raise HostError(f"{calibration_file}: {err}") from None
    return cal, f"g from {calibration_file}"


def _segment_lines(res) -> list[str]:
    """The per-segment table of a recording's comparison."""
    lines = [f"segments: {res.segment_source}; alg = online-float - offline, arith = online-fixed - online-float",
             f"{'seg':>4}{'t0 s':>8}{'t1 s':>8}" + "".join(f"{e + ' offline m':>13}{'alg mm':>9}{'arith mm':>9}"
                                                         for e in ESTIMATORS)]
    for i in sorted({r["section"] for r in res.segments}):
        rs = {r["estimator"]: r for r in res.segments if r["section"] == i}
        r0 = rs["M1"]
        lines.append(f"{i:>4}{r0['t_start_s']:>8.1f}{r0['t_end_s']:>8.1f}" + "".join(
            f"{rs[e]['offline_m']:>13.3f}{1e3 * rs[e]['algorithm_m']:>9.2f}{1e3 * rs[e]['arithmetic_m']:>9.2f}"
            for e in ESTIMATORS))
    return lines
