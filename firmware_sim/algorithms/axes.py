"""Vertical acceleration from the moving-mean gravity, in fixed point (mirrors ``host.gait.axes``).

Gravity in device axes is the centred moving mean of the calibrated specific force over
``gravity_window_s`` (the float chain's window, same alignment as ``scipy.ndimage.uniform_filter1d``:
samples ``i - w//2 .. i + w - 1 - w//2``) over the measured samples only. The vertical dynamic acceleration
is the projection on the unit gravity direction minus the gravity magnitude,

.. math:: a_v = \\frac{\\mathbf f \\cdot \\bar{\\mathbf g}}{\\lVert \\bar{\\mathbf g} \\rVert}
          - \\lVert \\bar{\\mathbf g} \\rVert

in g, :data:`~firmware_sim.algorithms.formats.ACC_Q`. Firmware steps per sample (all integer):

1. window sums ``S_j`` (Q18.13, 32 bits) += entering sample − leaving sample, count ``c`` likewise
   (the running sum is exact, so the vectorised prefix-sum difference is bit-exact);
2. ``g_j = round(S_j / c)`` (32/16 divide, ties away from zero) in Q2.13;
3. ``|g|² = Σ g_j²`` (three 16×16 multiplies, unsigned Q5.26) and ``|g| = isqrt(|g|²)`` (Q2.13, nearest);
4. ``f·g = Σ f_j g_j`` (Q5.26, saturating 32-bit sum) and ``a_v = round((f·g − |g|²) / |g|)`` (Q2.13),
   the same quantity with an exact numerator (``|g|`` is rounded to nearest).

A sample is valid where it was measured, the window holds at least one measured sample and ``|g| > 0.2 g``
(the float chain's rule).
"""

from __future__ import annotations

import numpy as np

from firmware_sim.algorithms.formats import ACC2_Q, ACC_Q, GRAVITY_SUM_Q
from firmware_sim.fixedpoint import ArithmeticContext, add, div_round, isqrt, mul, saturate, sub


def window_sums(x: np.ndarray, valid: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred window sums of ``x`` (``(n,)`` or ``(n, k)`` int) over valid samples, and the counts.

    >>> s, c = window_sums(np.array([1, 2, 3, 4]), np.array([1, 1, 0, 1], bool), 3)
    >>> s.tolist(), c.tolist()
    ([[3], [3], [6], [4]], [2, 2, 2, 1])
    """
    xx = np.asarray(x, np.int64)
    if xx.ndim == 1:
        xx = xx[:, None]
    n = xx.shape[0]
    ok = np.asarray(valid, bool)
    w = max(1, int(window))
    lo_off, hi_off = w // 2, w - 1 - w // 2
    cs = np.zeros((n + 1, xx.shape[1]), np.int64)
    np.cumsum(np.where(ok[:, None], xx, 0), axis=0, out=cs[1:])
    cc = np.concatenate([[0], np.cumsum(ok)])
    i = np.arange(n)
    lo = np.clip(i - lo_off, 0, n)
    hi = np.clip(i + hi_off + 1, 0, n)
    return cs[hi] - cs[lo], cc[hi] - cc[lo]


def vertical_acceleration_q(
    acc_q: np.ndarray,
    *,
    sampling_rate_hz: float,
    valid: np.ndarray | None = None,
    gravity_window_s: float = 4.0,
    ctx: ArithmeticContext | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertical dynamic acceleration of calibrated specific force ``acc_q`` (raw ACC_Q, ``(n, 3)``).

    Returns
    -------
    acc_v_q
        ``(n,)`` raw ACC_Q (g), 0 where not valid.
    gravity_q
        ``(n, 3)`` raw ACC_Q moving-mean gravity.
    valid
        ``(n,)`` bool.

    Examples
    --------
    >>> fs = 50.0; t = np.arange(500) / fs
    >>> up = np.array([0.6, 0.0, 0.8])
    >>> acc = ACC_Q.from_float(up[None, :] * (1 + 0.2 * np.sin(2 * np.pi * 2 * t))[:, None])
    >>> av, g, ok = vertical_acceleration_q(acc, sampling_rate_hz=fs)
    >>> bool(np.allclose(ACC_Q.to_float(av[100:400]), 0.2 * np.sin(2 * np.pi * 2 * t[100:400]), atol=2e-3))
    True
    """
    a = np.asarray(acc_q, np.int64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"acc_q must have shape (n, 3), got {a.shape}")
    n = a.shape[0]
    ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool).copy()
    w = int(round(gravity_window_s * sampling_rate_hz))
    if w > ACC_Q.max_raw:
        raise ValueError(f"gravity window of {w} samples exceeds the 16-bit count")
    # 1. running window sums (32-bit accumulators; |S| <= w * 2**15 < 2**31 for w < 65536)
    sums, count = window_sums(a, ok, w)
    sums = saturate(sums, GRAVITY_SUM_Q, ctx=ctx, op="axes.window_sum")
    if ctx is not None:
        ctx.cost("add32", 2 * 3 * n)           # add entering, subtract leaving, per axis
        ctx.cost("load_eeprom_sample", 2 * n)  # the two samples are read back from the EEPROM ring
        ctx.cost("mul16x16s", 2 * 9 * n)       # ... and re-calibrated (2 x 9 multiplies)
    has = count > 0
    # only samples whose window holds a measured sample are computed (the others have no gravity)
    h = np.flatnonzero(has) if not has.all() else slice(None)
    g = np.zeros((n, 3), np.int64)
    # 2. mean = gravity, rounded
    g[h] = div_round(sums[h], count[h][:, None], ACC_Q, ctx=ctx, op="axes.gravity_mean")
    # 3. |g| = isqrt(sum g_j^2)  (unsigned Q5.26 -> Q2.13, rounded to nearest)
    sq = mul(g[h], g[h], ctx=ctx)
    norm2 = add(add(sq[:, 0], sq[:, 1], 32, signed=False, ctx=ctx), sq[:, 2], 32, signed=False, ctx=ctx,
                op="axes.norm2")
    gn = saturate(isqrt(norm2, rounding="nearest", ctx=ctx), ACC_Q, ctx=ctx, op="axes.gravity_norm")
    keep = ok[h] & (gn > ACC_Q.from_float(0.2))
    ok[:] = False
    ok[h] = keep
    # 4. (f.g - |g|^2) / |g| at the measured samples: the numerator is exact, only the divisor |g|
    #    carries the square root's rounding (a relative 2^-14 of a_v); f.g/|g| - |g| would add it twice
    i = np.flatnonzero(ok) if not ok.all() else slice(None)
    p = mul(a[i], g[i], ctx=ctx)
    dot = add(add(p[:, 0], p[:, 1], ACC2_Q, ctx=ctx, op="axes.dot"), p[:, 2], ACC2_Q, ctx=ctx, op="axes.dot")
    full2, fullgn = np.zeros(n, np.int64), np.zeros(n, np.int64)
    full2[h], fullgn[h] = norm2, gn
    dyn = sub(dot, np.minimum(full2[i], ACC2_Q.max_raw), ACC2_Q, ctx=ctx, op="axes.dynamic")
    av = np.zeros(n, np.int64)
    av[i] = div_round(dyn, fullgn[i], ACC_Q, ctx=ctx, op="axes.vertical")
    return av, g, ok
