"""Foot-flat, heel-strike and toe-off on the integer signals (mirrors ``host.gait.events``).

The definitions are the float chain's (``host.gait.events.GaitEventDetector``, notes 1-4), with the same
parameters; only the numbers differ: the signals are raw :data:`~firmware_sim.algorithms.formats.LOWPASS_OUT_Q`
integers (g, not m/s^2) from :mod:`~firmware_sim.algorithms.lowpass`, the prominence threshold is the
integer ``round(min_prominence_m_s2 / g0 · 2^16)``, the heel-strike impact band is the integer difference
of the 10 Hz and 5 Hz filter outputs, and the second-pass distance
``min_step_fraction · median`` is computed in integers (half up). Peak search, windows and bouts use only
comparisons and integer indices, so they are exact. Across stretches where the 3 Hz filter is undefined
the search curve is drawn straight by integer interpolation (truncating divide), as the float chain draws
it with ``numpy.interp``.

On the device
-------------
The peak search with ``scipy.signal.find_peaks`` (distance, prominence) and the median of the step
durations look at a whole recording: here the chain is run over a recording (as the firmware could after
logging, reading the samples back from the EEPROM). An on-line state machine (hysteresis peak detector)
would need the state listed in :func:`~firmware_sim.algorithms.formats.state_variables`, but it would define
the events differently from the float chain, so it is not what the comparison uses.
"""

from __future__ import annotations

from typing import Self

import numpy as np

from firmware_sim.algorithms.formats import LOWPASS_OUT_Q, STANDARD_GRAVITY_M_S2
from firmware_sim.algorithms.lowpass import masked_gaussian_lowpass_q
from firmware_sim.fixedpoint import ArithmeticContext


