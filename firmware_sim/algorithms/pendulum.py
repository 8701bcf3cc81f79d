"""M1 and M2 in fixed point: ``S = K · 2 sqrt(2 l h − h²)`` (Alvarez eq 1; mirrors ``host.estimators.pendulum``).

Integer steps per step window:

1. ``h`` = max − min of the integer position (:mod:`~firmware_sim.algorithms.integration`), converted to
   metres in :data:`~.formats.EXCURSION_Q` (UQ0.16) by a right shift that brings 1 m under 2^16 and one
   16×16 multiply by a scale constant (:func:`excursion_q`);
2. ``x = 2 l h − h²`` in UQ2.30: ``l_raw · h_raw − (h_raw² >> 2)`` (l in UQ1.15); ``h > 2 l`` makes it
   negative: the step is *impossible* (NaN in the float chain), counted in ``n_impossible_``;
3. ``S/2 = isqrt(x)`` in UQ1.15, which read as UQ2.14 is ``S`` itself (:data:`~.formats.STEP_Q`);
4. ``K · S``: 16×16 multiply by K in UQ1.15, rounded back to UQ2.14.
"""

from __future__ import annotations

import math
from typing import Self

import numpy as np

from firmware_sim.algorithms.formats import EXCURSION_Q, K_Q, LENGTH_Q, PENDULUM_ARG_Q, STEP_Q
from firmware_sim.algorithms.integration import (
    StepSamplesQ,
    VerticalPositionsQ,
    position_unit_m,
    step_samples_q,
    vertical_positions_q,
)
from firmware_sim.fixedpoint import ArithmeticContext, isqrt, mul, mul_q, saturate, shift_right, sub


def excursion_constants(unit_m: float) -> tuple[int, int, int]:
    """``(s, c, k)`` with ``h_raw = ((units >> s) · c) >> k`` metres in UQ0.16 for positions in ``unit_m``.

    ``s`` makes 1 m fit 16 bits; ``c`` (16-bit) and ``k`` carry the scale with 16 significant bits.

    >>> excursion_constants(1.0 / 65536)
    (1, 32768, 14)
    """
    s = max(0, math.ceil(math.log2(1.0 / unit_m / EXCURSION_Q.max_raw)))
    scale = unit_m * 2.0 ** s * 2.0 ** EXCURSION_Q.frac_bits     # metres-lsb per shifted unit
    k = 0
    while round(scale * 2.0 ** (k + 1)) <= 0xFFFF:
        k += 1
    return s, int(round(scale * 2.0 ** k)), k


def excursion_q(units: np.ndarray, unit_m: float, *, ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Non-negative position ranges in ``unit_m`` -> metres, raw UQ0.16 (saturates above 1 m, counted)."""
    s, c, k = excursion_constants(unit_m)
    u = saturate(shift_right(np.asarray(units, np.int64), s, ctx=ctx), 16, signed=False, ctx=ctx,
                 op="pendulum.excursion")
    return saturate(shift_right(mul(u, c, signed=False, ctx=ctx), k, ctx=ctx), EXCURSION_Q, ctx=ctx,
                    op="pendulum.excursion")


def pendulum_length_q(h_q: np.ndarray, leg_q: int, *, ctx: ArithmeticContext | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """``2 sqrt(2 l h − h²)`` raw UQ2.14 and the mask of impossible steps (``h > 2 l``; length 0 there).

    >>> h = EXCURSION_Q.from_float(np.array([0.0, 0.05]))
    >>> s, bad = pendulum_length_q(h, int(LENGTH_Q.from_float(1.0)))
    >>> STEP_Q.to_float(s).round(4).tolist(), bad.tolist()
    ([0.0, 0.6245], [False, False])
    """
    h = np.asarray(h_q, np.int64)
    lh = mul(np.full_like(h, leg_q), h, signed=False, ctx=ctx)          # 2 l h in Q2.30
    hh = shift_right(mul(h, h, signed=False, ctx=ctx), 2, ctx=ctx)       # h^2 in Q2.30
    # unsigned 32-bit subtract: the borrow (here the sign of a 33-bit result) flags an impossible step
    x = sub(lh, hh, 33, ctx=ctx, op="pendulum.argument")
    impossible = x < 0
    x = saturate(np.where(impossible, 0, x), PENDULUM_ARG_Q, ctx=ctx, op="pendulum.argument")
    return isqrt(x, ctx=ctx), impossible


def scale_by_k(s_q: np.ndarray, k: float, *, ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``K · S`` with K quantised to UQ1.15 (0 .. 2), result UQ2.14."""
    kq = int(K_Q.from_float(k, ctx=ctx))
    return mul_q(np.asarray(s_q, np.int64), kq, K_Q.frac_bits, STEP_Q, signed=False, ctx=ctx, op="pendulum.k")


class _PendulumBaseQ:
    _which = "p1"

    def __init__(self, *, k: float = 1.0) -> None:
        self.k = k

    def estimate(
        self,
        acc_v_q: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        sampling_rate_hz: float,
        leg_length_m: float,
        valid: np.ndarray | None = None,
        ctx: ArithmeticContext | None = None,
        positions: tuple[StepSamplesQ, VerticalPositionsQ] | None = None,
    ) -> Self:
        """Estimate each step ``[step_start_k, step_end_k]`` of raw ACC_Q vertical acceleration.

        ``positions`` may pass the windows' samples and integer positions if already integrated (the
        firmware integrates once for M1-M3).

        Sets ``excursion_q_`` (UQ0.16 m), ``step_length_q_`` (UQ2.14 m, 0 where impossible or undefined),
        ``defined_`` (windows with two measured samples or more), ``impossible_`` (bool), ``n_impossible_``,
        and the float views ``vertical_excursion_m_`` and ``step_length_m_`` (NaN where not defined or
        impossible).
        """
        a = np.asarray(acc_v_q, np.int64)
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        if start.size and (start.min() < 0 or end.max() >= a.size):
            raise ValueError("step windows fall outside the signal")
        ok = np.ones(a.size, bool) if valid is None else np.asarray(valid, bool)
        ss, vp = positions if positions is not None else (None, None)
        if ss is None:
            ss = step_samples_q(start, end, ok)
            vp = vertical_positions_q(a, ss, ctx=ctx)
        pos = getattr(vp, self._which)
        span = ss.reduce_max(pos) - ss.reduce_min(pos)
        self.defined_ = ss.defined                       # windows with >= 2 measured samples
        self.excursion_q_ = excursion_q(span, position_unit_m(sampling_rate_hz, m2=self._which == "p2"), ctx=ctx)
        leg_q = int(LENGTH_Q.from_float(leg_length_m))
        s, impossible = pendulum_length_q(self.excursion_q_, leg_q, ctx=ctx)
        self.impossible_ = impossible & self.defined_
        self.n_impossible_ = int(np.count_nonzero(self.impossible_))
        good = self.defined_ & ~self.impossible_
        self.step_length_q_ = np.where(good, scale_by_k(s, self.k, ctx=ctx), 0)
        self.vertical_excursion_m_ = np.where(self.defined_, EXCURSION_Q.to_float(self.excursion_q_), np.nan)
        self.step_length_m_ = np.where(good, STEP_Q.to_float(self.step_length_q_), np.nan)
        return self


class PendulumM1Q(_PendulumBaseQ):
    """M1 in fixed point: integrals reset at each foot-flat (eq 1). ``k``: per-subject K."""

    _which = "p1"


class PendulumDriftM2Q(_PendulumBaseQ):
    """M2 in fixed point: M1 with the drift correction of eqs (2)-(3). ``k``: per-subject K."""

    _which = "p2"
