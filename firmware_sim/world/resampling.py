"""Rate conversion of a motion signal with an anti-aliasing polyphase filter.

The sensor model runs on a fine internal grid and every motion source must reach it without aliasing:
a recording at 100 Hz going to 1 kHz is interpolated, one at 1 kHz going to 200 Hz is low-passed first.
:func:`resample_g` wraps :func:`scipy.signal.resample_poly` (Kaiser-windowed FIR, cut-off at the lower
Nyquist frequency) with the rate ratio approximated by a fraction ``up/down``; the output rate is exactly
``rate_in_hz * up / down`` and is returned, never assumed.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from scipy import signal

from gaitlog.firmware_sim.errors import DeviceError

__all__ = ["rate_ratio", "resample_g"]

#: Largest denominator of the up/down fraction (keeps the polyphase filter short).
MAX_DENOMINATOR = 1000


def rate_ratio(rate_in_hz: float, rate_out_hz: float, *, max_denominator: int = MAX_DENOMINATOR) -> tuple[int, int]:
    """Return ``(up, down)`` with ``up / down`` closest to ``rate_out_hz / rate_in_hz``.

    Examples
    --------
    >>> rate_ratio(100.0, 1000.0), rate_ratio(102.4, 1000.0), rate_ratio(1000.0, 50.0)
    ((10, 1), (625, 64), (1, 20))
    """
    if not (rate_in_hz > 0 and rate_out_hz > 0 and np.isfinite(rate_in_hz) and np.isfinite(rate_out_hz)):
        raise DeviceError(f"sample rates must be positive and finite, got {rate_in_hz!r} -> {rate_out_hz!r}")
    frac = Fraction(rate_out_hz / rate_in_hz).limit_denominator(max_denominator)
    if frac.numerator == 0:
        raise DeviceError(f"cannot resample {rate_in_hz} Hz to {rate_out_hz} Hz: ratio too small")
    return frac.numerator, frac.denominator


def resample_g(acc_g: np.ndarray, rate_in_hz: float, rate_out_hz: float) -> tuple[np.ndarray, float]:
    """Resample ``(n, k)`` samples from ``rate_in_hz`` to (nearly) ``rate_out_hz``.

    Parameters
    ----------
    acc_g
        Signal, shape ``(n, k)``, any unit (g by convention), on a regular grid.
    rate_in_hz, rate_out_hz
        Input rate and requested output rate in Hz.

    Returns
    -------
    resampled : numpy.ndarray
        ``(m, k)`` float64, ``m = ceil(n * up / down)``; sample 0 is at the same time as input sample 0.
    sampling_rate_hz : float
        The exact output rate ``rate_in_hz * up / down``.

    Notes
    -----
    The edges are padded by extending the line through the end samples (``padtype="line"``), so a signal
    that sits at 1 g does not sag towards 0 at its ends as it would with zero padding.

    Examples
    --------
    >>> t = np.arange(200) / 100.0
    >>> x = np.c_[np.sin(2 * np.pi * 2.0 * t)]
    >>> y, r = resample_g(x, 100.0, 1000.0)
    >>> y.shape, r, bool(np.abs(y[500:1500, 0] - np.sin(2 * np.pi * 2.0 * np.arange(500, 1500) / 1000)).max() < 1e-3)
    ((2000, 1), 1000.0, True)
    """
    x = np.asarray(acc_g, dtype=np.float64)
    if x.ndim != 2:
        raise DeviceError(f"resample_g expects an (n, k) array, got shape {x.shape}")
    up, down = rate_ratio(rate_in_hz, rate_out_hz)
    sampling_rate_hz = rate_in_hz * up / down
    if up == down:
        return x.copy(), float(rate_in_hz)
    if x.shape[0] < 2:
        raise DeviceError(f"need at least 2 samples to resample, got {x.shape[0]}")
    y = signal.resample_poly(x, up, down, axis=0, padtype="line")
    return np.ascontiguousarray(y), float(sampling_rate_hz)
