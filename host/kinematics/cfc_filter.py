"""SAE J211 channel-frequency-class (CFC) filter, as used by Hall et al. (1997) at CFC 180.

The J211 digital filter is a 2-pole Butterworth low-pass designed by the bilinear transform with

.. math::
    ω_d = 2π · 2.0775 · CFC,\\quad ω_a = \\tan(ω_d T / 2),\\quad T = 1/f_s,

    a_0 = \\frac{ω_a^2}{1 + \\sqrt2 ω_a + ω_a^2},\\; a_1 = 2a_0,\\; a_2 = a_0,\\;
    b_1 = \\frac{−2(ω_a^2 − 1)}{1 + \\sqrt2 ω_a + ω_a^2},\\; b_2 = \\frac{−1 + \\sqrt2 ω_a − ω_a^2}{1 + \\sqrt2 ω_a + ω_a^2},

run forwards and then backwards over the data (4 poles, zero phase, −3 dB at ``5/3 · CFC``). These are
exactly the coefficients of ``scipy.signal.butter(2, 2.0775 * CFC, fs=fs)`` (with ``a = [1, −b1, −b2]``).
The design is only meaningful when the design frequency ``2.0775 · CFC`` is below Nyquist, i.e.
``fs > 2 · 2.0775 · CFC`` (748 Hz for CFC 180); lower rates are rejected.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import filtfilt

from gaitlog.host.errors import HostError

__all__ = ["CFC_DESIGN_FACTOR", "cfc_coefficients", "cfc_filter", "cfc_min_rate_hz"]

#: Ratio of the J211 design frequency to the channel class.
CFC_DESIGN_FACTOR = 2.0775


def cfc_min_rate_hz(cfc: float) -> float:
    """The sampling rate (Hz) at or below which a CFC ``cfc`` filter is invalid: ``2 · 2.0775 · cfc``.

    Examples
    --------
    >>> round(cfc_min_rate_hz(180), 6)
    747.9
    """
    return 2.0 * CFC_DESIGN_FACTOR * float(cfc)


def cfc_coefficients(cfc: float, sampling_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Numerator ``b`` and denominator ``a`` (scipy convention) of one pass of the J211 filter.

    Parameters
    ----------
    cfc
        Channel frequency class (60, 180, 600, 1000, ... ; any positive number), Hz.
    sampling_rate_hz
        Sampling rate in Hz; must exceed :func:`cfc_min_rate_hz`.

    Raises
    ------
    HostError
        When the class or the rate is not positive/finite, or ``sampling_rate_hz <= 2 · 2.0775 · cfc``.

    Examples
    --------
    >>> b, a = cfc_coefficients(180, 10_000)
    >>> np.round(b, 8), np.round(a, 8)
    (array([0.01179627, 0.02359254, 0.01179627]), array([ 1.        , -1.67011746,  0.71730255]))
    """
    if not (np.isfinite(cfc) and cfc > 0):
        raise HostError(f"CFC filter: the channel class must be a positive number of Hz, got {cfc!r}")
    if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise HostError(f"CFC filter: the sampling rate must be a positive number of Hz, got {sampling_rate_hz!r}")
    if sampling_rate_hz <= cfc_min_rate_hz(cfc):
        raise HostError(
            f"CFC {cfc:g} filter is invalid at {sampling_rate_hz:g} Hz: SAE J211 designs it at 2.0775 x CFC = "
            f"{CFC_DESIGN_FACTOR * cfc:g} Hz, which must be below Nyquist, so the sampling rate must exceed "
            f"{cfc_min_rate_hz(cfc):g} Hz; sample faster or choose a lower channel class"
        )
    wd = 2.0 * np.pi * CFC_DESIGN_FACTOR * cfc
    wa = np.tan(wd / sampling_rate_hz / 2.0)
    den = 1.0 + np.sqrt(2.0) * wa + wa * wa
    a0 = wa * wa / den
    b1 = -2.0 * (wa * wa - 1.0) / den
    b2 = (-1.0 + np.sqrt(2.0) * wa - wa * wa) / den
    return np.array([a0, 2.0 * a0, a0]), np.array([1.0, -b1, -b2])


def cfc_filter(x: np.ndarray, cfc: float, sampling_rate_hz: float, *, axis: int = 0) -> np.ndarray:
    """Filter ``x`` with the SAE J211 CFC filter, forwards then backwards (zero phase).

    Parameters
    ----------
    x
        Data of any shape; filtered along ``axis``. Any unit (returned in the same unit).
    cfc
        Channel frequency class in Hz (Hall et al. use 180).
    sampling_rate_hz
        Sampling rate in Hz.
    axis
        Time axis.

    Returns
    -------
    numpy.ndarray
        Filtered data, same shape. The ends are handled by odd extension (``scipy.signal.filtfilt``
        default padding), which keeps a constant or linear trend through the edges without start-up
        transients; the J211 standard leaves the pre-/post-data handling to the user.

    Raises
    ------
    HostError
        Invalid class or rate (see :func:`cfc_coefficients`), non-finite data, or too few samples for the
        edge padding (``<= 9``).
    """
    b, a = cfc_coefficients(cfc, sampling_rate_hz)
    data = np.asarray(x, dtype=np.float64)
    if not np.isfinite(data).all():
        raise HostError("CFC filter: the data contain NaN or infinite values; fill or cut gaps first")
    if data.shape[axis] <= 9:
        raise HostError(f"CFC filter: need more than 9 samples along axis {axis}, got {data.shape[axis]}")
    return filtfilt(b, a, data, axis=axis)
