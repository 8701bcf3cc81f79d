"""Per-step double integration of vertical acceleration on the measured samples (Alvarez eqs 1-3).

Each step window ``[s_k, e_k]`` (sample indices, consecutive foot-flats) is integrated with the
trapezoidal rule over its *measured* samples only, at their true times: a lost sample is skipped (the
quadrature step spans it), never filled in. All windows are processed at once: the samples of every window
are laid end to end and integrated with one cumulative sum, from which each window's value at its first
sample is subtracted (the reset at foot-flat).

Three vertical positions are produced per sample:

* M1 -- velocity and position reset to 0 at the foot-flat that starts the window, nothing else.
* M2 -- eqs (2)-(3): ``c1`` added to the acceleration so the velocity returns to 0 at the next foot-flat
  (``c1 = -mean(a)``), ``c2`` added to the velocity so the position returns to its start value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class StepSamples:
    """Samples of all step windows laid end to end.

    Attributes
    ----------
    index
        ``(m,)`` sample index in the recording.
    step
        ``(m,)`` window number of each sample.
    first
        ``(k,)`` position in ``index`` of each window's first sample (``np.add.reduceat`` boundaries).
    tau_s
        ``(m,)`` time since the window's first sample, s.
    duration_s
        ``(k,)`` window durations (last minus first measured sample), s.
    n_missing
        ``(k,)`` missing samples inside each window.
    """

    index: np.ndarray
    step: np.ndarray
    first: np.ndarray
    tau_s: np.ndarray
    duration_s: np.ndarray
    n_missing: np.ndarray

    def reduce_max(self, x: np.ndarray) -> np.ndarray:
        """Per-window maximum of a per-sample array (NaN ignored; NaN for an all-NaN window)."""
        return _reduce(np.fmax, x, self.first)

    def reduce_min(self, x: np.ndarray) -> np.ndarray:
        """Per-window minimum of a per-sample array (NaN ignored)."""
        return _reduce(np.fmin, x, self.first)


def _reduce(ufunc: np.ufunc, x: np.ndarray, first: np.ndarray) -> np.ndarray:
    if first.size == 0:
        return np.zeros(0)
    return ufunc.reduceat(x, first)


def step_samples(start: np.ndarray, end: np.ndarray, valid: np.ndarray, sampling_rate_hz: float) -> StepSamples:
    """Lay the measured samples of the windows ``[start_k, end_k]`` end to end.

    ``start_k`` and ``end_k`` must be measured samples with ``end_k > start_k``.

    >>> ss = step_samples(np.array([0, 4]), np.array([4, 6]), np.array([1, 1, 0, 1, 1, 1, 1], bool), 10.0)
    >>> ss.index.tolist(), ss.step.tolist(), ss.n_missing.tolist()
    ([0, 1, 3, 4, 4, 5, 6], [0, 0, 0, 0, 1, 1, 1], [1, 0])
    """
    start = np.asarray(start, np.int64)
    end = np.asarray(end, np.int64)
    if start.shape != end.shape:
        raise ValueError("start and end must have the same shape")
    if start.size and np.any(end <= start):
        raise ValueError("every step window must end after it starts (end > start)")
    valid = np.asarray(valid, bool)
    lengths = end - start + 1
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]) if start.size else np.zeros(0, np.int64)
    total = int(lengths.sum()) if start.size else 0
    step = np.repeat(np.arange(start.size), lengths)
    index = np.repeat(start, lengths) + (np.arange(total) - np.repeat(offsets, lengths))
    keep = valid[index]
    n_missing = np.bincount(step[~keep], minlength=start.size).astype(np.int64)
    index, step = index[keep], step[keep]
    first = np.flatnonzero(np.r_[True, step[1:] != step[:-1]]) if step.size else np.zeros(0, np.int64)
    tau_s = (index - np.repeat(index[first], np.diff(np.r_[first, index.size]))) / sampling_rate_hz
    last = np.r_[first[1:] - 1, index.size - 1] if first.size else first
    duration_s = tau_s[last] if first.size else np.zeros(0)
    return StepSamples(index, step, first, tau_s, duration_s, n_missing)


def _segment_cumtrapz(y: np.ndarray, ss: StepSamples) -> np.ndarray:
    """Cumulative trapezoid of ``y`` (per sample of ``ss``) within each window, 0 at each window's start."""
    if y.size == 0:
        return y.copy()
    dt = np.diff(ss.tau_s, prepend=0.0)
    inc = 0.5 * (y + np.r_[y[0], y[:-1]]) * dt
    inc[ss.first] = 0.0
    cs = np.cumsum(inc)
    seg_lengths = np.diff(np.r_[ss.first, y.size])
    return cs - np.repeat(cs[ss.first], seg_lengths)


def vertical_positions(acc_v_m_s2: np.ndarray, ss: StepSamples) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample vertical position (m) of every window: M1 (plain resets) and M2 (eqs 2-3 corrected).

    Examples
    --------
    A CoM moving as ``z = -A cos(2 pi t / T)`` (lowest at the window ends, zero velocity there):
    both positions span ``2 A``.

    >>> fs, T, A = 200.0, 0.5, 0.02
    >>> t = np.arange(int(T * fs) + 1) / fs
    >>> a = A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T)
    >>> ss = step_samples(np.array([0]), np.array([t.size - 1]), np.ones(t.size, bool), fs)
    >>> p1, p2 = vertical_positions(a, ss)
    >>> round(float(p2.max() - p2.min()), 4), round(float(p1.max() - p1.min()), 3)
    (0.04, 0.04)
    """
    a = np.asarray(acc_v_m_s2, np.float64)[ss.index]
    seg_len = np.diff(np.r_[ss.first, a.size]) if ss.first.size else np.zeros(0, np.int64)
    v = _segment_cumtrapz(a, ss)                      # v(t0) = 0: the reset at foot-flat
    p1 = _segment_cumtrapz(v, ss)                     # M1
    if a.size == 0:
        return p1, p1.copy()
    last = np.r_[ss.first[1:] - 1, a.size - 1]
    T = np.repeat(ss.duration_s, seg_len)
    with np.errstate(invalid="ignore", divide="ignore"):
        c1 = np.repeat(-v[last] / ss.duration_s, seg_len)          # eq (2): v(t1) = 0, c1 = -mean(a)
        p_c1 = p1 + 0.5 * c1 * ss.tau_s ** 2                        # exact trapezoid of c1 * tau
        end_p = np.repeat(p_c1[last], seg_len)
        c2 = -end_p / T                                              # eq (3): p(t1) = p(t0) = 0
    p2 = p_c1 + c2 * ss.tau_s
    return p1, p2
