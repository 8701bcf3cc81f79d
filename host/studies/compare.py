"""Offline vs on-line algorithm, float vs fixed point, vs truth: the error budget of M1-M5.

Four chains run on one walk (:func:`compare_walk`) or on one recording (:func:`compare_recording`):

* **ideal**: the offline float chain (:class:`gaitlog.host.gait.pipeline.StepPipeline`, the paper's PC processing)
  on the sensor's analog output at the sample instants, before quantisation (noise, filter,
  sample-and-hold included; no ADC). Simulated walks only;
* **offline**: the same chain on the ADC codes (``adc_bits`` bits), converted to g with the device calibration;
* **online-float**: the firmware's on-line algorithm
  (:class:`gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`) on the same codes and the same device
  calibration, in floating point;
* **online-fixed**: the same algorithm in the PIC's fixed point: what the logger computes and stores.

**One K.** Per calibration mode (single- and multi-speed, :func:`gaitlog.host.gait.sections.calibration_sets`), K
(:class:`gaitlog.host.gait.k_calibration.KFit`) is fitted once, on the *offline* chain's table of the
calibration sections (:func:`gaitlog.host.gait.k_calibration.calibrate_on_sections`), and that same K is used by every chain: ``apply_calibration`` for the
offline and ideal chains, the step configuration (``StepConfig(calibrated=True, k_m1=..., ...)``, K applied
in the algorithm's own arithmetic, as the header stores it) for the on-line algorithm. K is never refitted
per chain: a K fitted on each chain's own lengths absorbs any error proportional to the length (a 2 %
scale error of the fixed-point lengths becomes K' = K / 1.02 and vanishes from the distances, as
``tests/host/studies/test_compare_sim.py`` shows), and finding such errors is what the comparison is for.

**Error split** (:data:`SHARES`), per step and per 20 m section::

    adc        = offline      - ideal          (quantisation)
    algorithm  = online-float - offline        (causal on-line algorithm vs the offline chain)
    arithmetic = online-fixed - online-float   (the PIC's fixed point, same codes)

which add up to ``online-fixed - ideal``; on simulated walks each chain is also compared with the world's
truth (``<chain> - truth``). Steps are matched by time (:func:`match_steps`: foot-flats within ``tol_s``,
mutual nearest); a matched pair whose window start, heel-strike, toe-off or foot-flat differ by a sample
or more is a step where the two chains *detected different events*: it is counted and reported, and left
out of the per-step differences (an event one sample apart is a different step window, not an arithmetic
error); the section distances include every step. Per-20 m sections follow the paper's evaluation
(:mod:`gaitlog.host.studies.evaluation`): lap marks, the calibration sections left out, ratio estimated / real.
Saturation and wrap counts of every fixed-point run are kept (``saturation``); nothing saturates
unreported. :func:`bootstrap_budget` gives 95 % intervals over subjects for the summary figures.

Simulated walks (:class:`gaitlog.host.studies.simulation.AnalogWalk`): the world (:class:`gaitlog.firmware_sim.world.walking.Walking`) through the
device's sensor model (:class:`gaitlog.firmware_sim.sensor.SensorModel`, the logger's default seeded unit) and the
front end and timer of :class:`gaitlog.firmware_sim.adc.Adc`, exactly as :meth:`gaitlog.firmware_sim.device.Logger.record`
does (same codes at 10 bits: tested), but quantised here at any width (the PIC's converter stops at 10
bits; 12 bits is the sweep's hypothetical external converter) and kept before quantisation. The device
calibration is the sensor's own truth (offsets, gains, axes), unbiased for the floor quantiser (``+0.5``
code): the comparison isolates the ADC, the algorithm and the arithmetic; the pose calibration's own error
is evaluated in :mod:`gaitlog.host.studies.evaluation`.

Recordings (:func:`compare_recording`): a decoded recording has no truth and no analog output: offline,
online-float and online-fixed with the given K (or none: K = 1, M4/M5 undefined), sections between MARK
flags (``lap_m`` apart) or, without marks, every ``segment_m`` of the offline chain's M3 distance. A
recording that carries the device's own step records is checked against the host's replay of the on-line
algorithm, bit for bit (:func:`gaitlog.host.files.replay.verify_step_records`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gaitlog.firmware_sim.adc import TransferCurve
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.firmware_sim.algorithms.steps import (
    ESTIMATORS,
    StepTable,
    csv_text,
    float_csv_cells,
)
from gaitlog.host.files.replay import online_step_table
from gaitlog.host.gait.k_calibration import KFit, calibrate_on_sections
from gaitlog.host.gait.estimators.weinberg import weinberg_length_m
from gaitlog.host.gait.pipeline import StepPipeline, apply_calibration
from gaitlog.host.gait.streaming import BLOCK_SAMPLES as STREAM_BLOCK_SAMPLES, StreamingStepPipeline
from gaitlog.host.gait.sections import (
    MODES,
    Section,
    calibration_sets,
    section_fractions,
    sections_from_marks,
)
from gaitlog.host.studies.stats import (
    BOOTSTRAP_LEVEL,
    BOOTSTRAP_RESAMPLES,
    MEDIAN,
    subject_bootstrap,
    subject_resamples,
)
from gaitlog.protocol.header import CalibrationSlot

#: Foot-flats of two chains closer than this are the same step, s.
MATCH_TOL_S = 0.1
#: The chains, in the order of the error split.
CHAINS = ("ideal", "offline", "online-float", "online-fixed")
#: The error split: share -> (chain a, chain b); the share is ``a - b``.
SHARES: dict[str, tuple[str, str]] = {"adc": ("offline", "ideal"), "algorithm": ("online-float", "offline"),
                                      "arithmetic": ("online-fixed", "online-float")}

STEP_DIFF_COLUMNS = ("share", "pair", "estimator", "n", "median_abs_mm", "p95_abs_mm", "max_abs_mm", "bias_mm",
                     "max_rel", "n_matched", "n_different_events", "n_only_a", "n_only_b")
BUDGET_COLUMNS = ("kind", "share", "pair", "mode", "estimator", "statistic", "value", "ci_low", "ci_high",
                  "n_subjects", "n")


def column_key(chain: str) -> str:
    """A chain's name as a column/key fragment (``online-fixed`` -> ``online_fixed``)."""
    return chain.replace("-", "_")


