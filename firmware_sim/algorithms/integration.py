"""Per-step double integration in saturating 32-bit accumulators (mirrors ``host.gait.integration``).

Each step window ``[s_k, e_k]`` (consecutive foot-flats) is integrated over its measured samples with the
trapezoidal rule at their true sample times, exactly as the float chain does, but in integers that carry no
rounding at all: with ``Δn`` the number of sample periods between consecutive measured samples,

* velocity ``V += (a_k + a_{k−1}) · Δn``  (unit: ``2 · lsb · T_s``; :data:`~.formats.VELOCITY_Q`),
* position ``P += (V_k + V_{k−1}) · Δn``  (unit: ``4 · lsb · T_s²``; :data:`~.formats.POSITION_Q`),

reset to 0 at the window's first sample (M1, Alvarez eq 1). M2 (eqs 2-3) is a second pass over the same
samples (the firmware reads the step back from the EEPROM): ``c1 = −V_end / (2 T)`` is added to the
acceleration, held with 4 more fraction bits (``a·16 + c1``, 32-bit), and the position is integrated again;
then ``c2 = round(P_end / T)`` per sample period is subtracted as a ramp (one addition per sample). ``T``
is the window's duration in sample periods. Rounding happens only in ``c1`` (half a Q2.17 lsb: at most
``T²/8 · 2^-18 g`` ≈ 0.04 mm of position for a 0.5 s step) and ``c2``.

An accumulator that leaves the 32-bit range saturates (counted in the context): the exact sums are used
(vectorised) and only a window that overflows is re-run sample by sample with clipping, which is what the
firmware computes. On walking the bounds hold with a wide margin (``docs/FIXED_POINT.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware_sim.algorithms.formats import POSITION_Q, VELOCITY_Q
from firmware_sim.fixedpoint import ArithmeticContext, cumsum, div_round, saturate

#: Extra fraction bits of the M2 second pass (acceleration as a * 2**4 + c1).
M2_EXTRA_BITS = 4


@dataclass(frozen=True, eq=False)
class StepSamplesQ:
    """Measured samples of all step windows laid end to end (integer time).

    Attributes
    ----------
    index, step
        Sample index and window number of each measured sample.
    first
        ``(k,)`` position of each window's first sample (for an empty window: where it would start).
    n_measured
        ``(k,)`` measured samples per window; every per-window result of a window with fewer than two
        is undefined (the float chain's NaN).
    tau
        ``(m,)`` sample periods since the window's first measured sample.
    duration
        ``(k,)`` sample periods from first to last measured sample (0 where undefined).
    n_missing
        ``(k,)`` missing samples inside each window.
    """

    index: np.ndarray
    step: np.ndarray
    first: np.ndarray
    n_measured: np.ndarray
    tau: np.ndarray
    duration: np.ndarray
    n_missing: np.ndarray

    @property
    def defined(self) -> np.ndarray:
        """Windows with at least two measured samples."""
        return self.n_measured >= 2

    @property
    def last(self) -> np.ndarray:
        """Position of each window's last sample (of its first for an empty window, clipped)."""
        return np.clip(self.first + np.maximum(self.n_measured, 1) - 1, 0, max(self.index.size - 1, 0))

    def reduce_max(self, x: np.ndarray) -> np.ndarray:
        """Per-window maximum (0 where the window is undefined)."""
        return self._reduce(np.maximum, x)

    def reduce_min(self, x: np.ndarray) -> np.ndarray:
        """Per-window minimum (0 where the window is undefined)."""
        return self._reduce(np.minimum, x)

    def _reduce(self, ufunc: np.ufunc, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.first.size, np.int64)
        nonempty = self.n_measured > 0
        if nonempty.any():   # consecutive starts of the non-empty windows delimit exactly their samples
            out[nonempty] = ufunc.reduceat(np.asarray(x, np.int64), self.first[nonempty])
        return np.where(self.defined, out, 0)


def step_samples_q(start: np.ndarray, end: np.ndarray, valid: np.ndarray) -> StepSamplesQ:
    """Lay the measured samples of windows ``[start_k, end_k]`` end to end (``end_k > start_k``).

    >>> ss = step_samples_q(np.array([0, 4]), np.array([4, 6]), np.array([1, 1, 0, 1, 1, 1, 1], bool))
    >>> ss.index.tolist(), ss.tau.tolist(), ss.duration.tolist(), ss.n_missing.tolist()
    ([0, 1, 3, 4, 4, 5, 6], [0, 1, 3, 4, 0, 1, 2], [4, 2], [1, 0])
    """
    start = np.asarray(start, np.int64)
    end = np.asarray(end, np.int64)
    if start.shape != end.shape:
        raise ValueError("start and end must have the same shape")
    if start.size and np.any(end <= start):
        raise ValueError("every step window must end after it starts (end > start)")
    valid = np.asarray(valid, bool)
    k = start.size
    lengths = end - start + 1
    total = int(lengths.sum()) if k else 0
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]) if k else np.zeros(0, np.int64)
    step = np.repeat(np.arange(k), lengths)
    index = np.repeat(start, lengths) + (np.arange(total) - np.repeat(offsets, lengths))
    keep = valid[index]
    n_missing = np.bincount(step[~keep], minlength=k).astype(np.int64)
    index, step = index[keep], step[keep]
    n_measured = np.bincount(step, minlength=k).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(n_measured)[:-1]]).astype(np.int64) if k else np.zeros(0, np.int64)
    tau = index - index[first[step]] if index.size else np.zeros(0, np.int64)
    duration = np.zeros(k, np.int64)
    has = n_measured >= 2
    duration[has] = tau[first[has] + n_measured[has] - 1]
    return StepSamplesQ(index, step, first, n_measured, tau, duration, n_missing)


