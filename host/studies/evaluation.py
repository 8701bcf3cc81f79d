"""The paper's evaluation on simulated subjects (Alvarez et al. 2006, sections II-C and IV, Figs 5-6).

Chain, per subject (:func:`gaitlog.host.studies.simulation.record_subject`, :func:`evaluate_recording`):

1. *Device calibration*: the emulated logger (:class:`gaitlog.firmware_sim.device.Logger`, its own seeded sensor
   errors: offsets, sensitivities, misalignment) records a static-pose session
   (:class:`gaitlog.firmware_sim.world.poses.CalibrationPoses`), fitted with :class:`gaitlog.host.accelerometer.fit.AccCalibrator`
   ("a calibration procedure takes into account offset and scale factors and the orthogonality of the
   axes", II-B). ``calibrate_device=False`` uses the header's nominal map instead.
2. *Walking*: the same logger (after ERASE) records the protocol of
   :class:`gaitlog.firmware_sim.world.walking.Walking` (10-bit ADC at 50 Hz by default); its memory image (header +
   EEPROM, :func:`gaitlog.protocol.image.build_image`) is decoded as a dump would be (:func:`gaitlog.host.files.decode.decode_bytes`)
   and the codes converted to g with the fitted calibration. The lap button's MARK flags give the lap times,
   or (``laps="stopwatch"``, with the paper's protocol: 5-minute rests, the logger STOPped during them, one
   logging run per excursion) an observer's stopwatch sheet anchored at the set-off detected in each run
   (:mod:`gaitlog.host.gait.stopwatch_laps`).
3. *Steps*: :class:`gaitlog.host.gait.pipeline.StepPipeline` without calibration (raw M1-M4 lengths with K = 1,
   M5's cadence), with the subject's own leg and foot length ("the anatomical data of each individual").
4. *Sections*: consecutive lap marks 20 m apart (default marks 10, 30, ..., 190 m of each excursion:
   the first 10 m of gait initiation are discarded, as in the paper). The section holding the 180° turn is
   left out by default (the paper's subjects "were allowed to turn freely between both 100 m segments";
   the estimators model straight walking); ``include_turn=True`` keeps it.
5. *K calibration* (:func:`gaitlog.host.gait.sections.calibration_sets`, :func:`gaitlog.host.gait.k_calibration.calibrate_on_sections`):
   **single-speed** = the first 40 m (two sections) of the preferred-speed excursion, pooled as one 40 m
   section (M5 then falls back to the walk-ratio line, with the calibrator's warning recorded);
   **multi-speed** = the first 40 m of every excursion, one 40 m section per speed. Calibration steps are
   whole steps whose window midpoint falls between the marks (as counting steps between stopwatch laps).
6. *Evaluation*: every remaining 20 m section, estimated distance / real distance per estimator and mode.
   The first two sections of **every** excursion are excluded in **both** modes (they are calibration data
   in multi-speed), so single- and multi-speed are compared on the same sections; the preferred
   excursion's first 40 m are thus never evaluated (the paper does not say whether it excluded them; we
   exclude calibration data). M3 has no K: its rows are the same in both modes. A step's length is spread
   uniformly over its window (previous foot-flat to its foot-flat) and a section takes the overlapping
   fraction (``edge="fraction"``; ``edge="whole"`` counts whole steps by window midpoint, which adds the
   ±half-step quantisation of counting steps between laps).
7. *Events* (:func:`score_events`): detected heel-strikes / toe-offs / foot-flats against the world's
   truth: F1 within ±40 ms and the median absolute timing error of the matched events; foot-flats also
   against the centre of mass's low point (``com_min``, Alvarez's null vertical velocity).

Rows, summaries (median, quartiles, extremes per estimator and mode), the CSV (atomic), the printed table
and the paper-pattern checks (:func:`paper_pattern`) are below; the box-plot figure is
:mod:`gaitlog.host.studies.plots`. With intervals: :func:`bootstrap_summary` (percentile bootstrap over subjects),
the paper side by side (:func:`format_paper_table`, :func:`paper_claims`: what the paper's text states) and
M5 against the generating heel-strike intervals (:func:`m5_timing_question`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Self

import numpy as np

from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.errors import HostError
from gaitlog.host.gait.k_calibration import calibrate_on_sections
from gaitlog.host.gait.pipeline import StepPipeline, apply_calibration
from gaitlog.host.gait.sections import (
    MODES,
    calibration_sets,
    section_fractions,
    sections_from_marks,
)
from gaitlog.host.gait.stopwatch_laps import lap_table, set_off_times
from gaitlog.host.storage.json_text import json_text
from gaitlog.host.studies.compare import match_events, rows_csv_text
from gaitlog.host.studies.plots import plot_boxplots
from gaitlog.host.studies.simulation import (
    SimulatedRecording,
    map_subjects,
    record_subject,
    simulated_population,
)
from gaitlog.host.studies.stats import BOOTSTRAP_LEVEL, BOOTSTRAP_RESAMPLES, subject_bootstrap, subject_resamples
from gaitlog.atomic_write import atomic_write_text

ROW_COLUMNS = ("subject", "excursion", "speed_label", "section", "start_m", "end_m", "turn", "mode", "estimator",
               "estimated_m", "real_m", "ratio", "steps")
SUMMARY_COLUMNS = ("mode", "estimator", "n", "median", "q1", "q3", "min", "max", "iqr")
BOOT_COLUMNS = ("mode", "estimator", "statistic", "value", "ci_low", "ci_high", "n_subjects")


# ---------------------------------------------------------------------------------------------------------
# Sections and distances


# (lap sections and step weights: gaitlog.host.gait.sections)


# ---------------------------------------------------------------------------------------------------------
# Event scoring


@dataclass(frozen=True)
class EventScore:
    """Detection and timing of one event type against the truth."""

    event: str
    n_truth: int
    n_detected: int
    n_matched: int
    median_abs_error_s: float
    median_error_s: float

    @property
    def precision(self) -> float:
        return self.n_matched / self.n_detected if self.n_detected else float("nan")

    @property
    def recall(self) -> float:
        return self.n_matched / self.n_truth if self.n_truth else float("nan")

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r > 0 else 0.0


def score_events(table: Any, truth_steps: dict, *, tol_s: float = 0.04,
                 walking_intervals_s: Sequence[tuple[float, float]] | None = None) -> dict[str, EventScore]:
    """F1 (within ``tol_s``) and median timing error of heel-strike, toe-off and foot-flat.

    Truth contacts are every heel strike of the walk, including each excursion's closing contact; truth
    toe-offs are the trailing foot's (end of double support), truth foot-flats the leading foot's
    (anatomical: forefoot down, ~0.65 of double support). ``com_min`` scores the same detected foot-flats
    against the instant the centre of mass is lowest (its vertical velocity null: the instant Alvarez et al.
    call foot-flat and reset the integrals at; ~40 ms after heel strike in real people, ~50 ms before the
    anatomical foot-flat). Detected events outside ``walking_intervals_s`` (rests) count as false positives
    all the same.
    """
    st = truth_steps
    exc = np.asarray(st["excursion"])
    last = np.r_[exc[1:] != exc[:-1], True]
    truth = {
        "heel_strike": np.sort(np.r_[st["heel_strike_s"], np.asarray(st["next_heel_strike_s"])[last]]),
        "toe_off": np.sort(np.asarray(st["toe_off_s"], np.float64)),
        "foot_flat": np.sort(np.r_[st["foot_flat_s"], np.asarray(st["next_foot_flat_s"])[last]]),
    }
    if "com_min_s" in st:
        truth["com_min"] = np.sort(np.asarray(st["com_min_s"], np.float64))
    detected = {
        "heel_strike": table.time_s(table.heel_strike[table.heel_strike >= 0]),
        "toe_off": table.time_s(np.unique(table.toe_off[table.toe_off >= 0])),
        "foot_flat": table.time_s(table.foot_flat),
        "com_min": table.time_s(table.foot_flat),
    }
    out = {}
    for name in truth:
        t, d = truth[name], np.sort(detected[name])
        it, jd = match_events(t, d, tol_s)
        err = d[jd] - t[it]
        out[name] = EventScore(name, int(t.size), int(d.size), int(it.size),
                               float(np.median(np.abs(err))) if err.size else float("nan"),
                               float(np.median(err)) if err.size else float("nan"))
    return out


# ---------------------------------------------------------------------------------------------------------
# One subject


@dataclass(eq=False)
class SubjectResult:
    """Everything the evaluation keeps of one subject (small: rows and scores, no signals)."""

    subject_id: str
    rows: list[dict]
    events: dict[str, EventScore]
    calibrations: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    truth_ratio: list[float] = field(default_factory=list)
    m5: dict[str, Any] = field(default_factory=dict)


def evaluate_recording(rec: SimulatedRecording, *, section_m: float = 20.0, include_turn: bool = False,
                       edge: str = "fraction", calibration_sections: int = 2,
                       corridor_length_m: float = 100.0, detector: Any = None) -> SubjectResult:
    """Steps, K calibration (both modes), section ratios and event scores of one recording.

    ``detector``: a :class:`gaitlog.host.gait.events.GaitEventDetector` for the pipeline (default parameters when
    None).
    """
    sub = rec.subject
    pipe = StepPipeline(leg_length_m=sub.leg_length_m, foot_length_m=sub.foot_length_m, detector=detector).run(
        rec.acc_g, sampling_rate_hz=rec.sampling_rate_hz, valid=rec.valid, t0_s=rec.t0_s)
    table = pipe.steps_
    caught = [f"pipeline: {n}" for n in pipe.notes_]
    if rec.lap_sheet is not None:     # the observer's stopwatch, anchored at the set-off seen in each run
        laps = lap_table(rec.lap_sheet, set_off_times(rec.acc_g, rec.valid, rec.run_rows,
                                                      sampling_rate_hz=rec.sampling_rate_hz, t0_s=rec.t0_s))
        marks = laps["time_s"]
    else:                             # the MARK button
        laps, marks = rec.truth["laps"], rec.mark_times_s
    sections = sections_from_marks(marks, laps, corridor_length_m=corridor_length_m,
                                   section_m=section_m, sampling_rate_hz=rec.sampling_rate_hz)
    try:
        pools = calibration_sets(sections, calibration_sections=calibration_sections)
    except HostError as err:
        raise HostError(f"subject {sub.subject_id}: {section_m} m sections: {err}") from None
    cals = {mode: calibrate_on_sections(table, pools[mode], leg_length_m=sub.leg_length_m,
                                        foot_length_m=sub.foot_length_m, subject=sub.subject_id)
            for mode in MODES}
    caught += [f"calibration: {note}" for cal in cals.values() for note in cal.notes]
    lengths = {mode: {k: table.filled(v)[0] for k, v in apply_calibration(table, cal).items()}
               for mode, cal in cals.items()}
    calib_ids = {(s.excursion, s.index) for pool in pools["multi-speed"] for s in pool}
    rows: list[dict] = []
    truth_ratio: list[float] = []
    st = rec.truth["steps"]
    exact_m5, twin, exact_dur = _m5_exact_timing(table, st, pools, leg_length_m=sub.leg_length_m,
                                                 foot_length_m=sub.foot_length_m, subject=sub.subject_id)
    m5: dict[str, Any] = {mode: {"section_detected": [], "section_exact": []} for mode in MODES}
    evaluated = np.zeros(table.n_steps)         # each step's weight in the evaluated sections
    for s in sections:
        if (s.excursion, s.index) in calib_ids or (s.turn and not include_turn):
            continue
        f = section_fractions(table, s.t_start_s, s.t_end_s, edge=edge)
        evaluated += f
        # truth check: the world's own step lengths cut the same way (should be ~1: path vs corridor)
        t_a = np.asarray(st["heel_strike_s"])
        t_b = np.asarray(st["next_heel_strike_s"])
        ft = np.clip((np.minimum(t_b, s.t_end_s) - np.maximum(t_a, s.t_start_s)) / (t_b - t_a), 0, 1)
        truth_ratio.append(float(np.sum(ft * st["length_m"]) / s.real_m))
        for mode in MODES:
            m5[mode]["section_detected"].append(float(np.sum(f * lengths[mode]["M5"])) / s.real_m)
            m5[mode]["section_exact"].append(float(np.sum(f * exact_m5[mode])) / s.real_m)
            for est in ESTIMATORS:
                d = float(np.sum(f * lengths[mode][est]))
                rows.append({"subject": sub.subject_id, "excursion": s.excursion, "speed_label": s.speed_label,
                             "section": s.index, "start_m": s.start_m, "end_m": s.end_m, "turn": s.turn,
                             "mode": mode, "estimator": est, "estimated_m": d, "real_m": s.real_m,
                             "ratio": d / s.real_m, "steps": float(np.sum(f))})
    events = score_events(table, st)
    step = (twin >= 0) & (evaluated >= 0.5)      # per step: the paired steps of the evaluated sections
    true_len = np.asarray(st["length_m"], np.float64)[twin[step]]
    m5["timing_error_s"] = table.duration_s[step] - exact_dur[step]
    for mode in MODES:
        for key in ("section_detected", "section_exact"):
            m5[mode][key] = np.asarray(m5[mode][key], np.float64)
        m5[mode]["step_detected"] = lengths[mode]["M5"][step] / true_len - 1.0
        m5[mode]["step_exact"] = exact_m5[mode][step] / true_len - 1.0
    return SubjectResult(sub.subject_id, rows, events, cals, caught, truth_ratio, m5)


def _m5_exact_timing(table: Any, truth_steps: dict, pools: dict[str, Any], *, leg_length_m: float,
                     foot_length_m: float, subject: str) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """M5 with each detected step's duration replaced by its generating heel-strike interval.

    A detected step (window: previous foot-flat to its foot-flat) is paired with the world's step whose
    heel-strike interval holds the window's midpoint (robust to a foot-flat misplaced by up to half a step,
    which pairing the foot-flats themselves is not: it keeps only the steps detected on time); its exact
    duration is that step's ``next_heel_strike_s - heel_strike_s``; windowless steps keep their detected one.
    The M5 line is fitted again on the exact durations, on the same sections: a logger timing every step
    exactly would be calibrated with those times, and a line fitted on detected times carries their bias
    (e.g. ``mean(1/T)`` of alternating long and short detected steps) into the exact variant. Returns the
    exact-timing M5 lengths per mode (filled as the detected ones), and per detected step the index of its
    world twin (-1: none) and its exact duration.
    """
    hs = np.asarray(truth_steps["heel_strike_s"], np.float64)
    nhs = np.asarray(truth_steps["next_heel_strike_s"], np.float64)
    order = np.argsort(hs, kind="stable")
    mid = 0.5 * (table.time_s(table.start) + table.time_s(table.foot_flat))
    k = np.searchsorted(hs[order], mid, side="right") - 1
    idx = np.where((k >= 0) & np.isfinite(mid), order[np.clip(k, 0, None)], -1)
    idx[(idx >= 0) & ~(mid < nhs[np.clip(idx, 0, None)])] = -1
    paired = (idx >= 0) & np.isfinite(table.duration_s)
    idx[~paired] = -1
    dur = table.duration_s.copy()
    dur[paired] = nhs[idx[paired]] - hs[idx[paired]]
    raw = dict(table.raw_m)
    raw["M5"] = np.where(dur > 0, 1.0 / dur, np.nan)
    exact = replace(table, duration_s=dur, raw_m=raw)
    lengths = {mode: exact.filled(apply_calibration(exact, calibrate_on_sections(
        exact, pools[mode], leg_length_m=leg_length_m, foot_length_m=foot_length_m, subject=subject))["M5"])[0]
        for mode in MODES}
    return lengths, idx, dur


def _subject_job(job: tuple) -> SubjectResult:
    subject, seed, walk_plan, sampling_rate_hz, adc_bits, calibrate_device, laps, options = job
    rec = record_subject(subject, seed=seed, walk_plan=walk_plan, sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits,
                         calibrate_device=calibrate_device, laps=laps)
    return evaluate_recording(rec, corridor_length_m=(walk_plan.corridor_length_m if walk_plan else 100.0),
                              **options)


# ---------------------------------------------------------------------------------------------------------
# Population


def summarise(rows: Iterable[dict]) -> list[dict]:
    """Median, quartiles and extremes of the ratio per (mode, estimator) (NaN ratios are skipped)."""
    groups: dict[tuple[str, str], list[float]] = {}
    for r in rows:
        groups.setdefault((r["mode"], r["estimator"]), []).append(float(r["ratio"]))
    out = []
    for mode in MODES:
        for est in ESTIMATORS:
            v = np.asarray(groups.get((mode, est), []), np.float64)
            v = v[np.isfinite(v)]
            if v.size == 0:
                continue
            q1, med, q3 = np.percentile(v, [25, 50, 75])
            out.append({"mode": mode, "estimator": est, "n": int(v.size), "median": float(med), "q1": float(q1),
                        "q3": float(q3), "min": float(v.min()), "max": float(v.max()), "iqr": float(q3 - q1)})
    return out


def paper_pattern(summary: Sequence[dict]) -> dict[str, tuple[bool, str]]:
    """The qualitative findings of Alvarez et al. (IV-V), checked on a summary.

    - ``m1_widest``: with single-speed calibration M1 has the largest spread (IQR and range) of M1, M2, M4;
    - ``multi_narrower``: multi-speed calibration narrows M1, M2 and M4 (IQR of each, 0.2 % tolerance:
      "all the methods improve ... mainly through a significant reduction in the standard deviation");
    - ``m3_comparable``: uncalibrated M3's median is within 5 % of 1, no farther from 1 than 0.03 plus the
      worse of single-speed M2/M4, and its IQR is at most 1.5 times the larger of theirs.
    """
    s = {(r["mode"], r["estimator"]): r for r in summary}

    def g(mode: str, est: str, key: str) -> float:
        return float(s[(mode, est)][key])

    def rng(mode: str, est: str) -> float:
        return g(mode, est, "max") - g(mode, est, "min")

    out: dict[str, tuple[bool, str]] = {}
    ss = "single-speed"
    iqr = {e: g(ss, e, "iqr") for e in ("M1", "M2", "M4")}
    ranges = {e: rng(ss, e) for e in ("M1", "M2", "M4")}
    out["m1_widest"] = (iqr["M1"] >= max(iqr["M2"], iqr["M4"]) and ranges["M1"] >= max(ranges["M2"], ranges["M4"]),
                        f"single-speed IQR M1/M2/M4 = {iqr['M1']:.3f}/{iqr['M2']:.3f}/{iqr['M4']:.3f}, "
                        f"range {ranges['M1']:.3f}/{ranges['M2']:.3f}/{ranges['M4']:.3f}")
    narrower = {e: g("multi-speed", e, "iqr") <= g(ss, e, "iqr") + 0.002 for e in ("M1", "M2", "M4")}
    out["multi_narrower"] = (all(narrower.values()), "IQR single->multi: " + ", ".join(
        f"{e} {g(ss, e, 'iqr'):.3f}->{g('multi-speed', e, 'iqr'):.3f}" for e in ("M1", "M2", "M4")))
    m3_med, m3_iqr = g(ss, "M3", "median"), g(ss, "M3", "iqr")
    worst = max(abs(g(ss, "M2", "median") - 1), abs(g(ss, "M4", "median") - 1))
    ok = abs(m3_med - 1) <= 0.05 and abs(m3_med - 1) <= worst + 0.03 and m3_iqr <= 1.5 * max(g(ss, "M2", "iqr"),
                                                                                             g(ss, "M4", "iqr"))
    out["m3_comparable"] = (ok, f"M3 median {m3_med:.3f} IQR {m3_iqr:.3f}; single-speed M2 median "
                                f"{g(ss, 'M2', 'median'):.3f} IQR {g(ss, 'M2', 'iqr'):.3f}, M4 median "
                                f"{g(ss, 'M4', 'median'):.3f} IQR {g(ss, 'M4', 'iqr'):.3f}")
    return out


# ---------------------------------------------------------------------------------------------------------
# Intervals over subjects, the paper side by side, M5 and the step timing

#: The figures of :func:`bootstrap_summary`, per (mode, estimator).
BOOT_STATISTICS = ("median", "q1", "q3", "iqr", "min", "max")

#: What Alvarez et al. (2006, IV) state in their text about Figs 5-6, ratio estimated / real per 20 m section.
#: The box plots themselves are not in the OCR'd text (../shared/seeds), so their quartiles are unknown:
#: "Methods M1 to M4 ... median values vary between 100% and 105%" (both calibrations); "the worst case error
#: was obtained with method M1 using single speed calibration, and was almost a 40% higher than the real
#: value"; "Method M5 has the lower median of all (98%)" (multi-speed, Fig 6).
PAPER_MEDIAN_RANGE = (1.00, 1.05)
PAPER_M1_SINGLE_MAX = 1.40
#: :data:`PAPER_M1_SINGLE_MAX` ("almost a 40% higher") as the band the simulation's interval must reach.
PAPER_M1_SINGLE_MAX_BAND = (1.35, 1.45)
PAPER_M5_MEDIAN = 0.98


def _section_stats(v: np.ndarray) -> np.ndarray:
    """``BOOT_STATISTICS`` of a set of ratios (NaN when empty)."""
    v = v[np.isfinite(v)]
    if v.size == 0:
        return np.full(len(BOOT_STATISTICS), np.nan)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return np.array([med, q1, q3, q3 - q1, v.min(), v.max()])


def bootstrap_summary(results: Sequence[SubjectResult], *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0,
                      level: float = BOOTSTRAP_LEVEL) -> list[dict]:
    """:func:`summarise`'s figures (``BOOT_STATISTICS``) per mode and estimator with percentile-bootstrap
    intervals over subjects (subjects drawn with replacement, the same draws for every figure; a subject drawn
    twice counts twice). One row per (mode, estimator, statistic): ``value``, ``ci_low``, ``ci_high``."""
    counts = subject_resamples(len(results), n_resamples=n_resamples, seed=seed)
    out = []
    for mode in MODES:
        for est in ESTIMATORS:
            groups = [np.array([r["ratio"] for r in res.rows if r["mode"] == mode and r["estimator"] == est], float)
                      for res in results]
            if not any(g.size for g in groups):
                continue
            value, lo, hi = subject_bootstrap(groups, _section_stats, counts, level=level)
            for k, name in enumerate(BOOT_STATISTICS):
                out.append({"mode": mode, "estimator": est, "statistic": name, "value": float(value[k]),
                            "ci_low": float(lo[k]), "ci_high": float(hi[k]), "n_subjects": len(results)})
    return out


@dataclass(frozen=True)
class _Intervals:
    """:func:`bootstrap_summary`'s rows by ``(mode, estimator, statistic)``, read the ways the claims read them."""

    rows: dict[tuple[str, str, str], dict]

    @classmethod
    def of(cls, boot: Sequence[dict]) -> _Intervals:
        return cls({(r["mode"], r["estimator"], r["statistic"]): r for r in boot})

    def has(self, mode: str, est: str, stat: str) -> bool:
        return (mode, est, stat) in self.rows

    def value(self, mode: str, est: str, stat: str) -> float:
        return self.rows[(mode, est, stat)]["value"]

    def interval(self, mode: str, est: str, stat: str) -> tuple[float, float]:
        r = self.rows[(mode, est, stat)]
        return r["ci_low"], r["ci_high"]

    def figure(self, mode: str, est: str, stat: str) -> str:
        """The figure and its interval in per cent: ``"98.0 [96.1, 99.1]"``."""
        r = self.rows[(mode, est, stat)]
        return f"{100 * r['value']:.1f} [{100 * r['ci_low']:.1f}, {100 * r['ci_high']:.1f}]"

    def reaches(self, mode: str, est: str, stat: str, lo: float, hi: float) -> bool:
        """Whether the figure's interval reaches the range ``[lo, hi]``."""
        ci_low, ci_high = self.interval(mode, est, stat)
        return ci_high >= lo and ci_low <= hi


