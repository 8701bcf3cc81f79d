"""Calibrated acceleration -> per-step table with the five estimators (the float reference chain).

Steps of the chain (:class:`StepPipeline`):

1. Tilt correction: vertical (and AP) dynamic acceleration from the gravity direction
   (:func:`gaitlog.host.gait.axes.body_axes`).
2. Events: foot-flat, heel-strike, toe-off (:class:`gaitlog.host.gait.events.GaitEventDetector`).
3. One row per foot-flat: the step that ends there. Its window is the previous foot-flat of the same
   walking bout to this one; the first foot-flat of a bout (gait initiation, or after a gap longer than
   ``max_gap_s``) ends a step that has no window: it is counted but its length is NaN.
4. M1-M5 on every window (``gaitlog.host.gait.estimators``), raw (K = 1, or the cadence ``1/T`` for M5) and calibrated
   with a :class:`~gaitlog.host.gait.k_calibration.KFit` when one is given. Without one, M1 and M2 use
   K = 1 (the bare pendulum model), M4 and M5 are NaN (they have no physical scale without K).

Distance (:meth:`StepTable.distance_m`): the sum of the step lengths; a step whose length is NaN (no window,
a long gap, an impossible excursion) counts with the median length of the measured steps of its bout, and
the number of such steps is reported (``n_filled``).

Missing samples (:mod:`gaitlog.host.gait.gaps`, step 0 of the chain): a run of at most
:data:`~gaitlog.host.gait.gaps.MAX_INTERPOLATED_GAP_S` (0.1 s) is interpolated linearly on the sample grid; a
longer run stays missing, is used by no filter or integral, and ends the walking bout (step 3).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Self

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.host.gait.axes import BodyAxes, body_axes
from gaitlog.host.gait.estimators.cadence import CadenceM5
from gaitlog.host.gait.estimators.pendulum import PendulumDriftM2, PendulumM1
from gaitlog.host.gait.estimators.two_phase import TwoPhasePendulumM3
from gaitlog.host.gait.estimators.weinberg import WeinbergM4, weinberg_length_m
from gaitlog.host.gait.events import GaitEventDetector
from gaitlog.host.gait.gaps import MAX_INTERPOLATED_GAP_S, GapFiller
from gaitlog.host.gait.integration import step_samples

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.host.gait.k_calibration import KFit


class StepPipeline:
    """The float step chain: acceleration in g -> :class:`StepTable`.

    Parameters
    ----------
    leg_length_m, foot_length_m
        Anatomical inputs of M1-M3 (see :func:`gaitlog.host.gait.anthropometry.anatomical_lengths`).
    k_fit
        Per-subject constants (K of M1/M2/M4, K1/K2 of M5), or None.
    detector
        Event detector (default parameters when None).
    gravity_window_s
        Window of the moving-mean gravity estimate.
    max_fill_s
        Longest run of missing samples interpolated before everything else (:mod:`gaitlog.host.gait.gaps`).
    m3_double_support
        M3's double-support term (:data:`~gaitlog.host.gait.estimators.two_phase.DOUBLE_SUPPORT_RULES`; the foot
        length, Alvarez's, by default).

    Attributes
    ----------
    gaps_
        The fitted :class:`~gaitlog.host.gait.gaps.GapFiller` (missing fraction, longest gap, samples filled).
    axes_, events_, steps_
        :class:`~gaitlog.host.gait.axes.BodyAxes`, the fitted :class:`~gaitlog.host.gait.events.GaitEventDetector`,
        the :class:`StepTable`.
    notes_
        What the caller should tell the user, returned instead of warned: no walking steps detected, step
        lengths set to NaN for an impossible excursion (``n_impossible_`` of them, M1-M3 summed).

    Examples
    --------
    >>> from gaitlog.units import STANDARD_GRAVITY_M_S2
    >>> sampling_rate_hz = 50.0; t = np.arange(int(20 * sampling_rate_hz)) / sampling_rate_hz
    >>> z = 0.02 * np.cos(2 * np.pi * 2.0 * t)                  # CoM, 2 steps/s, h = 4 cm, lowest at t = 0.25 + k/2
    >>> acc = np.zeros((t.size, 3)); acc[:, 2] = 1.0 - 0.02 * (2 * np.pi * 2.0) ** 2 * np.cos(2 * np.pi * 2.0 * t) / STANDARD_GRAVITY_M_S2
    >>> p = StepPipeline(leg_length_m=0.9, foot_length_m=0.26).run(acc, sampling_rate_hz=sampling_rate_hz)
    >>> p.steps_.n_steps in (38, 39, 40)
    True
    >>> round(float(np.nanmedian(p.steps_.vertical_excursion_m["M2"])), 2)
    0.04
    """

    def __init__(
        self,
        *,
        leg_length_m: float,
        foot_length_m: float,
        k_fit: KFit | None = None,
        detector: GaitEventDetector | None = None,
        gravity_window_s: float = 4.0,
        max_fill_s: float = MAX_INTERPOLATED_GAP_S,
        m3_double_support: str = "foot",
    ) -> None:
        self.leg_length_m = leg_length_m
        self.foot_length_m = foot_length_m
        self.k_fit = k_fit
        self.detector = detector
        self.gravity_window_s = gravity_window_s
        self.max_fill_s = max_fill_s
        self.m3_double_support = m3_double_support

    def __repr__(self) -> str:
        k = "with K" if self.k_fit is not None else "raw (no K)"
        done = f", fitted: {self.steps_.n_steps} steps" if hasattr(self, "steps_") else ""
        return (f"StepPipeline(leg {self.leg_length_m:.3f} m, foot {self.foot_length_m:.3f} m, {k}, "
                f"gravity window {self.gravity_window_s:g} s{done})")

    def run(
        self, acc_g: np.ndarray, *, sampling_rate_hz: float, valid: np.ndarray | None = None, t0_s: float = 0.0
    ) -> Self:
        """Run the chain on calibrated specific force ``acc_g`` (``(n, 3)`` g, NaN/``valid`` for gaps)."""
        acc = np.asarray(acc_g, np.float64)
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise ValueError(f"acc_g must have shape (n, 3), got {acc.shape}")
        sampling_rate_hz = float(sampling_rate_hz)
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        if valid is not None and np.shape(valid) != (acc.shape[0],):
            raise ValueError(f"valid must have shape ({acc.shape[0]},), got {np.shape(valid)}")
        self.gaps_ = GapFiller(max_gap_s=self.max_fill_s).fill(
            acc, np.ones(acc.shape[0], bool) if valid is None else valid, sampling_rate_hz=sampling_rate_hz)
        acc, valid = self.gaps_.acc_, self.gaps_.valid_
        self.axes_: BodyAxes = body_axes(acc, sampling_rate_hz=sampling_rate_hz, valid=valid,
                                         gravity_window_s=self.gravity_window_s)
        ok = self.axes_.valid
        av = self.axes_.acc_v_m_s2
        det = (self.detector if self.detector is not None else GaitEventDetector()).clone()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self.events_ = det.detect(av, sampling_rate_hz=sampling_rate_hz, valid=ok)
        self.notes_: list[str] = [str(c.message) for c in caught]
        self.steps_ = self._table(av, ok, sampling_rate_hz, t0_s)
        return self

    def _table(self, av: np.ndarray, ok: np.ndarray, sampling_rate_hz: float, t0_s: float) -> StepTable:
        ev = self.events_
        lp = ev.first_harmonic_m_s2_
        ok = ok & np.isfinite(av)
        table, self.n_impossible_ = step_table(
            ev.foot_flat_, ev.heel_strike_, ev.toe_off_, ev.bout_, lambda lo, hi: (av[lo:hi], ok[lo:hi], lp[lo:hi]),
            sampling_rate_hz=sampling_rate_hz, t0_s=t0_s, leg_length_m=self.leg_length_m,
            foot_length_m=self.foot_length_m, k_fit=self.k_fit, m3_double_support=self.m3_double_support)
        if self.n_impossible_:
            self.notes_.append(impossible_note(self.n_impossible_, self.leg_length_m))
        return table


#: Steps whose windows start in the same block of this many samples are integrated together (one cumulative sum
#: from zero, :mod:`gaitlog.host.gait.integration`): a step's numbers depend on the samples of its block only, so
#: the streaming chain (:mod:`gaitlog.host.gait.streaming`) gives the whole-array results bit for bit, and the
#: running sum stays short on long recordings.
STEP_GROUP_SAMPLES = 1 << 16


def impossible_note(n_impossible: int, leg_length_m: float) -> str:
    """The note on the steps set to NaN for an impossible vertical excursion."""
    return (f"{n_impossible} step length(s) set to NaN for an impossible vertical excursion (h > 2 l with "
            f"l = {leg_length_m} m)")


def step_table(ff: np.ndarray, hs: np.ndarray, toe_off: np.ndarray, bout: np.ndarray,
               take: Callable[[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]], *, sampling_rate_hz: float,
               t0_s: float, leg_length_m: float, foot_length_m: float,
               k_fit: KFit | None, m3_double_support: str = "foot") -> tuple[StepTable, int]:
    """The step table (steps 3 and 4 of the module notes) from the per-foot-flat events and ``take(lo, hi)``, which
    returns the vertical acceleration, where it is measured and finite, and its first harmonic on samples
    ``[lo, hi)``; also the number of step lengths (M1-M3 summed) set to NaN for an impossible excursion."""
    m = ff.size
    start = np.full(m, -1, np.int64)
    toe = np.full(m, -1, np.int64)
    if m > 1:
        linked = bout[1:] == bout[:-1]
        start[1:] = np.where(linked, ff[:-1], -1)
        toe[1:] = np.where(linked, toe_off[:-1], -1)
    # a toe-off must fall between the window start and the heel-strike
    toe = np.where((toe > start) & ((hs < 0) | (toe < hs)), toe, -1)
    w = np.flatnonzero(start >= 0)
    s_w, e_w = start[w], ff[w]
    est = _estimate_groups(take, s_w, e_w, toe[w], np.where(hs[w] > s_w, hs[w], -1), sampling_rate_hz,
                           leg_length_m, foot_length_m, m3_double_support)

    def spread(x: np.ndarray) -> np.ndarray:
        out = np.full(m, np.nan)
        out[w] = x
        return out

    n_missing = np.zeros(m, np.int64)
    duration = np.full(m, np.nan)
    if w.size:
        duration[w] = (e_w - s_w) / sampling_rate_hz
        n_missing[w] = est["n_missing"]
    raw = {"M1": spread(est["M1"]), "M2": spread(est["M2"]), "M3": spread(est["M3"]), "M4": spread(est["M4"]),
           "M5": np.where(duration > 0, 1.0 / duration, np.nan)}
    table = StepTable(
        sampling_rate_hz, float(t0_s), ff, hs.copy(), toe, start, bout.copy(), duration, n_missing,
        {"M1": spread(est["h1"]), "M2": spread(est["h2"]), "M3": spread(est["h3"])},
        spread(est["range"]), raw, {},
    )
    table.length_m = apply_calibration(table, k_fit)
    return table, int(est["n_impossible"])


def _estimate_groups(take: Callable[[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]], s_w: np.ndarray,
                     e_w: np.ndarray, toe: np.ndarray, hs: np.ndarray, sampling_rate_hz: float, leg: float,
                     foot: float, m3_double_support: str = "foot") -> dict:
    """M1-M4 on the windows ``[s_w, e_w]``, the steps starting in one :data:`STEP_GROUP_SAMPLES` block at a time,
    each group on the samples its windows span (``take``); the per-step results concatenated."""
    keys = ("M1", "M2", "M3", "M4", "h1", "h2", "h3", "range", "n_missing")
    parts: dict[str, list] = {k: [] for k in keys}
    n_impossible = 0
    group = s_w // STEP_GROUP_SAMPLES
    cuts = np.flatnonzero(np.diff(group)) + 1
    for a, b in zip(np.r_[0, cuts].tolist(), np.r_[cuts, s_w.size].tolist()):
        if a == b:
            continue
        lo, hi = int(s_w[a]), int(e_w[a:b].max()) + 1
        av, ok, lp = take(lo, hi)
        s, e = s_w[a:b] - lo, e_w[a:b] - lo
        t, h = np.where(toe[a:b] >= 0, toe[a:b] - lo, -1), np.where(hs[a:b] >= 0, hs[a:b] - lo, -1)
        ss = step_samples(s, e, ok, sampling_rate_hz)     # shared by M1-M3
        with warnings.catch_warnings(record=True):    # the estimators' warnings are their n_impossible_ counts
            warnings.simplefilter("always")
            m1 = PendulumM1().estimate(av, step_start=s, step_end=e, sampling_rate_hz=sampling_rate_hz,
                                       leg_length_m=leg, valid=ok, samples=ss)
            m2 = PendulumDriftM2().estimate(av, step_start=s, step_end=e, sampling_rate_hz=sampling_rate_hz,
                                            leg_length_m=leg, valid=ok, samples=ss)
            m3 = TwoPhasePendulumM3(double_support=m3_double_support).estimate(
                av, step_start=s, step_end=e, step_toe_off=t, step_heel_strike=h, sampling_rate_hz=sampling_rate_hz,
                leg_length_m=leg, foot_length_m=foot, valid=ok, samples=ss)
            m4 = WeinbergM4().estimate(av, step_start=s, step_end=e, sampling_rate_hz=sampling_rate_hz, valid=ok,
                                       lowpassed=lp)
        n_impossible += sum(int(getattr(x, "n_impossible_", 0)) for x in (m1, m2, m3))
        for k, v in zip(keys, (m1.step_length_m_, m2.step_length_m_, m3.step_length_m_, m4.step_length_m_,
                               m1.vertical_excursion_m_, m2.vertical_excursion_m_, m3.single_support_excursion_m_,
                               m4.acc_range_m_s2_, ss.n_missing)):
            parts[k].append(v)
    out = {k: np.concatenate(v) if v else np.zeros(0, np.int64 if k == "n_missing" else np.float64)
           for k, v in parts.items()}
    out["n_impossible"] = n_impossible
    return out


def apply_calibration(table: StepTable, k_fit: KFit | None) -> dict[str, np.ndarray]:
    """Calibrated lengths of every estimator from the raw ones (see :class:`StepPipeline` notes)."""
    raw = table.raw_m
    nan = np.full(table.n_steps, np.nan)
    if k_fit is None:
        return {"M1": raw["M1"].copy(), "M2": raw["M2"].copy(), "M3": raw["M3"].copy(), "M4": nan.copy(),
                "M5": nan.copy()}
    m5 = CadenceM5(k1_m_s=k_fit.k1_m5_m_s, k2_m=k_fit.k2_m5_m).estimate(
        step_duration_s=table.duration_s).step_length_m_
    # M4: K with the exponent it was fitted with (the chain's raw lengths use M4_EXPONENT; an older K file's
    # 1/4 is applied to the step's range)
    if math.isclose(k_fit.m4_exponent, M4_EXPONENT):
        m4 = k_fit.k_m4 * raw["M4"]
    else:
        rng = table.acc_range_m_s2 if table.acc_range_m_s2.size == table.n_steps else nan
        m4 = weinberg_length_m(rng, k=k_fit.k_m4, exponent=k_fit.m4_exponent)
    return {
        "M1": k_fit.k_m1 * raw["M1"],
        "M2": k_fit.k_m2 * raw["M2"],
        "M3": raw["M3"].copy(),
        "M4": m4,
        "M5": m5,
    }
