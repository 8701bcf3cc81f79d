"""The host end of the serial line: every command of ``PROTOCOL.md`` over pyserial, with timeouts and retries.

:class:`LoggerLink` works on anything pyserial opens: a real port (``/dev/ttyUSB0``, ``COM3``), a pty path
printed by ``gaitlog serve --pty``, ``socket://127.0.0.1:PORT`` from ``gaitlog serve --tcp``, and the
in-process emulator ``emu://...`` (:mod:`gaitlog.host.link.transports.protocol_emu`).

Each command is one frame (``PROTOCOL.md`` section 3); the link numbers it with ``seq``, waits up to
``timeout_s`` for the answer with the same ``seq`` (less when an answer came damaged and the line then went
quiet for ``quiet_s``), and sends it again (new ``seq``, after a short growing pause) when the answer does
not come, comes damaged, or is ``NAK(BAD_CRC)``: as long as ``deadline_s`` has not passed since the first
attempt (and at most ``retries`` more times when ``retries`` is given). Nothing at all received in
:data:`NO_DEVICE_ATTEMPTS` attempts in a row ends it sooner. The error then says which it was: no byte at all
(port, baud, power) or bytes but no intact answer (a noisy line or a wrong baud rate). A NAK with any other
error is final and raised as :class:`~gaitlog.host.errors.HostError` naming the command and the error.

:meth:`LoggerLink.dump_checked` runs DUMP_CHECKED (``PROTOCOL.md`` section 4): a DATA frame is used only when
the DATA_CRC frame after it carries the CRC-32 of exactly the bytes received, so a damaged frame that passes
its CRC-16 (about 1 in 65,536) is re-read instead of stored. :meth:`LoggerLink.abort` ends a stream. The bulk memory dump
with re-reads and resume is :class:`gaitlog.host.link.memory_dump.MemoryDump` (:func:`gaitlog.host.link.memory_dump.dump_memory`).
"""

from __future__ import annotations

import math
import time
import zlib
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Any

import serial