_SS, _MS = "single-speed", "multi-speed"


def _medians_in_band(t: _Intervals, mode: str) -> tuple[str, str]:
    """Whether every M1-M4 median of ``mode`` reaches :data:`PAPER_MEDIAN_RANGE` with its interval (those that
    do not are named)."""
    ests = [e for e in ("M1", "M2", "M3", "M4") if t.has(mode, e, "median")]
    outside = [e for e in ests if not t.reaches(mode, e, "median", *PAPER_MEDIAN_RANGE)]
    figures = ", ".join(f"{e} {t.figure(mode, e, 'median')}" for e in ests)
    return figures, f"disagrees ({', '.join(outside)} outside)" if outside else "agrees"


def _m1_worst_case(t: _Intervals) -> tuple[str, str]:
    """Single-speed M1's largest ratio reaches :data:`PAPER_M1_SINGLE_MAX_BAND`."""
    return "M1 max " + t.figure(_SS, "M1", "max"), (
        "agrees" if t.reaches(_SS, "M1", "max", *PAPER_M1_SINGLE_MAX_BAND) else "disagrees")


def _m1_widest(t: _Intervals) -> tuple[str, str]:
    """Single-speed M1's IQR is the largest of M1-M4; the verdict says whether its interval clears M2's and M4's."""
    widest = all(t.value(_SS, "M1", "iqr") >= t.value(_SS, e, "iqr") for e in ("M2", "M3", "M4"))
    apart = all(t.interval(_SS, "M1", "iqr")[0] > t.interval(_SS, e, "iqr")[1] for e in ("M2", "M4"))
    figures = "IQR " + ", ".join(f"{e} {t.figure(_SS, e, 'iqr')}" for e in ("M1", "M2", "M3", "M4"))
    if not widest:
        return figures, "disagrees"
    return figures, "agrees" + (" (intervals apart from M2, M4)" if apart else " (intervals overlap)")