def pair_label(a: str, b: str) -> str:
    """``"a - b"``: the label of a difference between two chains."""
    return f"{a} - {b}"


# ---------------------------------------------------------------------------------------------------------
# The chains as host StepTables


def offline_step_table(acc_g: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                       k_fit: KFit | None = None, valid: np.ndarray | None = None, t0_s: float = 0.0) -> StepTable:
    """The offline float chain's table with the step constants ``k_fit`` (None: raw lengths; warnings about
    impossible excursions are silenced: they are counted as NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return StepPipeline(leg_length_m=leg_length_m, foot_length_m=foot_length_m, k_fit=k_fit).run(
            acc_g, sampling_rate_hz=sampling_rate_hz, valid=valid, t0_s=t0_s).steps_


def streamed_offline_table(codes: np.ndarray, valid: np.ndarray, adc_calibration: Any, *, sampling_rate_hz: float,
                           leg_length_m: float, foot_length_m: float, k_fit: KFit | None = None, t0_s: float = 0.0,
                           block: int = STREAM_BLOCK_SAMPLES) -> StepTable:
    """:func:`offline_step_table` of the codes in g (``adc_calibration.apply``, NaN where not ``valid``), computed
    ``block`` samples at a time (:class:`~gaitlog.host.gait.streaming.StreamingStepPipeline`, the whole-array
    table bit for bit): no ``(n, 3)`` float array and no whole-array chain is held, only the codes."""
    c, ok = np.asarray(codes), np.asarray(valid, bool)
    pipe = StreamingStepPipeline(leg_length_m=leg_length_m, foot_length_m=foot_length_m,
                                 sampling_rate_hz=sampling_rate_hz, k_fit=k_fit, t0_s=t0_s, block=block)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        for lo in range(0, c.shape[0], block):
            g = np.asarray(adc_calibration.apply(c[lo:lo + block].astype(np.float64)), np.float64)
            g[~ok[lo:lo + block]] = np.nan
            pipe.feed(g, ok[lo:lo + block])
        return pipe.finish().steps_


def with_m4_exponent(table: StepTable, exponent: float) -> StepTable:
    """An offline table whose raw M4 lengths are ``(a_max - a_min)^exponent`` of its steps' ranges (the chain
    computes them with :data:`~gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT`); ``table`` itself at that
    exponent."""
    if math.isclose(exponent, M4_EXPONENT):
        return table
    return replace(table, raw_m=table.raw_m | {"M4": weinberg_length_m(table.acc_range_m_s2, k=1.0, exponent=exponent)})


def calibrated(table: StepTable, k_fit: KFit | None) -> StepTable:
    """An offline table with the step constants ``k_fit`` applied to its raw lengths (``apply_calibration``)."""
    return replace(table, length_m=apply_calibration(table, k_fit))


# ---------------------------------------------------------------------------------------------------------
# Matching steps


def match_events(truth_s: np.ndarray, detected_s: np.ndarray, tol_s: float) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one matching of two sorted event-time lists: mutual nearest neighbours within ``tol_s``.

    Returns the matched indices into ``truth_s`` and ``detected_s``.

    Examples
    --------
    >>> match_events(np.array([1.0, 2.0, 3.0]), np.array([1.01, 2.5, 2.98, 3.02]), 0.04)
    (array([0, 2]), array([0, 2]))
    """
    t = np.sort(np.asarray(truth_s, np.float64))
    d = np.sort(np.asarray(detected_s, np.float64))
    if t.size == 0 or d.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)

    def nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        j = np.clip(np.searchsorted(b, a), 1, b.size - 1) if b.size > 1 else np.zeros(a.size, np.int64)
        if b.size == 1:
            return j
        return np.where(np.abs(b[j - 1] - a) <= np.abs(b[j] - a), j - 1, j)

    jt = nearest(t, d)  # nearest detected for each truth
    jd = nearest(d, t)  # nearest truth for each detected
    i = np.arange(t.size)
    ok = (jd[jt] == i) & (np.abs(d[jt] - t) <= tol_s)
    return i[ok], jt[ok]


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

    def a_of_b(self, n_b: int) -> np.ndarray:
        """For each of the ``n_b`` rows of table ``b``, its partner in ``a`` (``-1``: none)."""
        out = np.full(n_b, -1, np.int64)
        out[self.b] = self.a
        return out

    def b_of_a(self, n_a: int) -> np.ndarray:
        """For each of the ``n_a`` rows of table ``a``, its partner in ``b`` (``-1``: none)."""
        out = np.full(n_a, -1, np.int64)
        out[self.a] = self.b
        return out


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


