"""Frames of the UART protocol (``PROTOCOL.md`` section 3): layout, payloads, incremental parser.

A frame is ``A5 5A | type | seq | length (u16 LE) | payload | CRC-16/XMODEM (BE)`` with the CRC over
type ... payload. :data:`FRAME_STRUCT` and :data:`PAYLOAD_STRUCTS` are the construct declarations;
:class:`FrameParser` hunts, checks and resynchronises on a byte stream without ever allocating by a
length field.

Examples
--------
>>> encode_frame(FrameType.IDENTIFY, 7).hex(" ")
'a5 5a 01 07 00 00 f3 24'
>>> frames, errors = parse_stream(b"junk" + encode_frame(FrameType.ACK, 7, bytes([0x01])))
>>> frames[0], errors
(Frame(type=144, seq=7, payload=b'\\x01', offset=4), [FrameError(offset=0, reason='garbage', length=4, detail='')])
>>> parse_payload(frames[0])
{'command': <FrameType.IDENTIFY: 1>}
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

import construct as cs

from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.data_blocks import ADDRESS_BYTES, BLOCK_BYTES, CHECK_BYTES, MAX_BLOCKS_DATA, payload_data_bytes
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import CALIBRATION_SIZE, HEADER_SIZE, CalibrationSlot, DeviceHeader
from gaitlog.protocol.layout import named_fields
from gaitlog.protocol.steps import STEP_CONFIG_SIZE, StepConfig

__all__ = [
    "SYNC",
    "FRAME_OVERHEAD",
    "MAX_PAYLOAD",
    "MAX_DATA",
    "MAX_BLOCKS_DATA",
    "WIRE_PROTOCOL_VERSION",
    "KNOWN_WIRE_PROTOCOL_VERSIONS",
    "ERASE_GUARD",
    "FrameType",
    "COMMAND_TYPES",
    "ErrorCode",
    "DeviceState",
    "StartMode",
    "StrictEnum",
    "FRAME_STRUCT",
    "FRAME_HEAD_STRUCT",
    "PAYLOAD_STRUCTS",
    "Frame",
    "FrameError",
    "PayloadError",
    "encode_frame",
    "build_payload",
    "parse_payload",
    "FrameParser",
    "parse_stream",
]

SYNC = b"\xa5\x5a"
#: sync (2) + type (1) + seq (1) + length (2) + crc (2)
FRAME_OVERHEAD = 8
#: Largest READ length / DUMP chunk.
MAX_DATA = 4096
#: Largest legal ``length`` field: a DATA_BLOCKS frame of :data:`MAX_BLOCKS_DATA` bytes (address, 64 blocks and
#: their checks: 16,516; protocol version 1: 4100, a DATA frame of 4096 bytes).
MAX_PAYLOAD = ADDRESS_BYTES + MAX_BLOCKS_DATA + CHECK_BYTES * (MAX_BLOCKS_DATA // BLOCK_BYTES)
#: The protocol version this package speaks (INFO ``protocol_version``; section 7), and those it still reads.
WIRE_PROTOCOL_VERSION = 2
KNOWN_WIRE_PROTOCOL_VERSIONS = (1, 2)
ERASE_GUARD = b"ERASE"


class FrameType(enum.IntEnum):
    """Frame ``type`` codes (section 3.1). Commands are 0x01-0x0E, responses 0x81-0x91."""

    IDENTIFY = 0x01
    GET_STATUS = 0x02
    START = 0x03
    STOP = 0x04
    ERASE = 0x05
    READ_HEADER = 0x06
    READ = 0x07
    DUMP = 0x08
    XDUMP = 0x09
    SET_CALIBRATION = 0x0A
    SET_STEP_CONFIG = 0x0B
    ABORT = 0x0C
    DUMP_CHECKED = 0x0D
    DUMP_BLOCKS = 0x0E
    INFO = 0x81
    STATUS = 0x82
    HEADER = 0x86
    DATA = 0x87
    DUMP_END = 0x88
    DATA_CRC = 0x89
    DATA_BLOCKS = 0x8A
    ACK = 0x90
    NAK = 0x91


#: The command codes (host -> device); an ACK acknowledges one of these.
COMMAND_TYPES = frozenset(int(t) for t in FrameType if t < 0x80)


class ErrorCode(enum.IntEnum):
    """NAK error codes (section 3.2)."""

    BAD_CRC = 0x01
    UNKNOWN_COMMAND = 0x02
    BAD_LENGTH = 0x03
    BAD_ADDRESS = 0x04
    BUSY = 0x05
    BAD_ARGUMENT = 0x06
    MEMORY_FULL = 0x07


class DeviceState(enum.IntEnum):
    """``state`` byte of a STATUS response."""

    IDLE = 0
    LOGGING = 1
    FULL_STOPPED = 2


class StartMode(enum.IntEnum):
    """``mode`` byte of START."""

    STOP_WHEN_FULL = 0
    OVERWRITE = 1


class StrictEnum(cs.Adapter):
    """Like ``cs.Enum`` but an unknown code is an error (``cs.MappingError``), never a plain int.

    >>> StrictEnum(cs.Int8ul, ErrorCode).parse(b"\\x05")
    <ErrorCode.BUSY: 5>
    >>> StrictEnum(cs.Int8ul, ErrorCode).parse(b"\\x09")
    Traceback (most recent call last):
    ...
    construct.core.MappingError: Error in path (parsing)
    unknown ErrorCode code 9
    """

    def __init__(self, subcon: cs.Construct, enum_cls: type[enum.IntEnum],
                 allowed: frozenset[int] | None = None) -> None:
        super().__init__(subcon)
        self.enum_cls = enum_cls
        self.allowed = frozenset(int(m) for m in enum_cls) if allowed is None else frozenset(allowed)

    def _decode(self, obj: int, context: Any, path: str) -> enum.IntEnum:
        if obj not in self.allowed:
            raise cs.MappingError(f"unknown {self.enum_cls.__name__} code {obj}", path=path)
        return self.enum_cls(obj)

    def _encode(self, obj: Any, context: Any, path: str) -> int:
        try:
            value = int(self.enum_cls[obj] if isinstance(obj, str) else self.enum_cls(obj))
        except (ValueError, KeyError):
            value = None
        if value is None or value not in self.allowed:
            raise cs.MappingError(f"unknown {self.enum_cls.__name__} code {obj!r}", path=path)
        return value


#: type, seq, length, payload: the part the CRC covers.
FRAME_BODY_STRUCT = cs.Struct(
    "type" / cs.Int8ul,
    "seq" / cs.Int8ul,
    "length" / cs.Rebuild(cs.Int16ul, cs.len_(cs.this.payload)),
    "payload" / cs.Bytes(cs.this.length),
)

#: The whole frame (section 3).
FRAME_STRUCT = cs.Struct(
    "sync" / cs.Const(SYNC),
    "body" / cs.RawCopy(FRAME_BODY_STRUCT),
    "crc" / cs.Checksum(cs.Int16ub, lambda data: crc16_xmodem(data), cs.this.body.data),
)

#: The fixed 6-byte head of a frame (compiled: it is on the hot path of every DUMP).
FRAME_HEAD_STRUCT = cs.Struct(
    "sync" / cs.Const(SYNC), "type" / cs.Int8ul, "seq" / cs.Int8ul, "length" / cs.Int16ul
).compile()

_EMPTY = cs.Struct()

#: Payload layout of each frame type (section 3.1); all integers little-endian.
PAYLOAD_STRUCTS: dict[FrameType, cs.Struct] = {
    FrameType.IDENTIFY: _EMPTY,
    FrameType.GET_STATUS: _EMPTY,
    FrameType.START: cs.Struct("start_time_s" / cs.Int32ul, "mode" / StrictEnum(cs.Int8ul, StartMode)),
    FrameType.STOP: _EMPTY,
    FrameType.ERASE: cs.Struct("guard" / cs.Const(ERASE_GUARD)),
    FrameType.READ_HEADER: _EMPTY,
    FrameType.READ: cs.Struct("address" / cs.Int32ul, "length" / cs.Int16ul),
    FrameType.DUMP: cs.Struct("address" / cs.Int32ul, "length" / cs.Int32ul, "chunk" / cs.Int16ul),
    FrameType.DUMP_CHECKED: cs.Struct("address" / cs.Int32ul, "length" / cs.Int32ul, "chunk" / cs.Int16ul),
    FrameType.DUMP_BLOCKS: cs.Struct("address" / cs.Int32ul, "length" / cs.Int32ul, "chunk" / cs.Int16ul),
    FrameType.ABORT: _EMPTY,
    FrameType.XDUMP: _EMPTY,
    FrameType.SET_CALIBRATION: cs.Struct("calibration" / cs.Bytes(CALIBRATION_SIZE)),
    FrameType.SET_STEP_CONFIG: cs.Struct("step_config" / cs.Bytes(STEP_CONFIG_SIZE)),
    FrameType.INFO: cs.Struct(
        "device_id" / cs.Int32ul,
        "firmware_version" / cs.Int16ul,
        "protocol_version" / cs.Int8ul,
        "adc_bits" / cs.Int8ul,
        "sampling_rate_millihz" / cs.Int32ul,
        "capacity_samples" / cs.Int32ul,
        "packing" / cs.Int8ul,
        "memory_bytes" / cs.Int32ul,
    ),
    FrameType.STATUS: cs.Struct(
        "state" / StrictEnum(cs.Int8ul, DeviceState),
        "flags" / cs.Int8ul,
        "samples_written" / cs.Int32ul,
        "write_index" / cs.Int32ul,
    ),
    FrameType.HEADER: cs.Struct("header" / cs.Bytes(HEADER_SIZE)),
    FrameType.DATA: cs.Struct("address" / cs.Int32ul, "data" / cs.GreedyBytes),
    FrameType.DUMP_END: cs.Struct("address" / cs.Int32ul, "length" / cs.Int32ul, "frames" / cs.Int16ul),
    FrameType.DATA_CRC: cs.Struct("address" / cs.Int32ul, "crc32" / cs.Int32ul),
    FrameType.DATA_BLOCKS: cs.Struct("address" / cs.Int32ul, "blocks" / cs.GreedyBytes),
    FrameType.ACK: cs.Struct("command" / StrictEnum(cs.Int8ul, FrameType, COMMAND_TYPES)),
    FrameType.NAK: cs.Struct("command" / cs.Int8ul, "error" / StrictEnum(cs.Int8ul, ErrorCode)),
}

#: The settings commands' payloads as objects: type -> (field, class with ``to_bytes``/``from_bytes``);
#: a payload the class refuses is answered with NAK BAD_ARGUMENT.
SET_PAYLOADS: dict[FrameType, tuple[str, type]] = {
    FrameType.SET_CALIBRATION: ("calibration", CalibrationSlot),
    FrameType.SET_STEP_CONFIG: ("step_config", StepConfig),
}

#: Inclusive limits on payload fields beyond their integer width: (type, field) -> (min, max).
FIELD_LIMITS: dict[tuple[FrameType, str], tuple[int, int]] = {
    (FrameType.READ, "length"): (1, MAX_DATA),
    (FrameType.DUMP, "chunk"): (1, MAX_DATA),
    (FrameType.DUMP_CHECKED, "chunk"): (1, MAX_DATA),
    (FrameType.DUMP_BLOCKS, "chunk"): (1, MAX_BLOCKS_DATA),
}


#: (type, field) -> byte offset of the field in the payload.
PAYLOAD_OFFSETS: dict[FrameType, dict[str, int]] = {t: {name: off for name, off, _ in named_fields(s)}
                                                  for t, s in PAYLOAD_STRUCTS.items()}


@dataclass(frozen=True)
class Frame:
    """One checked frame: ``type`` and ``seq`` codes, payload bytes, offset of its sync in the stream."""

    type: int
    seq: int
    payload: bytes
    offset: int = 0

    @property
    def frame_type(self) -> FrameType | None:
        """``type`` as :class:`FrameType`, ``None`` for an unknown code."""
        try:
            return FrameType(self.type)
        except ValueError:
            return None

    def to_bytes(self) -> bytes:
        """The frame's wire bytes."""
        return encode_frame(self.type, self.seq, self.payload)


