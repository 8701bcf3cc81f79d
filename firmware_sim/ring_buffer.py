"""The 65,536-sample ring buffer of P32 words over the EEPROM bank, with its header.

The logging state lives in the PIC's RAM as a :class:`protocol.header.DeviceHeader` (``PROTOCOL.md``
section 2) and is committed to the PIC's data EEPROM at START, STOP, ERASE, SET_CALIBRATION and when a
stop-when-full log fills the memory (only changed bytes are written). Samples are collected in a RAM page
buffer and written one 128-byte EEPROM page (32 samples) at a time; the first page of a run may start
mid-page (after an earlier STOP flushed a partial page), and STOP flushes the partial page.

Full memory: in stop-when-full mode the log stops at ``capacity`` samples (``FULL_STOPPED``); in
overwrite mode the write index wraps and the oldest samples are overwritten (``WRAPPED``).

A block of samples is stored with whole-array operations: the partial first page by one page write,
every full page by one vectorised bank store (split only where the ring wraps), the rest kept in RAM.
"""

from __future__ import annotations

import numpy as np

from firmware_sim.eeprom import PAGE_BYTES, DataEeprom, EepromBank
from firmware_sim.errors import DeviceError
from protocol.header import (
    SAMPLES_WRITTEN_MAX,
    CalibrationSlot,
    DeviceHeader,
    HeaderFlag,
)
from protocol.packing import words_to_bytes

__all__ = ["RingBuffer", "MemoryFullError", "WORDS_PER_PAGE"]

WORDS_PER_PAGE = PAGE_BYTES // 4


class MemoryFullError(DeviceError):
    """START in stop-when-full mode with a full memory (ERASE first)."""


