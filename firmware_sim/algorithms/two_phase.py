"""M3 in fixed point: ``S = 2 sqrt(2 l h1 − h1²) + foot length``, no K (mirrors ``host.estimators.two_phase``).

``h1`` is the range of the M2 integer position between toe-off and heel-strike (single support); the
pendulum part is :func:`~firmware_sim.algorithms.pendulum.pendulum_length_q`, the foot length is added in
UQ2.14 (saturating).
"""

from __future__ import annotations

from typing import Self

import numpy as np

from firmware_sim.algorithms.formats import EXCURSION_Q, LENGTH_Q, STEP_Q
from firmware_sim.algorithms.integration import (
    StepSamplesQ,
    VerticalPositionsQ,
    position_unit_m,
    step_samples_q,
    vertical_positions_q,
)
from firmware_sim.algorithms.pendulum import excursion_q, pendulum_length_q
from firmware_sim.fixedpoint import ArithmeticContext, add, requantize


class TwoPhasePendulumM3Q:
    """M3 step length in fixed point (single-support pendulum + foot length)."""

    def __init__(self) -> None:
        pass

    def estimate(
        self,
        acc_v_q: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        step_toe_off: np.ndarray,
        step_heel_strike: np.ndarray,
        sampling_rate_hz: float,
        leg_length_m: float,
        foot_length_m: float,
        valid: np.ndarray | None = None,
        ctx: ArithmeticContext | None = None,
        positions: tuple[StepSamplesQ, VerticalPositionsQ] | None = None,
    ) -> Self:
        """As the float M3; ``-1`` toe-off / heel-strike means not detected (no length).

        Sets ``excursion_q_``, ``step_length_q_`` (0 where no length), ``defined_``, ``n_impossible_``,
        ``n_no_events_`` and the float views ``single_support_excursion_m_``, ``step_length_m_`` (NaN).
        """
        a = np.asarray(acc_v_q, np.int64)
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        to = np.asarray(step_toe_off, np.int64)
        hs = np.asarray(step_heel_strike, np.int64)
        if to.shape != start.shape or hs.shape != start.shape:
            raise ValueError("step_toe_off and step_heel_strike need one entry per step")
        ok = np.ones(a.size, bool) if valid is None else np.asarray(valid, bool)
        if positions is not None:
            ss, p2 = positions[0], positions[1].p2
        else:
            ss = step_samples_q(start, end, ok)
            p2 = vertical_positions_q(a, ss, ctx=ctx).p2
        has = (to >= start) & (hs <= end) & (to >= 0) & (hs >= 0) & (hs > to)
        inside = (ss.index >= to[ss.step]) & (ss.index <= hs[ss.step]) & has[ss.step]
        big = np.iinfo(np.int64).max
        hi = ss.reduce_max(np.where(inside, p2, -big)) if ss.first.size else np.zeros(0, np.int64)
        lo = ss.reduce_min(np.where(inside, p2, big)) if ss.first.size else np.zeros(0, np.int64)
        any_inside = (np.bincount(ss.step[inside], minlength=start.size) > 0) & ss.defined
        span = np.where(any_inside, hi - lo, 0)
        self.excursion_q_ = excursion_q(span, position_unit_m(sampling_rate_hz, m2=True), ctx=ctx)
        s1, impossible = pendulum_length_q(self.excursion_q_, int(LENGTH_Q.from_float(leg_length_m)), ctx=ctx)
        foot_q = requantize(LENGTH_Q.from_float(foot_length_m), LENGTH_Q, STEP_Q)
        s = add(s1, foot_q, STEP_Q, ctx=ctx, op="m3.foot")
        self.defined_ = any_inside & ~impossible
        self.n_impossible_ = int(np.count_nonzero(impossible & any_inside))
        self.n_no_events_ = int(np.count_nonzero(~has))
        self.step_length_q_ = np.where(self.defined_, s, 0)
        self.single_support_excursion_m_ = np.where(any_inside, EXCURSION_Q.to_float(self.excursion_q_), np.nan)
        self.step_length_m_ = np.where(self.defined_, STEP_Q.to_float(s), np.nan)
        return self
