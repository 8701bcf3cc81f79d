"""Fixed point vs floating point vs truth: what the ADC and the PIC's arithmetic cost M1-M5 (issue 5).

The same per-step chain runs three times on one walk (:func:`compare_walk`):

* **ideal**: the float chain (:class:`host.gait.pipeline.StepPipeline`) on the sensor's analog output at
  the sample instants, before quantisation (noise, filter, sample-and-hold included; no ADC);
* **float**: the float chain on the ADC codes (``bits`` bits), converted to g with the device calibration;
* **fixed**: the firmware chain (:class:`firmware_sim.algorithms.chain.FixedStepChain`) on the same codes,
  in the PIC's arithmetic, with the same calibration quantised as the PIC keeps it.

so that ``float - ideal`` is the ADC's share of the error and ``fixed - float`` the arithmetic's; ``ideal -
truth`` is what is left (the estimators' models, the event detection, the sampling rate). Steps are matched
by time (:func:`match_steps`: foot-flats within ``tol_s``, mutual nearest); a matched pair whose window
start, heel-strike, toe-off or foot-flat differ by a sample or more is a step where the two chains
*detected different events*: it is counted and reported, and left out of the per-step differences (an
event one sample apart is a different step window, not an arithmetic error). Per-20 m segments follow the
paper's evaluation (:mod:`host.evaluation`): lap marks, K fitted per arithmetic on its own calibration
sections (single- and multi-speed), ratio estimated / real. Saturation and wrap counts of every fixed-point
run are kept (``saturation``); nothing saturates unreported.

Simulated walks (:class:`AnalogWalk`): the world (:class:`firmware_sim.world.walking.Walking`) through the
device's sensor model (:class:`firmware_sim.sensor.SensorModel`, the logger's default seeded unit) and the
front end and timer of :class:`firmware_sim.adc.Adc`, exactly as :meth:`firmware_sim.device.Logger.record`
does (same codes at 10 bits: tested), but quantised here at any width (the PIC's converter stops at 10
bits; 12 bits is the sweep's hypothetical external converter) and kept before quantisation. The device
calibration is the sensor's own truth (offsets, gains, axes), unbiased for the floor quantiser (``+0.5``
code): the comparison isolates the ADC and the arithmetic; the pose calibration's own error is evaluated in
:mod:`host.evaluation`.

Recordings (:func:`compare_recording`): a decoded recording has no truth and no analog output: fixed vs
float only, segments between MARK flags (``lap_m`` apart) or, without marks, every ``segment_m`` of the
float chain's M3 distance.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from host.errors import HostError
from firmware_sim.algorithms.steps import ESTIMATORS
from host.evaluation import MODES, Section, match_events, section_fractions, sections_from_marks
from firmware_sim.algorithms.steps import StepTable

#: Foot-flats of two chains closer than this are the same step, s.
MATCH_TOL_S = 0.1
#: Arithmetic labels.
ARITHMETICS = ("ideal", "float", "fixed")

STEP_DIFF_COLUMNS = ("pair", "estimator", "n", "median_abs_mm", "p95_abs_mm", "max_abs_mm", "bias_mm",
                     "max_rel", "n_matched", "n_different_events", "n_only_a", "n_only_b")


# ---------------------------------------------------------------------------------------------------------
# The fixed-point chain as a host StepTable


def fixed_step_table(codes: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                     calibration: Any = None, adc_calibration: Any = None, code_bits: int = 10,
                     valid: np.ndarray | None = None, t0_s: float = 0.0) -> tuple[StepTable, Any]:
    """Run :class:`~firmware_sim.algorithms.chain.FixedStepChain` and return its table as a ``StepTable``.

    Parameters
    ----------
    codes
        ``(n, 3)`` ADC codes (``code_bits`` bits).
    calibration
        :class:`~host.estimators.calibration.KCalibration` or None (as the float chain).
    adc_calibration
        The device calibration: an object with ``offset_counts`` and ``matrix_g_per_count`` (a
        :class:`protocol.header.Calibration`), a :class:`~firmware_sim.algorithms.calibration.CalibrationQ`,
        or None for the nominal map of ``code_bits``.

    Returns
    -------
    table, chain
        The ``StepTable`` (same fields as the float chain's) and the fitted chain (``ctx_``: saturation,
        wraps, cycles).
    """
    from firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
    from firmware_sim.algorithms.chain import FixedStepChain

    if adc_calibration is None:
        cal_q = nominal_calibration_q(adc_bits=code_bits)
    elif isinstance(adc_calibration, CalibrationQ):
        cal_q = adc_calibration
    else:
        cal_q = CalibrationQ.from_float(adc_calibration.offset_counts, adc_calibration.matrix_g_per_count,
                                        code_bits=code_bits)
    c = np.asarray(codes)
    ok = np.ones(c.shape[0], bool) if valid is None else np.asarray(valid, bool)
    c = np.where(ok[:, None], c, 0).astype(np.int64)          # lost samples carry no code
    chain = FixedStepChain(leg_length_m=leg_length_m, foot_length_m=foot_length_m, calibration=calibration).run(
        c, sampling_rate_hz=sampling_rate_hz, adc_calibration=cal_q, valid=ok, t0_s=t0_s)
    return StepTable(**chain.steps_.table_fields()), chain


def float_step_table(acc_g: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                     calibration: Any = None, valid: np.ndarray | None = None, t0_s: float = 0.0) -> StepTable:
    """The float chain's table (warnings about impossible excursions are silenced: they are counted as NaN)."""
    from host.gait.pipeline import StepPipeline

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return StepPipeline(leg_length_m=leg_length_m, foot_length_m=foot_length_m, calibration=calibration).run(
            acc_g, sampling_rate_hz=sampling_rate_hz, valid=valid, t0_s=t0_s).steps_


