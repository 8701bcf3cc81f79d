"""The recording file of a kinematics instrument: CSV, a time column then one column per sensor axis.

Format
------
- Optional leading comment lines starting with ``#`` (free text: who, when, which platform).
- One header row of column names, each ending with its unit: ``time_s`` (or ``time_ms``) first, then one
  column per sensor axis named ``<sensor>_<unit>``, e.g. ``acc1_g``, ``A_x_rad_s``. Units read:

  ==========  ==================  =========================
  quantity    suffixes            converted to
  ==========  ==================  =========================
  time        ``_s``, ``_ms``     s
  specific    ``_g``, ``_mg``,    g (``STANDARD_GRAVITY_M_S2``
  force       ``_m_s2``           for m/s²)
  angular     ``_rad_s``,         rad/s
  rate        ``_deg_s``
  ==========  ==================  =========================

- One row per sample, any sampling rate, but uniform: the rate is ``1 / median(Δt)`` and a step that
  differs from the median by more than 1 % is refused with its row number (a gap must be cut, not bridged).

The platform description (:mod:`gaitlog.host.kinematics.platform_description`) refers to sensors by ``<sensor>``,
without the unit, so a file can change units without touching its platform.
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms.steps import csv_text
from gaitlog.host.errors import HostError
from gaitlog.atomic_write import atomic_write_text
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["SensorRecording", "read_sensor_csv", "split_unit", "write_sensor_csv"]

#: Unit suffix -> (quantity, factor to the canonical unit). Longest suffixes are tried first.
_UNITS: dict[str, tuple[str, float]] = {
    "_m_s2": ("specific force", 1.0 / STANDARD_GRAVITY_M_S2),
    "_rad_s": ("angular rate", 1.0),
    "_deg_s": ("angular rate", math.pi / 180.0),
    "_mg": ("specific force", 1e-3),
    "_ms": ("time", 1e-3),
    "_g": ("specific force", 1.0),
    "_s": ("time", 1.0),
}

#: Largest relative deviation of one time step from the median step.
_STEP_TOLERANCE = 0.01


def split_unit(column: str) -> tuple[str, str, float]:
    """``(sensor, quantity, factor)`` of a column name; raises :class:`HostError` if it has no known unit.

    Examples
    --------
    >>> split_unit("A_x_deg_s")[:2]
    ('A_x', 'angular rate')
    >>> split_unit("acc1_g")
    ('acc1', 'specific force', 1.0)
    """
    for suffix in sorted(_UNITS, key=len, reverse=True):
        if column.endswith(suffix) and len(column) > len(suffix):
            quantity, factor = _UNITS[suffix]
            return column[: -len(suffix)], quantity, factor
    raise HostError(
        f"column {column!r} does not state its unit: end the name with one of "
        f"{', '.join(sorted(_UNITS, key=len, reverse=True))} (e.g. time_s, acc1_g, A_x_rad_s)"
    )


@dataclass(frozen=True, eq=False)
class SensorRecording:
    """A recording in canonical units: time in s, specific force in g, angular rate in rad/s.

    Attributes
    ----------
    t_s
        ``(n,)`` sample times, s.
    channels
        ``{sensor: (n,) values}`` in the canonical unit of its quantity.
    quantities
        ``{sensor: "specific force" | "angular rate"}``.
    sampling_rate_hz
        ``1 / median(Δt)``.
    source
        File name, for messages.
    """

    t_s: np.ndarray
    channels: dict[str, np.ndarray]
    quantities: dict[str, str]
    sampling_rate_hz: float
    source: str = "<recording>"

    def columns(self, sensors: list[str], quantity: str) -> np.ndarray:
        """``(n, len(sensors))`` values of ``sensors``, each checked to exist and to be a ``quantity``."""
        out = np.empty((self.t_s.size, len(sensors)))
        for j, name in enumerate(sensors):
            if name not in self.channels:
                raise HostError(f"{self.source}: no column for sensor {name!r} (the file has "
                                f"{', '.join(self.channels) or 'no sensor columns'})")
            if self.quantities[name] != quantity:
                raise HostError(f"{self.source}: sensor {name!r} is a {self.quantities[name]} column, "
                                f"the platform needs a {quantity}")
            out[:, j] = self.channels[name]
        return out

    def select(self, start: int, stop: int) -> SensorRecording:
        """Samples ``start .. stop`` (inclusive)."""
        return SensorRecording(self.t_s[start : stop + 1], {k: v[start : stop + 1] for k, v in self.channels.items()},
                               self.quantities, self.sampling_rate_hz, self.source)


def read_sensor_csv(path: str | os.PathLike[str]) -> SensorRecording:
    """Read a recording CSV (module notes); one-line :class:`HostError` naming the file and the row."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise HostError(f"{p}: not a UTF-8 text file (a recording is CSV)") from err
    except OSError as err:
        raise HostError(f"{p}: cannot read the recording: {err.strerror or err}") from err
    lines = text.splitlines()
    first = 0
    while first < len(lines) and (not lines[first].strip() or lines[first].lstrip().startswith("#")):
        first += 1
    if first == len(lines):
        raise HostError(f"{p}: no header row (expected e.g. 'time_s,acc1_g,...')")
    names = [c.strip() for c in lines[first].split(",")]
    if len(set(names)) != len(names):
        raise HostError(f"{p}: line {first + 1}: repeated column names {names}")
    try:
        parsed = [split_unit(n) for n in names]
    except HostError as err:
        raise HostError(f"{p}: line {first + 1}: {err}") from None
    if parsed[0][1] != "time":
        raise HostError(f"{p}: line {first + 1}: the first column must be the time (time_s or time_ms), "
                        f"found {names[0]!r}")
    if len(names) < 2:
        raise HostError(f"{p}: line {first + 1}: no sensor columns after {names[0]!r}")
    for (sensor, quantity, _), name in zip(parsed[1:], names[1:]):
        if quantity == "time":
            raise HostError(f"{p}: line {first + 1}: only the first column may be a time, found {name!r}")
    body = "\n".join(lines[first + 1 :])
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2, dtype=np.float64)
    except ValueError as err:
        raise HostError(f"{p}: after line {first + 1}: not a table of {len(names)} numbers per row ({err})") from None
    if data.shape[0] < 2 or data.shape[1] != len(names):
        raise HostError(f"{p}: need at least 2 rows of {len(names)} numbers, found shape {data.shape}")
    bad = ~np.isfinite(data).all(axis=1)
    if bad.any():
        raise HostError(f"{p}: line {first + 2 + int(np.argmax(bad))}: a value is not a finite number")
    t = data[:, 0] * parsed[0][2]
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        raise HostError(f"{p}: the time column does not increase")
    off = np.abs(dt - step) > _STEP_TOLERANCE * step
    if off.any():
        k = int(np.argmax(off))
        raise HostError(f"{p}: line {first + 3 + k}: time step {dt[k]:.6g} s differs from the median "
                        f"{step:.6g} s by more than 1 % (samples must be uniform; cut the recording at gaps)")
    channels = {s: data[:, j + 1] * f for j, (s, _, f) in enumerate(parsed[1:])}
    if len(channels) != len(parsed) - 1:
        raise HostError(f"{p}: line {first + 1}: two columns name the same sensor in different units")
    quantities = {s: q for s, q, _ in parsed[1:]}
    return SensorRecording(t, channels, quantities, 1.0 / step, str(p))


def write_sensor_csv(path: str | os.PathLike[str], t_s: np.ndarray, columns: dict[str, np.ndarray],
                     *, comment: str = "", check_units: bool = True) -> None:
    """Write a recording CSV atomically: ``time_s`` then ``columns`` (names carry their units unless
    ``check_units`` is False, for dimensionless tables such as a truth file), ``%.9g``."""
    for name in columns:
        if check_units:
            split_unit(name)
    cols = [np.asarray(t_s, dtype=np.float64)] + [np.asarray(v, dtype=np.float64) for v in columns.values()]
    if len({c.shape for c in cols}) != 1 or cols[0].ndim != 1:
        raise ValueError(f"columns of different shapes: {[c.shape for c in cols]}")
    cells = [list(map("{:.9g}".format, c.tolist())) for c in cols]
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    atomic_write_text(path, head + csv_text(["time_s", *columns], cells))
