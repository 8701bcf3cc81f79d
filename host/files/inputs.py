"""One reader for every acceleration input a user has: :func:`read_acceleration` ->
:class:`~gaitlog.host.files.acceleration.AccelerationInput`.

Accepted inputs (detected from the bytes, not trusted from the name)
--------------------------------------------------------------------
* **Logger files** -- a memory image (``GLIM``), a raw XMODEM dump (``GLOG``) or a wire capture
  (:func:`gaitlog.host.files.decode.decode_file`), and the ``.npz`` of ``gaitlog decode``
  (:meth:`gaitlog.host.files.recording.Recording.load`; :func:`gaitlog.host.files.acceleration.read_npz` reads it
  alone, without this module's decoders). Counts become g with ``calibration`` (``gaitlog calibrate``),
  else the header's calibration slot, else the nominal map; missing samples stay missing; MARK flags are the
  lap marks.
* **IPOL lower-back layout** (:mod:`gaitlog.host.files.ipol`): a ``<s>-<t>_lb.txt`` file, its ``<s>-<t>.json``, or a
  folder holding exactly one trial (directly or in ``GaitData/``). Lost packets are missing samples.
* **CSV** (``,``, ``;`` or tab): any column order. The data start at the first line with at least three numbers
  (after ``skip_rows`` lines; ``#`` lines are comments); the non-empty line just before it, with as many
  fields, is the header. The three axes are ``columns`` (``"X,Y,Z"``: header names or 0-based indices) or
  else found by header name (``x_g``, ``acc_x``, ``ax``, ``x`` ...), or the only three numeric columns of a
  file without a header; anything else is an error asking for ``--columns``. Units come from the names
  (``_g``, ``_counts``, ``_m_s2``), else ``units``, else the median norm (~1 -> g, ~9.8 -> m/s^2). The rate is
  ``sampling_rate_hz``, else a ``time_s`` / ``time`` / ``t`` column in seconds (rows are put on that grid;
  a hole is missing samples). An empty or non-finite cell is a missing sample. The decoded CSV of
  ``gaitlog decode`` is read with its counts, g, flags (lap marks) and validity.

Nothing is interpolated here: a missing sample is NaN in ``acc_g`` and False in ``valid``.

A text file larger than :data:`STREAM_TEXT_BYTES` is parsed line by line from the file, never held whole: the
memory is the parsed table (``rows`` x ``columns`` float64, checked against the memory available as it grows), not
the text and its list of lines. No input is refused for its length: a CSV for what it parses, an NPZ for what its
arrays declare against what the zip holds (:mod:`gaitlog.host.storage.limits`).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import (
    AccelerationInput,
    check_rate,
    checked_options,
    from_recording,
    input_losses,
    ipol_named,
    npz_input,
    only_csv,
    starts_zip,
)
from gaitlog.host.files.decode import decode_bytes
from gaitlog.host.files.ipol import list_trials, read_trial
from gaitlog.host.storage.limits import (
    MAX_TEXT_BYTES,
    check_file_size,
    check_grid,
    check_memory,
    grid_limit,
)
from gaitlog.host.files.losses import say_losses
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.image import detect_format
from gaitlog.protocol.packing import FLAG_MARK
from gaitlog.units import STANDARD_GRAVITY_M_S2

# AccelerationInput, input_losses, UNITS and parse_columns are gaitlog.host.files.acceleration's
__all__ = ["STREAM_TEXT_BYTES", "read_acceleration"]

#: Text inputs larger than this are parsed line by line from the file (a logger file is far smaller: an image of
#: a full memory is under 600 kB, a wire capture of a noisy dump a few MB).
STREAM_TEXT_BYTES = 16 << 20
#: Rows parsed into one block of the table before the next is allocated.
_ROWS_PER_BLOCK = 1 << 16

#: Axis-column name triples recognised in a header (lower case), in order of preference, with their unit
#: (None: not told by the name).
_AXIS_NAMES: tuple[tuple[tuple[str, str, str], str | None], ...] = (
    (("x_g", "y_g", "z_g"), "g"),
    (("acc_x_g", "acc_y_g", "acc_z_g"), "g"),
    (("x_m_s2", "y_m_s2", "z_m_s2"), "m/s2"),
    (("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"), "m/s2"),
    (("x_counts", "y_counts", "z_counts"), "counts"),
    (("acc_x", "acc_y", "acc_z"), None),
    (("accx", "accy", "accz"), None),
    (("ax", "ay", "az"), None),
    (("x", "y", "z"), None),
)
#: Header names of a time column in seconds.
_TIME_NAMES = ("time_s", "time", "t", "t_s")
#: Median norm of gravity-including acceleration that tells the unit when nothing else does.
_NORM_RANGE = {"g": (0.5, 1.5), "m/s2": (5.0, 15.0)}


def read_acceleration(path: str | Path, *, sampling_rate_hz: float | None = None,
                      columns: str | Sequence[str | int] | None = None, units: str | None = None,
                      calibration: AccCalibration | str | Path | None = None, skip_rows: int = 0,
                      arrays: bool = True) -> AccelerationInput:
    """Read ``path`` (see the module notes); missing samples are said in one
    :class:`~gaitlog.host.files.losses.MissingSamplesWarning` (:func:`input_losses`).

    Parameters
    ----------
    path
        Logger file, ``.npz``, IPOL file or folder, or CSV.
    sampling_rate_hz
        Rate of a CSV (overrides its time column); for other inputs it must agree with the file's own rate.
    columns, units, skip_rows
        CSV only (an error for other inputs).
    calibration
        Accelerometer calibration (object or JSON path) applied to readings in its input unit.
    arrays
        False: a logger recording keeps its codes only (``acc_g`` and ``counts`` None; g block by block,
        :meth:`AccelerationInput.blocks`), for the long recordings of the streaming commands.

    Raises
    ------
    HostError
        A missing or unreadable file, an unknown format, an ambiguous or missing column, unit or rate, a flag
        that does not apply to this input; the message names the file (and line) and the flag to give.
    """
    data = _read(Path(path), sampling_rate_hz, columns, units, calibration, skip_rows, arrays)
    say_losses(input_losses(data))
    return data


def _read(p: Path, sampling_rate_hz: float | None, columns, units: str | None,
          calibration: AccCalibration | str | Path | None, skip_rows: int, arrays: bool = True) -> AccelerationInput:
    cols, cal = checked_options(sampling_rate_hz, columns, units, calibration, skip_rows)
    if p.is_dir() or ipol_named(p):
        only_csv(p, cols, units, skip_rows)
        return _from_ipol(p, sampling_rate_hz, cal)
    if not p.is_file():
        raise HostError(f"{p}: no such file")
    if starts_zip(p):                              # an NPZ: judged by its arrays, read from the file (not whole)
        return npz_input(p, cols, units, skip_rows, sampling_rate_hz, cal, arrays)
    large = _large_text(p)
    if large is not None:
        if large.lstrip().lower().startswith("acquisition frequency"):
            only_csv(p, cols, units, skip_rows)
            return _from_ipol(p, sampling_rate_hz, cal)
        try:
            with p.open(encoding="utf-8-sig", errors="replace", newline=None) as fh:
                return _from_csv(p, fh, sampling_rate_hz, cols, units, cal, skip_rows)
        except OSError as err:
            raise HostError(f"{p}: cannot read: {err.strerror or err}") from err
    check_file_size(p, MAX_TEXT_BYTES, "an input file")   # read whole: a logger file, or a small text
    try:
        data = p.read_bytes()
    except OSError as err:
        raise HostError(f"{p}: cannot read: {err.strerror or err}") from err
    if not data:
        raise HostError(f"{p}: empty file")
    kind = _kind(data, p)
    if kind == "text":
        text = data.decode("utf-8-sig", errors="replace")
        if text.lstrip().lower().startswith("acquisition frequency"):
            only_csv(p, cols, units, skip_rows)
            return _from_ipol(p, sampling_rate_hz, cal)
        return _from_csv(p, text.splitlines(), sampling_rate_hz, cols, units, cal, skip_rows)
    only_csv(p, cols, units, skip_rows)
    return from_recording(decode_bytes(data, source=str(p)), p, sampling_rate_hz, cal, arrays)


# ------------------------------------------------------------------------------------------------ formats
def _kind(data: bytes, p: Path) -> str:
    """``logger`` (image, raw dump, capture) or ``text``."""
    try:
        detect_format(data)
        return "logger"
    except ProtocolError as err:
        try:
            data[:65536].decode("utf-8")
        except UnicodeDecodeError as uerr:
            if uerr.start < 65536 - 4:        # not a character cut at the probe's end
                raise HostError(f"{p}: not a logger file, a decoded .npz, an IPOL file or a CSV text (not UTF-8 at "
                                f"byte {uerr.start}; {err.message})") from None
        return "text"


def _large_text(p: Path) -> str | None:
    """The first 64 KiB of ``p`` as text when ``p`` is a text file larger than :data:`STREAM_TEXT_BYTES` (to be
    parsed line by line), else None (read whole: small, a logger file, or not text)."""
    try:
        if p.stat().st_size <= STREAM_TEXT_BYTES:
            return None
        with p.open("rb") as fh:
            probe = fh.read(65536)
    except OSError as err:
        raise HostError(f"{p}: cannot read: {err.strerror or err}") from err
    try:
        detect_format(probe)
        return None
    except ProtocolError:
        pass
    try:
        return probe.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        if err.start < len(probe) - 4:
            return None                           # not text: the whole-file reader names the problem
        return probe[:err.start].decode("utf-8-sig")


def _from_ipol(p: Path, rate: float | None, cal: AccCalibration | None) -> AccelerationInput:
    lb = p
    if p.is_dir():
        trials = list_trials(p)
        if len(trials) != 1:
            raise HostError(f"{p}: holds {len(trials)} IPOL trials ({', '.join(t.name for t in trials[:4])}"
                            f"{' ...' if len(trials) > 4 else ''}); give one trial's _lb.txt file")
        lb = trials[0]
    elif p.suffix.lower() == ".json":
        lb = p.with_name(p.stem + "_lb.txt")
    if not lb.is_file():
        raise HostError(f"{lb}: no such file")
    trial = read_trial(lb)
    check_rate(p, trial.sampling_rate_hz, rate)
    acc = trial.acc_g
    note = "m/s^2 / 9.80665"
    if cal is not None:
        if cal.input_unit != "g":
            raise HostError(f"{p}: the calibration takes {cal.input_unit}, this file holds acceleration (g)")
        acc, note = np.asarray(cal.apply(acc), np.float64), "g from the given calibration"
    return AccelerationInput(acc, trial.valid.copy(), trial.sampling_rate_hz, np.zeros(0, np.int64),
                             f"{lb} (IPOL lower back; {note})", ipol_trial=trial)


def _split(line: str, delim: str) -> list[str]:
    return [f.strip() for f in line.split(delim)]


def _number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _from_csv(p: Path, lines: Iterable[str], rate: float | None, cols: list[str | int] | None, units: str | None,
              cal: AccCalibration | None, skip_rows: int) -> AccelerationInput:
    """A CSV from its ``lines`` (a list, or an open file read line by line: nothing but the table is kept)."""
    it = iter(lines)
    start, first, delim, header = _data_start(p, it, skip_rows)
    names = [h.lower() for h in header]
    numeric = [j for j, f in enumerate(_split(first, delim)) if _number(f)]
    axes = _axes(p, names, header, numeric, cols, units)
    time_col = next((names.index(t) for t in _TIME_NAMES if t in names), None) if rate is None else None
    extra = {names.index(c) for c in ("flags", "valid") if c in names}
    want = sorted({c for triple, _ in axes for c in triple} | ({time_col} if time_col is not None else set()) | extra)
    table = _parse_rows(p, itertools.chain([first], it), start, delim, want, header)
    pos = {c: k for k, c in enumerate(want)}
    if table.shape[0] < 2:
        raise HostError(f"{p}: fewer than 2 data lines")
    parts = _unit_parts(p, table, axes, pos)
    ok = np.all([np.all(np.isfinite(v), axis=1) for v in parts.values()], axis=0)
    if "valid" in names:
        ok &= table[:, pos[names.index("valid")]] == 1
    if rate is None:
        if time_col is None:
            raise HostError(f"{p}: no time column ({'/'.join(_TIME_NAMES)}) to take the rate from; give --rate HZ")
        rate, grid = _time_grid(p, table[:, pos[time_col]], start)
    else:
        grid = np.arange(table.shape[0])
    n = int(grid[-1]) + 1 if grid.size else 0
    valid = np.zeros(n, bool)
    valid[grid] = ok
    marks = np.zeros(0, np.int64)
    if "flags" in names:
        flags = np.nan_to_num(table[:, pos[names.index("flags")]]).astype(np.int64)
        marks = grid[(flags & FLAG_MARK) != 0]
    g, counts, note = _csv_g(p, parts, grid, valid, cal)
    if g is not None:
        valid &= np.all(np.isfinite(g), axis=1)
    unit_words = " and ".join(sorted(parts))
    return AccelerationInput(g, valid, float(rate), marks, f"{p} (CSV, {unit_words}; {note})", counts)


def _data_start(p: Path, it: Iterator[str], skip_rows: int) -> tuple[int, str, str, list[str]]:
    """The first data line of a CSV (module notes), read from ``it`` up to it: its index, the line, the delimiter
    and the header's fields (empty without a header)."""
    prev = None
    for i, line in enumerate(it):
        if i < skip_rows or not line.strip() or line.lstrip().startswith("#"):
            continue
        delim = next((d for d in ("\t", ";", ",") if d in line), ",")
        fields = _split(line, delim)
        if sum(_number(f) for f in fields) >= 3:
            return i, line, delim, prev if prev is not None and len(prev) == len(fields) else []
        prev = fields
    raise HostError(f"{p}: no line with three numbers (after {skip_rows} skipped); is this a CSV of accelerations?")


