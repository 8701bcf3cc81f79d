"""Peaks of a sampled curve by minimum distance and prominence: ``scipy.signal.find_peaks``'s rules in numpy.

The foot-flat search of :mod:`gaitlog.host.gait.events` needs two of ``find_peaks``' conditions, ``distance`` and
``prominence``; importing ``scipy.signal`` for them cost 0.6 s of every ``gaitlog estimate``. This module
gives the same peaks, index for index (tested against scipy as the oracle), in the same order of rules:

1. *Local maxima*: a sample, or a plateau of equal samples, with a lower sample on both sides; a plateau's
   peak is its middle sample (the left one of two). The first and last samples are never peaks.
2. *Distance*: from the highest peak down, every other peak closer than ``distance`` samples to a peak that
   is kept is dropped. Equal heights are ordered by ``np.argsort`` of the heights, the call scipy makes, so
   ties fall the same way.
3. *Prominence* of each remaining peak: its height above the higher of the two lowest points reached, on
   either side, before the curve rises above the peak (or reaches the end of the signal): kept when
   ``>= prominence``.

The prominence is vectorised: the point where the curve first rises above a peak is searched among the
curve's *tops* (maximal runs of equal samples that are higher than both neighbours, ends included) as each
top's previous greater top, by pointer jumping, and the lowest point up to it is one ``np.minimum.reduceat``.
The nearest higher top ``c`` to the left of a peak ``p`` gives the same minimum as scipy's sample-by-sample
walk, which stops at the nearest higher *sample* ``j``: ``c`` ends at or before ``j``, and a sample between
``c`` and ``j`` lower than the minimum after ``j`` would leave a higher top between it and ``j``, nearer
than ``c``. (Mirrored on the right.)
"""

from __future__ import annotations

import math

import numpy as np


