"""Per-step records, the step memory and the step configuration block (``PROTOCOL.md`` sections 2.2, 2.3).

While logging, the firmware's on-line step algorithm stores one 20-byte **per-step record** per detected
foot-flat in a third 24LC1025 (the *step memory*), beside the samples. This module is the format side of
that: the record layout (:data:`STEP_RECORD_STRUCT`, the construct declaration, and its numpy twin
:data:`STEP_RECORD_DTYPE` derived from it), the vectorised encoder and decoder of whole stores
(:func:`pack_step_records`, :func:`unpack_step_records`), the host addressing of the step memory
(:data:`STEP_ADDRESS_BASE`, :func:`memory_region`) and the 32-byte step configuration block of the device
header (:data:`STEP_CONFIG_STRUCT`, :class:`StepConfig`).

Examples
--------
>>> rec = empty_step_records(1)
>>> rec["end_sample"], rec["duration_samples"], rec["length_m1_q14"] = 1000, 55, 11469  # 0.7 m
>>> raw = pack_step_records(rec)
>>> len(raw), raw.hex(" ")
(20, 'e8 03 00 00 37 00 00 00 cd 2c 00 00 00 00 00 00 00 00 0e d1')
>>> back, crc_ok = unpack_step_records(raw)
>>> int(back["end_sample"][0]), round(float(step_lengths_m(back)[0, 0]), 4), crc_ok.tolist()
(1000, 0.7, [True])
>>> unpack_step_records(raw[:19] + b"\\x00")[1].tolist()
[False]
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any, Literal

import construct as cs
import numpy as np

from gaitlog.protocol.crc import crc16_xmodem, crc16_xmodem_rows
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.layout import CompiledOnReuse, field_offsets, named_fields

__all__ = [
    "STEP_RECORD_SIZE",
    "STEP_CAPACITY_RECORDS",
    "STEP_MEMORY_BYTES",
    "STEP_SCRATCH_BYTES",
    "STEP_ADDRESS_BASE",
    "STEP_CONFIG_SIZE",
    "STEPS_WRITTEN_MAX",
    "HEEL_STRIKE_NOT_FOUND",
    "STEP_LENGTH_FRACTION_BITS",
    "STEP_LENGTH_FIELDS",
    "StepFlag",
    "StepFormat",
    "ONLINE_ALGORITHM_VERSION",
    "ALGORITHM_VERSIONS",
    "StepConfigFlag",
    "M4_EXPONENT_EIGHTHS_MAX",
    "STEP_RECORD_BODY_STRUCT",
    "STEP_RECORD_STRUCT",
    "STEP_RECORD_OFFSETS",
    "STEP_RECORD_DTYPE",
    "STEP_CONFIG_STRUCT",
    "STEP_CONFIG_OFFSETS",
    "empty_step_records",
    "pack_step_records",
    "unpack_step_records",
    "stored_step_records",
    "build_step_record",
    "parse_step_record",
    "step_lengths_m",
    "memory_region",
    "StepConfig",
]

#: Bytes per record.
STEP_RECORD_SIZE = 20
#: Records in the step ring: as many as fit the first 64 KiB block of the step 24LC1025.
STEP_CAPACITY_RECORDS = 65536 // STEP_RECORD_SIZE  # 3276
#: Bytes of the step ring (record k at byte 20·k).
STEP_MEMORY_BYTES = STEP_RECORD_SIZE * STEP_CAPACITY_RECORDS  # 65,520
#: The second 64 KiB block of the step 24LC1025: the on-line algorithm's private scratch ring (never read
#: by the host).
STEP_SCRATCH_BYTES = 65536
#: Host address of step-memory byte 0 (READ / DUMP; sample memory addresses stay 0 ... 4·capacity − 1).
STEP_ADDRESS_BASE = 0x01000000
#: Bytes of the step configuration block (header offset 128).
STEP_CONFIG_SIZE = 32
#: ``steps_written`` saturates here.
STEPS_WRITTEN_MAX = 0xFFFFFFFF
#: ``heel_strike_samples`` of a step whose heel strike was not found.
HEEL_STRIKE_NOT_FOUND = -128
#: Step lengths are unsigned Q2.14 metres: raw / 2^14 = m (0 ... 4 m, 61 µm).
STEP_LENGTH_FRACTION_BITS = 14
#: The five length fields, M1 ... M5.
STEP_LENGTH_FIELDS = tuple(f"length_m{k}_q14" for k in range(1, 6))


class StepFlag(enum.IntFlag):
    """Bits of a record's ``flags`` byte (offset 7)."""

    NO_WINDOW = 0x01  #: bout start: no previous foot-flat, duration 0, every length 0
    NO_TOE_OFF = 0x02  #: toe-off not found (``toe_off_samples`` 0)
    NO_HEEL_STRIKE = 0x04  #: heel strike not found (``heel_strike_samples`` −128)
    M3_UNDEFINED = 0x08  #: no single-support phase (toe-off/heel-strike missing or out of order): M3 is 0
    IMPOSSIBLE = 0x10  #: a vertical excursion h > 2 l in M1, M2 or M3: that length is 0
    SATURATED = 0x20  #: a fixed-point operation saturated while this step was computed
    UNCALIBRATED = 0x40  #: no K configured: raw values (M1, M2, M4 with K = 1; M5 the cadence 1/T, Hz)