# ---------------------------------------------------------------------------------------------------------
# Matching steps


@dataclass(frozen=True)
class StepMatch:
    """Steps of table ``a`` and table ``b`` paired by time.

    Attributes
    ----------
    a, b
        Indices of the matched rows (same length).
    same_events
        For each pair: window start, heel-strike, toe-off and foot-flat all within half a sample.
    only_a, only_b
        Rows of one table with no partner in the other.
    """

    a: np.ndarray
    b: np.ndarray
    same_events: np.ndarray
    only_a: np.ndarray
    only_b: np.ndarray

    @property
    def n_matched(self) -> int:
        return int(self.a.size)

    @property
    def n_different_events(self) -> int:
        """Matched steps whose events differ, plus the steps only one chain found."""
        return int(np.count_nonzero(~self.same_events)) + int(self.only_a.size) + int(self.only_b.size)


def match_steps(a: StepTable, b: StepTable, *, tol_s: float = MATCH_TOL_S) -> StepMatch:
    """Pair the steps of two tables by foot-flat time (mutual nearest within ``tol_s``) and compare events.

    Examples
    --------
    >>> t = lambda ff, st: StepTable(50.0, 0.0, np.array(ff), np.full(len(ff), -1), np.full(len(ff), -1),
    ...                              np.array(st), np.zeros(len(ff), int), np.ones(len(ff)), np.zeros(len(ff), int))
    >>> m = match_steps(t([10, 40, 70, 100], [-1, 10, 40, 70]), t([10, 41, 100, 130], [-1, 10, 41, 100]))
    >>> m.a.tolist(), m.b.tolist(), m.same_events.tolist(), m.only_a.tolist(), m.only_b.tolist()
    ([0, 1, 3], [0, 1, 2], [True, False, False], [2], [3])
    >>> m.n_different_events
    4
    """
    ta, tb = a.time_s(a.foot_flat), b.time_s(b.foot_flat)
    oa, ob = np.argsort(ta, kind="stable"), np.argsort(tb, kind="stable")
    ia, ib = match_events(ta[oa], tb[ob], tol_s)
    ia, ib = oa[ia], ob[ib]
    half = 0.5 / max(a.sampling_rate_hz, b.sampling_rate_hz)
    same = np.ones(ia.size, bool)
    for name in ("start", "heel_strike", "toe_off", "foot_flat"):
        xa, xb = getattr(a, name)[ia], getattr(b, name)[ib]
        both = (xa >= 0) & (xb >= 0)
        close = np.abs(a.time_s(np.where(both, xa, 0)) - b.time_s(np.where(both, xb, 0))) < half
        same &= np.where(both, close, (xa < 0) & (xb < 0))
    return StepMatch(ia, ib, same, np.setdiff1d(np.arange(a.n_steps), ia), np.setdiff1d(np.arange(b.n_steps), ib))


