"""Put the emulated logger on a serial line, in a background thread: the TCP port and what every line shares.

The pseudo-terminal is :mod:`gaitlog.firmware_sim.pty_server` (POSIX only: it needs ``tty``, which Windows lacks).

The device speaks only when spoken to: bytes from the host go to :meth:`Firmware.receive` with the
arrival time (``time.monotonic``), its replies are queued and sent. Nothing is printed; the server gives
its address (:attr:`TcpServer.url`, :attr:`gaitlog.firmware_sim.pty_server.PtyServer.path`) for the caller to show.

Wire time (opt-in): device -> host bytes are released at the real byte time of the UART
(:class:`gaitlog.firmware_sim.uart.UartTiming`, 10 bits per 8N1 byte at the baud the PIC's crystal and SPBRG really
give), scheduled against the monotonic clock (the ``k``-th byte of a burst is released when
``t_burst + k · byte_time`` has passed; the thread wakes every ``tick_s`` and writes what is due), so the
pacing does not drift over a long transfer the way sleeping per byte would. Host -> device bytes are taken
as they come (the host's UART paces them).

Streams: a DUMP's frames are pulled from the firmware (:meth:`Firmware.transmit`) as the outgoing queue
drains below :data:`STREAM_AHEAD_BYTES` (wire time) or :data:`STREAM_AHEAD_FAST_BYTES`, so a command from
the host ends a stream within that many bytes plus the frame in flight, as on the device's UART.

Fault injection (:class:`FaultInjector`, device -> host only): corrupt each byte with probability
``corrupt_rate`` at seeded random positions (XOR with a random non-zero value), and cut the link once after
``cut_after_bytes`` bytes: the rest of the pending output is dropped and the device stays silent until the
host sends again (pty) or the connection is closed (TCP; a new connection works). The firmware forgets a
partial frame or XMODEM transfer at the cut, as it would after a line break.
"""

from __future__ import annotations

import select
import socket
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.uart import UartTiming

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.firmware_sim.device import Logger

__all__ = ["FaultInjector", "TcpServer", "serve_tcp"]

#: Wake-up period of the server thread when bytes are due or waiting, s.
TICK_S = 0.002
#: Wake-up period when idle (firmware time-outs), s.
IDLE_TICK_S = 0.02
#: Default delay between the end of a command and the first reply byte, s. A real line never answers
#: instantly: a host writing to a serial port flushes its input right after the write returns (lrzsz rx
#: does, after each 'C' and ACK) long before the byte has even left; on a pty a reply faster than that
#: would be flushed away.
TURNAROUND_S = 0.002
#: A stream is pulled from the firmware while fewer bytes than this are queued (wire time: 89 ms at 115200
#: baud, far more than a tick, so the line never idles inside a stream) ...
STREAM_AHEAD_BYTES = 1024
#: ... and without wire time (the bytes leave as fast as the peer reads them).
STREAM_AHEAD_FAST_BYTES = 65536


class FaultInjector:
    """Damage on the device -> host direction.

    Parameters
    ----------
    corrupt_rate
        Probability that a byte is corrupted (e.g. 0.001 = one in a thousand).
    seed
        Seed of the positions and values.
    cut_after_bytes
        Cut the link once, after this many device -> host bytes (``None``: never).

    Examples
    --------
    >>> f = FaultInjector(corrupt_rate=0.01, seed=1)
    >>> out, cut = f.apply(bytes(10_000))
    >>> len(out), cut, len(f.corrupted_offsets) == sum(b != 0 for b in out)
    (10000, False, True)
    >>> g = FaultInjector(cut_after_bytes=5)
    >>> g.apply(b"abcdefgh"), g.apply(b"ij")
    ((b'abcde', True), (b'ij', False))
    """

    def __init__(self, *, corrupt_rate: float = 0.0, seed: int = 0, cut_after_bytes: int | None = None) -> None:
        if not 0.0 <= corrupt_rate < 1.0:
            raise DeviceError(f"corrupt_rate must be in [0, 1), got {corrupt_rate}")
        if cut_after_bytes is not None and cut_after_bytes < 0:
            raise DeviceError(f"cut_after_bytes must be >= 0, got {cut_after_bytes}")
        self.corrupt_rate = corrupt_rate
        self.seed = seed
        self.cut_after_bytes = cut_after_bytes
        self._rng = np.random.default_rng(seed)
        self.bytes_seen = 0
        self.corrupted_offsets: list[int] = []
        self.cut_done = False

    def apply(self, data: bytes) -> tuple[bytes, bool]:
        """Return ``(bytes to deliver, cut now)`` for ``data`` about to leave the device."""
        cut = False
        if self.cut_after_bytes is not None and not self.cut_done:
            room = self.cut_after_bytes - self.bytes_seen
            if room < len(data):
                data, cut = data[:max(room, 0)], True
                self.cut_done = True
        if self.corrupt_rate > 0 and data:
            hit = np.flatnonzero(self._rng.random(len(data)) < self.corrupt_rate)
            if hit.size:
                arr = np.frombuffer(data, dtype=np.uint8).copy()
                arr[hit] ^= self._rng.integers(1, 256, hit.size, dtype=np.uint8)
                data = arr.tobytes()
                self.corrupted_offsets.extend((self.bytes_seen + hit).tolist())
        self.bytes_seen += len(data)
        return data, cut


