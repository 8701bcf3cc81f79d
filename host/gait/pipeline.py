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
    calibration
        Per-subject constants (K of M1/M2/M4, K1/K2 of M5), or None.
    detector
        Event detector (default parameters when None).
    gravity_window_s
        Window of the moving-mean gravity estimate.
    max_fill_s
        Longest run of missing samples interpolated before everything else (:mod:`gaitlog.host.gait.gaps`).

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
        calibration: KFit | None = None,
        detector: GaitEventDetector | None = None,
        gravity_window_s: float = 4.0,
        max_fill_s: float = MAX_INTERPOLATED_GAP_S,
    ) -> None:
        self.leg_length_m = leg_length_m
        self.foot_length_m = foot_length_m
        self.calibration = calibration
        self.detector = detector
        self.gravity_window_s = gravity_window_s
        self.max_fill_s = max_fill_s

    def __repr__(self) -> str:
        k = "with K" if self.calibration is not None else "raw (no K)"
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
        ff = ev.foot_flat_
        m = ff.size
        start = np.full(m, -1, np.int64)
        toe = np.full(m, -1, np.int64)
        if m > 1:
            linked = ev.bout_[1:] == ev.bout_[:-1]
            start[1:] = np.where(linked, ff[:-1], -1)
            toe[1:] = np.where(linked, ev.toe_off_[:-1], -1)
        has = start >= 0
        # a toe-off must fall between the window start and the heel-strike
        hs = ev.heel_strike_
        toe = np.where((toe > start) & ((hs < 0) | (toe < hs)), toe, -1)
        w = np.flatnonzero(has)
        s_w, e_w = start[w], ff[w]
        leg, foot = self.leg_length_m, self.foot_length_m
        ss = step_samples(s_w, e_w, ok & np.isfinite(av), sampling_rate_hz)     # shared by M1-M3
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m1 = PendulumM1().estimate(av, step_start=s_w, step_end=e_w, sampling_rate_hz=sampling_rate_hz,
                                       leg_length_m=leg, valid=ok, samples=ss)
            m2 = PendulumDriftM2().estimate(av, step_start=s_w, step_end=e_w, sampling_rate_hz=sampling_rate_hz,
                                            leg_length_m=leg, valid=ok, samples=ss)
            m3 = TwoPhasePendulumM3().estimate(av, step_start=s_w, step_end=e_w, step_toe_off=toe[w],
                                               step_heel_strike=np.where(hs[w] > s_w, hs[w], -1),
                                               sampling_rate_hz=sampling_rate_hz, leg_length_m=leg, foot_length_m=foot,
                                               valid=ok, samples=ss)
            m4 = WeinbergM4().estimate(av, step_start=s_w, step_end=e_w, sampling_rate_hz=sampling_rate_hz, valid=ok,
                                       lowpassed=ev.first_harmonic_m_s2_)
        del caught                     # the estimators' warnings are their n_impossible_ counts, summed here
        self.n_impossible_ = sum(int(getattr(x, "n_impossible_", 0)) for x in (m1, m2, m3))
        if self.n_impossible_:
            self.notes_.append(f"{self.n_impossible_} step length(s) set to NaN for an impossible vertical "
                               f"excursion (h > 2 l with l = {leg} m)")

        def spread(x: np.ndarray) -> np.ndarray:
            out = np.full(m, np.nan)
            out[w] = x
            return out

        n_missing = np.zeros(m, np.int64)
        duration = np.full(m, np.nan)
        if w.size:
            duration[w] = (e_w - s_w) / sampling_rate_hz
            n_missing[w] = ss.n_missing
        raw = {
            "M1": spread(m1.step_length_m_),
            "M2": spread(m2.step_length_m_),
            "M3": spread(m3.step_length_m_),
            "M4": spread(m4.step_length_m_),
            "M5": np.where(duration > 0, 1.0 / duration, np.nan),
        }
        table = StepTable(
            sampling_rate_hz, float(t0_s), ff, hs.copy(), toe, start, ev.bout_.copy(), duration, n_missing,
            {"M1": spread(m1.vertical_excursion_m_), "M2": spread(m2.vertical_excursion_m_),
             "M3": spread(m3.single_support_excursion_m_)},
            spread(m4.acc_range_m_s2_), raw, {},
        )
        table.length_m = apply_calibration(table, self.calibration)
        return table


def apply_calibration(table: StepTable, calibration: KFit | None) -> dict[str, np.ndarray]:
    """Calibrated lengths of every estimator from the raw ones (see :class:`StepPipeline` notes)."""
    raw = table.raw_m
    nan = np.full(table.n_steps, np.nan)
    if calibration is None:
        return {"M1": raw["M1"].copy(), "M2": raw["M2"].copy(), "M3": raw["M3"].copy(), "M4": nan.copy(),
                "M5": nan.copy()}
    m5 = CadenceM5(k1_m_s=calibration.k1_m5_m_s, k2_m=calibration.k2_m5_m).estimate(
        step_duration_s=table.duration_s).step_length_m_
    # M4: K with the exponent it was fitted with (the chain's raw lengths use M4_EXPONENT; an older K file's
    # 1/4 is applied to the step's range)
    if math.isclose(calibration.m4_exponent, M4_EXPONENT):
        m4 = calibration.k_m4 * raw["M4"]
    else:
        rng = table.acc_range_m_s2 if table.acc_range_m_s2.size == table.n_steps else nan
        m4 = weinberg_length_m(rng, k=calibration.k_m4, exponent=calibration.m4_exponent)
    return {
        "M1": calibration.k_m1 * raw["M1"],
        "M2": calibration.k_m2 * raw["M2"],
        "M3": raw["M3"].copy(),
        "M4": m4,
        "M5": m5,
    }