@dataclass(frozen=True)
class FrameError:
    """Bytes of a stream that gave no frame.

    Attributes
    ----------
    offset
        Stream offset of the first byte concerned.
    reason
        ``"garbage"`` (bytes outside any frame), ``"bad_length"`` (length field above
        :data:`MAX_PAYLOAD`; nothing allocated), ``"bad_crc"`` (CRC mismatch) or ``"truncated"`` (the stream
        ended, or the inter-byte timeout expired, inside a frame).
    length
        Number of stream bytes concerned (for ``bad_crc`` and ``truncated``: of the candidate frame).
    detail
        Human-readable specifics (the length field, the CRC values).
    """

    offset: int
    reason: str
    length: int
    detail: str = ""

    def __str__(self) -> str:
        extra = f" ({self.detail})" if self.detail else ""
        return f"offset {self.offset} (0x{self.offset:x}): {self.reason}, {self.length} bytes{extra}"


class PayloadError(ProtocolError):
    """A payload that does not fit its frame type; ``error_code`` is the NAK a device answers with."""

    def __init__(self, message: str, *, error_code: ErrorCode, offset: int | None = None,
                 source: str | None = None) -> None:
        self.error_code = ErrorCode(error_code)
        super().__init__(message, offset=offset, source=source)

    def at(self, *, source: str | None = None, offset: int | None = None) -> "PayloadError":
        new = super().at(source=source, offset=offset)
        return PayloadError(new.message, error_code=self.error_code, offset=new.offset, source=new.source)


