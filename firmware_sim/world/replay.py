"""Replay of a real recording as the physical motion the logger experiences.

A recording (acceleration in g or m/s^2, gravity included, at its own rate) is taken as the true specific
force along the device's nominal axes and resampled to whatever rate the sensor model asks for, with an
anti-aliasing polyphase filter (:func:`firmware_sim.world.resampling.resample_g`; never by picking samples).

Two file formats are read by :meth:`Replay.from_file`:

- **IPOL lower-back** (Voisard et al., IPOL 2023): tab-separated, a first line ``Acquisition frequency:
  100 Hz``, a header ``PacketCounter Acc_X Acc_Y Acc_Z ...``, acceleration in m/s^2. The files have lost
  packets: every row is placed on the regular ``PacketCounter`` grid (grid index ``i`` is packet
  ``first_counter + i``; the counter is unwrapped modulo 2^16). The physical input over a lost packet was
  continuous, so the missing samples are *interpolated* (linearly between the neighbouring packets) to
  keep the input continuous, and every filled range is reported in the truth (``filled_ranges_s``,
  ``filled_packets``): those stretches are not measured motion. A duplicated packet keeps its first copy.
- **CSV**: comma-separated (or ``;``/tab), optional header lines; three acceleration columns chosen by
  ``columns`` (names or 0-based indices; default: the first three numeric columns of the first data row,
  or columns named like ``x``/``acc_x``), and either a time column in seconds (``time_column``) or a rate
  (``sampling_rate_hz``). With a time column the rows are put on a regular grid at the median step; gaps longer
  than 1.5 steps are interpolated and reported like lost packets.

Units: ``"g"``, ``"m/s^2"`` or ``"auto"`` (mean norm near 1 -> g, near 9.8 -> m/s^2; anything else is an
error asking for explicit units).
"""

from __future__ import annotations

import io
import json
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from firmware_sim.errors import DeviceError
from firmware_sim.world.base import STANDARD_GRAVITY_M_S2, Motion
from firmware_sim.world.resampling import resample_g

__all__ = ["Replay", "detect_units", "to_g", "regular_grid"]

_UNITS = {"g": 1.0, "m/s^2": 1.0 / STANDARD_GRAVITY_M_S2, "m/s2": 1.0 / STANDARD_GRAVITY_M_S2}
_IPOL_FIRST = re.compile(r"^\s*Acquisition frequency:\s*([0-9.]+)\s*Hz", re.IGNORECASE)


def detect_units(acc: np.ndarray, *, source: str = "recording") -> str:
    """Guess the units of gravity-including acceleration from its mean norm.

    Returns ``"g"`` when the mean of the sample norms is within 0.5-1.5, ``"m/s^2"`` within 5-15;
    raises :class:`DeviceError` otherwise (say the units explicitly).

    >>> detect_units(np.array([[0.0, 0.0, 1.02]])), detect_units(np.array([[0.0, 9.7, 0.5]]))
    ('g', 'm/s^2')
    """
    norm = float(np.mean(np.linalg.norm(acc, axis=1)))
    if 0.5 <= norm <= 1.5:
        return "g"
    if 5.0 <= norm <= 15.0:
        return "m/s^2"
    raise DeviceError(
        f"{source}: cannot tell the units from a mean acceleration norm of {norm:.3g} "
        "(expected ~1 for g or ~9.8 for m/s^2); pass units='g' or units='m/s^2'"
    )


def to_g(acc: np.ndarray, units: str, *, source: str = "recording") -> tuple[np.ndarray, str]:
    """Convert ``acc`` to g; ``units`` is ``"g"``, ``"m/s^2"`` or ``"auto"``. Returns (acc_g, units used)."""
    if units == "auto":
        units = detect_units(acc, source=source)
    if units not in _UNITS:
        raise DeviceError(f"{source}: unknown units {units!r}; use 'g', 'm/s^2' or 'auto'")
    return acc * _UNITS[units], units