def _multi_speed_improves(t: _Intervals) -> tuple[str, str]:
    """Multi-speed K narrows M1, M2, M4 (IQR) and brings their medians no farther from 1."""
    ests = ("M1", "M2", "M4")
    iqr = {e: (t.value(_SS, e, "iqr"), t.value(_MS, e, "iqr")) for e in ests}
    off = {e: (abs(t.value(_SS, e, "median") - 1), abs(t.value(_MS, e, "median") - 1)) for e in ests}
    worse = {e: [name for name, ok in (("IQR", iqr[e][1] < iqr[e][0]), ("median", off[e][1] <= off[e][0])) if not ok]
             for e in ests}
    figures = ("IQR " + ", ".join(f"{e} {100 * s:.1f}->{100 * m:.1f}" for e, (s, m) in iqr.items())
               + "; |median-1| " + ", ".join(f"{e} {100 * s:.1f}->{100 * m:.1f}" for e, (s, m) in off.items()))
    if not any(worse.values()):
        return figures, "agrees"
    return figures, "disagrees (" + ", ".join(f"{e}: {' and '.join(w)} not better" for e, w in worse.items() if w) + ")"


def _m5_lowest_median(t: _Intervals) -> tuple[str, str]:
    """Multi-speed M5's median is the lowest of all estimators', and its interval reaches :data:`PAPER_M5_MEDIAN`."""
    lowest = all(t.value(_MS, "M5", "median") <= t.value(_MS, e, "median") for e in ESTIMATORS if e != "M5")
    if not lowest:
        verdict = "disagrees (not the lowest)"
    elif not t.reaches(_MS, "M5", "median", PAPER_M5_MEDIAN, PAPER_M5_MEDIAN):
        verdict = "disagrees (98 % outside the interval)"
    else:
        verdict = "agrees"
    return "M5 " + t.figure(_MS, "M5", "median"), verdict


