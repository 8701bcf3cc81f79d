"""Rest detection: find the static holds of a calibration session in a 3-axis recording.

A calibration session (Krohn et al. 2005 [1]_, Ferraris et al. 1995) is a sequence of holds, the device at
rest in a different orientation each time, separated by hand-held transitions. During a hold the
accelerometer reads gravity plus sensor noise only; this module finds those holds automatically.

Method (numbered steps are referred to in the code):

1. Moving standard deviation of every axis over a window of ``hold_s`` seconds (``w`` samples), by cumulative
   sums, for every window start ``k``: ``sd[k, j] = std(x[k:k + w, j])``. Windows holding a NaN (a gap of a
   decoded recording) are never static.
2. Noise floor per axis, estimated from the data: the ``floor_percentile``-th percentile of the non-zero
   moving SDs. With ``w`` samples of Gaussian noise the moving SD scatters by ``sigma / sqrt(2 (w - 1))``
   (5.7 % at 150 samples), so for a session that is static at least ``floor_percentile`` % of the time the
   floor sits within ~10 % of the sensor noise ``sigma``.
3. Threshold per axis ``sd_factor * sqrt(floor**2 + (q / 2)**2)`` with ``q`` the code step of that axis
   (smallest non-zero difference between distinct values; 0 for continuous data). Quantised holds have an
   SD anywhere between ~0 and ``q / 2`` depending on where the level falls within a code, so a bare
   ``1.3 x floor`` would reject good holds of a 10-bit logger.
4. A window is quiet when every axis is below its threshold; consecutive quiet windows merge into one
   candidate segment ``[k0, k1 + w)``. A few slowly moving samples at the ends barely raise a 3 s SD, so the
   ends are then cut back to where the 0.2 s running mean stays within ``4 sigma / sqrt(m) + q / 2`` of the
   mean of the segment's middle half (``m`` samples in 0.2 s); a segment left shorter than 0.9 ``hold_s`` is rejected. ``trim_s``
   is cut from both ends before the mean is taken.
5. Candidates are rejected, with the reason kept in ``rejected_``, when an axis is exactly constant (SD = 0:
   a stuck or sleeping sensor, or a saturated axis), when the orientation drifts by more than
   ``min_angle_deg / 2`` between the first and the last ``hold_s`` of the segment, when ``|mean| >=
   max_norm_g`` (in nominal g), and when the orientation lies within ``min_angle_deg`` of a longer hold already
   accepted (near-duplicate orientations add no information and would overweight one direction).

References
----------
.. [1] A. Krohn, M. Beigl, C. Decker, U. Kochendörfer, P. Robinson, T. Zimmer, "Inexpensive and automatic
   calibration for acceleration sensors", Ubiquitous Computing Systems (UCS 2004), LNCS 3598, Springer 2005,
   pp. 245-258.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Self

import numpy as np

from gaitlog.host.errors import HostError


class StaticWindowError(HostError, ValueError):
    """The recording cannot be searched for static windows (wrong shape, rate, window longer than data)."""


@dataclass(frozen=True, eq=False)
class StaticWindow:
    """One static hold.

    Attributes
    ----------
    start, stop
        Sample indices: the hold is ``x[start:stop]`` (``stop`` exclusive), after trimming.
    mean
        ``(3,)`` mean of the hold, in the unit of the input.
    sd
        ``(3,)`` standard deviation of every axis over the hold, in the unit of the input.
    """

    start: int
    stop: int
    mean: np.ndarray
    sd: np.ndarray

    @property
    def n_samples(self) -> int:
        """Number of samples averaged in ``mean``."""
        return self.stop - self.start


def _prefix_sums(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Prefix sums of a centred copy of ``x`` (NaN rows as 0), of its squares and of the NaN rows.

    Returns ``(s1 (n+1, 3), s2 (n+1, 3), bad (n+1,), centre (3,), finite (n,))``; the sum of ``x[a:b] - centre``
    is ``s1[b] - s1[a]``.
    """
    finite = np.isfinite(x).all(axis=1)
    centre = x[int(np.argmax(finite))].copy() if finite.any() else np.zeros(x.shape[1])
    xc = np.where(finite[:, None], x - centre, 0.0)  # centring keeps the sums of squares small
    zero = np.zeros((1, x.shape[1]))
    s1 = np.concatenate([zero, np.cumsum(xc, axis=0)])
    s2 = np.concatenate([zero, np.cumsum(xc * xc, axis=0)])
    bad = np.concatenate([[0], np.cumsum(~finite)])
    return s1, s2, bad, centre, finite


