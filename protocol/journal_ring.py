"""The journal ring of header version 3 (``PROTOCOL.md`` section 2.7): page commits in the step 24LC1025.

Header version 2 writes a journal entry to the PIC's data EEPROM after every sample page (section 2.4);
each entry's low byte is rewritten every 9.6 s, which wears a data EEPROM byte (100,000 cycles) out in
about 33 days of 8 h logging. Header version 3 keeps the data EEPROM for header commits only (START, STOP,
...) and writes the journal to a ring of :data:`RING_PAGES` pages at the end of the step EEPROM's first
64 KiB block (the step ring shrinks to :data:`STEP_CAPACITY_RECORDS_V3` records in front of it).

After every :data:`COMMIT_PAGES`-th page commit ``m`` of a run (m = 2, 4, ...) the firmware writes one
16-byte **entry** at the start of ring page ``(recording_number + m / 2 − 1) mod 96`` (one page write:
the page's write cycle):

====== ==== ======= ==============================================================
offset size type    field
====== ==== ======= ==============================================================
0      4    u32 LE  ``commit``: m, the run's page commits so far (a multiple of 2)
4      2    u16 LE  ``steps``: per-step records the run has stored (saturates at 65535)
6      4    u32 LE  ``recording_number`` of the run (header offset 52)
10     4    u32 LE  ``recording_nonce`` of the run (header offset 56)
14     2    u16 BE  ``entry_crc``: CRC-16/XMODEM over bytes 0-13
====== ==== ======= ==============================================================

Power-up takes, among the entries whose CRC holds, that name the run of the header and sit in their own
page, the one with the largest ``commit`` (``(0, 0)``: none). A cut tears at most the entry in flight (its
CRC then fails, so the previous entry, two pages earlier, stands) or a sample page: at most two pages
(64 samples) after the last entry are lost.

Examples
--------
>>> e = entry_bytes(4, steps=3, recording_number=7, recording_nonce=0x1234ABCD)
>>> e.hex(), ring_page(4, recording_number=7)
('04000000030007000000cdab3412b71f', 8)
>>> ring = [b"\\xff" * 16] * RING_PAGES
>>> ring[8] = e
>>> last_ring_commit(ring, recording_number=7, recording_nonce=0x1234ABCD)
(4, 3)
>>> last_ring_commit(ring, recording_number=8, recording_nonce=0x1234ABCD)   # another run's entry
(0, 0)
"""

from __future__ import annotations

import struct

from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.steps import STEP_RECORD_SIZE

__all__ = ["HEADER_VERSION_RING", "COMMIT_PAGES", "RING_PAGES", "RING_PAGE_BYTES", "RING_FIRST_BYTE",
           "ENTRY_BYTES_V3", "STEP_CAPACITY_RECORDS_V3", "entry_bytes", "parse_entry", "ring_page",
           "ring_address", "last_ring_commit"]

#: The header version whose run journal is this ring (section 2.7).
HEADER_VERSION_RING = 3
#: Sample pages per journal entry: an entry after every second page commit.
COMMIT_PAGES = 2
#: Pages of the ring (12 KiB): 1.05e8 s of logging (10 years at 8 h a day) writes 8.2e7 entries, 855,000 a
#: page, under the 24LC1025's 1,000,000 cycles.
RING_PAGES = 96
#: The 24LC1025's page (bytes).
RING_PAGE_BYTES = 128
_BLOCK_BYTES = 65536
#: Byte address of the ring's first page in the step EEPROM (0xD000: the last 96 pages of block 0).
RING_FIRST_BYTE = _BLOCK_BYTES - RING_PAGES * RING_PAGE_BYTES
#: Records of the step ring in front of the journal ring (2662 x 20 = 53,240 bytes; 8 bytes unused).
STEP_CAPACITY_RECORDS_V3 = RING_FIRST_BYTE // STEP_RECORD_SIZE
#: Bytes of one entry.
ENTRY_BYTES_V3 = 16
_BODY = struct.Struct("<IHII")
_STEPS_SATURATED = 0xFFFF


def entry_bytes(m: int, *, steps: int, recording_number: int, recording_nonce: int) -> bytes:
    """The 16-byte entry of page commit ``m`` with ``steps`` records stored by the run (saturated)."""
    body = _BODY.pack(int(m) & 0xFFFFFFFF, min(int(steps), _STEPS_SATURATED), int(recording_number) & 0xFFFFFFFF,
                      int(recording_nonce) & 0xFFFFFFFF)
    return body + crc16_xmodem(body).to_bytes(2, "big")


def parse_entry(data: bytes) -> tuple[int, int, int, int] | None:
    """``(commit, steps, recording_number, recording_nonce)`` of an entry whose CRC holds, else None."""
    data = bytes(data[:ENTRY_BYTES_V3])
    if len(data) < ENTRY_BYTES_V3 or crc16_xmodem(data[:14]) != int.from_bytes(data[14:16], "big"):
        return None
    return _BODY.unpack_from(data)


def ring_page(m: int, *, recording_number: int) -> int:
    """Ring page (0 … 95) of the entry of page commit ``m`` (a multiple of :data:`COMMIT_PAGES`): each run
    starts one page further on, so short runs do not all wear the first pages."""
    return (int(recording_number) + int(m) // COMMIT_PAGES - 1) % RING_PAGES


def ring_address(m: int, *, recording_number: int) -> int:
    """Step-EEPROM byte address of the entry of page commit ``m``."""
    return RING_FIRST_BYTE + RING_PAGE_BYTES * ring_page(m, recording_number=recording_number)


def last_ring_commit(entries: list[bytes], *, recording_number: int, recording_nonce: int) -> tuple[int, int]:
    """``(m, steps)`` of the run's last journalled page commit from the first 16 bytes of each ring page
    (``entries[k]``: page ``k``), ``(0, 0)`` when the ring holds none of the run's entries."""
    best = (0, 0)
    for k, raw in enumerate(entries):
        e = parse_entry(raw)
        if e is None or (e[2], e[3]) != (int(recording_number) & 0xFFFFFFFF, int(recording_nonce) & 0xFFFFFFFF):
            continue
        m = e[0]
        if m >= COMMIT_PAGES and m % COMMIT_PAGES == 0 and ring_page(m, recording_number=recording_number) == k \
                and m > best[0]:
            best = (m, e[1])
    return best
