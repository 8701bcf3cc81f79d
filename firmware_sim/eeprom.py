"""Non-volatile memories of the logger: two 24LC1025 I2C EEPROMs (samples) and the PIC's data EEPROM (header).

24LC1025 (Microchip DS21941), modelled behaviours:

- 128 KiB per device, two devices on the bus: 262,144 bytes of sample memory. A device is two 64 KiB
  blocks (the block select bit B0 of the control byte).
- **Page write**: up to 128 bytes into one page; bytes beyond the end of the page **wrap to the start of
  the same page** (overwriting it), as in the real part. Each page write starts an internal write cycle
  of ``page_write_time_s`` (5 ms max, 3 ms typical) during which the device does not acknowledge; a write
  attempted while busy raises :class:`DeviceError` (the firmware must acknowledge-poll).
- **Sequential read**: the address counter rolls over from the end of a 64 KiB block to the start of the
  **same** block; to read across, the master must re-address (:meth:`EepromBank.read` does, and counts
  its transactions).
- Wear: a write-cycle counter per page (endurance :data:`ENDURANCE_CYCLES`, 1,000,000 cycles): a page write of
  any number of bytes costs its page one cycle (:meth:`Eeprom24LC1025.page_write`, :meth:`write_full_pages`,
  and :meth:`count_page_writes` for the on-line algorithm's scratch ring, whose values its kernel keeps).

PIC16F877 data EEPROM: 256 bytes, erased to 0xFF, written byte by byte (~4 ms each); the firmware
writes only the bytes that change. A write counter per byte.
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.errors import DeviceError

__all__ = ["Eeprom24LC1025", "EepromBank", "DataEeprom", "PAGE_BYTES", "ENDURANCE_CYCLES",
           "DATA_EEPROM_ENDURANCE_CYCLES"]

PAGE_BYTES = 128
BLOCK_BYTES = 65536
DEVICE_BYTES = 131072
#: 24LC1025 endurance: write cycles per page (DS21941: 1,000,000).
ENDURANCE_CYCLES = 1_000_000
#: PIC16F877 data EEPROM endurance: erase/write cycles per byte (DS30292 parameter D120: 100,000 minimum).
DATA_EEPROM_ENDURANCE_CYCLES = 100_000


class Eeprom24LC1025:
    """One 24LC1025: 128 KiB, 128-byte pages, two 64 KiB blocks.

    Parameters
    ----------
    page_write_time_s
        Duration of the internal write cycle after each page write, s.

    Examples
    --------
    >>> e = Eeprom24LC1025()
    >>> e.page_write(120, bytes(range(12)), now_s=0.0)   # 8 bytes to 120..127, 4 wrap to 0..3
    0.005
    >>> e.sequential_read(0, 4).hex(), e.sequential_read(120, 8).hex()
    ('08090a0b', '0001020304050607')
    >>> e.sequential_read(65534, 4) == bytes(e.memory[65534:65536]) + bytes(e.memory[0:2])
    True
    """

    def __init__(self, *, page_write_time_s: float = 0.005) -> None:
        self.page_write_time_s = page_write_time_s
        self.memory = np.full(DEVICE_BYTES, 0xFF, dtype=np.uint8)
        self.wear = np.zeros(DEVICE_BYTES // PAGE_BYTES, dtype=np.uint32)
        self.busy_until_s = -np.inf
        self.write_time_s = 0.0

    def page_write(self, address: int, data: bytes, *, now_s: float) -> float:
        """Write up to 128 bytes starting at ``address``, wrapping within the page; return the time the
        write cycle ends. Raises :class:`DeviceError` if the device is still busy or ``data`` is too long."""
        if not 0 <= address < DEVICE_BYTES:
            raise DeviceError(f"24LC1025 address 0x{address:05x} outside 0..0x1ffff")
        if not 1 <= len(data) <= PAGE_BYTES:
            raise DeviceError(f"24LC1025 page write of {len(data)} bytes (1..{PAGE_BYTES})")
        if now_s < self.busy_until_s:
            raise DeviceError(
                f"24LC1025 busy until t={self.busy_until_s:.6f} s (write cycle); no acknowledge at t={now_s:.6f} s"
            )
        page = address // PAGE_BYTES
        base = page * PAGE_BYTES
        pos = base + (address - base + np.arange(len(data))) % PAGE_BYTES
        self.memory[pos] = np.frombuffer(bytes(data), dtype=np.uint8)
        self.wear[page] += 1
        self.write_time_s += self.page_write_time_s
        self.busy_until_s = now_s + self.page_write_time_s
        return self.busy_until_s

    def write_full_pages(self, first_page: int, data: np.ndarray) -> None:
        """Vectorised store of whole pages (``len(data)`` a multiple of 128) from page ``first_page``; the
        write cycles are accounted (``n_pages · page_write_time_s``) as if ack-polled back to back."""
        n = data.size // PAGE_BYTES
        if data.size % PAGE_BYTES or not 0 <= first_page <= first_page + n <= DEVICE_BYTES // PAGE_BYTES:
            raise DeviceError(f"full-page write of {data.size} bytes at page {first_page} out of range")
        self.memory[first_page * PAGE_BYTES:(first_page + n) * PAGE_BYTES] = data
        self.wear[first_page:first_page + n] += 1
        self.write_time_s += n * self.page_write_time_s

    def count_page_writes(self, first_page: int, writes: np.ndarray) -> None:
        """Account ``writes[i]`` page writes of page ``first_page + i`` whose bytes the emulator keeps elsewhere
        (the on-line algorithm's scratch ring: its kernel holds the values): one write cycle each, and the
        write time, as :meth:`page_write` would.

        >>> e = Eeprom24LC1025()
        >>> e.count_page_writes(512, np.array([2, 1])); e.wear[511:515].tolist(), e.write_time_s
        ([0, 2, 1, 0], 0.015)
        """
        w = np.asarray(writes, np.int64)
        if w.ndim != 1 or (w < 0).any() or not 0 <= first_page <= first_page + w.size <= self.wear.size:
            raise DeviceError(f"{w.size} page write counts from page {first_page} outside 0..{self.wear.size}")
        self.wear[first_page:first_page + w.size] += w.astype(np.uint32)
        self.write_time_s += int(w.sum()) * self.page_write_time_s

    def sequential_read(self, address: int, length: int) -> bytes:
        """Random-address then sequential read of ``length`` bytes; rolls over within the 64 KiB block."""
        if not 0 <= address < DEVICE_BYTES or length < 0:
            raise DeviceError(f"24LC1025 read at 0x{address:05x} length {length} out of range")
        block = address // BLOCK_BYTES * BLOCK_BYTES
        if address + length <= block + BLOCK_BYTES:
            return self.memory[address:address + length].tobytes()
        pos = block + (address - block + np.arange(length)) % BLOCK_BYTES
        return self.memory[pos].tobytes()


class EepromBank:
    """The sample memory: ``n_devices`` 24LC1025 on one I2C bus, addressed as one byte array.

    Examples
    --------
    >>> bank = EepromBank()
    >>> bank.size_bytes, bank.read_transactions
    (262144, 0)
    >>> len(bank.read(65536 - 8, 16)), bank.read_transactions     # crosses a 64 KiB block: re-addressed
    (16, 2)
    """

    def __init__(self, *, n_devices: int = 2, page_write_time_s: float = 0.005) -> None:
        if not 1 <= n_devices <= 4:
            raise DeviceError(f"24LC1025: 1..4 devices on a bus, got {n_devices}")
        self.devices = [Eeprom24LC1025(page_write_time_s=page_write_time_s) for _ in range(n_devices)]
        self.read_transactions = 0

    @property
    def size_bytes(self) -> int:
        """Total sample memory, bytes."""
        return DEVICE_BYTES * len(self.devices)

    @property
    def write_time_s(self) -> float:
        """Total internal write-cycle time spent so far, s."""
        return sum(d.write_time_s for d in self.devices)

    @property
    def wear(self) -> np.ndarray:
        """Write cycles per 128-byte page over the whole bank."""
        return np.concatenate([d.wear for d in self.devices])

    def _split(self, address: int) -> tuple[Eeprom24LC1025, int]:
        dev, off = divmod(address, DEVICE_BYTES)
        return self.devices[dev], off

    def contents(self) -> np.ndarray:
        """A copy of the whole memory, ``uint8``."""
        return np.concatenate([d.memory for d in self.devices])

    def load(self, data: bytes | np.ndarray) -> None:
        """Replace the whole contents (restoring a memory image); wear counters are kept."""
        arr = np.frombuffer(bytes(data), dtype=np.uint8) if not isinstance(data, np.ndarray) else data.astype(np.uint8)
        if arr.size != self.size_bytes:
            raise DeviceError(f"memory image holds {arr.size} bytes, the bank {self.size_bytes}")
        for i, d in enumerate(self.devices):
            d.memory[:] = arr[i * DEVICE_BYTES:(i + 1) * DEVICE_BYTES]

    def page_write(self, address: int, data: bytes, *, now_s: float) -> float:
        """Page write at a bank address (see :meth:`Eeprom24LC1025.page_write`)."""
        if not 0 <= address < self.size_bytes:
            raise DeviceError(f"sample memory address {address} outside 0..{self.size_bytes - 1}")
        dev, off = self._split(address)
        return dev.page_write(off, data, now_s=now_s)

    def ready_s(self, address: int) -> float:
        """Time at which the device holding ``address`` ends its write cycle (acknowledge polling)."""
        return self._split(address)[0].busy_until_s

    def write_full_pages(self, first_page: int, data: np.ndarray) -> None:
        """Vectorised store of whole pages across devices (the firmware's block store)."""
        pages_per_dev = DEVICE_BYTES // PAGE_BYTES
        data = np.asarray(data, dtype=np.uint8).reshape(-1)
        n = data.size // PAGE_BYTES
        if data.size % PAGE_BYTES or not 0 <= first_page <= first_page + n <= pages_per_dev * len(self.devices):
            raise DeviceError(f"full-page write of {data.size} bytes at page {first_page} out of range")
        page, pos = first_page, 0
        while pos < n:  # at most one split per device boundary
            dev, p_in = divmod(page, pages_per_dev)
            k = min(n - pos, pages_per_dev - p_in)
            self.devices[dev].write_full_pages(p_in, data[pos * PAGE_BYTES:(pos + k) * PAGE_BYTES])
            page, pos = page + k, pos + k
        return None

    def fault_write(self, address: int, data: bytes) -> None:
        """Set bytes as a fault leaves them (a page write cut by a power loss): no write cycle, no wear."""
        if not 0 <= address <= address + len(data) <= self.size_bytes:
            raise DeviceError(f"fault write of {len(data)} bytes at {address} outside 0..{self.size_bytes}")
        for i, b in enumerate(bytes(data)):
            dev, off = self._split(address + i)
            dev.memory[off] = b

    def read(self, address: int, length: int) -> bytes:
        """Read ``length`` bytes from a bank address, re-addressing at every 64 KiB block boundary (the
        24LC1025's sequential read would roll over within the block); counts the address transactions."""
        if length < 0 or not 0 <= address <= address + length <= self.size_bytes:
            raise DeviceError(f"read of {length} bytes at {address} outside 0..{self.size_bytes}")
        parts = []
        while length > 0:
            dev, off = self._split(address)
            k = min(length, BLOCK_BYTES - off % BLOCK_BYTES)
            parts.append(dev.sequential_read(off, k))
            self.read_transactions += 1
            address, length = address + k, length - k
        return b"".join(parts)


class DataEeprom:
    """The PIC16F877's 256-byte data EEPROM (erased 0xFF); writes only changed bytes, ~4 ms each.

    >>> d = DataEeprom()
    >>> d.write(0, b"GL"); d.write(0, b"GO")
    >>> d.read(0, 3), d.wear[:2].tolist(), round(d.write_time_s, 3)
    (b'GO\\xff', [1, 2], 0.012)
    """

    SIZE = 256

    def __init__(self, *, byte_write_time_s: float = 0.004) -> None:
        self.byte_write_time_s = byte_write_time_s
        self.memory = np.full(self.SIZE, 0xFF, dtype=np.uint8)
        self.wear = np.zeros(self.SIZE, dtype=np.uint32)
        self.write_time_s = 0.0

    def write(self, offset: int, data: bytes) -> None:
        """Write ``data`` at ``offset`` (bytes that already hold the value are skipped, as firmware does)."""
        if not 0 <= offset <= offset + len(data) <= self.SIZE:
            raise DeviceError(f"data EEPROM write of {len(data)} bytes at {offset} outside 0..{self.SIZE}")
        new = np.frombuffer(bytes(data), dtype=np.uint8)
        cur = self.memory[offset:offset + len(new)]
        changed = cur != new
        self.wear[offset:offset + len(new)] += changed
        self.write_time_s += int(changed.sum()) * self.byte_write_time_s
        cur[:] = new

    def read(self, offset: int = 0, length: int = SIZE) -> bytes:
        """Read ``length`` bytes at ``offset``."""
        if not 0 <= offset <= offset + length <= self.SIZE:
            raise DeviceError(f"data EEPROM read of {length} bytes at {offset} outside 0..{self.SIZE}")
        return self.memory[offset:offset + length].tobytes()
