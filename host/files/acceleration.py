"""An acceleration input as every command takes it (:class:`AccelerationInput`), and the reader of the decoded
recording ``.npz`` of ``gaitlog decode`` (:func:`read_npz`) with what every input kind shares: the checks of the
reading options, the losses said on stderr, a logger recording's counts-to-g map and lap marks.

The reader of every input (logger files, IPOL, CSV) is :func:`gaitlog.host.files.inputs.read_acceleration`, which
reads an ``.npz`` through this module; :func:`read_npz` reads it without loading the logger-file decoders, for a
caller that knows (:func:`is_npz`) that its input is one: the same :class:`AccelerationInput`, the same errors in the
same order, the same warnings.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.losses import SampleLosses, say_losses
from gaitlog.host.files.recording import Recording
from gaitlog.protocol.packing import FLAG_MARK

if TYPE_CHECKING:
    from gaitlog.host.files.ipol import IpolTrial

__all__ = ["UNITS", "AccelerationInput", "check_rate", "checked_options", "from_recording", "input_losses", "ipol_named",
           "is_npz", "npz_input", "only_csv", "parse_columns", "read_npz", "starts_zip"]

#: Units of acceleration columns a user can name (``--units``).
UNITS = ("g", "m/s2", "counts")


@dataclass(frozen=True, eq=False)
class AccelerationInput:
    """Tri-axial acceleration read from one input, on a regular grid.

    Attributes
    ----------
    acc_g
        ``(n, 3)`` float64 in g, NaN where missing; None for counts without a calibration (see :meth:`g`).
    valid
        ``(n,)`` bool, False where a sample is missing.
    sampling_rate_hz
        Rate of the grid, Hz.
    mark_index
        Sample indices of the lap marks (MARK flags), int64.
    source
        One line: the file, its format and how g was obtained.
    counts
        ``(n, 3)`` float64 ADC counts, NaN where missing, when the input holds counts; else None.
    adc_bits
        ADC width of a logger file, else None.
    recording
        The decoded logger file (codes, header, flags), else None.
    ipol_trial
        The IPOL trial (reference events, boundaries), else None.
    """

    acc_g: np.ndarray | None
    valid: np.ndarray
    sampling_rate_hz: float
    mark_index: np.ndarray
    source: str
    counts: np.ndarray | None = None
    adc_bits: int | None = None
    recording: Recording | None = field(default=None, repr=False)
    ipol_trial: IpolTrial | None = field(default=None, repr=False)
    #: A logger recording read with ``arrays=False``: its counts-to-g map, applied block by block (:meth:`blocks`)
    #: instead of ``acc_g`` and ``counts`` held whole.
    to_g: object = field(default=None, repr=False)

    @property
    def n_samples(self) -> int:
        """Grid length."""
        return int(self.valid.size)

    @property
    def n_missing(self) -> int:
        """Samples missing from the grid."""
        return int(np.count_nonzero(~self.valid))

    def g(self) -> np.ndarray:
        """:attr:`acc_g`, or a :class:`HostError` when the input is counts without a calibration."""
        if self.acc_g is None and self.to_g is not None and self.recording is not None:
            return self.recording.acc_g(self.to_g)
        if self.acc_g is None:
            raise HostError(f"{self.source}: acceleration in ADC counts and no calibration to turn it into g; "
                            "give --calibration CAL.json (from 'gaitlog calibrate')")
        return self.acc_g

    def blocks(self, size: int = 1 << 16) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(g, valid)`` of ``size`` samples at a time (the last block shorter): a logger recording read with
        ``arrays=False`` is converted one block at a time, so no ``(n, 3)`` float array is held."""
        n = self.n_samples
        if self.acc_g is None and self.to_g is not None and self.recording is not None:
            rec = self.recording
            for lo in range(0, n, size):
                g = np.asarray(self.to_g.apply(rec.codes[lo:lo + size].astype(np.float64)), np.float64)
                g[~self.valid[lo:lo + size]] = np.nan
                yield g, self.valid[lo:lo + size]
            return
        acc = self.g()
        for lo in range(0, n, size):
            yield acc[lo:lo + size], self.valid[lo:lo + size]

    def __repr__(self) -> str:
        return (f"AccelerationInput({self.n_samples} samples at {self.sampling_rate_hz:g} Hz, {self.n_missing} "
                f"missing, {self.mark_index.size} marks; {self.source})")


def parse_columns(text: str | Sequence[str | int] | None) -> list[str | int] | None:
    """``"X,Y,Z"`` (names or 0-based indices, comma-separated) -> three entries; None stays None."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")] if isinstance(text, str) else list(text)
    if len(parts) != 3 or any(p == "" for p in parts):
        raise HostError(f"--columns: expected three columns X,Y,Z (names or 0-based indices), got {text!r}")
    return [int(p) if isinstance(p, int) or p.isdigit() else p for p in parts]


def input_losses(data: AccelerationInput) -> SampleLosses:
    """What is missing from an input, with the reasons of a logger recording's gaps."""
    source = data.source.split(" (")[0]
    if data.recording is not None:
        return SampleLosses.from_recording(data.recording, data.valid, source)
    why = ("lost packets (IPOL file)" if data.ipol_trial is not None else
           "marked missing in the file (a decoded CSV's validity), empty or non-finite cells, or holes in its time grid")
    return SampleLosses.from_mask(data.valid, source, why)