def encode_frame(type: int, seq: int, payload: bytes = b"") -> bytes:  # noqa: A002 - name of the spec field
    """Wire bytes of one frame.

    Parameters
    ----------
    type
        Frame type code 0-255 (normally a :class:`FrameType`).
    seq
        Sequence number 0-255.
    payload
        At most :data:`MAX_PAYLOAD` bytes.

    Raises
    ------
    ProtocolError
        A code outside 0-255 or a payload above :data:`MAX_PAYLOAD` bytes.

    Examples
    --------
    >>> encode_frame(FrameType.NAK, 3, bytes([0x07, ErrorCode.BUSY])).hex(" ")
    'a5 5a 91 03 02 00 07 05 41 8c'
    """
    if not 0 <= int(type) <= 255:
        raise ProtocolError(f"frame type {type} outside 0..255")
    if not 0 <= int(seq) <= 255:
        raise ProtocolError(f"frame seq {seq} outside 0..255")
    if len(payload) > MAX_PAYLOAD:
        raise ProtocolError(f"frame payload of {len(payload)} bytes exceeds the maximum {MAX_PAYLOAD}")
    # same bytes as FRAME_STRUCT.build(...) (checked by the tests) at a tenth of the cost
    head = FRAME_HEAD_STRUCT.build(dict(type=int(type), seq=int(seq), length=len(payload)))
    crc = crc16_xmodem(payload, crc16_xmodem(head[2:]))
    return b"".join((head, payload, crc.to_bytes(2, "big")))


