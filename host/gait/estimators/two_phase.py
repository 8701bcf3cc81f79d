"""M3: two-phase pendulum, no calibration (Alvarez et al. 2006, Fig. 3-4).

.. math:: S = 2\\sqrt{2 l h_1 - h_1^2} + S_2

``h1`` is the vertical excursion (max - min) of the M2-corrected CoM position between toe-off and
heel-strike (single support, the inverted pendulum over the stance leg), ``S2`` the foot length (the
double-support displacement, taken constant). Steps without a toe-off or heel-strike, or with an impossible
``h1 > 2 l``, are NaN (counted in ``n_impossible_`` / ``n_no_events_``).

``double_support`` chooses the double-support term (:data:`DOUBLE_SUPPORT_RULES`; none has a constant chosen on
recordings):

* ``"foot"`` (the default, Alvarez's): ``S2`` = the foot length, the same for every step;
* ``"single-support-speed"``: the centre of mass crosses the double support at its mean single-support speed,
  ``S2 = S1 (T - T_ss) / T_ss`` with ``T`` the step window and ``T_ss`` toe-off to heel-strike (no foot length);
* ``"end-speed"``: at the speed the pendulum has where single support ends (toe-off and heel-strike): on an arc
  of radius ``l`` the velocity is tangent, so the horizontal speed is ``|v_z| cos(theta) / sin(theta)`` with
  ``sin(theta) = (S1 / 2) / l`` and ``v_z`` the M2-corrected vertical velocity at that event;
  ``S2 = v_x(toe-off) (toe-off - start) + v_x(heel-strike) (end - heel-strike)``.

The double support scored against the IPOL foot sensors: :mod:`gaitlog.host.studies.ipol_m3`.
"""

from __future__ import annotations

import warnings
from typing import Self

import numpy as np

from gaitlog.host.gait.estimators.pendulum import _check, pendulum_length_m
from gaitlog.host.gait.integration import StepSamples, m2_vertical_velocity, step_samples, vertical_positions

#: The double-support terms of :class:`TwoPhasePendulumM3` (module notes); the first is Alvarez's and the default.
DOUBLE_SUPPORT_RULES = ("foot", "single-support-speed", "end-speed")


