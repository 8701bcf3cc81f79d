"""The step store: the ring of per-step records in the third 24LC1025 (``PROTOCOL.md`` section 2.3).

While logging, the firmware's on-line step algorithm produces one 20-byte record per detected foot-flat
(:func:`gaitlog.protocol.steps.pack_step_records` builds them); the step store writes each at slot
``step_write_index`` of a ring of ``step_capacity`` records in the first 64 KiB block of the step EEPROM
(record ``k`` at byte ``20·k``): 2662 in front of the journal ring on header version 3 (section 2.7, the
logger's default), 3276 on header version 2. The ring always overwrites its oldest record: there is no
stop-when-full mode for steps. The second 64 KiB block of that EEPROM is the algorithm's private scratch
ring; the step store never touches it.

The counters ``steps_written`` and ``step_write_index`` live in the header in RAM, shared with the
:class:`~gaitlog.firmware_sim.ring_buffer.RingBuffer`, which commits it to the data EEPROM (at START, STOP, ERASE,
...); ERASE clears them and keeps the step configuration.

Records are written as they come, with real page writes: the bytes of a batch go to consecutive slots and
are split at every 128-byte page boundary and at the end of the ring, so a record that straddles a page
boundary takes two page writes; each page write waits for the end of the previous write cycle
(acknowledge polling), as the ring buffer's do. A record is 20 bytes and comes about twice a second, so
there is no RAM page buffer to flush.
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.eeprom import BLOCK_BYTES, PAGE_BYTES, Eeprom24LC1025
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.steps import (
    STEP_CAPACITY_RECORDS,
    STEP_RECORD_SIZE,
    STEPS_WRITTEN_MAX,
    stored_step_records,
)

__all__ = ["StepStore"]


class StepStore:
    """Ring of per-step records in a 24LC1025, its counters in the device header.

    Parameters
    ----------
    eeprom
        The step EEPROM (the third 24LC1025 on the bus, A1A0 = 10).
    header
        The device header in RAM (the same object as the ring buffer's); ``step_capacity`` records fit the
        ring (0: no step memory, nothing is stored), its counters are the current state.

    Examples
    --------
    Seven records are bytes 0-139: one page write of page 0 (records 0-5 and the first 8 bytes of record 6,
    which straddles the boundary), one of page 1.

    >>> from gaitlog.protocol.steps import empty_step_records, pack_step_records
    >>> store = StepStore(Eeprom24LC1025(), DeviceHeader(step_capacity=3276))
    >>> rec = empty_step_records(7)
    >>> rec["end_sample"] = np.arange(7) * 27
    >>> store.append(pack_step_records(rec))
    7
    >>> store.header.steps_written, store.header.step_write_index, store.eeprom.wear[:3].tolist()
    (7, 7, [1, 1, 0])
    >>> records, ok = store.records_in_order()
    >>> records["end_sample"].tolist(), bool(ok.all())
    ([0, 27, 54, 81, 108, 135, 162], True)
    """

    def __init__(self, eeprom: Eeprom24LC1025, header: DeviceHeader) -> None:
        if not 0 <= header.step_capacity <= STEP_CAPACITY_RECORDS:
            raise DeviceError(f"step_capacity {header.step_capacity}: the step ring holds at most "
                              f"{STEP_CAPACITY_RECORDS} records (one 64 KiB block)")
        self.eeprom = eeprom
        self.header = header

    # ------------------------------------------------------------------ state
    @property
    def capacity(self) -> int:
        """Capacity in records (0: no step memory)."""
        return int(self.header.step_capacity)

    @property
    def size_bytes(self) -> int:
        """Bytes of the ring (``20 · capacity``), the host-addressable step memory."""
        return STEP_RECORD_SIZE * self.capacity

    # ------------------------------------------------------------------ writing
    def append(self, records: bytes | bytearray | memoryview) -> int:
        """Store consecutive 20-byte records in the ring, oldest overwritten; return how many were stored.

        Parameters
        ----------
        records
            ``20 · n`` bytes, as :func:`gaitlog.protocol.steps.pack_step_records` builds them (their CRCs are the
            producer's; the store writes the bytes as they are).

        Raises
        ------
        DeviceError
            A length that is not a multiple of 20.
        """
        data = bytes(records)
        if len(data) % STEP_RECORD_SIZE:
            raise DeviceError(f"step records of {len(data)} bytes: not whole {STEP_RECORD_SIZE}-byte records")
        n = len(data) // STEP_RECORD_SIZE
        if n == 0 or self.capacity == 0:
            return 0
        h = self.header
        pos = 0
        slot = int(h.step_write_index)
        while pos < len(data):  # up to the end of the ring, then from slot 0 again
            k = min(len(data) - pos, STEP_RECORD_SIZE * (self.capacity - slot))
            self._write(STEP_RECORD_SIZE * slot, data[pos:pos + k])
            pos += k
            slot = (slot + k // STEP_RECORD_SIZE) % self.capacity
        h.steps_written = min(int(h.steps_written) + n, STEPS_WRITTEN_MAX)
        h.step_write_index = (int(h.step_write_index) + n) % self.capacity
        return n

    def _write(self, address: int, data: bytes) -> None:
        """Page writes of ``data`` from ``address`` (inside the ring), split at every page boundary."""
        pos = 0
        while pos < len(data):
            a = address + pos
            k = min(len(data) - pos, PAGE_BYTES - a % PAGE_BYTES)
            self.eeprom.page_write(a, data[pos:pos + k], now_s=self.eeprom.busy_until_s)
            pos += k

    def erase(self) -> None:
        """ERASE: forget every record (counters to 0; the bytes stay, as the header says none is meaningful).
        Raises :class:`DeviceError` while logging."""
        if self.header.logging:
            raise DeviceError("ERASE while logging")
        self.header.steps_written = 0
        self.header.step_write_index = 0

    def load(self, data: bytes | np.ndarray) -> None:
        """Replace the ring's bytes (restoring a memory image); wear counters are kept."""
        arr = data.astype(np.uint8) if isinstance(data, np.ndarray) else np.frombuffer(bytes(data), dtype=np.uint8)
        if arr.size != self.size_bytes:
            raise DeviceError(f"step memory image holds {arr.size} bytes, the step ring {self.size_bytes}")
        self.eeprom.memory[:arr.size] = arr

    # ------------------------------------------------------------------ reading
    def read_bytes(self, offset: int, length: int) -> bytes:
        """Bytes of the ring from step-memory offset ``offset`` (one sequential read: the ring lies inside the
        EEPROM's first 64 KiB block)."""
        if length < 0 or not 0 <= offset <= offset + length <= self.size_bytes:
            raise DeviceError(f"step memory read of {length} bytes at {offset} outside 0..{self.size_bytes}")
        assert self.size_bytes <= BLOCK_BYTES
        return self.eeprom.sequential_read(offset, length) if length else b""

    def contents(self) -> bytes:
        """The whole ring (``20 · capacity`` bytes) as the EEPROM holds it."""
        return self.read_bytes(0, self.size_bytes)

    def records_in_order(self) -> tuple[np.ndarray, np.ndarray]:
        """The stored records, oldest first (section 2.3's ring rules), and their CRC verdicts."""
        records, crc_ok, _ = stored_step_records(self.header, self.contents())
        return records, crc_ok