def _frame_type(t: int, offset: int | None, source: str | None) -> FrameType:
    try:
        return FrameType(t)
    except ValueError:
        raise PayloadError(f"unknown frame type 0x{int(t):02x}", error_code=ErrorCode.UNKNOWN_COMMAND,
                           offset=offset, source=source) from None


def build_payload(type: FrameType | int, **fields: Any) -> bytes:  # noqa: A002
    """Payload bytes of a frame type from its fields (names as in section 3.1).

    ``HEADER`` takes ``header`` (a :class:`DeviceHeader` or 256 bytes), ``SET_CALIBRATION`` takes
    ``calibration`` (a :class:`CalibrationSlot` or 64 bytes), ``SET_STEP_CONFIG`` takes ``step_config`` (a
    :class:`~gaitlog.protocol.steps.StepConfig` or 32 bytes), ``ERASE`` needs no field.

    Raises
    ------
    PayloadError
        Unknown type, missing or unexpected field, value out of range.

    Examples
    --------
    >>> build_payload(FrameType.READ, address=0x100, length=2048).hex(" ")
    '00 01 00 00 00 08'
    >>> build_payload(FrameType.READ, address=0x100, length=5000)
    Traceback (most recent call last):
    ...
    gaitlog.protocol.frames.PayloadError: offset 4 (0x4): READ length 5000 outside 1..4096
    """
    ftype = _frame_type(type, None, None)
    struct = PAYLOAD_STRUCTS[ftype]
    values = dict(fields)
    if ftype == FrameType.HEADER and isinstance(values.get("header"), DeviceHeader):
        values["header"] = values["header"].to_bytes()
    if ftype in SET_PAYLOADS:
        name, cls = SET_PAYLOADS[ftype]
        if isinstance(values.get(name), cls):
            try:
                values[name] = values[name].to_bytes()
            except ProtocolError as exc:
                raise PayloadError(exc.message, error_code=ErrorCode.BAD_ARGUMENT, offset=exc.offset) from None
    names = [sc.name for sc in struct.subcons if sc.name is not None and not isinstance(sc, cs.Const)]
    if ftype == FrameType.ERASE:
        names = []
        values.pop("guard", None)
    unexpected = set(values) - set(names)
    missing = [n for n in names if n not in values]
    if unexpected or missing:
        raise PayloadError(f"{ftype.name} payload fields are {names}; missing {missing}, unexpected "
                           f"{sorted(unexpected)}", error_code=ErrorCode.BAD_ARGUMENT)
    _check_limits(ftype, values, 0, None)
    if ftype == FrameType.DATA and len(values["data"]) > MAX_DATA:
        raise PayloadError(f"DATA of {len(values['data'])} bytes exceeds {MAX_DATA}",
                           error_code=ErrorCode.BAD_LENGTH, offset=4)
    if ftype == FrameType.DATA_BLOCKS and (payload_data_bytes(4 + len(values["blocks"])) or 0) > MAX_BLOCKS_DATA:
        raise PayloadError(f"DATA_BLOCKS of {len(values['blocks'])} bytes exceeds 64 blocks",
                           error_code=ErrorCode.BAD_LENGTH, offset=4)
    try:
        return struct.build(values)
    except cs.ConstructError as exc:
        raise PayloadError(f"{ftype.name} payload: {_construct_message(exc)}",
                           error_code=ErrorCode.BAD_ARGUMENT) from None


