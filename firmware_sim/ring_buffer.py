"""The 65,536-sample ring buffer of P32 words over the EEPROM bank, with its header.

The logging state lives in the PIC's RAM as a :class:`gaitlog.protocol.header.DeviceHeader` (``PROTOCOL.md``
section 2) and is committed to the PIC's data EEPROM at START, STOP, ERASE, SET_CALIBRATION and when a
stop-when-full log fills the memory (only changed bytes are written). Samples are collected in a RAM page
buffer and written one 128-byte EEPROM page (32 samples) at a time; the first page of a run may start
mid-page (after an earlier STOP flushed a partial page), and STOP flushes the partial page.

Full memory: in stop-when-full mode the log stops at ``capacity`` samples (``FULL_STOPPED``); in
overwrite mode the write index wraps and the oldest samples are overwritten (``WRAPPED``).

A block of samples is stored with whole-array operations: the partial first page by one page write,
every full page by one vectorised bank store (split only where the ring wraps), the rest kept in RAM.

Commits and power loss (section 2.4): START increments ``recording_number``, draws ``recording_nonce`` and
clears the page-commit journal; after every page write of the run (each one a *commit*) the journal entry of
that commit is written to the data EEPROM (changed bytes only: the ``steps`` field first, then ``commit``
from its high byte to its low byte). A power loss therefore loses at most the page in flight: at power-up
:meth:`gaitlog.protocol.header.DeviceHeader.recovered` rebuilds the counters of the last committed page.
:meth:`RingBuffer.power_cut` models the cut, including one inside the last page write or journal write.

Header version 3 (section 2.7): the journal is a ring of 96 pages in the step EEPROM (``slot_eeprom``); after
every second page commit one 16-byte entry is written there (one page write), and the data EEPROM is
written by header commits only. A power loss then loses at most two pages.

Header commits (section 2.5): with a slot EEPROM (the step 24LC1025) every commit first writes the new header
bytes 0-159 and CRC to the older of the two header slots there (:mod:`gaitlog.protocol.header_slots`), then the
changed bytes of the data EEPROM; a power loss inside it leaves either the old header or a slot from which
power-up rolls the new one forward. :meth:`RingBuffer.power_cut_header` models a cut at any byte of the last
commit (START's journal clear, the slot's page writes, the data EEPROM bytes).
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.eeprom import PAGE_BYTES, DataEeprom, Eeprom24LC1025, EepromBank
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.protocol.commit_journal import (
    ENTRY_BYTES,
    JOURNAL_ENTRIES,
    JOURNAL_OFFSET,
    empty_journal,
    with_commit,
)
from gaitlog.protocol.header import (
    HEADER_SIZE,
    SAMPLES_WRITTEN_MAX,
    CalibrationSlot,
    DeviceHeader,
    HeaderFlag,
)
from gaitlog.protocol.journal_ring import (
    COMMIT_PAGES,
    ENTRY_BYTES_V3,
    HEADER_VERSION_RING,
    RING_FIRST_BYTE,
    RING_PAGE_BYTES,
    RING_PAGES,
    entry_bytes,
    ring_address,
)
from gaitlog.protocol.header_slots import (
    SLOT_ADDRESSES,
    SLOT_BYTES,
    newest_slot,
    next_sequence,
    slot_bytes,
    slot_for,
)
from gaitlog.protocol.packing import words_to_bytes

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

    def __init__(self, bank: EepromBank, data_eeprom: DataEeprom, header: DeviceHeader, *,
                 slot_eeprom: Eeprom24LC1025 | None = None) -> None:
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
        self._commits = 0  # page commits of the current run
        self._run_steps0 = int(header.steps_written)  # steps_written at START
        self._run_samples0 = int(header.samples_written)
        self._torn0 = (int(header.torn_slots), int(header.torn_step_records))
        #: The last page write of the last store: (address, bytes before it, bytes written, journal before it),
        #: kept for :meth:`power_cut`; None when a sample came after it (nothing in flight).
        self._in_flight: tuple[int, bytes, bytes, bytes] | None = None
        self.slot_eeprom = slot_eeprom
        newest = newest_slot(self._slots()) if slot_eeprom is not None else None
        #: Sequence number of the last header commit through the slots (0: none yet).
        self.slot_sequence = newest[1] if newest is not None else 0
        #: The last header commit, for :meth:`power_cut_header`: (data EEPROM before, data EEPROM after, slot
        #: address, slot before, slot after), or None.
        self._commit_in_flight: tuple[bytes, bytes, int, bytes, bytes] | None = None
        #: Header version 3: the journal-ring entry written after the last page write (address, bytes before,
        #: bytes written), or None (the last page commit wrote no entry).
        self._entry_in_flight: tuple[int, bytes, bytes] | None = None
        if self.ring_journal and slot_eeprom is None:
            raise DeviceError("header version 3 keeps its journal ring in the step EEPROM: none was given")

    @property
    def ring_journal(self) -> bool:
        """The run's journal is the step EEPROM's journal ring (header version 3, section 2.7), not the data
        EEPROM's journal area."""
        return int(self.header.header_version) == HEADER_VERSION_RING

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

    def _slots(self) -> list[bytes]:
        assert self.slot_eeprom is not None
        return [self.slot_eeprom.sequential_read(a, SLOT_BYTES) for a in SLOT_ADDRESSES]

    def commit(self, *, journal: bytes | None = None) -> None:
        """Commit the header (section 2.5): the older header slot (two page writes, acknowledge-polled), then
        the data EEPROM (changed bytes only). ``journal``: START's cleared journal, written to the data EEPROM
        before the slot. Nothing is written when the data EEPROM and the newest slot already hold it."""
        new = self.header.to_bytes()
        before = self.data_eeprom.read()
        if journal is not None:
            self.data_eeprom.write(JOURNAL_OFFSET, journal)
        if self.slot_eeprom is None:
            self.data_eeprom.write(0, new)
            self._commit_in_flight = None
            return
        newest = newest_slot(self._slots())
        fixed = new[:JOURNAL_OFFSET] + new[HEADER_SIZE - 2:]
        current = self.data_eeprom.read()
        if newest is not None and newest[0] == fixed and current[:JOURNAL_OFFSET] + current[HEADER_SIZE - 2:] == fixed \
                and journal is None:
            self._commit_in_flight = None
            return
        self.slot_sequence = next_sequence(self.slot_sequence)
        addr = SLOT_ADDRESSES[slot_for(self.slot_sequence)]
        slot_before = self.slot_eeprom.sequential_read(addr, SLOT_BYTES)
        slot_new = slot_bytes(new, sequence=self.slot_sequence)
        for page in range(0, SLOT_BYTES, PAGE_BYTES):
            self.slot_eeprom.page_write(addr + page, slot_new[page:page + PAGE_BYTES],
                                        now_s=self.slot_eeprom.busy_until_s)
        self.data_eeprom.write(0, new)
        self._commit_in_flight = (before, self.data_eeprom.read(), addr, slot_before, slot_new)

    def header_write_order(self) -> list[tuple[str, int]]:
        """The last header commit's byte writes in order, the range of :meth:`power_cut_header`'s ``at_byte``:
        ``("d", offset)`` a data EEPROM byte, ``("s", i)`` slot byte ``i``. The journal clear first (offsets
        160-253), the slot, then bytes 0-159 and the CRC ascending; empty when there is no commit to cut."""
        if self._commit_in_flight is None:
            return []
        before, after, _, _, _ = self._commit_in_flight
        changed = [i for i in range(HEADER_SIZE) if before[i] != after[i]]
        journal = [("d", i) for i in changed if JOURNAL_OFFSET <= i < HEADER_SIZE - 2]
        rest = [("d", i) for i in changed if not JOURNAL_OFFSET <= i < HEADER_SIZE - 2]
        return journal + [("s", i) for i in range(SLOT_BYTES)] + rest

    def power_cut_header(self, at_byte: int) -> str:
        """The power fails inside the last header commit, at its byte write ``at_byte`` (see
        :meth:`header_write_order`): the writes before it are done, the byte at ``at_byte`` is torn (left
        differing from its new value), the later ones never happen. Returns where the cut fell: ``"journal"``,
        ``"slot"``, ``"data EEPROM"`` or ``"after"`` (``at_byte`` past the end: the commit was complete).
        The RAM state is not touched: power the device up afterwards."""
        if self._commit_in_flight is None or self.slot_eeprom is None:
            return "after"
        before, after, addr, slot_before, slot_after = self._commit_in_flight
        order = self.header_write_order()
        if at_byte >= len(order):
            return "after"
        data = bytearray(before)
        slot = bytearray(slot_before)
        for k, (where, i) in enumerate(order[:at_byte + 1]):
            target, new = (data, after) if where == "d" else (slot, slot_after)
            target[i] = new[i] if k < at_byte else new[i] ^ 0xA5
        self.data_eeprom.memory[:] = np.frombuffer(bytes(data), np.uint8)
        self.slot_eeprom.memory[addr:addr + SLOT_BYTES] = np.frombuffer(bytes(slot), np.uint8)
        where = order[at_byte][0]
        if where == "s":
            return "slot"
        return "journal" if JOURNAL_OFFSET <= order[at_byte][1] < HEADER_SIZE - 2 else "data EEPROM"

    # ------------------------------------------------------------------ commands
    def start(self, *, start_time_s: int, overwrite: bool, nonce: int = 0) -> None:
        """Begin a run: set the mode, start time and the run's first sample number, the next
        ``recording_number`` and the ``nonce`` (32 bits of entropy); clear the journal; commit the header.

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
        self._set_flag(HeaderFlag.POWER_LOST, False)
        h.start_time_s = int(start_time_s)
        h.run_start_sample = int(h.samples_written)
        h.recording_number = (int(h.recording_number) + 1) & 0xFFFFFFFF
        h.recording_nonce = int(nonce) & 0xFFFFFFFF
        h.commit_journal = empty_journal()
        self._pending = np.zeros(0, dtype=np.uint32)
        self._pending_slot = int(h.write_index)
        self._commits = 0
        self._run_steps0 = int(h.steps_written)
        self._run_samples0 = int(h.samples_written)
        self._torn0 = (int(h.torn_slots), int(h.torn_step_records))
        self._in_flight = None
        # the journal first (ignored while LOGGING is clear), then the header with LOGGING set
        self.commit(journal=h.commit_journal)

    def _end_run(self) -> None:
        """The run's samples and records overwrote the first of the torn slots and records."""
        h = self.header
        run_samples = int(h.samples_written) - self._run_samples0
        h.torn_slots = max(0, self._torn0[0] - run_samples)
        h.torn_step_records = max(0, self._torn0[1] - (int(h.steps_written) - self._run_steps0))

    def stop(self) -> None:
        """End the run: flush the RAM page buffer, clear ``LOGGING``, commit. No effect when idle."""
        if not self.logging:
            return
        self._flush()
        self._set_flag(HeaderFlag.LOGGING, False)
        self._end_run()
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
        h.torn_slots = h.torn_step_records = 0
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
            self._end_run()
            self.commit()
        return n

    def _store(self, w: np.ndarray) -> None:
        self._commit_in_flight = None  # a later write: the last header commit is complete
        cap = self.capacity
        commits = 0
        if w.size > cap:  # only the last `capacity` words survive; keep the page phase of the slots
            drop = (w.size - cap) // cap * cap
            self._account_overwrites(drop)
            commits += drop // WORDS_PER_PAGE
            w = w[drop:]
        buf = np.concatenate([self._pending, w])
        slot = self._pending_slot
        last: tuple[int, bytes] | None = None  # the last page write: address, bytes before it
        while buf.size:
            page_end = (slot // WORDS_PER_PAGE + 1) * WORDS_PER_PAGE
            if slot % WORDS_PER_PAGE:  # a partial first page: one page write when it completes
                k = page_end - slot
                if buf.size < k:
                    break
                addr = 4 * slot
                last = (addr, self.bank.read(addr, 4 * k))
                self.bank.page_write(addr, words_to_bytes(buf[:k]), now_s=self.bank.ready_s(addr))
                commits += 1
            else:
                k = min(buf.size // WORDS_PER_PAGE * WORDS_PER_PAGE, cap - slot)
                if k == 0:
                    break
                addr = 4 * (slot + k - WORDS_PER_PAGE)
                last = (addr, self.bank.read(addr, PAGE_BYTES))
                self.bank.write_full_pages(slot // WORDS_PER_PAGE, np.frombuffer(words_to_bytes(buf[:k]), np.uint8))
                commits += k // WORDS_PER_PAGE
            buf = buf[k:]
            slot = (slot + k) % cap
        self._pending = buf.copy()
        self._pending_slot = slot
        if commits:
            journal_before = self._ring_journal(commits) if self.ring_journal else self._journal(commits)
            assert last is not None
            self._in_flight = None if self._pending.size else (
                last[0], last[1], self.bank.read(last[0], len(last[1])), journal_before)
        elif w.size:
            self._in_flight = None  # a sample came after the last page write: nothing in flight

    def _journal(self, commits: int) -> bytes:
        """Write the journal entries of ``commits`` more page commits (section 2.4); return the journal as it
        was before the last one. Only the last 15 entries can survive: the earlier ones are accounted (one
        byte write each, the low byte of ``commit``), the rest written byte by byte as the firmware does."""
        h = self.header
        steps = int(h.steps_written) - self._run_steps0
        first = self._commits + 1
        self._commits += commits
        exact_from = max(first, self._commits - JOURNAL_ENTRIES + 1)
        skipped = exact_from - first
        if skipped:
            per_entry = np.bincount((np.arange(first, exact_from) - 1) % JOURNAL_ENTRIES, minlength=JOURNAL_ENTRIES)
            d = self.data_eeprom
            d.wear[JOURNAL_OFFSET + ENTRY_BYTES * np.arange(JOURNAL_ENTRIES)] += per_entry.astype(np.uint32)
            d.write_time_s += skipped * d.byte_write_time_s
        journal_before = h.commit_journal
        for m in range(exact_from, self._commits + 1):
            journal_before = h.commit_journal
            h.commit_journal = with_commit(h.commit_journal, m, steps=steps)
            k = (m - 1) % JOURNAL_ENTRIES
            entry = h.commit_journal[ENTRY_BYTES * k: ENTRY_BYTES * (k + 1)]
            self.data_eeprom.write(JOURNAL_OFFSET + ENTRY_BYTES * k, entry)
        return journal_before

    def _ring_journal(self, commits: int) -> bytes:
        """Header version 3 (section 2.7): after every second page commit, one 16-byte entry page write to the
        journal ring of the step EEPROM (acknowledge-polled). Only the last 96 entries can survive: the
        earlier ones are accounted (a write cycle of their page each). Returns the data EEPROM journal
        (untouched while logging)."""
        h = self.header
        steps = int(h.steps_written) - self._run_steps0
        first = self._commits + 1
        self._commits += commits
        entries = np.arange(-(-first // COMMIT_PAGES) * COMMIT_PAGES, self._commits + 1, COMMIT_PAGES)
        self._entry_in_flight = None
        if entries.size > RING_PAGES:
            pages = (int(h.recording_number) + entries[:-RING_PAGES] // COMMIT_PAGES - 1) % RING_PAGES
            self.slot_eeprom.count_page_writes(RING_FIRST_BYTE // RING_PAGE_BYTES,
                                               np.bincount(pages, minlength=RING_PAGES))
            entries = entries[-RING_PAGES:]
        for m in entries.tolist():
            addr = ring_address(m, recording_number=h.recording_number)
            before = self.slot_eeprom.sequential_read(addr, ENTRY_BYTES_V3)
            entry = entry_bytes(m, steps=steps, recording_number=h.recording_number,
                                recording_nonce=h.recording_nonce)
            self.slot_eeprom.page_write(addr, entry, now_s=self.slot_eeprom.busy_until_s)
            self._entry_in_flight = (addr, before, entry) if m == self._commits else None
        return h.commit_journal

    def ring_entries(self) -> list[bytes]:
        """The first 16 bytes of every journal-ring page (what power-up reads, section 2.7)."""
        return [self.slot_eeprom.sequential_read(RING_FIRST_BYTE + RING_PAGE_BYTES * k, ENTRY_BYTES_V3)
                for k in range(RING_PAGES)]

    def power_cut(self, at_byte: int | None, *, garbage: int = 0x5A) -> int:
        """The power fails now: what the EEPROMs hold afterwards (the RAM, page buffer included, is lost).

        Parameters
        ----------
        at_byte
            None: between two samples (nothing in flight). Otherwise the cut falls inside the last write, if
            the last sample completed a page (else nothing was in flight and ``at_byte`` is ignored): bytes
            ``0 … len(page) − 1`` count through the page write (the bytes before ``at_byte`` hold their new
            values, the byte at ``at_byte`` is ``garbage``, the rest their old values: a torn page), the next
            ones through the changed bytes of the journal entry, in the order the firmware writes them (torn
            the same way); beyond them the commit was complete.
        garbage
            The value a torn byte is left with.

        Returns
        -------
        int
            Bytes of the interrupted write that reached the EEPROM (``at_byte``, or 0 when nothing was in flight).
        """
        if at_byte is None or self._in_flight is None or not self.logging:
            return 0
        if self.ring_journal:
            return self._power_cut_ring(int(at_byte), garbage)
        addr, old, new, journal_before = self._in_flight
        n_page = len(new)
        journal_after = self.header.commit_journal
        order = _journal_write_order(journal_before, journal_after)
        if at_byte < n_page:
            torn = bytearray(old)
            torn[:at_byte] = new[:at_byte]
            torn[at_byte] = garbage
            self.bank.fault_write(addr, bytes(torn))
            self.data_eeprom.memory[JOURNAL_OFFSET:JOURNAL_OFFSET + len(journal_before)] = np.frombuffer(
                journal_before, np.uint8)
        elif at_byte - n_page < len(order):
            j = at_byte - n_page
            torn = bytearray(journal_before)
            for i in order[:j]:
                torn[i] = journal_after[i]
            torn[order[j]] = garbage
            self.data_eeprom.memory[JOURNAL_OFFSET:JOURNAL_OFFSET + len(torn)] = np.frombuffer(bytes(torn), np.uint8)
        return int(at_byte)

    def _power_cut_ring(self, at_byte: int, garbage: int) -> int:
        """:meth:`power_cut` of header version 3: bytes ``0 … len(page) − 1`` tear the sample page (the
        journal-ring entry after it, if the commit has one, is then not written), the next 16 the entry's page
        write (section 2.7)."""
        assert self._in_flight is not None and self.slot_eeprom is not None
        addr, old, new, _ = self._in_flight
        entry = self._entry_in_flight
        if at_byte < len(new):
            torn = bytearray(old)
            torn[:at_byte] = new[:at_byte]
            torn[at_byte] = garbage
            self.bank.fault_write(addr, bytes(torn))
            if entry is not None:
                self.slot_eeprom.memory[entry[0]:entry[0] + ENTRY_BYTES_V3] = np.frombuffer(entry[1], np.uint8)
        elif entry is not None and at_byte - len(new) < ENTRY_BYTES_V3:
            j = at_byte - len(new)
            torn = bytearray(entry[1])
            torn[:j] = entry[2][:j]
            torn[j] = garbage
            self.slot_eeprom.memory[entry[0]:entry[0] + ENTRY_BYTES_V3] = np.frombuffer(bytes(torn), np.uint8)
        return at_byte

    def in_flight_bytes(self) -> int:
        """Bytes of the last write still in flight if the power failed now (page and journal entry; 0: none)."""
        if self._in_flight is None or not self.logging:
            return 0
        if self.ring_journal:
            return len(self._in_flight[2]) + (ENTRY_BYTES_V3 if self._entry_in_flight is not None else 0)
        return len(self._in_flight[2]) + len(_journal_write_order(self._in_flight[3], self.header.commit_journal))

    def _account_overwrites(self, n_words: int) -> None:
        """Whole-memory overwrites inside one huge block: account their page writes without doing them."""
        passes = n_words // self.capacity
        for d in self.bank.devices:
            d.wear += np.uint32(passes)
            d.write_time_s += passes * d.wear.size * d.page_write_time_s

    def _flush(self) -> None:
        """Write the partial RAM page (a page write shorter than 128 bytes, within one page; STOP commits it
        with the header, so it has no journal entry)."""
        self._in_flight = None
        self._entry_in_flight = None  # the flushed page is in flight now, not the last entry
        self._commit_in_flight = None
        if self._pending.size:
            addr = 4 * self._pending_slot
            data = words_to_bytes(self._pending)
            self._in_flight = (addr, self.bank.read(addr, len(data)), data, self.header.commit_journal)
            self.bank.page_write(addr, data, now_s=self.bank.ready_s(addr))
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


def _journal_write_order(before: bytes, after: bytes) -> list[int]:
    """Journal bytes (offsets in the area) the firmware writes from ``before`` to ``after``, in its order: per
    changed entry, ``steps`` (low, high byte), then ``commit`` from its high byte to its low byte."""
    out = []
    for k in range(JOURNAL_ENTRIES):
        base = ENTRY_BYTES * k
        for i in (4, 5, 3, 2, 1, 0):
            if before[base + i] != after[base + i]:
                out.append(base + i)
    return out
