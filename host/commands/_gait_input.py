"""Input of the gait commands (``estimate``, ``calibrate-k``): a decoded recording or a CSV -> g.

Not a command (the leading underscore keeps it out of ``gaitlog --help``).

Accepted inputs
---------------
* ``.npz`` written by ``gaitlog decode`` (:meth:`host.files.recording.Recording.load`): counts converted with the
  header's calibration slot (else the nominal map) or ``--calibration``; invalid samples stay missing;
  MARK flags give the lap marks.
* ``.csv`` written by ``gaitlog decode`` (header ``sample_number,time_s,...,x_g,y_g,z_g,flags,valid``).
* Any other ``.csv``: acceleration in g in the columns named ``x_g,y_g,z_g`` / ``x,y,z`` / ``acc_x,...``
  or else the first three columns; an optional header line; empty cells are missing samples; the rate
  comes from ``--rate``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from host.errors import HostError


@dataclass
class GaitInput:
    """Calibrated acceleration of one input file."""

    acc_g: Any            # (n, 3) float64, g, NaN where missing
    valid: Any            # (n,) bool
    sampling_rate_hz: float
    mark_index: Any = field(default_factory=list)   # sample indices of MARK flags
    note: str = ""


def add_anatomy_options(parser: argparse.ArgumentParser) -> None:
    """--leg-length / --foot-length / --height and --rate."""
    parser.add_argument("--leg-length", type=float, metavar="M", help="leg length (greater trochanter to floor), m")
    parser.add_argument("--foot-length", type=float, metavar="M",
                        help="foot length heel to first metatarsal head (M3's S2), m")
    parser.add_argument("--height", type=float, metavar="M",
                        help="body height, m: leg and foot length are estimated from it when not given "
                             "(Winter; ANSUR; host.gait.anthropometry)")
    parser.add_argument("--rate", type=float, metavar="HZ", help="sample rate of a plain CSV input, Hz")
    parser.add_argument("--calibration", metavar="CAL.json",
                        help="accelerometer calibration (gaitlog calibrate) for an .npz input")


def load_input(path: str | Path, *, rate_hz: float | None = None, calibration: str | None = None) -> GaitInput:
    """Read ``path`` (see module notes). Raises :class:`HostError` naming the problem and the place."""
    import numpy as np

    from protocol.packing import FLAG_MARK

    p = Path(path)
    if not p.is_file():
        raise HostError(f"{p}: no such file")
    if p.suffix.lower() == ".npz":
        from host.files.recording import Recording

        rec = Recording.load(p)
        cal = None
        note = rec.default_calibration()[1]
        if calibration:
            from host.accelerometer.calibration import AccCalibration

            cal = AccCalibration.load(calibration)
            note = f"g from {calibration}"
        acc = rec.acc_g(cal)
        marks = np.flatnonzero((rec.flags & FLAG_MARK) != 0)
        valid = rec.valid & np.all(np.isfinite(acc), axis=1)
        return GaitInput(acc, valid, float(rec.sampling_rate_hz), marks, note)
    if p.suffix.lower() in (".csv", ".txt"):
        return _load_csv(p, rate_hz)
    raise HostError(f"{p}: unknown input type {p.suffix!r}; expected a decoded .npz or a .csv")


def _load_csv(p: Path, rate_hz: float | None) -> GaitInput:
    import numpy as np

    from protocol.packing import FLAG_MARK

    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as err:
        raise HostError(f"{p}: cannot read: {err}") from err
    lines = [ln for ln in lines if ln.strip()]
    if not lines:
        raise HostError(f"{p}: empty file")
    first = [c.strip().lower() for c in lines[0].split(",")]
    has_header = not all(_is_number(c) or c == "" for c in first)
    names = first if has_header else []
    body = lines[1:] if has_header else lines
    if not body:
        raise HostError(f"{p}: no data rows")
    from host.files.recording import CSV_COLUMNS

    decoded = names == list(CSV_COLUMNS)
    if decoded:
        cols = [names.index(c) for c in ("x_g", "y_g", "z_g")]
    else:
        cols = None
        for cand in (("x_g", "y_g", "z_g"), ("acc_x_g", "acc_y_g", "acc_z_g"), ("x", "y", "z"),
                     ("acc_x", "acc_y", "acc_z"), ("ax", "ay", "az")):
            if all(c in names for c in cand):
                cols = [names.index(c) for c in cand]
                break
        if cols is None:
            cols = [0, 1, 2]
    rows = np.full((len(body), 3), np.nan)
    flags = np.zeros(len(body), np.int64)
    times = np.full(len(body), np.nan)
    for i, ln in enumerate(body):  # parsing text, one line at a time
        cells = ln.split(",")
        if len(cells) <= max(cols):
            raise HostError(f"{p}: line {i + 1 + has_header}: expected at least {max(cols) + 1} columns, "
                            f"found {len(cells)}")
        for k, c in enumerate(cols):
            v = cells[c].strip()
            if v:
                try:
                    rows[i, k] = float(v)
                except ValueError:
                    raise HostError(f"{p}: line {i + 1 + has_header}, column {c + 1}: not a number: {v!r}") from None
        if decoded:
            f = cells[names.index("flags")].strip()
            flags[i] = int(float(f)) if f else 0
            t = cells[names.index("time_s")].strip()
            times[i] = float(t) if t else np.nan
    valid = np.all(np.isfinite(rows), axis=1)
    if decoded:
        if rate_hz is None:
            dt = np.diff(times[np.isfinite(times)])
            if dt.size == 0 or not np.all(dt > 0):
                raise HostError(f"{p}: time_s column is not increasing; pass --rate")
            rate_hz = float(1.0 / np.median(dt))
        marks = np.flatnonzero((flags & FLAG_MARK) != 0)
    else:
        if rate_hz is None:
            raise HostError(f"{p}: a plain CSV needs --rate HZ (its sample rate)")
        marks = np.zeros(0, np.int64)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise HostError(f"--rate must be a positive number, got {rate_hz!r}")
    med = np.nanmedian(np.linalg.norm(rows[valid], axis=1)) if valid.any() else np.nan
    if not (0.5 < med < 1.5):
        raise HostError(f"{p}: median acceleration norm is {med:.3g}; expected ~1 g (give acceleration in g)")
    return GaitInput(rows, valid, float(rate_hz), marks, f"acceleration in g from {p.name}")


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
