"""Gaussian low-pass filtering of a signal with missing samples, by normalised convolution.

A lost sample is not replaced by anything: the filtered value at sample ``i`` is the Gaussian-weighted mean
of the *measured* samples around ``i`` (Knutsson & Westin, "Normalized and differential convolution",
CVPR 1993). Where less than ``min_weight`` of the kernel's weight falls on measured samples the output is
NaN (too little data to say anything).

The Gaussian itself is :func:`gaussian_smooth`: ``scipy.ndimage.gaussian_filter1d(x, sigma, mode="constant",
truncate=4.0)`` value for value (the same kernel and the same order of additions; tested against scipy), in
numpy, so that the estimate path does not import ``scipy.ndimage`` (0.2 s).

Long signals are filtered in blocks of :data:`BLOCK_SAMPLES` with the kernel's halo (:func:`halo_blocks`), and the
moving mean's cumulative sums run block after block with the sum so far as the first term: the results are those
of the whole-array computation bit for bit, and the time per sample no longer grows once the arrays outgrow the
cache (``benchmarks/bench_long_recordings.py``).
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import SIGMA_S_AT_1HZ

#: Kernel half-width in standard deviations (scipy's default ``truncate``).
TRUNCATE_SIGMAS = 4.0

#: Samples per block of the element-wise stages (:func:`halo_blocks`): ~0.5 MB per float64 array.
BLOCK_SAMPLES = 65_536


def gaussian_sigma_s(cutoff_hz: float) -> float:
    """Sigma in seconds of the Gaussian whose -3 dB frequency is ``cutoff_hz``.

    >>> round(gaussian_sigma_s(3.0), 4)
    0.0442
    """
    if not cutoff_hz > 0:
        raise ValueError(f"cutoff_hz must be positive, got {cutoff_hz!r}")
    return SIGMA_S_AT_1HZ / cutoff_hz


def masked_gaussian_lowpass(
    x: np.ndarray,
    valid: np.ndarray | None,
    *,
    cutoff_hz: float,
    sampling_rate_hz: float,
    min_weight: float = 0.5,
) -> np.ndarray:
    """Gaussian low-pass (-3 dB at ``cutoff_hz``) of ``x`` along axis 0 using only samples where ``valid``.

    Parameters
    ----------
    x
        ``(n,)`` or ``(n, k)`` signal; values at invalid samples are ignored (may be NaN).
    valid
        ``(n,)`` bool mask of measured samples, or None (all measured, NaN entries excepted).
    cutoff_hz, sampling_rate_hz
        -3 dB frequency of the Gaussian and the sample rate, Hz.
    min_weight
        Fraction of the kernel weight that must fall on measured samples; below it the output is NaN.

    Returns
    -------
    numpy.ndarray
        Same shape as ``x``, float64.

    Examples
    --------
    >>> x = np.ones(20); v = np.ones(20, bool); v[5:7] = False; x[5:7] = np.nan
    >>> y = masked_gaussian_lowpass(x, v, cutoff_hz=3.0, sampling_rate_hz=50.0)
    >>> bool(np.allclose(y, 1.0))
    True
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:  # column by column on contiguous copies: ~10x faster than filtering along a strided axis 0
        return np.stack([masked_gaussian_lowpass(c, valid, cutoff_hz=cutoff_hz, sampling_rate_hz=sampling_rate_hz,
                                                 min_weight=min_weight) for c in np.ascontiguousarray(x.T)], axis=1)
    sigma = gaussian_sigma_s(cutoff_hz) * sampling_rate_hz
    radius = int(TRUNCATE_SIGMAS * sigma + 0.5)
    v = None if valid is None else np.asarray(valid, dtype=bool)
    out = np.full(x.shape, np.nan)
    for lo, hi, a, b in halo_blocks(x.size, radius):
        w = np.isfinite(x[lo:hi])
        if v is not None:
            w &= v[lo:hi]
        num = gaussian_smooth(np.where(w, x[lo:hi], 0.0), sigma)[a:b]
        # weight of a full kernel; zeros beyond the ends make the edges look like missing data (as they are)
        den = (ones_smoothed(w.size, sigma) if w.all() else gaussian_smooth(w.astype(np.float64), sigma))[a:b]
        np.divide(num, den, out=out[lo + a:lo + b], where=den >= min_weight)
    return out


def halo_blocks(n: int, halo: int, block: int | None = None) -> list[tuple[int, int, int, int]]:
    """Cut ``n`` samples into blocks of ``block`` (default :data:`BLOCK_SAMPLES`) with ``halo`` samples either side.

    Each item ``(lo, hi, a, b)`` is a segment ``[lo, hi)`` of the input (the block and its halo, clipped at the
    ends) whose own samples are ``[lo + a, lo + b)``: a filter of support ``2 halo + 1`` run on the segment is
    exact on ``[a, b)``. One block's arrays stay in the cache, where whole-array temporaries do not.

    >>> halo_blocks(10, 2, block=4)
    [(0, 6, 0, 4), (2, 10, 2, 6), (6, 10, 2, 4)]
    """
    block = max(1, BLOCK_SAMPLES if block is None else int(block))
    out = []
    for s in range(0, n, block):
        e = min(n, s + block)
        lo, hi = max(0, s - halo), min(n, e + halo)
        out.append((lo, hi, s - lo, e - lo))
    return out