def _unit_parts(p: Path, table: np.ndarray, axes: list[tuple[list[int], str]], pos: dict[int, int]
                ) -> dict[str, np.ndarray]:
    """``{unit: (rows, 3) columns}`` of the axis triples, the unit of an unnamed one told by the norm, each norm
    checked against gravity in its unit."""
    parts = {unit: _columns(table, [pos[c] for c in triple]) for triple, unit in axes}
    if "auto" in parts:
        v = parts.pop("auto")
        parts[_unit_from_norm(p, v)] = v
    for unit in ("g", "m/s2"):
        if unit in parts:
            _check_norm(p, parts[unit], unit)
    return parts


def _csv_g(p: Path, parts: dict[str, np.ndarray], grid: np.ndarray, valid: np.ndarray, cal: AccCalibration | None
           ) -> tuple[np.ndarray | None, np.ndarray | None, str]:
    """(g, counts, how g was obtained) on the grid, NaN where not ``valid``; g None for counts without a
    calibration."""
    n = valid.size

    def on_grid(v: np.ndarray) -> np.ndarray:
        if n == v.shape[0]:                # every row on its own grid point: the table's columns, NaN where missing
            out = v
        else:
            out = np.full((n, 3), np.nan)
            out[grid] = v
        out[~valid] = np.nan
        return out

    g = on_grid(parts["g"]) if "g" in parts else None
    counts = on_grid(parts["counts"]) if "counts" in parts else None
    note = "g"
    if "m/s2" in parts:
        g, note = on_grid(parts["m/s2"]) / STANDARD_GRAVITY_M_S2, "m/s^2 / 9.80665"
    if cal is not None:
        raw = counts if cal.input_unit == "counts" else g
        if raw is None:
            raise HostError(f"{p}: the calibration takes {cal.input_unit}, this file has no such columns")
        g, note = np.asarray(cal.apply(raw), np.float64), "g from the given calibration"
    elif g is None:
        note = "ADC counts"
    return g, counts, note


