"""Quintic Hermite splines: C2 trajectories whose derivatives are exact.

The walking world builds every smooth channel (path progress, centre-of-mass height, gait phase, posture)
from knots carrying value, first and second derivative. Between two knots the channel is the unique
quintic polynomial matching the six end conditions, so position, velocity and acceleration are one
piecewise polynomial and its exact derivatives: double integration of the rendered acceleration
reproduces the position exactly (up to the integration scheme).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PPoly


def quintic_hermite(t_s: np.ndarray, y: np.ndarray, dy: np.ndarray, ddy: np.ndarray) -> PPoly:
    """Piecewise quintic through knots with prescribed value, slope and curvature.

    Parameters
    ----------
    t_s
        Strictly increasing knot times, shape ``(m,)``, ``m >= 2``.
    y, dy, ddy
        Value, first and second time derivative at every knot, shape ``(m,)``.

    Returns
    -------
    scipy.interpolate.PPoly
        Degree-5 piecewise polynomial, C2 across knots; ``.derivative(k)`` is exact.

    Examples
    --------
    >>> pp = quintic_hermite(np.array([0.0, 2.0]), np.array([0.0, 1.0]), np.zeros(2), np.zeros(2))
    >>> float(pp(1.0)), float(pp.derivative()(0.0)), float(pp.derivative(2)(2.0))
    (0.5, 0.0, 0.0)
    """
    t = np.asarray(t_s, dtype=np.float64)
    y, dy, ddy = (np.asarray(a, dtype=np.float64) for a in (y, dy, ddy))
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"need at least two knots, got shape {t.shape}")
    if not (y.shape == dy.shape == ddy.shape == t.shape):
        raise ValueError("knot values and derivatives must have the shape of the knot times")
    h = np.diff(t)
    if np.any(h <= 0):
        bad = int(np.flatnonzero(h <= 0)[0])
        raise ValueError(f"knot times must be strictly increasing (knot {bad}: {t[bad]} -> {t[bad + 1]})")
    # End conditions in the normalised variable u = (t - t0) / h.
    p0, p1 = y[:-1], y[1:]
    v0, v1 = dy[:-1] * h, dy[1:] * h
    a0, a1 = ddy[:-1] * h**2, ddy[1:] * h**2
    dp = p1 - p0
    c = np.empty((6, h.size))
    c[5] = p0
    c[4] = v0
    c[3] = a0 / 2.0
    c[2] = 10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1
    c[1] = -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1
    c[0] = 6.0 * dp - 3.0 * v0 - 3.0 * v1 - 0.5 * a0 + 0.5 * a1
    # Back to powers of (t - t0): coefficient of u^k divided by h^k (PPoly: highest power first).
    powers = np.arange(5, -1, -1)[:, None]
    return PPoly(c / h[None, :] ** powers, t, extrapolate=True)


def constant_ppoly(t0_s: float, t1_s: float, value: float) -> PPoly:
    """A constant channel over ``[t0_s, t1_s]`` (all derivatives zero).

    Examples
    --------
    >>> float(constant_ppoly(0.0, 1.0, 3.0)(0.5))
    3.0
    """
    return quintic_hermite(np.array([t0_s, t1_s]), np.array([value, value]), np.zeros(2), np.zeros(2))


def evaluate(pp: PPoly, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value, first and second derivative of ``pp`` at ``t_s``.

    Examples
    --------
    >>> pp = quintic_hermite(np.array([0.0, 1.0]), np.array([0.0, 1.0]), np.ones(2), np.zeros(2))
    >>> [float(a[0]) for a in evaluate(pp, np.array([0.5]))]
    [0.5, 1.0, 0.0]
    """
    d012 = getattr(pp, "d012", None)    # profiles that share work between the three (gait_cycle)
    if d012 is not None:
        return d012(t_s)
    return pp(t_s), pp(t_s, nu=1), pp(t_s, nu=2)
