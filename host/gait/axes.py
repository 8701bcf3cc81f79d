"""Vertical and antero-posterior acceleration from the direction of gravity (minimal tilt correction).

The logger is strapped to the lower back and tilted as mounted. Over a few strides the dynamic
acceleration of the trunk averages to zero, so a moving mean of the specific force is the gravity vector in
device axes (Moe-Nilssen, Clin. Biomech. 13, 1998, "tilt correction"; Morris 1973 eqs 11-16 take the
same gravity vector at foot-flat for the initial direction-cosine matrix). The vertical dynamic
acceleration is the projection on the unit gravity direction minus the gravity magnitude:

.. math:: a_v = \\mathbf{f} \\cdot \\hat{\\mathbf{g}} - \\lVert \\bar{\\mathbf{f}} \\rVert

(positive up, m/s^2). The antero-posterior axis is the horizontal direction (perpendicular to
:math:`\\hat g`) of largest dynamic variance after removing the stride-frequency medio-lateral sway
(principal component of the horizontal acceleration band-limited above 1.5 Hz, where the AP component at
step frequency dominates the ML sway at stride frequency); its sign is not determined by gravity and is
chosen so that the AP acceleration is positive just before the vertical peak at foot-flat, as in forward
walking (the trunk is accelerated forwards while the CoM passes its lowest point; Zijlstra & Hof,
Gait Posture 18, 2003).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from host.gait.masked_filter import masked_gaussian_lowpass, masked_moving_mean

#: Standard gravity, m/s^2 per g.
STANDARD_GRAVITY_M_S2 = 9.80665


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
    >>> fs = 50.0; t = np.arange(500) / fs
    >>> up = np.array([0.6, 0.0, 0.8])          # device tilted, gravity along (0.6, 0, 0.8)
    >>> acc = up[None, :] * (1.0 + 0.2 * np.sin(2 * np.pi * 2 * t))[:, None]
    >>> ax = body_axes(acc, sampling_rate_hz=fs)
    >>> bool(np.allclose(ax.acc_v_m_s2[100:400], 0.2 * 9.80665 * np.sin(2 * np.pi * 2 * t[100:400]), atol=0.02))
    True
    """
    acc = np.asarray(acc_g, dtype=np.float64)
    if acc.ndim != 2 or acc.shape[1] != 3:
        raise ValueError(f"acc_g must have shape (n, 3), got {acc.shape}")
    ok = np.all(np.isfinite(acc), axis=1)
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool)
    grav = masked_moving_mean(acc, ok, window=int(round(gravity_window_s * sampling_rate_hz)))
    gnorm = np.linalg.norm(grav, axis=1)
    ok &= np.isfinite(gnorm) & (gnorm > 0.2)
    ghat = np.divide(grav, gnorm[:, None], out=np.zeros_like(grav), where=ok[:, None])
    acc_v = np.full(acc.shape[0], np.nan)
    acc_v[ok] = (np.einsum("ij,ij->i", acc[ok], ghat[ok]) - gnorm[ok]) * STANDARD_GRAVITY_M_S2
    # horizontal dynamic acceleration
    hor = np.full_like(acc, np.nan)
    dyn = acc[ok] - grav[ok]
    hor[ok] = dyn - np.einsum("ij,ij->i", dyn, ghat[ok])[:, None] * ghat[ok]
    acc_ap = np.full(acc.shape[0], np.nan)
    if np.count_nonzero(ok) >= 3:
        # remove the stride-frequency sway (< ~1.5 Hz) before the principal direction
        slow = masked_gaussian_lowpass(hor, ok, cutoff_hz=1.5, sampling_rate_hz=sampling_rate_hz)
        fast = hor - slow
        good = ok & np.all(np.isfinite(fast), axis=1)
        if np.count_nonzero(good) >= 3:
            cov = fast[good].T @ fast[good]
            _, vecs = np.linalg.eigh(cov)
            ap_dir = vecs[:, -1]
            acc_ap[ok] = hor[ok] @ ap_dir * STANDARD_GRAVITY_M_S2
            acc_ap = _orient_ap(acc_ap, acc_v, ok, sampling_rate_hz)
    return BodyAxes(acc_v, acc_ap, grav, ok)


def _orient_ap(acc_ap: np.ndarray, acc_v: np.ndarray, ok: np.ndarray, fs: float) -> np.ndarray:
    """Flip the AP sign so that AP leads vertical by a quarter step (forward walking).

    In forward walking the low-passed AP acceleration is positive while the vertical acceleration rises
    to its peak at the CoM's lowest point: the cross-correlation at a small negative lag (AP earlier) is
    positive.
    """
    v = masked_gaussian_lowpass(acc_v, ok, cutoff_hz=3.0, sampling_rate_hz=fs)
    a = masked_gaussian_lowpass(acc_ap, ok, cutoff_hz=3.0, sampling_rate_hz=fs)
    lag = max(1, int(round(0.1 * fs)))
    vv, aa = v[lag:], a[:-lag]
    good = np.isfinite(vv) & np.isfinite(aa)
    if np.count_nonzero(good) > 10 and float(np.sum(vv[good] * aa[good])) < 0:
        return -acc_ap
    return acc_ap
