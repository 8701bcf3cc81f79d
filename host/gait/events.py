"""Foot-flat, heel-strike and toe-off from lower-back vertical acceleration.

Notes
-----
1. *Foot-flat* (FF): the peaks of the first harmonic of the vertical acceleration (Gaussian low-pass,
   -3 dB at 3 Hz, the band Alvarez et al. use for M4). The CoM is lowest during double support, where the
   first harmonic of its vertical acceleration is highest and its vertical velocity is zero: the instant
   Alvarez et al. reset the integrals at ("foot-flat, where the vertical velocity of the body is null").
   Peaks must be ``min_step_s`` apart (cadence at most 240 steps/min) and stand out by the prominence of
   :mod:`gaitlog.firmware_sim.algorithms.parameters`: ``prominence_fraction`` of the walk's recent step amplitude,
   at least ``min_prominence_m_s2`` and at most ``max_prominence_m_s2``, the cap also before the first step
   (by default 0.25 and 0.5 m/s^2: a 1 cm CoM excursion at 1.6 steps/s already gives ~1.5 m/s^2 peak to
   trough, so brisk walking stays at the cap; slow 0.3 m steps rise 0.3-0.8 m/s^2 and get the floor). The
   amplitude follows the accepted peaks in time order, as the on-line algorithm's does. Only a peak above
   zero is a foot-flat, as in the on-line algorithm (version 2, :mod:`gaitlog.firmware_sim.algorithms.kernel` step
   5): in double support the centre of mass is accelerated upward; a peak at or below zero is a ripple of
   the single support. The minimum distance is applied to
   these candidates only (:func:`foot_flat_candidates`), the higher of two kept, as the on-line algorithm's
   pending foot-flat competes only with confirmed peaks; a second pass raises it to ``min_step_fraction``
   of the median step duration. (In on-line algorithm version 2 the distance came first, over every local
   maximum, as ``scipy.signal.find_peaks`` orders its rules: a weak bump 0.3 s before a step's foot-flat
   could then suppress it. IPOL trial 8-2: a 0.30 m/s^2 bump at 4.76 s suppressed the 0.60 m/s^2 peak at
   5.08 s that the on-line algorithm confirms.)
2. *Heel-strike* (HS): the impact. The loading impact of the leading leg reaches the lower back as a short
   upward peak (~20-40 ms wide) shortly after contact; the trailing leg's push-off makes a broader rise
   ~60-100 ms *before* contact, often the steeper of the two at 50 Hz. The impact is taken as the maximum of
   the vertical acceleration band-passed to ``impact_cutoff_hz``-``detail_cutoff_hz`` (difference of the
   10 Hz and 5 Hz Gaussian low-passes: the smooth centre-of-mass trough and the broad push-off are
   removed, a 20-40 ms peak is kept) within ``hs_search_s`` before to ``hs_after_s`` after the foot-flat,
   and the heel-strike ``hs_delay_s`` (40 ms) earlier. Measured with foot-sensor heel strikes (IPOL
   lower-back data, 43 trials at 50 Hz, 10 bits): the band-passed impact peak comes 30-80 ms after contact
   (subject medians, 50 ms over subjects); heel strikes within 40 ms F1 0.56 with the steepest rise of the
   10 Hz signal (Zijlstra & Hof, Gait Posture 18, 2003, put initial contact on that rising edge), 0.75
   with this rule. The delay is a population constant: it is where the rule's error comes from.
3. *Toe-off* (TO): the first local minimum of the vertical acceleration (10 Hz) within ``to_search_s``
   after the foot-flat: the unloading as the trailing foot leaves and single support begins.
4. Steps: consecutive foot-flats closer than ``max_step_s`` form a step (window ``[FF_k, FF_k+1]``,
   containing the toe-off after ``FF_k`` and the heel-strike before ``FF_k+1``). A longer interval, or a
   run of missing samples longer than ``max_gap_s``, ends a walking bout.
5. *Stop rule*: the step that brings the walker to a stop raises the first harmonic less than a walking
   step. After each foot-flat, the first peak ``stop_prominence_m_s2`` prominent between the minimum
   distance and three times it (about two typical steps) later is one more foot-flat when no foot-flat
   follows it within ``max_step_s`` (:func:`stop_steps`; the on-line algorithm's weak pending foot-flat,
   :mod:`gaitlog.firmware_sim.algorithms.kernel` step 5).

All indices are sample indices of the input. Samples marked invalid are never used (the filters are
normalised convolutions over measured samples only).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Self

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import (
    EventParameters,
    amplitude_update,
    minimum_distance,
    prominence_threshold,
    samples,
)
from gaitlog.firmware_sim.algorithms.steps import nan_median
from gaitlog.host.gait.gaps import MAX_INTERPOLATED_GAP_S, missing_runs
from gaitlog.host.gait.masked_filter import masked_gaussian_lowpass
from gaitlog.host.gait.peaks import find_peaks, keep_by_distance


class GaitEventDetector:
    """Detect foot-flat, heel-strike and toe-off in vertical trunk acceleration (the offline chain).

    Every duration becomes a whole number of samples by the one rounding rule of both chains
    (:func:`gaitlog.firmware_sim.algorithms.parameters.samples`, half up), and the second pass's distance is the
    shared integer rule (:func:`gaitlog.firmware_sim.algorithms.parameters.minimum_distance`).

    Parameters
    ----------
    parameters
        The rules shared with the firmware's on-line algorithm
        (:class:`gaitlog.firmware_sim.algorithms.parameters.EventParameters`: cut-offs, step limits, prominence,
        search windows, heel-strike delay, the second pass's fraction of the median step).
    max_gap_s
        Longest run of missing samples a step may contain (0.1 s); longer gaps split bouts.
    min_weight
        Normalised convolution: fraction of the Gaussian kernel's weight that must fall on measured
        samples for the filtered value to exist (0.25; the 3 Hz kernel spans ~±0.17 s, so a filtered value
        still rests on several measured samples of the same step phase).

    Attributes
    ----------
    foot_flat_, heel_strike_, toe_off_
        ``(m,)`` int sample indices, one per detected foot-flat (``-1`` where HS/TO was not found).
    step_start_, step_end_
        ``(k,)`` foot-flat indices delimiting each step.
    step_heel_strike_, step_toe_off_
        ``(k,)`` the HS before ``step_end_`` and the TO after ``step_start_`` of each step (``-1`` if none).
    bout_
        ``(m,)`` bout number of each foot-flat.
    """

    def __init__(self, parameters: EventParameters | None = None, *, max_gap_s: float = MAX_INTERPOLATED_GAP_S,
                 min_weight: float = 0.25) -> None:
        self.parameters = parameters if parameters is not None else EventParameters()
        self.max_gap_s = max_gap_s
        self.min_weight = min_weight

    def clone(self) -> GaitEventDetector:
        """A detector with the same settings and no results."""
        return GaitEventDetector(self.parameters, max_gap_s=self.max_gap_s, min_weight=self.min_weight)

    def detect(self, acc_v_m_s2: np.ndarray, *, sampling_rate_hz: float, valid: np.ndarray | None = None) -> Self:
        """Detect the events in ``acc_v_m_s2`` (``(n,)``, up positive, gravity removed)."""
        sampling_rate_hz = float(sampling_rate_hz)
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        a = np.asarray(acc_v_m_s2, dtype=np.float64)
        if a.ndim != 1:
            raise ValueError(f"acc_v_m_s2 must be one-dimensional, got shape {a.shape}")
        p = self.parameters
        ok = np.isfinite(a) if valid is None else (np.asarray(valid, bool) & np.isfinite(a))
        n = a.size
        self.first_harmonic_m_s2_ = lp = masked_gaussian_lowpass(
            a, ok, cutoff_hz=p.ff_cutoff_hz, sampling_rate_hz=sampling_rate_hz, min_weight=self.min_weight)
        det = masked_gaussian_lowpass(a, ok, cutoff_hz=p.detail_cutoff_hz, sampling_rate_hz=sampling_rate_hz,
                                      min_weight=self.min_weight)
        empty = np.zeros(0, dtype=np.int64)
        if n < 3 or not np.any(np.isfinite(lp)):
            for name, value in link_steps(empty, empty, empty, ok, sampling_rate_hz=sampling_rate_hz, max_gap_s=self.max_gap_s,
                                          max_step_s=p.max_step_s).items():
                setattr(self, name, value)
            return self
        # 1. foot-flat = first-harmonic peaks (NaN stretches cannot hold a peak)
        # the peak search needs a continuous curve: across stretches where the filter has too little
        # measured data the curve is drawn straight (for the search only), and no peak may lie there
        fin = np.isfinite(lp)
        sig = lp
        if not fin.all():
            sig = lp.copy()
            sig[~fin] = np.interp(np.flatnonzero(~fin), np.flatnonzero(fin), lp[fin])
        ff = curve_foot_flats(sig, None, lambda i: fin[i], p, sampling_rate_hz)
        # 2./3. heel-strike and toe-off around each foot-flat (vectorised over fixed-size windows)
        band = det - masked_gaussian_lowpass(a, ok, cutoff_hz=p.impact_cutoff_hz, sampling_rate_hz=sampling_rate_hz,
                                             min_weight=self.min_weight)
        hs, to = heel_strikes_toe_offs(det, band, ff, p, sampling_rate_hz)
        # 4. bouts and steps
        for name, value in link_steps(ff, hs, to, ok, sampling_rate_hz=sampling_rate_hz, max_gap_s=self.max_gap_s,
                                      max_step_s=p.max_step_s).items():
            setattr(self, name, value)
        return self

    @staticmethod
    def _search(x: np.ndarray, centre: np.ndarray, lo: int, hi: int, *, mode: str) -> np.ndarray:
        """Index of the max of ``x`` in ``[c+lo, c+hi]`` for every centre (NaN ignored, -1 if none)."""
        if centre.size == 0:
            return np.zeros(0, np.int64)
        offs = np.arange(lo, hi + 1)
        idx = centre[:, None] + offs[None, :]
        inside = (idx >= 0) & (idx < x.size)
        vals = np.where(inside, x[np.clip(idx, 0, x.size - 1)], np.nan)
        vals = np.where(np.isfinite(vals), vals, -np.inf)
        j = np.argmax(vals, axis=1)
        found = np.isfinite(vals[np.arange(centre.size), j])
        return np.where(found, idx[np.arange(centre.size), j], -1).astype(np.int64)

    @staticmethod
    def _first_local_min(x: np.ndarray, centre: np.ndarray, span: int) -> np.ndarray:
        """First local minimum of ``x`` in ``(c, c+span]`` for every centre (-1 if none)."""
        if centre.size == 0:
            return np.zeros(0, np.int64)
        offs = np.arange(0, span + 2)
        idx = centre[:, None] + offs[None, :]
        inside = idx < x.size
        vals = np.where(inside, x[np.clip(idx, 0, x.size - 1)], np.nan)
        mid = vals[:, 1:-1]
        is_min = (mid < vals[:, :-2]) & (mid <= vals[:, 2:])
        has = is_min.any(axis=1)
        j = np.argmax(is_min, axis=1) + 1
        return np.where(has, idx[np.arange(centre.size), j], -1).astype(np.int64)


def heel_strikes_toe_offs(det: np.ndarray, band: np.ndarray, ff: np.ndarray, parameters: EventParameters,
                          sampling_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The heel-strike before and the toe-off after each foot-flat ``ff`` (module notes 2 and 3; ``-1``: none) from
    the 10 Hz signal ``det`` and the impact band ``band``, arrays that hold every sample of the searched windows
    (or end where the recording does)."""
    p = parameters
    impact = GaitEventDetector._search(band, ff, -samples(p.hs_search_s, sampling_rate_hz),
                                       samples(p.hs_after_s, sampling_rate_hz), mode="argmax")
    hs = impact - samples(p.hs_delay_s, sampling_rate_hz)
    hs = np.where((impact >= 0) & (hs >= 0), hs, -1).astype(np.int64)
    to = GaitEventDetector._first_local_min(det, ff, samples(p.to_search_s, sampling_rate_hz))
    return hs, to


def foot_flat_candidates(sig: np.ndarray, parameters: EventParameters) -> np.ndarray:
    """The peaks of ``sig`` (the first harmonic, m/s^2) that may be foot-flats (module notes 1): prominent by
    the threshold in force, ``min(cap, max(floor, fraction · A))``, the cap before the first accepted peak
    (:func:`gaitlog.firmware_sim.algorithms.parameters.prominence_threshold`), and above zero. The minimum distance
    is applied to these candidates only, as the on-line algorithm lets only confirmed peaks compete: a
    nearby local maximum too weak to be a foot-flat cannot suppress one that is.

    ``A`` follows the peaks in time order as the on-line algorithm's hysteresis does: a peak (every local
    maximum at least ``min_prominence_m_s2`` prominent, no distance rule) is accepted when its prominence
    reaches the threshold in force, and then updates ``A`` with its rise from the lowest point since the
    previous accepted peak (:func:`gaitlog.firmware_sim.algorithms.parameters.amplitude_update`). A loop over the
    peaks, not the samples.

    Returns
    -------
    numpy.ndarray
        Increasing sample indices.
    """
    floor, cap, fraction = (parameters.min_prominence_m_s2, parameters.max_prominence_m_s2,
                            parameters.prominence_fraction)
    cand, prom = find_peaks(sig, prominence=floor, with_prominences=True)
    if cap <= floor:                            # a fixed threshold
        accepted = prom >= cap
    else:
        accepted = np.zeros(cand.size, bool)
        # the lowest sample from each candidate's predecessor (the start for the first) to it, both included: the
        # lowest since the last accepted peak is the lowest of these since it (NaN as numpy's min: sticky)
        lows = (np.minimum(np.minimum.reduceat(sig[:cand[-1] + 1], np.r_[0, cand[:-1]]), sig[cand]).tolist()
                if cand.size else [])
        amp, have, low = 0.0, False, float("inf")
        for i, (h, pq, lo) in enumerate(zip(sig[cand].tolist(), prom.tolist(), lows)):
            if lo < low or lo != lo:
                low = lo
            if pq >= prominence_threshold(amp, have, floor, cap, fraction):
                accepted[i] = True
                amp = amplitude_update(amp, h - low, not have, parameters.amplitude_shift)
                have, low = True, float("inf")
    return cand[accepted & (sig[cand] > 0)].astype(np.int64)


def curve_foot_flats(sig: np.ndarray, index: np.ndarray | None, finite: Callable[[np.ndarray], np.ndarray],
                     parameters: EventParameters, sampling_rate_hz: float) -> np.ndarray:
    """The foot-flats (module notes 1 and 5) of the first harmonic drawn without gaps, ``sig``.

    ``sig`` is either the whole curve (``index`` None) or its turning points only: the value of every maximal run
    of equal samples that is higher, or lower, than both neighbouring runs (the first and last runs included),
    ``index`` holding the sample index of each run's middle (:class:`gaitlog.host.gait.streaming.TurningPoints`).
    Peaks, prominences and the minima between peaks are the same on both, so the foot-flats are too.
    ``finite(i)`` says where the filtered curve itself exists (no foot-flat elsewhere). Returns sample indices.
    """
    p = parameters

    def at(j: np.ndarray) -> np.ndarray:
        return j if index is None else index[j]

    dist0 = max(1, samples(p.min_step_s, sampling_rate_hz))
    found = foot_flat_candidates(sig, p)
    candidates, height = at(found), sig[found]

    def foot_flats(distance: int) -> np.ndarray:
        """The candidates ``distance`` apart, the higher kept (notes 1)."""
        return candidates[keep_by_distance(candidates, height, distance)]

    ff = foot_flats(dist0)
    # second pass: a step cannot be much shorter than the typical step of the recording (cadence
    # changes slowly); peaks closer than ``min_step_fraction`` of the median step are not steps
    d = np.diff(ff)
    d = d[d <= samples(p.max_step_s, sampling_rate_hz)]
    dist = dist0
    if d.size >= 3:
        dist = minimum_distance(int(round(2 * nan_median(d))), dist0, p.min_step_fraction_scaled)
        ff = foot_flats(dist)
    ff = ff[finite(ff)] if ff.size else ff
    ff = ff.astype(np.int64)
    if p.stop_prominence_m_s2 > 0 and ff.size:
        q = at(find_peaks(sig, prominence=p.stop_prominence_m_s2))
        q = q[finite(q)] if q.size else q
        ff = stop_steps(q, ff, dist=dist, max_step=samples(p.max_step_s, sampling_rate_hz))
    return ff


def stop_steps(cand: np.ndarray, ff: np.ndarray, *, dist: int, max_step: int) -> np.ndarray:
    """The foot-flats ``ff`` with each walking bout's weak last step added (module notes 5, the stop rule).

    ``cand``: the peaks of the first harmonic at least the stop rule's prominence prominent, where it exists.
    After a foot-flat ``f`` (``ff`` holds full-prominence foot-flats only), the first peak ``q`` of ``cand``
    with ``f + dist <= q <= f + min(3 dist, max_step)`` (within about two
    typical steps: ``dist`` is 0.6 of the typical step) is the step that brings the walker to a stop when no
    foot-flat of ``ff`` follows within ``max_step`` after ``q`` (so ``f`` ended a bout, and ``q`` ends it).
    At most one such step per bout end.
    """
    if cand.size == 0 or ff.size == 0:
        return ff
    j = np.searchsorted(cand, ff + dist)
    q = cand[np.minimum(j, cand.size - 1)]
    nxt = np.r_[ff[1:], np.iinfo(np.int64).max]
    stop = (j < cand.size) & (q <= ff + min(max_step, 3 * dist)) & (nxt - q > max_step)
    return np.union1d(ff, q[stop]).astype(np.int64) if stop.any() else ff


def warn_if_no_steps(detector: GaitEventDetector) -> None:
    """Warn when a detection found no complete step."""
    if detector.step_start_.size == 0:
        warnings.warn("no walking steps detected (no two foot-flats within max_step_s)", stacklevel=3)


def link_steps(ff: np.ndarray, hs: np.ndarray, to: np.ndarray, ok: np.ndarray | tuple[np.ndarray, np.ndarray], *,
               sampling_rate_hz: float, max_gap_s: float, max_step_s: float) -> dict[str, np.ndarray]:
    """Walking bouts and steps from per-foot-flat event indices (index bookkeeping, no arithmetic).

    Consecutive foot-flats ``ff`` form a step when they are at most ``max_step_s`` apart and no run of
    missing samples (``~ok``; or ``ok`` is the ``(starts, ends)`` of those runs,
    :func:`gaitlog.host.gait.gaps.missing_runs`) between them is longer than ``max_gap_s``; otherwise a new bout starts. ``hs``
    and ``to`` are the heel-strike before and the toe-off after each foot-flat (``-1`` = none); a step's
    toe-off that does not precede its heel-strike is impossible and becomes ``-1``. (The on-line
    algorithm links its steps as it finds them, :mod:`gaitlog.firmware_sim.algorithms.kernel`.)

    Returns
    -------
    dict
        The detectors' result attributes: ``foot_flat_``, ``heel_strike_``, ``toe_off_``, ``bout_``,
        ``step_start_``, ``step_end_``, ``step_toe_off_``, ``step_heel_strike_``, ``step_bout_``.
    """
    if ff.size:
        interval_ok = np.diff(ff) <= max_step_s * sampling_rate_hz
        # no run of missing samples longer than max_gap_s touches [ff_k, ff_k+1)
        starts, ends = ok if isinstance(ok, tuple) else missing_runs(ok)
        long_ = ends - starts > int(round(max_gap_s * sampling_rate_hz))
        starts, ends = starts[long_], ends[long_]
        j = np.searchsorted(ends, ff[:-1], side="right")     # the first long run ending after ff_k
        crossed = (j < ends.size) & (starts[np.minimum(j, max(ends.size - 1, 0))] < ff[1:]) if ends.size else \
            np.zeros(ff.size - 1, bool)
        link = interval_ok & ~crossed
        bout = np.concatenate([[0], np.cumsum(~link)])
    else:
        link = np.zeros(0, bool)
        bout = np.zeros(0, np.int64)
    k = np.flatnonzero(link)
    step_toe_off = to[k]
    step_heel_strike = hs[k + 1]
    bad = (step_toe_off >= 0) & (step_heel_strike >= 0) & (step_toe_off >= step_heel_strike)
    return {"foot_flat_": ff, "heel_strike_": hs, "toe_off_": to, "bout_": bout, "step_start_": ff[k],
            "step_end_": ff[k + 1], "step_toe_off_": np.where(bad, -1, step_toe_off),
            "step_heel_strike_": step_heel_strike, "step_bout_": bout[k] if k.size else np.zeros(0, np.int64)}