def _m5_wide(t: _Intervals) -> tuple[str, str]:
    """Multi-speed M5's IQR is at least M2's and M4's."""
    wide = t.value(_MS, "M5", "iqr") >= max(t.value(_MS, e, "iqr") for e in ("M2", "M4"))
    figures = ", ".join(f"{e} {t.figure(_MS, e, 'iqr')}" for e in ("M5", "M2", "M4"))
    return "IQR " + figures, "agrees" if wide else "disagrees (M5 narrower than M2/M4)"


def _m3_comparable(t: _Intervals) -> tuple[str, str]:
    """Uncalibrated M3 (single speed) is no farther from 1 than 0.03 plus the worse of M2/M4, and its IQR at
    most 1.5 times the larger of theirs."""
    m3, worst = t.value(_SS, "M3", "median"), max(abs(t.value(_SS, e, "median") - 1) for e in ("M2", "M4"))
    comparable = (abs(m3 - 1) <= worst + 0.03
                  and t.value(_SS, "M3", "iqr") <= 1.5 * max(t.value(_SS, e, "iqr") for e in ("M2", "M4")))
    figures = f"M3 {t.figure(_SS, 'M3', 'median')}, IQR {t.figure(_SS, 'M3', 'iqr')}"
    return figures, "agrees" if comparable else "disagrees"


