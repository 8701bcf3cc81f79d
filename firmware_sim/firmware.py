"""The logger's firmware, sans-I/O: logging control, the sample path and the UART command handler.

Everything here is what the PIC16F877 program does, with the I/O cut off: bytes from the UART come in
through :meth:`Firmware.receive` (with the time they arrived), and the bytes the device sends come back as
its return value; the transport (:mod:`gaitlog.firmware_sim.transport`) owns the port and the clock. The sample
timer's interrupt handler is :meth:`Firmware.log_samples`, fed a block of ADC codes at a time.

On-line step algorithm (PROTOCOL.md 2.2, 2.3)
    When the header's step configuration is on (``step_format`` 3, the version it runs), START builds the firmware's step
    algorithm (:class:`gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`, fixed point) from the header —
    sampling rate, ADC width, calibration slot, step configuration — and every sample the interrupt stores
    is fed to it; each finished step's 20-byte record goes to :meth:`Firmware.log_steps`, which the
    :class:`~gaitlog.firmware_sim.step_store.StepStore` writes to the step memory. STOP, or a full memory in
    stop-when-full mode, ends the run: the pending foot-flat is finalised and its record stored before the
    header is committed. With ``step_format`` 0 the device logs samples only.

UART receiver (``PROTOCOL.md`` section 3)
    Hunts for ``A5 5A``; a length above 4100 is a framing error (skip the sync pair, hunt again, nothing
    allocated); a frame whose bytes stop arriving for longer than the inter-byte timeout (100 ms) is
    dropped. A CRC mismatch is answered ``NAK(BAD_CRC)`` when the header was intact — its type is a
    command and its length is that command's payload size (so the device knows it read the whole frame) —
    and is otherwise ignored; either way the hunt resumes after the sync pair. The ASCII line ``XDUMP``
    + CR, typed between frames, arms the XMODEM transfer of section 5 without an ACK.

Checks, in this order: payload length (``BAD_LENGTH``), field values (``BAD_ARGUMENT``), logging
(``BUSY`` for READ, DUMP, XDUMP, ERASE, SET_CALIBRATION, SET_STEP_CONFIG and also START — a START while
logging would silently restart the run), address range (``BAD_ADDRESS``: a READ/DUMP range lies entirely in
the sample memory or entirely in the step memory at ``0x01000000 +``), full memory (``MEMORY_FULL``).

Responses echo the command's ``seq``; in a DUMP stream the DATA frames count 0, 1, 2, ... (mod 256) and
DUMP_END echoes the command's ``seq``.

Streams (DUMP, DUMP_CHECKED; PROTOCOL.md section 4)
    A stream is sent one frame at a time as the UART drains (:meth:`Firmware.transmit`; with ``paced``
    False, the default for direct callers, :meth:`Firmware.receive` returns the whole stream at once). An
    intact command frame received while a stream is being sent ends it after the frame in flight: no
    DUMP_END; ABORT does only that (and cancels nothing else) and is answered ACK. DUMP_CHECKED follows
    every DATA frame with a DATA_CRC frame: the CRC-32 of the frame's bytes, computed byte by byte as they
    are read from the EEPROM (a 4-byte register; :data:`DUMP_CYCLES_PER_BYTE` says what that costs).
    DUMP_BLOCKS (protocol version 2, section 4.1) sends DATA_BLOCKS frames, a CRC-16/UMTS check after every
    64-sample block (a 2-byte register, bound to the header's CRC and the block's address), then the device
    header again in a HEADER frame, then DUMP_END.
"""

from __future__ import annotations

import dataclasses
import secrets
from collections.abc import Callable, Iterator

import numpy as np

