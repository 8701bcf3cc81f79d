"""The raw dump file XDUMP transfers (``PROTOCOL.md`` section 5), with its check trailer.

The file is the 256-byte device header, the used sample memory and the used step memory (the *body*), then
the check trailer twice (64 bytes of 0x1A between the copies, so that a small damaged region cannot hit both),
padded with 0x1A to a multiple of 1024 bytes. The trailer holds one CRC-32 per 256-byte chunk of the body,
bound to the chunk's index, and a copy of the header; it is part of the file the device sends, so any
XMODEM receiver keeps it. A reader that predates the trailer reads the body by the header's counters and
ignores the rest as padding.

A decoder uses a body chunk only when its CRC-32 matches, at its place, at the shift the trailer's position
implies (bytes dropped or inserted before it), or within ±64 bytes of the running shift; a file whose
trailer is lost (cut off, or written before the trailer existed) is read unverified, and says so.

Examples
--------
>>> from gaitlog.protocol.header import DeviceHeader
>>> h = DeviceHeader(capacity_samples=512, samples_written=200, write_index=200)
>>> raw = raw_dump_bytes(h.to_bytes(), bytes(range(200)) * 4)
>>> len(raw), raw.find(TRAILER_MAGIC)
(2048, 1056)
>>> body = parse_raw_dump(raw)
>>> body.verified, bool(body.byte_ok.all()), body.header.samples_written
(True, True, 200)
>>> damaged = raw[:500] + raw[501:]  # one byte dropped in chunk 1
>>> ok = parse_raw_dump(damaged).byte_ok
>>> int(ok.sum()), bool(ok[256:512].any())  # chunk 1 lost, the 800 bytes of the other chunks verified
(800, False)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import construct as cs
import numpy as np

from gaitlog.protocol.crc import crc32
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import HEADER_SIZE, DeviceHeader
from gaitlog.protocol.steps import STEP_RECORD_SIZE
from gaitlog.protocol.xmodem import BLOCK_1K, PAD

__all__ = [
    "CHUNK_BYTES",
    "SHIFTS_NEAREST_FIRST",
    "SHIFT_SEARCH_BYTES",
    "TRAILER_GAP_BYTES",
    "TRAILER_MAGIC",
    "TRAILER_OFFSETS",
    "TRAILER_PREFIX_STRUCT",
    "TRAILER_VERSION",
    "RawDump",
    "build_trailer",
    "chunk_crc32",
    "find_trailer",
    "parse_raw_dump",
    "raw_dump_bytes",
]

TRAILER_MAGIC = b"GLCK"
TRAILER_VERSION = 1
#: Bytes of body per CRC-32 (the last chunk may be shorter).
CHUNK_BYTES = 256
#: 0x1A bytes between the two copies of the trailer.
TRAILER_GAP_BYTES = 64
#: Dropped or inserted bytes are also searched for within this many bytes of the running shift.
SHIFT_SEARCH_BYTES = 64
#: The shifts tried, nearest first (the raw dump's chunks and the image's blocks of versions 1 and 2).
SHIFTS_NEAREST_FIRST = tuple(sorted(range(-SHIFT_SEARCH_BYTES, SHIFT_SEARCH_BYTES + 1), key=lambda x: (abs(x), x)))

#: The fixed start of the trailer; the header copy, the chunk CRCs and ``trailer_crc32`` follow.
TRAILER_PREFIX_STRUCT = cs.Struct(
    "magic" / cs.Bytes(4),
    "trailer_version" / cs.Int8ul,
    "reserved" / cs.Padding(1),
    "chunk_bytes" / cs.Int16ul,
    "body_bytes" / cs.Int32ul,
    "n_chunks" / cs.Int32ul,
)
#: field -> offset in the trailer.
TRAILER_OFFSETS = {"magic": 0, "trailer_version": 4, "chunk_bytes": 6, "body_bytes": 8, "n_chunks": 12,
                   "chunk_crc32": 16}  # then device_header (256) at 16 + 4·n_chunks, then trailer_crc32 (4)


@dataclass(eq=False)
class RawDump:
    """What :func:`parse_raw_dump` recovered.

    Attributes
    ----------
    header
        The device header (from the trailer's verified copy when there is a trailer).
    body
        ``(256 + used_bytes + step_used_bytes,)`` uint8: header, used sample memory, used step memory, as the
        device sent them; bytes not ok are meaningless.
    byte_ok
        Per body byte: verified by its chunk's CRC-32 (trailer present), or present in the file (no trailer:
        then nothing is verified, see ``verified``).
    verified
        The trailer was found: every ok byte is exact. False: the bytes are as the file holds them, unchecked.
    notes
        One line per problem found.
    byte_truncated
        Per body byte: beyond the end of the file (never in it).
    """

    header: DeviceHeader
    body: np.ndarray
    byte_ok: np.ndarray
    verified: bool
    notes: list[str] = field(default_factory=list)
    byte_truncated: np.ndarray | None = None


def chunk_crc32(index: int, chunk: bytes | memoryview) -> int:
    """CRC-32 of body chunk ``index``: over ``index`` (u32 LE), then the chunk's bytes.

    >>> hex(chunk_crc32(0, b""))
    '0x2144df1c'
    """
    return crc32(chunk, crc32(index.to_bytes(4, "little")))


def build_trailer(body: bytes) -> bytes:
    """The check trailer of ``body`` (header, used sample memory, used step memory)."""
    n = -(-len(body) // CHUNK_BYTES)
    view = memoryview(body)
    crcs = b"".join(chunk_crc32(j, view[j * CHUNK_BYTES : (j + 1) * CHUNK_BYTES]).to_bytes(4, "little")
                    for j in range(n))
    out = TRAILER_PREFIX_STRUCT.build(dict(magic=TRAILER_MAGIC, trailer_version=TRAILER_VERSION,
                                           chunk_bytes=CHUNK_BYTES, body_bytes=len(body), n_chunks=n))
    out += crcs + bytes(body[:HEADER_SIZE])
    return out + crc32(out).to_bytes(4, "little")


def raw_dump_bytes(header: bytes, memory_used: bytes, step_memory_used: bytes = b"") -> bytes:
    """The file XDUMP transfers: 256-byte header, then the sample memory from address 0, then the step
    memory from its address 0, then the check trailer twice, padded with 0x1A to a multiple of 1024 bytes.

    Parameters
    ----------
    header
        The 256-byte device header; it says how long the two memory parts are.
    memory_used
        The sample memory up to the end of the last stored sample (``DeviceHeader.used_bytes``; the whole
        memory when wrapped).
    step_memory_used
        The step memory up to the end of the last stored record (``DeviceHeader.step_used_bytes``: ``20 · n``
        for ``n`` stored records; empty without step memory).

    Raises
    ------
    ProtocolError
        A header that is not 256 bytes, or step bytes that are not whole 20-byte records.

    >>> len(raw_dump_bytes(bytes(256), bytes(4 * 300))), len(raw_dump_bytes(bytes(256), bytes(4 * 187), bytes(20)))
    (3072, 2048)
    """
    if len(header) != HEADER_SIZE:
        raise ProtocolError(f"raw dump header of {len(header)} bytes (expected {HEADER_SIZE})")
    if len(step_memory_used) % STEP_RECORD_SIZE:
        raise ProtocolError(f"raw dump step memory of {len(step_memory_used)} bytes is not whole "
                            f"{STEP_RECORD_SIZE}-byte records")
    body = b"".join((bytes(header), bytes(memory_used), bytes(step_memory_used)))
    trailer = build_trailer(body)
    out = b"".join((body, trailer, bytes([PAD]) * TRAILER_GAP_BYTES, trailer))
    return out + bytes([PAD]) * (-len(out) % BLOCK_1K)


@dataclass(frozen=True)
class _Trailer:
    offset: int
    body_bytes: int
    header: DeviceHeader
    crcs: np.ndarray


def find_trailer(data: bytes, source: str | None = None) -> _Trailer | None:
    """The first intact check trailer in ``data`` (its CRC-32 matches and its header copy is valid), or None.

    Raises
    ------
    ProtocolError
        An intact trailer whose fields disagree with its header copy (a writer's error, not damage).
    """
    start = 0
    while True:
        o = data.find(TRAILER_MAGIC, start)
        if o < 0 or o + 16 > len(data):
            return None
        start = o + 1
        p = TRAILER_PREFIX_STRUCT.parse(data[o : o + 16])
        n = int(p.n_chunks)
        hdr_at = o + TRAILER_OFFSETS["chunk_crc32"] + 4 * n
        end = hdr_at + HEADER_SIZE
        if (p.trailer_version != TRAILER_VERSION or p.chunk_bytes != CHUNK_BYTES or end + 4 > len(data)
                or n != -(-int(p.body_bytes) // CHUNK_BYTES)
                or crc32(data[o:end]) != int.from_bytes(data[end : end + 4], "little")):
            continue
        try:
            header = DeviceHeader.from_bytes(data[hdr_at:end], source=source)
        except ProtocolError as err:
            raise err.at(offset=hdr_at) from err
        body_bytes = HEADER_SIZE + header.used_bytes + header.step_used_bytes
        if body_bytes != p.body_bytes:
            raise ProtocolError(f"check trailer: body_bytes {p.body_bytes}, but its device header makes "
                                f"{body_bytes}", offset=o + TRAILER_OFFSETS["body_bytes"], source=source)
        crcs = np.frombuffer(data, dtype="<u4", count=n, offset=o + TRAILER_OFFSETS["chunk_crc32"])
        return _Trailer(o, body_bytes, header, crcs)


def parse_raw_dump(data: bytes | bytearray | memoryview, source: str | None = None) -> RawDump:
    """Parse a raw dump, verifying its body against the check trailer when there is one.

    Raises
    ------
    ProtocolError
        No trailer and no valid device header at offset 0 (or a file shorter than it).
    """
    data = bytes(data)
    trailer = find_trailer(data, source)
    if trailer is None:
        return _unverified(data, source)
    size = trailer.body_bytes
    body = np.full(size, 0xFF, dtype=np.uint8)
    ok = np.zeros(size, dtype=bool)
    truncated = np.zeros(size, dtype=bool)
    view = memoryview(data)
    total = len(data)
    end_shift = trailer.offset - size
    shift = 0
    window = SHIFTS_NEAREST_FIRST
    damaged, moved = [], []
    for j, want in enumerate(trailer.crcs.tolist()):
        start = j * CHUNK_BYTES
        stop = min(start + CHUNK_BYTES, size)
        found = None
        for s in (shift, end_shift, *(shift + d for d in window if d)):
            o = start + s
            if o >= 0 and o + stop - start <= total and chunk_crc32(j, view[o : o + stop - start]) == want:
                found = s
                break
        if found is None:
            if start + shift + stop - start > total and start + end_shift + stop - start > total:
                truncated[start:stop] = True
            else:
                damaged.append(j)
            continue
        if found != shift:
            moved.append((j, found))
        shift = found
        body[start:stop] = np.frombuffer(view[start + shift : stop + shift], dtype=np.uint8)
        ok[start:stop] = True
    view.release()
    notes = [f"raw dump checked by its check trailer at offset {trailer.offset}: "
             f"{int(ok.sum())} of {size} body bytes verified"]
    if damaged:
        notes.append(f"{len(damaged)} body chunk(s) of {CHUNK_BYTES} bytes damaged (CRC-32 mismatch, not found at a "
                     f"shifted offset): chunks {_ranges(damaged)}")
    if truncated.any():
        notes.append(f"body bytes from {int(np.argmax(truncated))} beyond the end of the file ({total} bytes)")
    notes += [f"body chunk {j} found shifted by {s:+d} bytes (bytes dropped or inserted before it)" for j, s in moved]
    return RawDump(trailer.header, body, ok, True, notes, truncated)


def _unverified(data: bytes, source: str | None) -> RawDump:
    """A raw dump without an intact trailer: header at 0 and nothing verified.

    When only padding follows the body (a dump written before the trailer existed) or the file ends inside
    the body (cut off), the body is returned as the file holds it, marked unverified. When other bytes follow
    the body (a damaged trailer, or bytes dropped or inserted), nothing can be trusted: every byte is not ok.
    """
    if len(data) < HEADER_SIZE:
        raise ProtocolError(f"truncated raw dump: {len(data)} bytes, the header alone is {HEADER_SIZE}, and no "
                            "check trailer", offset=len(data), source=source)
    header = DeviceHeader.from_bytes(data[:HEADER_SIZE], source=source)
    size = HEADER_SIZE + header.used_bytes + header.step_used_bytes
    body = np.full(size, 0xFF, dtype=np.uint8)
    got = np.frombuffer(data, dtype=np.uint8)[:size]
    body[: got.size] = got
    ok = np.zeros(size, dtype=bool)
    tail = data[size:]
    if tail.strip(bytes([PAD])):
        return _damaged_trailer(data, header, size, body, source)
    ok[: got.size] = True
    note = ("raw dump without its check trailer (written before raw dumps carried one, or its end was cut off): "
            "its bytes cannot be verified; a damaged or shifted byte would not be detected")
    return RawDump(header, body, ok, False, [note], ~ok)


def _damaged_trailer(data: bytes, header: DeviceHeader, size: int, body: np.ndarray, source: str | None
                     ) -> RawDump:
    """Bytes follow the body but no trailer is intact (damaged or cut inside): each chunk CRC-32 still in the
    file is tried against its chunk at its place (or at the shift the trailer's position implies). An entry is
    bound to its chunk's index, so a match is exact (a damaged entry matching damaged bytes is a 2⁻³² event);
    no wider search is made, since the entries are not checked as a whole."""
    ok = np.zeros(size, dtype=bool)
    o = data.find(TRAILER_MAGIC, max(0, size - 4096))
    n = -(-size // CHUNK_BYTES)
    verified = 0
    if o >= 0:
        view = memoryview(data)
        first = o + TRAILER_OFFSETS["chunk_crc32"]
        for j in range(min(n, max(0, (len(data) - first) // 4))):
            want = int.from_bytes(data[first + 4 * j : first + 4 * j + 4], "little")
            start, stop = j * CHUNK_BYTES, min((j + 1) * CHUNK_BYTES, size)
            for s in dict.fromkeys((0, o - size)):
                a = start + s
                if a >= 0 and a + stop - start <= len(data) and chunk_crc32(j, view[a : a + stop - start]) == want:
                    body[start:stop] = np.frombuffer(view[a : a + stop - start], dtype=np.uint8)
                    ok[start:stop] = True
                    verified += 1
                    break
        view.release()
    note = (f"raw dump whose check trailer is damaged or cut ({len(data) - size} bytes after the {size}-byte body, "
            f"not only padding): {verified} of {n} chunks verified by its entries one by one, the rest reported "
            "missing")
    return RawDump(header, body, ok, True, [note], np.zeros(size, dtype=bool))


def _ranges(indices: list[int]) -> str:
    """'3, 7-9' for [3, 7, 8, 9]."""
    parts, k = [], 0
    while k < len(indices):
        j = k
        while j + 1 < len(indices) and indices[j + 1] == indices[j] + 1:
            j += 1
        parts.append(f"{indices[k]}" if j == k else f"{indices[k]}-{indices[j]}")
        k = j + 1
    return ", ".join(parts)
