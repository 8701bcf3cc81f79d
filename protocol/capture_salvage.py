"""Frames of a damaged wire capture found again (``PROTOCOL.md`` sections 4 and 4.1), as an image's blocks are by
:mod:`gaitlog.protocol.image` and a raw dump's chunks by :mod:`gaitlog.protocol.raw_dump`.

Sans-I/O: each function takes the capture's bytes and what :func:`~gaitlog.protocol.frames.parse_stream` made of
them (its intact frames and its errors). The frame's fields are found where the construct declarations put them
(:data:`~gaitlog.protocol.frames.FRAME_BODY_STRUCT`, :data:`~gaitlog.protocol.frames.PAYLOAD_STRUCTS`,
:data:`~gaitlog.protocol.header.HEADER_OFFSETS`), never typed again.

* Device headers: :func:`find_header_copies` finds the HEADER frames, intact or damaged, and reads a damaged one's
  header only when it verifies on its own (:func:`header_verifies`); :func:`combined_header` puts one header
  together from two damaged copies; :func:`state_key` names the memory state a header describes.
* DATA_BLOCKS frames: :class:`BlocksFrames` finds the damaged ones (their sync or their length may be hit, bytes
  may be dropped or inserted) and keeps the blocks that verify under a header's ``binding``. Which header a frame
  belongs to is the decoder's rule, passed in.

Examples
--------
>>> from gaitlog.protocol.frames import FrameType, build_payload, encode_frame, parse_stream
>>> from gaitlog.protocol.header import DeviceHeader
>>> raw = DeviceHeader(capacity_samples=256).to_bytes()
>>> wire = bytearray(encode_frame(FrameType.HEADER, 1, build_payload(FrameType.HEADER, header=raw)))
>>> wire[3] ^= 0xFF  # its seq: the frame's CRC-16 fails, the header's own still verifies
>>> frames, errors = parse_stream(bytes(wire))
>>> copies, unreadable = find_header_copies(bytes(wire), frames, errors)
>>> [(offset, header == raw, salvaged) for offset, header, salvaged in copies], unreadable.tolist()
([(0, True, True)], [])
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import construct as cs
import numpy as np

from gaitlog.protocol.channel_map import MAX_CHANNELS
from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.data_blocks import ADDRESS_BYTES, payload_data_bytes, salvage_blocks
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import (
    FRAME_BODY_STRUCT,
    FRAME_OVERHEAD,
    PAYLOAD_STRUCTS,
    SYNC,
    Frame,
    FrameError,
    FrameType,
)
from gaitlog.protocol.header import (
    HEADER_OFFSETS,
    HEADER_SIZE,
    KNOWN_HEADER_VERSIONS,
    MAGIC,
    PACKING_P32,
    PROTOCOL_VERSION,
    DeviceHeader,
    HeaderFlag,
    crc_span,
)
from gaitlog.protocol.layout import named_fields

__all__ = ["TYPE_AT", "LENGTH_AT", "PAYLOAD_AT", "find_header_copies", "header_verifies", "state_key",
           "closed_state", "combined_header", "COMBINE_MAX_DIFFERING_BYTES", "BlocksFrames"]

_BODY = {name: (len(SYNC) + offset, sc) for name, offset, sc in named_fields(FRAME_BODY_STRUCT)}
#: Offsets from a frame's sync of its ``type``, ``length`` and ``payload`` fields.
TYPE_AT, LENGTH_AT, PAYLOAD_AT = _BODY["type"][0], _BODY["length"][0], _BODY["payload"][0]
_LENGTH = _BODY["length"][1]
_CRC = cs.Int16ub  # the frame's CRC-16 after its payload (FRAME_STRUCT's ``crc``)
_ADDRESS_AT, _ADDRESS = next((offset, sc) for name, offset, sc in named_fields(PAYLOAD_STRUCTS[FrameType.DATA_BLOCKS])
                             if name == "address")
_DUMP_END = PAYLOAD_STRUCTS[FrameType.DUMP_END]
#: Types of the frames a DUMP_BLOCKS stream holds: one of them may follow a DATA_BLOCKS frame.
_BLOCKS_STREAM_TYPES = tuple(bytes([t]) for t in (FrameType.HEADER, FrameType.DUMP_END, FrameType.DATA_BLOCKS))
_HEADER_TYPE = bytes([FrameType.HEADER])
_AT = {name: HEADER_OFFSETS[name][0] for name in ("header_version", "protocol_version", "axes", "packing", "flags")}
#: Differing bytes up to which two damaged copies of a header are combined (2^n candidates, each checked by the
#: header's CRC-16 and a copy's frame CRC-16).
COMBINE_MAX_DIFFERING_BYTES = 10


def _read(sc: cs.Construct, data: bytes, at: int) -> int:
    return int(sc.parse(data[at: at + sc.sizeof()]))


# ------------------------------------------------------------------------------------------ device headers
def find_header_copies(data: bytes, frames: list[Frame], errors: list[FrameError]
                       ) -> tuple[list[tuple[int, bytes, bool]], np.ndarray]:
    """Where a device header starts in a capture: ``(frame offset, header bytes, salvaged)`` of the headers
    that can be read, in stream order, and the frame offsets of those that cannot.

    An intact HEADER frame gives its payload (``salvaged`` False). In the bytes of no intact frame, a damaged
    HEADER frame is looked for: the magic ``GLOG`` (its payload) or a sync with type 0x86. Its 256 bytes are
    used (``salvaged`` True) only when :func:`header_verifies`; otherwise it is unreadable (the decoder then uses
    none of the frames after it under an earlier header). Vectorised, so that a hostile file full of ``GLOG``
    costs little.
    """
    known = {fr.offset: (bytes(fr.payload), False) for fr in frames
             if fr.type == FrameType.HEADER and len(fr.payload) == HEADER_SIZE}
    at = _outside_frames(_header_candidates(data, errors), frames, len(data))
    readable = np.zeros(at.size, dtype=bool)
    for i in _plausible(data, at).tolist():
        payload_at = int(at[i])
        raw = data[payload_at: payload_at + HEADER_SIZE]
        if header_verifies(raw):
            known[payload_at - PAYLOAD_AT] = (raw, True)
            readable[i] = True
    unreadable = at[~readable] - PAYLOAD_AT
    return [(off, raw, salvaged) for off, (raw, salvaged) in sorted(known.items())], unreadable


def _header_candidates(data: bytes, errors: list[FrameError]) -> np.ndarray:
    """Sorted stream offsets where a header may start: each magic, and the payload of each framing error that
    begins with a sync and the HEADER type."""
    b = np.frombuffer(data, dtype=np.uint8)
    n = b.size
    at = (np.flatnonzero(np.all([b[k: n - 3 + k] == MAGIC[k] for k in range(4)], axis=0)) if n >= 4 else
          np.zeros(0, np.int64))
    typed = [e.offset + PAYLOAD_AT for e in errors if data[e.offset: e.offset + len(SYNC)] == SYNC
             and data[e.offset + TYPE_AT: e.offset + TYPE_AT + 1] == _HEADER_TYPE]
    if typed:
        at = np.sort(np.concatenate([at, np.asarray(typed, dtype=np.int64)]))
        at = at[np.r_[True, at[1:] != at[:-1]]]
    return at


def _outside_frames(at: np.ndarray, frames: list[Frame], n: int) -> np.ndarray:
    """The offsets of ``at`` inside the capture and in no intact frame (intact frames do not overlap: the parser
    consumed each)."""
    starts = np.array([fr.offset for fr in frames], dtype=np.int64)
    ends = starts + np.array([FRAME_OVERHEAD + len(fr.payload) for fr in frames], dtype=np.int64)
    k = np.searchsorted(starts, at, side="right") - 1
    return at[(at < n) & ~((k >= 0) & (at < ends[np.maximum(k, 0)] if ends.size else False))]


def _plausible(data: bytes, at: np.ndarray) -> np.ndarray:
    """Indices into ``at`` of the whole headers whose fixed bytes of section 2 hold (a known header version,
    protocol 1, 1-8 axes: 3 or a channel map's channels, P32), before any CRC or parse."""
    b = np.frombuffer(data, dtype=np.uint8)
    idx = np.flatnonzero(at + HEADER_SIZE <= b.size)
    w = at[idx]
    axes = b[w + _AT["axes"]]
    return idx[np.isin(b[w + _AT["header_version"]], KNOWN_HEADER_VERSIONS)
               & (b[w + _AT["protocol_version"]] == PROTOCOL_VERSION) & (axes >= 1) & (axes <= MAX_CHANNELS)
               & (b[w + _AT["packing"]] == PACKING_P32)]


def header_verifies(raw: bytes) -> bool:
    """``raw`` is a header that a salvage may use: its own CRC-16 verifies, it parses, and it is version 1 or has
    LOGGING clear (section 2: version 2 keeps the journal, which a decoder would then need, outside that CRC)."""
    if crc16_xmodem(crc_span(raw[:-2])) != int.from_bytes(raw[-2:], "big"):
        return False
    try:
        h = DeviceHeader.from_bytes(raw)
    except ProtocolError:
        return False
    return h.header_version == 1 or not h.logging


def closed_state(header_bytes: bytes) -> bool:
    """The header is of version 2 or later with LOGGING clear: its journal is not part of the memory state
    (section 2.4)."""
    return (len(header_bytes) == HEADER_SIZE and header_bytes[_AT["header_version"]] != 1
            and not header_bytes[_AT["flags"]] & HeaderFlag.LOGGING)


def state_key(header_bytes: bytes) -> bytes:
    """The bytes that name a memory's state: the whole header, or of a :func:`closed_state` the part its CRC
    covers (the journal is then meaningless, section 2.4)."""
    if closed_state(header_bytes):
        return crc_span(header_bytes[:-2]) + header_bytes[-2:]
    return header_bytes


def combined_header(data: bytes, unreadable: np.ndarray) -> bytes | None:
    """A header put together from two damaged HEADER frames at the offsets ``unreadable`` (section 4.1): where
    the copies differ, each choice of bytes is tried; it is used only when exactly one choice passes the header's
    own CRC-16, a copy's frame CRC-16 (over that copy's type, seq and length) and :func:`header_verifies`. None
    otherwise."""
    copies = [int(off) for off in unreadable.tolist() if off >= 0 and off + FRAME_OVERHEAD + HEADER_SIZE <= len(data)]
    for i, a in enumerate(copies):
        for b in copies[i + 1:]:
            found = _combine_pair(data, a, b)
            if found is not None:
                return found
    return None


def _combine_pair(data: bytes, a: int, b: int) -> bytes | None:
    pa = np.frombuffer(data, np.uint8, HEADER_SIZE, a + PAYLOAD_AT)
    pb = np.frombuffer(data, np.uint8, HEADER_SIZE, b + PAYLOAD_AT)
    differ = np.flatnonzero(pa != pb)
    if not 0 < differ.size <= COMBINE_MAX_DIFFERING_BYTES:
        return None
    heads = [(data[o + TYPE_AT: o + PAYLOAD_AT], _read(_CRC, data, o + PAYLOAD_AT + HEADER_SIZE)) for o in (a, b)]
    good = set()
    trial = pa.copy()
    for choice in range(1 << differ.size):
        pick = np.array([(choice >> k) & 1 for k in range(differ.size)], dtype=bool)
        trial[differ] = np.where(pick, pb[differ], pa[differ])
        raw = trial.tobytes()
        if any(crc16_xmodem(raw, crc16_xmodem(head)) == stored for head, stored in heads) and header_verifies(raw):
            good.add(raw)
    return good.pop() if len(good) == 1 else None


# ------------------------------------------------------------------------------------------ DATA_BLOCKS frames
def _of_blocks_streams(data: bytes, frames: list[Frame], errors: list[FrameError]) -> bool:
    """The capture is of DUMP_BLOCKS streams: an intact DATA_BLOCKS frame, a damaged one whose sync and type
    survived, or a HEADER frame followed by DUMP_END (how a DUMP_BLOCKS stream ends)."""
    if any(fr.type == FrameType.DATA_BLOCKS for fr in frames):
        return True
    if any(data[e.offset: e.offset + TYPE_AT + 1] == SYNC + bytes([FrameType.DATA_BLOCKS]) for e in errors):
        return True
    return any(a.type == FrameType.HEADER and b.type == FrameType.DUMP_END for a, b in zip(frames, frames[1:]))


class _Span(NamedTuple):
    """An intact DATA_BLOCKS frame: stream offsets of its start and end, its address and data bytes."""

    start: int
    end: int
    address: int
    data_bytes: int


class BlocksFrames:
    """The DATA_BLOCKS frames of a capture (section 4.1): the intact ones, and the damaged ones found again.

    A damaged frame is looked for at each sync with the type 0x8A in the errors, and where an intact frame ends
    and no intact frame follows (a damaged sync); its blocks are tried at the addresses its own address field
    and its intact neighbours imply, for the extent its length field and the next intact frame imply.
    """

    def __init__(self, data: bytes, frames: list[Frame], errors: list[FrameError]) -> None:
        self.data = data
        #: The intact DATA_BLOCKS frames of a legal length.
        self.intact = [fr for fr in frames if fr.type == FrameType.DATA_BLOCKS and payload_data_bytes(len(fr.payload))]
        self._spans = [_Span(fr.offset, fr.offset + FRAME_OVERHEAD + len(fr.payload),
                             _read(_ADDRESS, fr.payload, _ADDRESS_AT), payload_data_bytes(len(fr.payload)))
                       for fr in self.intact]
        self._starts = np.array([fr.offset for fr in frames], dtype=np.int64)
        self._ends = self._starts + np.array([FRAME_OVERHEAD + len(fr.payload) for fr in frames], dtype=np.int64)
        lengths = [FRAME_OVERHEAD + len(fr.payload) for fr in self.intact]
        self._frame_bytes = max(set(lengths), key=lengths.count) if lengths else 0  # the stream's usual frame
        #: (stream offset, first address) of each DUMP_END: the stream it ends began at that address.
        self._stream_firsts = [(fr.offset, int(_DUMP_END.parse(fr.payload).address)) for fr in frames
                               if fr.type == FrameType.DUMP_END and len(fr.payload) == _DUMP_END.sizeof()]
        #: The capture is of DUMP_BLOCKS streams (:func:`_of_blocks_streams`).
        self.of_blocks_streams = _of_blocks_streams(data, frames, errors)
        self._error_syncs = {e.offset for e in errors if data[e.offset: e.offset + len(SYNC)] == SYNC}

    def salvage(self, binding: int, belongs: Callable[[int], bool]) -> list[tuple[int, bytes]]:
        """``(address, bytes)`` of the blocks of damaged frames that verify under ``binding``, trying only the
        frames at the offsets ``belongs`` accepts (the decoder's rule: the frame belongs to the header of that
        binding). Nothing when the capture is not of DUMP_BLOCKS streams (protocol version 1)."""
        if not self.of_blocks_streams:
            return []
        n = len(self.data)
        starts = set(self._starts.tolist())
        todo = self._error_syncs | {int(e) for e in self._ends.tolist() if e < n and e not in starts}
        done: set[int] = set()
        pieces: list[tuple[int, bytes]] = []
        while todo:
            s = min(todo)
            todo.discard(s)
            done.add(s)
            if s in starts or not belongs(s):
                continue
            found, ends = self._salvage_frame(s, binding)
            pieces += found
            if found:  # the next frame may be damaged too, its sync included: look where this one ends
                todo |= {e for e in ends if e < n and e not in done}
        return pieces

    def _salvage_frame(self, s: int, binding: int) -> tuple[list[tuple[int, bytes]], set[int]]:
        """The verified blocks of a damaged DATA_BLOCKS frame starting at stream offset ``s``, and the ends tried
        (:meth:`_extents`; when the end is uncertain only the blocks before the first bad one are kept).
        Addresses tried: :meth:`_addresses`."""
        k = int(np.searchsorted(self._starts, s, side="right"))
        next_start = int(self._starts[k]) if k < self._starts.size else len(self.data)
        whole, extents = self._extents(s, next_start)
        found: dict[int, bytes] = {}
        for end in sorted(extents):
            body = self.data[s + PAYLOAD_AT + ADDRESS_BYTES: end - (FRAME_OVERHEAD - PAYLOAD_AT)]
            n_data = payload_data_bytes(ADDRESS_BYTES + len(body)) or 0
            got = salvage_blocks(binding, body, self._addresses(s, n_data))
            # a frame whose extent is uncertain (bytes dropped or inserted, or its length field hit) may be shifted
            # after its first bad block: only the blocks before it are certain to be where they verify
            for address, chunk in (got if whole else got.leading()).pieces():
                found.setdefault(address, chunk)
        return list(found.items()), extents

    def _extents(self, s: int, next_start: int) -> tuple[bool, set[int]]:
        """Where the damaged frame at ``s`` may end, and whether that is certain (``whole``): its length field's
        end when the frame it gives ends where the next frame (or the capture) starts, no byte dropped or
        inserted inside; else the next intact frame's start, and the ends its length field and the stream's usual
        frame length give when they come before that."""
        data = self.data
        length = _read(_LENGTH, data, s + LENGTH_AT) if s + PAYLOAD_AT <= len(data) else 0
        end = s + FRAME_OVERHEAD + length
        if payload_data_bytes(length) and end <= next_start and self._frame_follows(end, next_start):
            return True, {end}
        extents = {next_start}
        for size in (FRAME_OVERHEAD + length, self._frame_bytes):
            if size > FRAME_OVERHEAD and payload_data_bytes(size - FRAME_OVERHEAD) and s + size <= next_start:
                extents.add(s + size)
        return False, extents

    def _frame_follows(self, end: int, next_start: int) -> bool:
        """A frame (or the capture's end) starts at ``end``: the next intact frame, a sync, or the type of a frame
        a DUMP_BLOCKS stream holds."""
        data = self.data
        return (end == next_start or end == len(data) or data[end: end + len(SYNC)] == SYNC
                or data[end + TYPE_AT: end + TYPE_AT + 1] in _BLOCKS_STREAM_TYPES)

    def _addresses(self, s: int, n_data: int) -> list[int]:
        """Candidate addresses of the damaged frame at ``s`` carrying ``n_data`` bytes: its address field, the
        addresses that follow the intact DATA_BLOCKS frame before it (this frame, or the one after a lost frame),
        the one that ends where the intact frame after it begins, and the first address of the stream of the next
        intact DUMP_END (the stream's first frame)."""
        address_at = s + PAYLOAD_AT + _ADDRESS_AT
        addresses = [_read(_ADDRESS, self.data, address_at)] if address_at + ADDRESS_BYTES <= len(self.data) else []
        before = [sp for sp in self._spans if sp.end <= s]
        if before:
            prev_end = before[-1].address + before[-1].data_bytes
            addresses += [prev_end, prev_end + before[-1].data_bytes]
        after = [sp for sp in self._spans if sp.start >= s + FRAME_OVERHEAD]
        if after:
            addresses.append(after[0].address - n_data)
        stream_first = next((first for offset, first in self._stream_firsts if offset > s), None)
        if stream_first is not None:
            addresses.append(stream_first)
        return addresses
