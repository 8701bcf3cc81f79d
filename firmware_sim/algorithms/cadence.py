"""M5 in fixed point: ``S = K1 / T_step + K2`` (mirrors ``host.estimators.cadence``).

``T_step`` is the step duration in sample periods (foot-flat to foot-flat, an integer). With
``K1' = K1 · fs`` (m · samples) in Q15.16, ``S = round(K1' / T) + K2`` is one 32/16 divide and one add,
then rounded to UQ2.14. The raw M5 value (the cadence ``1/T`` in Hz) is ``round(fs · 2^16 / T)`` in Q15.16.
"""

from __future__ import annotations

from typing import Self

import numpy as np

from firmware_sim.algorithms.formats import M5_Q, STEP_Q
from firmware_sim.fixedpoint import ArithmeticContext, add, div_round, requantize


def cadence_q(step_samples: np.ndarray, sampling_rate_hz: float, *, ctx: ArithmeticContext | None = None
              ) -> np.ndarray:
    """Cadence ``fs / T`` in Q15.16 Hz of step durations in sample periods (> 0).

    >>> M5_Q.to_float(cadence_q(np.array([25, 30]), 50.0)).round(5).tolist()
    [2.0, 1.66667]
    """
    fs_q = int(M5_Q.from_float(sampling_rate_hz))
    return div_round(np.full(np.shape(step_samples), fs_q), np.asarray(step_samples, np.int64), M5_Q, ctx=ctx,
                     op="m5.cadence")


class CadenceM5Q:
    """M5 step length ``K1 / T + K2`` in fixed point.

    >>> m5 = CadenceM5Q(k1_m_s=0.3, k2_m=0.1).estimate(step_samples=np.array([25, 30]), sampling_rate_hz=50.0)
    >>> m5.step_length_m_.round(4).tolist()
    [0.7, 0.6]
    """

    def __init__(self, *, k1_m_s: float = float("nan"), k2_m: float = float("nan")) -> None:
        self.k1_m_s = k1_m_s
        self.k2_m = k2_m

    def estimate(self, *, step_samples: np.ndarray, sampling_rate_hz: float,
                 ctx: ArithmeticContext | None = None) -> Self:
        """Set ``step_length_q_`` (UQ2.14) and ``step_length_m_`` (NaN for durations <= 0 or no constants)."""
        t = np.asarray(step_samples, np.int64)
        good = t > 0
        if not (np.isfinite(self.k1_m_s) and np.isfinite(self.k2_m)):
            self.step_length_q_ = np.zeros(t.shape, np.int64)
            self.step_length_m_ = np.full(t.shape, np.nan)
            return self
        k1 = int(M5_Q.from_float(self.k1_m_s * sampling_rate_hz, ctx=ctx))
        k2 = int(M5_Q.from_float(self.k2_m, ctx=ctx))
        q = div_round(np.full(t.shape, k1), np.where(good, t, 1), M5_Q, ctx=ctx, op="m5.k1")
        s = requantize(add(q, k2, M5_Q, ctx=ctx, op="m5.k2"), M5_Q, STEP_Q, ctx=ctx)
        self.step_length_q_ = np.where(good, s, 0)
        self.step_length_m_ = np.where(good, STEP_Q.to_float(s), np.nan)
        return self
