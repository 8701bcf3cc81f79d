"""A short batch recipe for M2 and M4, independent of the project's chain: the baseline every rule must beat.

:class:`RecipeBaseline` (printed beside the shipped chain by ``gaitlog evaluate ipol``, rows ``variant =
"baseline"``) shares nothing with :class:`gaitlog.host.gait.pipeline.StepPipeline` but the input:

1. Every missing sample is interpolated linearly on the sample grid (the logger's grid; the IPOL files are put
   on their ``PacketCounter`` grid by the reader).
2. Gravity from the first second of the recording (the walker stands): its direction gives the vertical, its
   norm the 1 g subtracted.
3. The vertical acceleration low-passed at 3 Hz, zero phase (4th-order Butterworth run forward and back); its
   peaks (at least :data:`MIN_STEP_S` apart and :data:`PEAK_PROMINENCE_M_S2` prominent) bound the steps.
4. M2: ``h`` from the *unfiltered* vertical acceleration of each step, integrated twice with a joint correction
   (a constant and a ramp added to the acceleration) that makes v(0) = v(T) = 0 and x(0) = x(T) = 0;
   ``h = max x - min x`` and ``S = 2 sqrt(2 l h - h^2)`` (Zijlstra & Hof 2003).
5. M4: ``S = range^(1/4)`` of the low-passed signal within the step (Weinberg 2002).
6. K per estimator = 20 m over the first trial's sum (the caller's; :meth:`RecipeBaseline.estimate` returns
   lengths with K = 1).

The two constants of step 3 are physical round values, not chosen on the recordings: no two steps 0.3 s apart
(cadence 200 steps/min), and a peak must rise 1 m/s^2 (0.1 g) above its surroundings (standing sways far less,
walking's per-step peak-to-peak is 5-11 m/s^2 at L5, ``ipol-lowerback-dev-walking-stats.md``).
"""

from __future__ import annotations

from typing import Self

import numpy as np
from scipy.signal import butter, filtfilt, find_peaks
from gaitlog.units import STANDARD_GRAVITY_M_S2


#: Low-pass of step 3, Hz (the paper's M4 filter).
LOWPASS_HZ = 3.0
#: Shortest step, s (step 3).
MIN_STEP_S = 0.3
#: Prominence of a step's peak, m/s^2 (step 3).
PEAK_PROMINENCE_M_S2 = 1.0
#: Standing at the start, s (step 2).
STANDING_S = 1.0


def _joint_correction_excursion_m(a_m_s2: np.ndarray, dt_s: float) -> float:
    """Step 4: ``max x - min x`` of the double integral of ``a + c0 + c1 t`` with v(0) = x(0) = 0 and (c0, c1)
    chosen so that v(T) = x(T) = 0 (trapezoidal rule)."""
    t = np.arange(a_m_s2.size) * dt_s

    def integral(y: np.ndarray) -> np.ndarray:
        return np.concatenate(([0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * dt_s)))

    def ends(y: np.ndarray) -> tuple[float, float]:
        v = integral(y)
        return v[-1], integral(v)[-1]

    basis = [np.ones_like(t), t]                     # the ends are linear in (c0, c1): solve for them
    m = np.array([ends(b) for b in basis]).T
    c = np.linalg.solve(m, -np.array(ends(a_m_s2)))
    x = integral(integral(a_m_s2 + c[0] * basis[0] + c[1] * basis[1]))
    return float(x.max() - x.min())