def _construct_message(exc: cs.ConstructError) -> str:
    text = str(exc).strip().splitlines()
    return text[-1] if text else type(exc).__name__


def _check_limits(ftype: FrameType, values: dict, base: int, source: str | None) -> None:
    for (t, name), (lo, hi) in FIELD_LIMITS.items():
        if t == ftype and not lo <= int(values[name]) <= hi:
            raise PayloadError(f"{ftype.name} {name} {values[name]} outside {lo}..{hi}",
                               error_code=ErrorCode.BAD_ARGUMENT,
                               offset=base + PAYLOAD_OFFSETS[ftype][name], source=source)


def parse_payload(frame: Frame, source: str | None = None) -> dict[str, Any]:
    """Fields of a frame's payload as a plain dict (enums as :class:`enum.IntEnum` members).

    ``HEADER`` gives ``{"header": DeviceHeader}`` (validated), ``SET_CALIBRATION`` gives
    ``{"calibration": CalibrationSlot}``, ``SET_STEP_CONFIG`` gives ``{"step_config": StepConfig}`` (an
    unknown format, reserved flag bits or format 1 with leg length 0 are ``BAD_ARGUMENT``), ``DATA`` gives
    ``{"address": int, "data": bytes}``.

    Raises
    ------
    PayloadError
        Unknown type (``UNKNOWN_COMMAND``), wrong length (``BAD_LENGTH``), a value out of range or an
        unknown enum code (``BAD_ARGUMENT``); offsets are stream offsets of the offending byte.
    ProtocolError
        An invalid device header inside a HEADER frame.

    Examples
    --------
    >>> parse_payload(Frame(FrameType.STATUS, 1, bytes.fromhex("01 05 10000000 10000000")))
    {'state': <DeviceState.LOGGING: 1>, 'flags': 5, 'samples_written': 16, 'write_index': 16}
    >>> parse_payload(Frame(FrameType.NAK, 1, bytes([0x03, 0x09]), offset=100))
    Traceback (most recent call last):
    ...
    gaitlog.protocol.frames.PayloadError: offset 107 (0x6b): NAK payload: unknown ErrorCode code 9
    """
    base = frame.offset + 6
    ftype = _frame_type(frame.type, frame.offset + 2, source)
    struct = PAYLOAD_STRUCTS[ftype]
    payload = frame.payload
    if ftype == FrameType.DATA:
        if not 4 <= len(payload) <= MAX_PAYLOAD:
            raise PayloadError(f"DATA payload of {len(payload)} bytes (expected 4..{MAX_PAYLOAD})",
                               error_code=ErrorCode.BAD_LENGTH, offset=frame.offset + 4, source=source)
        return {"address": int.from_bytes(payload[:4], "little"), "data": bytes(payload[4:])}
    if ftype == FrameType.DATA_BLOCKS:
        if payload_data_bytes(len(payload)) is None:
            raise PayloadError(f"DATA_BLOCKS payload of {len(payload)} bytes (4 + 258·k, or that + 3 … 257, expected)",
                               error_code=ErrorCode.BAD_LENGTH, offset=frame.offset + 4, source=source)
        return {"address": int.from_bytes(payload[:4], "little"), "blocks": bytes(payload[4:])}
    size = struct.sizeof()
    if len(payload) != size:
        raise PayloadError(f"{ftype.name} payload of {len(payload)} bytes (expected {size})",
                           error_code=ErrorCode.BAD_LENGTH, offset=frame.offset + 4, source=source)
    try:
        parsed = struct.parse(payload)
    except cs.ConstructError as exc:
        bad = _bad_field(ftype, payload)
        raise PayloadError(f"{ftype.name} payload: {_construct_message(exc)}", error_code=ErrorCode.BAD_ARGUMENT,
                           offset=base + bad, source=source) from None
    values = {k: v for k, v in parsed.items() if not k.startswith("_") and k != "guard"}
    _check_limits(ftype, values, base, source)
    if ftype == FrameType.HEADER:
        try:
            values["header"] = DeviceHeader.from_bytes(values["header"], source=source)
        except ProtocolError as exc:
            raise exc.at(offset=base, source=source) from None
    if ftype in SET_PAYLOADS:
        name, cls = SET_PAYLOADS[ftype]
        try:
            values[name] = cls.from_bytes(values[name], source=source)
        except ProtocolError as exc:
            raise PayloadError(exc.message, error_code=ErrorCode.BAD_ARGUMENT, offset=base + (exc.offset or 0),
                               source=source) from None
    return values