def find_peaks(x: np.ndarray, *, distance: float | None = None, prominence: float | None = None,
               with_prominences: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Indices of the peaks of ``x`` that are ``distance`` apart and at least ``prominence`` prominent.

    Parameters
    ----------
    x
        ``(n,)`` samples, no NaN.
    distance
        Minimum distance between kept peaks in samples (>= 1; rounded up), or None for no distance rule.
    prominence
        Minimum prominence in the unit of ``x``, or None for no prominence rule.
    with_prominences
        Also return the peaks' prominences (``scipy.signal.peak_prominences``).

    Returns
    -------
    numpy.ndarray
        ``(k,)`` increasing ``intp`` indices: ``scipy.signal.find_peaks(x, distance=distance,
        prominence=prominence)[0]``; with ``with_prominences``, a tuple ``(indices, prominences)``.

    Raises
    ------
    ValueError
        ``x`` is not one-dimensional or holds NaN, or ``distance < 1``.
    """
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"x must be one-dimensional, got shape {a.shape}")
    if np.isnan(a).any():
        raise ValueError("x holds NaN: peaks are only defined on a curve without gaps")
    if distance is not None and not distance >= 1:
        raise ValueError(f"distance must be >= 1 sample, got {distance!r}")
    if a.size == 0:
        return (np.zeros(0, dtype=np.intp), np.zeros(0)) if with_prominences else np.zeros(0, dtype=np.intp)
    run_start, run_end = _runs(a)
    v = a[run_start]
    higher_left = np.r_[True, v[1:] > v[:-1]]
    higher_right = np.r_[v[:-1] > v[1:], True]
    top = higher_left & higher_right
    peak_run = top.copy()
    peak_run[[0, -1]] = False  # the first and last samples are never peaks
    peaks = (run_start[peak_run] + run_end[peak_run]) // 2
    if distance is not None and peaks.size > 1:
        keep = keep_by_distance(peaks, a[peaks], math.ceil(distance))
        peaks, peak_run_index = peaks[keep], np.flatnonzero(peak_run)[keep]
    else:
        peak_run_index = np.flatnonzero(peak_run)
    prom = np.zeros(0)
    if (prominence is not None or with_prominences) and peaks.size:
        prom = _prominences(a, peaks, np.searchsorted(np.flatnonzero(top), peak_run_index),
                            run_start[top], run_end[top])
        if prominence is not None:
            peaks, prom = peaks[prom >= prominence], prom[prom >= prominence]
    peaks = peaks.astype(np.intp, copy=False)
    return (peaks, prom) if with_prominences else peaks


def _runs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last index of every maximal run of equal samples (a run of one sample included)."""
    change = np.flatnonzero(a[1:] != a[:-1]) + 1
    return np.r_[0, change], np.r_[change - 1, a.size - 1]


def keep_by_distance(peaks: np.ndarray, height: np.ndarray, distance: int) -> np.ndarray:
    """Mask of the peaks kept when, from the highest down, each kept peak removes its neighbours closer than
    ``distance`` (greedy and sequential by nature; a loop over the peaks, not the samples). Rule 2 of the
    module notes; :mod:`gaitlog.host.gait.events` applies it alone to the peaks that passed its own prominence rule.

    >>> keep_by_distance(np.array([3, 5, 9]), np.array([1.0, 2.0, 1.5]), 3).tolist()
    [False, True, True]
    """
    pos = peaks.tolist()
    keep = [True] * len(pos)
    for j in np.argsort(height)[::-1].tolist():  # the same argsort as scipy: ties fall the same way
        if not keep[j]:
            continue
        k = j - 1
        while k >= 0 and pos[j] - pos[k] < distance:
            keep[k] = False
            k -= 1
        k = j + 1
        while k < len(pos) and pos[k] - pos[j] < distance:
            keep[k] = False
            k += 1
    return np.array(keep, dtype=bool)


def _prominences(a: np.ndarray, peaks: np.ndarray, peak_top: np.ndarray, top_start: np.ndarray,
                 top_end: np.ndarray) -> np.ndarray:
    """Prominence of each peak; ``peak_top`` is the index of its own run among the tops."""
    n = a.size
    top_value = a[top_start]
    height = a[peaks]
    left = _nearest_higher_before(top_value, peak_top, height)
    lo = np.where(left >= 0, top_end[left] + 1, 0)  # (top_end[-1] where none: not used)
    # mirrored: the tops read from the right
    k = top_value.size
    right = _nearest_higher_before(top_value[::-1], k - 1 - peak_top, height)
    hi = np.where(right >= 0, top_start[(k - 1 - right) % k], n)
    padded = np.r_[a, 0.0]  # reduceat's last index may be n
    left_min = np.minimum.reduceat(padded, np.c_[lo, peaks + 1].ravel())[::2]
    right_min = np.minimum.reduceat(padded, np.c_[peaks, hi].ravel())[::2]
    return height - np.maximum(left_min, right_min)


def _nearest_higher_before(values: np.ndarray, index: np.ndarray, level: np.ndarray) -> np.ndarray:
    """For each query ``q`` (``level[q]`` is ``values[index[q]]``, a top's own value): the largest ``i < index[q]``
    with ``values[i] > level[q]``, or -1: the previous greater element, :func:`_previous_greater`."""
    return _previous_greater(values)[np.asarray(index, dtype=np.intp)]


def _previous_greater(values: np.ndarray) -> np.ndarray:
    """For every ``i``: the largest ``j < i`` with ``values[j] > values[i]``, or -1.

    Pointer jumping, all elements at once: each points at a candidate ``j`` with nothing above ``values[i]``
    between them (first ``i - 1``); while the candidate is not higher, it jumps to the candidate's own candidate,
    which keeps that true. The pointers double their reach each round (a few int arrays of memory, where a table
    of running maxima took one float array per power of two).

    >>> _previous_greater(np.array([5.0, 1.0, 3.0, 3.0, 6.0, 2.0])).tolist()
    [-1, 0, 0, 0, -1, 4]
    """
    p = np.arange(-1, values.size - 1, dtype=np.intp)
    active = np.arange(1, values.size, dtype=np.intp)
    while active.size:
        active = active[values[p[active]] <= values[active]]
        p[active] = p[p[active]]
        active = active[p[active] >= 0]
    return p