class _Outbox:
    """Device -> host byte queue: released after the turnaround, then at the wire rate (or at once)."""

    def __init__(self, byte_time_s: float | None) -> None:
        self.byte_time_s = byte_time_s
        self.buf = bytearray()
        self.t_next = 0.0  # release time of the next byte (wire time: its completion time)

    def put(self, data: bytes, now: float, *, not_before: float = 0.0) -> None:
        if not data:
            return
        if not self.buf and self.t_next < max(now, not_before):  # the line was idle
            self.t_next = max(now, not_before) + (self.byte_time_s or 0.0)
        self.buf += data

    def due(self, now: float) -> int:
        """Bytes that may be written at ``now``."""
        if not self.buf or now < self.t_next:
            return 0
        if self.byte_time_s is None:
            return len(self.buf)
        return min(len(self.buf), int((now - self.t_next) / self.byte_time_s) + 1)

    def sent(self, k: int) -> None:
        del self.buf[:k]
        if self.byte_time_s is not None:
            self.t_next += k * self.byte_time_s

    def wait_s(self, now: float) -> float:
        """How long the thread may sleep: 0 if bytes are due; in wire time at least one tick (the due
        bytes are then written in one go, ~23 at 115200 baud); the idle tick if nothing is queued."""
        if not self.buf:
            return IDLE_TICK_S
        ahead = self.t_next - now
        if ahead <= 0:
            return 0.0
        if self.byte_time_s is None:
            return min(ahead, IDLE_TICK_S)
        return min(max(ahead, TICK_S), IDLE_TICK_S)

    def clear(self) -> None:
        self.buf.clear()


class LineServer:
    """Common thread loop: read from an fd, feed the firmware, write paced replies."""

    def __init__(self, logger: Logger, *, baud: int, wire_time: bool, faults: FaultInjector | None,
                 fosc_hz: float, save_on_stop: bool, turnaround_s: float = TURNAROUND_S) -> None:
        self.logger = logger
        self.turnaround_s = turnaround_s
        self.uart = UartTiming(baud=baud, fosc_hz=fosc_hz)
        self.wire_time = wire_time
        self.faults = faults
        self.save_on_stop = save_on_stop
        self._out = _Outbox(self.uart.byte_time_s if wire_time else None)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._muted = False
        self.error: BaseException | None = None
        self.bytes_in = 0
        self.bytes_out = 0
        self._ahead = STREAM_AHEAD_BYTES if wire_time else STREAM_AHEAD_FAST_BYTES
        logger.firmware.paced = True

    # -- lifecycle
    def start(self) -> LineServer:
        """Start the background thread (idempotent)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run_guarded, name=type(self).__name__, daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread, close the line, save the logger's image if it has a path."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._close()
        self.logger.firmware.paced = False  # the logger may be used directly again
        if self.save_on_stop and self.logger.image_path is not None:
            self.logger.save_image()

    def __enter__(self) -> LineServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run_guarded(self) -> None:
        try:
            self._run()
        except BaseException as err:  # noqa: BLE001 - reported through .error, the thread must not die silently
            self.error = err

    # -- per-byte-stream handling shared by the transports
    def _on_input(self, data: bytes, now: float) -> None:
        self.bytes_in += len(data)
        self._muted = False
        # the reply cannot start before the command has crossed the line (wire time) and the
        # turnaround (device reaction + host adapter latency) has passed
        inbound = len(data) * self.uart.byte_time_s if self.wire_time else 0.0
        not_before = now + inbound + self.turnaround_s
        self._out.put(self.logger.firmware.receive(data, now), now, not_before=not_before)
        self._refill(now, not_before)

    def _on_tick(self, now: float) -> None:
        self.logger.advance(now)  # a run started over the UART samples in real time
        self._out.put(self.logger.firmware.poll(now), now)
        self._refill(now)

    def _refill(self, now: float, not_before: float = 0.0) -> None:
        """Queue the next frames of a stream while fewer than ``_ahead`` bytes wait."""
        fw = self.logger.firmware
        while fw.streaming and len(self._out.buf) < self._ahead:
            self._out.put(fw.transmit(), now, not_before=not_before)

    def _take_due(self, now: float) -> tuple[bytes, bool]:
        """Bytes to write now (after fault injection) and whether the link is cut."""
        k = self._out.due(now)
        if k == 0:
            return b"", False
        if self._muted:
            self._out.clear()
            return b"", False
        chunk = bytes(self._out.buf[:k])
        self._out.sent(k)
        if self.faults is None:
            return chunk, False
        chunk, cut = self.faults.apply(chunk)
        if cut:
            self._out.clear()
            self._muted = True
            self.logger.firmware.reset_link()
        return chunk, cut

    def _run(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _close(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError


def write_all(fd: int, data: bytes, stop: threading.Event, writer: Callable[[bytes], int]) -> None:
    """Write every byte, waiting while the peer's buffer is full."""
    view = memoryview(data)
    while view and not stop.is_set():
        try:
            n = writer(view)
        except (BlockingIOError, InterruptedError):
            select.select([], [fd], [], 0.05)
            continue
        view = view[n:]


