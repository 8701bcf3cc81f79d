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

from dataclasses import dataclass, field

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
    n_measured: np.ndarray
    #: positions already computed for an acceleration array (keyed by the array object; see
    #: :func:`vertical_positions`), so that M1, M2 and M3 on the same windows integrate once
    _positions: dict = field(default_factory=dict, repr=False, compare=False)

    def spread(self, x: np.ndarray) -> np.ndarray:
        """Per-window values ``(k,)`` repeated for each of the window's samples: ``x[step]``, read in order."""
        return np.repeat(x, self.n_measured)

    def reduce_max(self, x: np.ndarray) -> np.ndarray:
        """Per-window maximum of a per-sample array (NaN ignored; NaN for windows with < 2 samples)."""
        return self._reduce(np.fmax, x)

    def reduce_min(self, x: np.ndarray) -> np.ndarray:
        """Per-window minimum of a per-sample array (NaN ignored; NaN for windows with < 2 samples)."""
        return self._reduce(np.fmin, x)

    def _reduce(self, ufunc: np.ufunc, x: np.ndarray) -> np.ndarray:
        if self.first.size == 0:
            return np.zeros(0)
        x = np.asarray(x, np.float64)
        out = np.full(self.first.size, np.nan)
        inside = self.first < x.size                        # empty trailing windows start past the end
        if inside.any():
            out[inside] = ufunc.reduceat(x, self.first[inside])
        out[self.n_measured < 2] = np.nan
        return out


def step_samples(start: np.ndarray, end: np.ndarray, valid: np.ndarray, sampling_rate_hz: float) -> StepSamples:
    """Lay the measured samples of the windows ``[start_k, end_k]`` end to end.

    Windows must satisfy ``end_k > start_k``. A window with fewer than two measured samples gives NaN in
    every per-window result (``n_measured`` says which).

    >>> ss = step_samples(np.array([0, 4]), np.array([4, 6]), np.array([1, 1, 0, 1, 1, 1, 1], bool), 10.0)
    >>> ss.index.tolist(), ss.step.tolist(), ss.n_missing.tolist(), ss.first.tolist()
    ([0, 1, 3, 4, 4, 5, 6], [0, 0, 0, 0, 1, 1, 1], [1, 0], [0, 4])
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
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]) if k else np.zeros(0, np.int64)
    total = int(lengths.sum()) if k else 0
    step = np.repeat(np.arange(k), lengths)
    index = np.arange(total) + np.repeat(start - offsets, lengths)
    keep = valid[index]
    n_missing = np.bincount(step[~keep], minlength=k).astype(np.int64)
    index, step = index[keep], step[keep]
    n_measured = np.bincount(step, minlength=k).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(n_measured)[:-1]]).astype(np.int64) if k else np.zeros(0, np.int64)
    nz = n_measured > 0
    tau_s = (index - np.repeat(index[first[nz]], n_measured[nz])) / sampling_rate_hz if index.size else np.zeros(0)
    duration_s = np.full(k, np.nan)
    has = n_measured >= 2
    if has.any():
        last = first[has] + n_measured[has] - 1
        duration_s[has] = tau_s[last]
    return StepSamples(index, step, first, tau_s, duration_s, n_missing, n_measured)


def _segment_cumtrapz(y: np.ndarray, ss: StepSamples) -> np.ndarray:
    """Cumulative trapezoid of ``y`` (per sample of ``ss``) within each window, 0 at each window's start."""
    if y.size == 0:
        return y.copy()
    inc = np.empty(y.size)
    np.add(y[1:], y[:-1], out=inc[1:])
    inc[0] = y[0] + y[0]
    inc *= 0.5
    inc[1:] *= np.subtract(ss.tau_s[1:], ss.tau_s[:-1])
    inc[0] *= ss.tau_s[0]
    nz = ss.n_measured > 0
    starts = ss.first[nz]
    inc[starts] = 0.0
    cs = np.cumsum(inc, out=inc)
    cs -= np.repeat(cs[starts], ss.n_measured[nz])
    return cs