def gaussian_smooth(x: np.ndarray, sigma_samples: float) -> np.ndarray:
    """Gaussian filter of a ``(n,)`` signal, zeros beyond both ends, kernel cut at ``TRUNCATE_SIGMAS``.

    ``scipy.ndimage.gaussian_filter1d(x, sigma_samples, mode="constant", truncate=4.0)`` to the last bit:
    the kernel is scipy's (``exp(-x²/2σ²)`` over ``|x| <= int(4σ + 1/2)``, divided by its sum) and the sum
    is formed in scipy's order for a symmetric kernel, ``x[i]·w0 + Σ_{j=r..1} (x[i-j] + x[i+j])·w_j``.

    >>> gaussian_smooth(np.array([0.0, 0.0, 1.0, 0.0, 0.0]), 0.5).round(4).tolist()
    [0.0003, 0.1065, 0.7866, 0.1065, 0.0003]
    """
    x = np.asarray(x, dtype=np.float64)
    sigma = float(sigma_samples)
    radius = int(TRUNCATE_SIGMAS * sigma + 0.5)
    offsets = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 / (sigma * sigma) * offsets ** 2)
    kernel = kernel / kernel.sum()
    n = x.size
    padded = np.concatenate([np.zeros(radius), x, np.zeros(radius)])
    out = x * kernel[radius]
    term = np.empty(n)
    for j in range(radius, 0, -1):
        np.add(padded[radius - j:radius - j + n], padded[radius + j:radius + j + n], out=term)
        term *= kernel[radius + j]
        out += term
    return out


def ones_smoothed(n: int, sigma_samples: float) -> np.ndarray:
    """``gaussian_smooth(np.ones(n), sigma_samples)`` bit for bit, from one kernel's length: every sample a radius
    or more from both ends sums the same terms in the same order (one value), and an edge sample's terms are its
    mirror's (``1 + 0`` and ``0 + 1`` are the same number).

    >>> bool(np.array_equal(ones_smoothed(50, 2.65), gaussian_smooth(np.ones(50), 2.65)))
    True
    """
    radius = int(TRUNCATE_SIGMAS * float(sigma_samples) + 0.5)
    if n <= 2 * radius + 1:
        return gaussian_smooth(np.ones(n), sigma_samples)
    edge = gaussian_smooth(np.ones(2 * radius + 1), sigma_samples)
    out = np.full(n, edge[radius])
    out[:radius] = edge[:radius]
    out[n - radius:] = edge[radius + 1:]
    return out


def masked_moving_mean(x: np.ndarray, valid: np.ndarray | None, *, window: int) -> np.ndarray:
    """Centred moving mean over ``window`` samples using only measured samples (NaN where none).

    >>> masked_moving_mean(np.array([1.0, np.nan, 3.0]), None, window=3).tolist()
    [1.0, 2.0, 3.0]
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        return np.stack([masked_moving_mean(c, valid, window=window) for c in np.ascontiguousarray(x.T)], axis=1)
    v = None if valid is None else np.asarray(valid, dtype=bool)
    window = max(1, int(window))
    n = x.size
    # centred running sums by cumulative sums: O(n); the sums run over the whole signal, block after block
    cx = np.zeros(n + 1)
    cw = np.zeros(n + 1, np.int64)
    for lo, hi, _, _ in halo_blocks(n, 0):
        w = np.isfinite(x[lo:hi])
        if v is not None:
            w &= v[lo:hi]
        xz = np.where(w, x[lo:hi], 0.0)
        if lo:  # carry the sum so far as the first term: the additions of one whole-signal cumsum, in order
            xz = np.concatenate([cx[lo:lo + 1], xz])
            w = np.concatenate([cw[lo:lo + 1], w])
        np.cumsum(xz, out=cx[lo + 1 - (lo > 0):hi + 1])
        np.cumsum(w, out=cw[lo + 1 - (lo > 0):hi + 1])
    out = np.full(n, np.nan)
    for lo, hi, _, _ in halo_blocks(n, 0):
        a = lo - window // 2                              # the window of sample i is [i + a - lo, ... + window)
        num = shifted(cx, a + window, hi - lo) - shifted(cx, a, hi - lo)
        den = shifted(cw, a + window, hi - lo) - shifted(cw, a, hi - lo)
        np.divide(num, den, out=out[lo:hi], where=den > 0)
    return out


def shifted(c: np.ndarray, start: int, m: int) -> np.ndarray:
    """``c[..., clip(start + arange(m), 0, n - 1)]`` (``n = c.shape[-1]``) from slices: a view where no index is
    clipped, else a copy.

    >>> shifted(np.arange(4), -2, 8).tolist()
    [0, 0, 0, 1, 2, 3, 3, 3]
    >>> shifted(np.arange(8).reshape(2, 4), 2, 3).tolist()
    [[2, 3, 3], [6, 7, 7]]
    """
    n = c.shape[-1]
    lead = min(max(-start, 0), m)                  # indices below 0
    trail = min(max(start + m - n, 0), m - lead)   # indices above the last
    if not lead and not trail:
        return c[..., start:start + m]
    out = np.empty(c.shape[:-1] + (m,), c.dtype)
    out[..., :lead] = c[..., :1]
    out[..., m - trail:] = c[..., n - 1:]
    out[..., lead:m - trail] = c[..., start + lead:start + m - trail]
    return out