class FixedGaitEventDetector:
    """Detect foot-flat, heel-strike and toe-off in raw Q2.13 vertical acceleration (filters give Q2.16).

    Parameters
    ----------
    ff_cutoff_hz, detail_cutoff_hz, min_step_s, max_step_s, min_prominence_m_s2, hs_search_s, hs_after_s,
    to_search_s, max_gap_s, min_step_fraction, min_weight, impact_cutoff_hz, hs_delay_s
        As ``host.gait.events.GaitEventDetector`` (same defaults).

    Attributes
    ----------
    foot_flat_, heel_strike_, toe_off_, bout_, step_start_, step_end_, step_heel_strike_, step_toe_off_
        As the float detector.
    first_harmonic_q_, detail_q_
        Raw LOWPASS_OUT_Q 3 Hz and 10 Hz signals; ``first_harmonic_defined_``, ``detail_defined_`` their masks.
    """

    def __init__(
        self,
        *,
        ff_cutoff_hz: float = 3.0,
        detail_cutoff_hz: float = 10.0,
        min_step_s: float = 0.25,
        max_step_s: float = 1.5,
        min_prominence_m_s2: float = 0.5,
        hs_search_s: float = 0.2,
        hs_after_s: float = 0.06,
        to_search_s: float = 0.3,
        max_gap_s: float = 0.1,
        min_step_fraction: float = 0.6,
        min_weight: float = 0.25,
        impact_cutoff_hz: float = 5.0,
        hs_delay_s: float = 0.04,
    ) -> None:
        self.ff_cutoff_hz = ff_cutoff_hz
        self.detail_cutoff_hz = detail_cutoff_hz
        self.min_step_s = min_step_s
        self.max_step_s = max_step_s
        self.min_prominence_m_s2 = min_prominence_m_s2
        self.hs_search_s = hs_search_s
        self.hs_after_s = hs_after_s
        self.to_search_s = to_search_s
        self.max_gap_s = max_gap_s
        self.min_step_fraction = min_step_fraction
        self.min_weight = min_weight
        self.impact_cutoff_hz = impact_cutoff_hz
        self.hs_delay_s = hs_delay_s

    def detect(self, acc_v_q: np.ndarray, *, sampling_rate_hz: float, valid: np.ndarray | None = None,
               ctx: ArithmeticContext | None = None) -> Self:
        """Detect the events in raw ACC_Q vertical acceleration ``acc_v_q`` (``(n,)``, up positive)."""
        from scipy.signal import find_peaks

        fs = float(sampling_rate_hz)
        if not (np.isfinite(fs) and fs > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        a = np.asarray(acc_v_q, np.int64)
        if a.ndim != 1:
            raise ValueError(f"acc_v_q must be one-dimensional, got shape {a.shape}")
        n = a.size
        ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
        lp, fin = masked_gaussian_lowpass_q(a, ok, cutoff_hz=self.ff_cutoff_hz, sampling_rate_hz=fs,
                                            min_weight=self.min_weight, ctx=ctx)
        det, det_ok = masked_gaussian_lowpass_q(a, ok, cutoff_hz=self.detail_cutoff_hz, sampling_rate_hz=fs,
                                                min_weight=self.min_weight, ctx=ctx)
        self.first_harmonic_q_, self.first_harmonic_defined_ = lp, fin
        self.detail_q_, self.detail_defined_ = det, det_ok
        empty = np.zeros(0, np.int64)
        if n < 3 or not fin.any():
            for name, value in link_steps(empty, empty, empty, ok, sampling_rate_hz=fs, max_gap_s=self.max_gap_s,
                                          max_step_s=self.max_step_s).items():
                setattr(self, name, value)
            return self
        # 1. foot-flat: peaks of the 3 Hz signal (integer thresholds)
        lsb_per_g = 2 ** LOWPASS_OUT_Q.frac_bits
        prominence = int(np.floor(self.min_prominence_m_s2 / STANDARD_GRAVITY_M_S2 * lsb_per_g + 0.5))
        sig = lp if fin.all() else _integer_interp(lp, fin)
        dist0 = max(1, int(round(self.min_step_s * fs)))
        ff, _ = find_peaks(sig, distance=dist0, prominence=prominence)
        d = np.diff(ff)
        d = d[d <= self.max_step_s * fs]
        if d.size >= 3:
            # min_step_fraction * median, half up, in integers: median2 = 2 * median
            ds = np.sort(d)
            m = ds.size
            median2 = int(ds[m // 2]) * 2 if m % 2 else int(ds[m // 2 - 1]) + int(ds[m // 2])
            frac_num = int(round(self.min_step_fraction * 1000))          # a 3-digit constant
            dist2 = (frac_num * median2 + 1000) // 2000                      # round half up
            min_dist = max(dist0, dist2)
            ff, _ = find_peaks(sig, distance=max(1, min_dist), prominence=prominence)
            if ctx is not None:
                ctx.cost("mul16x16u", 1)
                ctx.cost("div32by16u", 1)
        ff = ff[fin[ff]] if ff.size else ff
        ff = ff.astype(np.int64)
        if ctx is not None:
            ctx.cost("compare16", 4 * n)        # peak search: neighbours, distance, prominence
        # 2./3. heel-strike (impact peak of the 5-10 Hz band, minus the delay) and toe-off
        low, low_ok = masked_gaussian_lowpass_q(a, ok, cutoff_hz=self.impact_cutoff_hz, sampling_rate_hz=fs,
                                                min_weight=self.min_weight, ctx=ctx)
        band = det - low
        impact = _search_argmax(band, det_ok & low_ok, ff, -int(round(self.hs_search_s * fs)),
                                int(round(self.hs_after_s * fs)))
        hs = impact - int(round(self.hs_delay_s * fs))
        hs = np.where((impact >= 0) & (hs >= 0), hs, -1).astype(np.int64)
        to = _first_local_min(det, det_ok, ff, int(round(self.to_search_s * fs)))
        if ctx is not None:
            ctx.cost("add16", n)
            ctx.cost("compare16", 3 * n)
        # 4. bouts and steps
        for name, value in link_steps(ff, hs, to, ok, sampling_rate_hz=fs, max_gap_s=self.max_gap_s,
                                      max_step_s=self.max_step_s).items():
            setattr(self, name, value)
        return self


def link_steps(ff: np.ndarray, hs: np.ndarray, to: np.ndarray, ok: np.ndarray, *, sampling_rate_hz: float,
               max_gap_s: float, max_step_s: float) -> dict[str, np.ndarray]:
    """Walking bouts and steps from per-foot-flat event indices (index bookkeeping, no arithmetic).

    Consecutive foot-flats ``ff`` form a step when they are at most ``max_step_s`` apart and no run of
    missing samples (``~ok``) between them is longer than ``max_gap_s``; otherwise a new bout starts. ``hs``
    and ``to`` are the heel-strike before and the toe-off after each foot-flat (``-1`` = none); a step's
    toe-off that does not precede its heel-strike is impossible and becomes ``-1``. Shared by the firmware's
    detector and the host's float detector (:class:`host.gait.events.GaitEventDetector`).

    Returns
    -------
    dict
        The detectors' result attributes: ``foot_flat_``, ``heel_strike_``, ``toe_off_``, ``bout_``,
        ``step_start_``, ``step_end_``, ``step_toe_off_``, ``step_heel_strike_``, ``step_bout_``.
    """
    if ff.size:
        interval_ok = np.diff(ff) <= max_step_s * sampling_rate_hz
        # longest run of missing samples between consecutive foot-flats
        worst = _between_max(_gap_lengths(ok), ff)
        link = interval_ok & (worst <= int(round(max_gap_s * sampling_rate_hz)))
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


def _integer_interp(x: np.ndarray, defined: np.ndarray) -> np.ndarray:
    """Straight integer lines across undefined stretches (ends held), truncating divide.

    >>> _integer_interp(np.array([0, 0, 0, 9, 0]), np.array([0, 1, 0, 1, 0], bool)).tolist()
    [0, 0, 4, 9, 9]
    """
    idx = np.flatnonzero(defined)
    n = x.size
    i = np.arange(n)
    right = np.searchsorted(idx, i)                 # first defined index >= i
    r = idx[np.clip(right, 0, idx.size - 1)]
    lft = idx[np.clip(right - 1, 0, idx.size - 1)]
    x0, x1 = x[lft], x[r]
    span = r - lft
    num = (x1 - x0) * (i - lft)
    step = np.where(span > 0, np.abs(num) // np.where(span > 0, span, 1) * np.sign(num), 0)
    out = np.where(right == 0, x[idx[0]], np.where(right >= idx.size, x[idx[-1]], x0 + step))
    return np.where(defined, x, out)


def _search_argmax(x: np.ndarray, ok: np.ndarray, centre: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """Index of the first maximum of ``x`` over defined samples in ``[c+lo, c+hi]`` (-1 if none)."""
    if centre.size == 0:
        return np.zeros(0, np.int64)
    offs = np.arange(lo, hi + 1)
    idx = centre[:, None] + offs[None, :]
    inside = (idx >= 0) & (idx < x.size)
    ci = np.clip(idx, 0, x.size - 1)
    usable = inside & ok[ci]
    floor = np.iinfo(np.int64).min
    vals = np.where(usable, x[ci], floor)
    j = np.argmax(vals, axis=1)
    rows = np.arange(centre.size)
    return np.where(usable[rows, j], idx[rows, j], -1).astype(np.int64)


def _first_local_min(x: np.ndarray, ok: np.ndarray, centre: np.ndarray, span: int) -> np.ndarray:
    """First local minimum (``x[j] < x[j-1]`` and ``x[j] <= x[j+1]``, all defined) in ``(c, c+span]``."""
    if centre.size == 0:
        return np.zeros(0, np.int64)
    offs = np.arange(0, span + 2)
    idx = centre[:, None] + offs[None, :]
    inside = idx < x.size
    ci = np.clip(idx, 0, x.size - 1)
    usable = inside & ok[ci]
    vals = x[ci]
    mid, left, right = vals[:, 1:-1], vals[:, :-2], vals[:, 2:]
    both = usable[:, 1:-1] & usable[:, :-2] & usable[:, 2:]
    is_min = both & (mid < left) & (mid <= right)
    has = is_min.any(axis=1)
    j = np.argmax(is_min, axis=1) + 1
    return np.where(has, idx[np.arange(centre.size), j], -1).astype(np.int64)


def _gap_lengths(ok: np.ndarray) -> np.ndarray:
    """For every sample, the length of the run of missing samples it belongs to (0 where measured)."""
    miss = ~ok
    if not miss.any():
        return np.zeros(ok.size, np.int64)
    d = np.diff(np.concatenate([[0], miss.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    paint = np.zeros(ok.size + 1, np.int64)
    np.add.at(paint, starts, ends - starts)
    np.add.at(paint, ends, -(ends - starts))
    return np.cumsum(paint)[:-1]


def _between_max(x: np.ndarray, marks: np.ndarray) -> np.ndarray:
    """``max(x[m_k:m_k+1])`` between consecutive strictly increasing ``marks``."""
    if marks.size < 2:
        return np.zeros(0, x.dtype)
    return np.maximum.reduceat(x[: marks[-1]], marks[:-1])