def step_deltas(a: StepTable, b: StepTable, match: StepMatch, estimator: str, *,
                only_same_events: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(a - b, b)`` of ``length_m[estimator]`` on the matched steps where both are finite (with
    ``only_same_events``, only the pairs whose events agree)."""
    sel = match.same_events if only_same_events else np.ones(match.n_matched, bool)
    x, y = a.length_m[estimator][match.a[sel]], b.length_m[estimator][match.b[sel]]
    g = np.isfinite(x) & np.isfinite(y)
    return x[g] - y[g], y[g]


def step_differences(a: StepTable, b: StepTable, match: StepMatch, *, pair: str = "a - b", share: str = "",
                     only_same_events: bool = True) -> list[dict]:
    """Per estimator, the per-step difference ``a - b`` of ``length_m`` on the matched steps.

    Steps where either length is NaN are skipped; with ``only_same_events`` so are the pairs whose events
    differ (they are counted in ``n_different_events``). ``max_rel`` is ``max |a - b| / |b|``.
    """
    out = []
    for est in ESTIMATORS:
        d, y = step_deltas(a, b, match, est, only_same_events=only_same_events)
        row = dict(share=share, pair=pair, estimator=est, n=int(d.size), n_matched=match.n_matched,
                   n_different_events=match.n_different_events, n_only_a=int(match.only_a.size),
                   n_only_b=int(match.only_b.size))
        if d.size:
            ad = np.abs(d)
            row.update(median_abs_mm=1e3 * float(np.median(ad)), p95_abs_mm=1e3 * float(np.percentile(ad, 95)),
                       max_abs_mm=1e3 * float(ad.max()), bias_mm=1e3 * float(np.mean(d)),
                       max_rel=float(np.max(ad / np.abs(y))))
        else:
            row.update(median_abs_mm=math.nan, p95_abs_mm=math.nan, max_abs_mm=math.nan, bias_mm=math.nan,
                       max_rel=math.nan)
        out.append(row)
    return out


# ---------------------------------------------------------------------------------------------------------
# Segments and K


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
    times_s, mark_times_s, sampling_rate_hz
        Sample instants, MARK sample times, sample rate.
    offset_code_10, axes_gain
        The sensor's truth in code units: ``code_10 = offset + gain_matrix @ a_g`` (within the rails).
    truth
        The walk's truth (``steps``, ``laps``, ``excursions``).
    adc_input_10, converter
        A real converter (:mod:`gaitlog.firmware_sim.adc`: sequential sampling, settling, INL/DNL, offset and
        gain error): its input in 10-bit code units (channels held one after the other, settled) and its
        transfer curve at 10 bits (the same device's at any width). None: the ideal converter, ``code_10``
        quantised by ``floor``. ``code_10`` stays the analog input of the ideal chain either way, so the
        converter's effects land in the ADC share (offline - ideal).
    """

    code_10: np.ndarray
    times_s: np.ndarray
    mark_times_s: np.ndarray
    sampling_rate_hz: float
    offset_code_10: np.ndarray
    gain_matrix_code_10: np.ndarray
    truth: dict
    adc_input_10: np.ndarray | None = None
    converter: TransferCurve | None = None

    def codes(self, adc_bits: int) -> np.ndarray:
        """``(n, 3)`` int64 codes of the ``adc_bits``-bit converter (``floor``, clipped, as ``Adc.convert``, or the
        real converter's transfer curve at that width)."""
        if self.converter is not None:
            x = (self.code_10 if self.adc_input_10 is None else self.adc_input_10) * 2.0 ** (adc_bits - 10)
            return self.converter.at_bits(adc_bits).quantise(x).astype(np.int64)
        x = np.floor(self.code_10 * 2.0 ** (adc_bits - 10))
        return np.clip(x, 0, (1 << adc_bits) - 1).astype(np.int64)

    def ideal_codes(self, adc_bits: int) -> np.ndarray:
        """The analog input in ``adc_bits``-bit code units, shifted by the floor's mean half code (unbiased); with a
        real converter, as its linear part (offset and gain, :meth:`TransferCurve.linear`) would code it, so that
        :meth:`calibration` gives the ideal chain the sensor's truth."""
        if self.converter is None:
            return self.code_10 * 2.0 ** (adc_bits - 10) - 0.5
        a, b = self.converter.at_bits(adc_bits).linear()
        return (self.code_10 * 2.0 ** (adc_bits - 10) - a) / b - 0.5

    def calibration(self, adc_bits: int) -> Any:
        """The device calibration for ``adc_bits``-bit codes: the sensor's truth, unbiased for ``floor``.

        A :class:`gaitlog.protocol.header.CalibrationSlot` (``a = M (c - o)``), ``o = offset - 1/2`` code. With a
        real converter, through its end-point line ``T_k = a + b k`` (:meth:`TransferCurve.linear`): ``o = (offset
        - a) / b - 1/2``, gains ``/ b``: a pose calibration on the device measures the converter's offset and
        gain error with the sensor's, so they are calibrated away; its INL and DNL are not. The sensor's
        temperature drift is not either (the truth is the sensor's at the reference temperature).
        """
        s = 2.0 ** (adc_bits - 10)
        if self.converter is None:
            return CalibrationSlot(self.offset_code_10 * s - 0.5, np.linalg.inv(self.gain_matrix_code_10 * s), valid=True)
        a, b = self.converter.at_bits(adc_bits).linear()
        return CalibrationSlot((self.offset_code_10 * s - a) / b - 0.5, np.linalg.inv(self.gain_matrix_code_10 * s / b),
                               valid=True)


# ---------------------------------------------------------------------------------------------------------
# One walk, four chains, one K


@dataclass(eq=False)
class ChainRun:
    """One chain on one walk.

    Attributes
    ----------
    chain
        One of :data:`CHAINS` (or ``exact-timing``).
    table
        The offline chains' table without K (raw lengths); for the on-line chains, which apply K themselves,
        the multi-speed run.
    calibrations
        The K of each mode: the same objects for every chain of a comparison (fitted on ``offline``).
    tables
        The calibrated table of each mode.
    saturation, saturated, wrapped, cycles_per_sample
        Fixed point only: the arithmetic report of every run, the counts, the mean PIC cycles per sample.
    step_config
        On-line chains only: the 32-byte step configuration block (PROTOCOL.md 2.2) the algorithm ran the
        multi-speed run with, as the logger's header stores it (b"": an offline chain).
    """

    chain: str
    table: StepTable
    calibrations: dict[str, Any]
    tables: dict[str, StepTable]
    saturation: str = ""
    saturated: int = 0
    wrapped: int = 0
    cycles_per_sample: float = math.nan
    step_config: bytes = b""


def _offline_run(chain: str, table: StepTable, cals: dict[str, Any]) -> ChainRun:
    return ChainRun(chain, table, cals, {m: calibrated(table, cals[m]) for m in MODES})


def _online_run(arithmetic: str, codes: np.ndarray, cals: dict[str, Any], *, algorithm: Callable[..., Any],
                **kw: Any) -> ChainRun:
    tables, reports, sat, wrap, cyc, block = {}, [], 0, 0, math.nan, b""
    for m in MODES:
        tables[m], alg = online_step_table(codes, k_fit=cals[m], arithmetic=arithmetic, algorithm=algorithm,
                                           **kw)
        if m == "multi-speed":
            block = alg.config.step_config.to_bytes()
        if arithmetic == "fixed":
            rep = alg.arithmetic_context().report()
            if rep:
                reports.append(f"{m}: {rep}")
            sat, wrap, cyc = sat + alg.saturations, wrap + alg.wraps, alg.cycles.mean
    return ChainRun(f"online-{arithmetic}", tables["multi-speed"], cals, tables, "; ".join(reports), sat, wrap, cyc,
                    block)


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
    subject_id, adc_bits, sampling_rate_hz
        What was compared.
    runs
        :class:`ChainRun` per chain (:data:`CHAINS`) and ``exact-timing`` (the offline chain on codes with
        each step's duration replaced by the truth's, with the same K: M5 without timing error).
    calibrations
        The one K per mode (fitted on the offline chain), used by every chain.
    step_diffs
        :func:`step_differences` rows (multi-speed lengths) for the shares (:data:`SHARES`) and for each
        chain against the truth (share ``truth``).
    step_deltas
        ``{(pair, estimator): per-step differences, m}`` behind ``step_diffs`` (same events only), for
        :func:`bootstrap_budget`.
    segments
        One row per evaluated 20 m section, mode and estimator: ``real_m``, each chain's distance
        (``<chain>_m``) and ratio (``ratio_<chain>``, chain names with ``_``), and the exact-timing M5.
    steps
        Per-step rows (the offline chain as the spine): times, matched indices, lengths of every chain
        and of the truth (multi-speed K).
    timing
        Step-duration error against the truth (offline chain on codes): median absolute and rms, ms.
    saturation
        The fixed-point runs' saturation/wrap report ("" = none).
    matches
        :class:`StepMatch` per share.
    """

    subject_id: str
    adc_bits: int
    sampling_rate_hz: float
    runs: dict[str, ChainRun]
    calibrations: dict[str, Any]
    step_diffs: list[dict]
    step_deltas: dict[tuple[str, str], np.ndarray]
    segments: list[dict]
    steps: dict[str, np.ndarray]
    timing: dict[str, float]
    saturation: str
    matches: dict[str, StepMatch] = field(default_factory=dict)


def compare_walk(sw: SampledWalk, subject: Any, *, adc_bits: int = 10, ideal_table: StepTable | None = None,
                 calibration_sections: int = 2, include_turn: bool = False,
                 fixed_algorithm: Callable[..., Any] = OnlineStepAlgorithm,
                 m4_exponent: float = M4_EXPONENT) -> WalkComparison:
    """The four chains on one sampled walk with one K per mode; steps matched; 20 m sections (module notes).

    Parameters
    ----------
    ideal_table
        The ideal chain's table without K, to reuse across ADC widths (it does not depend on ``adc_bits``).
    fixed_algorithm
        What runs the online-fixed chain (default the firmware's algorithm; tests inject errors with it).
    m4_exponent
        M4's exponent p of every chain: the offline chains' raw M4 (:func:`with_m4_exponent`), the K fitted on
        them and so the on-line algorithm's step configuration (byte 20, whole eighths up to 1/2).
    """
    leg, foot = subject.leg_length_m, subject.foot_length_m
    sampling_rate_hz, t0 = sw.sampling_rate_hz, float(sw.times_s[0])
    sections = sections_from_marks(sw.mark_times_s, sw.truth["laps"], sampling_rate_hz=sampling_rate_hz)
    pools = calibration_sets(sections, calibration_sections=calibration_sections)
    cal = sw.calibration(adc_bits)
    codes = sw.codes(adc_bits)
    kw = dict(sampling_rate_hz=sampling_rate_hz, leg_length_m=leg, foot_length_m=foot, t0_s=t0)
    offline = with_m4_exponent(offline_step_table(cal.apply(codes), **kw), m4_exponent)
    # the one K per mode, fitted on the offline chain: every chain below uses these objects
    cals = {m: calibrate_on_sections(offline, pools[m], leg_length_m=leg, foot_length_m=foot,
                                     subject=subject.subject_id, m4_exponent=m4_exponent) for m in MODES}
    ideal_table = with_m4_exponent(ideal_table if ideal_table is not None else
                                   offline_step_table(cal.apply(sw.ideal_codes(adc_bits)), **kw), m4_exponent)
    okw = dict(kw, adc_calibration=cal, adc_bits=adc_bits)
    runs = {"ideal": _offline_run("ideal", ideal_table, cals), "offline": _offline_run("offline", offline, cals),
            "online-float": _online_run("float", codes, cals, algorithm=OnlineStepAlgorithm, **okw),
            "online-fixed": _online_run("fixed", codes, cals, algorithm=fixed_algorithm, **okw)}
    st = sw.truth["steps"]
    exact, truth_idx = truth_table(offline, st)
    runs["exact-timing"] = _offline_run("exact-timing", exact, cals)
    tl = np.asarray(st["length_m"], np.float64)

    def truth_lengths(table: StepTable) -> StepTable:
        _, idx = truth_table(table, st)
        v = np.where(idx >= 0, tl[np.maximum(idx, 0)], np.nan)
        return replace(table, length_m={e: v for e in ESTIMATORS})

    mm = "multi-speed"
    t = {k: runs[k].tables[mm] for k in CHAINS}
    matches = {s: match_steps(t[a], t[b]) for s, (a, b) in SHARES.items()}
    diffs: list[dict] = []
    deltas: dict[tuple[str, str], np.ndarray] = {}
    pairs = [(s, a, b, t[b], matches[s]) for s, (a, b) in SHARES.items()]
    for k in CHAINS:
        tt = truth_lengths(t[k])
        pairs.append(("truth", k, "truth", tt, match_steps(t[k], tt)))   # identity pairing: same events
    for s, a, b, tb, m in pairs:
        label = pair_label(a, b)
        diffs += step_differences(t[a], tb, m, pair=label, share=s)
        for est in ESTIMATORS:
            deltas[(label, est)] = step_deltas(t[a], tb, m, est)[0]
    # timing against the truth (steps with a window and a truth twin)
    has = (truth_idx >= 0) & np.isfinite(offline.duration_s)
    dt = offline.duration_s[has] - exact.duration_s[has]
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
                row = dict(subject=subject.subject_id, adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz, excursion=s.excursion,
                           speed_label=s.speed_label, section=s.index, start_m=s.start_m, end_m=s.end_m,
                           mode=m, estimator=est, real_m=s.real_m)
                for k in runs:
                    row[f"{column_key(k)}_m"] = float(dist[(k, m)][i, j])
                    row[f"ratio_{column_key(k)}"] = float(dist[(k, m)][i, j]) / s.real_m
                seg_rows.append(row)
    # per-step rows (offline as the spine; online-fixed through its online-float partner)
    of = t["offline"]
    ideal_of = matches["adc"].b_of_a(of.n_steps)
    float_of = matches["algorithm"].a_of_b(of.n_steps)
    fixed_of = _take(matches["arithmetic"].a_of_b(t["online-float"].n_steps), float_of, fill=-1)
    same_adc = np.zeros(of.n_steps, bool)
    same_adc[matches["adc"].a] = matches["adc"].same_events
    same_alg = _same_of_b(matches["algorithm"], of.n_steps)
    same_ar = _take(_same_of_b(matches["arithmetic"], t["online-float"].n_steps), float_of, fill=False)
    steps: dict[str, np.ndarray] = {
        "step": np.arange(of.n_steps), "foot_flat_s": of.time_s(of.foot_flat), "duration_s": of.duration_s,
        "exact_duration_s": exact.duration_s, "ideal_step": ideal_of, "online_float_step": float_of,
        "online_fixed_step": fixed_of, "truth_step": truth_idx, "same_events_adc": same_adc,
        "same_events_algorithm": same_alg,
        "same_events_arithmetic": same_ar,
        "truth_length_m": np.where(truth_idx >= 0, tl[np.maximum(truth_idx, 0)], np.nan)}
    for est in ESTIMATORS:
        e = est.lower()
        steps[f"{e}_offline_m"] = of.length_m[est]
        for k, idx in (("ideal", ideal_of), ("online-float", float_of), ("online-fixed", fixed_of)):
            steps[f"{e}_{column_key(k)}_m"] = _take(t[k].length_m[est], idx)
    return WalkComparison(subject.subject_id, int(adc_bits), float(sampling_rate_hz), runs, cals, diffs, deltas, seg_rows, steps,
                          timing, runs["online-fixed"].saturation, matches)


def _take(values: np.ndarray, idx: np.ndarray, *, fill: Any = math.nan) -> np.ndarray:
    """``values[idx]`` with ``fill`` where ``idx < 0`` (or ``values`` is empty)."""
    values = np.asarray(values)
    if values.size == 0:
        return np.full(idx.size, fill)
    return np.where(idx >= 0, values[np.maximum(idx, 0)], fill)


def _same_of_b(match: StepMatch, n_b: int) -> np.ndarray:
    """For each of the ``n_b`` rows of table ``b``: matched with the same events."""
    out = np.zeros(n_b, bool)
    out[match.b] = match.same_events
    return out


# ---------------------------------------------------------------------------------------------------------
# Bootstrap over subjects (gaitlog.host.studies.stats)


def bootstrap_budget(comparisons: list[WalkComparison], *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0,
                     level: float = BOOTSTRAP_LEVEL) -> list[dict]:
    """The error budget's summary figures with bootstrap intervals over subjects.

    Subjects are resampled with replacement (``n_resamples`` times, ``seed``; the same draws for every
    figure); in each resample a figure is recomputed on the pooled values of the drawn subjects (a subject
    drawn twice counts twice), and the interval is the central ``level`` of those figures (percentile
    bootstrap). The figures:

    * ``kind="step"``: per pair (the shares, and each chain against the truth) and estimator, the median
      of ``|a - b|`` over the matched steps with the same events, mm (multi-speed K);
    * ``kind="section"``: per pair, mode and estimator, the median of ``ratio_a - ratio_b`` over the
      evaluated 20 m sections (for ``<chain> - truth``: ``ratio - 1``).

    With one subject the interval is the point itself (nothing to resample).
    """
    n_sub = len(comparisons)
    if n_sub == 0:
        return []
    counts = subject_resamples(n_sub, n_resamples=n_resamples, seed=seed)

    def row(kind: str, share: str, pair: str, mode: str, est: str, statistic: str, groups: list[np.ndarray]) -> dict:
        value, lo, hi = subject_bootstrap(groups, MEDIAN, counts, level=level)
        return dict(kind=kind, share=share, pair=pair, mode=mode, estimator=est, statistic=statistic, value=float(value),
                    ci_low=float(lo), ci_high=float(hi), n_subjects=n_sub, n=int(sum(g.size for g in groups)))

    out = []
    shares = {r["pair"]: r["share"] for r in comparisons[0].step_diffs}
    for pair, share in shares.items():
        for est in ESTIMATORS:
            groups = [1e3 * np.abs(c.step_deltas.get((pair, est), np.zeros(0))) for c in comparisons]
            out.append(row("step", share, pair, "multi-speed", est, "median |d| mm", groups))
    section_pairs = [(s, a, b) for s, (a, b) in SHARES.items()] + [("truth", k, "truth") for k in CHAINS]
    for mode in MODES:
        for share, a, b in section_pairs:
            for est in ESTIMATORS:
                groups = []
                for c in comparisons:
                    seg = [s for s in c.segments if s["mode"] == mode and s["estimator"] == est]
                    x = np.array([s[f"ratio_{column_key(a)}"] for s in seg], float)
                    y = np.array([s[f"ratio_{column_key(b)}"] if b != "truth" else 1.0 for s in seg], float)
                    d = x - y
                    groups.append(d[np.isfinite(d)])
                out.append(row("section", share, pair_label(a, b), mode, est, "median d ratio", groups))
    return out


def format_budget(rows: list[dict], *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0) -> str:
    """Printed :func:`bootstrap_budget`: one line per pair (and mode), the five estimators across."""
    if not rows:
        return "error budget: no subject"
    n_sub = rows[0]["n_subjects"]
    lines = [f"error budget with {100 * BOOTSTRAP_LEVEL:.0f} % bootstrap intervals over {n_sub} subject(s) "
             f"({n_resamples} resamples of the subjects, seed {seed}); one K per mode, fitted on the offline chain"]
    keys: list[tuple[str, str, str]] = []
    for r in rows:
        k = (r["kind"], r["mode"], r["pair"])
        if k not in keys:
            keys.append(k)
    by = {(r["kind"], r["mode"], r["pair"], r["estimator"]): r for r in rows}
    head = None
    for kind, mode, pair in keys:
        h = (kind, mode)
        if h != head:
            head = h
            what = ("per step: median |a - b|, mm (multi-speed K; matched steps with the same events)"
                    if kind == "step" else f"per 20 m section, {mode} K: median (ratio a - ratio b)")
            lines.append(what)
            lines.append(f"{'share':<11}{'a - b':<29}" + "".join(f"{e:>27}" for e in ESTIMATORS))
        cells = []
        for e in ESTIMATORS:
            r = by[(kind, mode, pair, e)]
            fmt = "{:.3f}" if kind == "step" else "{:+.4f}"
            cells.append(f"{fmt.format(r['value'])} [{fmt.format(r['ci_low'])}, {fmt.format(r['ci_high'])}]"
                         if math.isfinite(r["value"]) else "n/a")
        share = by[(kind, mode, pair, ESTIMATORS[0])]["share"]
        lines.append(f"{share:<11}{pair:<29}" + "".join(f"{c:>27}" for c in cells))
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------------
# Decoded recordings: offline vs on-line float vs on-line fixed


@dataclass(eq=False)
class RecordingComparison:
    """The offline chain and the on-line algorithm in both arithmetics on one recording
    (:func:`compare_recording`).

    Attributes
    ----------
    tables
        ``offline``, ``online-float`` and ``online-fixed`` tables (the same K, or none).
    matches
        :class:`StepMatch` of the shares ``algorithm`` and ``arithmetic``.
    step_diffs, segments, steps
        Per-step difference rows, per-section rows, per-step columns (offline as the spine).
    saturation, saturated, wrapped, cycles_per_sample
        The fixed-point run's report, counts and mean PIC cycles per sample.
    segment_source
        How the sections were cut.
    """

    tables: dict[str, StepTable]
    matches: dict[str, StepMatch]
    step_diffs: list[dict]
    segments: list[dict]
    steps: dict[str, np.ndarray]
    saturation: str
    saturated: int
    wrapped: int
    cycles_per_sample: float
    segment_source: str



def compare_recording(codes: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                      adc_calibration: CalibrationSlot | None = None, adc_bits: int = 10,
                      valid: np.ndarray | None = None, k_fit: KFit | None = None, mark_times_s: np.ndarray | None = None, lap_m: float = 20.0,
                      segment_m: float = 20.0, t0_s: float = 0.0, sections: list[Section] | None = None,
                      run_starts: np.ndarray | None = None, block: int = STREAM_BLOCK_SAMPLES) -> RecordingComparison:
    """Offline chain, on-line float and on-line fixed on the same codes (no truth): matched steps,
    differences, sections.

    ``adc_calibration`` (``offset_counts``, ``matrix_g_per_count``; None = nominal) converts codes to g for
    the offline chain and is the on-line algorithm's device calibration; ``k_fit`` holds the step constants
    (K) of every chain (None: raw lengths, M4/M5 undefined). ``run_starts``: the logging runs' first rows
    (SESSION_START), where the on-line algorithm restarts. Sections: ``sections`` when given (e.g. the
    walking plan's, :func:`gaitlog.host.gait.sections.sections_from_marks`), else between MARK flags ``lap_m`` apart, else
    every ``segment_m`` of the offline chain's M3 distance.

    Segment rows hold ``<chain>_m`` and ``ratio_<chain>`` for the three chains, ``algorithm_m`` and
    ``arithmetic_m`` (the shares in distance).

    In bounded memory besides the codes: the offline chain is fed ``block`` samples at a time
    (:func:`streamed_offline_table`) and the on-line algorithm is fed block-wise; the matching, sections and
    per-step columns work on the step tables.
    """
    c = np.asarray(codes)
    ok = np.ones(c.shape[0], bool) if valid is None else np.asarray(valid, bool)
    cal = adc_calibration if adc_calibration is not None else CalibrationSlot.nominal(adc_bits)
    kw = dict(sampling_rate_hz=sampling_rate_hz, leg_length_m=leg_length_m, foot_length_m=foot_length_m, t0_s=t0_s)
    okw = dict(kw, k_fit=k_fit, adc_calibration=cal, adc_bits=adc_bits, valid=ok, run_starts=run_starts)
    tables = {"offline": streamed_offline_table(c, ok, cal, k_fit=k_fit, block=block, **kw)}
    tables["online-float"], _ = online_step_table(c, arithmetic="float", **okw)
    tables["online-fixed"], alg = online_step_table(c, arithmetic="fixed", **okw)
    shares = {s: SHARES[s] for s in ("algorithm", "arithmetic")}
    matches = {s: match_steps(tables[a], tables[b]) for s, (a, b) in shares.items()}
    diffs = []
    for s, (a, b) in shares.items():
        diffs += step_differences(tables[a], tables[b], matches[s], pair=pair_label(a, b), share=s)
    marks = np.asarray(mark_times_s if mark_times_s is not None else [], np.float64)
    known = sections is not None or marks.size >= 2
    if sections is not None:
        source = "the given sections"
    elif marks.size >= 2:
        sections, source = sections_from_marks(marks, lap_m=lap_m), f"between MARK flags, {lap_m:g} m apart"
    else:
        sections = segments_by_distance(tables["offline"], segment_m=segment_m)
        source = f"every {segment_m:g} m of the offline chain's M3 distance (no lap marks; real length unknown)"
    dist = {k: segment_distances(t, sections) for k, t in tables.items()}
    seg_rows = []
    for i, s in enumerate(sections):
        for j, est in enumerate(ESTIMATORS):
            real = s.real_m if known else math.nan
            row: dict[str, Any] = dict(section=s.index, t_start_s=s.t_start_s, t_end_s=s.t_end_s, estimator=est,
                                       real_m=real)
            for k in tables:
                row[f"{column_key(k)}_m"] = float(dist[k][i, j])
            for k in tables:
                row[f"ratio_{column_key(k)}"] = float(dist[k][i, j]) / real
            for sh, (a, b) in shares.items():
                row[f"{sh}_m"] = float(dist[a][i, j] - dist[b][i, j])
            seg_rows.append(row)
    of = tables["offline"]
    float_of = matches["algorithm"].a_of_b(of.n_steps)
    fixed_of = _take(matches["arithmetic"].a_of_b(tables["online-float"].n_steps), float_of, fill=-1)
    steps: dict[str, np.ndarray] = {
        "step": np.arange(of.n_steps), "foot_flat_s": of.time_s(of.foot_flat), "duration_s": of.duration_s,
        "online_float_step": float_of, "online_fixed_step": fixed_of,
        "same_events_algorithm": _same_of_b(matches["algorithm"], of.n_steps),
        "same_events_arithmetic": _take(_same_of_b(matches["arithmetic"], tables["online-float"].n_steps),
                                        float_of, fill=False)}
    for est in ESTIMATORS:
        e = est.lower()
        steps[f"{e}_offline_m"] = of.length_m[est]
        steps[f"{e}_online_float_m"] = _take(tables["online-float"].length_m[est], float_of)
        steps[f"{e}_online_fixed_m"] = _take(tables["online-fixed"].length_m[est], fixed_of)
    return RecordingComparison(tables, matches, diffs, seg_rows, steps, alg.arithmetic_context().report(),
                               alg.saturations, alg.wraps, alg.cycles.mean, source)


# ---------------------------------------------------------------------------------------------------------
# Output helpers


def rows_csv_text(rows: list[dict], columns: list[str] | tuple[str, ...] | None = None) -> str:
    """CSV text of dict rows (floats ``%.6g``, NaN as empty, anything else ``str``; a missing key is empty).

    Column by column: the float cells of a column are formatted together
    (:func:`gaitlog.firmware_sim.algorithms.steps.float_csv_cells`), the rest by ``str``.
    """
    if not rows:
        return ""
    names = list(columns) if columns is not None else list(rows[0])
    if not names:
        return "\n" * (len(rows) + 1)  # an empty header and one empty line per row
    cells = []
    for name in names:
        values = [r.get(name, "") for r in rows]
        at = [i for i, v in enumerate(values) if isinstance(v, float)]
        if len(at) == len(values):
            cells.append(float_csv_cells(values))
            continue
        column = list(map(str, values))
        for i, text in zip(at, float_csv_cells([values[i] for i in at]), strict=True):
            column[i] = text
        cells.append(column)
    return csv_text(names, cells)


def format_step_diffs(rows: list[dict]) -> str:
    """Printed per-step difference table (one line per pair and estimator)."""
    lines = [f"{'share':<11}{'a - b':<29}{'est':<5}{'n':>6}{'med|d| mm':>11}{'p95 mm':>9}{'max mm':>9}"
             f"{'bias mm':>9}{'max rel %':>10}{'diff.ev':>8}"]
    for r in rows:
        lines.append(f"{r.get('share', ''):<11}{r['pair']:<29}{r['estimator']:<5}{r['n']:>6}"
                     f"{r['median_abs_mm']:>11.3f}{r['p95_abs_mm']:>9.3f}{r['max_abs_mm']:>9.2f}{r['bias_mm']:>+9.3f}"
                     f"{100 * r['max_rel']:>10.3f}{r['n_different_events']:>8}")
    return "\n".join(lines)


def pool_step_diffs(rows: list[dict]) -> list[dict]:
    """Per (pair, estimator) over subjects: median of medians, max of maxima, summed counts."""
    out = []
    keys = []
    for r in rows:
        if (r["pair"], r["estimator"]) not in keys:
            keys.append((r["pair"], r["estimator"]))
    for pair, est in keys:
        rs = [r for r in rows if r["pair"] == pair and r["estimator"] == est]
        out.append(dict(share=rs[0].get("share", ""), pair=pair, estimator=est, n=sum(r["n"] for r in rs),
                        median_abs_mm=float(np.nanmedian([r["median_abs_mm"] for r in rs])),
                        p95_abs_mm=float(np.nanmax([r["p95_abs_mm"] for r in rs])),
                        max_abs_mm=float(np.nanmax([r["max_abs_mm"] for r in rs])),
                        bias_mm=float(np.nanmedian([r["bias_mm"] for r in rs])),
                        max_rel=float(np.nanmax([r["max_rel"] for r in rs])),
                        n_different_events=sum(r["n_different_events"] for r in rs)))
    return out


def format_segments(results: list[WalkComparison]) -> str:
    """Per estimator and mode: section-ratio median/IQR of each chain and the split in ratio (max ``|d|``)."""
    lines = ["20 m sections: ratio estimated / real (median, IQR) per chain; ADC = offline - ideal, alg = "
             "online-float - offline, arith = online-fixed - online-float (max |difference in ratio|)",
             f"{'mode':<13}{'est':<5}{'n':>4}" + "".join(f"{c:>13}{'IQR':>7}" for c in CHAINS)
             + f"{'ADC max':>9}{'alg max':>9}{'arith max':>10}"]
    segs = [s for r in results for s in r.segments]
    for mode in ("single-speed", "multi-speed"):
        for est in ESTIMATORS:
            sel = [s for s in segs if s["mode"] == mode and s["estimator"] == est]
            if not sel:
                continue
            v = {k: np.array([s[f"ratio_{column_key(k)}"] for s in sel], float) for k in CHAINS}
            q = {k: np.percentile(x, [25, 50, 75]) for k, x in v.items()}
            lines.append(f"{mode:<13}{est:<5}{len(sel):>4}" + "".join(
                f"{q[k][1]:>13.3f}{q[k][2] - q[k][0]:>7.3f}" for k in CHAINS)
                + "".join(f"{np.max(np.abs(v[a] - v[b])):>{w}.{p}f}"
                          for (a, b), w, p in zip(SHARES.values(), (9, 9, 10), (4, 4, 5))))
    return "\n".join(lines)


def pooled_step_columns(results: list[WalkComparison]) -> dict[str, np.ndarray]:
    """The per-step tables of several simulated subjects as one, with a ``subject`` column (its number)."""
    cols: dict[str, list] = {}
    for r in results:
        n = r.steps["step"].size
        cols.setdefault("subject", []).append(np.full(n, int(r.subject_id.lstrip("S") or 0)))
        for k, v in r.steps.items():
            cols.setdefault(k, []).append(v)
    return {k: np.concatenate(v) for k, v in cols.items()}
