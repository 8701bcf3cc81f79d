"""M4: Weinberg's step length from the vertical acceleration range (Alvarez eq 4; Weinberg, ADI AN-602, 2002).

.. math:: S = K (a_{max} - a_{min})^p

with ``p`` :data:`gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT` (Weinberg's 1/4; 1/2, tuned on IPOL, did
not pass the project's rule for choices: that module's notes and :mod:`gaitlog.host.studies.tuning`)

per step, ``a`` the vertical acceleration low-passed at 3 Hz (its first harmonic; here a Gaussian
low-pass with -3 dB at 3 Hz over the measured samples), max and min within the step (foot-flat to
foot-flat). The range is taken in m/s^2, so K is in m / (m/s^2)^p. The distance over n steps is the sum
(the printed ``K n ...`` is that sum for n equal steps).
"""

from __future__ import annotations

from typing import Self

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.host.gait.integration import step_samples
from gaitlog.host.gait.masked_filter import masked_gaussian_lowpass


class WeinbergM4:
    """M4 step length ``K (a_max - a_min)^p``.

    Parameters
    ----------
    k
        Calibration constant, m / (m/s^2)^p.
    cutoff_hz
        Low-pass -3 dB frequency (3 Hz).
    exponent
        ``p`` (the shipped :data:`~gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT` unless a study varies it).

    Examples
    --------
    >>> sampling_rate_hz = 50.0; t = np.arange(101) / sampling_rate_hz
    >>> a = 2.0 * np.cos(2 * np.pi * 2 * t)                       # range 4 m/s^2
    >>> m4 = WeinbergM4(k=0.5).estimate(a, step_start=[25], step_end=[75], sampling_rate_hz=sampling_rate_hz)
    >>> round(float(m4.acc_range_m_s2_[0]), 2) < 4.0               # the 3 Hz low-pass attenuates 2 Hz a little
    True
    """

    def __init__(self, *, k: float = 1.0, cutoff_hz: float = 3.0, exponent: float = M4_EXPONENT) -> None:
        self.k = k
        self.cutoff_hz = cutoff_hz
        self.exponent = exponent

    def estimate(
        self,
        acc_v_m_s2: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        sampling_rate_hz: float,
        valid: np.ndarray | None = None,
        lowpassed: np.ndarray | None = None,
    ) -> Self:
        """Estimate each step; ``lowpassed`` may pass the 3 Hz signal if already computed.

        Sets ``acc_range_m_s2_`` and ``step_length_m_``.
        """
        acc = np.asarray(acc_v_m_s2, np.float64)
        if acc.ndim != 1:
            raise ValueError(f"acc_v_m_s2 must be one-dimensional, got shape {acc.shape}")
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        if start.size and (start.min() < 0 or end.max() >= acc.size):
            raise ValueError("step windows fall outside the signal")
        ok = np.isfinite(acc) if valid is None else (np.asarray(valid, bool) & np.isfinite(acc))
        lp = lowpassed if lowpassed is not None else masked_gaussian_lowpass(
            acc, ok, cutoff_hz=self.cutoff_hz, sampling_rate_hz=sampling_rate_hz)
        ss = step_samples(start, end, np.isfinite(lp), sampling_rate_hz)
        x = lp[ss.index]
        self.acc_range_m_s2_ = ss.reduce_max(x) - ss.reduce_min(x)
        self.step_length_m_ = weinberg_length_m(self.acc_range_m_s2_, k=self.k, exponent=self.exponent)
        return self


def weinberg_length_m(acc_range_m_s2: np.ndarray, *, k: float, exponent: float = M4_EXPONENT) -> np.ndarray:
    """``k (a_max - a_min)^exponent`` per step (NaN stays NaN).

    >>> weinberg_length_m(np.array([4.0, np.nan]), k=0.3, exponent=0.5).tolist()
    [0.6, nan]
    """
    return k * np.power(np.asarray(acc_range_m_s2, np.float64), exponent)


def range_share_length_m(acc_range_m_s2: np.ndarray, typical_range_m_s2: float, *, k: float,
                         exponent: float = M4_EXPONENT) -> np.ndarray:
    """M4 with a weak step counted as its share of a typical step: ``k r^p`` for a step whose range ``r`` is at
    least the typical range ``r_t``, ``k r_t^p (r / r_t)`` below it (NaN stays NaN).

    Weinberg's ``r^p`` with ``p = 1/4`` gives a step with a quarter of the typical range 71 % of a typical step's
    length, so the weak steps of a turn, a start or a stop count nearly as whole steps; here such a step counts
    25 %. No constant: ``r_t`` is the walk's own (a study passes the median range of the trial's steps). The two
    branches meet at ``r_t``.

    >>> range_share_length_m(np.array([4.0, 1.0, np.nan]), 4.0, k=1.0, exponent=0.5).tolist()
    [2.0, 0.5, nan]
    """
    r = np.asarray(acc_range_m_s2, np.float64)
    return np.where(r < typical_range_m_s2, k * typical_range_m_s2 ** exponent * (r / typical_range_m_s2),
                    weinberg_length_m(r, k=k, exponent=exponent))


def duration_share_length_m(acc_range_m_s2: np.ndarray, duration_s: np.ndarray, typical_duration_s: float, *,
                            k: float, exponent: float = M4_EXPONENT) -> np.ndarray:
    """M4 with a short step counted as its share of a typical step's time: ``k r^p min(1, T / T_t)``, ``T`` the
    step's duration and ``T_t`` the walk's typical one (a study passes the median of the trial's steps; NaN stays
    NaN). No constant.

    >>> duration_share_length_m(np.array([16.0, 16.0]), np.array([0.25, 0.6]), 0.5, k=1.0).tolist()
    [1.0, 2.0]
    """
    share = np.minimum(1.0, np.asarray(duration_s, np.float64) / typical_duration_s)
    return weinberg_length_m(acc_range_m_s2, k=k, exponent=exponent) * share
