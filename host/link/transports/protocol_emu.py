"""pyserial URL handler ``emu://``: the logger emulator, in-process, with deterministic fault injection.

URL grammar::

    emu://[IMAGE_PATH][?option=value&...]

    options (all optional):
      image=PATH       memory image (.glimg) the device starts from (same as IMAGE_PATH); default: an
                       erased device
      seed=N           seed of the fault generator (default 0)
      corrupt=P        probability that a device->host byte is replaced by a different byte
      drop=P           probability that a device->host byte is lost
      insert=P         probability that a random byte is inserted before a device->host byte
      cut_after=N      the line goes dead after N device->host bytes (a pulled cable); later bytes are lost
      h2d_corrupt=P, h2d_drop=P, h2d_insert=P
                       the same faults on the host->device direction (seeded with seed + 1)
      persist=1        save what the link changed back to the image when the port closes, as the EEPROMs
                       keep it (needs an image; like `gaitlog serve --persist`); default 0: the image is
                       left unchanged

Examples: ``emu:///tmp/mem.glimg``, ``emu://?image=/tmp/mem.glimg&corrupt=0.001&seed=3``,
``emu:///tmp/mem.glimg?persist=1``.

The device is ``gaitlog.firmware_sim.device.Logger``; its firmware is sans-I/O (``receive(data, now_s) -> bytes``),
so a :meth:`Serial.write` runs the command handler at once and queues its answer for :meth:`Serial.read`.
The baud rate is accepted and ignored (no wire-time pacing: use ``gaitlog serve --wire-time`` for that).
Faults touch the device->host direction (``corrupt``, ``drop``, ``insert``, ``cut_after``) and the
host->device direction (``h2d_*``) and are reproducible for a given seed and call sequence. A DUMP stream
is pulled from the firmware a few frames ahead of the reader (:meth:`gaitlog.firmware_sim.firmware.Firmware.transmit`),
so a command sent in the middle of a stream ends it as it would on the line.
Use this for tests; never ``loop://`` (a loopback is not a device).
"""

from __future__ import annotations

import time
import urllib.parse

import numpy as np
from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from gaitlog.firmware_sim.device import Logger

_FORM = ('expected "emu://[IMAGE_PATH][?image=PATH&seed=N&corrupt=P&drop=P&insert=P&cut_after=N&persist=0|1'
         '&h2d_corrupt=P&h2d_drop=P&h2d_insert=P]"')
_FLOAT_OPTIONS = ("corrupt", "drop", "insert", "h2d_corrupt", "h2d_drop", "h2d_insert")
#: How far ahead of the reader a stream is pulled from the firmware (bytes).
STREAM_AHEAD_BYTES = 8192
_INT_OPTIONS = ("seed", "cut_after")


class LineFaults:
    """Seeded byte faults on one direction of a serial line.

    Parameters
    ----------
    corrupt, drop, insert
        Per-byte probabilities of replacing a byte by a different one, losing it, and inserting a random
        byte before it.
    cut_after
        Number of bytes after which the line delivers nothing (None: never).
    seed
        Seed of the numpy generator.

    Examples
    --------
    >>> f = LineFaults(corrupt=0.5, seed=1)
    >>> out = f.apply(bytes(1000))
    >>> len(out), 400 < sum(b != 0 for b in out) < 600
    (1000, True)
    >>> LineFaults(cut_after=3).apply(b"abcdef")
    b'abc'
    """

    def __init__(self, *, corrupt: float = 0.0, drop: float = 0.0, insert: float = 0.0,
                 cut_after: int | None = None, seed: int = 0) -> None:
        self.corrupt = corrupt
        self.drop = drop
        self.insert = insert
        self.cut_after = cut_after
        self.seed = seed
        self._rng = np.random.default_rng(seed)
        self.delivered = 0
        self.n_corrupted = 0

    def apply(self, data: bytes) -> bytes:
        """Return ``data`` as it arrives at the other end."""
        if not data:
            return b""
        arr = np.frombuffer(data, dtype=np.uint8)
        if self.corrupt or self.drop or self.insert:
            n = arr.size
            u = self._rng.random((3, n))
            out = arr.copy()
            flip = u[0] < self.corrupt
            if flip.any():
                out[flip] ^= self._rng.integers(1, 256, size=int(flip.sum()), dtype=np.uint8)
                self.n_corrupted += int(flip.sum())
            keep = u[1] >= self.drop
            ins = u[2] < self.insert
            if ins.any():
                extra = self._rng.integers(0, 256, size=n, dtype=np.uint8)
                pieces = np.stack([extra, out], axis=1)
                mask = np.stack([ins, keep], axis=1)
                out = pieces[mask]
            else:
                out = out[keep]
            arr = out
        if self.cut_after is not None:
            room = max(self.cut_after - self.delivered, 0)
            arr = arr[:room]
        self.delivered += arr.size
        return arr.tobytes()