def step_differences(a: StepTable, b: StepTable, match: StepMatch, *, pair: str = "a-b",
                     only_same_events: bool = True) -> list[dict]:
    """Per estimator, the per-step difference ``a - b`` of ``length_m`` on the matched steps.

    Steps where either length is NaN are skipped; with ``only_same_events`` so are the pairs whose events
    differ (they are counted in ``n_different_events``). ``max_rel`` is ``max |a - b| / |b|``.
    """
    sel = match.same_events if only_same_events else np.ones(match.n_matched, bool)
    out = []
    for est in ESTIMATORS:
        x, y = a.length_m[est][match.a[sel]], b.length_m[est][match.b[sel]]
        g = np.isfinite(x) & np.isfinite(y)
        d = x[g] - y[g]
        row = dict(pair=pair, estimator=est, n=int(d.size), n_matched=match.n_matched,
                   n_different_events=match.n_different_events, n_only_a=int(match.only_a.size),
                   n_only_b=int(match.only_b.size))
        if d.size:
            ad = np.abs(d)
            row.update(median_abs_mm=1e3 * float(np.median(ad)), p95_abs_mm=1e3 * float(np.percentile(ad, 95)),
                       max_abs_mm=1e3 * float(ad.max()), bias_mm=1e3 * float(np.mean(d)),
                       max_rel=float(np.max(ad / np.abs(y[g]))))
        else:
            row.update(median_abs_mm=math.nan, p95_abs_mm=math.nan, max_abs_mm=math.nan, bias_mm=math.nan,
                       max_rel=math.nan)
        out.append(row)
    return out


# ---------------------------------------------------------------------------------------------------------
# Segments and K


def segments_from_mark_times(mark_times_s: np.ndarray, *, lap_m: float = 20.0) -> list[Section]:
    """Sections between consecutive MARK samples of a recording, each ``lap_m`` long."""
    t = np.sort(np.asarray(mark_times_s, np.float64))
    return [Section(0, "", i, i * lap_m, (i + 1) * lap_m, float(a), float(b), False)
            for i, (a, b) in enumerate(zip(t[:-1], t[1:]))]


def segments_by_distance(table: StepTable, *, estimator: str = "M3", segment_m: float = 20.0) -> list[Section]:
    """Consecutive stretches of ``segment_m`` of ``estimator``'s distance (no lap marks; real length unknown).

    The boundaries are foot-flat times where the cumulative (NaN-filled) distance crosses a multiple of
    ``segment_m``; ``start_m``/``end_m`` are those multiples (estimated, not real).
    """
    if table.n_steps == 0:
        return []
    v, _ = table.filled(table.length_m[estimator])
    cum = np.cumsum(np.nan_to_num(v))
    t = table.time_s(table.foot_flat)
    k = np.floor(cum / segment_m).astype(np.int64)
    edges = np.flatnonzero(np.diff(np.r_[0, k]) > 0)
    bounds = np.r_[t[0] - (table.duration_s[0] if np.isfinite(table.duration_s[0]) else 0.5), t[edges]]
    return [Section(0, "", i, i * segment_m, (i + 1) * segment_m, float(a), float(b), False)
            for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:]))]


def segment_distances(table: StepTable, sections: list[Section]) -> np.ndarray:
    """``(n_sections, 5)`` distance per section and estimator (step windows cut by time, NaN steps filled)."""
    out = np.full((len(sections), len(ESTIMATORS)), np.nan)
    if table.n_steps == 0:
        return out
    filled = np.column_stack([table.filled(table.length_m[e])[0] for e in ESTIMATORS])
    for i, s in enumerate(sections):
        f = section_fractions(table, s.t_start_s, s.t_end_s)
        out[i] = f @ np.nan_to_num(filled, nan=0.0) if np.any(f > 0) else 0.0
        out[i, ~np.any(np.isfinite(filled), axis=0)] = np.nan
    return out


def calibration_sets(sections: list[Section], *, calibration_sections: int = 2) -> dict[str, list[list[Section]]]:
    """Calibration data of both modes, as :func:`host.evaluation.evaluate_recording` chooses it.

    Single-speed: the first ``calibration_sections`` straight sections of the preferred excursion (else the
    first excursion), pooled; multi-speed: those of every excursion, one pool per excursion.
    """
    by_exc: dict[int, list[Section]] = {}
    for s in sections:
        if not s.turn:
            by_exc.setdefault(s.excursion, []).append(s)
    sets = {k: v[:calibration_sections] for k, v in sorted(by_exc.items()) if v}
    if not sets:
        raise HostError("no straight section between lap marks to calibrate K on")
    pref = [k for k, v in sets.items() if v[0].speed_label == "preferred"]
    single = pref[0] if pref else min(sets)
    return {"single-speed": [sets[single]], "multi-speed": list(sets.values())}


