"""The page-commit journal of a logging run (``PROTOCOL.md`` section 2.4): how much of an interrupted run
survives a power loss.

While logging, the header in the data EEPROM keeps the state of START (``LOGGING`` set, the counters of the
run's first sample); the samples go to the sample EEPROM one 128-byte page at a time. After each page write
has finished (acknowledge polling), the firmware writes one **journal entry** in the 94-byte journal area of
the header (offsets 160-253, outside the header CRC of header version 2): entry ``(m - 1) mod 15`` (6 bytes
at ``160 + 6·k``) gets ``commit`` = ``m`` (u32, the run's m-th page commit, 1, 2, ...) and ``steps`` (u16,
the per-step records the run has stored by then, saturating at 65535). Only changed bytes are written (the
PIC data EEPROM writes a byte in about 4 ms): one or two bytes per page. START first sets every entry to
0xFF (no commit).

A power loss can cut one write: the page in flight (its EEPROM bytes are then undefined) or the journal byte
in flight (its entry is then garbage). The reader therefore takes the largest ``m`` whose entry sits in its
slot (``(m - 1) mod 15``) and whose predecessor ``m - 1`` is also there (or ``m`` = 1): a torn entry can
only claim ``m`` + 1 after the last good ``m``, and then only if its bytes all arrived.

Examples
--------
>>> j = empty_journal()
>>> for m in range(1, 18):
...     j = with_commit(j, m, steps=m // 2)
>>> last_commit(j)
(17, 8)
>>> torn = bytearray(j); torn[6 * (17 % JOURNAL_ENTRIES)] ^= 0x5A   # entry 18 half written: garbage
>>> last_commit(bytes(torn))
(17, 8)
>>> committed_samples(3, first_slot=40, page_samples=32)   # first page 40..63 (24), then 2 x 32
88
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from gaitlog.protocol.steps import STEP_RECORD_SIZE, unpack_step_records

__all__ = ["torn_step_records", "JOURNAL_OFFSET", "JOURNAL_BYTES", "JOURNAL_ENTRIES", "ENTRY_BYTES", "STEPS_SATURATED",
           "empty_journal", "with_commit", "last_commit", "committed_samples", "changed_bytes"]

#: Offset of the journal area in the 256-byte header (header version 2).
JOURNAL_OFFSET = 160
#: Size of the journal area (offsets 160-253).
JOURNAL_BYTES = 94
#: Bytes of one entry: ``commit`` u32, ``steps`` u16, little-endian.
ENTRY_BYTES = 6
#: Entries in the area (15 x 6 = 90 bytes; the last 4 bytes of the area are unused).
JOURNAL_ENTRIES = JOURNAL_BYTES // ENTRY_BYTES
#: ``steps`` of an entry saturates here (the run's step count is then unknown).
STEPS_SATURATED = 0xFFFF
_ENTRY = struct.Struct("<IH")
_NO_COMMIT = 0xFFFFFFFF


def empty_journal() -> bytes:
    """The journal START leaves: every byte 0xFF (no commit)."""
    return b"\xff" * JOURNAL_BYTES


def with_commit(journal: bytes, m: int, *, steps: int) -> bytes:
    """The journal after commit ``m`` (>= 1) with ``steps`` records stored by the run (saturated at 65535)."""
    k = (int(m) - 1) % JOURNAL_ENTRIES
    j = bytearray(journal)
    j[ENTRY_BYTES * k: ENTRY_BYTES * (k + 1)] = _ENTRY.pack(int(m) & 0xFFFFFFFF, min(int(steps), STEPS_SATURATED))
    return bytes(j)


def changed_bytes(old: bytes, new: bytes) -> int:
    """Data EEPROM byte writes from ``old`` to ``new`` (the firmware writes changed bytes only)."""
    return sum(a != b for a, b in zip(old, new))


def _entries(journal: bytes) -> dict[int, int]:
    """commit number -> steps of the entries that sit in their own slot."""
    out = {}
    for k in range(JOURNAL_ENTRIES):
        m, steps = _ENTRY.unpack_from(journal, ENTRY_BYTES * k)
        if m != _NO_COMMIT and m >= 1 and (m - 1) % JOURNAL_ENTRIES == k:
            out[m] = steps
    return out


def last_commit(journal: bytes) -> tuple[int, int]:
    """``(m, steps)`` of the last page commit the journal proves (``(0, 0)``: none).

    The largest ``m`` in its slot whose predecessor is also in its slot (or ``m`` = 1); a torn entry (the
    write in flight at a power loss) never passes unless all its bytes were written.
    """
    e = _entries(bytes(journal[:JOURNAL_BYTES]))
    for m in sorted(e, reverse=True):
        if m == 1 or (m - 1) in e:
            return m, e[m]
    return 0, 0


def committed_samples(m: int, *, first_slot: int, page_samples: int) -> int:
    """Samples of a run made durable by ``m`` page commits when its first sample went to slot ``first_slot``:
    the first commit completes the first page (from ``first_slot`` to the page end), each later one a whole
    page."""
    if m <= 0:
        return 0
    return page_samples - first_slot % page_samples + (m - 1) * page_samples


def torn_step_records(header: Any, step_memory: bytes | np.ndarray, *, limit: int = 255) -> int:
    """Oldest stored step records that a run cut by a power loss overwrote after its last commit (section 2.4).

    The step store writes records as they come, so records stored after the last journal entry are not counted,
    yet they overwrote slots from ``step_write_index`` on, which a wrapped ring counts as its oldest records.
    Record ``end_sample`` numbers grow through the ring from the oldest to the newest, so such a record is told
    by an ``end_sample`` later than the newest counted record's; a record cut in its page write (bad CRC) right
    after them is the one in flight. Returns how many (at most ``limit``); 0 when the ring has not wrapped.
    """
    cap = int(header.step_capacity)
    if not header.steps_wrapped or cap == 0:
        return 0
    rows = np.asarray(np.frombuffer(bytes(step_memory), np.uint8) if not isinstance(step_memory, np.ndarray)
                      else step_memory, np.uint8)[: STEP_RECORD_SIZE * cap].reshape(cap, STEP_RECORD_SIZE)
    first = int(header.step_write_index)
    look = min(limit + 1, cap)
    slots = (first - 1 + np.arange(look + 1)) % cap  # the newest counted record, then the oldest ones
    records, crc_ok = unpack_step_records(rows[slots].reshape(-1))
    newest = int(records["end_sample"][0]) if crc_ok[0] else -1
    if newest < 0:
        return 0
    k, last = 0, newest
    for i in range(1, look + 1):
        if crc_ok[i] and int(records["end_sample"][i]) > last:
            k, last = i, int(records["end_sample"][i])
        else:
            if not crc_ok[i] and k == i - 1 and k > 0:
                k = i  # the record in flight, torn
            break
    return min(k, limit)
