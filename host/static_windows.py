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
   segment median (``m`` samples in 0.2 s); a segment left shorter than 0.9 ``hold_s`` is rejected. ``trim_s``
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

from host.errors import HostError


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


def _moving_sd(x: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Moving SD of every column over windows ``x[k:k + w]`` and whether each window is NaN-free.

    Returns ``(sd (n - w + 1, 3), finite (n - w + 1,))``; ``sd`` is 0 where the window is not finite.
    """
    finite = np.isfinite(x).all(axis=1)
    centre = np.nanmedian(x, axis=0) if finite.any() else np.zeros(x.shape[1])
    xc = np.where(finite[:, None], x - centre, 0.0)  # centring keeps the sums of squares small
    zero = np.zeros((1, x.shape[1]))
    s1 = np.concatenate([zero, np.cumsum(xc, axis=0)])
    s2 = np.concatenate([zero, np.cumsum(xc * xc, axis=0)])
    bad = np.concatenate([[0], np.cumsum(~finite)])
    m1 = (s1[w:] - s1[:-w]) / w
    var = (s2[w:] - s2[:-w]) / w - m1 * m1
    var = np.maximum(var, 0.0) * (w / max(w - 1, 1))
    ok = (bad[w:] - bad[:-w]) == 0
    return np.where(ok[:, None], np.sqrt(var), 0.0), ok


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

    @staticmethod
    def _refine(x: np.ndarray, a: int, b: int, m: int, tol: np.ndarray) -> tuple[int, int]:
        return _edge_refine(x, a, b, m, tol)

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
        x = np.asarray(acc, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise StaticWindowError(f"acceleration must have shape (n, 3), got {x.shape}")
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise StaticWindowError(f"sampling rate must be a positive number of Hz, got {sampling_rate_hz!r}")
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
        sd, ok = _moving_sd(x, w)  # step 1
        if not ok.any():
            return self
        floor = np.empty(3)
        for j in range(3):  # step 2
            s = sd[ok, j]
            s = s[s > 0]
            floor[j] = np.percentile(s, self.floor_percentile) if s.size else 0.0
        thr = self.sd_factor * np.sqrt(floor**2 + (self.code_step_ / 2) ** 2)  # step 3
        self.noise_floor_, self.threshold_ = floor, thr
        quiet = ok & (sd <= thr).all(axis=1)  # step 4
        trim = int(round(self.trim_s * sampling_rate_hz))
        candidates = []
        m = max(1, int(round(0.2 * sampling_rate_hz)))
        edge_tol = 4.0 * np.sqrt(floor**2 + self.code_step_**2 / 12) / np.sqrt(m) + self.code_step_ / 2
        for k0, k1 in _runs(quiet):
            a, b = self._refine(x, k0, k1 + w, m, edge_tol)
            if b - a < 0.9 * w:
                seg = x[a:b] if b - a >= 2 else x[k0:k1 + w]
                win = StaticWindow(a, b, seg.mean(axis=0), seg.std(axis=0, ddof=1))
                self.rejected_.append((win, f"only {(b - a) / sampling_rate_hz:.2f} s still after removing the "
                                            "moving ends"))
                continue
            if b - a - 2 * trim >= 2:
                a, b = a + trim, b - trim
            seg = x[a:b]
            first, last = x[k0:k0 + w].mean(axis=0), x[k1:k1 + w].mean(axis=0)
            sd_seg = np.where(np.ptp(seg, axis=0) == 0, 0.0, seg.std(axis=0, ddof=1))  # exact 0 when constant
            candidates.append((StaticWindow(a, b, seg.mean(axis=0), sd_seg), first, last))
        if not candidates:
            return self
        means = np.array([c[0].mean for c in candidates])
        if zero is None:
            zero_v = np.zeros(3)
        else:
            zero_v = np.broadcast_to(np.asarray(zero, dtype=np.float64), (3,)).copy()
        if unit_per_g is None:  # crude sphere through the candidates
            zero_v = 0.5 * (means.max(axis=0) + means.min(axis=0))
            radius = float(np.median(np.linalg.norm(means - zero_v, axis=1)))
            per_g = np.full(3, radius if radius > 0 else 1.0)
        else:
            per_g = np.broadcast_to(np.asarray(unit_per_g, dtype=np.float64), (3,)).copy()
        self.zero_, self.unit_per_g_ = zero_v, per_g
        kept = []
        for win, first, last in candidates:  # step 5
            nominal = (win.mean - zero_v) / per_g
            norm = float(np.linalg.norm(nominal))
            const = np.flatnonzero(win.sd == 0)
            drift = _angle_deg(first - zero_v, last - zero_v) if norm > 0 else 0.0
            if const.size:
                names = ", ".join("xyz"[j] for j in const)
                self.rejected_.append((win, f"constant (SD = 0) on axis {names}: stuck, sleeping or saturated"))
            elif norm >= self.max_norm_g:
                self.rejected_.append((win, f"|mean| = {norm:.2f} g is not below {self.max_norm_g} g"))
            elif norm == 0:
                self.rejected_.append((win, "|mean| = 0: no direction"))
            elif drift > self.min_angle_deg / 2:
                self.rejected_.append((win, f"orientation drifts by {drift:.1f} deg during the hold"))
            else:
                kept.append((win, nominal / norm))
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
        self.windows_ = sorted((a[0] for a in accepted), key=lambda s: s.start)
        self.rejected_.sort(key=lambda r: r[0].start)
        return self


def _edge_refine(x: np.ndarray, a: int, b: int, m: int, tol: np.ndarray) -> tuple[int, int]:
    """Step 4b: cut the ends of ``x[a:b]`` whose ``m``-sample running mean leaves the segment median by ``tol``."""
    seg = x[a:b]
    if len(seg) < m + 2:
        return a, b
    med = np.median(seg, axis=0)
    c = np.cumsum(np.vstack([np.zeros((1, 3)), seg - med]), axis=0)
    run = (c[m:] - c[:-m]) / m  # run[i] = mean of seg[i:i + m]
    on = (np.abs(run) <= tol).all(axis=1)
    if not on.any():
        return a, a
    first, last = int(np.argmax(on)), len(on) - 1 - int(np.argmax(on[::-1]))
    return a + first, a + last + m


def find_static_windows(acc: np.ndarray, sampling_rate_hz: float, *, hold_s: float = 3.0,
                        sd_factor: float = 1.3, max_norm_g: float = 2.0, min_angle_deg: float = 10.0,
                        zero: np.ndarray | None = None,
                        unit_per_g: float | np.ndarray | None = 1.0) -> list[StaticWindow]:
    """Static holds of ``acc`` (``(n, 3)``, any linear unit): :class:`StaticWindowDetector` in one call."""
    det = StaticWindowDetector(hold_s=hold_s, sd_factor=sd_factor, max_norm_g=max_norm_g,
                               min_angle_deg=min_angle_deg)
    return det.detect(acc, sampling_rate_hz=sampling_rate_hz, zero=zero, unit_per_g=unit_per_g).windows_
