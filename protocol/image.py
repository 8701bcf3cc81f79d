"""The memory-image file ``.glimg`` (``PROTOCOL.md`` section 6), with recovery of damaged files.

The file holds the device header and the whole memory region (the sample memory, then the step memory of
section 2.3) checked block by block with CRC-32, so that a decoder returns the intact part of a damaged file
and never a wrong byte. ``image_version`` 3, the version written, frames every block: a sync word, the block
index, its state and a CRC-32 bound to the index and to this file's header, so that a block is found
wherever dropped, inserted or duplicated bytes moved it, a neighbouring block can never pass for it, and the
loss from one damaged region is the blocks that region touches. The prefix and device header are stored
twice (start and end), each copy checked by its own CRC-32.

Versions 1 and 2 (one CRC-32 table in front, not bound to block indices) are still read: a block is used
only when its CRC-32 matches its entry of a table whose own CRC-32 verified, at its place, within ±64 bytes of
the running shift or at the shift the file's length implies (a verified entry is block ``i``'s CRC, so a block
found anywhere with it holds exactly block ``i``'s bytes). With a damaged table no block is used: an entry may
then have moved (bytes dropped or inserted in the table) and hold a neighbour's CRC, and a neighbour moved by
the same number of blocks in the memory would verify in its place; every block is reported missing, and the
notes say why.

Examples
--------
>>> from gaitlog.protocol.header import DeviceHeader
>>> h = DeviceHeader(capacity_samples=512, samples_written=200, write_index=200)
>>> memory = bytes(range(256)) * 8
>>> img = build_image(h, memory, missing_blocks=[1])
>>> len(img), img[:16].hex(" ")
(2632, '47 4c 49 4d 03 00 00 04 00 08 00 00 02 00 00 00')
>>> c = parse_image(img)
>>> c.block_ok.tolist(), c.block_missing.tolist(), bytes(c.memory[:1024]) == memory[:1024]
([True, False], [False, True], True)
>>> c.notes  # block 1 holds none of the 200 stored samples: the logger never wrote it
['block 1 empty (never written by the logger, so not transferred)']
>>> damaged = img[:1000] + img[1001:]  # one byte dropped inside block 0, which holds the 200 samples
>>> import warnings
>>> with warnings.catch_warnings(record=True) as caught:
...     warnings.simplefilter("always")
...     parse_image(damaged).block_ok.tolist()
[False, False]
>>> print(str(caught[0].message)[:79])
memory image: 1 of the 1 blocks holding stored samples are not usable (block 0)
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

import construct as cs
import numpy as np

from gaitlog.protocol.crc import crc32
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import Frame, FrameParser
from gaitlog.protocol.header import HEADER_SIZE, MAX_CAPACITY_SAMPLES, DeviceHeader
from gaitlog.protocol.header import MAGIC as HEADER_MAGIC
from gaitlog.protocol.raw_dump import SHIFT_SEARCH_BYTES, SHIFTS_NEAREST_FIRST, find_trailer
from gaitlog.protocol.steps import STEP_MEMORY_BYTES, STEP_RECORD_SIZE, stored_step_records

__all__ = [
    "BLOCK_MISSING",
    "BLOCK_PRESENT",
    "BLOCK_SYNC",
    "DEFAULT_BLOCK_SIZE",
    "FRAME_OVERHEAD_BYTES",
    "IMAGE_MAGIC",
    "IMAGE_OFFSETS",
    "IMAGE_PREFIX_STRUCT",
    "IMAGE_VERSION",
    "IMAGE_VERSION_FRAMED",
    "IMAGE_VERSION_STEPS",
    "PREAMBLE_BYTES",
    "SHIFT_SEARCH_BYTES",
    "ImageContents",
    "build_image",
    "detect_format",
    "frame_crc32",
    "image_memory_bytes",
    "image_version_for",
    "parse_image",
]

IMAGE_MAGIC = b"GLIM"
#: Image of a device without step memory (``step_capacity`` 0): the memory region is the sample memory.
IMAGE_VERSION = 1
#: Image of a device with step memory: the memory region is the sample memory, then the step memory.
IMAGE_VERSION_STEPS = 2
#: Framed image (the version written): every block carries its index, state and a CRC-32 bound to both and to
#: the file's header; the prefix and header are stored at the start and again at the end.
IMAGE_VERSION_FRAMED = 3
DEFAULT_BLOCK_SIZE = 1024
#: Start of every block frame of version 3.
BLOCK_SYNC = b"GLBK"
#: Version 3: prefix (16) + device header (256) + ``preamble_crc32`` (4), at the start and at the end.
PREAMBLE_BYTES = 16 + HEADER_SIZE + 4
#: Version 3: sync (4) + block_index (4) + state (1) + reserved (3) before the data, block_crc32 (4) after.
FRAME_OVERHEAD_BYTES = 16
BLOCK_PRESENT = 0
BLOCK_MISSING = 1
#: Largest ``memory_bytes`` of each image version.
_MAX_MEMORY_BYTES = {IMAGE_VERSION: 4 * MAX_CAPACITY_SAMPLES,
                     IMAGE_VERSION_STEPS: 4 * MAX_CAPACITY_SAMPLES + STEP_MEMORY_BYTES,
                     IMAGE_VERSION_FRAMED: 4 * MAX_CAPACITY_SAMPLES + STEP_MEMORY_BYTES}
_CAPTURE_PROBE_BYTES = 65536

#: The fixed 16-byte start of the file.
IMAGE_PREFIX_STRUCT = cs.Struct(
    "magic" / cs.Bytes(4),
    "image_version" / cs.Int8ul,
    "reserved" / cs.Padding(1),
    "block_size" / cs.Int16ul,
    "memory_bytes" / cs.Int32ul,
    "n_blocks" / cs.Int32ul,
)
#: field -> offset of the prefix fields (versions 1 and 2: the block table follows at 16).
IMAGE_OFFSETS = {"magic": 0, "image_version": 4, "block_size": 6, "memory_bytes": 8, "n_blocks": 12,
                 "block_crc32": 16}
#: field -> offset of the version-3 preamble fields after the prefix, and of the fields of a block frame.
PREAMBLE_OFFSETS = {"device_header": 16, "preamble_crc32": 16 + HEADER_SIZE}
FRAME_OFFSETS = {"sync": 0, "block_index": 4, "state": 8, "data": 12}


@dataclass(eq=False)
class ImageContents:
    """What :func:`parse_image` recovered.

    Attributes
    ----------
    header
        The validated device header.
    memory
        ``(4 · capacity_samples,)`` ``uint8`` sample memory; bytes of blocks that are not ok are 0xFF and
        meaningless (:meth:`byte_ok`).
    block_ok
        ``(n_blocks,)`` bool: the block's bytes are exact (CRC-32 verified). ``False`` => its samples (and step
        records) are missing. Blocks cover the sample memory followed by the step memory.
    block_size
        Bytes per block (the last block may be shorter).
    notes
        One line per problem found (damaged, shifted, missing, truncated blocks; table damage).
    block_missing
        ``(n_blocks,)`` bool: marked missing in the file: not received by the dump, or holding nothing stored
        (never written by the logger, so never read; the notes call those empty).
    block_truncated
        ``(n_blocks,)`` bool: beyond the end of a truncated file.
    block_shift
        ``(n_blocks,)`` int: shift in bytes (found − nominal offset) of each ok block; 0 elsewhere.
    table_ok
        The block table's CRC-32 matched.
    step_memory
        ``(20 · step_capacity,)`` ``uint8`` step memory; bytes of blocks that are not ok are 0xFF and
        meaningless (:meth:`step_byte_ok`). An ``image_version`` 1 file holds no step memory: empty when its
        header has none, all 0xFF and not ok when it has (a file written by a host older than the step
        memory).
    image_version
        1 (sample memory only), 2 (sample memory, then step memory, one CRC table) or 3 (the memory region in
        framed blocks, each checked by a CRC-32 bound to its index and to the header).
    """

    header: DeviceHeader
    memory: np.ndarray
    block_ok: np.ndarray
    block_size: int
    notes: list[str] = field(default_factory=list)
    block_missing: np.ndarray | None = None
    block_truncated: np.ndarray | None = None
    block_shift: np.ndarray | None = None
    table_ok: bool = True
    step_memory: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint8))
    image_version: int = IMAGE_VERSION

    @property
    def n_blocks(self) -> int:
        """Number of blocks."""
        return int(self.block_ok.size)

    def _region_ok(self) -> np.ndarray:
        """Per byte of the sample memory followed by the step memory: it belongs to an ok block (bytes not in
        the file's memory region, the step memory of a version-1 file, are never ok)."""
        size = self.memory.size + self.step_memory.size
        ok = np.repeat(self.block_ok, self.block_size)[:size]
        return ok if ok.size == size else np.concatenate([ok, np.zeros(size - ok.size, dtype=bool)])

    def byte_ok(self) -> np.ndarray:
        """``(4 · capacity_samples,)`` bool: the sample-memory byte belongs to an ok block."""
        return self._region_ok()[: self.memory.size]

    def step_byte_ok(self) -> np.ndarray:
        """``(20 · step_capacity,)`` bool: the step-memory byte belongs to an ok block (never, in a
        version-1 file: it holds no step memory)."""
        return self._region_ok()[self.memory.size:]

    def step_records(self) -> tuple[np.ndarray, np.ndarray]:
        """The stored per-step records in ring order (oldest first) and whether each is usable.

        Returns
        -------
        records : numpy.ndarray
            ``(n_steps_stored,)`` of :data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`; record ``i`` has the absolute
            number ``header.first_step_number + i``.
        ok : numpy.ndarray
            ``(n_steps_stored,)`` bool: all 20 bytes come from ok blocks and the record's CRC matches.
        """
        records, crc_ok, slots = stored_step_records(self.header, self.step_memory)
        bytes_ok = self.step_byte_ok().reshape(-1, STEP_RECORD_SIZE)[slots].all(axis=1)
        return records, crc_ok & bytes_ok


def _check_block_size(block_size: int, memory_bytes: int, source: str | None = None,
                      image_version: int = IMAGE_VERSION) -> None:
    if not (64 <= block_size <= 65532 and block_size % 4 == 0):
        raise ProtocolError(f"block_size {block_size} (expected a multiple of 4 in 64..65532, normally 1024)",
                            offset=IMAGE_OFFSETS["block_size"], source=source)
    top = _MAX_MEMORY_BYTES[image_version]
    if not (4 <= memory_bytes <= top and memory_bytes % 4 == 0):
        raise ProtocolError(f"memory_bytes {memory_bytes} (expected a multiple of 4 in 4..{top})",
                            offset=IMAGE_OFFSETS["memory_bytes"], source=source)


def image_version_for(header: DeviceHeader) -> int:
    """The ``image_version`` of the unframed layout (1 or 2) a device's image had before version 3: 2 when its
    header has step memory (``step_capacity`` > 0), else 1. :func:`build_image` writes version 3 unless asked
    for one of these."""
    return IMAGE_VERSION_STEPS if header.step_capacity > 0 else IMAGE_VERSION


def frame_crc32(preamble_crc32: int, block_index: int, state: int, data: bytes | memoryview) -> int:
    """``block_crc32`` of a version-3 block frame: CRC-32 over the file's ``preamble_crc32`` (4 bytes LE), then
    the frame's bytes 4 .. end of data (``block_index``, ``state``, reserved, data).

    The first term binds the block to this file's prefix and header, the second to its index: a block of
    another image, or the neighbouring block, can never verify in its place.

    >>> frame_crc32(0, 0, 0, b"") == crc32(bytes(12)), frame_crc32(7, 1, 0, b"x") == frame_crc32(7, 2, 0, b"x")
    (True, False)
    """
    crc = crc32(preamble_crc32.to_bytes(4, "little"))
    return crc32(data, crc32(block_index.to_bytes(4, "little") + bytes((state, 0, 0, 0)), crc))


def image_memory_bytes(header: DeviceHeader) -> int:
    """Bytes of the image's memory region: ``4 · capacity_samples + 20 · step_capacity``."""
    return header.memory_bytes + header.step_memory_bytes


def _as_bytes(data: bytes | bytearray | memoryview | np.ndarray) -> bytes:
    return np.asarray(data, dtype=np.uint8).tobytes() if isinstance(data, np.ndarray) else bytes(data)


def build_image(header: bytes | DeviceHeader, memory: bytes | bytearray | memoryview | np.ndarray,
                missing_blocks: Iterable[int] = (), block_size: int = DEFAULT_BLOCK_SIZE, *,
                step_memory: bytes | bytearray | memoryview | np.ndarray | None = None,
                image_version: int | None = None) -> bytes:
    """Bytes of a ``.glimg`` file (``image_version`` 3; an older version on request).

    Parameters
    ----------
    header
        The device header (a :class:`DeviceHeader` or its 256 bytes, validated).
    memory
        The whole sample memory: ``4 · capacity_samples`` bytes. Without ``step_memory``, a header with step
        memory needs the whole memory region here: the sample memory followed by the step memory
        (``4 · capacity_samples + 20 · step_capacity`` bytes).
    missing_blocks
        Indices of blocks never received; their bytes are stored as 0xFF and their state as 1 (in versions 1
        and 2 their ``block_crc32`` is the complement of the CRC-32 of those bytes, so that they can never
        verify; in version 3 the state is covered by the block's CRC-32).
    block_size
        Bytes per block.
    step_memory
        The whole step memory (``20 · step_capacity`` bytes of the header), when ``memory`` is the sample
        memory alone.
    image_version
        None (3, framed blocks), or the version a host older than version 3 wrote for this header
        (:func:`image_version_for`: 1 or 2), for tests and for comparisons with old files.

    Raises
    ------
    ProtocolError
        Invalid header, memory of the wrong size, bad block size or block index, an unknown version.
    """
    hdr = header if isinstance(header, DeviceHeader) else DeviceHeader.from_bytes(bytes(header))
    hbytes = hdr.to_bytes()
    mem = bytearray(_as_bytes(memory))
    if step_memory is not None:
        steps = _as_bytes(step_memory)
        if len(mem) != hdr.memory_bytes or len(steps) != hdr.step_memory_bytes:
            raise ProtocolError(f"sample memory of {len(mem)} bytes and step memory of {len(steps)} bytes, but the "
                                f"header's capacities of {hdr.capacity_samples} samples and {hdr.step_capacity} "
                                f"step records need {hdr.memory_bytes} and {hdr.step_memory_bytes}")
        mem += steps
    elif len(mem) != image_memory_bytes(hdr):
        needs = (f"{hdr.memory_bytes}" if not hdr.step_capacity else
                 f"{image_memory_bytes(hdr)} (with the {hdr.step_memory_bytes}-byte step memory of its "
                 f"{hdr.step_capacity} step records; or pass step_memory)")
        raise ProtocolError(f"memory of {len(mem)} bytes, but the header's capacity of {hdr.capacity_samples} "
                            f"samples needs {needs}")
    version = IMAGE_VERSION_FRAMED if image_version is None else int(image_version)
    if version != IMAGE_VERSION_FRAMED and version != image_version_for(hdr):
        raise ProtocolError(f"image_version {version}: this writer writes {IMAGE_VERSION_FRAMED}, or the old "
                            f"{image_version_for(hdr)} for this header")
    _check_block_size(int(block_size), len(mem), image_version=version)
    n = -(-len(mem) // block_size)
    states = np.zeros(n, dtype=np.uint8)
    for b in missing_blocks:
        if not 0 <= int(b) < n:
            raise ProtocolError(f"missing block {b} outside 0..{n - 1}")
        states[int(b)] = BLOCK_MISSING
        mem[int(b) * block_size : (int(b) + 1) * block_size] = b"\xff" * len(
            mem[int(b) * block_size : (int(b) + 1) * block_size])
    view = memoryview(mem)
    prefix = IMAGE_PREFIX_STRUCT.build(dict(magic=IMAGE_MAGIC, image_version=version,
                                            block_size=block_size, memory_bytes=len(mem), n_blocks=n))
    if version == IMAGE_VERSION_FRAMED:
        preamble = prefix + hbytes
        key = crc32(preamble)
        preamble += key.to_bytes(4, "little")
        frames = []
        for i in range(n):
            data = view[i * block_size : (i + 1) * block_size]
            state = int(states[i])
            frames += [BLOCK_SYNC, i.to_bytes(4, "little"), bytes((state, 0, 0, 0)), data,
                       frame_crc32(key, i, state, data).to_bytes(4, "little")]
        return b"".join([preamble, *frames, preamble])
    crcs = np.array([crc32(view[i * block_size : (i + 1) * block_size]) for i in range(n)], dtype="<u4")
    crcs[states == BLOCK_MISSING] ^= np.uint32(0xFFFFFFFF)
    table = prefix + crcs.tobytes() + states.tobytes()
    return b"".join((table, crc32(table).to_bytes(4, "little"), hbytes, bytes(mem)))


def _blocks(indices: np.ndarray) -> str:
    """'block 3' or 'blocks 3, 7-9'."""
    return ("block " if len(indices) == 1 else "blocks ") + _ranges(indices)


def _ranges(indices: np.ndarray) -> str:
    """'3, 7-9' for [3, 7, 8, 9]."""
    idx = [int(i) for i in indices]
    parts, k = [], 0
    while k < len(idx):
        j = k
        while j + 1 < len(idx) and idx[j + 1] == idx[j] + 1:
            j += 1
        parts.append(f"{idx[k]}" if j == k else f"{idx[k]}-{idx[j]}")
        k = j + 1
    return ", ".join(parts)


def _find_header(data: bytes, nominal: int, source: str | None) -> tuple[DeviceHeader, int]:
    """The device header at ``nominal`` or, failing that, the nearest valid one within the search window."""
    try:
        return DeviceHeader.from_bytes(data[nominal : nominal + HEADER_SIZE], source=source), 0
    except ProtocolError as exc:
        first_error = exc.at(offset=nominal)
    for d in SHIFTS_NEAREST_FIRST:
        o = nominal + d
        if d == 0 or o < 0 or data[o : o + 4] != HEADER_MAGIC:
            continue
        try:
            return DeviceHeader.from_bytes(data[o : o + HEADER_SIZE], source=source), d
        except ProtocolError:
            continue
    raise first_error


def parse_image(data: bytes | bytearray | memoryview, source: str | None = None) -> ImageContents:
    """Parse a ``.glimg`` file, recovering what is intact.

    Parameters
    ----------
    data
        The file's bytes.
    source
        File name for messages.

    Returns
    -------
    ImageContents
        Header, sample memory, step memory and per-block status; every byte of an ok block is exact.

    Raises
    ------
    ProtocolError
        Not an image (magic), unknown ``image_version``, version 2 with a header without step memory,
        inconsistent sizes, a file too short to hold its table, no valid device header near its place, or (version
        3) neither copy of the preamble intact. The message names the offset.

    Notes
    -----
    A version-1 file whose header has step memory (written by a host older than the step memory) is read:
    its step memory is not in the file, so :meth:`ImageContents.step_byte_ok` is all ``False`` and a
    warning says how many stored step records that loses.
    """
    data = bytes(data)
    preamble = _find_preamble(data, source)
    if preamble is not None:
        version, bs, header = IMAGE_VERSION_FRAMED, preamble.block_size, preamble.header
        blocks, notes, table_ok = _recover_frames(data, preamble), [], True
        if preamble.offset:
            notes.append(f"image preamble (prefix and device header) at offset 0 damaged: used its copy at offset "
                         f"{preamble.offset}")
        damaged_text = "damaged (no block frame with this index and a matching CRC-32 anywhere in the file)"
        mem0, mem_bytes, hshift = PREAMBLE_BYTES, preamble.memory_bytes, 0
        total_nominal = 2 * PREAMBLE_BYTES + mem_bytes + FRAME_OVERHEAD_BYTES * preamble.n_blocks
    else:
        version, bs, mem_bytes, n = _read_prefix(data, source)
        crcs, states, table_ok, notes = _read_block_table(data, n)
        header_at = 16 + 5 * n + 4
        header, hshift = _find_header(data, header_at, source)
        if hshift:
            notes.append(f"device header found shifted by {hshift:+d} bytes (bytes dropped or inserted before it)")
        _check_memory_size(header, version, mem_bytes, source)
        mem0 = header_at + HEADER_SIZE
        blocks = _recover_blocks(data, mem0, bs, mem_bytes, crcs, states if table_ok else None, hshift)
        if not table_ok:
            notes.append(f"image version {version} has no block indices in its CRCs: with its block table damaged, "
                         "an entry may hold a neighbouring block's CRC-32 (bytes dropped or inserted in the table), "
                         "so no block can be verified and all are reported missing; image version "
                         f"{IMAGE_VERSION_FRAMED} (written since) binds each block's CRC-32 to its index")
        damaged_text = (f"damaged (CRC-32 mismatch, not found within ±{SHIFT_SEARCH_BYTES} bytes or at the shift "
                        "the file's length implies)" if table_ok else
                        "unverifiable (the block table that holds their CRC-32s is damaged)")
        total_nominal = mem0 + mem_bytes
    stored = _stored_blocks(header, blocks.ok.size, bs)
    notes += _block_notes(blocks, stored["samples"] | stored["step records"], hshift, mem0, mem_bytes, len(data),
                          damaged_text, total_nominal)
    if version == IMAGE_VERSION and header.n_steps_stored:
        notes.append(f"image version {IMAGE_VERSION} holds no step memory: the header's {header.n_steps_stored} "
                     "stored step records are not in the file")
        warnings.warn(f"{source or 'memory image'}: {notes[-1]}", stacklevel=2)
    for what, needed in stored.items():
        lost = ~blocks.ok & needed
        if lost.any():
            warnings.warn(f"{source or 'memory image'}: {int(lost.sum())} of the {int(needed.sum())} blocks holding "
                          f"stored {what} are not usable ({_blocks(np.flatnonzero(lost))}); " + "; ".join(notes),
                          stacklevel=2)
    region = np.frombuffer(blocks.memory, dtype=np.uint8)
    steps = region[header.memory_bytes:] if version != IMAGE_VERSION else \
        np.full(header.step_memory_bytes, 0xFF, dtype=np.uint8)
    return ImageContents(header=header, memory=region[: header.memory_bytes].copy(), block_ok=blocks.ok,
                         block_size=bs, notes=notes, block_missing=blocks.marked, block_truncated=blocks.truncated,
                         block_shift=blocks.shifts, table_ok=table_ok, step_memory=steps.copy(),
                         image_version=version)


@dataclass(frozen=True)
class _Preamble:
    """An intact version-3 preamble (prefix, device header, ``preamble_crc32``)."""

    offset: int
    block_size: int
    memory_bytes: int
    n_blocks: int
    header: DeviceHeader
    key: int  #: its ``preamble_crc32``, which every block's CRC-32 starts from


def _find_preamble(data: bytes, source: str | None) -> _Preamble | None:
    """The first intact version-3 preamble in the file (normally at 0; else its copy at the end), or None when
    there is none (a file of version 1 or 2, or one whose both copies are damaged).

    A preamble is intact when its CRC-32 matches; its fields are then what the writer wrote, so an
    inconsistent one is an error, not a candidate to skip.
    """
    start = 0
    while True:
        o = data.find(IMAGE_MAGIC, start)
        if o < 0 or o + PREAMBLE_BYTES > len(data):
            return None
        start = o + 1
        end = o + PREAMBLE_BYTES - 4
        if data[o + 4] != IMAGE_VERSION_FRAMED or crc32(data[o:end]) != int.from_bytes(data[end : end + 4], "little"):
            continue
        p = IMAGE_PREFIX_STRUCT.parse(data[o : o + 16])
        bs, mem_bytes, n = int(p.block_size), int(p.memory_bytes), int(p.n_blocks)
        try:
            _check_block_size(bs, mem_bytes, source, IMAGE_VERSION_FRAMED)
            if n != -(-mem_bytes // bs):
                raise ProtocolError(f"n_blocks: {n}, but {mem_bytes} bytes in blocks of {bs} make "
                                    f"{-(-mem_bytes // bs)}", offset=IMAGE_OFFSETS["n_blocks"], source=source)
            header = DeviceHeader.from_bytes(data[o + 16 : end], source=source)
        except ProtocolError as err:
            raise err.at(offset=o) from err
        if image_memory_bytes(header) != mem_bytes:
            raise ProtocolError(f"memory_bytes: {mem_bytes}, but the device header's capacity of "
                                f"{header.capacity_samples} samples and {header.step_capacity} step records needs "
                                f"{image_memory_bytes(header)}", offset=o + IMAGE_OFFSETS["memory_bytes"],
                                source=source)
        return _Preamble(o, bs, mem_bytes, n, header, int.from_bytes(data[end : end + 4], "little"))


def _recover_frames(data: bytes, pre: _Preamble) -> _Blocks:
    """Find every block frame of a version-3 file wherever it is.

    Candidates are the nominal frame places, every occurrence of :data:`BLOCK_SYNC`, and the places next to a
    block already found (a frame whose sync word is damaged); a candidate is a block when its index is legal
    and its CRC-32 (:func:`frame_crc32`) matches. Two different frames verifying for one index (never seen
    without deliberate forgery) make that block unusable.
    """
    n, bs, mem_bytes, total = pre.n_blocks, pre.block_size, pre.memory_bytes, len(data)
    frame = bs + FRAME_OVERHEAD_BYTES
    sizes = np.minimum(bs, mem_bytes - bs * np.arange(n, dtype=np.int64))
    nominal = PREAMBLE_BYTES + frame * np.arange(n, dtype=np.int64)
    memory = bytearray(b"\xff" * mem_bytes)
    blocks = _Blocks(memory, *(np.zeros(n, dtype=bool) for _ in range(5)), np.zeros(n, dtype=np.int64), 0)
    found = np.full(n, -1, dtype=np.int64)
    state = np.zeros(n, dtype=np.uint8)
    conflict = np.zeros(n, dtype=bool)
    view = memoryview(data)

    def verify(c: int) -> int:
        """Index of the block whose frame starts at ``c``, or -1."""
        if c < 0 or c + 12 > total:
            return -1
        idx = int.from_bytes(data[c + 4 : c + 8], "little")
        st = data[c + 8]
        if idx >= n or st > BLOCK_MISSING or data[c + 9 : c + 12] != b"\0\0\0":
            return -1
        stop = c + 12 + int(sizes[idx])
        if stop + 4 > total or frame_crc32(pre.key, idx, st, view[c + 12 : stop]) != \
                int.from_bytes(data[stop : stop + 4], "little"):
            return -1
        if found[idx] < 0:
            found[idx], state[idx] = c, st
        elif state[idx] != st or data[c + 12 : stop] != data[found[idx] + 12 : found[idx] + 12 + sizes[idx]]:
            conflict[idx] = True
        return idx

    arr = np.frombuffer(data, dtype=np.uint8)
    sync = np.frombuffer(BLOCK_SYNC, dtype=np.uint8)
    hits = np.ones(max(total - 3, 0), dtype=bool)
    for k in range(4):
        hits &= arr[k : k + hits.size] == sync[k]
    # np.union1d's sorted distinct values, without the numpy.ma import its np.unique costs (~15 ms of a decode)
    candidates = np.sort(np.concatenate([np.flatnonzero(hits), nominal[nominal < total]]))
    candidates = candidates[np.r_[True, candidates[1:] != candidates[:-1]]] if candidates.size else candidates
    end = 0
    for c in candidates.tolist():
        if c >= end and (idx := verify(c)) >= 0:
            end = c + int(sizes[idx]) + FRAME_OVERHEAD_BYTES
    for order in (range(1, n), range(n - 2, -1, -1)):  # frames next to found ones: their sync may be damaged
        for i in order:
            j = i - 1 if order.step > 0 else i + 1
            if found[i] < 0 and found[j] >= 0:
                verify(int(found[j] + sizes[j] + FRAME_OVERHEAD_BYTES) if j < i else
                       int(found[j] - sizes[i] - FRAME_OVERHEAD_BYTES))
    usable = (found >= 0) & ~conflict
    for i in np.flatnonzero(usable & (state == BLOCK_PRESENT)).tolist():
        c, size = int(found[i]), int(sizes[i])
        memory[i * bs : i * bs + size] = view[c + 12 : c + 12 + size]
    view.release()
    blocks.ok = usable & (state == BLOCK_PRESENT)
    blocks.marked = usable & (state == BLOCK_MISSING)
    blocks.shifts = np.where(blocks.ok, found - nominal, 0)
    # where a lost block would have been: after the nearest block found before it, at that block's shift
    placed = np.flatnonzero(found >= 0)
    before = np.searchsorted(placed, np.arange(n)) - 1
    shift_before = np.where(before >= 0, (found - nominal)[placed[np.maximum(before, 0)]] if placed.size else 0, 0)
    beyond = nominal + shift_before + sizes + FRAME_OVERHEAD_BYTES > total
    lost = (found < 0) | conflict
    blocks.truncated = lost & beyond & ~conflict
    blocks.damaged = lost & ~blocks.truncated
    blocks.conflict = conflict
    blocks.last_shift = int((found - nominal)[placed[-1]]) if placed.size else 0
    return blocks


def _read_prefix(data: bytes, source: str | None) -> tuple[int, int, int, int]:
    """``(image_version, block_size, memory_bytes, n_blocks)`` of the fixed prefix, checked against each other
    and against the file's length (it must hold the block table and its CRC)."""
    if len(data) < 16:
        raise ProtocolError(f"memory image truncated: {len(data)} bytes, the fixed prefix alone is 16",
                            offset=len(data), source=source)
    p = IMAGE_PREFIX_STRUCT.parse(data[:16])
    if p.magic != IMAGE_MAGIC:
        raise ProtocolError(f"magic: expected {IMAGE_MAGIC!r}, found {p.magic!r} (not a gaitlog memory image)",
                            offset=0, source=source)
    if p.image_version not in _MAX_MEMORY_BYTES:
        raise ProtocolError(f"image_version: unknown version {p.image_version} (this decoder knows "
                            f"{', '.join(map(str, _MAX_MEMORY_BYTES))})", offset=IMAGE_OFFSETS["image_version"],
                            source=source)
    version = int(p.image_version)
    if version == IMAGE_VERSION_FRAMED:
        raise ProtocolError(f"image_version {version}: neither copy of the preamble (prefix, device header and their "
                            f"CRC-32; at offset 0 and at the end of the file) is intact", offset=0, source=source)
    bs, mem_bytes, n = int(p.block_size), int(p.memory_bytes), int(p.n_blocks)
    _check_block_size(bs, mem_bytes, source, version)
    if n != -(-mem_bytes // bs):
        raise ProtocolError(f"n_blocks: {n}, but {mem_bytes} bytes in blocks of {bs} make {-(-mem_bytes // bs)}",
                            offset=IMAGE_OFFSETS["n_blocks"], source=source)
    table_end = 16 + 5 * n
    if len(data) < table_end + 4:
        raise ProtocolError(f"memory image truncated inside its block table ({len(data)} of {table_end + 4} "
                            "bytes)", offset=len(data), source=source)
    return version, bs, mem_bytes, n


def _read_block_table(data: bytes, n: int) -> tuple[np.ndarray, np.ndarray, bool, list[str]]:
    """``(crcs, states, table_ok, notes)`` of the block table; a table whose CRC-32 fails is noted (no block is
    then used)."""
    table_end = 16 + 5 * n
    crcs = np.frombuffer(data, dtype="<u4", count=n, offset=16)
    states = np.frombuffer(data, dtype=np.uint8, count=n, offset=16 + 4 * n)
    table_ok = crc32(data[:table_end]) == int.from_bytes(data[table_end : table_end + 4], "little")
    notes = [] if table_ok else [f"block table CRC-32 mismatch (offset {table_end}): its entries and states cannot be "
                                 "trusted"]
    return crcs, states, table_ok, notes


def _check_memory_size(header: DeviceHeader, version: int, mem_bytes: int, source: str | None) -> None:
    """The prefix's ``memory_bytes`` against what the header's capacities need for this ``image_version``."""
    if version == IMAGE_VERSION_STEPS and header.step_capacity == 0:
        raise ProtocolError(f"image_version: {version}, but the device header has no step memory (step_capacity "
                            f"0; an image without step memory is version {IMAGE_VERSION})",
                            offset=IMAGE_OFFSETS["image_version"], source=source)
    # a version-1 file holds the sample memory only, also when its header has step memory (written by a host
    # that predates the step memory): its step records are then not in the file
    expected = image_memory_bytes(header) if version == IMAGE_VERSION_STEPS else header.memory_bytes
    if expected != mem_bytes:
        steps = f" and {header.step_capacity} step records" if version == IMAGE_VERSION_STEPS else ""
        raise ProtocolError(f"memory_bytes: {mem_bytes}, but the device header's capacity of "
                            f"{header.capacity_samples} samples{steps} needs {expected}",
                            offset=IMAGE_OFFSETS["memory_bytes"], source=source)


@dataclass
class _Blocks:
    """What :func:`_recover_blocks` found of each block (all arrays ``(n_blocks,)``)."""

    memory: bytearray  #: the memory region; bytes of blocks not ok are 0xFF
    ok: np.ndarray  #: bytes exact (CRC-32 verified)
    marked: np.ndarray  #: marked missing in the table
    truncated: np.ndarray  #: beyond the end of the file
    damaged: np.ndarray  #: CRC-32 mismatch, not found within the shift window
    unknown_state: np.ndarray  #: a state byte that is neither present nor missing
    shifts: np.ndarray  #: shift in bytes of each ok block (0 elsewhere)
    last_shift: int  #: shift of the last block found
    conflict: np.ndarray | None = None  #: version 3: two different frames verified for this index


def _recover_blocks(data: bytes, mem0: int, bs: int, mem_bytes: int, crcs: np.ndarray,
                    states: np.ndarray | None, hshift: int) -> _Blocks:
    """Versions 1 and 2: find each block by its CRC-32 at its place, or within ±:data:`SHIFT_SEARCH_BYTES` of
    it, or at the shift the file's length implies (bytes dropped or inserted before it move every later block).

    ``states`` None (a damaged table): no block is used. Its entries may be displaced (bytes dropped or
    inserted in the table), so entry ``i`` may hold the CRC-32 of block ``i - k``; bytes dropped or inserted in
    the memory region can move block ``i - k`` by ``k`` blocks onto the place of block ``i``, where it would
    verify (measured: 3,568 wrong samples in one file of 10,000 damaged ones). Nothing in these versions tells
    the two apart, so every block is reported damaged.
    """
    n = len(crcs)
    memory = bytearray(b"\xff" * mem_bytes)
    found_blocks = _Blocks(memory, *(np.zeros(n, dtype=bool) for _ in range(5)), np.zeros(n, dtype=np.int64), hshift)
    view = memoryview(data)
    total = len(data)
    shift = hshift
    length_shift = total - (mem0 + mem_bytes)
    window = SHIFTS_NEAREST_FIRST
    if states is None:
        found_blocks.damaged[:] = True
        return found_blocks
    for i in range(n):
        start = i * bs
        size = min(bs, mem_bytes - start)
        want = int(crcs[i])
        if states is not None and states[i] != BLOCK_PRESENT:
            (found_blocks.marked if states[i] == BLOCK_MISSING else found_blocks.unknown_state)[i] = True
            continue
        o = mem0 + start + shift
        if o >= 0 and o + size <= total and crc32(view[o : o + size]) == want:
            found = shift
        else:
            found = None
            tries = [d for d in window if d] + ([length_shift - shift] if length_shift != shift else [])
            for d in tries:
                od = o + d
                if od >= 0 and od + size <= total and crc32(view[od : od + size]) == want:
                    found = shift + d
                    break
        if found is None:
            (found_blocks.truncated if o + size > total else found_blocks.damaged)[i] = True
            continue
        shift = found
        o = mem0 + start + shift
        memory[start : start + size] = view[o : o + size]
        found_blocks.ok[i] = True
        found_blocks.shifts[i] = shift
    view.release()
    found_blocks.last_shift = shift
    return found_blocks


def _stored_blocks(header: DeviceHeader, n: int, bs: int) -> dict[str, np.ndarray]:
    """``{"samples": ..., "step records": ...}``: bool ``(n,)`` of the blocks holding stored samples (the whole
    sample memory when wrapped; else bytes 0 .. 4·n_stored) and stored step records (step memory bytes
    0 .. 20·n_steps_stored, after the samples)."""
    out = {}
    for what, first, stop in (("samples", 0, header.used_bytes),
                              ("step records", header.memory_bytes, header.memory_bytes + header.step_used_bytes)):
        needed = np.zeros(n, dtype=bool)
        if stop > first:
            needed[first // bs: -(-stop // bs)] = True
        out[what] = needed
    return out


def _block_notes(blocks: _Blocks, stored: np.ndarray, hshift: int, mem0: int, mem_bytes: int,
                 total: int, damaged_text: str, total_nominal: int) -> list[str]:
    """One line per kind of block problem. A block marked missing that holds nothing stored was never written
    by the logger (a dump does not read it): it is called empty, not lost."""
    notes = []
    if (blocks.marked & stored).any():
        notes.append(f"{_blocks(np.flatnonzero(blocks.marked & stored))} marked missing (never received)")
    if (blocks.marked & ~stored).any():
        notes.append(f"{_blocks(np.flatnonzero(blocks.marked & ~stored))} empty (never written by the logger, "
                     "so not transferred)")
    if blocks.conflict is not None and blocks.conflict.any():
        notes.append(f"{_blocks(np.flatnonzero(blocks.conflict))}: two different frames verify for the same index; "
                     "neither is used")
    damaged = blocks.damaged & ~blocks.conflict if blocks.conflict is not None else blocks.damaged
    if damaged.any():
        notes.append(f"{_blocks(np.flatnonzero(damaged))} {damaged_text}")
    if blocks.truncated.any():
        notes.append(f"{_blocks(np.flatnonzero(blocks.truncated))} missing: file truncated at {total} bytes "
                     f"(complete file: {total_nominal})")
    if blocks.unknown_state.any():
        notes.append(f"{_blocks(np.flatnonzero(blocks.unknown_state))} have an unknown state byte; not used")
    moved = np.flatnonzero(blocks.ok & (np.diff(np.concatenate(([hshift], blocks.shifts))) != 0))
    for i in moved:
        notes.append(f"block {i} found shifted by {int(blocks.shifts[i]):+d} bytes (bytes dropped or inserted "
                     "before it)")
    if total > total_nominal + blocks.last_shift and blocks.ok.all():
        notes.append(f"{total - (total_nominal + blocks.last_shift)} trailing bytes after the memory ignored")
    return notes


def detect_format(data: bytes | bytearray | memoryview) -> Literal["image", "raw", "capture"]:
    """Which of the three inputs a byte string is.

    ``"image"``: starts with ``GLIM`` (section 6); ``"raw"``: starts with the device header magic ``GLOG``
    (an XDUMP raw dump, section 5); ``"capture"``: an intact frame (section 3) within the first 64 KiB. A file
    whose first bytes are damaged is still an image when it holds an intact version-3 preamble, and a raw
    dump when it holds an intact check trailer.

    Raises
    ------
    ProtocolError
        None of the three.

    >>> detect_format(b"GLIM..."), detect_format(b"GLOG..."), detect_format(b"\\x00" + bytes.fromhex("a55a0207000068f8"))
    ('image', 'raw', 'capture')
    """
    head = bytes(data[:4])
    if head == IMAGE_MAGIC:
        return "image"
    if head == HEADER_MAGIC:
        return "raw"
    data = bytes(data)
    try:
        if _find_preamble(data, None) is not None:
            return "image"
    except ProtocolError:
        return "image"
    try:
        if find_trailer(data) is not None:
            return "raw"
    except ProtocolError:
        return "raw"
    parser = FrameParser()
    items = parser.feed(bytes(data[:_CAPTURE_PROBE_BYTES])) + parser.flush()
    if any(isinstance(x, Frame) for x in items):
        return "capture"
    raise ProtocolError(f"not a memory image (magic {IMAGE_MAGIC!r}), a raw dump (magic {HEADER_MAGIC!r}) or a "
                        f"wire capture (no intact A5 5A frame in the first {min(len(data), _CAPTURE_PROBE_BYTES)} "
                        f"bytes); found {head!r} at the start", offset=0)