def _bad_field(ftype: FrameType, payload: bytes) -> int:
    """Offset of the first field of ``payload`` that does not parse (for error messages)."""
    for sc in PAYLOAD_STRUCTS[ftype].subcons:
        off = PAYLOAD_OFFSETS[ftype].get(sc.name or "", None)
        if off is None:
            continue
        try:
            sc.parse(payload[off:])
        except cs.ConstructError:
            return off
    return 0


class FrameParser:
    """Incremental, sans-I/O frame receiver that resynchronises after any damage.

    Feed it bytes as they arrive; it returns checked :class:`Frame` objects and :class:`FrameError` reports
    in stream order. It hunts for ``A5 5A``; a length above :data:`MAX_PAYLOAD` is a framing error (nothing
    is allocated, the sync pair is skipped and the hunt goes on); a CRC mismatch skips the sync pair too, so a
    frame hidden behind a corrupted length field is still found. Every stream byte that ends up in no frame
    is covered by exactly one reported error (garbage runs are merged).

    Call :meth:`flush` at the end of the stream or when the inter-byte timeout expires: a partial frame is
    reported ``truncated`` and the bytes after its sync are searched again.

    Examples
    --------
    >>> p = FrameParser()
    >>> wire = encode_frame(FrameType.GET_STATUS, 9)
    >>> p.feed(wire[:5]), p.buffered
    ([], 5)
    >>> p.feed(wire[5:] + wire[:4])
    [Frame(type=2, seq=9, payload=b'', offset=0)]
    >>> p.flush()
    [FrameError(offset=8, reason='truncated', length=4, detail='stream ended inside a frame')]
    """

    def __init__(self, *, max_payload: int = MAX_PAYLOAD) -> None:
        self.max_payload = int(max_payload)
        self._buf = bytearray()
        self._pos = 0  # first unprocessed byte in _buf
        self._base = 0  # stream offset of _buf[0]
        self._garbage: list[int] | None = None  # pending garbage run [start, end) in stream offsets
        self._quiet_until = 0  # stream bytes below this are already covered by a reported error

    @property
    def buffered(self) -> int:
        """Bytes received but not yet turned into a frame or an error."""
        return len(self._buf) - self._pos

    @property
    def stream_offset(self) -> int:
        """Total bytes fed so far."""
        return self._base + len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame | FrameError]:
        """Add received bytes; return the frames and errors they complete, in stream order."""
        self._buf += data
        return self._scan(final=False)

    def flush(self) -> list[Frame | FrameError]:
        """End of stream (or inter-byte timeout): report what is left; the parser is then empty."""
        out = self._scan(final=True)
        self._emit_garbage(out)
        self._base += len(self._buf)
        self._buf = bytearray()
        self._pos = 0
        return out

    # -- internals -------------------------------------------------------------------------------
    def _skip(self, a: int, b: int, out: list) -> None:
        start, end = max(self._base + a, self._quiet_until), self._base + b
        if end <= start:
            return
        if self._garbage is not None and self._garbage[1] == start:
            self._garbage[1] = end
        else:
            self._emit_garbage(out)
            self._garbage = [start, end]

    def _emit_garbage(self, out: list) -> None:
        if self._garbage is not None:
            g0, g1 = self._garbage
            out.append(FrameError(g0, "garbage", g1 - g0))
            self._garbage = None

    def _error(self, out: list, i: int, reason: str, length: int, detail: str) -> None:
        self._emit_garbage(out)
        start = self._base + i
        out.append(FrameError(start, reason, length, detail))
        self._quiet_until = max(self._quiet_until, start + length)

    def _scan(self, final: bool) -> list[Frame | FrameError]:
        out: list[Frame | FrameError] = []
        buf = self._buf
        n = len(buf)
        pos = self._pos
        view = memoryview(buf)
        try:
            while pos < n:
                i = buf.find(SYNC, pos)
                if i < 0:
                    keep = 1 if (not final and buf[n - 1] == SYNC[0]) else 0
                    self._skip(pos, n - keep, out)
                    pos = n - keep
                    break
                self._skip(pos, i, out)
                pos = i
                if n - i < 6:
                    if not final:
                        break
                    self._error(out, i, "truncated", n - i, "stream ended inside a frame")
                    pos = i + 2
                    continue
                length = buf[i + 4] | (buf[i + 5] << 8)
                if length > self.max_payload:
                    self._error(out, i, "bad_length", 6, f"length field {length} > {self.max_payload}")
                    pos = i + 2
                    continue
                end = i + FRAME_OVERHEAD + length
                if end > n:
                    if not final:
                        break
                    self._error(out, i, "truncated", n - i, f"stream ended inside a frame of length {length}")
                    pos = i + 2
                    continue
                stored = (buf[end - 2] << 8) | buf[end - 1]
                computed = crc16_xmodem(view[i + 2 : end - 2])
                if stored != computed:
                    self._error(out, i, "bad_crc", end - i, f"stored 0x{stored:04x}, computed 0x{computed:04x}")
                    pos = i + 2
                    continue
                self._emit_garbage(out)
                out.append(Frame(buf[i + 2], buf[i + 3], bytes(view[i + 6 : end - 2]), self._base + i))
                self._quiet_until = max(self._quiet_until, self._base + end)
                pos = end
        finally:
            view.release()
        if pos > 65536 or pos == n:
            del buf[:pos]
            self._base += pos
            pos = 0
        self._pos = pos
        return out


def parse_stream(data: bytes | bytearray | memoryview, source: str | None = None
                 ) -> tuple[list[Frame], list[FrameError]]:
    """All frames of a complete byte stream and the errors between them.

    ``source`` is accepted for symmetry with the other decoders (errors are returned, not raised).

    >>> f, e = parse_stream(encode_frame(1, 0)[:-1] + encode_frame(2, 1))
    >>> [x.type for x in f], [(x.offset, x.reason, x.length) for x in e]
    ([2], [(0, 'bad_crc', 8)])
    """
    parser = FrameParser()
    items = parser.feed(data) + parser.flush()
    frames = [x for x in items if isinstance(x, Frame)]
    errors = [x for x in items if isinstance(x, FrameError)]
    return frames, errors