class TcpServer(LineServer):
    """The logger on a TCP port (``socket://host:port`` for pyserial); one client at a time.

    A new connection resets the firmware's receiver (partial frame, XMODEM transfer).
    """

    def __init__(self, logger: Logger, *, host: str = "127.0.0.1", port: int = 0, baud: int = 115200,
                 wire_time: bool = False, faults: FaultInjector | None = None, fosc_hz: float = 18_432_000.0,
                 save_on_stop: bool = True, turnaround_s: float = TURNAROUND_S) -> None:
        super().__init__(logger, baud=baud, wire_time=wire_time, faults=faults, fosc_hz=fosc_hz,
                         save_on_stop=save_on_stop, turnaround_s=turnaround_s)
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.host, self.port = self._listener.getsockname()[:2]
        self.url = f"socket://{self.host}:{self.port}"
        self._client: socket.socket | None = None

    def _drop_client(self) -> None:
        if self._client is not None:
            try:
                self._client.close()
            except OSError:
                pass
        self._client = None
        self._out.clear()
        self.logger.firmware.reset_link()

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            wait = self._out.wait_s(now)
            socks = [self._listener] + ([self._client] if self._client is not None else [])
            try:
                readable, _, _ = select.select(socks, [], [], wait if wait > 0 else 0)
            except (OSError, ValueError):
                return
            now = time.monotonic()
            if self._listener in readable:
                try:
                    conn, _ = self._listener.accept()
                except BlockingIOError:
                    conn = None
                if conn is not None:
                    self._drop_client()
                    conn.setblocking(False)
                    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    self._client = conn
                    self._muted = False
            client = self._client
            if client is not None and client in readable:
                try:
                    data = client.recv(65536)
                except (BlockingIOError, InterruptedError):
                    data = None
                except OSError:
                    data = b""
                if data == b"":
                    self._drop_client()
                    continue
                if data:
                    self._on_input(data, now)
            self._on_tick(now)
            chunk, cut = self._take_due(time.monotonic())
            if self._client is not None and chunk:
                c = self._client
                try:
                    write_all(c.fileno(), chunk, self._stop, c.send)
                    self.bytes_out += len(chunk)
                except OSError:
                    self._drop_client()
                    continue
            if cut:
                self._drop_client()

    def _close(self) -> None:
        self._drop_client()
        try:
            self._listener.close()
        except OSError:
            pass


def serve_tcp(logger: Logger, *, host: str = "127.0.0.1", port: int = 0, baud: int = 115200,
              wire_time: bool = False, faults: FaultInjector | None = None, fosc_hz: float = 18_432_000.0,
              save_on_stop: bool = True, turnaround_s: float = TURNAROUND_S) -> TcpServer:
    """A started :class:`TcpServer` for ``logger`` (``.url`` is ``socket://127.0.0.1:PORT``)."""
    return TcpServer(logger, host=host, port=port, baud=baud, wire_time=wire_time, faults=faults,
                     fosc_hz=fosc_hz, save_on_stop=save_on_stop, turnaround_s=turnaround_s).start()  # type: ignore[return-value]
