"""Per-step results as one table, whichever chain produced them: the names and units both chains share.

:class:`StepTable` has one row per foot-flat: the step that ends there (its window is the previous
foot-flat of the same walking bout; the first foot-flat of a bout ends a step without a window, counted
but without a length). It is filled by the host's offline chain (``gaitlog.host.gait.pipeline.StepPipeline``, the
paper's PC processing) and by the on-line algorithm's records (:meth:`StepTable.from_online`, the
firmware's, in either arithmetic), so every comparison, calibration and evaluation reads the same fields.

Distance (:meth:`StepTable.distance_m`): the sum of the step lengths; a step whose length is NaN (no window,
a long gap, an impossible excursion) counts with the median length of the measured steps of its bout, and
the number of such steps is reported (``n_filled``).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitlog.atomic_write import atomic_write_text
from gaitlog.protocol.steps import StepFlag
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["ESTIMATORS", "StepTable", "columns_csv_text", "csv_text", "distinct", "fixed_csv_cells", "float_csv_cells",
           "int_csv_cells", "nan_median"]

#: The step-length estimators of Alvarez et al. (2006): M1 pendulum, M2 pendulum with drift correction,
#: M3 two-phase pendulum + foot length (no K), M4 Weinberg, M5 cadence line.
ESTIMATORS = ("M1", "M2", "M3", "M4", "M5")


def nan_median(values: np.ndarray) -> float:
    """``np.nanmedian`` of ``values`` (flattened; NaN when none is a number), the same bits, by ``np.partition``:
    ``np.median`` imports ``numpy.ma`` for its NaN check (about 30 ms of a short ``gaitlog estimate``).

    >>> nan_median(np.array([3.0, np.nan, 1.0, 2.0, 10.0])), nan_median(np.array([np.nan]))
    (2.5, nan)
    """
    v = np.asarray(values, np.float64).ravel()
    v = v[~np.isnan(v)]
    k = v.size // 2
    if v.size == 0:
        return math.nan
    if v.size % 2:
        return float(np.partition(v, k)[k])
    p = np.partition(v, (k - 1, k))
    return float((p[k - 1] + p[k]) / 2)


def distinct(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` (sorted, flattened) without ``numpy.ma`` (which ``np.unique`` imports to ask whether
    its input is masked).

    >>> distinct(np.array([3, 1, 3, 2, 1])).tolist()
    [1, 2, 3]
    """
    v = np.sort(np.asarray(values).ravel())
    return v[np.r_[True, v[1:] != v[:-1]]] if v.size else v