#: The paper's stated findings, in :func:`paper_claims`'s order: the claim, what the paper states, and its judge
#: (the simulation's figures and the verdict, from the intervals).
_PAPER_CLAIMS: tuple[tuple[str, str, Callable[[_Intervals], tuple[str, str]]], ...] = (
    *((f"{mode}: M1-M4 medians 100-105 %", "100-105", functools.partial(_medians_in_band, mode=mode))
      for mode in MODES),
    ("single-speed: M1 worst case ~140 %", "~140", _m1_worst_case),
    ("single-speed: M1 has the highest variance", "M1 widest", _m1_widest),
    ("multi-speed K improves M1, M2, M4 (median and spread)", "all improve", _multi_speed_improves),
    ("multi-speed: M5 has the lowest median (98 %)", "98, lowest", _m5_lowest_median),
    ("multi-speed: M5 has a high variance", "high", _m5_wide),
    ("M3 without K comparable to single-speed M2, M4", "similar", _m3_comparable),
)


def paper_claims(boot: Sequence[dict]) -> list[tuple[str, str, str, str]]:
    """The paper's stated findings against the simulation: ``(claim, paper, simulation, verdict)`` rows, one per
    claim of the module's table ``_PAPER_CLAIMS``.

    A figure agrees when its 95 % interval reaches the paper's value (or range); an ordering ("M1 widest",
    "multi-speed narrower") agrees when it holds for the point estimates, and the verdict says whether the
    intervals separate."""
    t = _Intervals.of(boot)
    return [(claim, paper, *judge(t)) for claim, paper, judge in _PAPER_CLAIMS]