from gaitlog.firmware_sim.algorithms.kernel import SCRATCH_FIRST_BYTE, scratch_start_page
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps, step_algorithm_for
from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.firmware_sim.eeprom import PAGE_BYTES, Eeprom24LC1025
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.fixedpoint import CYCLES, DEFAULT_FOSC_HZ
from gaitlog.firmware_sim.ring_buffer import MemoryFullError, RingBuffer
from gaitlog.firmware_sim.step_store import StepStore
from gaitlog.protocol.crc import crc16_xmodem, crc32
from gaitlog.protocol.data_blocks import blocks_payload, header_binding
from gaitlog.protocol.frames import (
    COMMAND_TYPES,
    FRAME_OVERHEAD,
    MAX_PAYLOAD,
    PAYLOAD_STRUCTS,
    SYNC,
    DeviceState,
    ErrorCode,
    Frame,
    FrameType,
    PayloadError,
    WIRE_PROTOCOL_VERSION,
    build_payload,
    encode_frame,
    parse_payload,
)
from gaitlog.protocol.header import PACKING_P32, DeviceHeader
from gaitlog.protocol.packing import FLAG_MARK, FLAG_SESSION_START, pack_words
from gaitlog.protocol.steps import ONLINE_ALGORITHM_VERSION, StepConfig, memory_region, pack_step_records
from gaitlog.protocol.raw_dump import raw_dump_bytes
from gaitlog.protocol.xmodem import XmodemSender

__all__ = ["Firmware", "FIRMWARE_VERSION", "INTER_BYTE_TIMEOUT_S", "ASCII_XDUMP", "as_run", "step_algorithm_for",
           "CRC32_CYCLES_PER_BYTE", "DUMP_CYCLES_PER_BYTE", "uart_cycles_per_byte"]

#: Firmware version 1.3 (major·256 + minor): on-line algorithm version 4 (``step_format`` 4; 1.2 ran and
#: stored version 3, 1.1 version 2, 1.0 version 1).
FIRMWARE_VERSION = 0x0103
#: Partial frames are dropped after this much silence.
INTER_BYTE_TIMEOUT_S = 0.1
#: The terminal command that arms XDUMP.
ASCII_XDUMP = b"XDUMP\r"

#: PIC16 instruction cycles per byte of the reflected CRC-32 (zlib) with a 16-entry nibble table (64 RETLW
#: bytes of program memory), two nibbles a byte: index = low nibble of the register (3), shift the 32-bit
#: register right by 4 with SWAPF/ANDLW/IORWF (21), four table look-ups CALL/ADDWF PCL/RETLW with their XOR
#: (4 x 8) and PCLATH set-up (2): 58 a nibble, plus the XOR of the data byte (2). Estimate from the instruction
#: timings (DS30292); a table-free bitwise CRC-32 costs about 146 (8 x (RRF x4, BTFSS, 4 x MOVLW/XORWF, loop)).
CRC32_CYCLES_PER_BYTE = 2 * (3 + 21 + 4 * 8 + 2) + 2
#: What the firmware does per byte of a DUMP_CHECKED stream, in instruction cycles: read it from the EEPROM
#: (I2C, :data:`gaitlog.firmware_sim.fixedpoint.CYCLES` ``i2c_byte``), update the frame's CRC-16 (nibble table, ~half the
#: CRC-32's work: estimate), the CRC-32 (:data:`CRC32_CYCLES_PER_BYTE`) and load TXREG (estimate).
DUMP_CYCLES_PER_BYTE = {"i2c_byte": CYCLES["i2c_byte"], "crc16": 60, "crc32": CRC32_CYCLES_PER_BYTE, "txreg": 6}


def uart_cycles_per_byte(baud: float = 115200.0, fosc_hz: float = DEFAULT_FOSC_HZ) -> float:
    """Instruction cycles the PIC has while the UART sends one 8N1 byte: ``fosc / 4 · 10 / baud``.

    >>> round(uart_cycles_per_byte()), sum(DUMP_CYCLES_PER_BYTE.values())   # the CRC-32 costs no wire time
    (400, 314)
    """
    return fosc_hz / 4.0 * 10.0 / baud


_BUSY_WHEN_LOGGING = frozenset(
    {FrameType.READ, FrameType.DUMP, FrameType.DUMP_CHECKED, FrameType.DUMP_BLOCKS, FrameType.XDUMP, FrameType.ERASE, FrameType.SET_CALIBRATION,
     FrameType.SET_STEP_CONFIG, FrameType.START}
)
_PAYLOAD_SIZE = {t: PAYLOAD_STRUCTS[FrameType(t)].sizeof() for t in COMMAND_TYPES}