def read_npz(path: str | Path, *, sampling_rate_hz: float | None = None,
             columns: str | Sequence[str | int] | None = None, units: str | None = None,
             calibration: AccCalibration | str | Path | None = None, skip_rows: int = 0,
             arrays: bool = True) -> AccelerationInput:
    """:func:`gaitlog.host.files.inputs.read_acceleration` of a decoded recording ``.npz`` (``path`` one that
    :func:`is_npz` accepts; the parameters, result, warnings and errors are that function's)."""
    p = Path(path)
    cols, cal = checked_options(sampling_rate_hz, columns, units, calibration, skip_rows)
    data = npz_input(p, cols, units, skip_rows, sampling_rate_hz, cal, arrays)
    say_losses(input_losses(data))
    return data


def npz_input(p: Path, cols: list[str | int] | None, units: str | None, skip_rows: int, rate: float | None,
              cal: AccCalibration | None, arrays: bool = True) -> AccelerationInput:
    """The :class:`AccelerationInput` of the decoded recording ``.npz`` ``p`` (its options checked by
    :func:`checked_options`; no CSV-only option given), its losses not yet said."""
    only_csv(p, cols, units, skip_rows)
    return from_recording(Recording.load(p), p, rate, cal, arrays)


def is_npz(path: str | Path) -> bool:
    """Whether :func:`gaitlog.host.files.inputs.read_acceleration` reads ``path`` as a decoded recording ``.npz``:
    a file that is not named as an IPOL trial and starts as a zip archive. False when it cannot be read (the reader
    of every input says why)."""
    p = Path(path)
    if p.is_dir() or ipol_named(p) or not p.is_file():
        return False
    try:
        return starts_zip(p)
    except HostError:
        return False


def ipol_named(p: Path) -> bool:
    """Whether ``p`` is named as an IPOL trial (a ``.json`` description or a ``_lb.txt`` lower-back file)."""
    return p.suffix.lower() == ".json" or p.name.endswith("_lb.txt")


def checked_options(sampling_rate_hz: float | None, columns: str | Sequence[str | int] | None, units: str | None,
                    calibration: AccCalibration | str | Path | None, skip_rows: int
                    ) -> tuple[list[str | int] | None, AccCalibration | None]:
    """The reading options checked, before any file is opened: the parsed ``columns`` and the calibration
    (loaded from its JSON file when a path is given)."""
    if sampling_rate_hz is not None and not (math.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise HostError(f"--rate must be a positive number of Hz, got {sampling_rate_hz:g}")
    if units is not None and units not in UNITS:
        raise HostError(f"--units must be one of {', '.join(UNITS)}, got {units!r}")
    if skip_rows < 0:
        raise HostError(f"--skip-rows must be >= 0, got {skip_rows}")
    cols = parse_columns(columns)
    cal = AccCalibration.load(calibration) if isinstance(calibration, (str, Path)) else calibration
    return cols, cal


def starts_zip(p: Path) -> bool:
    """Whether ``p`` starts as a zip archive (an NPZ) does."""
    try:
        with p.open("rb") as fh:
            return fh.read(4) == b"PK\x03\x04"
    except OSError as err:
        raise HostError(f"{p}: cannot read: {err.strerror or err}") from err


def only_csv(p: Path, cols: object, units: str | None, skip_rows: int) -> None:
    """A :class:`HostError` when a CSV-only option was given for ``p``, an input that says its own layout."""
    for flag, given in (("--columns", cols is not None), ("--units", units is not None), ("--skip-rows", skip_rows)):
        if given:
            raise HostError(f"{p}: {flag} applies to a CSV input only; this file says its own layout")


def check_rate(p: Path, file_rate: float, asked: float | None) -> None:
    """A :class:`HostError` when ``--rate`` (``asked``) disagrees with the rate ``p`` states."""
    if asked is not None and abs(asked - file_rate) > 1e-9 * file_rate:
        raise HostError(f"{p}: the file says {file_rate:g} Hz, --rate says {asked:g} Hz; drop --rate")


def from_recording(rec: Recording, p: Path, rate: float | None, cal: AccCalibration | None,
                    arrays: bool = True) -> AccelerationInput:
    """The :class:`AccelerationInput` of a logger recording read from ``p`` (g through ``cal``, else the header's
    calibration slot, else the nominal map; ``arrays``: as :func:`read_npz`)."""
    check_rate(p, float(rec.sampling_rate_hz), rate)
    rec.require_three_axes()                       # an instrument's dump (a channel map): refused before any block
    if cal is None:
        m, note = rec.default_calibration()
    else:
        if cal.input_unit != "counts":
            raise HostError(f"{p}: the calibration takes {cal.input_unit}, this file holds ADC counts")
        m, note = cal, "g from the given calibration"
    marks = np.flatnonzero((np.asarray(rec.flags) & FLAG_MARK) != 0)
    source = f"{p} (logger recording, {int(rec.adc_bits)}-bit; {note})"
    if not arrays:
        return AccelerationInput(None, np.asarray(rec.valid, bool), float(rec.sampling_rate_hz), marks, source,
                                 None, int(rec.adc_bits), rec, to_g=m)
    counts = rec.codes.astype(np.float64)
    counts[~rec.valid] = np.nan
    acc = rec.acc_g(m)
    valid = np.asarray(rec.valid, bool) & np.all(np.isfinite(acc), axis=1)
    return AccelerationInput(acc, valid, float(rec.sampling_rate_hz), marks, source, counts, int(rec.adc_bits), rec)