class StepFormat(enum.IntEnum):
    """``step_format`` byte of the step configuration block."""

    OFF = 0  #: the on-line step algorithm is off (plain logging)
    V1 = 1  #: on-line algorithm version 1 (firmware 1.0; images only: later firmware stores its own version)
    V2 = 2  #: on-line algorithm version 2 (firmware 1.1; images only: firmware 1.2 stores 3)
    V3 = 3  #: on-line algorithm version 3 (firmware 1.2; images only: firmware 1.3 stores 4)
    V4 = 4  #: on-line algorithm version 4 (firmware 1.3: the version the firmware runs)


#: The on-line algorithm version the firmware runs: SET_STEP_CONFIG with any on-line ``step_format`` turns
#: it on, and the device stores this version in its header (PROTOCOL.md 2.2), so an image says which
#: algorithm wrote its step records.
ONLINE_ALGORITHM_VERSION = StepFormat.V4
#: The largest M4 exponent a step configuration holds, in eighths (1/2: the uncalibrated record's ``range^p``, in
#: (m/s^2)^p, must fit its 0-4 m length field up to a range of 16 m/s^2).
M4_EXPONENT_EIGHTHS_MAX = 4

#: What each on-line algorithm version computed, one line each (a decoder says it for an image's records).
ALGORITHM_VERSIONS = {
    StepFormat.V1: ("on-line algorithm version 1 (firmware 1.0): minimum foot-flat distance min_step until three "
                    "step intervals are known, every confirmed peak a foot-flat candidate; M4 = K range^p with "
                    "p = 1/4 in earlier and 1/2 in later builds, which the image does not record"),
    StepFormat.V2: ("on-line algorithm version 2 (firmware 1.1): minimum foot-flat distance from a prior typical "
                    "step of 0.55 s until three step intervals are known, foot-flats only above zero, a fixed "
                    "0.5 m/s^2 foot-flat prominence; M4 = K range^(1/2)"),
    StepFormat.V3: ("on-line algorithm version 3 (firmware 1.2): as version 2, with the foot-flat prominence 0.25 "
                    "of the recent step amplitude within 0.25-0.5 m/s^2 (slow, short-stepped walking)"),
    StepFormat.V4: ("on-line algorithm version 4 (firmware 1.3): as version 3, with M4's exponent p from the step "
                    "configuration (m4_exponent_eighths; the firmware's default 1/4, Weinberg's) and no stop rule "
                    "(a bout's weak last step is not counted)"),
}


class StepConfigFlag(enum.IntFlag):
    """Bits of the configuration's ``step_flags`` byte (offset 1); the other bits are 0."""

    CALIBRATED = 0x01  #: the K constants are valid


#: Record bytes 0-17, the part the CRC covers (section 2.3).
STEP_RECORD_BODY_STRUCT = cs.Struct(
    "end_sample" / cs.Int32ul,
    "duration_samples" / cs.Int8ul,
    "toe_off_samples" / cs.Int8ul,
    "heel_strike_samples" / cs.Int8sl,
    "flags" / cs.Int8ul,
    "length_m1_q14" / cs.Int16ul,
    "length_m2_q14" / cs.Int16ul,
    "length_m3_q14" / cs.Int16ul,
    "length_m4_q14" / cs.Int16ul,
    "length_m5_q14" / cs.Int16ul,
)