def parse_url(url: str) -> dict:
    """Options of an ``emu://`` URL as a dict (``image``, ``seed``, ``corrupt``, ``drop``, ``insert``,
    ``cut_after``, ``persist``, ``h2d_corrupt``, ``h2d_drop``, ``h2d_insert``); :class:`SerialException` quoting the expected form on anything else.

    Examples
    --------
    >>> parse_url("emu:///tmp/a.glimg?corrupt=0.001&seed=2")["corrupt"]
    0.001
    >>> parse_url("emu://?colour=red")
    Traceback (most recent call last):
    ...
    serial.serialutil.SerialException: emu://?colour=red: unknown option 'colour'; expected "emu://[IMAGE_PATH]...
    """
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "emu":
        raise SerialException(f"{url}: not an emu:// URL; {_FORM}")
    opts: dict = {"image": None, "seed": 0, "corrupt": 0.0, "drop": 0.0, "insert": 0.0, "cut_after": None,
                  "persist": False, "h2d_corrupt": 0.0, "h2d_drop": 0.0, "h2d_insert": 0.0}
    path = urllib.parse.unquote(parts.netloc + parts.path)
    if path:
        opts["image"] = path
    for key, values in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items():
        value = values[-1]
        try:
            if key == "image":
                opts["image"] = value
            elif key in _FLOAT_OPTIONS:
                opts[key] = float(value)
                if not 0.0 <= opts[key] <= 1.0:
                    raise ValueError(f"probability {value} outside 0..1")
            elif key == "persist":
                if value not in ("0", "1"):
                    raise ValueError(f"{value!r} is not 0 or 1")
                opts["persist"] = value == "1"
            elif key in _INT_OPTIONS:
                opts[key] = int(value)
                if opts[key] < 0:
                    raise ValueError(f"{value} is negative")
            else:
                raise SerialException(f"{url}: unknown option {key!r}; {_FORM}")
        except ValueError as err:
            raise SerialException(f"{url}: bad value for {key}: {err}; {_FORM}") from err
    if opts["persist"] and not opts["image"]:
        raise SerialException(f"{url}: persist=1 needs an image to save to; {_FORM}")
    return opts


class Serial(SerialBase):
    """``emu://`` serial port: writes go to the emulated firmware, reads return its (faulted) answers."""

    def __init__(self, *args, **kwargs) -> None:
        self._rx = bytearray()
        self._device = None
        self._faults: LineFaults | None = None
        self._h2d_faults: LineFaults | None = None
        self._t0 = time.monotonic()
        super().__init__(*args, **kwargs)

    # --------------------------------------------------------------------------------------- lifecycle
    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        opts = parse_url(self.portstr)
        try:
            if opts["image"]:
                self._device = Logger.from_image(opts["image"],
                                                 image_path=opts["image"] if opts["persist"] else None)
            else:
                self._device = Logger()
        except (OSError, ValueError) as err:
            raise SerialException(f"{self.portstr}: cannot start the emulated device: {err}") from err
        except Exception as err:  # DeviceError / ProtocolError from a bad image
            if type(err).__name__ in ("DeviceError", "ProtocolError"):
                raise SerialException(f"{self.portstr}: cannot start the emulated device: {err}") from err
            raise
        self._faults = LineFaults(corrupt=opts["corrupt"], drop=opts["drop"], insert=opts["insert"],
                                  cut_after=opts["cut_after"], seed=opts["seed"])
        self._h2d_faults = LineFaults(corrupt=opts["h2d_corrupt"], drop=opts["h2d_drop"], insert=opts["h2d_insert"],
                                      seed=opts["seed"] + 1)
        self._device.firmware.paced = True
        self._t0 = time.monotonic()
        self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        device, self._device = self._device, None
        if self.is_open and device is not None and device.image_path is not None:  # persist=1
            device.save_image()
        self.is_open = False
        super().close()

    @property
    def device(self):
        """The emulated ``gaitlog.firmware_sim.device.Logger`` (for tests)."""
        return self._device

    @property
    def faults(self) -> LineFaults | None:
        """The fault injector of the device->host direction."""
        return self._faults

    @property
    def h2d_faults(self) -> LineFaults | None:
        """The fault injector of the host->device direction."""
        return self._h2d_faults

    def _reconfigure_port(self, *args, **kwargs) -> None:
        """Settings are accepted and ignored (no wire-time pacing in-process)."""

    # ---------------------------------------------------------------------------------------------- I/O
    def _now_s(self) -> float:
        return time.monotonic() - self._t0

    def _pump(self, data: bytes = b"") -> None:
        firmware = self._device.firmware
        out = firmware.receive(bytes(data), self._now_s()) if data else firmware.poll(self._now_s())
        if out:
            self._rx += self._faults.apply(bytes(out))
        while firmware.streaming and len(self._rx) < STREAM_AHEAD_BYTES:
            self._rx += self._faults.apply(firmware.transmit())

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        if not self._rx:
            self._pump()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise PortNotOpenError()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while len(self._rx) < size:
            self._pump()
            if len(self._rx) >= size:
                break
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                time.sleep(min(left, 0.005))
            else:
                time.sleep(0.005)
        out = bytes(self._rx[:size])
        del self._rx[:size]
        return out

    def write(self, data) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        data = to_bytes(data)
        self._pump(self._h2d_faults.apply(bytes(data)) or b"")
        return len(data)

    def reset_input_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self) -> int:
        return 0

    def cancel_read(self) -> None:  # pragma: no cover - nothing blocks for long
        pass

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
