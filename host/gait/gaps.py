"""Missing samples before the estimators: short gaps interpolated, long gaps split the walk.

A recording's lost samples stay missing in what ``gaitlog decode`` writes (a decoder never invents a sample).
The offline chain decides what to do with them, once, here (:class:`GapFiller`, run first by
:class:`gaitlog.host.gait.pipeline.StepPipeline`):

1. A run of missing samples of at most :data:`MAX_INTERPOLATED_GAP_S` with a measured sample on each side is
   filled by linear interpolation on the sample grid, per axis.
2. A longer run stays missing; the event detector ends the walking bout there
   (:class:`gaitlog.host.gait.events.GaitEventDetector`, whose ``max_gap_s`` is the same constant), so no step
   window spans it: the step across it has no length and counts with its bout's median
   (:meth:`gaitlog.firmware_sim.algorithms.steps.StepTable.distance_m`).
3. Per recording: the missing fraction, the longest gap and the number of samples filled and left missing
   (the fitted attributes), which ``gaitlog evaluate ipol`` reports per trial.

Why interpolate: left missing, a lost sample is skipped by every integral and filter (the quadrature step spans
it), but the detector's band-passes and the step windows then see fewer, flatter samples: deleting 10 % of the
samples of clean IPOL trials at random shortened M2's trial distance by 2.2 % on average (bursts of 1-5
samples: 3.5 %), M1's by 1.9 %. Interpolated, the mean change is below 1 % (measured, ``docs/topics/accuracy.md``).
Why 0.1 s: the IPOL files lose 1-3 packets at a time (99th percentile 7 packets, 70 ms; one run of 0.64 s),
and 0.1 s is a fifth of a step (0.55 s median): the step's fundamental (1.8 Hz) and the 3 Hz low-pass that M4
and the foot-flat detector read are still followed by a straight line over it, while a longer gap may hide a
heel strike. The value is not chosen on the recordings' step lengths (not a tuned constant).

Why linear and not cubic: at 50 Hz the lower-back acceleration is not smooth (a quarter to half of each axis's
power above 5 Hz), so a cubic's O(dt^4) error does not apply. Measured by deleting 10 % of the samples of the
clean IPOL trials (``benchmarks/gap_interpolants.py``), the 4-point cubic, the natural spline, PCHIP and Akima
cut the RMS error of a filled sample by 8-17 % (linear: 0.63 m/s^2) and M1 misses the targets with every one
(median absolute change of a trial 0.77-0.90 % against linear's 1.05 %; its foot-flats move nearly as often), while
the 4-point cubic and the spline bias M2 with bursts on simulated walks (+0.9 %, +1.1 %): M1's sensitivity is
its missing drift correction, not the interpolant. The simplest fill stays.
"""

from __future__ import annotations

from typing import Self

import numpy as np

#: The longest run of missing samples that is interpolated; a longer one ends a walking bout (module notes).
MAX_INTERPOLATED_GAP_S = 0.1


def missing_runs(valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start (inclusive) and end (exclusive) indices of the runs of False in ``valid``.

    >>> s, e = missing_runs(np.array([1, 0, 0, 1, 0, 1], bool))
    >>> s.tolist(), e.tolist()
    ([1, 4], [3, 5])
    """
    v = np.asarray(valid, bool).astype(np.int8)
    edge = np.ones(1, np.int8)                                # int8 throughout: 1 byte a sample, not 8
    d = np.diff(np.concatenate((edge, v, edge)))
    return np.flatnonzero(d == -1), np.flatnonzero(d == 1)


class GapFiller:
    """Linear interpolation of the short runs of missing samples (module notes).

    Parameters
    ----------
    max_gap_s
        Longest run of missing samples filled, s (:data:`MAX_INTERPOLATED_GAP_S`; 0: nothing filled).

    Attributes
    ----------
    acc_, valid_
        The signal with the short gaps filled (NaN left in the long ones) and its validity mask.
    missing_fraction_
        Fraction of the samples missing in the input.
    longest_gap_s_
        The longest run of missing samples in the input, s (0 when none).
    n_filled_, n_left_missing_
        Samples interpolated, and samples left missing (in gaps longer than ``max_gap_s`` or at an end).

    Examples
    --------
    >>> x = np.array([0.0, np.nan, 2.0, 3.0, np.nan, np.nan, np.nan, 7.0])
    >>> g = GapFiller(max_gap_s=0.02).fill(x, np.isfinite(x), sampling_rate_hz=100.0)
    >>> g.acc_.tolist()[:4], int(g.n_filled_), int(g.n_left_missing_), round(g.longest_gap_s_, 2)
    ([0.0, 1.0, 2.0, 3.0], 1, 3, 0.03)
    """

    def __init__(self, *, max_gap_s: float = MAX_INTERPOLATED_GAP_S) -> None:
        self.max_gap_s = max_gap_s

    def fill(self, acc: np.ndarray, valid: np.ndarray, *, sampling_rate_hz: float) -> Self:
        """Fill the short gaps of ``acc`` (``(n,)`` or ``(n, k)``; ``valid``: ``(n,)`` measured samples)."""
        x = np.array(acc, np.float64)
        ok = np.asarray(valid, bool) & np.all(np.isfinite(x.reshape(x.shape[0], -1)), axis=1)
        start, end = missing_runs(ok)
        length = end - start
        n = ok.size
        short = (length <= int(round(self.max_gap_s * sampling_rate_hz))) & (start > 0) & (end < n)
        self.missing_fraction_ = float(np.count_nonzero(~ok) / n) if n else 0.0
        self.longest_gap_s_ = float(length.max() / sampling_rate_hz) if length.size else 0.0
        fill = np.zeros(n, bool)
        if np.any(short):       # mark the short runs: +1 at each start, -1 at each end, cumulated
            mark = np.zeros(n + 1, np.int64)
            np.add.at(mark, start[short], 1)
            np.add.at(mark, end[short], -1)
            fill = np.cumsum(mark[:n]) > 0
            idx = np.arange(n)
            cols = x.reshape(n, -1)
            for k in range(cols.shape[1]):
                cols[fill, k] = np.interp(idx[fill], idx[ok], cols[ok, k])
        self.acc_ = x
        self.valid_ = ok | fill
        self.n_filled_ = int(np.count_nonzero(fill))
        self.n_left_missing_ = int(np.count_nonzero(~self.valid_))
        return self
