"""Centred Gaussian FIR low-pass over the measured samples, integer weights (mirrors
``host.gait.masked_filter.masked_gaussian_lowpass``).

The float chain filters by normalised convolution with a Gaussian (-3 dB at ``cutoff_hz``, truncated at
4 sigma like ``scipy.ndimage.gaussian_filter1d``). The firmware uses the same kernel with its weights
rounded to :data:`~firmware_sim.algorithms.formats.KERNEL_Q` (Q1.14, summing to about 2^14): per output
sample one 16×16 multiply-accumulate per tap into a 32-bit sum (Q4.27; ``|num| <= 2^15 · 2^14 = 2^29``
cannot overflow), the sum of the weights of the measured taps (``den``, at most ~2^14), and one rounded
32/16 divide ``num / den`` plus a 16/16 divide of its remainder for three more bits, giving
:data:`~firmware_sim.algorithms.formats.LOWPASS_OUT_Q` (Q2.16 in 24 bits, rounded half away from zero:
the long division is exact). Where ``den`` is below ``min_weight`` of the full kernel the output
is not defined (the float chain's NaN).

A FIR rather than an IIR: the float chain's filter is a centred (zero-phase) Gaussian, and the comparison
must differ only by arithmetic. On-line the FIR runs ``radius`` samples behind (0.18 s for 3 Hz at 50 Hz).
Integer convolution is exact, so the vectorised ``numpy.convolve`` is bit-exact to the per-sample MAC loop.
"""

from __future__ import annotations

import numpy as np

from firmware_sim.algorithms.formats import ACC_Q, KERNEL_Q, LOWPASS_OUT_Q
from firmware_sim.fixedpoint import ArithmeticContext, add, div, div_round, shift_left

#: Gaussian sigma (s) whose -3 dB cut-off is 1 Hz: |H(f)| = exp(-(2 pi f sigma)^2 / 2) = 1/sqrt(2).
SIGMA_S_AT_1HZ = float(np.sqrt(np.log(2.0)) / (2.0 * np.pi))


def gaussian_kernel_q(cutoff_hz: float, sampling_rate_hz: float, *, truncate: float = 4.0) -> np.ndarray:
    """Raw Q1.14 weights of the Gaussian with -3 dB at ``cutoff_hz`` (scipy's radius ``int(4 sigma + 0.5)``).

    >>> k = gaussian_kernel_q(3.0, 50.0)
    >>> k.size, int(k.sum()), int(k[9])
    (19, 16382, 2960)
    """
    if not (cutoff_hz > 0 and sampling_rate_hz > 0):
        raise ValueError(f"cutoff_hz and sampling_rate_hz must be positive, got {cutoff_hz!r}, {sampling_rate_hz!r}")
    sigma = SIGMA_S_AT_1HZ / cutoff_hz * sampling_rate_hz
    radius = int(truncate * sigma + 0.5)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    phi = np.exp(-0.5 * (x / sigma) ** 2)
    phi /= phi.sum()
    return KERNEL_Q.from_float(phi)


def masked_gaussian_lowpass_q(
    x_q: np.ndarray,
    valid: np.ndarray | None,
    *,
    cutoff_hz: float,
    sampling_rate_hz: float,
    min_weight: float = 0.5,
    ctx: ArithmeticContext | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Low-pass raw :data:`ACC_Q` samples ``x_q`` (``(n,)``) over the ``valid`` ones.

    Returns
    -------
    y_q, defined
        ``(n,)`` raw :data:`LOWPASS_OUT_Q` (0 where not defined) and the bool mask where it is defined.

    Examples
    --------
    >>> x = np.full(30, 4096); v = np.ones(30, bool); v[10:12] = False
    >>> y, d = masked_gaussian_lowpass_q(x, v, cutoff_hz=3.0, sampling_rate_hz=50.0)
    >>> bool(np.all(y == 4096 * 8)), bool(d.all())
    (True, True)
    """
    x = np.asarray(x_q, np.int64)
    if x.ndim != 1:
        raise ValueError(f"x_q must be one-dimensional, got shape {x.shape}")
    n = x.size
    ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
    wq = gaussian_kernel_q(cutoff_hz, sampling_rate_hz)
    r = (wq.size - 1) // 2
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, bool)
    num = np.convolve(np.where(ok, x, 0), wq)[r:r + n]
    den = np.convolve(ok.astype(np.int64), wq)[r:r + n]
    if ctx is not None:
        ctx.cost("mul16x16s", wq.size * n)
        ctx.cost("add32", 2 * wq.size * n)
    threshold = int(np.ceil(min_weight * int(wq.sum())))
    defined = den >= max(1, threshold)
    i = np.flatnonzero(defined) if not defined.all() else slice(None)   # only defined outputs are computed
    extra = LOWPASS_OUT_Q.frac_bits - ACC_Q.frac_bits
    q1, r1 = div(num[i], den[i], 32, ctx=ctx, op="lowpass")                            # Q2.13 part
    q2 = div_round(shift_left(r1, extra, 32, ctx=ctx), den[i], 32, ctx=ctx, op="lowpass")  # 3 more bits
    y = np.zeros(n, np.int64)
    y[i] = add(shift_left(q1, extra, LOWPASS_OUT_Q, ctx=ctx), q2, LOWPASS_OUT_Q, ctx=ctx, op="lowpass")
    return y, defined