def _columns(table: np.ndarray, index: list[int]) -> np.ndarray:
    """``table[:, index]``, a view when the columns are adjacent and in order (a long table is not copied)."""
    if index == list(range(index[0], index[0] + len(index))):
        return table[:, index[0]:index[0] + len(index)]
    return table[:, index]


def _parse_rows(p: Path, lines: Iterable[str], start: int, delim: str, want: list[int],
                header: list[str]) -> np.ndarray:
    """The ``want`` columns of the data lines (line ``start`` on; blank and ``#`` lines skipped) as float64, NaN
    for an empty cell; filled a block of rows at a time, the table (and its final copy) checked against the memory
    available before each block is allocated (:func:`~gaitlog.host.storage.limits.check_memory`)."""
    blocks: list[np.ndarray] = []
    block = np.full((_ROWS_PER_BLOCK, len(want)), np.nan)
    k = 0
    for line_no, ln in enumerate(lines, start + 1):   # text, one line at a time (np.loadtxt cannot take empty cells)
        if not ln.strip() or ln.lstrip().startswith("#"):
            continue
        if k == _ROWS_PER_BLOCK:  # a row past a full block: the table judged before the next block is allocated
            blocks.append(block)
            check_memory(2 * (len(blocks) + 1) * block.nbytes, p, f"line {line_no}: the table so far")
            block, k = np.full((_ROWS_PER_BLOCK, len(want)), np.nan), 0
        cells = ln.split(delim)
        if len(cells) <= want[-1]:
            raise HostError(f"{p}: line {line_no}: {len(cells)} fields, column {want[-1]} is missing")
        for j, c in enumerate(want):
            v = cells[c].strip()
            if v:
                try:
                    block[k, j] = float(v)
                except ValueError:
                    name = header[c] if header else f"column {c}"
                    raise HostError(f"{p}: line {line_no}, {name}: not a number: {v!r}") from None
        k += 1
    blocks.append(block[:k])
    if len(blocks) == 1:
        return blocks[0]
    table = np.empty((sum(b.shape[0] for b in blocks), len(want)))   # pages taken as the blocks are copied in
    at = 0
    for i, b in enumerate(blocks):
        table[at:at + b.shape[0]] = b
        at += b.shape[0]
        blocks[i] = b = None               # each block given back once copied: the peak is the table and one block
    return table