#: The whole 20-byte record: body plus big-endian CRC-16/XMODEM over bytes 0-17.
STEP_RECORD_STRUCT = cs.Struct(
    "body" / cs.RawCopy(STEP_RECORD_BODY_STRUCT),
    "record_crc" / cs.Checksum(cs.Int16ub, lambda data: crc16_xmodem(data), cs.this.body.data),
)

#: Step configuration block, 32 bytes at header offset 128 (section 2.2).
STEP_CONFIG_STRUCT = cs.Struct(
    "step_format" / cs.Int8ul,
    "step_flags" / cs.Int8ul,
    "leg_length_q15" / cs.Int16ul,
    "foot_length_q15" / cs.Int16ul,
    "k_m1_q15" / cs.Int16ul,
    "k_m2_q15" / cs.Int16ul,
    "k_m4_q15" / cs.Int16ul,
    "k1_m5_q16" / cs.Int32sl,
    "k2_m5_q16" / cs.Int32sl,
    "m4_exponent_eighths" / cs.Int8ul,
    "reserved" / cs.Padding(11),
)


_CRC_FIELD = STEP_RECORD_STRUCT.subcons[1].subcon.checksumfield  # Int16ub
#: field name -> (offset, size) in the 20-byte record (``record_crc`` included).
STEP_RECORD_OFFSETS: dict[str, tuple[int, int]] = {
    **field_offsets(STEP_RECORD_BODY_STRUCT),
    "record_crc": (STEP_RECORD_BODY_STRUCT.sizeof(), _CRC_FIELD.sizeof()),
}
#: field name -> (offset, size) in the 32-byte step configuration block.
STEP_CONFIG_OFFSETS: dict[str, tuple[int, int]] = field_offsets(STEP_CONFIG_STRUCT)

_NUMPY_CODE = {"B": "u1", "b": "i1", "H": "u2", "h": "i2", "L": "u4", "l": "i4", "I": "u4", "i": "i4"}


def _numpy_type(ff: cs.FormatField) -> str:
    """The numpy type string of a construct integer field (``"<L"`` -> ``"<u4"``)."""
    order, code = ff.fmtstr[0], ff.fmtstr[1:]
    return (order if code not in "Bb" else "|") + _NUMPY_CODE[code]


def _int_range(ff: cs.FormatField) -> tuple[int, int]:
    """Inclusive value range of a construct integer field."""
    bits = 8 * ff.sizeof()
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if ff.fmtstr[1:].islower() else (0, (1 << bits) - 1)


#: numpy twin of :data:`STEP_RECORD_STRUCT` (derived from it): bytes 0-17 little-endian, ``record_crc`` ``>u2``.
STEP_RECORD_DTYPE = np.dtype(
    [(name, _numpy_type(sc)) for name, _, sc in named_fields(STEP_RECORD_BODY_STRUCT)]
    + [("record_crc", _numpy_type(_CRC_FIELD))]
)

assert STEP_RECORD_STRUCT.sizeof() == STEP_RECORD_DTYPE.itemsize == STEP_RECORD_SIZE
assert STEP_CONFIG_STRUCT.sizeof() == STEP_CONFIG_SIZE and STEP_MEMORY_BYTES <= 65536
_BODY_SIZE = STEP_RECORD_OFFSETS["record_crc"][0]  # 18


# ---------------------------------------------------------------------------------------------- records
def empty_step_records(n: int) -> np.ndarray:
    """``(n,)`` zeroed records of :data:`STEP_RECORD_DTYPE`, to fill in and :func:`pack_step_records`."""
    return np.zeros(int(n), dtype=STEP_RECORD_DTYPE)


def _as_records(records: np.ndarray) -> np.ndarray:
    r = np.asarray(records)
    if r.dtype.names != STEP_RECORD_DTYPE.names:
        raise ProtocolError(f"step records must be a structured array with the fields {STEP_RECORD_DTYPE.names}, "
                            f"got {r.dtype}")
    return np.ascontiguousarray(r.reshape(-1).astype(STEP_RECORD_DTYPE, copy=False))