class RecipeBaseline:
    """The recipe's M2 and M4 on one recording (module notes).

    Parameters
    ----------
    leg_length_m
        Leg length of M2's pendulum.

    Attributes
    ----------
    vertical_m_s2_, lowpassed_m_s2_
        ``(n,)`` the vertical acceleration of step 2 and its low-pass of step 3, m/s^2.
    peak_
        The peaks of step 3 (sample indices).
    step_end_
        ``(k,)`` sample index of each step's end (the peak that closes it).
    length_m_
        ``{"M2": (k,), "M4": (k,)}`` step lengths with K = 1 (M2 in metres, M4 in (m/s^2)^(1/4)).
    """

    def __init__(self, *, leg_length_m: float) -> None:
        self.leg_length_m = leg_length_m

    def estimate(self, acc_g: np.ndarray, valid: np.ndarray, *, sampling_rate_hz: float) -> Self:
        """Steps 1-5 on ``acc_g`` (``(n, 3)`` g) with ``valid`` (``(n,)``) at ``sampling_rate_hz``."""
        vertical = standing_vertical_m_s2(acc_g, valid, sampling_rate_hz=sampling_rate_hz)      # 1, 2
        low = zero_phase_lowpass_m_s2(vertical, sampling_rate_hz=sampling_rate_hz)              # 3
        peaks = step_peaks(low, sampling_rate_hz=sampling_rate_hz)
        self.vertical_m_s2_, self.lowpassed_m_s2_, self.peak_ = vertical, low, peaks
        self.step_end_ = peaks[1:]
        self.length_m_ = {"M2": joint_correction_lengths_m(vertical, peaks[:-1], peaks[1:], sampling_rate_hz=
                                                           sampling_rate_hz, leg_length_m=self.leg_length_m),  # 4
                          "M4": np.array([np.ptp(low[a:b + 1]) for a, b in zip(peaks[:-1], peaks[1:])]) ** 0.25}  # 5
        return self


def standing_vertical_m_s2(acc_g: np.ndarray, valid: np.ndarray, *, sampling_rate_hz: float) -> np.ndarray:
    """Steps 1 and 2: every missing sample of ``acc_g`` (``(n, 3)`` g) interpolated, projected on the direction of
    the first second's mean and that mean's norm subtracted; m/s^2, up positive."""
    idx = np.arange(acc_g.shape[0])
    ok = np.asarray(valid, bool) & np.all(np.isfinite(acc_g), axis=1)
    acc = np.column_stack([np.interp(idx, idx[ok], acc_g[ok, k]) for k in range(3)])
    g = acc[: max(int(STANDING_S * sampling_rate_hz), 2)].mean(axis=0)
    return (acc @ (g / np.linalg.norm(g)) - np.linalg.norm(g)) * STANDARD_GRAVITY_M_S2


def zero_phase_lowpass_m_s2(x_m_s2: np.ndarray, *, sampling_rate_hz: float) -> np.ndarray:
    """Step 3's filter: 4th-order Butterworth at :data:`LOWPASS_HZ`, run forward and back (``x`` finite)."""
    return filtfilt(*butter(4, LOWPASS_HZ, fs=sampling_rate_hz), x_m_s2)


def step_peaks(low_m_s2: np.ndarray, *, sampling_rate_hz: float) -> np.ndarray:
    """Step 3's peaks of the low-passed vertical acceleration (sample indices): the steps lie between them."""
    peaks, _ = find_peaks(low_m_s2, distance=max(int(MIN_STEP_S * sampling_rate_hz), 1),
                          prominence=PEAK_PROMINENCE_M_S2)
    return peaks


def joint_correction_lengths_m(vertical_m_s2: np.ndarray, start: np.ndarray, end: np.ndarray, *,
                               sampling_rate_hz: float, leg_length_m: float) -> np.ndarray:
    """Step 4 on the windows ``[start_k, end_k]`` of ``vertical_m_s2`` (finite there): M2's lengths with K = 1
    (NaN for an excursion over twice the leg)."""
    dt = 1.0 / sampling_rate_hz
    h = np.array([_joint_correction_excursion_m(vertical_m_s2[a:b + 1], dt) for a, b in zip(start, end)])
    l_m = leg_length_m
    return np.where(h < 2 * l_m, 2 * np.sqrt(np.clip(2 * l_m * h - h ** 2, 0, None)), np.nan)