def regular_grid(index: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Place ``values`` at integer grid positions ``index`` (sorted, unique) and interpolate the holes.

    Returns the ``(m, k)`` filled array, ``m = index[-1] - index[0] + 1``, and a bool mask ``filled``
    (True where a value was interpolated).

    >>> v, f = regular_grid(np.array([0, 1, 4]), np.array([[0.0], [1.0], [4.0]]))
    >>> v[:, 0].tolist(), f.tolist()
    ([0.0, 1.0, 2.0, 3.0, 4.0], [False, False, True, True, False])
    """
    rel = index - index[0]
    m = int(rel[-1]) + 1
    grid = np.arange(m)
    out = np.empty((m, values.shape[1]), dtype=np.float64)
    for j in range(values.shape[1]):  # 3 columns: one np.interp each
        out[:, j] = np.interp(grid, rel, values[:, j])
    filled = np.ones(m, dtype=bool)
    filled[rel] = False
    return out, filled


def _ranges(mask: np.ndarray) -> np.ndarray:
    """``(k, 2)`` [first, last] index pairs of the True runs of ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return np.c_[np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1]


class Replay:
    """A recorded acceleration replayed as the logger's physical input.

    Parameters
    ----------
    acc_g
        ``(n, 3)`` specific force in g on a regular grid, gravity included, device axes.
    sampling_rate_hz
        Rate of ``acc_g`` in Hz.
    t0_s
        Time of the first sample, seconds.
    truth
        Ground truth and provenance passed through to :class:`Motion` (``filled_ranges_s`` etc.).
    marker_times_s
        Marker-button times, seconds.

    Examples
    --------
    >>> t = np.arange(1000) / 100.0
    >>> acc = np.c_[0.1 * np.sin(2 * np.pi * t), np.zeros_like(t), np.ones_like(t)]
    >>> m = Replay(acc, sampling_rate_hz=100.0).render(500.0)
    >>> m.n_samples, m.sampling_rate_hz
    (5000, 500.0)
    """

    def __init__(
        self,
        acc_g: np.ndarray,
        *,
        sampling_rate_hz: float,
        t0_s: float = 0.0,
        truth: Mapping[str, Any] | None = None,
        marker_times_s: np.ndarray | Sequence[float] = (),
    ) -> None:
        self.acc_g = np.asarray(acc_g, dtype=np.float64)
        self.sampling_rate_hz = float(sampling_rate_hz)
        self.t0_s = float(t0_s)
        self.truth = dict(truth or {})
        self.marker_times_s = np.asarray(marker_times_s, dtype=np.float64)

    def render(self, sampling_rate_hz: float) -> Motion:
        """The recording resampled to ``sampling_rate_hz`` (anti-aliased; the exact achieved rate is in the Motion)."""
        if self.acc_g.ndim != 2 or self.acc_g.shape[1] != 3 or self.acc_g.shape[0] < 2:
            raise DeviceError(f"replay needs an (n >= 2, 3) acceleration array, got {self.acc_g.shape}")
        acc, rate = resample_g(self.acc_g, self.sampling_rate_hz, sampling_rate_hz)
        truth = dict(self.truth)
        truth.setdefault("source_rate_hz", self.sampling_rate_hz)
        return Motion(acc_g=acc, sampling_rate_hz=rate, t0_s=self.t0_s, truth=truth, marker_times_s=self.marker_times_s)

    @property
    def n_interpolated(self) -> int:
        """Samples of :attr:`acc_g` interpolated over lost packets or gaps (not measured motion)."""
        return int(self.truth.get("n_filled", 0))

    @classmethod
    def from_samples(cls, acc_g: np.ndarray, valid: np.ndarray, *, sampling_rate_hz: float, source: str = "recording",
                     marker_times_s: np.ndarray | Sequence[float] = ()) -> Replay:
        """A recording on a regular grid with missing samples (``valid`` False): the holes are interpolated
        linearly, as the physical input was continuous, and reported (``truth["n_filled"]``,
        :attr:`n_interpolated`, ``filled_ranges_s``).

        >>> r = Replay.from_samples(np.ones((5, 3)), np.array([1, 0, 0, 1, 1], bool), sampling_rate_hz=10.0)
        >>> r.n_interpolated, r.truth["filled_packets"].tolist()
        (2, [[1, 2]])
        """
        ok = np.asarray(valid, bool) & np.all(np.isfinite(acc_g), axis=1)
        idx = np.flatnonzero(ok)
        if idx.size < 2:
            raise DeviceError(f"{source}: fewer than 2 measured samples to replay")
        grid, filled = regular_grid(idx, np.asarray(acc_g, np.float64)[idx])
        truth = _fill_truth(filled, float(sampling_rate_hz))
        truth.update(source=source, first_sample=int(idx[0]))
        return cls(grid, sampling_rate_hz=float(sampling_rate_hz), t0_s=idx[0] / float(sampling_rate_hz), truth=truth,
                   marker_times_s=marker_times_s)

    # -- file readers -------------------------------------------------------------------------------------
    @classmethod
    def from_file(
        cls,
        path: str | Path,
        *,
        units: str = "auto",
        sampling_rate_hz: float | None = None,
        columns: Sequence[str | int] | None = None,
        time_column: str | int | None = None,
        delimiter: str | None = None,
    ) -> Replay:
        """Read an IPOL lower-back file or a CSV file (see the module docstring).

        Parameters
        ----------
        path
            The recording.
        units
            ``"g"``, ``"m/s^2"`` or ``"auto"``.
        sampling_rate_hz
            Sample rate of a CSV without time column (overrides the IPOL first line if given).
        columns
            Three acceleration columns (header names or 0-based indices), x, y, z in device axes.
        time_column
            CSV column of sample times in seconds.
        delimiter
            CSV delimiter; default sniffed from the first data line (``,``, ``;`` or tab).

        Raises
        ------
        DeviceError
            Missing file, no data rows, non-numeric values (row and column named), undecidable units,
            missing rate, non-increasing times.
        """
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8", errors="replace")
        except OSError as err:
            raise DeviceError(f"{p}: cannot read recording: {err.strerror or err}") from err
        first = text.split("\n", 1)[0]
        if _IPOL_FIRST.match(first):
            return cls._from_ipol(p, text, units=units, sampling_rate_hz=sampling_rate_hz, columns=columns)
        return cls._from_csv(
            p, text, units=units, sampling_rate_hz=sampling_rate_hz, columns=columns, time_column=time_column, delimiter=delimiter
        )

    @classmethod
    def _from_ipol(
        cls, p: Path, text: str, *, units: str, sampling_rate_hz: float | None, columns: Sequence[str | int] | None
    ) -> Replay:
        lines = text.splitlines()
        file_rate = float(_IPOL_FIRST.match(lines[0]).group(1))  # type: ignore[union-attr]
        if len(lines) < 3:
            raise DeviceError(f"{p}: IPOL file has no data rows")
        names = lines[1].split("\t")
        cols = list(columns) if columns is not None else ["Acc_X", "Acc_Y", "Acc_Z"]
        idx = [_column_index(c, names, p) for c in cols]
        if "PacketCounter" not in names:
            raise DeviceError(f"{p}: line 2: no PacketCounter column in the IPOL header")
        ci = names.index("PacketCounter")
        try:
            data = np.loadtxt(io.StringIO("\n".join(lines[2:])), delimiter="\t", ndmin=2)
        except ValueError as err:
            raise DeviceError(f"{p}: IPOL data rows (from line 3): {err}") from err
        if data.shape[1] != len(names):
            raise DeviceError(f"{p}: expected {len(names)} columns per row, found {data.shape[1]}")
        counter = data[:, ci].astype(np.int64)
        # unwrap a 16-bit packet counter
        steps = np.diff(counter) % 65536
        grid = np.r_[0, np.cumsum(steps)] + counter[0]
        keep = np.r_[True, steps != 0]
        if not keep.all():
            dup = np.flatnonzero(~keep)
            if not np.allclose(data[dup][:, idx], data[dup - 1][:, idx]):
                warnings.warn(f"{p}: duplicated packets with different values; kept the first copy", stacklevel=3)
        grid, acc_raw = grid[keep], data[keep][:, idx]
        acc, used = to_g(acc_raw, units, source=str(p))
        acc_grid, filled = regular_grid(grid, acc)
        rate = float(sampling_rate_hz) if sampling_rate_hz is not None else file_rate
        truth = _fill_truth(filled, rate)
        truth.update(
            source=str(p), format="ipol", units=used, first_packet_counter=int(grid[0]),
            n_duplicates=int((~keep).sum()),
        )
        meta = p.with_name(p.name.replace("_lb.txt", ".json"))
        if meta.is_file():
            try:
                truth["ipol_meta"] = json.loads(meta.read_text())
            except (OSError, ValueError) as err:
                warnings.warn(f"{meta}: metadata not read ({err})", stacklevel=3)
        return cls(acc_grid, sampling_rate_hz=rate, truth=truth)

    @classmethod
    def _from_csv(
        cls,
        p: Path,
        text: str,
        *,
        units: str,
        sampling_rate_hz: float | None,
        columns: Sequence[str | int] | None,
        time_column: str | int | None,
        delimiter: str | None,
    ) -> Replay:
        lines = text.splitlines()
        # the data start at the first line with at least 3 numeric fields ('#' comment lines skipped); the
        # last non-empty line before it, if it has as many fields, is the header of column names
        start, names, d = None, [], delimiter or ","
        prev: list[str] | None = None
        for i, line in enumerate(lines):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            d = delimiter or _sniff_delimiter(line)
            fields = [f.strip() for f in line.split(d)]
            if sum(_is_number(f) for f in fields) >= 3:
                start = i
                names = prev if prev is not None and len(prev) == len(fields) else []
                n_fields = len(fields)
                first_numeric = [j for j, f in enumerate(fields) if _is_number(f)]
                break
            prev = fields
        if start is None:
            raise DeviceError(f"{p}: no data row with 3 numeric fields found (is this a CSV of accelerations?)")
        if columns is None:
            lowered = [n.lower() for n in names]
            guess = [_find_axis(lowered, a) for a in "xyz"]
            cols: list[str | int] = guess if all(g is not None for g in guess) else first_numeric[:3]  # type: ignore[assignment]
        else:
            cols = list(columns)
        if len(cols) != 3:
            raise DeviceError(f"{p}: need exactly 3 acceleration columns, got {cols!r}")
        idx = [_column_index(c, names, p, n_fields=n_fields) for c in cols]
        tcol = None if time_column is None else _column_index(time_column, names, p, n_fields=n_fields)
        use = idx + ([tcol] if tcol is not None else [])
        try:
            data = np.loadtxt(
                io.StringIO("\n".join(lines[start:])), delimiter=d, usecols=use, ndmin=2, comments="#"
            )
        except ValueError as err:
            raise DeviceError(f"{p}: data rows from line {start + 1}: {err}") from err
        if data.shape[0] < 2:
            raise DeviceError(f"{p}: need at least 2 data rows")
        acc_raw = data[:, :3]
        acc, used = to_g(acc_raw, units, source=str(p))
        truth: dict[str, Any] = {"source": str(p), "format": "csv", "units": used, "columns": cols}
        if time_column is not None:
            t = data[:, 3]
            dt = np.diff(t)
            if not (dt > 0).all():
                k = int(np.flatnonzero(dt <= 0)[0])
                raise DeviceError(f"{p}: line {start + k + 2}: time does not increase ({t[k]} -> {t[k + 1]})")
            step = float(np.median(dt))
            rate = float(sampling_rate_hz) if sampling_rate_hz is not None else 1.0 / step
            pos = np.round((t - t[0]) * rate).astype(np.int64)
            keep = np.r_[True, np.diff(pos) > 0]
            acc_grid, filled = regular_grid(pos[keep], acc[keep])
            truth.update(_fill_truth(filled, rate))
            return cls(acc_grid, sampling_rate_hz=rate, t0_s=float(t[0]), truth=truth)
        if sampling_rate_hz is None:
            raise DeviceError(f"{p}: no time column given: pass sampling_rate_hz (the sample rate of the file)")
        truth.update(_fill_truth(np.zeros(acc.shape[0], dtype=bool), float(sampling_rate_hz)))
        return cls(acc, sampling_rate_hz=float(sampling_rate_hz), truth=truth)


def _fill_truth(filled: np.ndarray, sampling_rate_hz: float) -> dict[str, Any]:
    r = _ranges(filled)
    return {
        "filled": filled,
        "filled_packets": r,
        "filled_ranges_s": r / sampling_rate_hz + np.array([0.0, 1.0 / sampling_rate_hz]) * (r.size > 0),
        "n_filled": int(filled.sum()),
    }


def _sniff_delimiter(line: str) -> str:
    for d in ("\t", ";", ","):
        if d in line:
            return d
    return ","


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _find_axis(lowered: list[str], axis: str) -> int | None:
    for cand in (axis, f"acc_{axis}", f"acc{axis}", f"a{axis}", f"accel_{axis}"):
        if cand in lowered:
            return lowered.index(cand)
    return None


def _column_index(col: str | int, names: list[str], p: Path, *, n_fields: int | None = None) -> int:
    n = n_fields if n_fields is not None else len(names)
    if isinstance(col, (int, np.integer)):
        if not 0 <= int(col) < n:
            raise DeviceError(f"{p}: column index {col} outside 0..{n - 1}")
        return int(col)
    if col in names:
        return names.index(col)
    if col.isdigit():
        return _column_index(int(col), names, p, n_fields=n)
    raise DeviceError(f"{p}: no column named {col!r} (columns: {', '.join(names) or 'none, no header'})")