class RingBuffer:
    """Ring of P32 sample words in an :class:`EepromBank`, its header in a :class:`DataEeprom`.

    Parameters
    ----------
    bank
        Sample memory; its size must be ``4 · capacity_samples``.
    data_eeprom
        The PIC's data EEPROM holding the committed header.
    header
        Initial header (device id, versions, rate, ADC bits, calibration ...); its counters are used as
        the current state (a restored image), ``LOGGING`` is cleared.

    Examples
    --------
    >>> rb = RingBuffer(EepromBank(), DataEeprom(), DeviceHeader(capacity_samples=65536))
    >>> rb.start(start_time_s=1000, overwrite=False)
    >>> rb.append(np.arange(40, dtype=np.uint32))
    40
    >>> rb.stop(); h = rb.header
    >>> h.samples_written, h.write_index, h.logging, rb.read_words(0, 3).tolist()
    (40, 40, False, [0, 1, 2])
    """

    def __init__(self, bank: EepromBank, data_eeprom: DataEeprom, header: DeviceHeader) -> None:
        if bank.size_bytes != 4 * header.capacity_samples:
            raise DeviceError(
                f"sample memory of {bank.size_bytes} bytes does not hold {header.capacity_samples} P32 samples"
            )
        self.bank = bank
        self.data_eeprom = data_eeprom
        self.header = header
        self.header.flags &= ~int(HeaderFlag.LOGGING)
        self._pending = np.zeros(0, dtype=np.uint32)  # RAM page buffer
        self._pending_slot = header.write_index  # slot of _pending[0]

    # ------------------------------------------------------------------ state
    @property
    def capacity(self) -> int:
        """Capacity in samples."""
        return int(self.header.capacity_samples)

    @property
    def logging(self) -> bool:
        """A run is in progress."""
        return self.header.logging

    @property
    def room_samples(self) -> int | None:
        """Samples the run can still store before stop-when-full ends it; None in overwrite mode (never
        ends)."""
        if self.header.overwrite:
            return None
        return max(self.capacity - self.header.samples_written, 0)

    @property
    def full(self) -> bool:
        """The memory holds ``capacity`` samples (stop-when-full cannot start)."""
        return self.header.samples_written >= self.capacity

    def _set_flag(self, flag: HeaderFlag, on: bool) -> None:
        self.header.flags = (self.header.flags | int(flag)) if on else (self.header.flags & ~int(flag))

    def commit(self) -> None:
        """Write the header to the data EEPROM (changed bytes only)."""
        self.data_eeprom.write(0, self.header.to_bytes())

    # ------------------------------------------------------------------ commands
    def start(self, *, start_time_s: int, overwrite: bool) -> None:
        """Begin a run: set the mode, start time and the run's first sample number; commit the header.

        Raises
        ------
        DeviceError
            Already logging.
        MemoryFullError
            Stop-when-full mode with a full memory.
        """
        if self.logging:
            raise DeviceError("START while logging")
        if not overwrite and self.full:
            raise MemoryFullError(
                f"memory full ({self.header.samples_written} samples written, capacity {self.capacity}): ERASE first"
            )
        h = self.header
        self._set_flag(HeaderFlag.OVERWRITE, overwrite)
        self._set_flag(HeaderFlag.FULL_STOPPED, False)
        self._set_flag(HeaderFlag.LOGGING, True)
        h.start_time_s = int(start_time_s)
        h.run_start_sample = int(h.samples_written)
        self._pending = np.zeros(0, dtype=np.uint32)
        self._pending_slot = int(h.write_index)
        self.commit()

    def stop(self) -> None:
        """End the run: flush the RAM page buffer, clear ``LOGGING``, commit. No effect when idle."""
        if not self.logging:
            return
        self._flush()
        self._set_flag(HeaderFlag.LOGGING, False)
        self.commit()

    def erase(self) -> None:
        """Forget every sample (counters to 0, flags cleared but ``CAL_VALID``); the EEPROM bytes are
        left as they are (the header says none is meaningful), as the firmware would to avoid 2048 page
        writes. Raises :class:`DeviceError` while logging."""
        if self.logging:
            raise DeviceError("ERASE while logging")
        h = self.header
        h.write_index = 0
        h.samples_written = 0
        h.run_start_sample = 0
        h.start_time_s = 0
        h.flags = 0
        self._pending = np.zeros(0, dtype=np.uint32)
        self._pending_slot = 0
        self.commit()

    def set_calibration(self, calibration: CalibrationSlot) -> None:
        """Store calibration constants in the header slot and commit."""
        if self.logging:
            raise DeviceError("SET_CALIBRATION while logging")
        self.header.calibration = calibration
        self.commit()

    # ------------------------------------------------------------------ samples
    def append(self, words: np.ndarray) -> int:
        """Store a block of P32 words in order; return how many were accepted.

        In stop-when-full mode the block is cut at the capacity, the run stops with ``FULL_STOPPED`` and
        the header is committed. Nothing is accepted when not logging.
        """
        if not self.logging:
            return 0
        w = np.asarray(words, dtype=np.uint32).reshape(-1)
        h = self.header
        cap = self.capacity
        room = self.room_samples
        if room is not None:
            w = w[:room]
        n = int(w.size)
        if n:
            self._store(w)
            h.samples_written = min(h.samples_written + n, SAMPLES_WRITTEN_MAX)
            h.write_index = (h.write_index + n) % cap
            if h.overwrite and h.samples_written >= cap:
                self._set_flag(HeaderFlag.WRAPPED, True)
        if not h.overwrite and h.samples_written >= cap:
            self._flush()
            self._set_flag(HeaderFlag.LOGGING, False)
            self._set_flag(HeaderFlag.FULL_STOPPED, True)
            self.commit()
        return n

    def _store(self, w: np.ndarray) -> None:
        cap = self.capacity
        if w.size > cap:  # only the last `capacity` words survive; keep the page phase of the slots
            drop = (w.size - cap) // cap * cap
            self._account_overwrites(drop)
            w = w[drop:]
        buf = np.concatenate([self._pending, w])
        slot = self._pending_slot
        while buf.size:
            page_end = (slot // WORDS_PER_PAGE + 1) * WORDS_PER_PAGE
            if slot % WORDS_PER_PAGE:  # a partial first page: one page write when it completes
                k = page_end - slot
                if buf.size < k:
                    break
                addr = 4 * slot
                self.bank.page_write(addr, words_to_bytes(buf[:k]), now_s=self.bank.ready_s(addr))
            else:
                k = min(buf.size // WORDS_PER_PAGE * WORDS_PER_PAGE, cap - slot)
                if k == 0:
                    break
                self.bank.write_full_pages(slot // WORDS_PER_PAGE, np.frombuffer(words_to_bytes(buf[:k]), np.uint8))
            buf = buf[k:]
            slot = (slot + k) % cap
        self._pending = buf.copy()
        self._pending_slot = slot

    def _account_overwrites(self, n_words: int) -> None:
        """Whole-memory overwrites inside one huge block: account their page writes without doing them."""
        passes = n_words // self.capacity
        for d in self.bank.devices:
            d.wear += np.uint32(passes)
            d.write_time_s += passes * d.wear.size * d.page_write_time_s

    def _flush(self) -> None:
        """Write the partial RAM page (a page write shorter than 128 bytes, within one page)."""
        if self._pending.size:
            addr = 4 * self._pending_slot
            self.bank.page_write(addr, words_to_bytes(self._pending), now_s=self.bank.ready_s(addr))
            self._pending_slot = (self._pending_slot + self._pending.size) % self.capacity
            self._pending = np.zeros(0, dtype=np.uint32)

    # ------------------------------------------------------------------ reading
    def read_bytes(self, address: int, length: int) -> bytes:
        """Bytes of the sample memory (the EEPROM; the RAM page buffer is flushed at STOP)."""
        return self.bank.read(address, length)

    def read_words(self, first_slot: int, n: int) -> np.ndarray:
        """``n`` words from slot ``first_slot`` (no wrap)."""
        return np.frombuffer(self.bank.read(4 * first_slot, 4 * n), dtype="<u4").astype(np.uint32)

    def words_in_order(self) -> np.ndarray:
        """The stored words, oldest first (the decoder's rule of section 2)."""
        mem = np.frombuffer(self.bank.read(0, self.bank.size_bytes), dtype="<u4").astype(np.uint32)
        return mem[self.header.stored_slots()]