def pack_step_records(records: np.ndarray) -> bytes:
    """Bytes of consecutive records, with their CRCs filled in (vectorised).

    Parameters
    ----------
    records
        ``(n,)`` structured array of :data:`STEP_RECORD_DTYPE` (other byte orders of the same fields are
        converted); its ``record_crc`` field is ignored.

    Returns
    -------
    bytes
        ``20·n`` bytes, the same as :data:`STEP_RECORD_STRUCT` builds record by record.

    Raises
    ------
    ProtocolError
        Not an array with the record's fields.
    """
    r = _as_records(records).copy()
    rows = r.view(np.uint8).reshape(-1, STEP_RECORD_SIZE)
    r["record_crc"] = crc16_xmodem_rows(rows[:, :_BODY_SIZE])
    return r.tobytes()


def unpack_step_records(data: bytes | bytearray | memoryview | np.ndarray, *, source: str | None = None,
                        base_offset: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Records and their CRC verdicts from ``20·n`` bytes (vectorised).

    Parameters
    ----------
    data
        Consecutive records (e.g. the step memory from address 0, or ``uint8`` array).
    source, base_offset
        Name and offset of ``data`` in its file or stream, for error messages.

    Returns
    -------
    records : numpy.ndarray
        ``(n,)`` array of :data:`STEP_RECORD_DTYPE` (a copy).
    crc_ok : numpy.ndarray
        ``(n,)`` bool: the stored ``record_crc`` matches bytes 0-17. A record with ``False`` must not be used.

    Raises
    ------
    ProtocolError
        A length that is not a multiple of 20 (the offset is that of the incomplete record).
    """
    raw = np.frombuffer(bytes(data) if not isinstance(data, np.ndarray) else data.astype(np.uint8).tobytes(),
                        dtype=np.uint8)
    if raw.size % STEP_RECORD_SIZE:
        whole = raw.size - raw.size % STEP_RECORD_SIZE
        raise ProtocolError(f"step records: {raw.size} bytes is not a multiple of {STEP_RECORD_SIZE} (the last "
                            f"record has {raw.size - whole} bytes)", offset=base_offset + whole, source=source)
    records = raw.view(STEP_RECORD_DTYPE).copy()
    rows = raw.reshape(-1, STEP_RECORD_SIZE)
    crc_ok = crc16_xmodem_rows(rows[:, :_BODY_SIZE]) == records["record_crc"]
    return records, crc_ok


def stored_step_records(header: Any, step_memory: np.ndarray | bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stored records of a step memory in ring order (oldest first, section 2.3's ring rules).

    Parameters
    ----------
    header
        The :class:`gaitlog.protocol.header.DeviceHeader` whose step counters describe the ring.
    step_memory
        ``(20 · step_capacity,)`` bytes of the step memory from its address 0.

    Returns
    -------
    records, crc_ok, slots
        As :func:`unpack_step_records`, and each record's slot in the ring (``header.step_slots()``).
    """
    slots = header.step_slots()
    rows = np.frombuffer(bytes(step_memory), np.uint8) if not isinstance(step_memory, np.ndarray) else \
        np.asarray(step_memory, np.uint8)
    records, crc_ok = unpack_step_records(rows.reshape(-1, STEP_RECORD_SIZE)[slots].reshape(-1))
    return records, crc_ok, slots


def build_step_record(**fields: int) -> bytes:
    """One record built by :data:`STEP_RECORD_STRUCT` (construct; the reference for the numpy path).

    Raises
    ------
    ProtocolError
        A missing field or a value that does not fit its field (named).

    Examples
    --------
    >>> build_step_record(end_sample=1000, duration_samples=55, toe_off_samples=0, heel_strike_samples=0,
    ...     flags=0, length_m1_q14=11469, length_m2_q14=0, length_m3_q14=0, length_m4_q14=0,
    ...     length_m5_q14=0).hex()[-4:]
    '0ed1'
    """
    try:
        return STEP_RECORD_STRUCT.build(dict(body=dict(value=fields)))
    except (cs.ConstructError, KeyError) as exc:
        raise ProtocolError(f"step record: cannot build {fields}: {str(exc).strip().splitlines()[-1]}") from None


def parse_step_record(data: bytes, *, source: str | None = None, base_offset: int = 0) -> dict[str, int]:
    """Fields of one 20-byte record, parsed by :data:`STEP_RECORD_STRUCT`; the CRC must match.

    Raises
    ------
    ProtocolError
        Wrong length, or ``record_crc`` mismatch (offset of the CRC field).
    """
    if len(data) != STEP_RECORD_SIZE:
        raise ProtocolError(f"step record: expected {STEP_RECORD_SIZE} bytes, found {len(data)}",
                            offset=base_offset, source=source)
    try:
        parsed = STEP_RECORD_STRUCT.parse(bytes(data))
    except cs.ChecksumError:
        stored = int.from_bytes(data[_BODY_SIZE:], "big")
        raise ProtocolError(f"record_crc: CRC mismatch: stored 0x{stored:04x}, computed "
                            f"0x{crc16_xmodem(data[:_BODY_SIZE]):04x} over bytes 0-17",
                            offset=base_offset + _BODY_SIZE, source=source) from None
    return {k: int(v) for k, v in parsed.body.value.items() if not k.startswith("_")}


def step_lengths_m(records: np.ndarray) -> np.ndarray:
    """``(n, 5)`` float step lengths M1 ... M5 in m (raw / 2^14); 0 means "not computed" (see the flags)."""
    r = np.asarray(records)
    return np.stack([r[f].astype(np.float64) for f in STEP_LENGTH_FIELDS], axis=-1) / (1 << STEP_LENGTH_FRACTION_BITS)


# ------------------------------------------------------------------------------------------- addressing
def memory_region(address: int, length: int, *, sample_memory_bytes: int, step_memory_bytes: int
                  ) -> tuple[Literal["samples", "steps"], int] | None:
    """The region a READ/DUMP range ``[address, address + length)`` lies in, and its offset there.

    The sample memory is ``[0, sample_memory_bytes)``; the step memory is ``[STEP_ADDRESS_BASE,
    STEP_ADDRESS_BASE + step_memory_bytes)``. A range must lie entirely inside one of them (else ``None``:
    the device answers NAK BAD_ADDRESS).

    Examples
    --------
    >>> memory_region(0x01000000 + 40, 20, sample_memory_bytes=262144, step_memory_bytes=65520)
    ('steps', 40)
    >>> memory_region(262140, 8, sample_memory_bytes=262144, step_memory_bytes=65520) is None
    True
    """
    a, n = int(address), int(length)
    if n < 0 or a < 0:
        return None
    if a + n <= sample_memory_bytes:
        return "samples", a
    if a >= STEP_ADDRESS_BASE and a + n <= STEP_ADDRESS_BASE + step_memory_bytes:
        return "steps", a - STEP_ADDRESS_BASE
    return None


# ----------------------------------------------------------------------------------------- configuration
# physical attribute of StepConfig -> its integer field; the field's name ends in _q<fraction bits>
_CONFIG_VALUES: tuple[tuple[str, str], ...] = (
    ("leg_length_m", "leg_length_q15"),
    ("foot_length_m", "foot_length_q15"),
    ("k_m1", "k_m1_q15"),
    ("k_m2", "k_m2_q15"),
    ("k_m4", "k_m4_q15"),
    ("k1_m5_m_s", "k1_m5_q16"),
    ("k2_m5_m", "k2_m5_q16"),
)
_CONFIG_SUBCONS = {name: sc for name, _, sc in named_fields(STEP_CONFIG_STRUCT)}
_STEP_CONFIG_FAST = CompiledOnReuse(STEP_CONFIG_STRUCT)


def _fraction_bits(fieldname: str) -> int:
    return int(fieldname.rsplit("_q", 1)[1])


def _m4_eighths(exponent: object) -> int:
    """M4's exponent as the stored eighths (0: not given), or :class:`ProtocolError` naming the field."""
    try:
        e = float(exponent) * 8.0  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise _config_error(f"m4_exponent must be a number, got {exponent!r}", "m4_exponent_eighths") from None
    if not (math.isfinite(e) and abs(e - round(e)) < 1e-9 and 0 <= round(e) <= M4_EXPONENT_EIGHTHS_MAX):
        raise _config_error(f"m4_exponent must be 0 (not given) or a whole number of eighths up to "
                            f"{M4_EXPONENT_EIGHTHS_MAX}/8, got {exponent!r}", "m4_exponent_eighths")
    return int(round(e))


def _config_error(what: str, fieldname: str, source: str | None = None, base: int = 0) -> ProtocolError:
    return ProtocolError(f"{fieldname}: {what}", offset=base + STEP_CONFIG_OFFSETS[fieldname][0], source=source)


@dataclass(frozen=True)
class StepConfig:
    """The step configuration block (section 2.2) in physical units.

    Parameters
    ----------
    step_format
        0 (:attr:`StepFormat.OFF`): on-line step algorithm off; 1-4: on (:data:`ALGORITHM_VERSIONS`; the
        device runs :data:`ONLINE_ALGORITHM_VERSION` and stores it, whichever of them it was sent).
    calibrated
        The K constants are valid (``step_flags`` bit ``CALIBRATED``).
    leg_length_m, foot_length_m
        Leg length and foot length (heel to first metatarsal head, M3's S2), m; unsigned Q1.15 (0 ... 2 m).
    k_m1, k_m2
        K of M1 and M2 (dimensionless), unsigned Q1.15 (0 ... 2).
    k_m4
        K of M4, m/(m/s²)^p (p: ``m4_exponent``), unsigned Q1.15 (0 ... 2).
    k1_m5_m_s, k2_m5_m
        M5's ``S = K1/T + K2``: K1 in m·s and K2 in m, signed Q15.16 (±32768).
    m4_exponent
        M4's exponent p (``S = K range^p``), whole eighths from 1/8 to 1/2, stored in eighths (byte 20,
        ``m4_exponent_eighths``); 0: not given (SET_STEP_CONFIG: the firmware's default; a block of versions 1-3,
        whose byte 20 was reserved: p is the version's, 1/2 for versions 2 and 3).

    Notes
    -----
    Each value is stored as ``floor(x · 2^n + 0.5)`` (round half up); :meth:`quantised` gives the values
    exactly as stored and :attr:`raw` the stored integers, which are what the firmware uses.

    Examples
    --------
    >>> cfg = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1,
    ...                  k_m2=1.05, k_m4=0.5, k1_m5_m_s=0.3, k2_m5_m=0.25)
    >>> cfg.to_bytes()[:12].hex(" ")
    '01 01 33 73 9a 19 cd 8c 66 86 00 40'
    >>> cfg.raw["leg_length_q15"], round(cfg.quantised().leg_length_m, 6)
    (29491, 0.899994)
    >>> StepConfig(step_format=1).to_bytes()
    Traceback (most recent call last):
    ...
    gaitlog.protocol.errors.ProtocolError: offset 2 (0x2): leg_length_q15: step_format 1 needs a leg length > 0 (found 0.0 m)
    """

    step_format: int = StepFormat.OFF
    calibrated: bool = False
    leg_length_m: float = 0.0
    foot_length_m: float = 0.0
    k_m1: float = 0.0
    k_m2: float = 0.0
    k_m4: float = 0.0
    k1_m5_m_s: float = 0.0
    k2_m5_m: float = 0.0
    m4_exponent: float = 0.0

    @classmethod
    def off(cls) -> "StepConfig":
        """The all-zero block: the on-line step algorithm off (the default of a device header)."""
        return cls()

    @property
    def enabled(self) -> bool:
        """The on-line step algorithm is on (``step_format`` ≠ 0)."""
        return int(self.step_format) != StepFormat.OFF

    @property
    def older_algorithm(self) -> str | None:
        """What wrote the step records when an older on-line algorithm version than
        :data:`ONLINE_ALGORITHM_VERSION` did (its :data:`ALGORITHM_VERSIONS` line); None when the algorithm
        is off or the records are this version's."""
        if not self.enabled or int(self.step_format) == ONLINE_ALGORITHM_VERSION:
            return None
        return ALGORITHM_VERSIONS[StepFormat(int(self.step_format))]

    @property
    def raw(self) -> dict[str, int]:
        """The stored integers by field name (``step_format``, ``step_flags``, ``leg_length_q15``, ...).

        Raises
        ------
        ProtocolError
            As :meth:`to_bytes`.
        """
        try:
            fmt = StepFormat(int(self.step_format))
        except (ValueError, TypeError):
            raise _config_error(f"unknown step format {self.step_format!r} (known: 0 off, 1-4 on-line "
                                f"algorithm versions)",
                                "step_format") from None
        out = {"step_format": int(fmt), "step_flags": int(StepConfigFlag.CALIBRATED) if self.calibrated else 0}
        for attr, fieldname in _CONFIG_VALUES:
            value = getattr(self, attr)
            try:
                x = float(value)
            except (TypeError, ValueError):
                raise _config_error(f"{attr} must be a number, got {value!r}", fieldname) from None
            if not math.isfinite(x):
                raise _config_error(f"non-finite {attr} {x}", fieldname)
            q = math.floor(x * (1 << _fraction_bits(fieldname)) + 0.5)
            lo, hi = _int_range(_CONFIG_SUBCONS[fieldname])
            if not lo <= q <= hi:
                scale = 1 << _fraction_bits(fieldname)
                raise _config_error(f"{attr} {x} outside the stored range {lo / scale:g} ... {hi / scale:.6g}",
                                    fieldname)
            out[fieldname] = q
        if fmt != StepFormat.OFF and out["leg_length_q15"] == 0:
            raise _config_error(f"step_format {int(fmt)} needs a leg length > 0 (found {self.leg_length_m} m)",
                                "leg_length_q15")
        out["m4_exponent_eighths"] = _m4_eighths(self.m4_exponent)
        return out

    def to_bytes(self) -> bytes:
        """The 32-byte block (reserved bytes 0; byte 20 M4's exponent in eighths, 0 when not given).

        Raises
        ------
        ProtocolError
            Unknown ``step_format``, a non-finite or out-of-range value, or an on-line format with a leg
            length that is 0 once stored; the error names the field and its offset in the block.
        """
        return _STEP_CONFIG_FAST.build(self.raw)

    @classmethod
    def from_bytes(cls, data: bytes | bytearray | memoryview, *, source: str | None = None,
                   base_offset: int = 0) -> "StepConfig":
        """Parse a 32-byte block (reserved bytes 21-31 are ignored, and byte 20 below version 4, where it was
        reserved).

        Raises
        ------
        ProtocolError
            Wrong length, ``step_format`` > 4, reserved ``step_flags`` bits set, an on-line format with a
            leg length of 0, or M4's exponent above 1/2; offsets are ``base_offset`` plus the field's offset in
            the block.
        """
        if len(data) != STEP_CONFIG_SIZE:
            raise ProtocolError(f"step configuration block: expected {STEP_CONFIG_SIZE} bytes, found {len(data)}",
                                offset=base_offset, source=source)
        c = _STEP_CONFIG_FAST.parse(bytes(data))
        if c.step_format not in {int(f) for f in StepFormat}:
            raise _config_error(f"unknown step format {c.step_format} (known: 0 off, 1-4 on-line algorithm "
                                "versions)",
                                "step_format", source, base_offset)
        eighths = c.m4_exponent_eighths if c.step_format >= StepFormat.V4 else 0   # versions 1-3: reserved
        if eighths > M4_EXPONENT_EIGHTHS_MAX:
            raise _config_error(f"M4's exponent {eighths}/8 above {M4_EXPONENT_EIGHTHS_MAX}/8",
                                "m4_exponent_eighths", source, base_offset)
        if c.step_flags & ~int(StepConfigFlag.CALIBRATED):
            raise _config_error(f"reserved bits set in 0x{c.step_flags:02x} (only 0x01 CALIBRATED is defined)",
                                "step_flags", source, base_offset)
        if c.step_format != StepFormat.OFF and c.leg_length_q15 == 0:
            raise _config_error(f"step_format {c.step_format} needs a leg length > 0 (found 0)",
                                "leg_length_q15", source,
                                base_offset)
        values = {attr: c[name] / (1 << _fraction_bits(name)) for attr, name in _CONFIG_VALUES}
        return cls(step_format=StepFormat(c.step_format),
                   calibrated=bool(c.step_flags & StepConfigFlag.CALIBRATED), m4_exponent=eighths / 8, **values)

    def quantised(self) -> "StepConfig":
        """The configuration exactly as it is stored."""
        return StepConfig.from_bytes(self.to_bytes())