def fit_k(table: StepTable, pools: list[list[Section]], *, leg_length_m: float, foot_length_m: float,
          subject: str = "") -> Any:
    """K of one mode from the raw lengths of ``table`` (whole steps by window midpoint, as evaluation does)."""
    from host.estimators.calibration import calibrate

    data = []
    for secs in pools:
        mask = section_fractions(table, secs[0].t_start_s, secs[-1].t_end_s, edge="whole") > 0
        data.append((table.select(mask), float(sum(s.real_m for s in secs))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # the single-speed M5 fallback is expected
        return calibrate(data, leg_length_m=leg_length_m, foot_length_m=foot_length_m, subject=subject)


# ---------------------------------------------------------------------------------------------------------
# Simulated walks: analog output, codes of any width


@dataclass(frozen=True, eq=False)
class SampledWalk:
    """The sensor's analog output at the logger's sample instants, ready to quantise at any width.

    Attributes
    ----------
    code_10
        ``(n, 3)`` continuous converter input in 10-bit code units (``floor`` of it is the 10-bit code),
        clipped to the converter's span.
    times_s, mark_times_s, rate_hz
        Sample instants, MARK sample times, sample rate.
    offset_code_10, axes_gain
        The sensor's truth in code units: ``code_10 = offset + gain_matrix @ a_g`` (within the rails).
    truth
        The walk's truth (``steps``, ``laps``, ``excursions``).
    """

    code_10: np.ndarray
    times_s: np.ndarray
    mark_times_s: np.ndarray
    rate_hz: float
    offset_code_10: np.ndarray
    gain_matrix_code_10: np.ndarray
    truth: dict

    def codes(self, bits: int) -> np.ndarray:
        """``(n, 3)`` int64 codes of an ideal ``bits``-bit converter (``floor``, clipped, as ``Adc.convert``)."""
        x = np.floor(self.code_10 * 2.0 ** (bits - 10))
        return np.clip(x, 0, (1 << bits) - 1).astype(np.int64)

    def ideal_codes(self, bits: int) -> np.ndarray:
        """The analog input in ``bits``-bit code units, shifted by the floor's mean half code (unbiased)."""
        return self.code_10 * 2.0 ** (bits - 10) - 0.5

    def calibration(self, bits: int) -> Any:
        """The device calibration for ``bits``-bit codes: the sensor's truth, unbiased for ``floor``.

        A :class:`protocol.header.Calibration` (``a = M (c - o)``), ``o = offset - 1/2`` code.
        """
        from protocol.header import Calibration

        s = 2.0 ** (bits - 10)
        return Calibration(self.offset_code_10 * s - 0.5, np.linalg.inv(self.gain_matrix_code_10 * s), valid=True)


class AnalogWalk:
    """A subject walking the protocol, seen by the logger's sensor on its fine analog grid.

    Parameters
    ----------
    subject
        :class:`firmware_sim.world.subject.Subject`.
    seed
        Seed of the walk; the sensor is the unit ``SensorModel.draw(seed=sensor_seed)`` (default: the
        logger's default for ``device_id = 1 + seed % 60000``, as :func:`host.evaluation.record_subject`).
    protocol
        :class:`firmware_sim.world.gait_protocol.WalkingProtocol` (default: the paper's).

    Attributes
    ----------
    volts_, rate_hz_, truth_, sensor_
        Sensor output (``(n, 3)`` V, noise-free: the noise is drawn at the sample instants), its rate, the
        walk's truth and the sensor.
    """

    def __init__(self, *, subject: Any, seed: int = 0, protocol: Any = None, sensor_seed: int | None = None) -> None:
        self.subject = subject
        self.seed = seed
        self.protocol = protocol
        self.sensor_seed = sensor_seed

    def run(self) -> AnalogWalk:
        """Render the walk and the sensor's response (the expensive part, done once per subject)."""
        from firmware_sim.sensor import SensorModel
        from firmware_sim.world.walking import Walking

        sseed = self.sensor_seed if self.sensor_seed is not None else 1 + self.seed % 60000
        self.sensor_ = SensorModel.draw(seed=int(sseed))
        motion = Walking(subject=self.subject, protocol=self.protocol, seed=self.seed).render(
            self.sensor_.internal_rate_hz)
        self.rate_hz_ = float(motion.rate_hz)
        self.t0_s_ = float(motion.t0_s)
        self.t_last_s_ = self.t0_s_ + (motion.acc_g.shape[0] - 1) / self.rate_hz_
        self.marker_times_s_ = np.asarray(motion.marker_times_s, np.float64)
        self.volts_ = self.sensor_.respond(motion.acc_g, self.rate_hz_, noise=False)
        self.truth_ = {k: motion.truth[k] for k in ("steps", "laps", "excursions", "rests") if k in motion.truth}
        return self

    def sample(self, rate_hz: float) -> SampledWalk:
        """The analog output at the sample instants of a ``rate_hz`` timer, noise included (as
        :meth:`firmware_sim.device.Logger.record`: same instants, same hold, same noise stream)."""
        from firmware_sim.adc import Adc

        adc = Adc(bits=10, rate_hz=rate_hz)
        sen = self.sensor_
        times = adc.sample_times_s(self.t0_s_, self.t_last_s_)
        held = adc.hold(self.volts_, self.rate_hz_, self.t0_s_, times)
        held = held + sen.noise_g(times, rng=np.random.default_rng(sen.seed)) * sen.gain_v_per_g
        # the converter input in 10-bit code units (Adc.convert without the floor), clipped to the span
        lsb = adc.lsb_v
        v = adc.ref_v + adc.gain * (held - adc.ref_v)
        x = np.clip((v - adc.vref_low_v) / lsb, 0.0, float(adc.n_codes) - 1e-9)
        offset = (adc.ref_v + adc.gain * (sen.zero_g_v + sen.gain_v_per_g * sen.offset_g - adc.ref_v)
                  - adc.vref_low_v) / lsb
        gain = (adc.gain * sen.gain_v_per_g / lsb)[:, None] * sen.axes
        marks = np.zeros(times.size, bool)
        if self.marker_times_s_.size:
            k = np.searchsorted(times, self.marker_times_s_, side="left")
            marks[k[k < times.size]] = True
        return SampledWalk(x, times, times[marks], float(rate_hz), offset, gain, self.truth_)


# ---------------------------------------------------------------------------------------------------------
# One walk, three chains


@dataclass(eq=False)
class ChainRun:
    """One chain on one walk: the uncalibrated table, K per mode and the calibrated tables."""

    arithmetic: str
    table: StepTable
    calibrations: dict[str, Any]
    tables: dict[str, StepTable]
    saturation: str = ""
    saturated: int = 0
    wrapped: int = 0
    cycles_per_sample: float = math.nan


def _run_chain(arithmetic: str, sw: SampledWalk, bits: int, subject: Any, pools: dict[str, list]) -> ChainRun:
    leg, foot = subject.leg_length_m, subject.foot_length_m
    fs, t0 = sw.rate_hz, float(sw.times_s[0])
    cal = sw.calibration(bits)
    if arithmetic == "fixed":
        codes = sw.codes(bits)
        kw = dict(sampling_rate_hz=fs, leg_length_m=leg, foot_length_m=foot, adc_calibration=cal,
                  code_bits=bits, t0_s=t0)
        table, chain = fixed_step_table(codes, **kw)
        ctxs = [chain]
        cals = {m: fit_k(table, pools[m], leg_length_m=leg, foot_length_m=foot, subject=subject.subject_id)
                for m in MODES}
        tables = {}
        for m in MODES:
            tables[m], ch = fixed_step_table(codes, calibration=cals[m], **kw)
            ctxs.append(ch)
        rep = "; ".join(f"{name}: {c.ctx_.report()}" for name, c in zip(("raw",) + MODES, ctxs) if c.ctx_.report())
        return ChainRun("fixed", table, cals, tables, rep, sum(c.ctx_.total_saturated for c in ctxs),
                        sum(c.ctx_.total_wrapped for c in ctxs), chain.cycles_per_sample_)
    from host.gait.pipeline import apply_calibration

    c = sw.codes(bits) if arithmetic == "float" else sw.ideal_codes(bits)
    acc = cal.apply(c)
    table = float_step_table(acc, sampling_rate_hz=fs, leg_length_m=leg, foot_length_m=foot, t0_s=t0)
    cals = {m: fit_k(table, pools[m], leg_length_m=leg, foot_length_m=foot, subject=subject.subject_id)
            for m in MODES}
    tables = {m: replace(table, length_m=apply_calibration(table, cals[m])) for m in MODES}
    return ChainRun(arithmetic, table, cals, tables)


def truth_table(table: StepTable, truth_steps: dict, *, tol_s: float = MATCH_TOL_S) -> tuple[StepTable, np.ndarray]:
    """``table`` with every matched step's duration (and M5 cadence) replaced by the world's exact one.

    A chain step runs foot-flat to foot-flat; its truth twin is the world step whose ``next_foot_flat_s``
    is nearest to the chain's foot-flat (mutual nearest within ``tol_s``) and the exact duration is
    ``next_foot_flat_s - foot_flat_s``. Returns the table (raw M5 = 1 / exact duration; the other columns
    unchanged) and, per row, the index of the truth step (``-1``: unmatched, keeps its sampled timing).
    """
    st = truth_steps
    t_end = np.asarray(st["next_foot_flat_s"], np.float64)
    order = np.argsort(t_end, kind="stable")
    ic, it = match_events(table.time_s(table.foot_flat), t_end[order], tol_s)
    idx = np.full(table.n_steps, -1, np.int64)
    idx[ic] = order[it]
    dur = table.duration_s.copy()
    has = (idx >= 0) & np.isfinite(dur)
    dur[has] = t_end[idx[has]] - np.asarray(st["foot_flat_s"], np.float64)[idx[has]]
    raw = dict(table.raw_m)
    raw["M5"] = np.where(dur > 0, 1.0 / dur, np.nan)
    return replace(table, duration_s=dur, raw_m=raw), idx


@dataclass(eq=False)
class WalkComparison:
    """Result of :func:`compare_walk` for one subject, one ADC width and one sample rate.

    Attributes
    ----------
    subject_id, bits, rate_hz
        What was compared.
    runs
        :class:`ChainRun` per arithmetic (``ideal``, ``float``, ``fixed``) and ``exact-timing`` (the float
        chain on codes with each step's duration replaced by the truth's, K refitted: M5 without timing
        error).
    step_diffs
        :func:`step_differences` rows (multi-speed lengths) for the pairs ``fixed-float`` (arithmetic),
        ``float-ideal`` (ADC), ``ideal-truth`` and ``fixed-truth``.
    segments
        One row per evaluated 20 m section, mode and estimator: ``real_m`` and the distance and ratio of
        each arithmetic, and the exact-timing M5.
    steps
        Per-step rows (float chain on codes as the spine): times, matched indices, lengths of every
        arithmetic and of the truth (multi-speed K).
    timing
        Step-duration error against the truth (float chain on codes): median absolute and rms, s.
    saturation
        The fixed-point runs' saturation/wrap report ("" = none).
    """

    subject_id: str
    bits: int
    rate_hz: float
    runs: dict[str, ChainRun]
    step_diffs: list[dict]
    segments: list[dict]
    steps: dict[str, np.ndarray]
    timing: dict[str, float]
    saturation: str
    matches: dict[str, StepMatch] = field(default_factory=dict)


def compare_walk(sw: SampledWalk, subject: Any, *, bits: int = 10, ideal: ChainRun | None = None,
                 calibration_sections: int = 2, include_turn: bool = False) -> WalkComparison:
    """Ideal, float and fixed chains on one sampled walk; steps matched; 20 m sections (module notes).

    ``ideal`` may be passed in to reuse one ideal run across ADC widths (it does not depend on ``bits``).
    """
    sections = sections_from_marks(sw.mark_times_s, sw.truth["laps"], rate_hz=sw.rate_hz)
    pools = calibration_sets(sections, calibration_sections=calibration_sections)
    runs = {"ideal": ideal if ideal is not None else _run_chain("ideal", sw, bits, subject, pools),
            "float": _run_chain("float", sw, bits, subject, pools),
            "fixed": _run_chain("fixed", sw, bits, subject, pools)}
    st = sw.truth["steps"]
    fl = runs["float"].table
    exact, truth_idx = truth_table(fl, st)
    leg, foot = subject.leg_length_m, subject.foot_length_m
    from host.gait.pipeline import apply_calibration

    ecals = {m: fit_k(exact, pools[m], leg_length_m=leg, foot_length_m=foot) for m in MODES}
    runs["exact-timing"] = ChainRun("exact-timing", exact, ecals,
                                    {m: replace(exact, length_m=apply_calibration(exact, ecals[m])) for m in MODES})
    # the truth as a table (lengths of the matched world steps) for per-step differences
    tl = np.asarray(st["length_m"], np.float64)

    def truth_lengths(table: StepTable) -> StepTable:
        _, idx = truth_table(table, st)
        v = np.where(idx >= 0, tl[np.maximum(idx, 0)], np.nan)
        return replace(table, length_m={e: v for e in ESTIMATORS})

    mm = "multi-speed"
    t = {k: runs[k].tables[mm] for k in ARITHMETICS}
    matches = {"fixed-float": match_steps(t["fixed"], t["float"]), "float-ideal": match_steps(t["float"], t["ideal"])}
    diffs = step_differences(t["fixed"], t["float"], matches["fixed-float"], pair="fixed-float")
    diffs += step_differences(t["float"], t["ideal"], matches["float-ideal"], pair="float-ideal")
    for k in ("ideal", "fixed"):
        tt = truth_lengths(t[k])
        self_match = match_steps(t[k], tt)         # identity pairing, events equal by construction
        diffs += step_differences(t[k], tt, self_match, pair=f"{k}-truth")
    # timing against the truth (steps with a window and a truth twin)
    has = (truth_idx >= 0) & np.isfinite(fl.duration_s)
    dt = fl.duration_s[has] - exact.duration_s[has]
    timing = dict(n=int(dt.size), median_abs_ms=1e3 * float(np.median(np.abs(dt))) if dt.size else math.nan,
                  rms_ms=1e3 * float(np.sqrt(np.mean(dt ** 2))) if dt.size else math.nan)
    # 20 m sections
    calib_ids = {(s.excursion, s.index) for pool in pools["multi-speed"] for s in pool}
    evaluated = [s for s in sections if (s.excursion, s.index) not in calib_ids and (include_turn or not s.turn)]
    dist = {(k, m): segment_distances(runs[k].tables[m], evaluated) for k in runs for m in MODES}
    seg_rows = []
    for i, s in enumerate(evaluated):
        for m in MODES:
            for j, est in enumerate(ESTIMATORS):
                row = dict(subject=subject.subject_id, bits=bits, rate_hz=sw.rate_hz, excursion=s.excursion,
                           speed_label=s.speed_label, section=s.index, start_m=s.start_m, end_m=s.end_m,
                           mode=m, estimator=est, real_m=s.real_m)
                for k in runs:
                    key = k.replace("-", "_")
                    row[f"{key}_m"] = float(dist[(k, m)][i, j])
                    row[f"ratio_{key}"] = float(dist[(k, m)][i, j]) / s.real_m
                seg_rows.append(row)
    # per-step rows (float on codes as spine)
    mf, mi = matches["fixed-float"], matches["float-ideal"]
    fixed_of = np.full(fl.n_steps, -1, np.int64)
    fixed_of[mf.b] = mf.a
    ideal_of = np.full(fl.n_steps, -1, np.int64)
    ideal_of[mi.a] = mi.b
    same = np.zeros(fl.n_steps, bool)
    same[mf.b] = mf.same_events
    steps: dict[str, np.ndarray] = {
        "step": np.arange(fl.n_steps), "foot_flat_s": fl.time_s(fl.foot_flat), "duration_s": fl.duration_s,
        "exact_duration_s": exact.duration_s, "fixed_step": fixed_of, "ideal_step": ideal_of,
        "truth_step": truth_idx, "same_events_fixed": same,
        "truth_length_m": np.where(truth_idx >= 0, tl[np.maximum(truth_idx, 0)], np.nan)}
    for est in ESTIMATORS:
        e = est.lower()
        steps[f"{e}_float_m"] = t["float"].length_m[est]
        steps[f"{e}_fixed_m"] = np.where(fixed_of >= 0, t["fixed"].length_m[est][np.maximum(fixed_of, 0)], np.nan) \
            if t["fixed"].n_steps else np.full(fl.n_steps, np.nan)
        steps[f"{e}_ideal_m"] = np.where(ideal_of >= 0, t["ideal"].length_m[est][np.maximum(ideal_of, 0)], np.nan) \
            if t["ideal"].n_steps else np.full(fl.n_steps, np.nan)
    return WalkComparison(subject.subject_id, int(bits), float(sw.rate_hz), runs, diffs, seg_rows, steps, timing,
                          runs["fixed"].saturation, matches)


# ---------------------------------------------------------------------------------------------------------
# Decoded recordings: fixed vs float


@dataclass(eq=False)
class RecordingComparison:
    """Fixed vs float on the codes of one recording (:func:`compare_recording`)."""

    float_table: StepTable
    fixed_table: StepTable
    match: StepMatch
    step_diffs: list[dict]
    segments: list[dict]
    steps: dict[str, np.ndarray]
    saturation: str
    saturated: int
    wrapped: int
    cycles_per_sample: float
    segment_source: str


def compare_recording(codes: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                      adc_calibration: Any = None, code_bits: int = 10, valid: np.ndarray | None = None,
                      calibration: Any = None, mark_times_s: np.ndarray | None = None, lap_m: float = 20.0,
                      segment_m: float = 20.0, t0_s: float = 0.0,
                      sections: list[Section] | None = None) -> RecordingComparison:
    """Fixed vs float chain on the same codes (no truth): matched steps, differences, segments.

    ``adc_calibration`` (``offset_counts``, ``matrix_g_per_count``; None = nominal) converts codes to g for
    the float chain and, quantised, for the fixed chain; ``calibration`` is an optional K calibration (the
    same K for both: the difference is the arithmetic alone). Segments: ``sections`` when given (e.g. the
    protocol's, :func:`host.evaluation.sections_from_marks`), else between MARK flags ``lap_m`` apart, else
    every ``segment_m`` of the float chain's M3 distance.
    """
    from protocol.header import Calibration

    c = np.asarray(codes)
    ok = np.ones(c.shape[0], bool) if valid is None else np.asarray(valid, bool)
    cal = adc_calibration if adc_calibration is not None else Calibration.nominal(code_bits)
    acc = np.asarray(cal.apply(c.astype(np.float64)), np.float64)
    acc[~ok] = np.nan
    kw = dict(sampling_rate_hz=sampling_rate_hz, leg_length_m=leg_length_m, foot_length_m=foot_length_m,
              calibration=calibration, t0_s=t0_s)
    fl = float_step_table(acc, valid=ok, **kw)
    fx, chain = fixed_step_table(c, adc_calibration=cal, code_bits=code_bits, valid=ok, **kw)
    m = match_steps(fx, fl)
    diffs = step_differences(fx, fl, m, pair="fixed-float")
    marks = np.asarray(mark_times_s if mark_times_s is not None else [], np.float64)
    known = sections is not None or marks.size >= 2
    if sections is not None:
        source = "the given sections"
    elif marks.size >= 2:
        sections, source = segments_from_mark_times(marks, lap_m=lap_m), f"between MARK flags, {lap_m:g} m apart"
    else:
        sections = segments_by_distance(fl, segment_m=segment_m)
        source = f"every {segment_m:g} m of the float chain's M3 distance (no lap marks; real length unknown)"
    d_fl, d_fx = segment_distances(fl, sections), segment_distances(fx, sections)
    seg_rows = []
    for i, s in enumerate(sections):
        for j, est in enumerate(ESTIMATORS):
            real = s.real_m if known else math.nan
            seg_rows.append(dict(section=s.index, t_start_s=s.t_start_s, t_end_s=s.t_end_s, estimator=est,
                                 real_m=real, float_m=float(d_fl[i, j]), fixed_m=float(d_fx[i, j]),
                                 ratio_float=float(d_fl[i, j]) / real, ratio_fixed=float(d_fx[i, j]) / real,
                                 diff_m=float(d_fx[i, j] - d_fl[i, j])))
    fixed_of = np.full(fl.n_steps, -1, np.int64)
    fixed_of[m.b] = m.a
    same = np.zeros(fl.n_steps, bool)
    same[m.b] = m.same_events
    steps: dict[str, np.ndarray] = {"step": np.arange(fl.n_steps), "foot_flat_s": fl.time_s(fl.foot_flat),
                                    "duration_s": fl.duration_s, "fixed_step": fixed_of, "same_events": same}
    for est in ESTIMATORS:
        e = est.lower()
        steps[f"{e}_float_m"] = fl.length_m[est]
        steps[f"{e}_fixed_m"] = (np.where(fixed_of >= 0, fx.length_m[est][np.maximum(fixed_of, 0)], np.nan)
                                 if fx.n_steps else np.full(fl.n_steps, np.nan))
    ctx = chain.ctx_
    return RecordingComparison(fl, fx, m, diffs, seg_rows, steps, ctx.report(), ctx.total_saturated,
                               ctx.total_wrapped, chain.cycles_per_sample_, source)


# ---------------------------------------------------------------------------------------------------------
# Output helpers


def columns_csv_text(cols: dict[str, np.ndarray]) -> str:
    """CSV text of named equal-length columns (``%.6g``; empty cells for NaN)."""
    names = list(cols)
    arrays = [np.asarray(cols[n]) for n in names]
    n = arrays[0].size if arrays else 0
    lines = [",".join(names)]
    for i in range(n):   # formatting only
        cells = []
        for a in arrays:
            x = a[i]
            if a.dtype == bool:
                cells.append(str(int(x)))
            elif np.issubdtype(a.dtype, np.integer):
                cells.append(str(int(x)))
            else:
                cells.append("" if not np.isfinite(x) else f"{float(x):.6g}")
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def rows_csv_text(rows: list[dict], columns: list[str] | tuple[str, ...] | None = None) -> str:
    """CSV text of dict rows (floats ``%.6g``, NaN as empty)."""
    if not rows:
        return ""
    cols = list(columns) if columns is not None else list(rows[0])
    lines = [",".join(cols)]
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c, "")
            if isinstance(v, float):
                cells.append("" if not math.isfinite(v) else f"{v:.6g}")
            else:
                cells.append(str(v))
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def format_step_diffs(rows: list[dict]) -> str:
    """Printed per-step difference table."""
    lines = [f"{'pair':<13}{'est':<5}{'n':>6}{'med|d| mm':>11}{'p95 mm':>9}{'max mm':>9}{'bias mm':>9}"
             f"{'max rel %':>10}{'diff.ev':>8}"]
    for r in rows:
        lines.append(f"{r['pair']:<13}{r['estimator']:<5}{r['n']:>6}{r['median_abs_mm']:>11.3f}{r['p95_abs_mm']:>9.3f}"
                     f"{r['max_abs_mm']:>9.2f}{r['bias_mm']:>+9.3f}{100 * r['max_rel']:>10.3f}"
                     f"{r['n_different_events']:>8}")
    return "\n".join(lines)
