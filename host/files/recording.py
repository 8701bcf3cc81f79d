"""A decoded recording of the logger: raw counts, validity, flags, sample numbers, gaps and header.

A :class:`Recording` is what :mod:`gaitlog.host.files.decode` returns for a memory image, a raw XMODEM dump or a wire
capture, and what every later stage (calibration, orientation, gait events, estimators) takes as input.

Rows and gaps
-------------
Row ``i`` is stored sample ``i`` in ring order (0 = oldest). A row whose bytes were not received intact has
``valid[i] = False``; its codes and flags are 0 and carry no information (``acc_g`` gives NaN there), and the
row belongs to one of the :class:`Gap` entries in ``gaps``. A decoder never invents a sample: every valid row
is bit-exact as stored by the device.

Sample numbers count samples since the last ERASE (``PROTOCOL.md`` section 2: the oldest stored sample is
number ``samples_written - n``); the time of sample number ``k`` is ``start_time_s + k / sampling_rate_hz``
(Unix time, UTC) and ``k / sampling_rate_hz`` seconds after the start of the log.

Per-step records
----------------
A device with step memory (``PROTOCOL.md`` 2.3) also stores one 20-byte record per foot-flat that its
on-line step algorithm found. ``step_records`` holds the records the decoder could use, in ring order (oldest
first), exactly as the device stored them; ``step_record_numbers`` their absolute record numbers (0 = first
record after ERASE). A stored record whose bytes were not received intact or whose CRC does not match is not
in ``step_records``: it is counted in one of the ``step_losses`` runs, with the reason. A record's
``end_sample`` is a sample number, so its time is on the same clock as the samples.
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from gaitlog.firmware_sim.sampling import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.firmware_sim.algorithms.steps import csv_text, distinct, fixed_csv_cells, int_csv_cells
from gaitlog.host.errors import HostError
from gaitlog.host.storage.limits import MAX_NPZ_EXPANSION, NPZ_SMALL_BYTES, check_memory
from gaitlog.atomic_write import atomic_write, atomic_write_text
from gaitlog.protocol.channel_map import ChannelMap
from gaitlog.protocol.header import CalibrationSlot, DeviceHeader
from gaitlog.protocol.steps import (
    HEEL_STRIKE_NOT_FOUND,
    STEP_LENGTH_FIELDS,
    STEP_RECORD_DTYPE,
    StepFlag,
    step_lengths_m,
    unpack_step_records,
)

#: Version of the NPZ layout written by :meth:`Recording.save_npz`. The step-record arrays were added to
#: version 1 as optional arrays (a file without them is read as one saved before they existed), so files of
#: either age load everywhere.
NPZ_FORMAT_VERSION = 1

#: The arrays of the NPZ layout (others in a file are not read).
_NPZ_ARRAYS = ("codes", "valid", "flags", "sample_numbers", "header_bytes", "step_record_bytes", "step_record_numbers",
               "metadata_json")
#: Most bytes deflate inflates one compressed byte to (its longest match, 258 bytes, coded in 2 bits: 1,032): a zip
#: member saying it is larger than this times its compressed size lies about its size.
DEFLATE_MAX_RATIO = 1032
#: The arrays a recording NPZ must have, and the first axis they share (the samples).
_NPZ_REQUIRED = ("codes", "valid", "flags", "sample_numbers", "header_bytes", "metadata_json")
_NPZ_PER_SAMPLE = ("codes", "valid", "flags", "sample_numbers")

#: Rows of the sample CSV formatted at a time (:meth:`Recording.to_csv`).
_CSV_ROWS = 1 << 16
#: zlib level of the NPZ written by :meth:`Recording.save_npz` (numpy's ``savez_compressed`` takes the default, 6).
_NPZ_COMPRESS_LEVEL = 1
#: CSV columns written by :meth:`Recording.to_csv`, in order.
CSV_COLUMNS = (
    "sample_number", "time_s", "x_counts", "y_counts", "z_counts", "x_g", "y_g", "z_g", "flags", "valid",
)

#: The raw values of an uncalibrated device record that are not lengths, by the index of their length field:
#: M4 with K = 1 is range^p ((m/s^2)^p, p = 1/2) and M5 with K1 = 1 m s, K2 = 0 is the cadence 1/T in Hz
#: (PROTOCOL.md 2.2). They get their own columns; a ``_m`` column only ever holds a length in m.
RAW_STEP_CSV_COLUMNS = {3: "raw_m4_range_pow_p", 4: "raw_m5_cadence_hz"}

#: CSV columns written by :meth:`Recording.to_steps_csv`, in order (one row per device step record).
STEP_CSV_COLUMNS = (
    "record_number", "end_sample", "time_s", "duration_s", "toe_off_s", "heel_strike_s", "flags",
    *(f"length_m{k}_m" for k in range(1, len(STEP_LENGTH_FIELDS) + 1)), *RAW_STEP_CSV_COLUMNS.values(), "lengths",
)


class RecordGap(NamedTuple):
    """A run of consecutive stored step records (absolute record numbers, both ends inclusive) that the decoder
    could not use, with the reason."""

    first_record_number: int
    last_record_number: int
    reason: str

    @property
    def n_records(self) -> int:
        """Number of records in the run."""
        return self.last_record_number - self.first_record_number + 1


class Gap(NamedTuple):
    """A run of consecutive missing samples (both ends inclusive), with the reason they are missing."""

    first_sample_number: int
    last_sample_number: int
    reason: str

    @property
    def n_samples(self) -> int:
        """Number of samples in the gap."""
        return self.last_sample_number - self.first_sample_number + 1


class CountsToG(Protocol):
    """Anything that converts ``(n, 3)`` ADC counts to ``(n, 3)`` acceleration in g."""

    def apply(self, counts: np.ndarray) -> np.ndarray:  # pragma: no cover - protocol
        ...


def gaps_from_mask(valid: np.ndarray, sample_numbers: np.ndarray, reasons: np.ndarray | None = None,
                   reason_names: Sequence[str] = ("missing",)) -> list[Gap]:
    """Group the invalid rows into runs of equal reason.

    Parameters
    ----------
    valid
        ``(n,)`` bool.
    sample_numbers
        ``(n,)`` int64, consecutive.
    reasons
        ``(n,)`` small int index into ``reason_names`` for every invalid row (ignored where valid);
        ``None`` means reason 0 everywhere.
    reason_names
        Text of each reason code.

    Examples
    --------
    >>> v = np.array([1, 0, 0, 1, 0, 0], bool)
    >>> r = np.array([0, 0, 0, 0, 0, 1])
    >>> gaps_from_mask(v, np.arange(10, 16), r, ["lost", "cut"])
    [Gap(first_sample_number=11, last_sample_number=12, reason='lost'), \
Gap(first_sample_number=14, last_sample_number=14, reason='lost'), \
Gap(first_sample_number=15, last_sample_number=15, reason='cut')]
    """
    valid = np.asarray(valid, dtype=bool)
    n = valid.size
    if n == 0 or valid.all():
        return []
    key = np.zeros(n, dtype=np.int64) if reasons is None else np.asarray(reasons, dtype=np.int64).copy()
    key[valid] = -1
    change = np.flatnonzero(np.diff(key)) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [n])) - 1
    gaps = []
    for s, e in zip(starts.tolist(), ends.tolist()):
        if key[s] >= 0:
            gaps.append(Gap(int(sample_numbers[s]), int(sample_numbers[e]), str(reason_names[key[s]])))
    return gaps


@dataclass(eq=False)
class Recording:
    """Samples of one logger memory, in ring order, with validity and gaps.

    Attributes
    ----------
    codes
        ``(n, 3)`` uint16 raw ADC codes (counts) x, y, z; 0 where not ``valid``.
    valid
        ``(n,)`` bool, True where the sample was received bit-exact.
    flags
        ``(n,)`` uint8 sample flags (bit 0 SESSION_START, bit 1 MARK; ``PROTOCOL.md`` section 1).
    sample_numbers
        ``(n,)`` int64 absolute sample numbers (consecutive).
    sampling_rate_hz
        Sample rate from the header, Hz.
    start_time_s
        Unix time (UTC, s) of sample number 0 (the header's ``start_time_s``).
    header
        The device header the samples were decoded with (``gaitlog.protocol.header.DeviceHeader``), or None.
    gaps
        Every run of missing samples, with its reason.
    adc_bits
        ADC resolution (for the nominal counts-to-g map).
    source
        Where the samples came from (file name, port), if known.
    notes
        Human-readable remarks of the decoder (recovered shifts, conversion used, ...).
    step_records
        ``(m,)`` :data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`: the device's per-step records that were received
        intact with a matching CRC, in ring order (oldest first), byte for byte as stored.
    step_record_numbers
        ``(m,)`` int64 absolute record numbers of ``step_records`` (increasing; a jump is a loss).
    step_losses
        Every run of stored step records that could not be used, with its reason.
    """

    codes: np.ndarray
    valid: np.ndarray
    flags: np.ndarray
    sample_numbers: np.ndarray
    sampling_rate_hz: float
    start_time_s: float = 0.0
    header: Any = None
    gaps: list[Gap] = field(default_factory=list)
    adc_bits: int = 10
    source: str | None = None
    notes: list[str] = field(default_factory=list)
    step_records: np.ndarray | None = None
    step_record_numbers: np.ndarray | None = None
    step_losses: list[RecordGap] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.codes = np.ascontiguousarray(self.codes, dtype=np.uint16).reshape(-1, 3)
        n = self.codes.shape[0]
        self.valid = np.asarray(self.valid, dtype=bool).reshape(-1)
        self.flags = np.asarray(self.flags, dtype=np.uint8).reshape(-1)
        self.sample_numbers = np.asarray(self.sample_numbers, dtype=np.int64).reshape(-1)
        for name in ("valid", "flags", "sample_numbers"):
            if getattr(self, name).shape[0] != n:
                raise HostError(f"Recording.{name} has {getattr(self, name).shape[0]} rows, codes has {n}")
        if not (np.isfinite(self.sampling_rate_hz) and self.sampling_rate_hz > 0):
            raise HostError(f"Recording.sampling_rate_hz must be > 0, got {self.sampling_rate_hz!r}")
        self.gaps = [Gap(int(a), int(b), str(r)) for a, b, r in self.gaps]
        records = np.zeros(0, STEP_RECORD_DTYPE) if self.step_records is None else np.asarray(self.step_records)
        if records.dtype.names != STEP_RECORD_DTYPE.names:
            raise HostError(f"Recording.step_records must have the fields of STEP_RECORD_DTYPE, got {records.dtype}")
        self.step_records = np.ascontiguousarray(records.reshape(-1).astype(STEP_RECORD_DTYPE, copy=False))
        m = self.step_records.shape[0]
        if self.step_record_numbers is None:
            if m:
                raise HostError("Recording.step_record_numbers is needed with step_records")
            self.step_record_numbers = np.zeros(0, np.int64)
        self.step_record_numbers = np.asarray(self.step_record_numbers, dtype=np.int64).reshape(-1)
        if self.step_record_numbers.shape[0] != m:
            raise HostError(f"Recording.step_record_numbers has {self.step_record_numbers.shape[0]} rows, "
                            f"step_records has {m}")
        if m > 1 and np.any(np.diff(self.step_record_numbers) <= 0):
            raise HostError("Recording.step_record_numbers must increase (ring order)")
        self.step_losses = [RecordGap(int(a), int(b), str(r)) for a, b, r in self.step_losses]

    # ----------------------------------------------------------------------------------------- construction
    @classmethod
    def from_arrays(cls, codes: np.ndarray, *, valid: np.ndarray | None = None, flags: np.ndarray | None = None,
                    first_sample_number: int = 0, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, start_time_s: float = 0.0,
                    header: Any = None, adc_bits: int = 10, reason: str = "missing",
                    source: str | None = None) -> "Recording":
        """Build a recording from arrays; gaps are derived from ``valid`` and invalid rows are zeroed.

        Examples
        --------
        >>> r = Recording.from_arrays(np.full((4, 3), 512), valid=np.array([1, 0, 0, 1], bool),
        ...                           first_sample_number=100)
        >>> r.gaps
        [Gap(first_sample_number=101, last_sample_number=102, reason='missing')]
        >>> r.acc_g()[:2]
        array([[ 0.,  0.,  0.],
               [nan, nan, nan]])
        """
        codes = np.array(codes, dtype=np.uint16).reshape(-1, 3)
        n = codes.shape[0]
        valid_a = np.ones(n, bool) if valid is None else np.array(valid, dtype=bool)
        flags_a = np.zeros(n, np.uint8) if flags is None else np.array(flags, dtype=np.uint8)
        codes[~valid_a] = 0
        flags_a[~valid_a] = 0
        sn = first_sample_number + np.arange(n, dtype=np.int64)
        return cls(codes=codes, valid=valid_a, flags=flags_a, sample_numbers=sn,
                   sampling_rate_hz=float(sampling_rate_hz), start_time_s=float(start_time_s), header=header,
                   gaps=gaps_from_mask(valid_a, sn, None, [reason]), adc_bits=int(adc_bits), source=source)

    # ------------------------------------------------------------------------------------------- properties
    @property
    def n_samples(self) -> int:
        """Number of rows (stored samples, valid or not)."""
        return int(self.codes.shape[0])

    @property
    def n_valid(self) -> int:
        """Number of valid rows."""
        return int(np.count_nonzero(self.valid))

    @property
    def n_missing(self) -> int:
        """Number of rows reported missing."""
        return self.n_samples - self.n_valid

    @property
    def time_s(self) -> np.ndarray:
        """``(n,)`` seconds since the start of the log (sample number 0)."""
        return self.sample_numbers / self.sampling_rate_hz

    @property
    def duration_s(self) -> float:
        """Time span covered by the rows, ``n / sampling_rate_hz``, in seconds."""
        return self.n_samples / self.sampling_rate_hz

    @property
    def step_config(self) -> Any:
        """The header's step configuration (``gaitlog.protocol.steps.StepConfig``), or None without a header."""
        return getattr(self.header, "step_config", None)

    @property
    def n_step_records(self) -> int:
        """Number of usable device step records."""
        return int(self.step_records.shape[0])

    def __repr__(self) -> str:
        return (f"Recording({self.n_samples} samples ({self.n_missing} missing, {len(self.gaps)} gap(s)) at "
                f"{self.sampling_rate_hz:g} Hz, {self.adc_bits}-bit, {self.n_step_records} step record(s); "
                f"{self.source})")

    @property
    def n_steps_dropped(self) -> int:
        """Number of stored step records that could not be used (the sum over ``step_losses``)."""
        return sum(g.n_records for g in self.step_losses)

    def gap_times_s(self, gap: Gap) -> tuple[float, float]:
        """Start and end time (s since the start of the log) of ``gap``: from its first sample to the
        sample after its last."""
        return gap.first_sample_number / self.sampling_rate_hz, (gap.last_sample_number + 1) / self.sampling_rate_hz

    # --------------------------------------------------------------------------------------------- physics
    def default_calibration(self) -> tuple[CountsToG, str]:
        """Counts-to-g map of the header's calibration slot, or the nominal map when the slot is empty.

        Returns the map and a note saying which one it is (``PROTOCOL.md`` section 2.1).
        """
        cal = getattr(self.header, "calibration", None)
        if cal is not None and bool(getattr(cal, "valid", False)):
            return cal, "g from the header's calibration slot"
        return (CalibrationSlot.nominal(self.adc_bits),
                f"g from the nominal map (no calibration in the header): 0 g at code {2 ** (self.adc_bits - 1)}, "
                f"{4.0 / 2 ** self.adc_bits:.6g} g per count")

    def require_three_axes(self) -> None:
        """An instrument's dump (a channel map in the header, ``PROTOCOL.md`` 2.6) has no three axes in g."""
        if isinstance(getattr(self.header, "calibration", None), ChannelMap):
            raise HostError(f"{self.source}: holds an instrument's channels (a channel map, PROTOCOL.md 2.6), not "
                            "the logger's three accelerometer axes: `gaitlog decode` writes its recording CSV for "
                            "`gaitlog kinematics`")

    def acc_g(self, calibration: CountsToG | None = None) -> np.ndarray:
        """Acceleration in g, ``(n, 3)`` float64, NaN at invalid rows.

        Parameters
        ----------
        calibration
            Object with ``apply(counts) -> g`` (``gaitlog.protocol.header.CalibrationSlot``, ``gaitlog.host.accelerometer.calibration.
            AccCalibration``); default: the header's calibration slot, else the nominal ±2 g map.
        """
        self.require_three_axes()
        cal = self.default_calibration()[0] if calibration is None else calibration
        g = np.asarray(cal.apply(self.codes.astype(np.float64)), dtype=np.float64).reshape(-1, 3).copy()
        g[~self.valid] = np.nan
        return g

    # -------------------------------------------------------------------------------------------- metadata
    def metadata(self) -> dict[str, Any]:
        """JSON-ready description (everything except the sample arrays)."""
        header_info = None
        if self.header is not None:
            header_info = {
                "device_id": int(self.header.device_id),
                "firmware_version": int(self.header.firmware_version),
                "protocol_version": int(self.header.protocol_version),
                "samples_written": int(self.header.samples_written),
                "write_index": int(self.header.write_index),
                "capacity_samples": int(self.header.capacity_samples),
                "wrapped": bool(self.header.wrapped),
                "overwrite": bool(self.header.overwrite),
                "calibration_valid": bool(self.header.calibration.valid),
                "steps_written": int(getattr(self.header, "steps_written", 0)),
                "step_write_index": int(getattr(self.header, "step_write_index", 0)),
                "step_capacity": int(getattr(self.header, "step_capacity", 0)),
            }
            if self.step_config is not None:
                header_info["step_config"] = {k: (v if isinstance(v, bool) else float(v) if k != "step_format"
                                                  else int(v)) for k, v in vars(self.step_config).items()}
        return {
            "format_version": NPZ_FORMAT_VERSION,
            "source": self.source,
            "sampling_rate_hz": self.sampling_rate_hz,
            "start_time_s": self.start_time_s,
            "adc_bits": self.adc_bits,
            "n_samples": self.n_samples,
            "n_valid": self.n_valid,
            "first_sample_number": int(self.sample_numbers[0]) if self.n_samples else None,
            "gaps": [
                {"first_sample_number": g.first_sample_number, "last_sample_number": g.last_sample_number,
                 "n_samples": g.n_samples, "start_s": self.gap_times_s(g)[0], "end_s": self.gap_times_s(g)[1],
                 "reason": g.reason}
                for g in self.gaps
            ],
            "header": header_info,
            "notes": list(self.notes),
            "step_records": {
                "n_decoded": self.n_step_records,
                "n_dropped": self.n_steps_dropped,
                "first_record_number": int(self.step_record_numbers[0]) if self.n_step_records else None,
                "losses": [{"first_record_number": g.first_record_number, "last_record_number": g.last_record_number,
                            "n_records": g.n_records, "reason": g.reason} for g in self.step_losses],
            },
        }

    # ---------------------------------------------------------------------------------------------- saving
    def save_npz(self, path: str | os.PathLike[str]) -> None:
        """Write the recording to ``path`` (NPZ; metadata as a JSON string inside), atomically.

        Arrays: ``codes``, ``valid``, ``flags``, ``sample_numbers``, ``header_bytes`` (the 256-byte device
        header, empty when none), ``step_record_bytes`` (the usable step records, 20 bytes each as stored),
        ``step_record_numbers``, ``metadata_json`` (with the step-record losses).
        """
        header_bytes = np.zeros(0, np.uint8)
        if self.header is not None:
            header_bytes = np.frombuffer(self.header.to_bytes(), dtype=np.uint8)
        meta = json.dumps(self.metadata(), sort_keys=True)
        step_bytes = np.frombuffer(self.step_records.tobytes(), dtype=np.uint8)
        arrays = {"codes": self.codes, "valid": self.valid, "flags": self.flags, "sample_numbers": self.sample_numbers,
                  "header_bytes": header_bytes, "step_record_bytes": step_bytes,
                  "step_record_numbers": self.step_record_numbers, "metadata_json": np.array(meta)}
        # compressed straight into the file (no copy in memory), as np.savez_compressed does but at zlib's level 1:
        # a full memory's NPZ 6 % larger, written in a sixth of the time of the default level 6
        with atomic_write(path, "wb") as handle, zipfile.ZipFile(handle, "w", zipfile.ZIP_DEFLATED,
                                                                 compresslevel=_NPZ_COMPRESS_LEVEL) as archive:
            for name, values in arrays.items():
                with archive.open(name + ".npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, np.asanyarray(values), allow_pickle=False)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "Recording":
        """Read a recording written by :meth:`save_npz`; :class:`HostError` naming the file if it is not one.

        A file saved before the step records existed (no ``step_record_bytes``) loads with no step records;
        when its header says the device had stored some, they are one loss "not in this NPZ".
        """
        path = Path(path)
        try:
            with path.open("rb") as fh:
                magic = fh.read(4)
        except OSError as err:
            raise HostError(f"{path}: cannot read recording: {err.strerror or err}") from err
        if magic != b"PK\x03\x04":
            raise HostError(f"{path}: not a gaitlog recording NPZ (an NPZ is a zip archive; this file starts with "
                            f"{magic!r}, offset 0)")
        arrays = read_npz_arrays(path, _NPZ_ARRAYS, required=_NPZ_REQUIRED)
        try:
            meta = json.loads(str(arrays["metadata_json"]))
        except (ValueError, RecursionError) as err:
            raise HostError(f"{path}: metadata_json is not JSON ({err})") from err
        if not isinstance(meta, dict):
            raise HostError(f"{path}: metadata_json must be a JSON object")
        if meta.get("format_version") != NPZ_FORMAT_VERSION:
            raise HostError(f"{path}: recording format version {meta.get('format_version')!r} is not supported "
                            f"(this gaitlog reads version {NPZ_FORMAT_VERSION})")
        header = None
        if arrays["header_bytes"].size:
            header = DeviceHeader.from_bytes(arrays["header_bytes"].tobytes(), source=str(path))
        try:
            gaps = [Gap(g["first_sample_number"], g["last_sample_number"], g["reason"]) for g in meta["gaps"]]
            records, numbers, losses = _load_step_records(path, arrays, meta, header)
            return cls(codes=arrays["codes"], valid=arrays["valid"], flags=arrays["flags"],
                       sample_numbers=arrays["sample_numbers"], sampling_rate_hz=float(meta["sampling_rate_hz"]),
                       start_time_s=float(meta["start_time_s"]), header=header, gaps=gaps,
                       adc_bits=int(meta["adc_bits"]), source=meta.get("source"), notes=list(meta.get("notes", [])),
                       step_records=records, step_record_numbers=numbers, step_losses=losses)
        except KeyError as err:
            raise HostError(f"{path}: metadata_json lacks the field {err.args[0]!r}") from err
        except (TypeError, ValueError, AttributeError, OverflowError) as err:
            raise HostError(f"{path}: bad metadata_json field ({type(err).__name__}: {err})") from err

    def to_csv(self, path: str | os.PathLike[str], calibration: CountsToG | None = None) -> None:
        """Write one row per stored sample (columns :data:`CSV_COLUMNS`), atomically.

        Missing rows keep their sample number and time, have ``valid`` 0 and empty counts, g and flags.
        """
        self.require_three_axes()
        cal = self.default_calibration()[0] if calibration is None else calibration
        with atomic_write(path, "w", encoding="utf-8", newline="") as fh:
            for lo in range(0, max(self.n_samples, 1), _CSV_ROWS):    # a block of rows at a time: bounded memory
                text = self._csv_rows(cal, lo, lo + _CSV_ROWS)
                fh.write(text if lo == 0 else text.split("\n", 1)[1])

    def _csv_rows(self, cal: CountsToG, lo: int, hi: int) -> str:
        """:meth:`to_csv`'s text of the rows ``[lo, hi)``, with the header."""
        codes = self.codes[lo:hi]
        g = np.asarray(cal.apply(codes.astype(np.float64)), dtype=np.float64).reshape(-1, 3)
        valid = np.asarray(self.valid[lo:hi], bool)
        sample_numbers = self.sample_numbers[lo:hi]
        columns = [int_csv_cells(sample_numbers), fixed_csv_cells(sample_numbers / self.sampling_rate_hz, 4),
                   *(int_csv_cells(codes[:, k], valid) for k in range(3)),
                   *(fixed_csv_cells(g[:, k], 6, valid) for k in range(3)),
                   int_csv_cells(self.flags[lo:hi], valid), int_csv_cells(valid)]
        return csv_text(CSV_COLUMNS, columns)

    def to_steps_csv(self, path: str | os.PathLike[str]) -> None:
        """Write one row per usable device step record (columns :data:`STEP_CSV_COLUMNS`), atomically.

        ``time_s``, ``toe_off_s`` and ``heel_strike_s`` are times on the clock of the sample CSV (s since sample
        number 0): the foot-flat that ends the step, the toe-off and the heel strike. ``duration_s`` is foot-flat
        to foot-flat. A field the record leaves undefined is empty: the duration and toe-off of a bout's first
        step (``NO_WINDOW``), a toe-off or heel strike not found, a length of 0 ("not computed", the flags say
        why). ``flags`` lists the flag names joined by ``|``. ``lengths`` is ``K`` when the device applied the
        calibrated constants (lengths in m) and ``raw`` when it did not (``UNCALIBRATED``: M1, M2, M4 with
        K = 1, M5 the cadence 1/T in Hz; PROTOCOL.md 2.2). A raw record's M4 and M5 are not lengths: they go to
        ``raw_m4_range_pow_p`` and ``raw_m5_cadence_hz`` (:data:`RAW_STEP_CSV_COLUMNS`) and its ``length_m4_m`` and
        ``length_m5_m`` are empty; a calibrated record leaves the raw columns empty.
        """
        r = self.step_records
        sampling_rate_hz = self.sampling_rate_hz
        end = r["end_sample"].astype(np.int64)
        dur = r["duration_samples"].astype(np.int64)
        toe = r["toe_off_samples"].astype(np.int64)
        heel = r["heel_strike_samples"].astype(np.int64)
        fl = r["flags"].astype(np.int64)
        lengths = step_lengths_m(r)
        has_window = (dur > 0) & ((fl & StepFlag.NO_WINDOW) == 0)
        has_toe = has_window & (toe > 0) & ((fl & StepFlag.NO_TOE_OFF) == 0)
        has_heel = (heel != HEEL_STRIKE_NOT_FOUND) & ((fl & StepFlag.NO_HEEL_STRIKE) == 0)

        names = {int(v): "|".join(f.name for f in StepFlag if v & f) for v in distinct(fl).tolist()}
        calibrated = (fl & StepFlag.UNCALIBRATED) == 0
        columns = [
            self.step_record_numbers.astype(str).tolist(), end.astype(str).tolist(), _cells(end / sampling_rate_hz),
            _cells(dur / sampling_rate_hz, has_window), _cells((end - dur + toe) / sampling_rate_hz, has_toe), _cells((end + heel) / sampling_rate_hz, has_heel),
            [names[v] for v in fl.tolist()],
            *(_cells(lengths[:, k], (lengths[:, k] != 0) & (calibrated | (k not in RAW_STEP_CSV_COLUMNS)))
              for k in range(lengths.shape[1])),
            *(_cells(lengths[:, k], (lengths[:, k] != 0) & ~calibrated) for k in RAW_STEP_CSV_COLUMNS),
            ["K" if v else "raw" for v in calibrated.tolist()],
        ]
        atomic_write_text(path, csv_text(STEP_CSV_COLUMNS, columns))

    @staticmethod
    def read_csv(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
        """Read a CSV written by :meth:`to_csv` back into columns (missing values as NaN)."""
        text = Path(path).read_text(encoding="utf-8").splitlines()
        if not text or text[0].split(",") != list(CSV_COLUMNS):
            raise HostError(f"{path}: line 1: expected header {','.join(CSV_COLUMNS)}")
        if len(text) > 1:
            cells = np.array([ln.split(",") for ln in text[1:]])
            if cells.ndim != 2 or cells.shape[1] != len(CSV_COLUMNS):
                raise HostError(f"{path}: expected {len(CSV_COLUMNS)} columns on every line")
            cells[cells == ""] = "nan"
            arr = cells.astype(np.float64)
        else:
            arr = np.zeros((0, len(CSV_COLUMNS)))
        return {name: arr[:, k] for k, name in enumerate(CSV_COLUMNS)}

    def summary(self, max_listed: int | None = None) -> str:
        """A few lines describing the recording (samples, gaps, duration).

        ``max_listed`` caps the gaps and lost step-record runs listed one per line (``None``: all of them);
        the rest are counted on one line.
        """
        lines = [f"{self.n_samples} samples ({self.n_valid} valid, {self.n_missing} missing) at "
                 f"{self.sampling_rate_hz:g} Hz, {self.duration_s:.2f} s"]
        if self.n_samples:
            lines.append(f"sample numbers {int(self.sample_numbers[0])}..{int(self.sample_numbers[-1])}")
        lines.append(f"{len(self.gaps)} gap(s)")
        for gp in self.gaps[:max_listed]:
            t0, t1 = self.gap_times_s(gp)
            lines.append(f"  samples {gp.first_sample_number}..{gp.last_sample_number} "
                         f"({t0:.2f}-{t1:.2f} s): {gp.reason}")
        lines.extend(_more_line(len(self.gaps), max_listed, "gap(s)"))
        if int(getattr(self.header, "step_capacity", 0)) or self.n_step_records or self.step_losses:
            lines.append(f"{self.n_step_records} step record(s) decoded, {self.n_steps_dropped} dropped")
            for g in self.step_losses[:max_listed]:
                lines.append(f"  records {g.first_record_number}..{g.last_record_number}: {g.reason}")
            lines.extend(_more_line(len(self.step_losses), max_listed, "run(s) of lost records"))
        return "\n".join(lines)


def _more_line(n: int, max_listed: int | None, what: str) -> list[str]:
    """``["  ... N more what"]`` when ``max_listed`` hid some of ``n`` items, else ``[]``."""
    if max_listed is None or n <= max_listed:
        return []
    return [f"  ... {n - max_listed} more {what} (-v lists them all)"]


def _cells(values: np.ndarray, defined: np.ndarray | None = None) -> list[str]:
    """CSV cells of float values: the shortest text that reads back the same float, empty where not defined."""
    v = np.asarray(values, np.float64).ravel().tolist()
    # one %-format of the column, split at a separator no number holds: repr of each, twice as fast as repr per cell
    text = ("\x1f".join(["%r"] * len(v)) % tuple(v)).split("\x1f") if v else []
    if defined is not None:
        text = [t if ok else "" for t, ok in zip(text, np.asarray(defined, bool).tolist())]
    return text


class _Member(NamedTuple):
    """One ``.npy`` member of an NPZ, as its headers declare it."""

    info: zipfile.ZipInfo
    shape: tuple[int, ...]
    fortran: bool
    dtype: np.dtype
    nbytes: int


def read_npz_arrays(path: Path, names: Sequence[str],
                    required: Sequence[str] = ()) -> dict[str, np.ndarray]:
    """The arrays ``names`` of the NPZ ``path`` (others are not read), judged by their headers before any is read.

    Each member's ``.npy`` header is read first, and nothing is inflated until all agree with what the file holds:
    object arrays (pickles) are refused; a declared shape must be the zip member's declared size, which deflate
    must be able to reach from the compressed size (:data:`DEFLATE_MAX_RATIO`); the arrays together may be at most
    :data:`~gaitlog.host.storage.limits.MAX_NPZ_EXPANSION` times their compressed size (a zip bomb of zeros is
    about 1,000 times) unless small, must include ``required``, must share their sample count when they are a
    recording's, and must fit in memory (:func:`~gaitlog.host.storage.limits.check_memory`). The data are then
    read up to the declared size only.

    Raises
    ------
    HostError
        Not a zip archive, a damaged or truncated member, a pickled, oversized or inconsistent array; naming the
        file and the member.
    """
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            members = _npz_members(path, zf, names)
            _judge_npz(path, members, required)
            for name, m in members.items():
                raw = np.empty(m.nbytes, np.uint8)       # read in place: no bytes object and copy beside it
                with zf.open(m.info) as fh:
                    _npy_header(fh)
                    got = _read_into(fh, raw)
                if got != m.nbytes:
                    raise HostError(f"{path}: array {name!r}: truncated ({got} of {m.nbytes} bytes)")
                array = raw.view(m.dtype)
                arrays[name] = array.reshape(m.shape[::-1]).T if m.fortran else array.reshape(m.shape)
    except HostError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError) as err:
        raise HostError(f"{path}: damaged or truncated recording NPZ ({err})") from err
    return arrays


def _npy_header(fh: Any) -> tuple[tuple[int, ...], bool, np.dtype]:
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version not in ((1, 0), (2, 0)):
        raise ValueError(f".npy format version {version} is not read")
    read_header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    return read_header(fh)


def _npz_members(path: Path, zf: zipfile.ZipFile, names: Sequence[str]) -> dict[str, _Member]:
    """The members ``names`` by their headers (the ``.npy`` header inflated, nothing more), each checked alone."""
    members: dict[str, _Member] = {}
    for info in zf.infolist():
        name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
        if name not in names or name in members:
            continue
        where = f"{path}: array {name!r}"
        if info.flag_bits & 0x1:
            raise HostError(f"{where}: encrypted in the zip (a gaitlog NPZ never is)")
        if info.compress_type == zipfile.ZIP_STORED and info.file_size != info.compress_size:
            raise HostError(f"{where}: stored uncompressed in {info.compress_size} bytes, the zip says "
                            f"{info.file_size}: not a gaitlog recording NPZ")
        if info.file_size > DEFLATE_MAX_RATIO * info.compress_size + 4096:
            raise HostError(f"{where}: the zip says {info.file_size} bytes from {info.compress_size} compressed, "
                            f"more than deflate can give: not a gaitlog recording NPZ")
        with zf.open(info) as fh:
            try:
                shape, fortran, dtype = _npy_header(fh)
            except ValueError as err:
                raise HostError(f"{where}: {err}") from None
            header_bytes = fh.tell()
        if dtype.hasobject:
            raise HostError(f"{where}: holds Python objects (a pickle), which gaitlog never reads")
        nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
        if header_bytes + nbytes != info.file_size:
            raise HostError(f"{where}: declares shape {shape} ({nbytes} bytes), its zip member holds "
                            f"{info.file_size - header_bytes}: not a gaitlog recording NPZ")
        members[name] = _Member(info, tuple(shape), bool(fortran), dtype, nbytes)
    return members


def _judge_npz(path: Path, members: dict[str, _Member], required: Sequence[str]) -> None:
    """The members together against what the file holds (sizes, required arrays, shared sample count, memory)."""
    total = sum(m.nbytes for m in members.values())
    packed = sum(m.info.compress_size for m in members.values())
    if total > max(NPZ_SMALL_BYTES, MAX_NPZ_EXPANSION * packed):
        raise HostError(f"{path}: its arrays declare {total} bytes from {packed} compressed "
                        f"({total / max(packed, 1):,.0f} times); a recording NPZ is at most {MAX_NPZ_EXPANSION} "
                        "times: a zip bomb, not read")
    missing = sorted(set(required) - members.keys())
    if missing:
        raise HostError(f"{path}: not a gaitlog recording NPZ (missing arrays {missing})")
    counts = {name: members[name].shape[0] if members[name].shape else -1
              for name in _NPZ_PER_SAMPLE if name in members and name in required}
    if len(set(counts.values())) > 1:
        raise HostError(f"{path}: not a gaitlog recording NPZ (its arrays disagree on the sample count: "
                        + ", ".join(f"{k} {v}" for k, v in counts.items()) + ")")
    check_memory(total, path, "its arrays")


def _read_into(fh: Any, raw: np.ndarray) -> int:
    """Fill ``raw`` (uint8) from ``fh`` up to its size; the number of bytes read (fewer at the end of the data)."""
    view = memoryview(raw)
    got = 0
    while got < raw.size:
        k = fh.readinto(view[got:got + (1 << 20)])   # a zip member's readinto reads a bytes object this long
        if not k:
            break
        got += k
    return got


def _load_step_records(path: Path, arrays: dict[str, np.ndarray], meta: dict[str, Any], header: Any
                       ) -> tuple[np.ndarray, np.ndarray, list[RecordGap]]:
    """The step records of a loaded NPZ (none in a file saved before they existed)."""
    if "step_record_bytes" not in arrays:
        n_stored = int(getattr(header, "n_steps_stored", 0)) if header is not None else 0
        losses = []
        if n_stored:
            first = int(header.first_step_number)
            losses.append(RecordGap(first, first + n_stored - 1, "not in this NPZ (saved before gaitlog kept the "
                                                                  "step records): decode the dump again"))
        return np.zeros(0, STEP_RECORD_DTYPE), np.zeros(0, np.int64), losses
    raw = arrays["step_record_bytes"]
    numbers = arrays.get("step_record_numbers")
    if raw.dtype != np.uint8 or numbers is None:
        raise HostError(f"{path}: step_record_bytes must be uint8 with step_record_numbers beside it")
    try:
        records, crc_ok = unpack_step_records(raw.tobytes(), source=str(path))
    except Exception as err:  # ProtocolError: not whole records
        raise HostError(f"{path}: step_record_bytes: {err}") from err
    if not crc_ok.all():
        raise HostError(f"{path}: step record {int(np.flatnonzero(~crc_ok)[0])} of step_record_bytes fails its CRC "
                        "(the NPZ is damaged): decode the dump again")
    info = meta.get("step_records") or {}
    losses = [RecordGap(g["first_record_number"], g["last_record_number"], g["reason"])
              for g in info.get("losses", [])]
    return records, numbers, losses
