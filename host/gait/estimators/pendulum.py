"""M1 and M2: the inverted-pendulum step length (Alvarez eq 1, after Zijlstra & Hof 2003).

.. math:: S = K \\cdot 2\\sqrt{2 l h - h^2}

``l`` leg length, ``h`` the vertical excursion (max - min) of the CoM within the step, from the double
integral of the vertical acceleration between consecutive foot-flats: reset at foot-flat only (M1), or
with the c1/c2 drift correction of eqs (2)-(3) (M2). An impossible excursion (``h > 2 l``, or not finite)
gives NaN for that step; such steps are counted in ``n_impossible_`` and warned about (the square root of
a negative number is not hidden behind ``abs``).
"""

from __future__ import annotations

import warnings
from typing import Self

import numpy as np

from gaitlog.host.gait.integration import StepSamples, step_samples, vertical_positions


def pendulum_length_m(h_m: np.ndarray, leg_length_m: float) -> tuple[np.ndarray, int]:
    """``2 sqrt(2 l h - h^2)`` with NaN (and a count) where ``h`` is negative, > 2 l or not finite.

    >>> s, bad = pendulum_length_m(np.array([0.0, 0.05, 2.5]), 1.0)
    >>> np.round(s, 4).tolist(), bad
    ([0.0, 0.6245, nan], 1)
    """
    h = np.asarray(h_m, np.float64)
    impossible = ~np.isfinite(h) | (h < 0) | (h > 2 * leg_length_m)
    with np.errstate(invalid="ignore"):
        s = 2.0 * np.sqrt(np.where(impossible, np.nan, 2 * leg_length_m * h - h * h))
    return s, int(np.count_nonzero(impossible & np.isfinite(h)))


def _check(acc: np.ndarray, start: np.ndarray, end: np.ndarray, leg_length_m: float) -> None:
    if acc.ndim != 1:
        raise ValueError(f"acc_v_m_s2 must be one-dimensional, got shape {acc.shape}")
    if not (np.isfinite(leg_length_m) and leg_length_m > 0):
        raise ValueError(f"leg_length_m must be positive, got {leg_length_m!r}")
    if start.size and (start.min() < 0 or end.max() >= acc.size):
        raise ValueError("step windows fall outside the signal")
    if start.size > 1 and np.any(np.diff(start) <= 0):
        raise ValueError("step windows must be strictly increasing sample indices")


class _PendulumBase:
    _which = 0

    def __init__(self, *, k: float = 1.0) -> None:
        self.k = k

    def estimate(
        self,
        acc_v_m_s2: np.ndarray,
        *,
        step_start: np.ndarray,
        step_end: np.ndarray,
        sampling_rate_hz: float,
        leg_length_m: float,
        valid: np.ndarray | None = None,
        samples: StepSamples | None = None,
    ) -> Self:
        """Estimate the length of each step ``[step_start_k, step_end_k]`` (foot-flat to foot-flat).

        Sets ``vertical_excursion_m_``, ``step_length_m_`` (NaN for impossible steps) and ``n_impossible_``.
        """
        acc = np.asarray(acc_v_m_s2, np.float64)
        start = np.asarray(step_start, np.int64)
        end = np.asarray(step_end, np.int64)
        _check(acc, start, end, leg_length_m)
        ok = np.isfinite(acc) if valid is None else (np.asarray(valid, bool) & np.isfinite(acc))
        # ``samples`` lets a caller that runs several estimators on the same windows lay them out once
        ss = samples if samples is not None else step_samples(start, end, ok, sampling_rate_hz)
        pos = vertical_positions(acc, ss)[self._which]
        self.vertical_excursion_m_ = ss.reduce_max(pos) - ss.reduce_min(pos)
        s, self.n_impossible_ = pendulum_length_m(self.vertical_excursion_m_, leg_length_m)
        self.step_length_m_ = self.k * s
        if self.n_impossible_:
            warnings.warn(f"{type(self).__name__}: {self.n_impossible_} step(s) with an impossible vertical "
                          f"excursion (h > 2 l = {2 * leg_length_m:.2f} m) set to NaN", stacklevel=2)
        return self


class PendulumM1(_PendulumBase):
    """M1: ``K * 2 sqrt(2 l h - h^2)``, velocity and position reset to 0 at each foot-flat (eq 1).

    Parameters
    ----------
    k
        Per-subject calibration constant K (1 = the bare pendulum model).

    Examples
    --------
    CoM ``z = -A cos(2 pi t / T)`` over one step, A = 2 cm, l = 0.9 m: ``h = 4 cm``.

    >>> sampling_rate_hz, T, A, l = 200.0, 0.5, 0.02, 0.9
    >>> t = np.arange(int(T * sampling_rate_hz) + 1) / sampling_rate_hz
    >>> a = A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T)
    >>> m1 = PendulumM1().estimate(a, step_start=[0], step_end=[t.size - 1], sampling_rate_hz=sampling_rate_hz, leg_length_m=l)
    >>> round(float(m1.step_length_m_[0]), 2), round(float(2 * np.sqrt(2 * l * 0.04 - 0.04 ** 2)), 2)
    (0.53, 0.53)
    """

    _which = 0


class PendulumDriftM2(_PendulumBase):
    """M2: M1 with the drift correction of eqs (2)-(3) (velocity 0 and position back at the next foot-flat).

    Parameters
    ----------
    k
        Per-subject calibration constant K.
    """

    _which = 1
