"""The host end of the serial line: every command of ``PROTOCOL.md`` over pyserial, with timeouts and retries.

:class:`LoggerLink` works on anything pyserial opens: a real port (``/dev/ttyUSB0``, ``COM3``), a pty path
printed by ``gaitlog serve --pty``, ``socket://127.0.0.1:PORT`` from ``gaitlog serve --tcp``, and the
in-process emulator ``emu://...`` (:mod:`host.link.transports.protocol_emu`).

Each command is one frame (``PROTOCOL.md`` section 3); the link numbers it with ``seq``, waits up to
``timeout_s`` for the answer with the same ``seq``, and sends it again (new ``seq``) when the answer does not
come, comes damaged, or is ``NAK(BAD_CRC)``, at most ``retries`` more times. A NAK with any other error is
final and raised as :class:`~host.errors.HostError` naming the command and the error. The bulk memory dump
with re-reads and resume is :class:`host.link.memory_dump.MemoryDump` (:func:`host.link.memory_dump.dump_memory`).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Any

import serial

from host.errors import HostError
from host.link.transports import register
from protocol.errors import ProtocolError
from protocol.frames import (
    MAX_DATA,
    PAYLOAD_OFFSETS,
    PAYLOAD_STRUCTS,
    ErrorCode,
    Frame,
    FrameError,
    FrameParser,
    FrameType,
    StartMode,
    build_payload,
    encode_frame,
    parse_payload,
)
from protocol.header import (
    CALIBRATION_SIZE,
    HEADER_SIZE,
    MILLIHZ_PER_HZ,
    PROTOCOL_VERSION,
    DeviceHeader,
    firmware_version_text,
)
from protocol.steps import STEP_ADDRESS_BASE, StepConfig

_ERROR_HINTS = {ErrorCode.BUSY: "the device is logging: stop it first",
                ErrorCode.MEMORY_FULL: "the memory is full: erase it first",
                ErrorCode.BAD_ADDRESS: "the range is outside the device's sample and step memories"}
_INFO_SIZE = PAYLOAD_STRUCTS[FrameType.INFO].sizeof()
_STATUS_SIZE = PAYLOAD_STRUCTS[FrameType.STATUS].sizeof()
_DUMP_END_SIZE = PAYLOAD_STRUCTS[FrameType.DUMP_END].sizeof()
#: Where the data start in a DATA payload (after its address), and where a NAK carries its error code.
_DATA_OFFSET = PAYLOAD_OFFSETS[FrameType.DATA]["data"]
_NAK_ERROR_OFFSET = PAYLOAD_OFFSETS[FrameType.NAK]["error"]


def _nak_error(frame: Frame) -> int | None:
    """The error code of a NAK frame (None when its payload is too short to hold one)."""
    return frame.payload[_NAK_ERROR_OFFSET] if len(frame.payload) > _NAK_ERROR_OFFSET else None


def _name(ftype: int) -> str:
    """``FrameType`` name of a code (hex for an unknown one)."""
    try:
        return FrameType(ftype).name
    except ValueError:
        return f"0x{ftype:02x}"


def _build(name: str, **fields: Any) -> bytes:
    """Command payload via ``protocol.frames.build_payload`` (ProtocolError -> HostError)."""
    try:
        return build_payload(FrameType[name], **fields)
    except ProtocolError as err:
        raise HostError(f"cannot build {name} command: {err}") from err


def device_identity(info: dict[str, int]) -> dict[str, Any]:
    """An IDENTIFY answer (:meth:`LoggerLink.identify`) in the host's words: ``sampling_rate_hz`` (float) for
    the wire's ``sampling_rate_millihz``, ``firmware_version`` as ``"major.minor"``; the other fields as sent.

    >>> device_identity({"device_id": 7, "firmware_version": 0x0102, "sampling_rate_millihz": 50_000})
    {'device_id': 7, 'firmware_version': '1.2', 'sampling_rate_hz': 50.0}
    """
    out: dict[str, Any] = {}
    for name, value in info.items():
        if name == "sampling_rate_millihz":
            out["sampling_rate_hz"] = value / MILLIHZ_PER_HZ
        elif name == "firmware_version":
            out[name] = firmware_version_text(value)
        else:
            out[name] = value
    return out


@dataclass
class LinkStats:
    """Counters of one link (for the dump metadata)."""

    bytes_received: int = 0
    frames_ok: int = 0
    frame_errors: int = 0
    command_retries: int = 0
    timeouts: int = 0
    naks: dict[str, int] = field(default_factory=dict)


def open_serial(port: str, *, baud: int = 115200, poll_s: float = 0.02):
    """Open ``port`` (path, ``socket://``, ``emu://``, ...) with pyserial, 8N1, no flow control.

    Raises
    ------
    HostError
        The port does not exist or cannot be opened (message names it and says what to check).
    """
    register()
    try:
        return serial.serial_for_url(port, baudrate=baud, bytesize=8, parity="N", stopbits=1, timeout=poll_s,
                                     write_timeout=10.0, xonxoff=False, rtscts=False, dsrdtr=False)
    except (serial.SerialException, ValueError, OSError) as err:
        raise HostError(f"cannot open port {port!r}: {err}. Check the device path or URL (a pty path printed "
                        "by `gaitlog serve --pty`, socket://HOST:PORT, emu://IMAGE)") from err


class LoggerLink:
    """A connection to a logger.

    Parameters
    ----------
    port
        Device path, pty path, ``socket://HOST:PORT`` or ``emu://...`` URL.
    baud
        Baud rate (8N1).
    timeout_s
        How long to wait for an answer to a command, and for the next byte of a DUMP stream.
    retries
        How many times a command is sent again after a timeout or a damaged answer.
    capture
        Binary file object that receives every byte read from the device (a wire capture that
        ``gaitlog decode`` reads), or None.
    serial_port
        An already open pyserial object to use instead of opening ``port``.

    Examples
    --------
    >>> LoggerLink("/nonexistent/ttyX")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    host.errors.HostError: cannot open port '/nonexistent/ttyX': ...
    """

    def __init__(self, port: str, *, baud: int = 115200, timeout_s: float = 1.0, retries: int = 3,
                 capture: IO[bytes] | None = None, serial_port: Any = None) -> None:
        self.port = port
        self.baud = baud
        self.timeout_s = timeout_s
        self.retries = retries
        self.capture = capture
        self.stats = LinkStats()
        self._ser = serial_port if serial_port is not None else open_serial(port, baud=baud)
        self._parser_cls = FrameParser
        self._parser = FrameParser()
        self._pending: deque = deque()
        self._seq = 0

    # --------------------------------------------------------------------------------------- lifecycle
    def close(self) -> None:
        """Close the port."""
        if self._ser is not None:
            self._ser.close()
            self._ser = None

    def __enter__(self) -> "LoggerLink":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def serial(self) -> Any:
        """The underlying pyserial object."""
        return self._ser

    # ------------------------------------------------------------------------------------------ receive
    def _read_some(self) -> bytes:
        ser = self._ser
        try:
            waiting = ser.in_waiting
            data = ser.read(waiting if waiting else 1)
        except Exception as err:  # serial.SerialException, OSError: the port went away
            raise HostError(f"{self.port}: read failed: {err}") from err
        if data:
            self.stats.bytes_received += len(data)
            if self.capture is not None:
                self.capture.write(data)
        return data

    def flush_input(self) -> None:
        """Forget everything received so far (stale answers, the tail of an abandoned stream)."""
        try:
            self._ser.reset_input_buffer()
        except Exception:  # some transports cannot; reading on is enough  # pragma: no cover
            pass
        self._parser = self._parser_cls()
        self._pending.clear()

    def next_frame(self, timeout_s: float, *, idle: bool = False):
        """Return the next intact frame, or None when ``timeout_s`` passes (since the call, or with
        ``idle=True`` since the last byte received). Damaged frames are counted and skipped."""
        deadline = time.monotonic() + timeout_s
        while not self._pending:
            if time.monotonic() > deadline:
                if self._parser.buffered:
                    # inter-byte timeout inside a frame (a damaged length field, say): discard that frame and
                    # look for frames in the bytes after its sync
                    self._take(self._parser.flush())
                    if self._pending:
                        break
                self.stats.timeouts += 1
                return None
            data = self._read_some()
            if not data:
                continue
            if idle:
                deadline = time.monotonic() + timeout_s
            self._take(self._parser.feed(data))
        return self._pending.popleft()

    def _take(self, items: list) -> None:
        for item in items:
            if isinstance(item, FrameError):
                if item.reason != "garbage":
                    self.stats.frame_errors += 1
            else:
                self.stats.frames_ok += 1
                self._pending.append(item)

    # ------------------------------------------------------------------------------------------- send
    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFF
        return self._seq

    def send(self, ftype: int, payload: bytes = b"") -> int:
        """Send one command frame (after discarding stale input); return its ``seq``."""
        self.flush_input()
        seq = self._next_seq()
        try:
            self._ser.write(encode_frame(ftype, seq, payload))
            self._ser.flush()
        except Exception as err:
            raise HostError(f"{self.port}: write failed: {err}") from err
        return seq

    def _raise_nak(self, ftype: int, frame: Frame) -> None:
        code = _nak_error(frame)
        try:
            name = ErrorCode(code).name
        except ValueError:
            name = "without an error code" if code is None else f"error 0x{code:02x}"
        self.stats.naks[name] = self.stats.naks.get(name, 0) + 1
        hint = _ERROR_HINTS.get(code)
        raise HostError(f"{self.port}: device refused {_name(ftype)}: NAK {name}" + (f" ({hint})" if hint else ""))

    def transact(self, ftype: int, payload: bytes, expect: int, *, expect_len: int | None = None):
        """Send a command and return the answer frame of type ``expect`` (retrying as described above)."""
        name = _name(ftype)
        for attempt in range(self.retries + 1):
            if attempt:
                self.stats.command_retries += 1
            seq = self.send(ftype, payload)
            while (frame := self.next_frame(self.timeout_s)) is not None:
                if frame.seq != seq:
                    continue
                if frame.type == FrameType.NAK:
                    if _nak_error(frame) == ErrorCode.BAD_CRC:  # our frame was damaged
                        break
                    self._raise_nak(ftype, frame)
                if frame.type == expect and (expect_len is None or len(frame.payload) == expect_len):
                    return frame
        raise HostError(f"{self.port}: no valid answer to {name} after {self.retries + 1} attempt(s) of "
                        f"{self.timeout_s:g} s: check the port, the baud rate ({self.baud}) and that the device "
                        "is on")

    # ----------------------------------------------------------------------------------------- commands
    def identify(self) -> dict[str, int]:
        """IDENTIFY -> INFO fields (``device_id``, ``firmware_version``, ``protocol_version``, ``adc_bits``,
        ``sampling_rate_millihz``, ``capacity_samples``, ``packing``, ``memory_bytes``); refuses an unknown
        protocol version."""
        fr = self.transact(FrameType.IDENTIFY, b"", FrameType.INFO, expect_len=_INFO_SIZE)
        info = self._fields(fr)
        if info["protocol_version"] != PROTOCOL_VERSION:
            raise HostError(f"{self.port}: device speaks protocol version {info['protocol_version']}, this host "
                            f"knows version {PROTOCOL_VERSION}: update gaitlog")
        return info

    def status(self) -> dict[str, int]:
        """STATUS -> ``state`` (a :class:`protocol.frames.DeviceState` code), ``flags``, ``samples_written``,
        ``write_index``."""
        fr = self.transact(FrameType.GET_STATUS, b"", FrameType.STATUS, expect_len=_STATUS_SIZE)
        return self._fields(fr)

    def _fields(self, frame) -> dict[str, int]:
        """Payload fields of an answer (``protocol.frames.parse_payload``), as plain ints."""
        try:
            fields = parse_payload(frame, source=self.port)
        except ProtocolError as err:
            raise HostError(f"{self.port}: malformed {frame.frame_type!s} answer: {err}") from err
        return {k: int(v) for k, v in fields.items() if not k.startswith("_")}

    def _ack(self, ftype: int, payload: bytes = b"") -> None:
        self.transact(ftype, payload, FrameType.ACK)

    def start(self, start_time_s: int | None = None, *, overwrite: bool = False) -> None:
        """START logging at Unix time ``start_time_s`` (default: now), ring mode if ``overwrite``."""
        t = int(time.time()) if start_time_s is None else int(start_time_s)
        mode = StartMode.OVERWRITE if overwrite else StartMode.STOP_WHEN_FULL
        self._ack(FrameType.START, _build("START", start_time_s=t, mode=mode))

    def stop(self) -> None:
        """STOP logging."""
        self._ack(FrameType.STOP)

    def erase(self) -> None:
        """ERASE the sample memory and the step memory (sends the ``b"ERASE"`` guard); the calibration and the
        step configuration stay."""
        self._ack(FrameType.ERASE, _build("ERASE"))

    def set_calibration(self, slot: bytes) -> None:
        """SET_CALIBRATION with a calibration slot of ``CALIBRATION_SIZE`` bytes
        (``protocol.header.CalibrationSlot.to_bytes()``)."""
        if len(slot) != CALIBRATION_SIZE:
            raise HostError(f"calibration slot must be {CALIBRATION_SIZE} bytes, got {len(slot)}")
        self._ack(FrameType.SET_CALIBRATION, bytes(slot))

    def set_step_config(self, config: StepConfig | bytes) -> None:
        """SET_STEP_CONFIG: store the on-line step algorithm's configuration in the device header.

        Parameters
        ----------
        config
            A :class:`protocol.steps.StepConfig` (``StepConfig.off()`` turns the algorithm off) or its 32 bytes.

        Raises
        ------
        HostError
            A configuration that cannot be stored (the field is named) or that the device refuses (NAK
            ``BAD_ARGUMENT``, ``BUSY`` while logging).
        """
        self._ack(FrameType.SET_STEP_CONFIG, _build("SET_STEP_CONFIG", step_config=config))

    def read_header(self):
        """READ_HEADER -> ``(header_bytes, DeviceHeader)`` (the header validated)."""
        fr = self.transact(FrameType.READ_HEADER, b"", FrameType.HEADER, expect_len=HEADER_SIZE)
        raw = bytes(fr.payload)
        try:
            return raw, DeviceHeader.from_bytes(raw, source=f"{self.port} HEADER frame")
        except ProtocolError as err:
            raise HostError(f"{self.port}: the device's header is invalid: {err}") from err

    def read(self, address: int, length: int) -> bytes:
        """READ ``length`` (1 ... ``MAX_DATA``) bytes at the memory address ``address``: the sample memory from 0, the
        step memory from ``protocol.steps.STEP_ADDRESS_BASE`` (:meth:`read_step_memory`)."""
        if not 1 <= length <= MAX_DATA:
            raise HostError(f"READ length must be 1..{MAX_DATA}, got {length}")
        payload = _build("READ", address=address, length=length)
        fr = self.transact(FrameType.READ, payload, FrameType.DATA, expect_len=_DATA_OFFSET + length)
        data = parse_payload(fr, source=self.port)
        if data["address"] != address:  # pragma: no cover - a device bug, not line noise (CRC was good)
            raise HostError(f"{self.port}: READ at {address} answered with address {data['address']}")
        return data["data"]

    def read_step_memory(self, offset: int, length: int) -> bytes:
        """READ ``length`` (1 ... ``MAX_DATA``) bytes of the step memory from its byte ``offset`` (the record in slot
        ``k`` is bytes ``20k ... 20k+19``; PROTOCOL.md 2.3), at address ``STEP_ADDRESS_BASE + offset``."""
        if offset < 0:
            raise HostError(f"step memory offset must be >= 0, got {offset}")
        return self.read(STEP_ADDRESS_BASE + int(offset), length)

    def dump_stream(self, address: int, length: int, chunk: int,
                    on_data: Callable[[int, bytes], None]) -> bool:
        """DUMP ``length`` bytes at ``address`` in DATA frames of ``chunk`` bytes; call ``on_data(address,
        data)`` for every intact DATA frame whose address and size fit the request.

        Returns True when DUMP_END arrived, False when the stream stopped (no byte for ``timeout_s``) or
        ``on_data`` returned True (the caller has everything it needs). Raises on a NAK.
        """
        command = _build("DUMP", address=address, length=length, chunk=chunk)
        seq = self.send(FrameType.DUMP, command)
        end = address + length
        # a damaged DUMP command gets NAK(BAD_CRC); resend it once per retry
        attempts = 0
        while True:
            frame = self.next_frame(self.timeout_s, idle=True)
            if frame is None:
                return False
            if frame.type == FrameType.NAK and frame.seq == seq:
                if _nak_error(frame) == ErrorCode.BAD_CRC and attempts < self.retries:
                    attempts += 1
                    self.stats.command_retries += 1
                    seq = self._next_seq()
                    self._ser.write(encode_frame(FrameType.DUMP, seq, command))
                    continue
                self._raise_nak(FrameType.DUMP, frame)
            if frame.type == FrameType.DATA and len(frame.payload) > _DATA_OFFSET:
                data = parse_payload(frame, source=self.port)
                a, n = data["address"], len(data["data"])
                fits = address <= a and a + n <= end and (a - address) % chunk == 0 and n == min(chunk, end - a)
                if fits and on_data(a, data["data"]):
                    return False
            elif frame.type == FrameType.DUMP_END and len(frame.payload) == _DUMP_END_SIZE:
                end_fields = self._fields(frame)
                if end_fields["address"] == address and end_fields["length"] == length:
                    return True
