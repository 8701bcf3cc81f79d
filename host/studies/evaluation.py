"""The paper's evaluation on simulated subjects (Alvarez et al. 2006, sections II-C and IV, Figs 5-6).

Chain, per subject (:func:`host.studies.simulation.record_subject`, :func:`evaluate_recording`):

1. *Device calibration*: the emulated logger (:class:`firmware_sim.device.Logger`, its own seeded sensor
   errors: offsets, sensitivities, misalignment) records a static-pose session
   (:class:`firmware_sim.world.poses.CalibrationPoses`), fitted with :class:`host.accelerometer.fit.AccCalibrator`
   ("a calibration procedure takes into account offset and scale factors and the orthogonality of the
   axes", II-B). ``calibrate_device=False`` uses the header's nominal map instead.
2. *Walking*: the same logger (after ERASE) records the protocol of
   :class:`firmware_sim.world.walking.Walking` (10-bit ADC at 50 Hz by default); its memory image (header +
   EEPROM, :func:`protocol.image.build_image`) is decoded as a dump would be (:func:`host.files.decode.decode_bytes`)
   and the codes converted to g with the fitted calibration. The lap button's MARK flags give the lap times.
3. *Steps*: :class:`host.gait.pipeline.StepPipeline` without calibration (raw M1-M4 lengths with K = 1,
   M5's cadence), with the subject's own leg and foot length ("the anatomical data of each individual").
4. *Sections*: consecutive lap marks 20 m apart (default marks 10, 30, ..., 190 m of each excursion:
   the first 10 m of gait initiation are discarded, as in the paper). The section holding the 180° turn is
   left out by default (the paper's subjects "were allowed to turn freely between both 100 m segments";
   the estimators model straight walking); ``include_turn=True`` keeps it.
5. *K calibration* (:func:`host.gait.sections.calibration_sets`, :func:`host.gait.k_calibration.calibrate_on_sections`):
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
:mod:`host.studies.plots`.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Self

import numpy as np

from firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ
from firmware_sim.algorithms.steps import ESTIMATORS
from host.errors import HostError
from host.gait.k_calibration import calibrate_on_sections
from host.gait.pipeline import StepPipeline, apply_calibration
from host.gait.sections import (
    MODES,
    calibration_sets,
    section_fractions,
    sections_from_marks,
)
from host.studies.compare import match_events
from host.studies.plots import plot_boxplots
from host.studies.simulation import SimulatedRecording, map_subjects, record_subject, simulated_population
from protocol.atomic_write import atomic_write_text

ROW_COLUMNS = ("subject", "excursion", "speed_label", "section", "start_m", "end_m", "turn", "mode", "estimator",
               "estimated_m", "real_m", "ratio", "steps")
SUMMARY_COLUMNS = ("mode", "estimator", "n", "median", "q1", "q3", "min", "max", "iqr")


# ---------------------------------------------------------------------------------------------------------
# Sections and distances


# (lap sections and step weights: host.gait.sections)


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


def evaluate_recording(rec: SimulatedRecording, *, section_m: float = 20.0, include_turn: bool = False,
                       edge: str = "fraction", calibration_sections: int = 2,
                       corridor_length_m: float = 100.0, detector: Any = None) -> SubjectResult:
    """Steps, K calibration (both modes), section ratios and event scores of one recording.

    ``detector``: a :class:`host.gait.events.GaitEventDetector` for the pipeline (default parameters when
    None).
    """
    sub = rec.subject
    pipe = StepPipeline(leg_length_m=sub.leg_length_m, foot_length_m=sub.foot_length_m, detector=detector).run(
        rec.acc_g, sampling_rate_hz=rec.sampling_rate_hz, valid=rec.valid, t0_s=rec.t0_s)
    table = pipe.steps_
    caught = [f"pipeline: {n}" for n in pipe.notes_]
    sections = sections_from_marks(rec.mark_times_s, rec.truth["laps"], corridor_length_m=corridor_length_m,
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
    for s in sections:
        if (s.excursion, s.index) in calib_ids or (s.turn and not include_turn):
            continue
        f = section_fractions(table, s.t_start_s, s.t_end_s, edge=edge)
        # truth check: the world's own step lengths cut the same way (should be ~1: path vs corridor)
        t_a = np.asarray(st["heel_strike_s"])
        t_b = np.asarray(st["next_heel_strike_s"])
        ft = np.clip((np.minimum(t_b, s.t_end_s) - np.maximum(t_a, s.t_start_s)) / (t_b - t_a), 0, 1)
        truth_ratio.append(float(np.sum(ft * st["length_m"]) / s.real_m))
        for mode in MODES:
            for est in ESTIMATORS:
                d = float(np.sum(f * lengths[mode][est]))
                rows.append({"subject": sub.subject_id, "excursion": s.excursion, "speed_label": s.speed_label,
                             "section": s.index, "start_m": s.start_m, "end_m": s.end_m, "turn": s.turn,
                             "mode": mode, "estimator": est, "estimated_m": d, "real_m": s.real_m,
                             "ratio": d / s.real_m, "steps": float(np.sum(f))})
    events = score_events(table, st)
    return SubjectResult(sub.subject_id, rows, events, cals, caught, truth_ratio)


def _subject_job(job: tuple) -> SubjectResult:
    subject, seed, walk_plan, sampling_rate_hz, adc_bits, calibrate_device, options = job
    rec = record_subject(subject, seed=seed, walk_plan=walk_plan, sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits,
                         calibrate_device=calibrate_device)
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


def _csv_text(rows: Sequence[dict], columns: Sequence[str]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


class SimulatedEvaluation:
    """Run N simulated subjects through the protocol, the logger and the float chain; evaluate.

    Parameters
    ----------
    n_subjects, seed
        Subjects drawn by :func:`firmware_sim.world.subject.random_subjects` (``seed``); subject ``i`` walks
        with seed ``seed * 1000 + i`` (independent of ``n_subjects`` and of ``workers``).
    walk_plan
        :class:`~firmware_sim.world.walk_plan.WalkPlan` (default: the paper's, with the population's gait
        initiation and turn, :data:`~firmware_sim.world.walk_plan.POPULATION_PLANS`).
    population
        ``"people"`` (default: the walker tuned to real lower-back walking) or ``"v1"``.
    sampling_rate_hz, adc_bits
        Logger rate and ADC resolution.
    workers
        Processes (``concurrent.futures``); 1 runs in this process. Results do not depend on it.
    section_m, include_turn, edge, calibration_sections
        See :func:`evaluate_recording`.
    calibrate_device
        Fit the device calibration on a pose session first.
    detector
        :class:`host.gait.events.GaitEventDetector` of the pipeline (None: default parameters).

    Attributes
    ----------
    results_
        One :class:`SubjectResult` per subject.
    rows_, summary_
        All section rows, and :func:`summarise` of them.
    events_
        Event scores pooled over subjects.
    """

    def __init__(self, *, n_subjects: int = 4, seed: int = 0, walk_plan: Any = None, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ,
                 adc_bits: int = 10, workers: int = 1, section_m: float = 20.0, include_turn: bool = False,
                 edge: str = "fraction", calibration_sections: int = 2, calibrate_device: bool = True,
                 detector: Any = None, population: str = "people") -> None:
        self.n_subjects = n_subjects
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
                                                   walk_plan=self.walk_plan)
        jobs = [(s, self.seed * 1000 + i, walk_plan, self.sampling_rate_hz, self.adc_bits, self.calibrate_device, options)
                for i, s in enumerate(subjects)]
        self.results_ = map_subjects(_subject_job, jobs, workers=self.workers, progress=progress)
        self.rows_ = [r for res in self.results_ for r in res.rows]
        self.summary_ = summarise(self.rows_)
        self.events_ = pool_event_scores([res.events for res in self.results_])
        return self

    def format_table(self) -> str:
        """Printed table: summary and events."""
        return format_summary(self.summary_, self.events_)

    def write_csv(self, path: str | Path, *, summary_path: str | Path | None = None) -> None:
        """Section rows (``ROW_COLUMNS``) to ``path`` and optionally the summary to ``summary_path``, atomically."""
        atomic_write_text(path, _csv_text(self.rows_, ROW_COLUMNS))
        if summary_path is not None:
            atomic_write_text(summary_path, _csv_text(self.summary_, SUMMARY_COLUMNS))


    def write_outputs(self, out_dir: str | Path, *, stem: str = "simulated", title: str | None = None) -> dict[str, Path]:
        """Rows CSV, summary CSV and the Figs 5-6 box plot into ``out_dir`` (each written atomically)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"rows": out / f"{stem}_sections.csv", "summary": out / f"{stem}_summary.csv",
                 "figure": out / f"{stem}_boxplots.png"}
        self.write_csv(paths["rows"], summary_path=paths["summary"])
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