def _axes(p: Path, names: list[str], header: list[str], numeric: list[int], cols: list[str | int] | None,
          units: str | None) -> list[tuple[list[int], str]]:
    """The axis column triples to read, each with its unit (the decoded CSV has both counts and g)."""
    if cols is not None:
        idx = []
        for c in cols:
            if isinstance(c, int):
                if not 0 <= c < max(len(names), numeric[-1] + 1):
                    raise HostError(f"{p}: --columns: index {c} is outside the file's columns")
                idx.append(c)
            elif c.lower() in names:
                idx.append(names.index(c.lower()))
            else:
                raise HostError(f"{p}: --columns: no column {c!r} (header: {', '.join(header) or 'none'})")
        hint = next((u for t, u in _AXIS_NAMES if tuple(names[i] for i in idx if i < len(names)) == t), None)
        return [(idx, _unit(p, hint, units))]
    found = [([names.index(a) for a in t], u) for t, u in _AXIS_NAMES if all(a in names for a in t)]
    if found:
        named = [(i, u) for i, u in found if u is not None]
        if units is not None or not named:
            return [(found[0][0], _unit(p, found[0][1], units))]
        return [(i, u) for i, u in named if u in ("g", "counts")][:2] or [named[0]]
    if len(numeric) == 3:
        return [(numeric, _unit(p, None, units))]
    raise HostError(f"{p}: cannot tell which columns are x, y, z ({len(numeric)} numeric columns"
                    f"{', header: ' + ', '.join(header) if header else ', no header'}); give --columns X,Y,Z")