def format_paper_table(boot: Sequence[dict]) -> str:
    """The side-by-side table: per mode and estimator the simulation's median, IQR and extremes with their
    intervals over subjects, and what the paper states; then :func:`paper_claims`."""
    if not boot:
        return "paper side by side: no section"
    n_sub = boot[0]["n_subjects"]
    b = {(r["mode"], r["estimator"], r["statistic"]): r for r in boot}

    def cell(mode: str, est: str, stat: str) -> str:
        r = b[(mode, est, stat)]
        return f"{100 * r['value']:5.1f} [{100 * r['ci_low']:5.1f},{100 * r['ci_high']:5.1f}]"

    def paper(mode: str, est: str) -> tuple[str, str]:
        med = "98" if (mode, est) == ("multi-speed", "M5") else "100-105" if est != "M5" else "n/s"
        ext = "max ~140" if (mode, est) == ("single-speed", "M1") else "n/s"
        return med, ext

    lines = [(f"side by side with Alvarez et al. (2006) Figs 5-6: ratio estimated / real per 20 m section, % "
              f"[{100 * BOOTSTRAP_LEVEL:.0f} % bootstrap interval over {n_sub} subjects]; paper: what its text "
              "states (n/s: not stated; its box plots are not in the text)"),
             (f"{'mode':<13}{'est':<4}{'median':>20}{'IQR':>20}{'min':>20}{'max':>20}  {'paper median':>13}"
              f"{'paper extremes':>16}")]
    for mode in MODES:
        for est in ESTIMATORS:
            if (mode, est, "median") not in b:
                continue
            med, ext = paper(mode, est)
            lines.append(f"{mode:<13}{est:<4}" + "".join(f"{cell(mode, est, s):>20}" for s in
                                                          ("median", "iqr", "min", "max")) + f"  {med:>13}{ext:>16}")
    lines.append("")
    lines.append("the paper's findings on the simulated population:")
    for claim, pap, sim, verdict in paper_claims(boot):
        lines.append(f"  {claim} (paper: {pap}): {sim} -> {verdict}")
    return "\n".join(lines)


def m5_timing_question(results: Sequence[SubjectResult], *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ,
                       n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0, level: float = BOOTSTRAP_LEVEL) -> dict:
    """Does M5's spread come from timing steps at ``sampling_rate_hz``? (Alvarez et al. V: "A possible reason
    for this is the low temporal resolution in the measurement of the step duration".)

    Per mode and level (``step``: each paired step's relative error against the world's step length;
    ``section``: the 20 m section ratios), M5 with the detected step durations against M5 with the generating
    heel-strike intervals (:func:`_m5_exact_timing`, its line fitted on them): the IQR and standard deviation
    of each and ``timing_share = 1 - (IQR(exact) / IQR(detected))²``, the part of M5's spread the step timing
    adds (robust: a variance ratio is dominated by the few steps whose events the detector misplaces by a
    large fraction of a step), each with a bootstrap interval over subjects; and the detected durations' rms error against the heel-strike
    intervals, with the part the sample period alone explains (``1 / (rate √6)``, two uniform roundings).
    The answer, per level: "yes" when the share's interval lies above 0.5 in some mode, "partly" when it lies
    above 0 with the share at least 0.25, else "no" (no share distinguishable from none, or a small one).
    """
    counts = subject_resamples(len(results), n_resamples=n_resamples, seed=seed)

    def spread(det: np.ndarray, exa: np.ndarray) -> np.ndarray:
        ok = np.isfinite(det) & np.isfinite(exa)
        d, e = det[ok], exa[ok]
        if d.size < 3:
            return np.full(5, np.nan)
        vd, ve = np.var(d, ddof=1), np.var(e, ddof=1)
        (d1, d3), (e1, e3) = np.percentile(d, [25, 75]), np.percentile(e, [25, 75])
        return np.array([d3 - d1, e3 - e1, np.sqrt(vd), np.sqrt(ve),
                         1.0 - ((e3 - e1) / (d3 - d1)) ** 2 if d3 > d1 else np.nan])

    rows = []
    for mode in MODES:
        for level_name in ("step", "section"):
            det = [np.asarray(r.m5[mode][f"{level_name}_detected"], float) for r in results]
            exa = [np.asarray(r.m5[mode][f"{level_name}_exact"], float) for r in results]
            value, lo, hi = subject_bootstrap(det, spread, counts, exa, level=level)
            row = {"mode": mode, "level": level_name, "n": int(sum(d.size for d in det)), "n_subjects": len(results)}
            for k, name in enumerate(("iqr_detected", "iqr_exact", "sd_detected", "sd_exact", "timing_share")):
                row[name], row[name + "_low"], row[name + "_high"] = float(value[k]), float(lo[k]), float(hi[k])
            rows.append(row)
    err = np.concatenate([np.asarray(r.m5["timing_error_s"], float) for r in results])
    err = err[np.isfinite(err)]
    timing = {"rms_ms": float(1e3 * np.sqrt(np.mean(err ** 2))) if err.size else float("nan"),
              "sampling_rms_ms": float(1e3 / sampling_rate_hz / np.sqrt(6.0)), "n_steps": int(err.size)}
    answer = {}
    for level_name in ("step", "section"):
        sel = [r for r in rows if r["level"] == level_name]
        answer[level_name] = ("yes" if any(r["timing_share_low"] >= 0.5 for r in sel) else
                              "partly" if any(r["timing_share_low"] > 0 and r["timing_share"] >= 0.25 for r in sel)
                              else "no")
    return {"rows": rows, "timing": timing, "answer": answer}