def _segment_trapezoid(y: np.ndarray, ss: StepSamplesQ, ctx: ArithmeticContext | None, op: str) -> np.ndarray:
    """Saturating 32-bit running sum of ``(y_k + y_{k-1}) · Δn`` within each window, 0 at its start."""
    if y.size == 0:
        return y.copy()
    dn = np.diff(ss.tau, prepend=0)
    inc = (y + np.r_[y[0], y[:-1]]) * dn
    inc[ss.first[ss.n_measured > 0]] = 0
    inc = saturate(inc, VELOCITY_Q, ctx=ctx, op=op + ".increment")
    cs = np.cumsum(inc)
    out = cs - cs[ss.first[ss.step]]
    if ctx is not None:
        ctx.cost("add32", 2 * y.size)
        ctx.cost("sat32", y.size)
    lo, hi = VELOCITY_Q.min_raw, VELOCITY_Q.max_raw
    bad = np.flatnonzero((out < lo) | (out > hi))
    if bad.size:  # only windows that overflow are re-run with a clipping accumulator (the firmware's loop)
        for k in np.unique(ss.step[bad]):
            a, b = ss.first[k], ss.first[k] + ss.n_measured[k]
            out[a:b] = cumsum(inc[a:b], VELOCITY_Q, ctx=ctx, op=op)
    return out


@dataclass(frozen=True, eq=False)
class VerticalPositionsQ:
    """Integer positions of every window's samples (per sample of a :class:`StepSamplesQ`).

    Attributes
    ----------
    p1
        M1 position, unit ``4 · 2^-13 g · T_s²``.
    p2
        M2 position, unit ``4 · 2^-17 g · T_s²`` (16x finer).
    """

    p1: np.ndarray
    p2: np.ndarray


def position_unit_m(sampling_rate_hz: float, *, m2: bool) -> float:
    """Metres per unit of :attr:`VerticalPositionsQ.p1` (``m2=False``) or ``p2``.

    >>> round(position_unit_m(50.0, m2=False) * 1e9, 2)
    119.71
    """
    from firmware_sim.algorithms.formats import ACC_Q, STANDARD_GRAVITY_M_S2

    frac = ACC_Q.frac_bits + (M2_EXTRA_BITS if m2 else 0)
    return STANDARD_GRAVITY_M_S2 * 2.0 ** -frac / (4.0 * sampling_rate_hz ** 2)


def vertical_positions_q(acc_v_q: np.ndarray, ss: StepSamplesQ, *,
                         ctx: ArithmeticContext | None = None) -> VerticalPositionsQ:
    """M1 and M2 positions of raw ACC_Q vertical acceleration over the windows of ``ss``.

    Examples
    --------
    CoM ``z = -A cos(2 pi t / T)`` sampled at 200 Hz: both positions span ``2 A`` = 4 cm.

    >>> from firmware_sim.algorithms.formats import ACC_Q
    >>> fs, T, A = 200.0, 0.5, 0.02
    >>> t = np.arange(int(T * fs) + 1) / fs
    >>> a = ACC_Q.from_float(A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T) / 9.80665)
    >>> ss = step_samples_q(np.array([0]), np.array([t.size - 1]), np.ones(t.size, bool))
    >>> pos = vertical_positions_q(a, ss)
    >>> h1 = float(np.ptp(pos.p1)) * position_unit_m(fs, m2=False)
    >>> h2 = float(np.ptp(pos.p2)) * position_unit_m(fs, m2=True)
    >>> round(h1, 4), round(h2, 4)
    (0.04, 0.04)
    """
    a = np.asarray(acc_v_q, np.int64)[ss.index]
    v = _segment_trapezoid(a, ss, ctx, "integration.v1")
    p1 = _segment_trapezoid(v, ss, ctx, "integration.p1")
    if a.size == 0:
        return VerticalPositionsQ(p1, p1.copy())
    last = ss.last
    dur = np.maximum(ss.duration, 1)       # undefined windows (< 2 samples) give no result anyway
    # eq (2): c1 = -mean(a) = -V_end / (2 T), with M2_EXTRA_BITS more fraction bits
    scale = 1 << (M2_EXTRA_BITS - 1)
    c1 = div_round(saturate(-v[last] * scale, 32, ctx=ctx, op="integration.c1"), dur, 32, ctx=ctx,
                   op="integration.c1")
    a2 = saturate((a << M2_EXTRA_BITS) + c1[ss.step], 32, ctx=ctx, op="integration.a2")
    v2 = _segment_trapezoid(a2, ss, ctx, "integration.v2")
    p_c1 = _segment_trapezoid(v2, ss, ctx, "integration.p2")
    # eq (3): c2 per sample period so that the position returns to its start, subtracted as a ramp
    c2 = div_round(p_c1[last], dur, 32, ctx=ctx, op="integration.c2")
    p2 = saturate(p_c1 - c2[ss.step] * ss.tau, POSITION_Q, ctx=ctx, op="integration.ramp")
    if ctx is not None:
        ctx.cost("add32", a.size)
    return VerticalPositionsQ(p1, p2)
