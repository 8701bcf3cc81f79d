"""The offline chain of :class:`gaitlog.host.gait.pipeline.StepPipeline` on a recording fed in blocks, in bounded
memory, with the whole-array results bit for bit.

:class:`StreamingStepPipeline` takes the acceleration block after block (:meth:`~StreamingStepPipeline.feed`, any
block sizes) and returns the step table at :meth:`~StreamingStepPipeline.finish`. Inside, the recording is cut into
blocks of ``block`` samples, each computed with a halo of input samples on either side (short-gap filling,
the 4 s gravity mean, the Gaussian low-passes), so every sample is computed as in the whole array:

1. Per block: short gaps filled, gravity and the vertical acceleration, its first harmonic (3 Hz). The moving
   mean's cumulative sum continues from block to block (the carried sum is the first term: the additions of one
   whole-signal sum, in order). Kept: the vertical acceleration and where it is measured (in a temporary file), and
   the first harmonic's *turning points* (:class:`TurningPoints`: the runs higher or lower than both neighbours),
   on which peaks and prominences are those of the whole curve, however far a prominence reaches.
2. At the end: the foot-flats on the turning points
   (:func:`gaitlog.host.gait.events.curve_foot_flats`: the prominence rule in time order, the minimum distance,
   the recording's median step, the stop rule), heel strikes and toe-offs from the 10 Hz and impact bands
   recomputed around the foot-flats, block by block, the bouts from the long runs of missing samples, and M1-M5
   per group of steps (:func:`gaitlog.host.gait.pipeline.step_table`), each group on the samples it spans.

Memory: one block's temporaries, the turning points (a few bytes a sample) and the step table; the kept vertical
acceleration (9 bytes a sample) goes to a temporary file and is read back a group of steps at a time. A step is
counted once (a foot-flat is one turning point, wherever the blocks are cut).
"""

from __future__ import annotations

import ctypes
import functools
import tempfile
import warnings
from typing import TYPE_CHECKING, Self

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import samples
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.host.gait.axes import _vertical_block
from gaitlog.host.gait.events import GaitEventDetector, curve_foot_flats, heel_strikes_toe_offs, link_steps
from gaitlog.host.gait.gaps import MAX_INTERPOLATED_GAP_S, GapFiller, missing_runs
from gaitlog.host.gait.masked_filter import TRUNCATE_SIGMAS, gaussian_sigma_s, masked_gaussian_lowpass, shifted
from gaitlog.host.gait.pipeline import impossible_note, step_table

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.host.gait.k_calibration import KFit

__all__ = ["StreamingStepPipeline", "TurningPoints", "bound_heap", "give_back_memory"]

#: Samples computed per block (the last one may be shorter).
BLOCK_SAMPLES = 1 << 16


#: glibc's ``mallopt`` parameter of the mmap threshold, and the value set while a chain streams (:func:`bound_heap`).
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 256 << 10


def bound_heap() -> None:
    """Serve allocations of :data:`MMAP_THRESHOLD_BYTES` and more from mmap for the rest of the process (glibc;
    nothing elsewhere): glibc otherwise raises its threshold to the largest array freed (up to 32 MB), and the
    block-sized temporaries of a long recording then fragment the heap (measured: 215 -> 205 MB peak for 4M
    samples, the same time)."""
    libc = _libc()
    if libc is not None:
        libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)


def give_back_memory() -> None:
    """Return the C heap's free pages to the operating system (glibc's ``malloc_trim``; nothing elsewhere).

    numpy's temporaries of a few hundred kB come from the heap once glibc has raised its mmap threshold, and a
    freed one in the middle of the heap stays in the process: between the stages of a long recording the
    resident memory would grow by tens of MB that nothing uses (measured: 43 MB after the on-line run of 4M
    samples)."""
    libc = _libc()
    if libc is not None:
        libc.malloc_trim(0)


@functools.cache
def _libc():
    try:
        libc = ctypes.CDLL("libc.so.6")
        return libc if hasattr(libc, "malloc_trim") and hasattr(libc, "mallopt") else None
    except OSError:
        return None