def format_m5_question(m5: dict) -> str:
    """Printed :func:`m5_timing_question`."""
    if not m5.get("rows"):
        return "M5 and the step timing: no steps"
    t = m5["timing"]
    lines = [(f"M5 and the step timing (exact = the world's generating heel-strike intervals, M5's line refitted on "
              f"them; "
              f"{100 * BOOTSTRAP_LEVEL:.0f} % intervals over {m5['rows'][0]['n_subjects']} subjects): step = "
              "relative error of each step against its true length, section = 20 m ratio"),
             f"{'mode':<13}{'level':<8}{'n':>6}{'IQR detected T':>24}{'IQR exact T':>24}{'timing share':>24}"]

    def c(r: dict, k: str) -> str:
        return f"{100 * r[k]:5.1f} [{100 * r[k + '_low']:5.1f},{100 * r[k + '_high']:5.1f}]"

    for r in m5["rows"]:
        lines.append(f"{r['mode']:<13}{r['level']:<8}{r['n']:>6}{c(r, 'iqr_detected'):>24}{c(r, 'iqr_exact'):>24}"
                     f"{c(r, 'timing_share'):>24}")
    text = {"yes": "yes, the step timing is the major part of M5's spread",
            "partly": "partly, the step timing is a visible part of M5's spread",
            "no": "no, M5's spread does not come from the step timing"}
    lines.append(f"detected step durations off the heel-strike intervals by {t['rms_ms']:.0f} ms rms "
                 f"({t['n_steps']} steps), of which the sample period alone explains {t['sampling_rms_ms']:.0f} ms")
    lines.append(f"M5 and the step timing: per step {text[m5['answer']['step']]}; per 20 m section "
                 f"{text[m5['answer']['section']]}" + (" (what remains is the cadence-length line itself)"
                                                       if m5["answer"]["section"] == "no" else ""))
    return "\n".join(lines)


def format_summary(summary: Sequence[dict], events: dict[str, EventScore] | None = None) -> str:
    """A plain-text table of the summary (ratios in %), with the pooled event scores when given."""
    lines = [f"{'mode':<13}{'est':<5}{'n':>5}{'median':>9}{'q1':>8}{'q3':>8}{'min':>8}{'max':>8}{'IQR':>7}"]
    for r in summary:
        lines.append(f"{r['mode']:<13}{r['estimator']:<5}{r['n']:>5}{100 * r['median']:>8.1f}%"
                     f"{100 * r['q1']:>7.1f}%{100 * r['q3']:>7.1f}%{100 * r['min']:>7.1f}%{100 * r['max']:>7.1f}%"
                     f"{100 * r['iqr']:>6.1f}%")
    if events:
        lines.append("")
        lines.append(f"{'event':<12}{'truth':>7}{'found':>7}{'F1':>7}{'|err| med':>11}{'bias':>9}")
        for e in events.values():
            lines.append(f"{e.event:<12}{e.n_truth:>7}{e.n_detected:>7}{e.f1:>7.3f}"
                         f"{1000 * e.median_abs_error_s:>9.1f}ms{1000 * e.median_error_s:>7.1f}ms")
    return "\n".join(lines)