def _unit(p: Path, hint: str | None, units: str | None) -> str:
    if units is not None and hint is not None and units != hint:
        raise HostError(f"{p}: the column names say {hint}, --units says {units}")
    return units or hint or "auto"


def _median_norm(v: np.ndarray) -> float:
    """Median norm of the finite rows of ``v`` (``np.linalg.norm``'s sums, a block of rows at a time, into one
    array whose median is taken in place: 8 bytes a row, not three copies of the table)."""
    finite = np.all(np.isfinite(v), axis=1)
    norm = np.empty(int(np.count_nonzero(finite)))
    at = 0
    for lo in range(0, v.shape[0], _ROWS_PER_BLOCK):
        b = v[lo:lo + _ROWS_PER_BLOCK][finite[lo:lo + _ROWS_PER_BLOCK]]
        np.sqrt(np.add.reduce(b * b, axis=1), out=norm[at:at + b.shape[0]])
        at += b.shape[0]
    return float(np.median(norm, overwrite_input=True)) if norm.size else float("nan")


def _unit_from_norm(p: Path, v: np.ndarray) -> str:
    norm = _median_norm(v)
    for unit, (lo, hi) in _NORM_RANGE.items():
        if lo <= norm <= hi:
            return unit
    raise HostError(f"{p}: cannot tell the unit from a median acceleration norm of {norm:.3g} (~1 for g, ~9.8 "
                    "for m/s^2); give --units g|m/s2|counts")


def _check_norm(p: Path, v: np.ndarray, unit: str) -> None:
    lo, hi = _NORM_RANGE[unit]
    norm = _median_norm(v)
    if not lo <= norm <= hi:
        raise HostError(f"{p}: median acceleration norm is {norm:.3g}, not what gravity gives in {unit} "
                        f"({lo:g}-{hi:g}); check --units and --columns")


def _time_grid(p: Path, t: np.ndarray, start: int) -> tuple[float, np.ndarray]:
    """Rate from the median step of the time column, and each row's grid index."""
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise HostError(f"{p}: line {start + bad[0] + 1}: the time column is empty; give --rate HZ instead")
    dt = np.diff(t)
    if dt.size == 0 or not np.all(dt > 0):
        k = int(np.flatnonzero(dt <= 0)[0]) if dt.size else 0
        raise HostError(f"{p}: line {start + k + 2}: time does not increase; give --rate HZ instead")
    step = float(np.median(dt))
    span = (t[-1] - t[0]) / step
    if not span < grid_limit(t.size):
        k = int(np.argmax(dt))
        check_grid(int(min(span, 2**62)) + 1, t.size, p, f"line {start + k + 2}: a time gap of {dt[k]:g} s at a "
                   f"{1.0 / step:g} Hz grid")
    check_memory(int(span + 1) * 49, p, "its time grid")     # g and counts (n, 3) float64, valid
    grid = np.round((t - t[0]) / step).astype(np.int64)
    if np.any(np.diff(grid) <= 0):
        raise HostError(f"{p}: the times are not on a regular grid (two rows within one step); give --rate HZ")
    return 1.0 / step, grid