class _Spill:
    """The kept per-sample arrays (the vertical acceleration and where it is measured), appended block after block
    to temporary files and read back by range (:meth:`take`): the process holds one block of them, not the recording
    (the operating system's file cache holds the rest, outside the process's memory)."""

    def __init__(self) -> None:
        self.files = (tempfile.TemporaryFile(), tempfile.TemporaryFile())
        self.dtypes = (np.dtype(np.float64), np.dtype(bool))
        self.n = 0

    def append(self, *arrays: np.ndarray) -> None:
        for f, a, dt in zip(self.files, arrays, self.dtypes):
            f.seek(self.n * dt.itemsize)
            f.write(np.ascontiguousarray(a, dt).tobytes())
        self.n += arrays[0].size

    def take(self, lo: int, hi: int) -> tuple[np.ndarray, ...]:
        lo, hi = max(lo, 0), min(hi, self.n)
        out = []
        for f, dt in zip(self.files, self.dtypes):
            f.seek(lo * dt.itemsize)
            out.append(np.frombuffer(f.read((hi - lo) * dt.itemsize), dt).copy())
        return tuple(out)

    def close(self) -> None:
        for f in self.files:
            f.close()


class TurningPoints:
    """The turning points of a curve fed in order (:meth:`feed`): one entry per maximal run of equal samples that is
    higher, or lower, than both neighbouring runs, the first and the last run always included.

    ``values`` and ``index`` (the run's middle sample, where ``find_peaks`` puts a plateau's peak) after
    :meth:`finish`. Peaks, prominences and the minimum between two peaks are the same on these as on the curve.

    >>> tp = TurningPoints(); tp.feed(np.array([0.0, 1.0, 1.0, 2.0])); tp.feed(np.array([1.0, 1.0, 3.0, 0.0]))
    >>> tp.finish(); tp.values.tolist(), tp.index.tolist()
    ([0.0, 2.0, 1.0, 3.0, 0.0], [0, 3, 4, 6, 7])
    """

    def __init__(self) -> None:
        self._values: list[np.ndarray] = []
        self._index: list[np.ndarray] = []
        self._prev: float | None = None          # value of the run before the open one
        self._run: tuple[float, int, int] | None = None   # the open run: value, first and last sample
        self.n = 0

    def feed(self, x: np.ndarray) -> None:
        """The next samples of the curve (finite)."""
        if x.size == 0:
            return
        change = np.flatnonzero(x[1:] != x[:-1]) + 1
        rs = np.r_[0, change] + self.n
        re = np.r_[change - 1, x.size - 1] + self.n
        v = x[rs - self.n]
        self.n += x.size
        if self._run is not None:
            if v[0] == self._run[0]:
                rs[0] = self._run[1]
            else:
                v, rs, re = np.r_[self._run[0], v], np.r_[self._run[1], rs], np.r_[self._run[2], re]
        prev = np.r_[np.nan if self._prev is None else self._prev, v[:-1]]
        closed = v[:-1]
        after = v[1:]
        before = prev[:-1]
        first = np.isnan(before)
        turn = first | ((closed > before) & (closed > after)) | ((closed < before) & (closed < after))
        self._values.append(closed[turn])
        self._index.append((rs[:-1][turn] + re[:-1][turn]) // 2)
        self._prev = float(closed[-1]) if closed.size else self._prev
        self._run = (float(v[-1]), int(rs[-1]), int(re[-1]))

    def finish(self) -> None:
        """Close the last run (always a turning point)."""
        if self._run is not None:
            self._values.append(np.array([self._run[0]]))
            self._index.append(np.array([(self._run[1] + self._run[2]) // 2]))
            self._run = None
        self.values = np.concatenate(self._values) if self._values else np.zeros(0)
        self.index = np.concatenate(self._index).astype(np.int64) if self._index else np.zeros(0, np.int64)
        self._values, self._index = [], []


class _DrawnCurve:
    """The first harmonic drawn straight across the stretches where it does not exist (as
    :class:`~gaitlog.host.gait.events.GaitEventDetector` draws it for its peak search: ``np.interp`` between the
    finite neighbours, the nearest finite value beyond the ends), fed to :class:`TurningPoints` in order; a
    stretch waits for its right neighbour. Also the stretches themselves (``gaps``)."""

    def __init__(self, out: TurningPoints) -> None:
        self.out = out
        self.n = 0
        self.last: tuple[int, float] | None = None     # the last finite sample
        self.open: int | None = None                   # first sample of an unfinished stretch
        self.gap_starts: list[int] = []
        self.gap_ends: list[int] = []

    def feed(self, lp: np.ndarray) -> None:
        n0, self.n = self.n, self.n + lp.size
        fin = np.isfinite(lp)
        s, e = missing_runs(fin)
        self.gap_starts.extend((s + n0).tolist())
        self.gap_ends.extend((e + n0).tolist())
        idx = np.flatnonzero(fin)
        if idx.size == 0:
            if self.open is None and lp.size:
                self.open = n0
            return
        f0, f1 = int(idx[0]), int(idx[-1])
        start = n0 if self.open is None else self.open
        if start < n0 + f0:
            self._line(start, n0 + f0, float(lp[f0]))
        x = lp[f0:f1 + 1]
        if idx.size != f1 - f0 + 1:
            x = x.copy()
            holes = np.flatnonzero(~fin[f0:f1 + 1]) + f0
            x[holes - f0] = np.interp(holes, idx, lp[idx])
        self.out.feed(x)
        self.last = (n0 + f1, float(lp[f1]))
        self.open = n0 + f1 + 1 if f1 + 1 < lp.size else None

    def _line(self, a: int, b: int, right: float) -> None:
        """Samples ``[a, b)`` of a stretch whose right neighbour (at ``b``) is ``right``."""
        for lo in range(a, b, BLOCK_SAMPLES):
            q = np.arange(lo, min(b, lo + BLOCK_SAMPLES))
            if self.last is None:
                self.out.feed(np.full(q.size, right))
            else:
                self.out.feed(np.interp(q, [self.last[0], b], [self.last[1], right]))

    def finish(self) -> None:
        if self.open is not None and self.last is not None:
            for lo in range(self.open, self.n, BLOCK_SAMPLES):
                self.out.feed(np.full(min(self.n, lo + BLOCK_SAMPLES) - lo, self.last[1]))
        self.out.finish()

    def finite(self, i: np.ndarray) -> np.ndarray:
        """Where the first harmonic exists, at the samples ``i``."""
        starts, ends = np.asarray(self.gap_starts, np.int64), np.asarray(self.gap_ends, np.int64)
        j = np.searchsorted(starts, i, side="right") - 1
        inside = (j >= 0) & (i < ends[np.maximum(j, 0)]) if starts.size else np.zeros(i.size, bool)
        return ~inside


class StreamingStepPipeline:
    """:class:`gaitlog.host.gait.pipeline.StepPipeline` fed block by block (module notes).

    Parameters are those of :class:`~gaitlog.host.gait.pipeline.StepPipeline`, and ``block`` (samples computed
    at a time). After :meth:`finish`: ``steps_`` (the :class:`StepTable`), ``notes_``, ``n_samples_``.

    Examples
    --------
    >>> from gaitlog.host.gait.pipeline import StepPipeline
    >>> t = np.arange(3000) / 50.0
    >>> acc = np.zeros((t.size, 3)); acc[:, 2] = 1.0 + 0.2 * np.cos(2 * np.pi * 1.8 * t)
    >>> s = StreamingStepPipeline(leg_length_m=0.9, foot_length_m=0.26, sampling_rate_hz=50.0, block=777)
    >>> for lo in range(0, t.size, 1000):
    ...     s.feed(acc[lo:lo + 1000])
    >>> a = s.finish().steps_
    >>> b = StepPipeline(leg_length_m=0.9, foot_length_m=0.26).run(acc, sampling_rate_hz=50.0).steps_
    >>> bool(np.array_equal(a.raw_m["M2"], b.raw_m["M2"], equal_nan=True)), a.n_steps == b.n_steps
    (True, True)
    """

    def __init__(self, *, leg_length_m: float, foot_length_m: float, sampling_rate_hz: float,
                 k_fit: KFit | None = None, detector: GaitEventDetector | None = None,
                 gravity_window_s: float = 4.0, max_fill_s: float = MAX_INTERPOLATED_GAP_S, t0_s: float = 0.0,
                 block: int = BLOCK_SAMPLES) -> None:
        rate = float(sampling_rate_hz)
        if not (np.isfinite(rate) and rate > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        self.leg_length_m, self.foot_length_m, self.k_fit = leg_length_m, foot_length_m, k_fit
        self.rate, self.t0_s, self.block = rate, t0_s, max(1, int(block))
        self.detector = (detector if detector is not None else GaitEventDetector()).clone()
        self.max_fill_s = max_fill_s
        p = self.detector.parameters
        self.window = max(1, int(round(gravity_window_s * rate)))
        self.radius = max(int(TRUNCATE_SIGMAS * gaussian_sigma_s(c) * rate + 0.5)
                          for c in (p.ff_cutoff_hz, p.detail_cutoff_hz, p.impact_cutoff_hz))
        self.gap = int(round(max_fill_s * rate)) + 1
        self.halo = self.radius + self.window + self.gap + 2
        self._raw: list[tuple[np.ndarray, np.ndarray]] = []      # input not yet dropped, from sample self._base
        self._base = 0
        self._avail = 0
        self._done = 0                                            # samples computed
        self._carry = (0, np.zeros(3), np.int64(0))               # cumulative sums (and count) at a sample
        self._kept = _Spill()
        self._points = TurningPoints()
        self._curve = _DrawnCurve(self._points)

    def feed(self, acc_g: np.ndarray, valid: np.ndarray | None = None) -> None:
        """The next ``(m, 3)`` samples in g (NaN or ``valid`` False where missing)."""
        acc = np.asarray(acc_g, np.float64)
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise ValueError(f"acc_g must have shape (m, 3), got {acc.shape}")
        ok = np.ones(acc.shape[0], bool) if valid is None else np.asarray(valid, bool)
        if ok.shape != (acc.shape[0],):
            raise ValueError(f"valid must have shape ({acc.shape[0]},), got {ok.shape}")
        self._raw.append((acc, ok))
        self._avail += acc.shape[0]
        while self._avail - (self._done + self.block) >= self.halo:
            self._compute(self._done + self.block, None)

    def finish(self) -> Self:
        """Compute the rest and the step table."""
        n = self._avail
        while self._done < n:
            self._compute(min(n, self._done + self.block), n)
        self._raw = []
        self._curve.finish()
        self.n_samples_ = n
        self.notes_: list[str] = []
        try:
            self.steps_ = self._table(n)
        finally:
            self._kept.close()
        return self

    # ------------------------------------------------------------------------------------------- per block
    def _input(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """Input samples ``[lo, hi)`` (``lo >= self._base``); drops what no later block needs."""
        acc = np.concatenate([a for a, _ in self._raw]) if len(self._raw) > 1 else self._raw[0][0]
        ok = np.concatenate([v for _, v in self._raw]) if len(self._raw) > 1 else self._raw[0][1]
        keep = max(self._base, min(lo, self._done + self.block - self.halo))
        self._raw = [(acc[keep - self._base:], ok[keep - self._base:])]
        out = acc[lo - self._base:hi - self._base], ok[lo - self._base:hi - self._base]
        self._base = keep
        return out

    def _compute(self, e: int, n: int | None) -> None:
        """Compute samples ``[self._done, e)``; ``n`` is the recording's length once known."""
        s = self._done
        end = self._avail if n is None else n
        w, r, half = self.window, self.radius, self.window // 2
        av_lo, av_hi = max(0, s - r), min(end, e + r)
        c_lo, c_hi = max(0, av_lo - half), min(end, av_hi - 1 - half + w)
        q = self._carry[0]
        seg_lo, seg_hi = max(0, q - self.gap), min(end, c_hi + self.gap)
        acc, ok = self._input(seg_lo, seg_hi)
        filled = GapFiller(max_gap_s=self.max_fill_s).fill(acc, ok, sampling_rate_hz=self.rate)
        x, v = filled.acc_, filled.valid_
        v = v & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1]) & np.isfinite(x[:, 2])
        # cumulative sums over [q, c_hi], the carried sums first; a sample counts where measured (v: finite on
        # every axis), so the three axes' counts are one
        wk = v[q - seg_lo:c_hi - seg_lo]
        cx = np.empty((3, c_hi - q + 1))
        for k in range(3):
            np.cumsum(np.r_[self._carry[1][k], np.where(wk, x[q - seg_lo:c_hi - seg_lo, k], 0.0)], out=cx[k])
        cw = np.cumsum(np.r_[self._carry[2], wk])
        # the window of sample i is [i - half, i - half + w) within the recording: columns from slices (never
        # below q, the carried sums' sample)
        m = av_hi - av_lo
        num = shifted(cx, av_lo - half + w - q, m) - shifted(cx, av_lo - half - q, m)
        den = shifted(cw, av_lo - half + w - q, m) - shifted(cw, av_lo - half - q, m)
        grav = np.full(num.shape, np.nan)
        np.divide(num, den, out=grav, where=den > 0)
        nq = max(0, e - r - half)
        self._carry = (nq, cx[:, nq - q].copy(), cw[nq - q])
        rows = x[av_lo - seg_lo:av_hi - seg_lo]
        good = v[av_lo - seg_lo:av_hi - seg_lo].copy()
        av = np.empty(m)
        good &= _vertical_block(rows, grav, av)
        av[~good] = np.nan
        good &= np.isfinite(av)
        p, mw = self.detector.parameters, self.detector.min_weight
        lp = masked_gaussian_lowpass(av, good, cutoff_hz=p.ff_cutoff_hz, sampling_rate_hz=self.rate,
                                     min_weight=mw)[s - av_lo:e - av_lo]
        self._kept.append(av[s - av_lo:e - av_lo].copy(), good[s - av_lo:e - av_lo].copy())
        self._curve.feed(lp)
        self._done = e
        if (e // self.block) % 8 == 0:
            give_back_memory()

    # ------------------------------------------------------------------------------------------- at the end
    def _bands(self, lo: int, hi: int, *cutoffs: float) -> tuple[int, np.ndarray, np.ndarray, list[np.ndarray]]:
        """Samples ``[lo, hi)`` with the radius of the widest filter either side: (their start, a_v, measured, the
        masked Gaussian low-pass at each of ``cutoffs``), the low-passes exact on ``[lo, hi)``."""
        mw, rate = self.detector.min_weight, self.rate
        a = max(0, lo - self.radius)
        av, ok = self._kept.take(a, hi + self.radius)
        return a, av, ok, [masked_gaussian_lowpass(av, ok, cutoff_hz=c, sampling_rate_hz=rate, min_weight=mw)
                           for c in cutoffs]

    def _events(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Foot-flats, heel strikes and toe-offs (``-1``: none)."""
        p, pts = self.detector.parameters, self._points
        if n < 3 or pts.values.size == 0:
            empty = np.zeros(0, np.int64)
            return empty, empty, empty
        ff = curve_foot_flats(pts.values, pts.index, self._curve.finite, p, self.rate)
        reach = max(samples(p.hs_search_s, self.rate), samples(p.hs_after_s, self.rate),
                    samples(p.to_search_s, self.rate) + 1) + 1
        hs, to = np.full(ff.size, -1, np.int64), np.full(ff.size, -1, np.int64)
        group = ff // self.block
        cuts = np.r_[0, np.flatnonzero(np.diff(group)) + 1, ff.size].tolist()
        for a, b in zip(cuts[:-1], cuts[1:]):
            if a == b:
                continue
            lo = max(0, int(ff[a]) - reach)
            start, _, _, (det, imp) = self._bands(lo, min(n, int(ff[b - 1]) + reach + 1), p.detail_cutoff_hz,
                                                  p.impact_cutoff_hz)
            h, t = heel_strikes_toe_offs(det, det - imp, ff[a:b] - start, p, self.rate)
            hs[a:b] = np.where(h >= 0, h + start, -1)
            to[a:b] = np.where(t >= 0, t + start, -1)
        return ff, hs, to

    def _table(self, n: int) -> StepTable:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ff, hs, to = self._events(n)
            self._points = self._curve = None           # the turning points are read: their memory goes
            give_back_memory()
            runs = self._missing_runs()
            ev = link_steps(ff, hs, to, runs, sampling_rate_hz=self.rate, max_gap_s=self.detector.max_gap_s,
                            max_step_s=self.detector.parameters.max_step_s)
        self.notes_ += [str(c.message) for c in caught]

        def take(lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            give_back_memory()                      # the previous group's temporaries
            start, av, ok, (lp,) = self._bands(lo, hi, self.detector.parameters.ff_cutoff_hz)
            return av[lo - start:hi - start], ok[lo - start:hi - start], lp[lo - start:hi - start]

        table, self.n_impossible_ = step_table(
            ev["foot_flat_"], ev["heel_strike_"], ev["toe_off_"], ev["bout_"], take, sampling_rate_hz=self.rate,
            t0_s=self.t0_s, leg_length_m=self.leg_length_m, foot_length_m=self.foot_length_m,
            k_fit=self.k_fit)
        if self.n_impossible_:
            self.notes_.append(impossible_note(self.n_impossible_, self.leg_length_m))
        return table

    def _missing_runs(self) -> tuple[np.ndarray, np.ndarray]:
        """Start and end of every run of samples not measured (or not finite), joined across blocks."""
        starts: list[int] = []
        ends: list[int] = []
        for at in range(0, self._kept.n, BLOCK_SAMPLES):
            s, e = missing_runs(self._kept.take(at, at + BLOCK_SAMPLES)[1])
            s, e = (s + at).tolist(), (e + at).tolist()
            if s and ends and ends[-1] == s[0]:
                ends[-1] = e[0]
                s, e = s[1:], e[1:]
            starts += s
            ends += e
        return np.asarray(starts, np.int64), np.asarray(ends, np.int64)