def as_run(config: StepConfig | None) -> StepConfig | None:
    """The step configuration as the firmware stores it: an on-line ``step_format`` (1-4) becomes the version it
    runs (:data:`gaitlog.protocol.steps.ONLINE_ALGORITHM_VERSION`), so the header says what wrote the records, and
    an M4 exponent not given (0) becomes the firmware's default
    (:data:`gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT`), so it says what M4 computed."""
    if config is None or not config.enabled:
        return config
    return dataclasses.replace(config, step_format=ONLINE_ALGORITHM_VERSION,
                               m4_exponent=config.m4_exponent if config.m4_exponent > 0 else M4_EXPONENT)


class Firmware:
    """The device program over a :class:`RingBuffer` and a :class:`StepStore`.

    Parameters
    ----------
    ring
        Storage (sample memory and header).
    steps
        The step memory, sharing ``ring.header``; default a store over a fresh 24LC1025 with the header's
        ``step_capacity`` (0: no step memory, as for a header that has none).
    inter_byte_timeout_s
        Silence after which a partial command frame is dropped.
    nonce_source
        Where START takes the run's ``recording_nonce`` (32 bits; section 2.4): the PIC gathers it from the
        low bits of free-running timer 1 and of ADC conversions at START. Default: the host's CSPRNG, so two
        emulated devices never agree; pass a seeded source for reproducible bytes.

    Examples
    --------
    >>> from gaitlog.firmware_sim.eeprom import DataEeprom, EepromBank
    >>> from gaitlog.protocol.header import DeviceHeader
    >>> fw = Firmware(RingBuffer(EepromBank(), DataEeprom(), DeviceHeader(device_id=7)))
    >>> fw.receive(encode_frame(FrameType.GET_STATUS, 5), now_s=0.0).hex(" ")
    'a5 5a 82 05 0a 00 00 00 00 00 00 00 00 00 00 00 fc 30'
    >>> fw.receive(encode_frame(0x55, 6), now_s=0.0).hex(" ")   # unknown command
    'a5 5a 91 06 02 00 55 02 7a e1'
    """

    def __init__(self, ring: RingBuffer, *, steps: StepStore | None = None,
                 inter_byte_timeout_s: float = INTER_BYTE_TIMEOUT_S, fosc_hz: float = DEFAULT_FOSC_HZ,
                 nonce_source: Callable[[], int] | None = None) -> None:
        if steps is not None and steps.header is not ring.header:
            raise DeviceError("the step store and the ring buffer must share one header")
        self.ring = ring
        self.steps = steps if steps is not None else StepStore(Eeprom24LC1025(), ring.header)
        self.inter_byte_timeout_s = inter_byte_timeout_s
        self._rx = bytearray()  # unprocessed received bytes (a partial frame, or a partial ASCII line)
        self._line = b""  # recent bytes received between frames (ASCII command detection)
        self._last_rx_s = -np.inf
        self._xmodem: XmodemSender | None = None
        self._run_first = False  # the next logged sample is the first of a run (SESSION_START)
        self.fosc_hz = float(fosc_hz)
        self.nonce_source = nonce_source if nonce_source is not None else (lambda: secrets.randbits(32))
        #: The on-line step algorithm of the current (or last) run, None when the configuration is off.
        self.step_algorithm: OnlineStepAlgorithm | None = None
        self.stats = {"frames": 0, "bad_crc": 0, "framing_errors": 0, "timeouts": 0, "naks": 0,
                      "streams_aborted": 0, "crc32_bytes": 0}
        #: True: a stream leaves through :meth:`transmit` as the line drains (the transports); False: whole.
        self.paced = False
        self._stream: Iterator[bytes] | None = None

    # ------------------------------------------------------------------ logging
    @property
    def state(self) -> DeviceState:
        """IDLE, LOGGING or FULL_STOPPED (STATUS ``state``)."""
        if self.ring.logging:
            return DeviceState.LOGGING
        if self.ring.header.full_stopped:
            return DeviceState.FULL_STOPPED
        return DeviceState.IDLE

    @property
    def in_transfer(self) -> bool:
        """An XMODEM transfer is armed or running."""
        return self._xmodem is not None

    def start_logging(self, *, start_time_s: int, overwrite: bool) -> None:
        """START: begin a run (raises :class:`DeviceError` / ``MemoryFullError`` as the ring does); the step
        algorithm starts afresh from the header's configuration."""
        self.ring.start(start_time_s=start_time_s, overwrite=overwrite, nonce=self.nonce_source())
        self._run_first = True
        self.step_algorithm = step_algorithm_for(self.ring.header, fosc_hz=self.fosc_hz)

    def stop_logging(self) -> None:
        """STOP: finalise the pending step, end the run, flush the page buffer, commit the header."""
        self._end_steps()
        self.ring.stop()

    def _end_steps(self) -> None:
        """The run ends: the step algorithm's pending foot-flat becomes final and is stored."""
        alg = self.step_algorithm
        if alg is not None and self.ring.logging:
            before = alg.scratch_page_writes
            steps = alg.flush()                  # with the scratch ring's tail written first (a page write)
            self._count_scratch_writes(alg.scratch_page_writes - before)
            self._store_steps(steps)

    def _store_steps(self, steps: OnlineSteps) -> None:
        if steps.n_steps:
            self.log_steps(pack_step_records(steps.to_records(self.ring.header.run_start_sample)))

    def log_samples(self, codes: np.ndarray, marks: np.ndarray | None = None) -> int:
        """Timer ISR for a block of samples: flag, pack and store them; return how many were stored.

        Parameters
        ----------
        codes
            ``(n, 3)`` ADC codes (counts).
        marks
            ``(n,)`` bool: the marker button fired since the previous sample (sets MARK).
        """
        if not self.ring.logging:
            return 0
        c = np.asarray(codes)
        flags = np.zeros(c.shape[0], dtype=np.uint8)
        if marks is not None:
            flags[np.asarray(marks, dtype=bool)] |= FLAG_MARK
        if self._run_first and c.shape[0]:
            flags[0] |= FLAG_SESSION_START
            self._run_first = False
        alg = self.step_algorithm
        if alg is None:
            return self.ring.append(pack_words(c, flags))
        room = self.ring.room_samples
        n = c.shape[0] if room is None else min(c.shape[0], room)
        before = alg.scratch_page_writes
        steps = alg.feed(c[:n])                  # the algorithm sees exactly the samples that are stored
        self._count_scratch_writes(alg.scratch_page_writes - before)
        self._store_steps(steps)
        if room is not None and n == room:       # stop-when-full: this block fills the memory, the run ends
            self._end_steps()
        return self.ring.append(pack_words(c, flags))

    def _count_scratch_writes(self, writes: np.ndarray) -> None:
        """The step algorithm's scratch page writes (per page of its ring, from the run's start) on the step
        EEPROM: each run starts the ring at the page its first sample's number points to (2 bytes a sample, modulo
        the ring), so that short runs do not all wear the ring's first pages."""
        start = scratch_start_page(self.ring.header.run_start_sample)
        self.steps.eeprom.count_page_writes(SCRATCH_FIRST_BYTE // PAGE_BYTES, np.roll(writes, start))

    def log_steps(self, records: bytes) -> int:
        """Store per-step records from the on-line step algorithm (20 bytes each, section 2.3); return how
        many were stored: none unless logging, none without step memory."""
        if not self.ring.logging:
            return 0
        return self.steps.append(records)

    # ------------------------------------------------------------------ settings
    def set_step_config(self, config: StepConfig) -> None:
        """SET_STEP_CONFIG: store the step configuration in the header and commit it (like SET_CALIBRATION).

        An on-line ``step_format`` (1, 2 or 3) turns the algorithm on; the header stores the version this
        firmware runs (:data:`gaitlog.protocol.steps.ONLINE_ALGORITHM_VERSION`), so its records say what wrote them.

        Raises
        ------
        DeviceError
            While logging.
        ProtocolError
            A configuration that cannot be stored (section 2.2).
        """
        if self.ring.logging:
            raise DeviceError("SET_STEP_CONFIG while logging")
        config.to_bytes()  # refuse before changing anything
        self.ring.header.step_config = as_run(config)
        self.ring.commit()

    def erase(self) -> None:
        """ERASE: forget every sample and every per-step record (the calibration and step configuration
        stay); raises :class:`DeviceError` while logging."""
        if self.ring.logging:
            raise DeviceError("ERASE while logging")
        self.steps.erase()
        self.ring.erase()  # commits the header, step counters included

    # ------------------------------------------------------------------ UART
    def reset_link(self) -> None:
        """Forget a partial frame, end a stream and abort an XMODEM transfer (the host went away)."""
        self._rx.clear()
        self._line = b""
        self._xmodem = None
        self._stream = None

    @property
    def streaming(self) -> bool:
        """A DUMP stream has frames left to send."""
        return self._stream is not None

    def transmit(self) -> bytes:
        """The next frame of the stream being sent (``b""`` when none): the UART asks for it as it drains."""
        if self._stream is None:
            return b""
        frame = next(self._stream, b"")
        if not frame:
            self._stream = None
        return frame

    def _end_stream(self) -> None:
        if self._stream is not None:
            self._stream = None
            self.stats["streams_aborted"] += 1

    def poll(self, now_s: float) -> bytes:
        """Apply time-outs at ``now_s``: drop a stale partial frame; XMODEM start/ACK time-outs."""
        if self._rx and now_s - self._last_rx_s > self.inter_byte_timeout_s:
            self._drop_partial()
        if self._xmodem is not None:
            out = self._xmodem.poll(now_s)
            if self._xmodem.finished:
                self._xmodem = None
            return out
        return b""

    def _drop_partial(self) -> None:
        if self._rx.find(SYNC) >= 0:
            self.stats["timeouts"] += 1
        self._rx.clear()

    def receive(self, data: bytes, now_s: float) -> bytes:
        """Bytes from the host arriving at ``now_s`` (seconds, any monotonic clock); return the reply bytes
        (with ``paced`` False also the whole of a stream a command started)."""
        out = self._receive(data, now_s)
        if not self.paced and self._stream is not None:
            out += b"".join(iter(self.transmit, b""))
        return out

    def _receive(self, data: bytes, now_s: float) -> bytes:
        if self._rx and now_s - self._last_rx_s > self.inter_byte_timeout_s:
            self._drop_partial()
        self._last_rx_s = now_s
        data = bytes(data)
        if self._xmodem is not None:
            return self._to_xmodem(data, now_s)
        self._rx += data
        out: list[bytes] = []
        pos = 0
        buf = self._rx
        n = len(buf)
        while pos < n:
            i = buf.find(SYNC, pos)
            hunted = bytes(buf[pos:n if i < 0 else i])
            if hunted:
                combined = self._line + hunted
                k = combined.find(ASCII_XDUMP)
                if k >= 0:  # the ASCII command: what follows it is for the XMODEM sender
                    rest = bytes(buf[pos + k + len(ASCII_XDUMP) - len(self._line):])
                    self._rx.clear()
                    self._line = b""
                    self._arm_xmodem(now_s)
                    return b"".join(out) + (self._to_xmodem(rest, now_s) if rest else b"")
                self._line = combined[-(len(ASCII_XDUMP) - 1):]
            if i < 0:
                pos = n - 1 if buf[n - 1] == SYNC[0] else n
                break
            pos = i
            if n - i < 6:
                break
            ftype, seq = buf[i + 2], buf[i + 3]
            length = buf[i + 4] | (buf[i + 5] << 8)
            if length > MAX_PAYLOAD:
                self.stats["framing_errors"] += 1
                pos = i + 2
                continue
            end = i + FRAME_OVERHEAD + length
            if end > n:
                break
            stored = (buf[end - 2] << 8) | buf[end - 1]
            if crc16_xmodem(bytes(buf[i + 2:end - 2])) != stored:
                self.stats["bad_crc"] += 1
                if ftype in COMMAND_TYPES and length == _PAYLOAD_SIZE[ftype]:
                    out.append(self._nak(ftype, seq, ErrorCode.BAD_CRC))
                pos = i + 2
                continue
            self.stats["frames"] += 1
            self._line = b""
            pos = end
            self._end_stream()  # an intact frame from the host ends a stream after the frame in flight
            out.append(self._command(Frame(ftype, seq, bytes(buf[i + 6:end - 2])), now_s))
            if self._xmodem is not None:  # XDUMP acknowledged: the rest is for the XMODEM sender
                rest = bytes(buf[pos:])
                self._rx.clear()
                if rest:
                    out.append(self._to_xmodem(rest, now_s))
                return b"".join(out)
        del self._rx[:pos]
        return b"".join(out)

    # ------------------------------------------------------------------ XMODEM
    def _arm_xmodem(self, now_s: float) -> None:
        h = self.ring.header
        payload = raw_dump_bytes(h.to_bytes(), self.ring.read_bytes(0, h.used_bytes),
                                 self.steps.read_bytes(0, h.step_used_bytes))
        self._xmodem = XmodemSender(payload)
        self._xmodem.poll(now_s)  # starts the 60 s wait for 'C'

    def _to_xmodem(self, data: bytes, now_s: float) -> bytes:
        assert self._xmodem is not None
        out = self._xmodem.receive(data)
        if not self._xmodem.finished:
            self._xmodem.poll(now_s)
        else:
            self._xmodem = None
        return out

    # ------------------------------------------------------------------ commands
    def _nak(self, command: int, seq: int, error: ErrorCode) -> bytes:
        self.stats["naks"] += 1
        return encode_frame(FrameType.NAK, seq, bytes((command & 0xFF, int(error))))

    def _ack(self, command: int, seq: int) -> bytes:
        return encode_frame(FrameType.ACK, seq, bytes((command,)))

    def _command(self, frame: Frame, now_s: float) -> bytes:
        t, seq = frame.type, frame.seq
        if t not in COMMAND_TYPES:
            return self._nak(t, seq, ErrorCode.UNKNOWN_COMMAND)
        ftype = FrameType(t)
        try:
            fields = parse_payload(frame)
        except PayloadError as err:
            return self._nak(t, seq, err.error_code)
        if ftype in _BUSY_WHEN_LOGGING and self.ring.logging:
            return self._nak(t, seq, ErrorCode.BUSY)
        h = self.ring.header
        if ftype == FrameType.IDENTIFY:
            return encode_frame(FrameType.INFO, seq, build_payload(
                FrameType.INFO, device_id=h.device_id, firmware_version=h.firmware_version,
                protocol_version=WIRE_PROTOCOL_VERSION, adc_bits=h.adc_bits, sampling_rate_millihz=h.sampling_rate_millihz,
                capacity_samples=h.capacity_samples, packing=PACKING_P32, memory_bytes=h.memory_bytes,
            ))
        if ftype == FrameType.GET_STATUS:
            return encode_frame(FrameType.STATUS, seq, build_payload(
                FrameType.STATUS, state=self.state, flags=h.flags, samples_written=h.samples_written,
                write_index=h.write_index,
            ))
        if ftype == FrameType.START:
            try:
                self.start_logging(start_time_s=int(fields["start_time_s"]), overwrite=bool(int(fields["mode"])))
            except MemoryFullError:
                return self._nak(t, seq, ErrorCode.MEMORY_FULL)
            return self._ack(t, seq)
        if ftype == FrameType.STOP:
            self.stop_logging()
            return self._ack(t, seq)
        if ftype == FrameType.ERASE:
            self.erase()
            return self._ack(t, seq)
        if ftype == FrameType.READ_HEADER:
            return encode_frame(FrameType.HEADER, seq, h.to_bytes())
        if ftype == FrameType.READ:
            address, length = int(fields["address"]), int(fields["length"])
            data = self._read(address, length)
            if data is None:
                return self._nak(t, seq, ErrorCode.BAD_ADDRESS)
            return encode_frame(FrameType.DATA, seq, address.to_bytes(4, "little") + data)
        if ftype in (FrameType.DUMP, FrameType.DUMP_CHECKED, FrameType.DUMP_BLOCKS):
            return self._dump(seq, int(fields["address"]), int(fields["length"]), int(fields["chunk"]),
                              checked=ftype == FrameType.DUMP_CHECKED, blocks=ftype == FrameType.DUMP_BLOCKS)
        if ftype == FrameType.ABORT:  # the stream it ends was ended on arrival
            return self._ack(t, seq)
        if ftype == FrameType.XDUMP:
            self._arm_xmodem(now_s)
            return self._ack(t, seq)
        if ftype == FrameType.SET_CALIBRATION:
            self.ring.set_calibration(fields["calibration"])
            return self._ack(t, seq)
        if ftype == FrameType.SET_STEP_CONFIG:
            self.set_step_config(fields["step_config"])
            return self._ack(t, seq)
        raise AssertionError(f"unhandled command {ftype!r}")  # pragma: no cover - table is complete

    def _read(self, address: int, length: int) -> bytes | None:
        """Bytes of a READ/DUMP range: inside the sample memory or inside the step memory; ``None`` if the
        range lies in neither (BAD_ADDRESS)."""
        h = self.ring.header
        where = memory_region(address, length, sample_memory_bytes=h.memory_bytes,
                              step_memory_bytes=self.steps.size_bytes)
        if where is None:
            return None
        region, offset = where
        return self.ring.read_bytes(offset, length) if region == "samples" else self.steps.read_bytes(offset, length)

    def _dump(self, seq: int, address: int, length: int, chunk: int, *, checked: bool, blocks: bool = False
              ) -> bytes:
        """DUMP / DUMP_CHECKED / DUMP_BLOCKS: start the stream of DATA (DATA_BLOCKS) frames of ``chunk`` bytes
        back to back (each followed by its DATA_CRC when ``checked``), then (DUMP_BLOCKS) the HEADER again, then
        DUMP_END (sections 4, 4.1); NAK BAD_ADDRESS at once."""
        h = self.ring.header
        if memory_region(address, length, sample_memory_bytes=h.memory_bytes,
                         step_memory_bytes=self.steps.size_bytes) is None:
            command = FrameType.DUMP_BLOCKS if blocks else FrameType.DUMP_CHECKED if checked else FrameType.DUMP
            return self._nak(command, seq, ErrorCode.BAD_ADDRESS)
        self._stream = self._stream_frames(seq, address, length, chunk, checked, blocks)
        return b""

    def _stream_frames(self, seq: int, address: int, length: int, chunk: int, checked: bool,
                       blocks: bool = False) -> Iterator[bytes]:
        n_frames = 0
        header = self.ring.header.to_bytes()
        binding = header_binding(header)
        for k, off in enumerate(range(0, length, chunk)):
            a = address + off
            data = self._read(a, min(chunk, length - off))
            if blocks:
                yield encode_frame(FrameType.DATA_BLOCKS, k & 0xFF, blocks_payload(binding, a, data))
                n_frames += 1
                continue
            yield encode_frame(FrameType.DATA, k & 0xFF, a.to_bytes(4, "little") + data)
            if checked:
                self.stats["crc32_bytes"] += len(data)
                yield encode_frame(FrameType.DATA_CRC, k & 0xFF, build_payload(FrameType.DATA_CRC, address=a,
                                                                               crc32=crc32(data)))
            n_frames += 1
        if blocks:  # the header travels again, so that one damaged copy does not lose a capture (section 4.1)
            yield encode_frame(FrameType.HEADER, seq, header)
        end = build_payload(FrameType.DUMP_END, address=address, length=length, frames=n_frames & 0xFFFF)
        yield encode_frame(FrameType.DUMP_END, seq, end)