def vertical_positions(acc_v_m_s2: np.ndarray, ss: StepSamples) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample vertical position (m) of every window: M1 (plain resets) and M2 (eqs 2-3 corrected).

    Examples
    --------
    A CoM moving as ``z = -A cos(2 pi t / T)`` (lowest at the window ends, zero velocity there):
    both positions span ``2 A``.

    >>> sampling_rate_hz, T, A = 200.0, 0.5, 0.02
    >>> t = np.arange(int(T * sampling_rate_hz) + 1) / sampling_rate_hz
    >>> a = A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T)
    >>> ss = step_samples(np.array([0]), np.array([t.size - 1]), np.ones(t.size, bool), sampling_rate_hz)
    >>> p1, p2 = vertical_positions(a, ss)
    >>> round(float(p2.max() - p2.min()), 4), round(float(p1.max() - p1.min()), 3)
    (0.04, 0.04)
    """
    cached = ss._positions.get(id(acc_v_m_s2))
    if cached is not None and cached[0] is acc_v_m_s2:
        return cached[1], cached[2]
    a = np.asarray(acc_v_m_s2, np.float64)[ss.index]
    v = _segment_cumtrapz(a, ss)                      # v(t0) = 0: the reset at foot-flat
    p1 = _segment_cumtrapz(v, ss)                     # M1
    if a.size == 0:
        return p1, p1.copy()
    has = ss.n_measured > 0
    last = np.zeros(ss.first.size, np.int64)
    last[has] = ss.first[has] + ss.n_measured[has] - 1
    T = ss.spread(ss.duration_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        c1 = -ss.spread(v[last]) / T                                  # eq (2): v(t1) = 0, c1 = -mean(a)
        p_c1 = p1 + 0.5 * c1 * ss.tau_s ** 2                         # exact trapezoid of c1 * tau
        c2 = -ss.spread(p_c1[last]) / T                               # eq (3): p(t1) = p(t0) = 0
    p2 = p_c1 + c2 * ss.tau_s
    ss._positions[id(acc_v_m_s2)] = (acc_v_m_s2, p1, p2)   # the reference keeps the id unique
    return p1, p2


def m2_vertical_velocity(acc_v_m_s2: np.ndarray, ss: StepSamples) -> np.ndarray:
    """Per-sample vertical velocity (m/s) of every window with M2's corrections (eqs 2-3): the derivative of
    :func:`vertical_positions`' M2 position, ``v + c1 tau + c2`` (0 at the window's ends up to ``c2``).

    >>> sampling_rate_hz, T, A = 200.0, 0.5, 0.02
    >>> t = np.arange(int(T * sampling_rate_hz) + 1) / sampling_rate_hz
    >>> a = A * (2 * np.pi / T) ** 2 * np.cos(2 * np.pi * t / T)          # z = -A cos(2 pi t / T)
    >>> ss = step_samples(np.array([0]), np.array([t.size - 1]), np.ones(t.size, bool), sampling_rate_hz)
    >>> v = m2_vertical_velocity(a, ss)
    >>> round(float(v[25]), 3), round(float(A * 2 * np.pi / T), 3)        # fastest a quarter into the step
    (0.251, 0.251)
    """
    a = np.asarray(acc_v_m_s2, np.float64)[ss.index]
    if a.size == 0:
        return a
    v = _segment_cumtrapz(a, ss)
    p1 = _segment_cumtrapz(v, ss)
    has = ss.n_measured > 0
    last = np.zeros(ss.first.size, np.int64)
    last[has] = ss.first[has] + ss.n_measured[has] - 1
    T = ss.spread(ss.duration_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        c1 = -ss.spread(v[last]) / T
        p_c1 = p1 + 0.5 * c1 * ss.tau_s ** 2
        c2 = -ss.spread(p_c1[last]) / T
    return v + c1 * ss.tau_s + c2