class SimulatedEvaluation:
    """Run N simulated subjects through the protocol, the logger and the float chain; evaluate.

    Parameters
    ----------
    n_subjects, seed
        Subjects drawn by :func:`gaitlog.firmware_sim.world.subject.random_subjects` (``seed``); subject ``i`` walks
        with seed ``seed * 1000 + i`` (independent of ``n_subjects`` and of ``workers``).
    walk_plan
        :class:`~gaitlog.firmware_sim.world.walk_plan.WalkPlan` (default: the paper's, with the population's gait
        initiation and turn, :data:`~gaitlog.firmware_sim.world.walk_plan.POPULATION_PLANS`).
    population
        ``"people"`` (default: the walker tuned to real lower-back walking) or ``"v1"``.
    protocol
        ``"compact"`` (default: 60 s rests logged, the population's heights) or ``"paper"`` (Alvarez's
        protocol as run: 5-minute rests with the logger stopped, subjects of the paper's heights;
        :func:`gaitlog.host.studies.simulation.simulated_population`).
    laps
        ``"mark"`` (default: the logger's MARK button, exact) or ``"stopwatch"`` (the paper's observer,
        :mod:`gaitlog.firmware_sim.world.stopwatch`, placed on the recording by :mod:`gaitlog.host.gait.stopwatch_laps`;
        needs the ``"paper"`` protocol's one logging run per excursion).
    n_resamples
        Bootstrap resamples of the subjects for the intervals (0: no intervals, no M5 question).
    sampling_rate_hz, adc_bits
        Logger rate and ADC resolution.
    workers
        Processes (``concurrent.futures``); 1 runs in this process. Results do not depend on it.
    section_m, include_turn, edge, calibration_sections
        See :func:`evaluate_recording`.
    calibrate_device
        Fit the device calibration on a pose session first.
    detector
        :class:`gaitlog.host.gait.events.GaitEventDetector` of the pipeline (None: default parameters).

    Attributes
    ----------
    results_
        One :class:`SubjectResult` per subject.
    rows_, summary_
        All section rows, and :func:`summarise` of them.
    events_
        Event scores pooled over subjects.
    bootstrap_, m5_
        :func:`bootstrap_summary` and :func:`m5_timing_question` (empty when ``n_resamples`` is 0).
    """

    def __init__(self, *, n_subjects: int = 4, seed: int = 0, walk_plan: Any = None, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ,
                 adc_bits: int = 10, workers: int = 1, section_m: float = 20.0, include_turn: bool = False,
                 edge: str = "fraction", calibration_sections: int = 2, calibrate_device: bool = True,
                 detector: Any = None, population: str = "people", protocol: str = "compact", laps: str = "mark",
                 n_resamples: int = BOOTSTRAP_RESAMPLES) -> None:
        self.n_subjects = n_subjects
        self.protocol = protocol
        self.laps = laps
        self.n_resamples = n_resamples
        self.population = population
        self.seed = seed
        self.walk_plan = walk_plan
        self.sampling_rate_hz = sampling_rate_hz
        self.adc_bits = adc_bits
        self.workers = workers
        self.section_m = section_m
        self.include_turn = include_turn
        self.edge = edge
        self.calibration_sections = calibration_sections
        self.calibrate_device = calibrate_device
        self.detector = detector

    def run(self, progress: Callable[[], object] | None = None) -> Self:
        """Simulate, record, estimate and evaluate every subject; ``progress()`` is called after each one."""
        if self.n_subjects < 1:
            raise HostError(f"n_subjects must be >= 1, got {self.n_subjects}")
        options = dict(section_m=self.section_m, include_turn=self.include_turn, edge=self.edge,
                       calibration_sections=self.calibration_sections, detector=self.detector)
        subjects, walk_plan = simulated_population(self.n_subjects, seed=self.seed, population=self.population,
                                                   walk_plan=self.walk_plan, protocol=self.protocol)
        if self.laps == "stopwatch" and (walk_plan is None or walk_plan.logger_runs != "per-excursion"):
            raise HostError("stopwatch laps need the logger STARTed and STOPped around each excursion (the paper's "
                            "protocol); use MARK laps with this walk plan")
        jobs = [(s, self.seed * 1000 + i, walk_plan, self.sampling_rate_hz, self.adc_bits, self.calibrate_device,
                 self.laps, options) for i, s in enumerate(subjects)]
        self.results_ = map_subjects(_subject_job, jobs, workers=self.workers, progress=progress)
        self.rows_ = [r for res in self.results_ for r in res.rows]
        self.summary_ = summarise(self.rows_)
        self.events_ = pool_event_scores([res.events for res in self.results_])
        self.bootstrap_, self.m5_ = [], {}
        if self.n_resamples > 0 and self.results_:
            self.bootstrap_ = bootstrap_summary(self.results_, n_resamples=self.n_resamples, seed=self.seed)
            self.m5_ = m5_timing_question(self.results_, sampling_rate_hz=self.sampling_rate_hz,
                                          n_resamples=self.n_resamples, seed=self.seed)
        return self

    def format_table(self) -> str:
        """Printed table: summary and events, then (with intervals) the paper side by side and M5's question."""
        text = format_summary(self.summary_, self.events_)
        if self.bootstrap_:
            text += "\n\n" + format_paper_table(self.bootstrap_) + "\n\n" + format_m5_question(self.m5_)
        return text

    def to_json(self, out: str | Path, paths: dict[str, Path]) -> str:
        """The summary, the intervals and the files :meth:`write_outputs` wrote into ``out`` (``paths``) as one
        JSON document."""
        return json_text({"out": str(out), "summary": self.summary_, "intervals": self.bootstrap_, "files": paths})

    def write_csv(self, path: str | Path, *, summary_path: str | Path | None = None) -> None:
        """Section rows (``ROW_COLUMNS``) to ``path`` and optionally the summary to ``summary_path``, atomically."""
        atomic_write_text(path, rows_csv_text(self.rows_, ROW_COLUMNS))
        if summary_path is not None:
            atomic_write_text(summary_path, rows_csv_text(self.summary_, SUMMARY_COLUMNS))


    def write_outputs(self, out_dir: str | Path, *, stem: str = "simulated", title: str | None = None) -> dict[str, Path]:
        """Rows CSV, summary CSV and the Figs 5-6 box plot into ``out_dir`` (each written atomically)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"rows": out / f"{stem}_sections.csv", "summary": out / f"{stem}_summary.csv",
                 "figure": out / f"{stem}_boxplots.png"}
        self.write_csv(paths["rows"], summary_path=paths["summary"])
        if self.bootstrap_:
            paths["intervals"] = out / f"{stem}_intervals.csv"
            atomic_write_text(paths["intervals"], rows_csv_text(self.bootstrap_, BOOT_COLUMNS))
        plot_boxplots(self.rows_, paths["figure"], title=title or (
            f"{self.n_subjects} simulated subjects, {self.sampling_rate_hz:g} Hz, {self.adc_bits} bit"))
        return paths


def pool_event_scores(per_subject: Sequence[dict[str, EventScore]]) -> dict[str, EventScore]:
    """Counts summed over subjects; timing errors: median of the subjects' medians."""
    out = {}
    for name in ("heel_strike", "toe_off", "foot_flat", "com_min"):
        xs = [p[name] for p in per_subject if name in p]
        if not xs:
            continue
        out[name] = EventScore(name, sum(x.n_truth for x in xs), sum(x.n_detected for x in xs),
                               sum(x.n_matched for x in xs),
                               float(np.nanmedian([x.median_abs_error_s for x in xs])),
                               float(np.nanmedian([x.median_error_s for x in xs])))
    return out