class TwoPhasePendulumM3:
    """M3 step length: single-support pendulum + foot length (no K).

    Examples
    --------
    Single support from 0.1 s to 0.4 s of a 0.5 s step; the CoM rises and falls by 2 cm as the pendulum of
    a 0.9 m leg whose chord is 2 sqrt(2 l h1 - h1^2).

    >>> sampling_rate_hz, T, A, l, foot = 200.0, 0.5, 0.02, 0.9, 0.26
    >>> t = np.arange(int(T * sampling_rate_hz) + 1) / sampling_rate_hz
    >>> a = A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T)
    >>> to, hs = 20, 80                       # samples; z(to) = z(hs) = -A cos(0.8 pi)
    >>> m3 = TwoPhasePendulumM3().estimate(a, step_start=[0], step_end=[100], step_toe_off=[to],
    ...     step_heel_strike=[hs], sampling_rate_hz=sampling_rate_hz, leg_length_m=l, foot_length_m=foot)
    >>> h1 = A - (-A * np.cos(2 * np.pi * 0.1 / T))
    >>> round(float(m3.step_length_m_[0]), 3), round(float(2 * np.sqrt(2 * l * h1 - h1 ** 2) + foot), 3)
    (0.691, 0.691)
    """

    def __init__(self, *, double_support: str = "foot") -> None:
        if double_support not in DOUBLE_SUPPORT_RULES:
            raise ValueError(f"double_support must be one of {', '.join(DOUBLE_SUPPORT_RULES)}, got {double_support!r}")
        self.double_support = double_support

    def estimate(
        self,
        acc_v_m_s2: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        step_toe_off: np.ndarray,
        step_heel_strike: np.ndarray,
        sampling_rate_hz: float,
        leg_length_m: float,
        foot_length_m: float,
        valid: np.ndarray | None = None,
        samples: StepSamples | None = None,
    ) -> Self:
        """Estimate each step ``[step_start_k, step_end_k]`` with single support ``[toe_off_k, heel_strike_k]``.

        ``-1`` in ``step_toe_off`` / ``step_heel_strike`` means "not detected" (the step is NaN).
        Sets ``single_support_excursion_m_``, ``pendulum_length_m_`` (S1), ``double_support_length_m_`` (S2),
        ``step_length_m_``, ``n_impossible_``, ``n_no_events_``.
        """
        acc = np.asarray(acc_v_m_s2, np.float64)
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        to = np.asarray(step_toe_off, np.int64)
        hs = np.asarray(step_heel_strike, np.int64)
        _check(acc, start, end, leg_length_m)
        if not (np.isfinite(foot_length_m) and foot_length_m >= 0):
            raise ValueError(f"foot_length_m must be non-negative, got {foot_length_m!r}")
        if to.shape != start.shape or hs.shape != start.shape:
            raise ValueError("step_toe_off and step_heel_strike need one entry per step")
        ok = np.isfinite(acc) if valid is None else (np.asarray(valid, bool) & np.isfinite(acc))
        # ``samples`` lets a caller that runs several estimators on the same windows lay them out once
        ss = samples if samples is not None else step_samples(start, end, ok, sampling_rate_hz)
        p2 = vertical_positions(acc, ss)[1]
        has = (to >= start) & (hs <= end) & (to >= 0) & (hs >= 0) & (hs > to)
        inside = (ss.index >= ss.spread(to)) & (ss.index <= ss.spread(hs)) & ss.spread(has)
        h1 = ss.reduce_max(np.where(inside, p2, np.nan)) - ss.reduce_min(np.where(inside, p2, np.nan))
        self.single_support_excursion_m_ = h1
        s1, self.n_impossible_ = pendulum_length_m(h1, leg_length_m)
        self.n_no_events_ = int(np.count_nonzero(~has))
        self.pendulum_length_m_ = s1
        self.double_support_length_m_ = self._double_support(acc, ss, s1, start, end, np.where(has, to, start),
                                                             np.where(has, hs, end), sampling_rate_hz,
                                                             leg_length_m, foot_length_m)
        self.step_length_m_ = s1 + self.double_support_length_m_
        if self.n_impossible_:
            warnings.warn(f"M3: {self.n_impossible_} step(s) with an impossible single-support excursion "
                          f"(h1 > 2 l) set to NaN", stacklevel=2)
        return self

    def _double_support(self, acc: np.ndarray, ss: StepSamples, s1: np.ndarray, start: np.ndarray, end: np.ndarray,
                        to: np.ndarray, hs: np.ndarray, sampling_rate_hz: float, leg_length_m: float,
                        foot_length_m: float) -> np.ndarray:
        """S2 per step by :attr:`double_support` (module notes); NaN where S1 is."""
        before_s, after_s = (to - start) / sampling_rate_hz, (end - hs) / sampling_rate_hz
        if self.double_support == "foot":
            return np.where(np.isfinite(s1), foot_length_m, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.double_support == "single-support-speed":
                return s1 * (before_s + after_s) / ((hs - to) / sampling_rate_hz)
            v = m2_vertical_velocity(acc, ss)
            v_to, v_hs = self._at(v, ss, to), self._at(v, ss, hs)
            half = s1 / 2
            cot = np.sqrt(leg_length_m ** 2 - half ** 2) / half   # horizontal / vertical speed on the arc
            return cot * (np.abs(v_to) * before_s + np.abs(v_hs) * after_s)

    @staticmethod
    def _at(v: np.ndarray, ss: StepSamples, index: np.ndarray) -> np.ndarray:
        """Each window's value of the per-sample ``v`` at sample ``index[k]`` (its nearest measured sample)."""
        if index.size == 0 or ss.index.size == 0:
            return np.full(index.size, np.nan)
        span = int(ss.index.max()) + 1
        key = ss.step * span + ss.index                    # strictly increasing: window, then sample
        k = np.searchsorted(key, np.arange(index.size) * span + index)
        k = np.clip(np.minimum(np.maximum(k, ss.first), ss.first + ss.n_measured - 1), 0, ss.index.size - 1)
        return np.where(ss.n_measured > 0, v[k], np.nan)
