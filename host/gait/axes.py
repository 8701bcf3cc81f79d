"""Vertical and antero-posterior acceleration from the direction of gravity (minimal tilt correction).

The logger is strapped to the lower back and tilted as mounted. Over a few strides the dynamic
acceleration of the trunk averages to zero, so a moving mean of the specific force is the gravity vector in
device axes (Moe-Nilssen, Clin. Biomech. 13, 1998, "tilt correction"; Morris 1973 eqs 11-16 take the
same gravity vector at foot-flat for the initial direction-cosine matrix). The vertical dynamic
acceleration is the projection on the unit gravity direction minus the gravity magnitude:

.. math:: a_v = \\mathbf{f} \\cdot \\hat{\\mathbf{g}} - \\lVert \\bar{\\mathbf{f}} \\rVert

(positive up, m/s^2). The antero-posterior axis is the horizontal direction (perpendicular to
:math:`\\hat g`) of largest dynamic variance after removing the stride-frequency medio-lateral sway
(principal direction of the horizontal jerk, in which the AP component at step frequency dominates the
ML sway at stride frequency); its sign is not determined by gravity and is
chosen so that the AP acceleration is positive just before the vertical peak at foot-flat, as in forward
walking (the trunk is accelerated forwards while the CoM passes its lowest point; Zijlstra & Hof,
Gait Posture 18, 2003).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitlog.host.gait.masked_filter import halo_blocks, masked_moving_mean
from gaitlog.units import STANDARD_GRAVITY_M_S2


@dataclass(frozen=True, eq=False)
class BodyAxes:
    """Tilt-corrected acceleration.

    Attributes
    ----------
    acc_v_m_s2
        ``(n,)`` vertical dynamic acceleration (up positive, gravity removed), NaN where not measured.
    acc_ap_m_s2
        ``(n,)`` antero-posterior dynamic acceleration (sign: see module notes), NaN where not measured.
    gravity_g
        ``(n, 3)`` the moving-mean gravity vector in device axes, g.
    valid
        ``(n,)`` bool, samples where the vertical acceleration is defined.
    """

    acc_v_m_s2: np.ndarray
    acc_ap_m_s2: np.ndarray
    gravity_g: np.ndarray
    valid: np.ndarray


def body_axes(
    acc_g: np.ndarray,
    *,
    sampling_rate_hz: float,
    valid: np.ndarray | None = None,
    gravity_window_s: float = 4.0,
) -> BodyAxes:
    """Vertical and AP acceleration of calibrated specific force ``acc_g`` (``(n, 3)``, g).

    Parameters
    ----------
    acc_g
        Calibrated specific force in g, gravity included (project convention), NaN allowed where missing.
    sampling_rate_hz
        Sample rate, Hz.
    valid
        Optional ``(n,)`` mask of measured samples.
    gravity_window_s
        Length of the moving mean that estimates gravity: several strides (a stride lasts ~1 s).

    Examples
    --------
    >>> sampling_rate_hz = 50.0; t = np.arange(500) / sampling_rate_hz
    >>> up = np.array([0.6, 0.0, 0.8])          # device tilted, gravity along (0.6, 0, 0.8)
    >>> acc = up[None, :] * (1.0 + 0.2 * np.sin(2 * np.pi * 2 * t))[:, None]
    >>> ax = body_axes(acc, sampling_rate_hz=sampling_rate_hz)
    >>> bool(np.allclose(ax.acc_v_m_s2[100:400], 0.2 * STANDARD_GRAVITY_M_S2 * np.sin(2 * np.pi * 2 * t[100:400]), atol=0.02))
    True
    """
    acc = np.asarray(acc_g, dtype=np.float64)
    if acc.ndim != 2 or acc.shape[1] != 3:
        raise ValueError(f"acc_g must have shape (n, 3), got {acc.shape}")
    n = acc.shape[0]
    ok = np.isfinite(acc[:, 0]) & np.isfinite(acc[:, 1]) & np.isfinite(acc[:, 2])   # 8x all(axis=1)'s speed
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool)
    window = int(round(gravity_window_s * sampling_rate_hz))
    grav = np.empty((3, n))
    for k in range(3):
        grav[k] = masked_moving_mean(acc[:, k], ok, window=window)
    acc_v = np.empty(n)
    hor = np.empty((3, n))
    for lo, hi, _, _ in halo_blocks(n, 0):      # element-wise, one cache-sized block at a time
        ok[lo:hi] &= _vertical_block(acc[lo:hi], grav[:, lo:hi], acc_v[lo:hi], hor[:, lo:hi])
        acc_v[lo:hi][~ok[lo:hi]] = np.nan
    acc_ap = np.full(n, np.nan)
    pair = ok[1:] & ok[:-1]
    if np.count_nonzero(pair) >= 3:
        # principal direction of the horizontal *jerk* (first difference): differencing weights the AP
        # component at step frequency (~2 Hz) 4x over the ML sway at stride frequency (~1 Hz) in variance
        d = _jerk(hor, pair)
        _, vecs = np.linalg.eigh(d @ d.T)
        del d
        ap_dir = vecs[:, -1]
        for lo, hi, _, _ in halo_blocks(n, 0):
            np.copyto(hor[:, lo:hi], 0.0, where=~ok[lo:hi])
        acc_ap = ap_dir @ hor
        acc_ap *= STANDARD_GRAVITY_M_S2
        acc_ap[~ok] = np.nan
        acc_ap = _orient_ap(acc_ap, acc_v, sampling_rate_hz)
    return BodyAxes(acc_v, acc_ap, grav.T, ok)


def _vertical_block(acc: np.ndarray, grav: np.ndarray, acc_v: np.ndarray, hor: np.ndarray | None = None
                    ) -> np.ndarray:
    """One block of :func:`body_axes`: ``acc_v`` and ``hor`` (unless None) filled from ``acc`` ``(m, 3)`` and
    ``grav`` ``(3, m)``; returns where the gravity estimate is usable."""
    cols = np.ascontiguousarray(acc.T)
    gnorm = np.sqrt(grav[0] ** 2 + grav[1] ** 2 + grav[2] ** 2)
    ok = np.isfinite(gnorm) & (gnorm > 0.2)
    with np.errstate(invalid="ignore", divide="ignore"):
        ghat = grav / gnorm
    dyn = cols[0] * ghat[0] + cols[1] * ghat[1] + cols[2] * ghat[2] - gnorm       # projection minus |g|
    np.multiply(dyn, STANDARD_GRAVITY_M_S2, out=acc_v)
    if hor is not None:    # horizontal dynamic acceleration (the vertical part removed)
        np.subtract(cols - grav, dyn * ghat, out=hor)
    return ok


def _jerk(hor: np.ndarray, pair: np.ndarray) -> np.ndarray:
    """``np.diff(hor, axis=1)[:, pair]`` (the same Fortran-ordered array), filled block by block."""
    d = np.empty((3, int(np.count_nonzero(pair))), order="F")
    at = 0
    for lo, hi, _, _ in halo_blocks(pair.size, 0):
        p = pair[lo:hi]
        m = int(np.count_nonzero(p))
        for r in range(3):
            d[r, at:at + m] = np.subtract(hor[r, lo + 1:hi + 1], hor[r, lo:hi])[p]
        at += m
    return d


def _orient_ap(acc_ap: np.ndarray, acc_v: np.ndarray, sampling_rate_hz: float) -> np.ndarray:
    """Flip the AP sign so that AP leads vertical by ~0.1 s (forward walking).

    In forward walking the AP acceleration is positive while the vertical acceleration rises to its peak
    at the CoM's lowest point: their correlation with AP taken 0.1 s earlier is positive.
    """
    lag = max(1, int(round(0.1 * sampling_rate_hz)))
    vv, aa = acc_v[lag:], acc_ap[:-lag]
    good = np.isfinite(vv) & np.isfinite(aa)
    if np.count_nonzero(good) > 10 and float(np.sum(vv[good] * aa[good])) < 0:
        return -acc_ap
    return acc_ap
