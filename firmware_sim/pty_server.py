"""The emulated logger on a pseudo-terminal (POSIX only: ``tty`` and ``os.openpty`` do not exist on Windows,
which is why this is not in :mod:`gaitlog.firmware_sim.transport`, whose TCP server works everywhere)."""

from __future__ import annotations

import errno
import os
import select
import time
import tty
from typing import TYPE_CHECKING

from gaitlog.firmware_sim.transport import (
    IDLE_TICK_S,
    TURNAROUND_S,
    FaultInjector,
    LineServer,
    write_all,
)

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.firmware_sim.device import Logger

__all__ = ["PtyServer", "serve_pty"]


class PtyServer(LineServer):
    """The logger on a pseudo-terminal; the host opens :attr:`path` like a serial port.

    Both ends are put in raw mode (no echo, no CR/LF translation, no flow control); the server keeps
    its own handle on the terminal side so the pty survives the host closing and reopening it.
    """

    def __init__(self, logger: Logger, *, baud: int = 115200, wire_time: bool = False,
                 faults: FaultInjector | None = None, fosc_hz: float = 18_432_000.0,
                 save_on_stop: bool = True, turnaround_s: float = TURNAROUND_S) -> None:
        super().__init__(logger, baud=baud, wire_time=wire_time, faults=faults, fosc_hz=fosc_hz,
                         save_on_stop=save_on_stop, turnaround_s=turnaround_s)
        self._master, self._slave = os.openpty()
        tty.setraw(self._master)
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)

    def _run(self) -> None:
        fd = self._master
        while not self._stop.is_set():
            now = time.monotonic()
            wait = self._out.wait_s(now)
            try:
                readable, _, _ = select.select([fd], [], [], wait if wait > 0 else 0)
            except (OSError, ValueError):
                return
            now = time.monotonic()
            if readable:
                try:
                    data = os.read(fd, 65536)
                except BlockingIOError:
                    data = b""
                except OSError as err:
                    if err.errno == errno.EIO:  # no terminal side open: wait for one
                        time.sleep(IDLE_TICK_S)
                        continue
                    raise
                if data:
                    self._on_input(data, now)
            self._on_tick(now)
            chunk, _ = self._take_due(time.monotonic())
            if chunk:
                write_all(fd, chunk, self._stop, lambda v: os.write(fd, v))
                self.bytes_out += len(chunk)

    def _close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1


def serve_pty(logger: Logger, *, baud: int = 115200, wire_time: bool = False, faults: FaultInjector | None = None,
              fosc_hz: float = 18_432_000.0, save_on_stop: bool = True, turnaround_s: float = TURNAROUND_S
              ) -> PtyServer:
    """A started :class:`PtyServer` for ``logger`` (use as a context manager, or call ``.stop()``)."""
    return PtyServer(logger, baud=baud, wire_time=wire_time, faults=faults, fosc_hz=fosc_hz,
                     save_on_stop=save_on_stop, turnaround_s=turnaround_s).start()  # type: ignore[return-value]
