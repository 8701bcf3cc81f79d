"""Device header (256 bytes) and calibration slot (64 bytes): ``PROTOCOL.md`` sections 2 and 2.1.

The construct declarations :data:`HEADER_STRUCT` and :data:`CALIBRATION_STRUCT` are the byte layouts; the
dataclasses :class:`DeviceHeader` and :class:`CalibrationSlot` are the validated values with the decoder's rules
(stored samples, oldest slot, sample numbers and times; the same for the per-step records of the step
memory, section 2.3). The step configuration block at offset 128 is :class:`gaitlog.protocol.steps.StepConfig`.

Examples
--------
>>> h = DeviceHeader(device_id=7, samples_written=3, write_index=3, start_time_s=1_000_000_000)
>>> raw = h.to_bytes()
>>> len(raw), raw[:8].hex(), raw[-2:].hex()
(256, '474c4f4702010001', '8f8f')
>>> back = DeviceHeader.from_bytes(raw)
>>> back.device_id, back.n_stored, back.first_slot, back.sampling_rate_hz, back.start_time.isoformat()
(7, 3, 0, 50.0, '2001-09-09T01:46:40+00:00')
>>> DeviceHeader.from_bytes(b"GLOX" + raw[4:], source="x.glimg")
Traceback (most recent call last):
...
gaitlog.protocol.errors.ProtocolError: x.glimg, offset 0 (0x0): magic: expected b'GLOG', found b'GLOX' (not a gaitlog device header)
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import enum
from dataclasses import dataclass

import construct as cs
import numpy as np

from gaitlog.protocol.adc_bits import MAX_STORED_ADC_BITS, adc_bits_problem, check_adc_bits
from gaitlog.protocol.channel_map import CAL_FORMAT_CHANNEL_MAP, ChannelMap
from gaitlog.protocol.commit_journal import (
    JOURNAL_BYTES,
    JOURNAL_OFFSET,
    STEPS_SATURATED,
    committed_samples,
    empty_journal,
    last_commit,
)
from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.journal_ring import COMMIT_PAGES, HEADER_VERSION_RING, STEP_CAPACITY_RECORDS_V3
from gaitlog.protocol.layout import CompiledOnReuse, field_offsets
from gaitlog.protocol.steps import (
    STEP_CAPACITY_RECORDS,
    STEP_CONFIG_SIZE,
    STEP_RECORD_SIZE,
    STEPS_WRITTEN_MAX,
    StepConfig,
)

__all__ = [
    "HEADER_SIZE",
    "CALIBRATION_SIZE",
    "CAPACITY_SAMPLES",
    "MEMORY_BYTES",
    "MAGIC",
    "HEADER_VERSION",
    "PROTOCOL_VERSION",
    "KNOWN_HEADER_VERSIONS",
    "PAGE_SAMPLES",
    "PACKING_P32",
    "MAX_CAPACITY_SAMPLES",
    "SAMPLES_WRITTEN_MAX",
    "MILLIHZ_PER_HZ",
    "firmware_version_text",
    "HeaderFlag",
    "CalFormat",
    "HEADER_STRUCT",
    "HEADER_BODY_STRUCT",
    "CALIBRATION_STRUCT",
    "HEADER_OFFSETS",
    "HEADER_INT_FIELDS",
    "CALIBRATION_OFFSETS",
    "CalibrationSlot",
    "DeviceHeader",
]

HEADER_SIZE = 256
CALIBRATION_SIZE = 64
CAPACITY_SAMPLES = 65536
MEMORY_BYTES = 4 * CAPACITY_SAMPLES  # 262,144
MAGIC = b"GLOG"
#: Header version 2: recording identity (52-63), the page-commit journal (160-253, section 2.4) and the
#: header CRC over bytes 0-159. Version 1 headers (CRC over 0-253, no identity, no journal) are still read.
HEADER_VERSION = 2
#: Header versions a decoder reads.
KNOWN_HEADER_VERSIONS = (1, 2, HEADER_VERSION_RING)
#: Samples per 128-byte sample EEPROM page (the unit of a commit, section 2.4).
PAGE_SAMPLES = 32
PROTOCOL_VERSION = 1
PACKING_P32 = 1
MAX_CAPACITY_SAMPLES = 1 << 20
SAMPLES_WRITTEN_MAX = 0xFFFFFFFF  # the counter saturates here
#: The header's and INFO's ``sampling_rate_millihz`` counts millihertz (50 Hz = 50000).
MILLIHZ_PER_HZ = 1000


def firmware_version_text(code: int) -> str:
    """``firmware_version`` (major·256 + minor) as ``"major.minor"``.

    >>> firmware_version_text(0x0102)
    '1.2'
    """
    return f"{int(code) >> 8}.{int(code) & 0xFF}"


_Q16 = 1 << 16
_Q30 = 1 << 30


class HeaderFlag(enum.IntFlag):
    """Bits of the header ``flags`` byte (offset 19)."""

    OVERWRITE = 0x01  #: ring mode; clear = stop when full
    WRAPPED = 0x02  #: the write index has wrapped: the oldest sample is at ``write_index``
    LOGGING = 0x04  #: a logging run is in progress
    CAL_VALID = 0x08  #: the calibration slot holds an affine calibration (``cal_format`` 1)
    FULL_STOPPED = 0x10  #: logging stopped because the memory was full (stop-when-full mode)
    POWER_LOST = 0x20  #: the current run (from ``run_start_sample``) ended by a power loss (section 2.4)


class CalFormat(enum.IntEnum):
    """``cal_format`` byte of the calibration slot."""

    NONE = 0
    AFFINE = 1


#: Calibration slot, 64 bytes (section 2.1).
CALIBRATION_STRUCT = cs.Struct(
    "cal_format" / cs.Int8ul,
    "reserved0" / cs.Padding(3),
    "offset_q16" / cs.Array(3, cs.Int32sl),
    "matrix_q30" / cs.Array(9, cs.Int32sl),
    "reserved1" / cs.Padding(12),
)

#: Header bytes 0-253, the part the CRC covers (section 2). This is the one list of the header's fields: the
#: integer fields (with the default of a new header) become :class:`DeviceHeader`'s fields.
HEADER_BODY_STRUCT = cs.Struct(
    "magic" / cs.Const(MAGIC),
    "header_version" / cs.Default(cs.Int8ul, HEADER_VERSION),
    "protocol_version" / cs.Default(cs.Int8ul, PROTOCOL_VERSION),
    "firmware_version" / cs.Default(cs.Int16ul, 0x0100),
    "device_id" / cs.Default(cs.Int32ul, 1),
    "sampling_rate_millihz" / cs.Default(cs.Int32ul, 50 * MILLIHZ_PER_HZ),
    "adc_bits" / cs.Default(cs.Int8ul, 10),
    "axes" / cs.Default(cs.Int8ul, 3),
    "packing" / cs.Default(cs.Int8ul, PACKING_P32),
    "flags" / cs.Default(cs.Int8ul, 0),
    "start_time_s" / cs.Default(cs.Int32ul, 0),
    "capacity_samples" / cs.Default(cs.Int32ul, CAPACITY_SAMPLES),
    "write_index" / cs.Default(cs.Int32ul, 0),
    "samples_written" / cs.Default(cs.Int32ul, 0),
    "adc_vref_mv" / cs.Default(cs.Int32ul, 5000),
    "run_start_sample" / cs.Default(cs.Int32ul, 0),
    "steps_written" / cs.Default(cs.Int32ul, 0),
    "step_write_index" / cs.Default(cs.Int16ul, 0),
    "step_capacity" / cs.Default(cs.Int16ul, 0),
    "recording_number" / cs.Default(cs.Int32ul, 0),
    "recording_nonce" / cs.Default(cs.Int32ul, 0),
    "torn_slots" / cs.Default(cs.Int8ul, 0),
    "torn_step_records" / cs.Default(cs.Int8ul, 0),
    "reserved0" / cs.Padding(2),
    "calibration" / cs.Bytes(CALIBRATION_SIZE),
    "step_config" / cs.Bytes(STEP_CONFIG_SIZE),
    "commit_journal" / cs.Bytes(JOURNAL_BYTES),
)



def crc_span(body: bytes) -> bytes:
    """The bytes the header CRC covers: 0-253 in header version 1, 0-159 in version 2 and later (the journal
    area 160-253 changes while logging without a new CRC, section 2.4). The version is byte 4."""
    return body if len(body) > 4 and body[4] == 1 else body[:JOURNAL_OFFSET]


#: The whole 256-byte header: body plus big-endian CRC-16/XMODEM (over :func:`crc_span` of the body). Parsing
#: it checks the magic (``Const``) and the CRC (``Checksum``).
HEADER_STRUCT = cs.Struct(
    "body" / cs.RawCopy(HEADER_BODY_STRUCT),
    "header_crc" / cs.Checksum(cs.Int16ub, lambda data: crc16_xmodem(crc_span(data)), cs.this.body.data),
)


# the declarations above, compiled once reused (the hot paths: the emulated device; same values and bytes,
# tests/protocol/test_layout.py)
_HEADER_FAST = CompiledOnReuse(HEADER_STRUCT)
_CALIBRATION_FAST = CompiledOnReuse(CALIBRATION_STRUCT)

#: field name -> (offset, size) in the 256-byte header (``header_crc`` included).
HEADER_OFFSETS: dict[str, tuple[int, int]] = {**field_offsets(HEADER_BODY_STRUCT),
                                              "header_crc": field_offsets(HEADER_STRUCT)["header_crc"]}
#: field name -> (offset, size) in the 64-byte calibration slot.
CALIBRATION_OFFSETS: dict[str, tuple[int, int]] = field_offsets(CALIBRATION_STRUCT)

assert HEADER_BODY_STRUCT.sizeof() == HEADER_SIZE - 2 and CALIBRATION_STRUCT.sizeof() == CALIBRATION_SIZE


def _err(what: str, fieldname: str, source: str | None, base: int = 0, table: dict | None = None) -> ProtocolError:
    off = (table or HEADER_OFFSETS)[fieldname][0] + base
    return ProtocolError(f"{fieldname}: {what}", offset=off, source=source)


@dataclass(eq=False)
class CalibrationSlot:
    """Affine accelerometer calibration ``a_g = M · (codes − offset)`` (section 2.1).

    Parameters
    ----------
    offset_counts
        ``(3,)`` offset in ADC counts (stored in Q15.16: resolution 2⁻¹⁶ count, range ±32768).
    matrix_g_per_count
        ``(3, 3)`` matrix ``M`` in g per count, row-major (stored in Q1.30: resolution 2⁻³⁰ g/count, range ±2).
    valid
        ``True`` for a stored affine calibration (``cal_format`` 1); ``False`` for the nominal map, which is
        stored as ``cal_format`` 0 with zero fields.

    Examples
    --------
    >>> cal = CalibrationSlot(np.array([512.0, 500.25, 530.5]), np.diag([1 / 256, 1 / 250, 1 / 260]), True)
    >>> raw = cal.to_bytes()
    >>> raw[:16].hex()
    '01000000000000020040f40100801202'
    >>> cal.apply(np.array([[768, 500, 530]])).round(6).tolist()
    [[1.0, -0.001, -0.001923]]
    >>> CalibrationSlot.from_bytes(raw).offset_counts.tolist()
    [512.0, 500.25, 530.5]
    """

    offset_counts: np.ndarray
    matrix_g_per_count: np.ndarray
    valid: bool = True

    def __post_init__(self) -> None:
        self.offset_counts = np.asarray(self.offset_counts, dtype=np.float64).reshape(3)
        self.matrix_g_per_count = np.asarray(self.matrix_g_per_count, dtype=np.float64).reshape(3, 3)
        self.valid = bool(self.valid)

    @classmethod
    def nominal(cls, adc_bits: int = 10) -> "CalibrationSlot":
        """The nominal map: offset ``2^(adc_bits−1)`` counts, ``M = diag(4 g / 2^adc_bits)`` (±2 g span).

        >>> float(CalibrationSlot.nominal(10).matrix_g_per_count[0, 0]), CalibrationSlot.nominal(10).valid
        (0.00390625, False)
        """
        check_adc_bits(adc_bits)
        span = float(1 << int(adc_bits))
        return cls(np.full(3, span / 2), np.eye(3) * (4.0 / span), valid=False)

    def apply(self, codes: np.ndarray) -> np.ndarray:
        """Acceleration in g, ``(n, 3)``, from codes in counts, ``(n, 3)``."""
        c = np.asarray(codes, dtype=np.float64)
        return (c - self.offset_counts) @ self.matrix_g_per_count.T

    def quantised(self) -> "CalibrationSlot":
        """The calibration exactly as it is stored (offset to 2⁻¹⁶ count, matrix to 2⁻³⁰ g/count)."""
        return CalibrationSlot.from_bytes(self.to_bytes()) if self.valid else self

    def to_bytes(self) -> bytes:
        """The 64-byte slot. ``valid=False`` gives ``cal_format`` 0 and zero fields.

        Raises
        ------
        ProtocolError
            A non-finite value, an offset outside ±32768 counts or a matrix element outside ±2 g/count.
        """
        if not self.valid:
            return bytes(CALIBRATION_SIZE)
        off = self.offset_counts
        mat = self.matrix_g_per_count
        if not (np.all(np.isfinite(off)) and np.all(np.isfinite(mat))):
            raise _err("non-finite value", "offset_q16" if not np.all(np.isfinite(off)) else "matrix_q30",
                       None, table=CALIBRATION_OFFSETS)
        off_q = np.rint(off * _Q16)
        mat_q = np.rint(mat.reshape(9) * _Q30)
        lim = float(1 << 31)
        if np.any(off_q < -lim) or np.any(off_q >= lim):
            raise _err(f"offset {off.tolist()} counts outside the Q15.16 range ±32768", "offset_q16", None,
                       table=CALIBRATION_OFFSETS)
        if np.any(mat_q < -lim) or np.any(mat_q >= lim):
            raise _err("matrix element outside the Q1.30 range ±2 g/count", "matrix_q30", None,
                       table=CALIBRATION_OFFSETS)
        return _CALIBRATION_FAST.build(
            dict(cal_format=int(CalFormat.AFFINE), offset_q16=[int(v) for v in off_q],
                 matrix_q30=[int(v) for v in mat_q])
        )

    @classmethod
    def from_bytes(cls, data: bytes, adc_bits: int = 10, *, source: str | None = None,
                   base_offset: int = 0) -> "CalibrationSlot":
        """Parse a 64-byte slot; ``cal_format`` 0 gives :meth:`nominal` for ``adc_bits``.

        Raises
        ------
        ProtocolError
            Wrong length, or a ``cal_format`` other than 0 or 1 (offset ``base_offset + 0``).
        """
        if len(data) != CALIBRATION_SIZE:
            raise ProtocolError(f"calibration slot: expected {CALIBRATION_SIZE} bytes, found {len(data)}",
                                offset=base_offset, source=source)
        c = _CALIBRATION_FAST.parse(data)
        if c.cal_format == CalFormat.NONE:
            return cls.nominal(adc_bits)
        if c.cal_format != CalFormat.AFFINE:
            raise _err(f"unknown calibration format {c.cal_format} (known: 0 none, 1 affine, 2 channel map)", "cal_format",
                       source, base_offset, CALIBRATION_OFFSETS)
        return cls(np.array(c.offset_q16, dtype=np.float64) / _Q16,
                   np.array(c.matrix_q30, dtype=np.float64).reshape(3, 3) / _Q30, valid=True)


_U_LIMITS = {1: 0xFF, 2: 0xFFFF, 4: 0xFFFFFFFF}
#: The integer fields of the header and the value of each in a new header, in layout order (read from the
#: construct declaration).
_HEADER_INT_DEFAULTS: dict[str, int] = {sc.name: sc.subcon.value for sc in HEADER_BODY_STRUCT.subcons
                                        if isinstance(sc.subcon, cs.Default)}
#: The integer fields of the header, in layout order.
HEADER_INT_FIELDS: tuple[str, ...] = tuple(_HEADER_INT_DEFAULTS)

#: The integer fields as a dataclass (the base of :class:`DeviceHeader`), generated from the declaration.
_HeaderIntFields = dataclasses.make_dataclass(
    "_HeaderIntFields", [(name, int, dataclasses.field(default=value)) for name, value in _HEADER_INT_DEFAULTS.items()],
    eq=False)


def _construct_error(exc: cs.ConstructError, data: bytes, source: str | None) -> ProtocolError:
    """A construct parsing error of :data:`HEADER_STRUCT` as a one-line error naming the field and its offset."""
    if isinstance(exc, cs.ChecksumError):
        at, size = HEADER_OFFSETS["header_crc"]
        span = crc_span(data[:at])
        stored, computed = int.from_bytes(data[at: at + size], "big"), crc16_xmodem(span)
        return _err(f"CRC mismatch: stored 0x{stored:04x}, computed 0x{computed:04x} over bytes 0-{len(span) - 1}",
                    "header_crc", source)
    if isinstance(exc, cs.ConstError):
        at, size = HEADER_OFFSETS["magic"]
        return _err(f"expected {MAGIC!r}, found {data[at: at + size]!r} (not a gaitlog device header)", "magic",
                    source)
    return ProtocolError(f"device header: {str(exc).strip().splitlines()[-1]}", source=source)  # pragma: no cover


@dataclass(eq=False)
class DeviceHeader(_HeaderIntFields):
    """The 256-byte device header (section 2), validated.

    Field names and meanings are those of the table in ``PROTOCOL.md`` section 2; the integer fields and
    their defaults come from :data:`HEADER_BODY_STRUCT`; ``magic`` and ``header_crc`` are implicit. ``calibration`` ``None`` means the nominal map for ``adc_bits``.
    The ``CAL_VALID`` flag bit is written from ``calibration.valid``. ``step_config`` ``None`` means the
    on-line step algorithm off (:meth:`StepConfig.off`); ``step_capacity`` 0 means no step memory (the
    default, and the behaviour of headers written before the step memory existed).

    Examples
    --------
    >>> h = DeviceHeader(step_capacity=3276, steps_written=3300, step_write_index=24)
    >>> h.n_steps_stored, h.first_step_slot, h.first_step_number, h.step_used_bytes
    (3276, 24, 24, 65520)
    >>> h.step_slots()[[0, -1]].tolist()
    [24, 23]
    """

    calibration: CalibrationSlot | ChannelMap | None = None
    step_config: StepConfig | None = None
    commit_journal: bytes = dataclasses.field(default_factory=empty_journal)

    def __post_init__(self) -> None:
        if self.calibration is None:
            self.calibration = CalibrationSlot.nominal(self.adc_bits if adc_bits_problem(self.adc_bits) is None else MAX_STORED_ADC_BITS)
        if self.step_config is None:
            self.step_config = StepConfig.off()
        flags = int(self.flags) & ~int(HeaderFlag.CAL_VALID)
        self.flags = flags | (int(HeaderFlag.CAL_VALID) if self.calibration.valid else 0)

    # ------------------------------------------------------------------ derived quantities (section 2)
    @property
    def overwrite(self) -> bool:
        """Ring mode (``OVERWRITE`` flag); ``False`` = stop when full."""
        return bool(self.flags & HeaderFlag.OVERWRITE)

    @property
    def wrapped(self) -> bool:
        """``WRAPPED`` flag: the oldest stored sample is at ``write_index``."""
        return bool(self.flags & HeaderFlag.WRAPPED)

    @property
    def logging(self) -> bool:
        """``LOGGING`` flag."""
        return bool(self.flags & HeaderFlag.LOGGING)

    @property
    def power_lost(self) -> bool:
        """``POWER_LOST`` flag (header version 2; the bit is reserved in version 1)."""
        return self.header_version != 1 and bool(self.flags & HeaderFlag.POWER_LOST)

    @property
    def recording_id(self) -> tuple[int, int, int]:
        """``(device_id, recording_number, recording_nonce)``: which recording this is (section 2.4); two
        headers of different recordings never share it (both numbers are 0 in header version 1)."""
        return int(self.device_id), int(self.recording_number), int(self.recording_nonce)

    def torn_slot_numbers(self) -> np.ndarray:
        """Slots a page write cut by a power loss left undefined that the header counts as stored (``torn_slots``
        from ``write_index``, when the memory has wrapped), ``int64``."""
        if not self.torn_slots or not self.wrapped:
            return np.zeros(0, dtype=np.int64)
        return (self.write_index + np.arange(self.torn_slots, dtype=np.int64)) % self.capacity_samples

    def recovered(self, last: tuple[int, int] | None = None) -> "DeviceHeader":
        """The header after a power loss during a run (``LOGGING`` set, header version 2): the counters of the
        run's last committed page from the journal (section 2.4), ``LOGGING`` cleared, ``POWER_LOST`` set,
        ``torn_slots`` the slots of the page in flight that were stored samples, ``torn_step_records`` 0 (the
        firmware sets it after looking at the step ring). What the firmware writes at power-up and what a
        decoder applies to a header read with ``LOGGING`` set. A header without ``LOGGING``, or of version 1
        (no journal), is returned unchanged. ``last``: ``(m, steps)`` of the last commit when the journal is
        elsewhere (header version 3: :func:`gaitlog.protocol.journal_ring.last_ring_commit`; without it a
        version-3 run recovers nothing, as its data EEPROM journal stays empty); up to two pages from the
        recovered ``write_index`` are then torn.
        """
        if not self.logging or self.header_version == 1:
            return self
        m, steps = last if last is not None else last_commit(self.commit_journal)
        cap = int(self.capacity_samples)
        n = committed_samples(m, first_slot=int(self.write_index), page_samples=PAGE_SAMPLES)
        if not self.overwrite:
            n = min(n, cap - int(self.samples_written))
        sw = min(int(self.samples_written) + n, SAMPLES_WRITTEN_MAX)
        wi = (int(self.write_index) + n) % cap
        flags = int(self.flags) & ~int(HeaderFlag.LOGGING) | int(HeaderFlag.POWER_LOST)
        if self.overwrite and sw >= cap:
            flags |= int(HeaderFlag.WRAPPED)
        if not self.overwrite and sw >= cap:
            flags |= int(HeaderFlag.FULL_STOPPED)
        torn = 0
        if flags & HeaderFlag.WRAPPED and not flags & HeaderFlag.FULL_STOPPED:
            torn = PAGE_SAMPLES - wi % PAGE_SAMPLES
            if self.header_version == HEADER_VERSION_RING:
                torn = min(torn + (COMMIT_PAGES - 1) * PAGE_SAMPLES, cap)
        out = self.replace(flags=flags, samples_written=sw, write_index=wi, torn_slots=torn, torn_step_records=0)
        if self.step_capacity and steps != STEPS_SATURATED:
            out.steps_written = min(int(self.steps_written) + steps, STEPS_WRITTEN_MAX)
            out.step_write_index = (int(self.step_write_index) + steps) % int(self.step_capacity)
        return out

    @property
    def full_stopped(self) -> bool:
        """``FULL_STOPPED`` flag."""
        return bool(self.flags & HeaderFlag.FULL_STOPPED)

    @property
    def n_stored(self) -> int:
        """Stored samples ``min(samples_written, capacity_samples)``."""
        return min(self.samples_written, self.capacity_samples)

    @property
    def first_slot(self) -> int:
        """Slot of the oldest stored sample: ``write_index`` if wrapped, else 0."""
        return self.write_index if self.wrapped else 0

    @property
    def first_sample_number(self) -> int:
        """Absolute sample number (0 = first sample after ERASE) of the oldest stored sample."""
        return self.samples_written - self.n_stored

    @property
    def sampling_rate_hz(self) -> float:
        """Sampling rate in Hz (``sampling_rate_millihz / MILLIHZ_PER_HZ``)."""
        return self.sampling_rate_millihz / MILLIHZ_PER_HZ

    @property
    def start_time(self) -> _dt.datetime:
        """``start_time_s`` as an aware UTC datetime (time of sample number ``run_start_sample``)."""
        return _dt.datetime.fromtimestamp(self.start_time_s, tz=_dt.timezone.utc)

    @property
    def memory_bytes(self) -> int:
        """Size of the sample memory in bytes (4 per slot)."""
        return 4 * self.capacity_samples

    @property
    def used_bytes(self) -> int:
        """Meaningful bytes of the memory from address 0: ``4 · n_stored`` (the whole memory when wrapped)."""
        return 4 * self.n_stored

    @property
    def step_memory_bytes(self) -> int:
        """Size of the step ring in bytes (20 per record; 0 without step memory)."""
        return STEP_RECORD_SIZE * self.step_capacity

    @property
    def n_steps_stored(self) -> int:
        """Stored per-step records ``min(steps_written, step_capacity)``."""
        return min(self.steps_written, self.step_capacity)

    @property
    def steps_wrapped(self) -> bool:
        """The step ring has wrapped (``steps_written`` ≥ ``step_capacity`` > 0): the oldest record is at
        ``step_write_index``."""
        return 0 < self.step_capacity <= self.steps_written

    @property
    def first_step_slot(self) -> int:
        """Slot of the oldest stored record: ``step_write_index`` if the step ring wrapped, else 0."""
        return self.step_write_index if self.steps_wrapped else 0

    @property
    def first_step_number(self) -> int:
        """Absolute number (0 = first record after ERASE) of the oldest stored record."""
        return self.steps_written - self.n_steps_stored

    @property
    def step_used_bytes(self) -> int:
        """Meaningful bytes of the step memory from its address 0: ``20 · n_steps_stored``."""
        return STEP_RECORD_SIZE * self.n_steps_stored

    def step_slots(self) -> np.ndarray:
        """Slots of the stored records, oldest first: ``(first_step_slot + i) mod step_capacity``, ``int64``."""
        return _ring_slots(self.first_step_slot, self.n_steps_stored, self.step_capacity)

    def stored_slots(self) -> np.ndarray:
        """Slots of the stored samples, oldest first: ``(first_slot + i) mod capacity``, ``int64``."""
        return _ring_slots(self.first_slot, self.n_stored, self.capacity_samples)

    def sample_numbers(self) -> np.ndarray:
        """Absolute sample numbers of the stored samples, oldest first, ``int64``."""
        return self.first_sample_number + np.arange(self.n_stored, dtype=np.int64)

    def sample_time_s(self, sample_numbers: np.ndarray | int) -> np.ndarray:
        """Unix time in s of absolute sample numbers: ``start_time_s + (k − run_start_sample) / rate``.

        Exact for samples of the current run (``k ≥ run_start_sample``); for older runs it is an
        extrapolation (the device does not store earlier start times; their first samples carry the
        SESSION_START flag).
        """
        k = np.asarray(sample_numbers, dtype=np.float64)
        return self.start_time_s + (k - self.run_start_sample) / self.sampling_rate_hz

    # ------------------------------------------------------------------ validation and bytes
    def validate(self, source: str | None = None) -> None:
        """Check every field against section 2; raise :class:`ProtocolError` naming the field and offset."""
        for name in HEADER_INT_FIELDS:
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise _err(f"must be an integer, got {value!r}", name, source)
            if not 0 <= int(value) <= _U_LIMITS[HEADER_OFFSETS[name][1]]:
                raise _err(f"{value} does not fit in {HEADER_OFFSETS[name][1]} unsigned byte(s)", name, source)
        if self.header_version not in KNOWN_HEADER_VERSIONS:
            raise _err(f"unknown header version {self.header_version} (this decoder knows "
                       f"{', '.join(map(str, KNOWN_HEADER_VERSIONS))})", "header_version", source)
        if self.protocol_version != PROTOCOL_VERSION:
            raise _err(f"unknown protocol version {self.protocol_version} (this decoder knows "
                       f"{PROTOCOL_VERSION})", "protocol_version", source)
        if self.sampling_rate_millihz == 0:
            raise _err("sample rate 0", "sampling_rate_millihz", source)
        if (problem := adc_bits_problem(self.adc_bits)) is not None:
            raise _err(problem, "adc_bits", source)
        mapped = isinstance(self.calibration, ChannelMap)
        channels = self.calibration.n_channels if mapped else 3
        if self.axes != channels:
            raise _err(f"{self.axes} axes (expected {channels}" + (": the channel map's channels)" if mapped else
                       "; other counts need a channel map in the calibration slot, section 2.6)"), "axes", source)
        if mapped and self.step_config is not None and self.step_config.enabled:
            raise _err("a channel map (section 2.6) with the on-line step algorithm on: the algorithm reads the "
                       "three-axis accelerometer", "step_config", source)
        if self.packing != PACKING_P32:
            raise _err(f"unknown packing {self.packing} (expected 1 = P32)", "packing", source)
        cap = self.capacity_samples
        if not 1 <= cap <= MAX_CAPACITY_SAMPLES:
            raise _err(f"{cap} outside 1..{MAX_CAPACITY_SAMPLES}", "capacity_samples", source)
        if self.write_index >= cap:
            raise _err(f"{self.write_index} not below capacity {cap}", "write_index", source)
        sw = self.samples_written
        if self.wrapped:
            if sw < cap:
                raise _err(f"WRAPPED set but only {sw} samples written (capacity {cap})", "samples_written",
                           source)
            if sw != SAMPLES_WRITTEN_MAX and self.write_index != sw % cap:
                raise _err(f"{sw} samples written but write_index {self.write_index} "
                           f"(expected {sw % cap})", "samples_written", source)
        else:
            if sw > cap:
                raise _err(f"{sw} samples written exceed capacity {cap} without WRAPPED", "samples_written",
                           source)
            if self.write_index != sw % cap:
                raise _err(f"{sw} samples written but write_index {self.write_index} (expected {sw % cap})",
                           "samples_written", source)
        if self.run_start_sample > sw:
            raise _err(f"{self.run_start_sample} beyond samples_written {sw}", "run_start_sample", source)
        pages = COMMIT_PAGES if self.header_version == HEADER_VERSION_RING else 1
        if self.torn_slots > pages * PAGE_SAMPLES - self.write_index % PAGE_SAMPLES:
            raise _err(f"{self.torn_slots} slots from write_index {self.write_index} leave its "
                       f"{PAGE_SAMPLES}-sample page" + (" and the next" if pages > 1 else ""), "torn_slots", source)
        if self.header_version == 1 and (self.recording_number or self.recording_nonce or self.torn_slots
                                         or self.torn_step_records):
            raise _err("header version 1 has no recording identity and no torn slots", "header_version", source)
        self._validate_steps(source)
        if not isinstance(self.calibration, (CalibrationSlot, ChannelMap)):
            raise _err("must be a CalibrationSlot or a ChannelMap", "calibration", source)
        if not isinstance(self.step_config, StepConfig):
            raise _err("must be a StepConfig", "step_config", source)
        try:
            self.step_config.raw  # noqa: B018 - quantises and range-checks every value
        except ProtocolError as exc:
            raise exc.at(offset=HEADER_OFFSETS["step_config"][0], source=source) from None

    def _validate_steps(self, source: str | None) -> None:
        """The step counters (section 2.3): like the sample counters, but the step ring always overwrites."""
        cap, sw, wi = self.step_capacity, self.steps_written, self.step_write_index
        most = STEP_CAPACITY_RECORDS_V3 if self.header_version == HEADER_VERSION_RING else STEP_CAPACITY_RECORDS
        if cap > most:
            raise _err(f"{cap} records do not fit the step ring (at most {most} in a 64 KiB block"
                       + (", in front of the journal ring)" if most != STEP_CAPACITY_RECORDS else ")"),
                       "step_capacity", source)
        if cap == 0:
            if sw != 0:
                raise _err(f"{sw} records written but step_capacity is 0 (no step memory)", "steps_written",
                           source)
            if wi != 0:
                raise _err(f"{wi} but step_capacity is 0 (no step memory; expected 0)", "step_write_index",
                           source)
            return
        if wi >= cap:
            raise _err(f"{wi} not below step_capacity {cap}", "step_write_index", source)
        if sw != STEPS_WRITTEN_MAX and wi != sw % cap:
            raise _err(f"{sw} records written but step_write_index {wi} (expected {sw % cap})", "steps_written",
                       source)

    def to_bytes(self) -> bytes:
        """The 256-byte header with its CRC (``CAL_VALID`` written from ``calibration.valid``).

        Raises
        ------
        ProtocolError
            A field violating section 2 (named, with its offset).
        """
        self.__post_init__()
        self.validate()
        assert self.calibration is not None and self.step_config is not None
        values = {name: int(getattr(self, name)) for name in HEADER_INT_FIELDS}
        journal = bytes(self.commit_journal) if self.header_version != 1 else bytes(JOURNAL_BYTES)
        if len(journal) != JOURNAL_BYTES:
            raise _err(f"{len(journal)} bytes (expected {JOURNAL_BYTES})", "commit_journal", None)
        return _HEADER_FAST.build({"body": {"value": {"calibration": self.calibration.to_bytes(),
                                                      "step_config": self.step_config.to_bytes(),
                                                      "commit_journal": journal, **values}}})

    @classmethod
    def from_bytes(cls, data: bytes | bytearray | memoryview, source: str | None = None) -> "DeviceHeader":
        """Parse and validate a 256-byte header.

        Parameters
        ----------
        data
            At least 256 bytes; only the first 256 are read.
        source
            Name of the file or port, for error messages.

        Raises
        ------
        ProtocolError
            Short input, wrong magic, bad CRC, unknown versions, or a field violating section 2; the error
            names the field and its byte offset in the header.
        """
        data = bytes(data[:HEADER_SIZE])
        if len(data) < HEADER_SIZE:
            raise ProtocolError(f"device header truncated: {len(data)} of {HEADER_SIZE} bytes",
                                offset=len(data), source=source)
        try:
            body = _HEADER_FAST.parse(data).body.value  # checks the magic and the CRC
        except cs.ConstructError as exc:
            raise _construct_error(exc, data, source) from None
        values = {name: int(body[name]) for name in HEADER_INT_FIELDS}
        # versions first: a newer layout may not be parseable further
        header = cls.__new__(cls)
        for name, value in values.items():
            setattr(header, name, value)
        header.calibration = CalibrationSlot.nominal(10)
        header.step_config = StepConfig.off()
        header.commit_journal = bytes(body.commit_journal) if header.header_version != 1 else empty_journal()
        if header.header_version == 1:  # bytes 52-63 were reserved: ignored, as section 7 says
            header.recording_number = header.recording_nonce = header.torn_slots = header.torn_step_records = 0
        if header.header_version not in KNOWN_HEADER_VERSIONS or header.protocol_version != PROTOCOL_VERSION:
            header.validate(source)
        if (problem := adc_bits_problem(header.adc_bits)) is not None:
            raise _err(problem, "adc_bits", source)
        cal_off = HEADER_OFFSETS["calibration"][0]
        cal: CalibrationSlot | ChannelMap
        if body.calibration[0] == CAL_FORMAT_CHANNEL_MAP:  # section 2.6: an instrument's channels
            cal = ChannelMap.from_bytes(body.calibration, source=source, base_offset=cal_off)
        else:
            cal = CalibrationSlot.from_bytes(body.calibration, header.adc_bits, source=source, base_offset=cal_off)
        if bool(header.flags & HeaderFlag.CAL_VALID) != cal.valid:
            raise ProtocolError(
                f"calibration: CAL_VALID flag is {bool(header.flags & HeaderFlag.CAL_VALID)} but cal_format "
                f"is {int(cal.valid)}", offset=cal_off, source=source)
        header.calibration = cal
        header.step_config = StepConfig.from_bytes(body.step_config, source=source,
                                                   base_offset=HEADER_OFFSETS["step_config"][0])
        header.validate(source)
        return header

    def replace(self, **changes: object) -> "DeviceHeader":
        """A copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]




def _ring_slots(first: int, n: int, capacity: int) -> np.ndarray:
    """Slots ``(first + i) mod capacity`` for ``i < n <= capacity``, ``int64`` (no modulo: 10x faster)."""
    slots = np.arange(first, first + n, dtype=np.int64)
    slots[slots >= capacity] -= capacity
    return slots