from gaitlog.host.errors import HostError
from gaitlog.host.link.transports import register
from gaitlog.protocol.data_blocks import verified_blocks
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import (
    KNOWN_WIRE_PROTOCOL_VERSIONS,
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
from gaitlog.protocol.header import (
    CALIBRATION_SIZE,
    HEADER_SIZE,
    MILLIHZ_PER_HZ,
    DeviceHeader,
    firmware_version_text,
)
from gaitlog.protocol.steps import STEP_ADDRESS_BASE, StepConfig

_ERROR_HINTS = {ErrorCode.BUSY: "the device is logging: stop it first",
                ErrorCode.MEMORY_FULL: "the memory is full: erase it first",
                ErrorCode.BAD_ADDRESS: "the range is outside the device's sample and step memories"}
_INFO_SIZE = PAYLOAD_STRUCTS[FrameType.INFO].sizeof()
_STATUS_SIZE = PAYLOAD_STRUCTS[FrameType.STATUS].sizeof()
_DUMP_END_SIZE = PAYLOAD_STRUCTS[FrameType.DUMP_END].sizeof()
#: Where the data start in a DATA payload (after its address), and where a NAK carries its error code.
_DATA_OFFSET = PAYLOAD_OFFSETS[FrameType.DATA]["data"]
_NAK_ERROR_OFFSET = PAYLOAD_OFFSETS[FrameType.NAK]["error"]
_DATA_CRC_SIZE = PAYLOAD_STRUCTS[FrameType.DATA_CRC].sizeof()
#: Attempts in a row with no byte at all received after which a command gives up before its deadline.
NO_DEVICE_ATTEMPTS = 6
#: Pause before the k-th resend of a command: BACKOFF_S · 2^(k-1), at most BACKOFF_MAX_S.
BACKOFF_S = 0.01
BACKOFF_MAX_S = 0.5


def _runs(pieces: list[tuple[int, bytes]]) -> list[tuple[int, bytes]]:
    """Adjacent ``(address, bytes)`` pieces joined into runs.

    >>> _runs([(0, b"ab"), (2, b"c"), (9, b"d")])
    [(0, b'abc'), (9, b'd')]
    """
    out: list[tuple[int, list[bytes], int]] = []
    for address, data in pieces:
        if out and out[-1][2] == address:
            out[-1][1].append(data)
            out[-1] = (out[-1][0], out[-1][1], address + len(data))
        else:
            out.append((address, [data], address + len(data)))
    return [(a, b"".join(parts)) for a, parts, _ in out]


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
    """Command payload via ``gaitlog.protocol.frames.build_payload`` (ProtocolError -> HostError)."""
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
    crc32_mismatches: int = 0
    streams_abandoned: int = 0
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


@dataclass
class StreamResult:
    """How a :meth:`LoggerLink.dump_checked` stream went: DUMP_END seen, DATA frames verified, chunk positions
    covered (up to the furthest frame received intact), frames in the request."""

    ended: bool = False
    frames_verified: int = 0
    frames_seen: int = 0
    frames_total: int = 0

    def seen(self, a: int, address: int, chunk: int) -> None:
        self.frames_seen = max(self.frames_seen, (a - address) // chunk + 1)


class _Stream:
    """The data frames of one checked dump stream (:meth:`LoggerLink._stream`): ``take`` reads one frame and
    returns True (the stream is done: return its result), False (a data frame, taken) or None (not a data frame
    of this protocol)."""

    def __init__(self, link: LoggerLink, address: int, length: int, chunk: int,
                 on_data: Callable[[int, bytes], bool | None], keep_going: Callable[[int, int], bool] | None) -> None:
        self.link, self.address, self.length, self.chunk = link, address, length, chunk
        self.on_data, self.keep_going = on_data, keep_going
        self.end = address + length
        self.n_frames = -(-length // chunk)
        self.result = StreamResult(frames_total=self.n_frames)

    def restart(self) -> StreamResult:
        """A new attempt (the command just sent): a fresh result."""
        self.result = StreamResult(frames_total=self.n_frames)
        return self.result

    def quiet(self) -> None:
        """The line went quiet."""

    def take(self, frame: Frame) -> bool | None:
        raise NotImplementedError

    def _abandon(self, frames_seen: int) -> bool:
        """``keep_going`` says no: count the stream abandoned."""
        if self.keep_going is not None and not self.keep_going(self.result.frames_verified, frames_seen):
            self.link.stats.streams_abandoned += 1
            return True
        return False


class _ChecksumStream(_Stream):
    """DUMP_CHECKED: a DATA frame, then its DATA_CRC (CRC-32 of the frame's bytes)."""

    def restart(self) -> StreamResult:
        self.pending: tuple[int, bytes] | None = None
        return super().restart()

    def take(self, frame: Frame) -> bool | None:
        if frame.type == FrameType.DATA and len(frame.payload) > _DATA_OFFSET:
            return self._data(frame)
        if frame.type == FrameType.DATA_CRC and len(frame.payload) == _DATA_CRC_SIZE:
            return self._data_crc(frame)
        self.pending = None
        return None

    def _data(self, frame: Frame) -> bool:
        a = int.from_bytes(frame.payload[:_DATA_OFFSET], "little")
        data = frame.payload[_DATA_OFFSET:]
        n = len(data)
        fits = self.address <= a and a + n <= self.end and (a - self.address) % self.chunk == 0 and n == min(
            self.chunk, self.end - a)
        self.pending = (a, data) if fits else None
        if not fits:
            return False
        self.result.seen(a, self.address, self.chunk)
        # this frame's own check is still to come: judge the frames before it
        return self._abandon(self.result.frames_seen - 1)

    def _data_crc(self, frame: Frame) -> bool:
        result, pending = self.result, self.pending
        a = int.from_bytes(frame.payload[:4], "little")
        crc = int.from_bytes(frame.payload[4:8], "little")
        if self.address <= a < self.end and (a - self.address) % self.chunk == 0:
            result.seen(a, self.address, self.chunk)
        self.pending = None
        if pending is not None and pending[0] == a:
            if zlib.crc32(pending[1]) & 0xFFFFFFFF == crc:
                result.frames_verified += 1
                if self.on_data(a, pending[1]):
                    return True
            else:
                self.link.stats.crc32_mismatches += 1
        if result.frames_seen == self.n_frames and (a - self.address) // self.chunk == self.n_frames - 1:
            result.ended = True  # the last frame's check: only DUMP_END is left to come
            return True
        return self._abandon(result.frames_seen)


class _BlockStream(_Stream):
    """DUMP_BLOCKS (protocol version 2): DATA_BLOCKS frames whose 64-sample blocks carry their own checks, bound
    to the header's CRC (``binding``)."""

    def __init__(self, *args: Any, binding: int) -> None:
        super().__init__(*args)
        self.binding = binding

    def restart(self) -> StreamResult:
        self.damaged_before = self.link.stats.frame_errors
        return super().restart()

    def quiet(self) -> None:
        if self.link.stats.frame_errors > self.damaged_before:  # frames came, damaged: the stream ran unseen
            self.result.frames_seen = self.n_frames

    def take(self, frame: Frame) -> bool | None:
        if not (frame.type == FrameType.DATA_BLOCKS and len(frame.payload) > _DATA_OFFSET):
            return None
        result = self.result
        a = int.from_bytes(frame.payload[:_DATA_OFFSET], "little")
        if not (self.address <= a < self.end and (a - self.address) % self.chunk == 0):
            return False
        found = verified_blocks(self.binding, frame.payload)
        want = min(self.chunk, self.end - a)
        result.seen(a, self.address, self.chunk)
        result.frames_verified += found.data_bytes == want
        self.link.stats.crc32_mismatches += found.data_bytes != want
        for run_address, data in _runs(found.pieces()):  # one call per run of verified blocks
            if run_address + len(data) <= self.end and self.on_data(run_address, data):
                return True
        if result.frames_seen == self.n_frames and self.link.capture is None:
            result.ended = True  # the rest is the header's copy and DUMP_END
            return True
        return self._abandon(result.frames_seen)


class LoggerLink:
    """A connection to a logger.

    Parameters
    ----------
    port
        Device path, pty path, ``socket://HOST:PORT`` or ``emu://...`` URL.
    baud
        Baud rate (8N1).
    timeout_s
        How long to wait for an answer to a command, and for the next byte of a DUMP stream: a finite
        number of seconds > 0.
    retries
        At most this many resends of a command after a timeout or a damaged answer (None: as many as
        ``deadline_s`` allows).
    deadline_s
        Time after which a command's resends stop (from its first attempt).
    quiet_s
        After bytes of a damaged answer, this much silence ends the wait for it (default
        ``min(timeout_s, 0.2)``); in a stream, the silence after which it counts as ended.
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
    gaitlog.host.errors.HostError: cannot open port '/nonexistent/ttyX': ...
    """

    def __init__(self, port: str, *, baud: int = 115200, timeout_s: float = 1.0, retries: int | None = None,
                 deadline_s: float = 30.0, quiet_s: float | None = None, capture: IO[bytes] | None = None,
                 serial_port: Any = None) -> None:
        for name, value in (("answer timeout", timeout_s), ("command deadline", deadline_s),
                            ("quiet time", 1.0 if quiet_s is None else quiet_s)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= 86400):
                raise HostError(f"{name} must be a finite number of seconds in (0, 86400], got {value}")
        if retries is not None and retries < 0:
            raise HostError(f"retries must be >= 0, got {retries}")
        self.port = port
        self.baud = baud
        self.timeout_s = float(timeout_s)
        self.retries = retries
        self.deadline_s = float(deadline_s)
        self.quiet_s = min(self.timeout_s, 0.2) if quiet_s is None else float(quiet_s)
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

    def __enter__(self) -> LoggerLink:
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

    def next_frame(self, timeout_s: float, *, idle: bool = False, quiet_s: float | None = None):
        """Return the next intact frame, or None when ``timeout_s`` passes (since the call, or with
        ``idle=True`` since the last byte received), or, with ``quiet_s``, when bytes came in this call and
        then none for ``quiet_s``. Damaged frames are counted and skipped."""
        deadline = time.monotonic() + timeout_s
        got, last = False, 0.0
        while not self._pending:
            now = time.monotonic()
            if got and quiet_s is not None:
                deadline = min(deadline, last + quiet_s)
            if now > deadline:
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
            got, last = True, time.monotonic()
            if idle:
                deadline = last + timeout_s
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
        t0 = time.monotonic()
        bytes_before, damaged_before = self.stats.bytes_received, self.stats.frame_errors
        attempt = silent = 0
        while True:
            if attempt:
                self.stats.command_retries += 1
                time.sleep(min(BACKOFF_S * 2 ** (attempt - 1), BACKOFF_MAX_S))
            attempt += 1
            seq = self.send(ftype, payload)
            heard = self.stats.bytes_received
            while (frame := self.next_frame(self.timeout_s, quiet_s=self.quiet_s)) is not None:
                if frame.seq != seq:
                    continue
                if frame.type == FrameType.NAK:
                    if _nak_error(frame) == ErrorCode.BAD_CRC:  # our frame was damaged
                        break
                    self._raise_nak(ftype, frame)
                if frame.type == expect and (expect_len is None or len(frame.payload) == expect_len):
                    return frame
            silent = silent + 1 if self.stats.bytes_received == heard else 0
            if ((self.retries is not None and attempt > self.retries) or silent >= NO_DEVICE_ATTEMPTS
                    or time.monotonic() - t0 >= self.deadline_s):
                break
        spent = time.monotonic() - t0
        received = self.stats.bytes_received - bytes_before
        if received == 0:
            raise HostError(f"{self.port}: no answer to {name}: not one byte received in {attempt} attempt(s) over "
                            f"{spent:.1f} s: check the port, the baud rate ({self.baud}) and that the device is on")
        damaged = self.stats.frame_errors - damaged_before
        raise HostError(f"{self.port}: no intact answer to {name} in {attempt} attempt(s) over {spent:.1f} s although "
                        f"{received} bytes arrived ({damaged} damaged frame(s)): the line is too noisy or the baud "
                        f"rate ({self.baud}) is wrong")

    # ----------------------------------------------------------------------------------------- commands
    def identify(self) -> dict[str, int]:
        """IDENTIFY -> INFO fields (``device_id``, ``firmware_version``, ``protocol_version``, ``adc_bits``,
        ``sampling_rate_millihz``, ``capacity_samples``, ``packing``, ``memory_bytes``); refuses an unknown
        protocol version."""
        fr = self.transact(FrameType.IDENTIFY, b"", FrameType.INFO, expect_len=_INFO_SIZE)
        info = self._fields(fr)
        if info["protocol_version"] not in KNOWN_WIRE_PROTOCOL_VERSIONS:
            raise HostError(f"{self.port}: device speaks protocol version {info['protocol_version']}, this host "
                            f"knows versions {', '.join(map(str, KNOWN_WIRE_PROTOCOL_VERSIONS))}: update gaitlog")
        return info

    def status(self) -> dict[str, int]:
        """STATUS -> ``state`` (a :class:`gaitlog.protocol.frames.DeviceState` code), ``flags``, ``samples_written``,
        ``write_index``."""
        fr = self.transact(FrameType.GET_STATUS, b"", FrameType.STATUS, expect_len=_STATUS_SIZE)
        return self._fields(fr)

    def _fields(self, frame) -> dict[str, int]:
        """Payload fields of an answer (``gaitlog.protocol.frames.parse_payload``), as plain ints."""
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

    def abort(self, *, wait: bool = True) -> None:
        """ABORT: end a stream the device is sending (``PROTOCOL.md`` section 4). ``wait=False`` only sends
        the frame (best effort, for a host on its way out: no error is raised)."""
        if wait:
            self._ack(FrameType.ABORT)
            return
        try:
            self._ser.write(encode_frame(FrameType.ABORT, self._next_seq()))
            self._ser.flush()
        except Exception:  # noqa: BLE001 - the port may be gone; there is nothing left to tell the device
            pass

    def erase(self) -> None:
        """ERASE the sample memory and the step memory (sends the ``b"ERASE"`` guard); the calibration and the
        step configuration stay."""
        self._ack(FrameType.ERASE, _build("ERASE"))

    def set_calibration(self, slot: bytes) -> None:
        """SET_CALIBRATION with a calibration slot of ``CALIBRATION_SIZE`` bytes
        (``gaitlog.protocol.header.CalibrationSlot.to_bytes()``)."""
        if len(slot) != CALIBRATION_SIZE:
            raise HostError(f"calibration slot must be {CALIBRATION_SIZE} bytes, got {len(slot)}")
        self._ack(FrameType.SET_CALIBRATION, bytes(slot))

    def set_step_config(self, config: StepConfig | bytes) -> None:
        """SET_STEP_CONFIG: store the on-line step algorithm's configuration in the device header.

        Parameters
        ----------
        config
            A :class:`gaitlog.protocol.steps.StepConfig` (``StepConfig.off()`` turns the algorithm off) or its 32 bytes.

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
        step memory from ``gaitlog.protocol.steps.STEP_ADDRESS_BASE`` (:meth:`read_step_memory`)."""
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

    def dump_checked(self, address: int, length: int, chunk: int, on_data: Callable[[int, bytes], bool | None],
                     *, keep_going: Callable[[int, int], bool] | None = None) -> StreamResult:
        """DUMP_CHECKED ``length`` bytes at ``address`` in DATA frames of ``chunk`` bytes; call ``on_data(address,
        data)`` for every DATA frame whose address and size fit the request and whose bytes the DATA_CRC after
        it verifies (CRC-32).

        The stream ends at DUMP_END, when the line is quiet for ``quiet_s`` after the first byte (``timeout_s``
        before it), when ``on_data`` returns True, or when ``keep_going(frames_verified, frames_seen)`` returns
        False (checked after each frame; ``frames_seen`` counts the chunk positions up to the furthest frame
        received intact, verified or not). The device keeps streaming until the next command (or
        :meth:`abort`) ends it. Raises on a NAK other than BAD_CRC (a damaged command is sent again, within
        the retries and deadline of a command).
        """
        return self._stream(FrameType.DUMP_CHECKED, _ChecksumStream(self, address, length, chunk, on_data, keep_going))

    def dump_blocks(self, address: int, length: int, chunk: int, on_data: Callable[[int, bytes], bool | None],
                    *, binding: int, keep_going: Callable[[int, int], bool] | None = None) -> StreamResult:
        """DUMP_BLOCKS (protocol version 2, ``PROTOCOL.md`` 4.1) ``length`` bytes at ``address`` in DATA_BLOCKS frames
        of ``chunk`` bytes; call ``on_data(address, data)`` for every 64-sample block of an intact frame (CRC-16
        good, address and size fitting the request) whose check verifies under ``binding`` (the header's CRC).

        Ends as :meth:`dump_checked`; a frame counts as verified when all its blocks verify. After the last frame
        the device sends the header again and DUMP_END: with a capture file the stream is read to its end so
        that the capture holds that second copy, without one the call returns at once.
        """
        return self._stream(FrameType.DUMP_BLOCKS,
                            _BlockStream(self, address, length, chunk, on_data, keep_going, binding=binding))

    def _stream(self, ftype: int, stream: _Stream) -> StreamResult:
        """Send ``ftype`` (DUMP_CHECKED or DUMP_BLOCKS) for ``stream`` and read the frames that answer it, each
        through ``stream.take`` (its protocol's data frames); the NAK and DUMP_END rules, the quiet line and the
        retries of a damaged command are the same for both."""
        command = _build(FrameType(ftype).name, address=stream.address, length=stream.length, chunk=stream.chunk)
        t0 = time.monotonic()
        attempt = 0
        while True:
            seq = self.send(ftype, command)
            attempt += 1
            result = stream.restart()
            resend = False
            while True:
                frame = self.next_frame(self.timeout_s, idle=True, quiet_s=self.quiet_s)
                if frame is None:
                    stream.quiet()
                    break
                if frame.type == FrameType.NAK and frame.seq == seq:
                    if _nak_error(frame) == ErrorCode.BAD_CRC:
                        resend = True
                        break
                    self._raise_nak(ftype, frame)
                done = stream.take(frame)
                if done:
                    return result
                if done is None and frame.type == FrameType.DUMP_END and len(frame.payload) == _DUMP_END_SIZE:
                    end_fields = self._fields(frame)
                    if end_fields["address"] == stream.address and end_fields["length"] == stream.length:
                        result.ended = True
                        result.frames_seen = stream.n_frames
                        return result
            if not resend or time.monotonic() - t0 >= self.deadline_s or (
                    self.retries is not None and attempt > self.retries):
                if result.frames_seen:
                    result.frames_seen = stream.n_frames  # the stream ran to its end unseen (or never started)
                return result
            self.stats.command_retries += 1

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
