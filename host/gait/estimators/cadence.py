"""M5: step length linear in step frequency (Alvarez et al. 2006; Ladetto 2003).

.. math:: S = K_1 / T_{step} + K_2

``T_step`` the step duration (foot-flat to foot-flat), ``K1`` (m/s... m per Hz, i.e. m*s) and ``K2`` (m)
fitted per subject by :func:`gaitlog.host.gait.k_calibration.calibrate`.
"""

from __future__ import annotations

from typing import Self

import numpy as np


class CadenceM5:
    """M5 step length ``K1 / T + K2``.

    Examples
    --------
    >>> m5 = CadenceM5(k1_m_s=0.3, k2_m=0.1).estimate(step_duration_s=np.array([0.5, 0.6]))
    >>> np.round(m5.step_length_m_, 3).tolist()
    [0.7, 0.6]
    """

    def __init__(self, *, k1_m_s: float = float("nan"), k2_m: float = float("nan")) -> None:
        self.k1_m_s = k1_m_s
        self.k2_m = k2_m

    def estimate(self, *, step_duration_s: np.ndarray) -> Self:
        """Set ``step_length_m_`` from the step durations (NaN / non-positive durations give NaN)."""
        t = np.asarray(step_duration_s, np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.step_length_m_ = np.where(t > 0, self.k1_m_s / t + self.k2_m, np.nan)
        return self
