"""Translation of a segment from its accelerations and orientation (Morris 1973), with cycle drift removal.

Steps (Morris, appendix and main text):

1. rotate the measured specific force to space axes with the direction-cosine matrix and subtract gravity
   (:func:`remove_gravity`): ``a = g0 · (λ f − e3)`` in m/s², space axis 3 up;
2. integrate twice with the trapezoidal rule (:func:`cumulative_trapezoid_m`);
3. cycle drift removal (:func:`remove_cycle_drift`): the movement is periodic, so a quantity's values at the
   beginning and end of a gait cycle (start = end of the cycle, Morris Fig 4b) are made equal by subtracting
   the linear ramp between them. Applied to the velocity it removes the effect of a constant acceleration
   bias ``b`` (velocity error ``b·t``); applied to the position it removes the unknown initial velocity
   (position error ``v0·t``); a bias left in place would give ``b·T²/2`` at the end of the cycle.

:class:`CycleTranslation` chains the three over one cycle. Over a gait cycle a segment's position does not
return to its start in the walking direction: give the known displacement per cycle (e.g. the stride) in
``cycle_displacement_m``, or leave the position unconstrained on that axis with ``closed_axes``.
"""

from __future__ import annotations

from typing import Self

import numpy as np

from gaitlog.host.errors import HostError
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = [
    "CycleTranslation",
    "STANDARD_GRAVITY_M_S2",
    "cumulative_trapezoid_m",
    "remove_cycle_drift",
    "remove_gravity",
]


def remove_gravity(acc_g: np.ndarray, dcm: np.ndarray) -> np.ndarray:
    """Translational acceleration in space axes (m/s²) from body specific force (g) and orientation.

    ``a = g0 · (λ f − e3)`` with ``λ`` body-to-space (space axis 3 up); a device at rest gives 0.

    Parameters
    ----------
    acc_g
        ``(n, 3)`` specific force in body axes, g (gravity included, +1 g on the up axis at rest).
    dcm
        ``(n, 3, 3)`` body-to-space direction-cosine matrices.

    Examples
    --------
    >>> remove_gravity(np.array([[0.0, 0.0, 1.0]]), np.eye(3)[None]) + 0.0
    array([[0., 0., 0.]])
    """
    f = np.asarray(acc_g, dtype=np.float64)
    lam = np.asarray(dcm, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3 or lam.shape != (f.shape[0], 3, 3):
        raise HostError(f"remove_gravity: need acc_g (n, 3) and dcm (n, 3, 3), got {f.shape} and {lam.shape}")
    out = np.einsum("nij,nj->ni", lam, f)
    out[:, 2] -= 1.0
    return out * STANDARD_GRAVITY_M_S2


def cumulative_trapezoid_m(x: np.ndarray, sampling_rate_hz: float, initial: np.ndarray | float = 0.0) -> np.ndarray:
    """Cumulative trapezoidal integral along axis 0, starting at ``initial`` (same length as ``x``).

    Units: the integral of ``x`` over seconds (e.g. m/s² -> m/s).
    """
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    out[0] = initial
    if x.shape[0] > 1:
        out[1:] = np.cumsum(0.5 / sampling_rate_hz * (x[1:] + x[:-1]), axis=0) + out[0]
    return out


def remove_cycle_drift(x: np.ndarray, *, end_minus_start: np.ndarray | float = 0.0) -> np.ndarray:
    """Subtract the linear ramp that makes ``x[-1] − x[0]`` equal ``end_minus_start`` (Morris Fig 4b).

    Parameters
    ----------
    x
        ``(n, ...)`` samples of one cycle, first and last sample at the same phase of the cycle.
    end_minus_start
        Wanted difference between the last and first value (0: start = end), broadcast over ``x[0]``.

    Examples
    --------
    >>> remove_cycle_drift(np.array([0.0, 1.0, 2.0, 3.0]))
    array([0., 0., 0., 0.])
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if n < 2:
        raise HostError(f"remove_cycle_drift: a cycle needs at least 2 samples, got {n}")
    ramp = np.linspace(0.0, 1.0, n).reshape((n,) + (1,) * (x.ndim - 1))
    drift = x[-1] - x[0] - np.asarray(end_minus_start, dtype=np.float64)
    return x - ramp * drift


class CycleTranslation:
    """Velocity and position of a body-fixed point over one gait cycle (Morris 1973, Fig 6).

    Parameters
    ----------
    cycle_displacement_m
        ``(3,)`` known displacement of the point over the cycle in space axes (0 = returns to its start).
    closed_axes
        Space axes on which the position constraint is applied (others keep the initial velocity).
    initial_velocity_m_s
        Velocity at the first sample, used on the open axes (and as the start on closed axes before
        drift removal).
    remove_drift
        Apply the cycle drift removal to velocity (start = end) and to position on the closed axes.

    Attributes
    ----------
    acceleration_m_s2_, velocity_m_s_, position_m_ : ``(n, 3)`` in space axes (position relative to the
    first sample).
    """

    def __init__(
        self,
        *,
        cycle_displacement_m: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
        closed_axes: tuple[int, ...] = (0, 1, 2),
        initial_velocity_m_s: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
        remove_drift: bool = True,
    ) -> None:
        self.cycle_displacement_m = cycle_displacement_m
        self.closed_axes = closed_axes
        self.initial_velocity_m_s = initial_velocity_m_s
        self.remove_drift = remove_drift

    def integrate(self, acc_m_s2: np.ndarray, *, sampling_rate_hz: float) -> Self:
        """Integrate one cycle of space-axis translational acceleration ``(n, 3)`` (m/s²)."""
        a = np.asarray(acc_m_s2, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] < 2:
            raise HostError(f"CycleTranslation: need acceleration of shape (n >= 2, 3), got {a.shape}")
        if not np.isfinite(a).all():
            raise HostError(f"CycleTranslation: non-finite acceleration at sample {int(np.argwhere(~np.isfinite(a))[0, 0])}")
        v0 = np.asarray(self.initial_velocity_m_s, dtype=np.float64)
        if self.remove_drift:
            a = a - (a[-1] - a[0]) * np.linspace(0.0, 1.0, a.shape[0])[:, None]  # acceleration start = end
        v = cumulative_trapezoid_m(a, sampling_rate_hz, v0)
        if self.remove_drift:
            v = remove_cycle_drift(v)  # velocity start = end
        p = cumulative_trapezoid_m(v, sampling_rate_hz, 0.0)
        if self.remove_drift and self.closed_axes:
            ax = list(self.closed_axes)
            disp = np.broadcast_to(np.asarray(self.cycle_displacement_m, dtype=np.float64), (3,))[ax]
            # the ramp on position is a constant velocity offset: apply it to velocity too
            drift = p[-1, ax] - p[0, ax] - disp
            p[:, ax] = remove_cycle_drift(p[:, ax], end_minus_start=disp)
            v[:, ax] -= drift * sampling_rate_hz / (a.shape[0] - 1)
        self.acceleration_m_s2_ = a
        self.velocity_m_s_ = v
        self.position_m_ = p
        return self
