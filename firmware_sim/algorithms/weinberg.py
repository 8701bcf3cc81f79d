"""M4 in fixed point: ``S = K (a_max − a_min)^(1/4)`` (mirrors ``host.estimators.weinberg``).

``a`` is the 3 Hz low-passed vertical acceleration (raw Q2.16 g from the event detector's filter); its
range in the step is rounded to ``r``, a 16-bit unsigned Q3.13 (< 8 g). The fourth root keeps 13 fraction bits with two
integer square roots: ``y = isqrt(r << 13)`` (the square root in Q.13), ``root = isqrt(y << 13)``; both
arguments stay below 2^30. The float chain takes the range in m/s^2, so its K multiplies
``(g0 r)^(1/4) = g0^(1/4) r^(1/4)``: the firmware folds ``g0^(1/4)`` into its constant ``K' = K g0^(1/4)``
(UQ1.15, so K < 1.13 m/(m/s^2)^(1/4)) and computes ``S = root · K'`` (16×16 multiply, UQ2.14).
"""

from __future__ import annotations

from typing import Self

import numpy as np

from firmware_sim.algorithms.formats import K_Q, LOWPASS_OUT_Q, ROOT4_Q, STANDARD_GRAVITY_M_S2, STEP_Q
from firmware_sim.algorithms.integration import step_samples_q
from firmware_sim.fixedpoint import ArithmeticContext, isqrt, mul_q, saturate, shift_left, shift_right

G0_ROOT4 = STANDARD_GRAVITY_M_S2 ** 0.25


def root4_q(range_q: np.ndarray, *, ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Fourth root of unsigned Q3.13 ranges, raw Q3.13 (floor of each square root).

    >>> ROOT4_Q.to_float(root4_q(np.array([0, 8192, 4 * 8192, 2 ** 16 - 1]))).round(4).tolist()
    [0.0, 1.0, 1.4142, 1.6818]
    """
    r = saturate(np.asarray(range_q, np.int64), 16, signed=False, ctx=ctx, op="m4.range")
    y = isqrt(shift_left(r, ROOT4_Q.frac_bits, 32, signed=False, ctx=ctx), ctx=ctx)
    return isqrt(shift_left(y, ROOT4_Q.frac_bits, 32, signed=False, ctx=ctx), ctx=ctx)


class WeinbergM4Q:
    """M4 step length in fixed point. ``k`` in m / (m/s^2)^(1/4), as the float M4; ``cutoff_hz`` 3 Hz."""

    def __init__(self, *, k: float = 1.0, cutoff_hz: float = 3.0) -> None:
        self.k = k
        self.cutoff_hz = cutoff_hz

    def estimate(
        self,
        lowpassed_q: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        defined: np.ndarray,
        ctx: ArithmeticContext | None = None,
    ) -> Self:
        """Estimate each step from the raw Q2.16 3 Hz signal (``defined`` marks where it exists).

        Sets ``range_q_`` (Q2.16 g, the full-precision range), ``root_q_``, ``step_length_q_`` (UQ2.14 m),
        ``defined_``, and float views
        ``acc_range_m_s2_``, ``step_length_m_`` (NaN where the window has fewer than two defined samples).
        """
        lp = np.asarray(lowpassed_q, np.int64)
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        ss = step_samples_q(start, end, np.asarray(defined, bool))
        x = lp[ss.index]
        self.range_q_ = ss.reduce_max(x) - ss.reduce_min(x)
        if ctx is not None:
            ctx.cost("compare32", 2 * x.size)
        r13 = shift_right(self.range_q_, LOWPASS_OUT_Q.frac_bits - ROOT4_Q.frac_bits, ctx=ctx)
        self.root_q_ = root4_q(r13, ctx=ctx)
        kq = int(K_Q.from_float(self.k * G0_ROOT4, ctx=ctx))
        self.step_length_q_ = mul_q(self.root_q_, kq, ROOT4_Q.frac_bits + K_Q.frac_bits - STEP_Q.frac_bits, STEP_Q,
                                    signed=False, ctx=ctx, op="m4.k")
        self.defined_ = ss.defined
        self.step_length_q_ = np.where(self.defined_, self.step_length_q_, 0)
        self.acc_range_m_s2_ = np.where(self.defined_, LOWPASS_OUT_Q.to_float(self.range_q_) * STANDARD_GRAVITY_M_S2,
                                        np.nan)
        self.step_length_m_ = np.where(self.defined_, STEP_Q.to_float(self.step_length_q_), np.nan)
        return self