def _moving_sd_from(s1: np.ndarray, s2: np.ndarray, bad: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Step 1: moving SD (ddof 1) of every column over windows ``x[k:k + w]`` from the prefix sums, and whether
    each window is NaN-free: ``(sd (n - w + 1, 3), ok (n - w + 1,))``; ``sd`` is 0 where not ``ok``."""
    m1 = (s1[w:] - s1[:-w]) / w
    var = (s2[w:] - s2[:-w]) / w - m1 * m1
    var = np.maximum(var, 0.0) * (w / max(w - 1, 1))
    ok = (bad[w:] - bad[:-w]) == 0
    return np.where(ok[:, None], np.sqrt(var), 0.0), ok


def _segment_stats(s1: np.ndarray, s2: np.ndarray, changes: np.ndarray, centre: np.ndarray, a: np.ndarray,
                   b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means and SDs (ddof 1; exactly 0 for a constant axis) of the segments ``x[a[i]:b[i]]``, ``(len(a), 3)``."""
    n = np.maximum(b - a, 1)[:, None].astype(np.float64)
    m1 = (s1[b] - s1[a]) / n
    var = np.maximum((s2[b] - s2[a]) / n - m1 * m1, 0.0) * n / np.maximum(n - 1, 1)
    moved = (changes[np.maximum(b - 1, a)] - changes[a]) > 0
    return m1 + centre, np.where(moved, np.sqrt(var), 0.0)


def _code_step(col: np.ndarray, max_values: int = 20000) -> float:
    """Smallest non-zero difference between distinct finite values of ``col`` (0 for continuous data)."""
    v = col[np.isfinite(col)]
    if v.size > max_values:
        v = v[:: v.size // max_values + 1]
    u = np.unique(v)
    if u.size < 2:
        return 0.0
    step = float(np.diff(u).min())
    # continuous (float) data: the smallest gap is far below the spread of the values
    return step if step > 1e-9 * max(float(np.ptp(u)), 1e-300) * 1e3 else 0.0


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(first, last), ...]`` inclusive index ranges of the True runs of ``mask``."""
    if not mask.any():
        return []
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1) - 1
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _angle_deg(u: np.ndarray, v: np.ndarray) -> float:
    c = float(np.clip(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)), -1.0, 1.0))
    return float(np.degrees(np.arccos(c)))


class StaticWindowDetector:
    """Find the static holds of a recording (steps 1-5 of the module docstring).

    Parameters
    ----------
    hold_s
        Minimum hold, seconds; also the length of the moving-SD window.
    sd_factor
        Threshold on the moving SD as a multiple of the noise floor (step 3).
    floor_percentile
        Percentile of the moving SDs taken as the noise floor (step 2).
    max_norm_g
        Holds whose mean, in nominal g, has a norm at or above this are rejected.
    min_angle_deg
        Holds closer than this to a longer accepted hold are near-duplicates and rejected.
    trim_s
        Seconds cut from each end of a segment before its mean is taken.
    """

    def __init__(self, *, hold_s: float = 3.0, sd_factor: float = 1.3, floor_percentile: float = 10.0,
                 max_norm_g: float = 2.0, min_angle_deg: float = 10.0, trim_s: float = 0.25) -> None:
        self.hold_s = hold_s
        self.sd_factor = sd_factor
        self.floor_percentile = floor_percentile
        self.max_norm_g = max_norm_g
        self.min_angle_deg = min_angle_deg
        self.trim_s = trim_s

    def detect(self, acc: np.ndarray, *, sampling_rate_hz: float, zero: np.ndarray | None = None,
               unit_per_g: float | np.ndarray | None = 1.0) -> Self:
        """Find the static holds of ``acc``.

        Parameters
        ----------
        acc
            ``(n, 3)`` samples in any linear unit (counts, g); NaN marks missing samples.
        sampling_rate_hz
            Sampling rate, Hz.
        zero, unit_per_g
            Scalars or ``(3,)``. Nominal map to g used only for the ``max_norm_g`` test and the orientation angles:
            ``g ~ (acc - zero) / unit_per_g``. ``zero`` defaults to 0; ``unit_per_g=None`` estimates both from
            the candidate segments (centre of the per-axis extremes, median radius), which needs holds on
            both sides of every axis.

        Returns
        -------
        self
            With ``windows_`` (list of :class:`StaticWindow`, in time order), ``rejected_`` (list of
            ``(StaticWindow, reason)``), ``noise_floor_`` and ``threshold_`` (``(3,)``, input unit),
            ``code_step_`` (``(3,)``, input unit, 0 for continuous data) and ``window_samples_``.

        Examples
        --------
        >>> rng = np.random.default_rng(0)
        >>> holds = [np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, -1.0, 0])]
        >>> parts = []
        >>> for g in holds:
        ...     parts += [g + 0.001 * rng.standard_normal((250, 3)), rng.uniform(-1, 1, (50, 3))]
        >>> det = StaticWindowDetector(hold_s=3.0).detect(np.vstack(parts), sampling_rate_hz=50.0)
        >>> [(w.start, w.stop) for w in det.windows_]
        [(12, 238), (312, 538), (612, 838)]
        >>> np.round(det.windows_[2].mean, 2) + 0.0
        array([ 0., -1.,  0.])
        """
        x = self._checked_input(acc, sampling_rate_hz)
        w = int(round(self.hold_s * sampling_rate_hz))
        if w < 2:
            raise StaticWindowError(f"hold of {self.hold_s} s at {sampling_rate_hz} Hz is under 2 samples")
        self.window_samples_ = w
        self.windows_: list[StaticWindow] = []
        self.rejected_: list[tuple[StaticWindow, str]] = []
        self.noise_floor_ = np.full(3, np.nan)
        self.threshold_ = np.full(3, np.nan)
        self.code_step_ = np.array([_code_step(x[:, j]) for j in range(3)])
        if x.shape[0] < w:
            return self
        s1, s2, bad, centre, _ = _prefix_sums(x)
        sd, ok = _moving_sd_from(s1, s2, bad, w)  # step 1
        if not ok.any():
            return self
        self.noise_floor_, self.threshold_ = self._noise_threshold(sd, ok)  # steps 2-3
        quiet = ok & (sd <= self.threshold_).all(axis=1)  # step 4
        runs = np.array(_runs(quiet), dtype=np.int64).reshape(-1, 2)
        if not len(runs):
            return self
        cand = self._candidates(x, s1, s2, centre, runs, sampling_rate_hz)
        self.zero_, self.unit_per_g_ = self._nominal_map(cand, zero, unit_per_g)
        kept = self._screen(cand, sampling_rate_hz)  # step 5
        self.windows_ = self._without_near_duplicates(kept)
        self.rejected_.sort(key=lambda r: r[0].start)
        return self

    @staticmethod
    def _checked_input(acc: np.ndarray, sampling_rate_hz: float) -> np.ndarray:
        """``acc`` as a float ``(n, 3)`` array; :class:`StaticWindowError` on a wrong shape or rate."""
        x = np.asarray(acc, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise StaticWindowError(f"acceleration must have shape (n, 3), got {x.shape}")
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise StaticWindowError(f"sampling rate must be a positive number of Hz, got {sampling_rate_hz!r}")
        return x

    def _noise_threshold(self, sd: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Steps 2-3: the noise floor per axis and the quiet threshold (input unit)."""
        floor = np.empty(3)
        for j in range(3):  # step 2
            s = sd[ok, j]
            s = s[s > 0]
            floor[j] = np.percentile(s, self.floor_percentile) if s.size else 0.0
        thr = self.sd_factor * np.sqrt(floor**2 + (self.code_step_ / 2) ** 2)  # step 3
        return floor, thr

    def _candidates(self, x: np.ndarray, s1: np.ndarray, s2: np.ndarray, centre: np.ndarray, runs: np.ndarray,
                    sampling_rate_hz: float) -> _Candidates:
        """Step 4: the quiet runs as candidate holds, ends refined and trimmed, with their statistics."""
        w, floor = self.window_samples_, self.noise_floor_
        k0, k1 = runs[:, 0], runs[:, 1]
        m = max(1, int(round(0.2 * sampling_rate_hz)))
        edge_tol = 4.0 * np.sqrt(floor**2 + self.code_step_**2 / 12) / np.sqrt(m) + self.code_step_ / 2
        a, b = _edge_refine(s1, k0, k1 + w, m, edge_tol)
        changes = np.concatenate([np.zeros((1, 3), np.int64),
                                  np.cumsum(np.diff(np.nan_to_num(x), axis=0) != 0, axis=0)])
        short = (b - a) < 0.9 * w
        trim = int(round(self.trim_s * sampling_rate_hz))
        can_trim = (b - a - 2 * trim) >= 2
        a = np.where(can_trim & ~short, a + trim, a)
        b = np.where(can_trim & ~short, b - trim, b)
        sa, sb = np.where(b - a >= 2, a, k0), np.where(b - a >= 2, b, k1 + w)
        means, sds = _segment_stats(s1, s2, changes, centre, sa, sb)
        first = (s1[k0 + w] - s1[k0]) / w + centre
        last = (s1[k1 + w] - s1[k1]) / w + centre
        wins = [StaticWindow(int(a[i]), int(b[i]), means[i], sds[i]) for i in range(len(a))]
        return _Candidates(wins, means, short, first, last)

    @staticmethod
    def _nominal_map(cand: _Candidates, zero: np.ndarray | None,
                     unit_per_g: float | np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``(zero, unit_per_g)``, ``(3,)`` each: as given, or a crude sphere through the candidates."""
        means, short = cand.means, cand.short
        if zero is None:
            zero_v = np.zeros(3)
        else:
            zero_v = np.broadcast_to(np.asarray(zero, dtype=np.float64), (3,)).copy()
        if unit_per_g is None:  # crude sphere through the candidates
            cm = means[~short] if (~short).any() else means
            zero_v = 0.5 * (cm.max(axis=0) + cm.min(axis=0))
            radius = float(np.median(np.linalg.norm(cm - zero_v, axis=1)))
            per_g = np.full(3, radius if radius > 0 else 1.0)
        else:
            per_g = np.broadcast_to(np.asarray(unit_per_g, dtype=np.float64), (3,)).copy()
        return zero_v, per_g

    def _screen(self, cand: _Candidates, sampling_rate_hz: float) -> list[tuple[StaticWindow, np.ndarray]]:
        """Step 5, one hold at a time: reject (into ``rejected_``) or keep with its unit direction."""
        zero_v, per_g = self.zero_, self.unit_per_g_
        nominal = (cand.means - zero_v) / per_g
        norms = np.linalg.norm(nominal, axis=1)
        f0, f1 = cand.first - zero_v, cand.last - zero_v
        cosd = np.einsum("ij,ij->i", f0, f1) / np.maximum(np.linalg.norm(f0, axis=1) * np.linalg.norm(f1, axis=1),
                                                          1e-300)
        drift = np.degrees(np.arccos(np.clip(cosd, -1.0, 1.0)))
        kept = []
        for i, win in enumerate(cand.windows):
            const = np.flatnonzero(win.sd == 0)
            if cand.short[i]:
                self.rejected_.append((win, f"only {win.n_samples / sampling_rate_hz:.2f} s still after removing "
                                            "the moving ends"))
            elif const.size:
                names = ", ".join("xyz"[j] for j in const)
                self.rejected_.append((win, f"constant (SD = 0) on axis {names}: stuck, sleeping or saturated"))
            elif norms[i] >= self.max_norm_g:
                self.rejected_.append((win, f"|mean| = {norms[i]:.2f} g is not below {self.max_norm_g} g"))
            elif norms[i] == 0:
                self.rejected_.append((win, "|mean| = 0: no direction"))
            elif drift[i] > self.min_angle_deg / 2:
                self.rejected_.append((win, f"orientation drifts by {drift[i]:.1f} deg during the hold"))
            else:
                kept.append((win, nominal[i] / norms[i]))
        return kept

    def _without_near_duplicates(self, kept: list[tuple[StaticWindow, np.ndarray]]) -> list[StaticWindow]:
        """Step 5, across holds: longest first, a hold within ``min_angle_deg`` of an accepted one is rejected;
        the accepted holds in time order."""
        order = sorted(range(len(kept)), key=lambda i: -kept[i][0].n_samples)
        accepted: list[tuple[StaticWindow, np.ndarray]] = []
        cos_limit = np.cos(np.radians(self.min_angle_deg))
        for i in order:
            win, u = kept[i]
            dup = next((a for a in accepted if float(np.dot(a[1], u)) > cos_limit), None)
            if dup is None:
                accepted.append((win, u))
            else:
                ang = _angle_deg(u, dup[1])
                self.rejected_.append((win, f"near-duplicate orientation: {ang:.1f} deg from the hold at "
                                            f"samples {dup[0].start}-{dup[0].stop}"))
        return sorted((a[0] for a in accepted), key=lambda s: s.start)


@dataclass(frozen=True, eq=False)
class _Candidates:
    """Candidate holds of step 4 (``short``: left under 0.9 ``hold_s`` by the end refinement), with the mean of
    their first and last ``hold_s`` (the drift test of step 5), ``(n, 3)`` input unit."""

    windows: list[StaticWindow]
    means: np.ndarray
    short: np.ndarray
    first: np.ndarray
    last: np.ndarray


def _edge_refine(s1: np.ndarray, a: np.ndarray, b: np.ndarray, m: int,
                 tol: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step 4 (ends): cut each segment ``[a, b)`` back to where its ``m``-sample running mean stays within
    ``tol`` (``(3,)``) of the mean of the segment's middle half. All segments at once, from the prefix sums
    ``s1`` of :func:`_prefix_sums`; returns the new ``(a, b)`` (``a == b`` where nothing is still)."""
    length = b - a
    q = length // 4
    ref = (s1[b - q] - s1[a + q]) / np.maximum(length - 2 * q, 1)[:, None]
    n_pos = np.maximum(length - m + 1, 0)  # running-mean positions a .. b - m
    offsets = np.concatenate([[0], np.cumsum(n_pos)[:-1]])
    total = int(n_pos.sum())
    seg = np.repeat(np.arange(len(a)), n_pos)
    idx = np.arange(total) - np.repeat(offsets, n_pos) + np.repeat(a, n_pos)
    run = (s1[idx + m] - s1[idx]) / m
    on = (np.abs(run - ref[seg]) <= tol).all(axis=1)
    big = np.iinfo(np.int64).max
    has = n_pos > 0
    first = np.full(len(a), big)
    last = np.full(len(a), -1)
    if total:
        first[has] = np.minimum.reduceat(np.where(on, idx, big), offsets[has])
        last[has] = np.maximum.reduceat(np.where(on, idx, -1), offsets[has])
    found = last >= 0
    new_a = np.where(found, first, a)
    new_b = np.where(found, last + m, a)
    return new_a, new_b


def find_static_windows(acc: np.ndarray, sampling_rate_hz: float, *, hold_s: float = 3.0,
                        sd_factor: float = 1.3, max_norm_g: float = 2.0, min_angle_deg: float = 10.0,
                        zero: np.ndarray | None = None,
                        unit_per_g: float | np.ndarray | None = 1.0) -> list[StaticWindow]:
    """Static holds of ``acc`` (``(n, 3)``, any linear unit): :class:`StaticWindowDetector` in one call."""
    det = StaticWindowDetector(hold_s=hold_s, sd_factor=sd_factor, max_norm_g=max_norm_g,
                               min_angle_deg=min_angle_deg)
    return det.detect(acc, sampling_rate_hz=sampling_rate_hz, zero=zero, unit_per_g=unit_per_g).windows_