@dataclass(eq=False)
class StepTable:
    """One row per detected step (ending at a foot-flat). Indices are samples of the input, ``-1`` = none.

    Attributes
    ----------
    sampling_rate_hz, t0_s
        Sample rate and time of sample 0.
    foot_flat, heel_strike, toe_off, start, bout
        ``(m,)`` int: the foot-flat ending the step, the heel-strike before it, the toe-off after the
        previous foot-flat, the window start (previous foot-flat, -1 if none), the walking-bout number.
    duration_s, n_missing
        Window duration (NaN if none) and missing samples inside it.
    vertical_excursion_m
        ``{"M1": h, "M2": h, "M3": h1}`` per step.
    acc_range_m_s2
        M4's 3 Hz vertical acceleration range per step.
    raw_m
        Per estimator, the length with K = 1 (M5: the cadence ``1/T`` in Hz).
    length_m
        Per estimator, the calibrated length (see module notes), m.
    """

    sampling_rate_hz: float
    t0_s: float
    foot_flat: np.ndarray
    heel_strike: np.ndarray
    toe_off: np.ndarray
    start: np.ndarray
    bout: np.ndarray
    duration_s: np.ndarray
    n_missing: np.ndarray
    vertical_excursion_m: dict[str, np.ndarray] = field(default_factory=dict)
    acc_range_m_s2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    raw_m: dict[str, np.ndarray] = field(default_factory=dict)
    length_m: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of steps (rows)."""
        return int(self.foot_flat.size)

    def __repr__(self) -> str:
        bouts = int(np.unique(self.bout[self.bout >= 0]).size) if self.n_steps else 0
        return (f"StepTable({self.n_steps} steps in {bouts} bout(s) at {self.sampling_rate_hz:g} Hz, "
                f"estimators {','.join(self.raw_m) or 'none'})")

    def time_s(self, index: np.ndarray) -> np.ndarray:
        """Times of sample indices (NaN where ``-1``)."""
        index = np.asarray(index)
        return np.where(index >= 0, self.t0_s + index / self.sampling_rate_hz, np.nan)

    def select(self, mask: np.ndarray) -> StepTable:
        """The rows where ``mask`` is true."""
        mask = np.asarray(mask, bool)
        return StepTable(
            self.sampling_rate_hz, self.t0_s, self.foot_flat[mask], self.heel_strike[mask], self.toe_off[mask],
            self.start[mask], self.bout[mask], self.duration_s[mask], self.n_missing[mask],
            {k: v[mask] for k, v in self.vertical_excursion_m.items()}, self.acc_range_m_s2[mask],
            {k: v[mask] for k, v in self.raw_m.items()}, {k: v[mask] for k, v in self.length_m.items()},
        )

    def event_time_s(self) -> np.ndarray:
        """Time of each step for sectioning: its heel-strike, or its foot-flat when no heel-strike was found."""
        idx = np.where(self.heel_strike >= 0, self.heel_strike, self.foot_flat)
        return self.time_s(idx)

    def event_counts(self) -> dict[str, int]:
        """How many steps had each event found, and how many M3 lengths are filled (per table, e.g. a trial).

        Returns
        -------
        dict
            ``steps`` (rows), ``windows`` (rows with a window: a measured step), ``heel_strike_found``,
            ``toe_off_found`` (of the windows: toe-off is only searched inside a window), ``single_support``
            (windows with both events in order, the toe-off before the heel-strike: M3 is measured) and
            ``m3_filled`` (windows without it: :meth:`distance_m` counts them with the bout's median M3).

        Examples
        --------
        >>> t = StepTable(50.0, 0.0, np.array([10, 40, 70]), np.array([8, 38, -1]), np.array([-1, 20, -1]),
        ...               np.array([-1, 10, 40]), np.zeros(3, np.int64), np.array([np.nan, 0.6, 0.6]),
        ...               np.zeros(3, np.int64), {"M3": np.array([np.nan, 0.03, np.nan])})
        >>> t.event_counts()
        {'steps': 3, 'windows': 2, 'heel_strike_found': 2, 'toe_off_found': 1, 'single_support': 1, 'm3_filled': 1}
        """
        window = self.start >= 0
        h1 = self.vertical_excursion_m.get("M3", np.full(self.n_steps, np.nan))
        measured = window & np.isfinite(h1)
        return {"steps": self.n_steps, "windows": int(window.sum()),
                "heel_strike_found": int(np.count_nonzero(self.heel_strike >= 0)),
                "toe_off_found": int(np.count_nonzero(window & (self.toe_off >= 0))),
                "single_support": int(measured.sum()), "m3_filled": int(np.count_nonzero(window & ~measured))}

    def filled(self, values: np.ndarray) -> tuple[np.ndarray, int]:
        """``values`` with NaN replaced by the median of the finite values of the same bout (see notes).

        Returns the filled array and the number of replaced entries. A bout without any finite value uses
        the median over all bouts; with no finite value at all the result stays NaN.
        """
        v = np.asarray(values, np.float64).copy()
        bad = ~np.isfinite(v)
        if not bad.any():
            return v, 0
        overall = nan_median(v) if np.any(~bad) else np.nan
        for b in distinct(self.bout[bad]):  # loop over bouts (few), not samples
            sel = self.bout == b
            good = v[sel & ~bad]
            v[sel & bad] = nan_median(good) if good.size else overall
        return v, int(np.count_nonzero(bad))

    def distance_m(self, estimator: str, *, raw: bool = False) -> tuple[float, int]:
        """Distance walked by ``estimator`` (sum over steps, NaN steps filled) and the number filled.

        For ``raw=True`` and M5 the sum is of the cadences ``1/T`` (what M5's calibration needs).
        """
        src = self.raw_m if raw else self.length_m
        if estimator not in src:
            raise KeyError(f"unknown estimator {estimator!r}; expected one of {sorted(src)}")
        if self.n_steps == 0:
            return 0.0, 0
        v, n = self.filled(src[estimator])
        return float(np.sum(v)), n

    def columns(self) -> dict[str, np.ndarray]:
        """The table as named columns (times in s, lengths in m) for CSV export."""
        cols: dict[str, np.ndarray] = {
            "step": np.arange(self.n_steps),
            "bout": self.bout,
            "start_s": self.time_s(self.start),
            "toe_off_s": self.time_s(self.toe_off),
            "heel_strike_s": self.time_s(self.heel_strike),
            "foot_flat_s": self.time_s(self.foot_flat),
            "duration_s": self.duration_s,
            "n_missing": self.n_missing,
            "h_m1_m": self.vertical_excursion_m.get("M1", np.full(self.n_steps, np.nan)),
            "h_m2_m": self.vertical_excursion_m.get("M2", np.full(self.n_steps, np.nan)),
            "h1_m3_m": self.vertical_excursion_m.get("M3", np.full(self.n_steps, np.nan)),
            "acc_range_m4_m_s2": self.acc_range_m_s2,
        }
        for name in ESTIMATORS:
            cols[f"length_{name.lower()}_m"] = self.length_m.get(name, np.full(self.n_steps, np.nan))
        return cols

    def to_csv_text(self) -> str:
        """CSV text of :meth:`columns` (:func:`columns_csv_text`)."""
        return columns_csv_text(self.columns())

    def to_csv(self, path: str | Path) -> None:
        """Write :meth:`to_csv_text` atomically."""
        atomic_write_text(path, self.to_csv_text())

    @classmethod
    def from_online(cls, steps, *, t0_s: float = 0.0) -> StepTable:
        """The table of on-line records (:class:`gaitlog.firmware_sim.algorithms.online.OnlineSteps`, either arithmetic).

        One row per record. A length of 0 in a record means "no value" (no window, no single-support
        phase, an impossible excursion) and becomes NaN, as in the offline chain. Records computed without
        a calibrated K hold the raw values (K = 1; M5 the cadence): they fill ``raw_m``, and ``length_m``
        is M1-M3 with M4/M5 NaN (the offline chain's rule without calibration). With K, ``length_m`` holds
        the device's lengths and ``raw_m`` the cadence for M5 only (re-run uncalibrated for raw lengths).
        """
        sampling_rate_hz = float(steps.sampling_rate_hz)
        n = steps.n_steps
        window = steps.duration > 0
        start = np.where(window, steps.end - steps.duration, -1)
        bout = np.cumsum(~window) - 1 if n else np.zeros(0, np.int64)
        bout = np.maximum(bout, 0)
        duration_s = np.where(window, steps.duration / sampling_rate_hz, np.nan)
        lengths = steps.length_m()
        values = np.where(lengths > 0, lengths, np.nan)
        exc = steps.excursion_m()
        exc = np.where(window[:, None] & (exc > 0), exc, np.nan)
        exc[:, 2] = np.where(steps.has_flag(StepFlag.M3_UNDEFINED), np.nan, exc[:, 2])
        rng = np.where(window, steps.range_g() * STANDARD_GRAVITY_M_S2, np.nan)
        cadence = np.where(window, sampling_rate_hz / np.maximum(steps.duration, 1), np.nan)
        named = {name: values[:, i] for i, name in enumerate(ESTIMATORS)}
        if steps.calibrated:
            length_m = named
            raw_m = {name: np.full(n, np.nan) for name in ESTIMATORS}
            raw_m["M5"] = cadence
        else:
            raw_m = named
            length_m = {name: (named[name].copy() if name in ("M1", "M2", "M3") else np.full(n, np.nan))
                        for name in ESTIMATORS}
        return cls(sampling_rate_hz, float(t0_s), steps.end.copy(), steps.heel_strike.copy(), steps.toe_off.copy(), start,
                   bout.astype(np.int64), duration_s, np.zeros(n, np.int64),
                   {"M1": exc[:, 0], "M2": exc[:, 1], "M3": exc[:, 2]}, rng, raw_m, length_m)


def columns_csv_text(cols: dict[str, np.ndarray | list[str]]) -> str:
    """CSV text of named equal-length columns: integers and booleans as integers, floats ``%.6g``, NaN as an
    empty cell, text as it is (quoted by :func:`csv_text` where it holds a comma, a quote or a line break).

    Formatted column by column (:func:`float_csv_cells`), then written row by row (:func:`csv_text`): no
    per-cell numpy indexing (0.1 s per 3,000-step table and 3.5 s per 110,000 before).

    >>> columns_csv_text({"n": np.array([1, 2]), "x_m": np.array([0.5, np.nan]), "ok": np.array([True, False])})
    'n,x_m,ok\\n1,0.5,1\\n2,,0\\n'
    >>> columns_csv_text({"n": np.array([1]), "note": ["a, b"]})
    'n,note\\n1,"a, b"\\n'
    """
    cells = []
    for values in cols.values():
        a = np.asarray(values)
        if a.dtype == bool or np.issubdtype(a.dtype, np.integer):
            cells.append(list(map(str, (a.astype(np.int64) if a.dtype == bool else a).tolist())))
        elif a.dtype.kind in "USO":
            cells.append(list(map(str, a.tolist())))
        else:
            cells.append(float_csv_cells(a))
    return csv_text(list(cols), cells)


def float_csv_cells(values: np.ndarray | list[float]) -> list[str]:
    """The CSV cells of real values: ``%.6g``, an empty cell for NaN and infinities (the one rule of every
    CSV table the package writes)."""
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        return []
    # one %-format of the whole column, split at a separator no number holds: twice as fast as a format per cell
    cells = ("\x1f".join(["%.6g"] * a.size) % tuple(a.ravel().tolist())).split("\x1f")
    for i in np.flatnonzero(~np.isfinite(a)).tolist():
        cells[i] = ""
    return cells


#: Powers of ten as uint64, 10^0 .. 10^19 (every uint64 has at most 20 digits).
_POW10 = np.array([10 ** k for k in range(20)], dtype=np.uint64)
#: Below 2^52 every half-integer is a float64: a scaled value under it is rounded by numpy (see fixed_csv_cells).
_HALVES_EXACT = float(2 ** 52)
#: Veltkamp's splitting constant of float64, 2^27 + 1.
_SPLITTER = float(2 ** 27 + 1)


def int_csv_cells(values: np.ndarray, defined: np.ndarray | None = None) -> np.ndarray:
    """The CSV cells of integers (or booleans: 0 and 1), ``str(int(v))``, empty where not ``defined``, as a
    character matrix for :func:`csv_text`: formatted by numpy, no Python object per cell.

    A character matrix is ``(n, width)`` uint8, one ASCII cell per row, right-aligned; NUL bytes are padding.

    >>> [bytes(row) for row in int_csv_cells(np.array([0, -7, 12]), np.array([True, True, False]))]
    [b'\\x00\\x000', b'\\x00-7', b'\\x00\\x00\\x00']
    """
    a = np.asarray(values).ravel()
    if a.dtype == bool:
        a = a.view(np.uint8)
    if a.dtype.kind == "u":
        negative, magnitude = None, a
    else:
        a = a.astype(np.int64, copy=False)
        negative = a < 0
        # |a| without overflow at the int64 minimum: -a = ~a + 1, with ~a >= 0 where a < 0
        magnitude = np.where(negative, (~a).astype(np.uint64) + np.uint64(1), a.astype(np.uint64))
    return _digit_cells(magnitude, negative, 0, defined)


def fixed_csv_cells(values: np.ndarray, decimals: int, defined: np.ndarray | None = None) -> np.ndarray:
    """The CSV cells of real values with ``decimals`` (0 to 15) digits after the point, ``format(v, f".{decimals}f")``
    byte for byte (``-0.0000`` for a small negative, ``nan``, ``inf``), empty where not ``defined``, as a character
    matrix for :func:`csv_text` (:func:`int_csv_cells`), formatted by numpy.

    The digits are ``|v| · 10^decimals`` rounded half to even, as Python rounds the exact decimal value: the
    product's rounding error is found exactly (Dekker's product), and settles a product that rounded onto a half.
    A value that is not finite, or whose product reaches 2^52, is formatted by Python.

    >>> csv_text(["x", "y"], [fixed_csv_cells(np.array([0.5, -1e-9, 2.03125, 1.00005, np.nan]), 4),
    ...                       fixed_csv_cells(np.arange(5.0), 0)])
    'x,y\\n0.5000,0\\n-0.0000,1\\n2.0312,2\\n1.0001,3\\nnan,4\\n'
    """
    if not 0 <= decimals <= 15:
        raise ValueError(f"decimals must be 0 to 15, not {decimals}")
    a = np.asarray(values, dtype=np.float64).ravel()
    scale = 10.0 ** decimals
    with np.errstate(invalid="ignore", over="ignore"):
        magnitude = np.abs(a)
        exact = np.isfinite(magnitude) & (magnitude * scale < _HALVES_EXACT)
        magnitude = np.where(exact, magnitude, 0.0)
        scaled = magnitude * scale
    rounded = np.rint(scaled)
    on_half = np.flatnonzero(np.abs(scaled - np.floor(scaled)) == 0.5)
    if on_half.size:  # the exact product is scaled + its rounding error: a half only when that error is 0
        error = _product_error(magnitude[on_half], scale, scaled[on_half])
        rounded[on_half] = np.where(error > 0, np.ceil(scaled[on_half]),
                                    np.where(error < 0, np.floor(scaled[on_half]), rounded[on_half]))
    negative = np.signbit(a)
    cells = _digit_cells(rounded.astype(np.uint64), negative if negative.any() else None, decimals, None)
    inexact = np.flatnonzero(~exact)
    if inexact.size:                                   # NaN, infinities and huge values: Python's text
        text = [format(v, f".{decimals}f").encode() for v in a[inexact].tolist()]
        width = max(cells.shape[1], max(map(len, text)))
        cells = np.concatenate([np.zeros((a.size, width - cells.shape[1]), np.uint8), cells], axis=1)
        cells[inexact] = np.frombuffer(b"".join(t.rjust(width, b"\0") for t in text), np.uint8).reshape(-1, width)
    if defined is not None:
        cells[~np.asarray(defined, bool).ravel()] = 0
    return cells


def _product_error(x: np.ndarray, y: float, product: np.ndarray) -> np.ndarray:
    """``x · y - product`` exactly, for ``product`` the float64 product of ``x`` and ``y`` (Dekker's two-product,
    Veltkamp's split into 26-bit halves; exact while nothing overflows)."""
    def split(v):
        c = _SPLITTER * v
        high = c - (c - v)
        return high, v - high

    xh, xl = split(x)
    yh, yl = split(np.float64(y))
    return ((xh * yh - product) + xh * yl + xl * yh) + xl * yl


def _digit_cells(magnitude: np.ndarray, negative: np.ndarray | None, decimals: int,
                 defined: np.ndarray | None) -> np.ndarray:
    """The character matrix of ``magnitude`` (unsigned) in decimal with a point before its last ``decimals``
    digits (at least one digit before it), a ``-`` where ``negative`` (None: nowhere).

    Digit by digit from the last, each a division of the whole column by 10: a scalar divisor, which numpy
    divides by multiplication (sixteen times faster than dividing by an array of powers of ten)."""
    n = magnitude.size
    top = int(magnitude.max()) if n else 0
    most = max(int(np.searchsorted(_POW10, np.uint64(top), side="right")), decimals + 1)
    kind = np.uint16 if top < 1 << 16 else np.uint32 if top < 1 << 32 else np.uint64  # narrow division is faster
    sign, point = int(negative is not None), int(decimals > 0)
    cells = np.zeros((n, sign + most + point), np.uint8)
    quotient, ten = magnitude.astype(kind), kind(10)
    column = cells.shape[1] - 1
    for k in range(most):                          # k: the digit's place from the right
        if point and k == decimals:
            cells[:, column] = ord(".")
            column -= 1
        next_quotient = quotient // ten
        digit = (quotient - next_quotient * ten).astype(np.uint8) | np.uint8(ord("0"))
        if k > decimals:                           # a leading zero (quotient 0) is padding
            digit *= quotient != 0
        cells[:, column] = digit
        column -= 1
        quotient = next_quotient
    if negative is not None and negative.any():
        rows = np.flatnonzero(negative)
        digits = np.maximum(np.searchsorted(_POW10, magnitude[rows].astype(np.uint64), side="right"), decimals + 1)
        cells[rows, cells.shape[1] - 1 - digits - point] = ord("-")
    if defined is not None:
        cells[~np.asarray(defined, bool).ravel()] = 0
    return cells


def csv_text(names: Sequence[str], cells: Sequence[Sequence[str] | np.ndarray]) -> str:
    """CSV text of a header and columns of formatted cells (all the same length): the one CSV writer of the
    package, the standard library's (:mod:`csv`, ``\\n`` line ends, a cell quoted only where it holds a comma,
    a quote or a line break), so every table reads back with :mod:`csv` as its header's columns.

    A column is a sequence of ``str``, or a character matrix (:func:`int_csv_cells`, :func:`fixed_csv_cells`);
    when every column is a matrix (and no cell needs quoting), numpy puts the rows together, without a Python
    object per cell.

    >>> csv_text(["file", "error"], [["a.glimg"], ["bad header, version 9"]])
    'file,error\\na.glimg,"bad header, version 9"\\n'
    >>> csv_text(["n", "x"], [int_csv_cells(np.array([1, -22])), fixed_csv_cells(np.array([0.25, -3.0]), 1)])
    'n,x\\n1,0.2\\n-22,-3.0\\n'
    """
    matrices = [isinstance(c, np.ndarray) and c.ndim == 2 for c in cells]
    if any(matrices):
        text = _matrix_csv_text(names, cells) if all(matrices) else None
        if text is not None:
            return text
        cells = [_matrix_cells(c) if is_matrix else c for c, is_matrix in zip(cells, matrices)]
    # Fast path, byte for byte what csv writes: the rows joined, kept only when nothing needs quoting -- no
    # quote or carriage return anywhere, exactly one comma less than columns and one line end per row (a comma
    # or line break inside a cell breaks the count) and more than one column (csv quotes a lone empty cell).
    # Four times faster than csv's writer on a million rows of numbers (1.0 s -> 0.27 s for ten columns).
    text = "\n".join(map(",".join, (names, *zip(*cells)))) + "\n"
    n_rows = 1 + min((len(c) for c in cells), default=0)
    if (len(names) > 1 and '"' not in text and "\r" not in text and text.count("\n") == n_rows
            and text.count(",") == (len(names) - 1) * n_rows):
        return text
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    writer.writerows(zip(*cells))
    text = buf.getvalue()
    return text if "\r" not in text else _csv_text_quoting_cr(names, cells)


def _matrix_cells(chars: np.ndarray) -> list[str]:
    """The cells of a character matrix as text."""
    rows = np.ascontiguousarray(chars, np.uint8)
    return [b.replace(b"\0", b"").decode() for b in rows.view(f"S{max(rows.shape[1], 1)}").ravel().tolist()] \
        if rows.shape[1] else [""] * rows.shape[0]


def _matrix_csv_text(names: Sequence[str], cells: Sequence[np.ndarray]) -> str | None:
    """:func:`csv_text` of character matrices, by numpy: the cells and separators of each row side by side, the
    NUL padding dropped. None when the general writer must do it (a character at or below the comma, which may
    need quoting; one column, where :mod:`csv` quotes an empty cell; columns of different lengths)."""
    n = cells[0].shape[0] if cells else 0
    if len(names) < 2 or len(cells) != len(names) or any(c.shape[0] != n for c in cells):
        return None
    cells = [c.astype(np.uint8, copy=False) for c in cells]
    # nothing to quote when every character is above the comma ('-', '.', digits, letters): the quote, the
    # carriage return and the line feed are below it. NUL padding, less one, wraps to 255
    if n and min((int((c - np.uint8(1)).min()) for c in cells if c.size), default=255) < ord(","):
        return None
    comma, line_end = np.full((n, 1), ord(","), np.uint8), np.full((n, 1), ord("\n"), np.uint8)
    table = np.concatenate([part for chars in cells for part in (chars, comma)][:-1] + [line_end], axis=1)
    return ",".join(names) + "\n" + table[table != 0].tobytes().decode("utf-8")


def _csv_text_quoting_cr(names: Sequence[str], cells: Sequence[Sequence[str]]) -> str:
    """:func:`csv_text` for cells holding a carriage return: :mod:`csv` quotes only the characters of its line
    terminator, so each row is written with ``\\r\\n`` (a cell with ``\\r`` is quoted) and ends with ``\\n``."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\r\n")
    lines = []
    for row in (names, *zip(*cells)):
        buf.seek(0)
        buf.truncate()
        writer.writerow(row)
        lines.append(buf.getvalue()[:-2] + "\n")
    return "".join(lines)
