"""The two header slots of the step EEPROM that make a header commit atomic (``PROTOCOL.md`` section 2.5).

The header lives in the PIC's 256-byte data EEPROM, written byte by byte (~4 ms each): a power loss inside
a header commit (START, STOP, a full memory, ERASE, SET_CALIBRATION, SET_STEP_CONFIG, the commit at
power-up) would leave bytes 0-159 half old, half new, and a header whose CRC fails. So every header commit
first writes the new header bytes 0-159 and its CRC to one of two **header slots** in the step 24LC1025
(the older one: slots alternate), with a sequence number and a slot CRC, and only then the data EEPROM.
At power-up the newest slot whose CRC holds is the header being committed, or the last one committed: when
the data EEPROM's bytes 0-159 and CRC differ from it (a cut inside the data EEPROM write, or after the slot
write and before it), they are rolled forward to it. The journal area (160-253) is never in a slot: it is
written only while logging, outside the header CRC (section 2.4).

A slot is 168 bytes at a page boundary (two page writes):

====== ==== ============ ===============================================================
offset size type         field
====== ==== ============ ===============================================================
0      160  bytes        the header's bytes 0-159
160    2    u16 BE       ``header_crc`` (the header's bytes 254-255)
162    4    u32 LE       ``sequence``: 1, 2, ... over the device's header commits
166    2    u16 BE       ``slot_crc``: CRC-16/XMODEM over slot bytes 0-165
====== ==== ============ ===============================================================

Commit ``sequence`` = s goes to slot ``s mod 2``; the newest valid slot is the valid one with the larger
sequence (serial-number arithmetic mod 2³²; one valid slot: that one; none: a device that never committed
through the slots, whose data EEPROM is then used as it stands). Sequence 0 is never written (a slot of
zeros has a valid CRC): after 0xFFFFFFFE comes 1 (:func:`next_sequence`), which keeps the slots alternating.

Examples
--------
>>> h = bytes(range(256))  # any 256 header bytes: 0-159 and the CRC (254-255) go into the slot
>>> s = slot_bytes(h, sequence=5)
>>> len(s), s[160:168].hex()
(168, 'feff05000000018d')
>>> parse_slot(s) == (h[:160] + h[254:256], 5)
True
>>> torn = bytearray(s); torn[40] ^= 0xFF
>>> parse_slot(bytes(torn)) is None
True
>>> committed = committed_header(b"\\xff" * 256, [b"\\xff" * 168, s])  # the data EEPROM torn to nothing
>>> committed.rolled_forward, committed.header == h[:160] + b"\\xff" * 94 + h[254:256]
(True, True)
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from gaitlog.protocol.commit_journal import JOURNAL_BYTES, JOURNAL_OFFSET
from gaitlog.protocol.crc import crc16_xmodem

__all__ = [
    "SLOT_ADDRESSES",
    "SLOT_BYTES",
    "SLOT_COUNT",
    "CommittedHeader",
    "committed_header",
    "newest_slot",
    "next_sequence",
    "parse_slot",
    "slot_bytes",
    "slot_for",
]

#: Bytes of one slot (header bytes 0-159, the header CRC, the sequence, the slot CRC).
SLOT_BYTES = 168
#: Slots (written alternately).
SLOT_COUNT = 2
#: Byte addresses of the slots in the step 24LC1025: the last two 256-byte page pairs of its second 64 KiB
#: block (the on-line algorithm's scratch ring fills the block from its beginning up to the first slot).
SLOT_ADDRESSES = (0x1FE00, 0x1FF00)
_HEADER_CRC = slice(254, 256)
_SEQ = struct.Struct("<I")


def slot_bytes(header: bytes, *, sequence: int) -> bytes:
    """The 168-byte slot holding ``header`` (256 bytes: bytes 0-159 and its CRC are kept) under ``sequence``."""
    body = bytes(header[:JOURNAL_OFFSET]) + bytes(header[_HEADER_CRC]) + _SEQ.pack(int(sequence) & 0xFFFFFFFF)
    return body + crc16_xmodem(body).to_bytes(2, "big")


def parse_slot(data: bytes) -> tuple[bytes, int] | None:
    """``(header bytes 0-159 + header CRC, sequence)`` of a slot whose CRC holds, else None."""
    data = bytes(data[:SLOT_BYTES])
    if len(data) < SLOT_BYTES or crc16_xmodem(data[:166]) != int.from_bytes(data[166:168], "big"):
        return None
    sequence = _SEQ.unpack_from(data, 162)[0]
    return None if sequence == 0 else (data[:162], sequence)


def next_sequence(sequence: int) -> int:
    """The sequence of the commit after ``sequence`` (0: none yet): 1, 2, …, 0xFFFFFFFE, then 1 again.

    >>> next_sequence(0), next_sequence(41), next_sequence(0xFFFFFFFE)
    (1, 42, 1)
    """
    return int(sequence) + 1 if 0 <= int(sequence) < 0xFFFFFFFE else 1


def slot_for(sequence: int) -> int:
    """Slot (0 or 1) that header commit ``sequence`` goes to."""
    return int(sequence) % SLOT_COUNT


def newest_slot(slots: list[bytes]) -> tuple[bytes, int] | None:
    """The valid slot with the newest sequence (serial-number order mod 2³²), or None when neither holds."""
    good = [p for p in (parse_slot(s) for s in slots) if p is not None]
    if not good:
        return None
    if len(good) == 1:
        return good[0]
    a, b = good
    return b if 0 < (b[1] - a[1]) % (1 << 32) < (1 << 31) else a


@dataclass(frozen=True)
class CommittedHeader:
    """What power-up finds: the 256 header bytes to use, whether they were rolled forward from a slot, and
    the newest slot's sequence (0: no valid slot)."""

    header: bytes
    rolled_forward: bool
    sequence: int


def committed_header(data_eeprom: bytes, slots: list[bytes]) -> CommittedHeader:
    """The committed header from the data EEPROM (256 bytes) and the header slots.

    The newest valid slot wins over the data EEPROM's bytes 0-159 and CRC when they differ (a header commit
    cut after its slot was written); the journal area is the data EEPROM's. Without a valid slot the data
    EEPROM is returned as it stands (its own CRC then decides).
    """
    data_eeprom = bytes(data_eeprom)
    newest = newest_slot(slots)
    if newest is None:
        return CommittedHeader(data_eeprom, False, 0)
    fixed, sequence = newest
    current = data_eeprom[:JOURNAL_OFFSET] + data_eeprom[_HEADER_CRC]
    if current == fixed:
        return CommittedHeader(data_eeprom, False, sequence)
    journal = data_eeprom[JOURNAL_OFFSET:JOURNAL_OFFSET + JOURNAL_BYTES]
    return CommittedHeader(fixed[:JOURNAL_OFFSET] + journal + fixed[JOURNAL_OFFSET:], True, sequence)
