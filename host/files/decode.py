"""Decode a memory image, a raw XMODEM dump or a raw wire capture into a :class:`~gaitlog.host.files.recording.Recording`.

Three inputs (``gaitlog.protocol.image.detect_format`` tells them apart):

``image``
    A ``.glimg`` memory-image file (``PROTOCOL.md`` section 6), as written by the emulator and by
    ``gaitlog dump``. Each 1024-byte block is used only when its CRC-32 matches (shifted blocks are recovered
    by ``gaitlog.protocol.image.parse_image``); blocks marked missing or never found are reported as gaps.
``raw``
    The file an XMODEM receiver (``rx``) writes after XDUMP (section 5): the 256-byte header, then the memory
    from address 0, then the check trailer (``gaitlog.protocol.raw_dump``), padded with 0x1A. Each 256-byte chunk is
    used only when its CRC-32 in the trailer matches (shifted chunks are found again); samples of damaged
    chunks or beyond the end of a short file are reported missing. A raw dump without its trailer (older
    firmware, or an end cut off) cannot be verified: its samples are reported missing, and a warning and the
    notes (``verified: NO``) say so; ``accept_unverified=True`` (``--accept-unverified``) keeps them as the
    file holds them, marked valid but UNVERIFIED in the same words.
``capture``
    The device-to-host bytes of a DUMP/READ session (sections 3-4): HEADER and DATA frames. A memory byte is
    known only when an intact DATA frame (CRC-16 good) carried it; everything else is reported missing.

Then, for all three, the ring order is restored (oldest sample first, ``PROTOCOL.md`` section 2's derived
quantities) and the P32 words are unpacked with numpy. A sample is valid only if all four of its bytes were
received intact: the decoder never invents a sample.

Per-step records (``PROTOCOL.md`` 2.3) come the same way: from the step memory of an image of version 2, the
step part of a raw dump (after the sample part, ``20 · n`` bytes), and the DATA frames of a capture at the
step addresses (``gaitlog.protocol.steps.STEP_ADDRESS_BASE`` +). The stored records are put in ring order
(``DeviceHeader.step_slots``) and a record is used only when all 20 of its bytes were received intact and its
CRC-16 matches; the others are dropped, never repaired, and reported as ``Recording.step_losses`` runs with
the reason (:data:`STEP_REASONS`), in a note and in a warning. :func:`gaitlog.host.files.replay.verify_step_records`
checks the used records against the host's replay of the device's algorithm.
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from gaitlog.host.errors import HostError
from gaitlog.host.files.losses import SampleLosses, say_losses
from gaitlog.host.files.recording import RecordGap, Recording, gaps_from_mask
from gaitlog.protocol.commit_journal import torn_step_records
from gaitlog.protocol.crc import crc16_xmodem, crc32
from gaitlog.protocol.data_blocks import ADDRESS_BYTES, header_binding, payload_data_bytes, salvage_blocks
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import FRAME_OVERHEAD, SYNC, FrameType, parse_stream
from gaitlog.protocol.header import (
    HEADER_SIZE,
    KNOWN_HEADER_VERSIONS,
    MAGIC,
    PAGE_SAMPLES,
    DeviceHeader,
    HeaderFlag,
    crc_span,
)
from gaitlog.protocol.image import detect_format, parse_image
from gaitlog.protocol.journal_ring import HEADER_VERSION_RING
from gaitlog.protocol.packing import unpack_words
from gaitlog.protocol.raw_dump import parse_raw_dump
from gaitlog.protocol.steps import (
    ONLINE_ALGORITHM_VERSION,
    STEP_RECORD_DTYPE,
    STEP_RECORD_SIZE,
    memory_region,
    stored_step_records,
)

#: Reason texts of the gaps, indexed by the reason codes used below.
REASONS = (
    "block marked missing in the image (never received by the dump)",       # 0
    "block damaged in the image (CRC-32 mismatch, not found at a shifted offset)",  # 1
    "beyond the end of the truncated input",                                 # 2
    "not received intact (no DATA frame with a good CRC, nor 64-sample block with a good check, covered it)",  # 3
    "code outside the ADC range of the header's adc_bits",                  # 4
    "chunk damaged in the raw dump (CRC-32 of its check trailer mismatch, not found at a shifted offset)",  # 5
    "raw dump's check trailer damaged: nothing can be verified",            # 6
    "slot of the page in flight when a power loss cut a run (contents undefined)",  # 7
    "may have been overwritten by a run a power loss cut (header version 1: no journal)",  # 8
    "image of version 1 or 2 whose block table is damaged: its blocks cannot be verified",  # 9
    ("raw dump without its check trailer (cut off, or older firmware): cannot be verified "
     "(--accept-unverified keeps it, marked UNVERIFIED)"),                   # 10
    ("received only in DATA_BLOCKS frames between damaged header copies that do not verify, with no readable copy "
     "of the decoded header on both sides: the memory state they were read from is not proven"),  # 11
)
(_R_MISSING, _R_DAMAGED, _R_TRUNCATED, _R_NOT_RECEIVED, _R_RANGE, _R_CHUNK, _R_UNVERIFIABLE, _R_TORN, _R_NO_JOURNAL,
 _R_TABLE, _R_NO_TRAILER, _R_UNPLACED) = range(12)
#: Reason texts of the step-record losses (the first four as for samples).
STEP_REASONS = REASONS[:4] + (
    "record CRC mismatch (its bytes arrived, but not as the device wrote them: a page write cut by a power loss, "
    "or damage)",                                                           # 4
    "not in the file (an image of version 1 holds no step memory)",          # 5
    REASONS[_R_CHUNK],                                                       # 6
    REASONS[_R_UNVERIFIABLE],                                                # 7
    "overwritten by a record a power loss left uncommitted (after the run's last journal entry)",  # 8
    REASONS[_R_NO_TRAILER],                                                  # 9
    REASONS[_R_UNPLACED],                                                    # 10
)
_S_CRC, _S_NOT_IN_FILE, _S_CHUNK, _S_UNVERIFIABLE, _S_TORN, _S_NO_TRAILER, _S_UNPLACED = 4, 5, 6, 7, 8, 9, 10

_TYPE_HEADER = int(FrameType.HEADER)
_TYPE_DATA = int(FrameType.DATA)
_TYPE_DATA_CRC = int(FrameType.DATA_CRC)
_TYPE_DATA_BLOCKS = int(FrameType.DATA_BLOCKS)
_TYPE_DUMP_END = int(FrameType.DUMP_END)
#: Differing bytes up to which two damaged copies of a header are combined (2^n candidates, each checked by the
#: header's CRC-16 and a copy's frame CRC-16).
COMBINE_MAX_DIFFERING_BYTES = 10
_FLAG_LOGGING = int(HeaderFlag.LOGGING)


def decode_file(path: str | os.PathLike[str], *, accept_unverified: bool = False) -> Recording:
    """Decode the file at ``path`` (image, raw dump or wire capture); errors name the file, missing samples are said
    in one :class:`~gaitlog.host.files.losses.MissingSamplesWarning`.

    ``accept_unverified``: as :func:`decode_bytes`.

    Raises
    ------
    ProtocolError
        The bytes are none of the three formats, or the header is invalid (message: file, offset, reason).
    OSError
        The file cannot be read.
    """
    path = Path(path)
    data = path.read_bytes()
    rec = decode_bytes(data, source=str(path), accept_unverified=accept_unverified)
    say_losses(SampleLosses.from_recording(rec))
    return rec


def decode_bytes(data: bytes, source: str | None = None, *, accept_unverified: bool = False) -> Recording:
    """Decode an image, a raw dump or a wire capture held in memory.

    Parameters
    ----------
    data
        The file's bytes.
    source
        Name used in messages and stored in ``Recording.source``.
    accept_unverified
        Keep the samples of a raw dump without its check trailer (nothing can verify them) as the file holds
        them, marked valid but UNVERIFIED (a warning and the notes); by default they are reported missing.
        No other input is affected.

    Returns
    -------
    Recording
        Stored samples in ring order (oldest first), exact or reported missing (with ``accept_unverified``,
        a raw dump without trailer: as the file holds them, and said so).
    """
    data = bytes(data)
    if not data:
        raise ProtocolError("empty input: expected a memory image, a raw dump or a wire capture", offset=0,
                            source=source)
    try:
        fmt = detect_format(data)
        if fmt == "image":
            return _decode_image(data, source)
        if fmt == "raw":
            return _decode_raw(data, source, accept_unverified)
        if fmt == "capture":
            return _decode_capture(data, source)
        raise ProtocolError(f"unknown input format {fmt!r}", offset=0)  # pragma: no cover
    except ProtocolError as err:
        if err.source is None and source is not None:
            raise err.at(source=source) from err
        raise


# ------------------------------------------------------------------------------------------------ formats
def _decode_image(data: bytes, source: str | None) -> Recording:
    contents = parse_image(data, source=source)
    header = contents.header
    memory = np.asarray(contents.memory, dtype=np.uint8)
    block_size = int(contents.block_size)
    block_ok = np.asarray(contents.block_ok, dtype=bool)
    # Reason per block: marked missing in the table, or damaged/not found (anything else not ok).
    marked = getattr(contents, "block_missing", None)
    if marked is None:
        marked = getattr(contents, "block_marked_missing", None)
    block_reason = np.full(block_ok.size, _R_DAMAGED, dtype=np.int8)
    if marked is not None:
        block_reason[np.asarray(marked, dtype=bool)] = _R_MISSING
    truncated = getattr(contents, "block_truncated", None)
    if truncated is not None:
        block_reason[np.asarray(truncated, dtype=bool)] = _R_TRUNCATED
    if not contents.table_ok:  # versions 1 and 2: no entry of a damaged table can be tied to its block
        block_reason[:] = _R_TABLE
    notes = list(getattr(contents, "notes", []))
    header = _interrupted_run(header, contents.step_memory, source, notes)
    steps = _image_steps(contents, header, block_reason, source, notes)
    if block_size % 4 == 0:
        per = block_size // 4
        slot_ok = np.repeat(block_ok, per)[: memory.size // 4]
        slot_reason = np.repeat(block_reason, per)[: memory.size // 4] if not block_ok.all() else None
    else:  # pragma: no cover - blocks not made of whole samples (the spec uses 1024)
        slot_ok, slot_reason = _slots_from_bytes(np.repeat(block_ok, block_size)[: memory.size],
                                                 np.repeat(block_reason, block_size)[: memory.size])
    return _assemble(header, memory, slot_ok, slot_reason, source, "memory image", notes, steps)


def _image_steps(contents, header, block_reason: np.ndarray, source: str | None, notes: list[str]):
    """Step records of a parsed image: the step memory and which of its bytes come from ok blocks."""
    step_memory = np.asarray(contents.step_memory, dtype=np.uint8)
    byte_ok = np.asarray(contents.step_byte_ok(), dtype=bool)
    if int(contents.image_version) == 1:
        reason = np.full(step_memory.size, _S_NOT_IN_FILE, dtype=np.int8)
    else:
        per_byte = np.repeat(block_reason, int(contents.block_size))
        reason = per_byte[contents.memory.size: contents.memory.size + step_memory.size]
    return _assemble_steps(header, step_memory, byte_ok, reason, source, notes)


def _decode_raw(data: bytes, source: str | None, accept_unverified: bool = False) -> Recording:
    dump = parse_raw_dump(data, source=source)
    header, notes = dump.header, list(dump.notes)
    refused = not dump.verified and not accept_unverified and bool(dump.byte_ok.any())
    if refused:  # no trailer: nothing verifies these bytes, so they are missing unless the user accepts them
        dump.byte_ok = np.zeros_like(dump.byte_ok)
    used, step_used = int(header.used_bytes), int(header.step_used_bytes)
    cap_bytes = int(header.capacity_samples) * 4
    memory = np.full(cap_bytes, 0xFF, dtype=np.uint8)
    memory[:used] = dump.body[HEADER_SIZE: HEADER_SIZE + used]
    byte_ok = np.zeros(cap_bytes, dtype=bool)
    byte_ok[:used] = dump.byte_ok[HEADER_SIZE: HEADER_SIZE + used]
    byte_reason = np.full(cap_bytes, _R_TRUNCATED, dtype=np.int8)
    byte_reason[:used] = np.where(dump.byte_truncated[HEADER_SIZE: HEADER_SIZE + used], _R_TRUNCATED,
                                  _R_CHUNK if dump.verified else _R_NO_TRAILER if refused else _R_UNVERIFIABLE)
    slot_ok, slot_reason = _slots_from_bytes(byte_ok, byte_reason)
    # the step part follows the used sample bytes: step memory bytes 0 .. 20·n_steps_stored (section 5)
    step_memory = np.full(int(header.step_memory_bytes), 0xFF, dtype=np.uint8)
    step_memory[:step_used] = dump.body[HEADER_SIZE + used:]
    step_ok = np.zeros(step_memory.size, dtype=bool)
    step_ok[:step_used] = dump.byte_ok[HEADER_SIZE + used:]
    step_reason = np.full(step_memory.size, _R_TRUNCATED, dtype=np.int8)
    step_reason[:step_used] = np.where(dump.byte_truncated[HEADER_SIZE + used:], _R_TRUNCATED,
                                       _S_CHUNK if dump.verified else _S_NO_TRAILER if refused else _S_UNVERIFIABLE)
    header = _interrupted_run(header, step_memory, source, notes)
    steps = _assemble_steps(header, step_memory, step_ok, step_reason, source, notes)
    rec = _assemble(header, memory, slot_ok, slot_reason, source, "raw XMODEM dump", notes, steps)
    if dump.verified:
        rec.notes.insert(1, "verified: every sample marked valid is exact (checked by the raw dump's check trailer)")
    elif refused:
        present = int((~dump.byte_truncated[HEADER_SIZE: HEADER_SIZE + used]).sum()) // 4
        text = (f"verified: NO: raw dump without its check trailer (cut off, or older firmware): its {present} "
                "samples present cannot be verified and are reported missing (--accept-unverified keeps them, "
                "marked UNVERIFIED)")
        rec.notes.insert(1, text)
        warnings.warn(f"{source or 'raw dump'}: {text}", stacklevel=3)
    elif not dump.byte_ok.any():
        text = f"verified: NO: {notes[0]}"
        rec.notes.insert(1, text)
        warnings.warn(f"{source or 'raw dump'}: {text}", stacklevel=3)
    else:
        text = (f"verified: NO: {int(rec.valid.sum())} samples and {rec.n_step_records} step records UNVERIFIED, "
                f"kept as the file holds them (--accept-unverified): {notes[0]}")
        rec.notes.insert(1, text)
        warnings.warn(f"{source or 'raw dump'}: {text}", stacklevel=3)
    return rec


def _decode_capture(data: bytes, source: str | None) -> Recording:
    frames, errors = parse_stream(data, source=source)
    known, unreadable = _header_boundaries(data, frames, errors)
    combined = _combined_header(data, unreadable) if not known else None
    if combined is not None:
        known = [(off, combined, True) for off in unreadable.tolist()]
        unreadable = unreadable[:0]
    if not known:
        damaged = unreadable.size
        raise ProtocolError(
            f"wire capture has no intact HEADER frame (type 0x86) among {len(frames)} intact frames and "
            f"{len(errors)} framing errors"
            + (f", and the {damaged} damaged one(s) do not verify (the header's own CRC-16 or the rules of section 2 "
               "fail, or LOGGING is set and its journal is outside that CRC)" if damaged else "")
            + ": cannot place the samples", offset=int(unreadable[0]) if damaged else 0, source=source)
    notes = []
    header_offset, header_bytes, salvaged = known[-1]
    try:
        header = DeviceHeader.from_bytes(header_bytes, source=source)
    except ProtocolError as err:
        raise err.at(offset=header_offset + 6) from err
    if combined is not None:
        text = (f"every HEADER frame is damaged; the header was put together from {len(known)} damaged copies "
                "(each byte where they differ taken from the copy whose choice passes the header's CRC-16 and a "
                "copy's frame CRC-16)")
        notes.append(text)
        warnings.warn(f"{source or 'capture'}: {text}", stacklevel=3)
    elif salvaged:
        text = (f"the HEADER frame at offset {header_offset} is damaged (its frame CRC-16 or framing failed); the "
                "256-byte header it carries passed its own CRC-16 and every rule of section 2 (LOGGING clear: the "
                "journal outside that CRC is not used) and places the samples")
        notes.append(text)
        warnings.warn(f"{source or 'capture'}: {text}", stacklevel=3)
    data_frames, rejected = _checked_data_frames(frames)
    if rejected:
        notes.append(f"{rejected} DATA frame(s) of a DUMP_CHECKED stream not used: their DATA_CRC frame was damaged, "
                     "or its CRC-32 differs from the bytes received (section 4)")
    data_frames, foreign, unknown = _frames_of_header(known, unreadable, header_bytes, data_frames)
    if foreign:
        others = {h for _, h, _ in known if _header_key(h) != _header_key(header_bytes)}
        ids = sorted({_recording_text(h) for h in others} - {_recording_text(header_bytes)})
        why = (f"{len(ids)} other recording(s) ({', '.join(ids)})" if ids else
               f"{len(others)} other state(s) of this recording's header" if others else "no known header")
        text = (f"the capture spans {len(others) + unknown + 1} device headers: decoded "
                f"{_recording_text(header_bytes)} (HEADER frame at offset {header_offset}); {foreign} DATA frame(s) "
                f"under {why}"
                + (f", or under {unknown} damaged HEADER frame(s) that do not verify" if unknown else "")
                + ", or before any HEADER frame, were not used")
        notes.append(text)
        warnings.warn(f"{source or 'capture'}: {text}", stacklevel=3)
    cap_bytes = int(header.capacity_samples) * 4
    step_bytes = int(header.step_memory_bytes)
    memory = np.zeros(cap_bytes, dtype=np.uint8)
    covered = np.zeros(cap_bytes, dtype=bool)
    step_memory = np.full(step_bytes, 0xFF, dtype=np.uint8)
    step_covered = np.zeros(step_bytes, dtype=bool)
    outside = _place([(int.from_bytes(fr.payload[:4], "little"), fr.payload[4:]) for fr in data_frames], memory,
                     covered, step_memory, step_covered)
    blocks = _capture_blocks(data, frames, errors, known, unreadable, header_bytes)
    outside += _place(blocks.pieces, memory, covered, step_memory, step_covered)
    if blocks.salvaged:
        notes.append(f"{blocks.salvaged} 64-sample block(s) kept from damaged DATA_BLOCKS frames (their checks verify "
                     "at their addresses under this header, section 4.1)")
    if blocks.foreign:
        notes.append(f"{blocks.foreign} DATA_BLOCKS frame(s) under another header were not used")
    unplaced, step_unplaced = np.zeros(cap_bytes, dtype=bool), np.zeros(step_bytes, dtype=bool)
    _place(blocks.unplaced_pieces, np.zeros(cap_bytes, np.uint8), unplaced, np.zeros(step_bytes, np.uint8),
           step_unplaced)  # where only blocks of frames no readable header places were received
    if blocks.unplaced:
        text = (f"{blocks.unplaced} DATA_BLOCKS frame(s) not used although their blocks verify under this header's "
                "binding: each lies between damaged header copies that do not verify, with no readable copy of this "
                "header on both sides, so the memory state it was read from is not proven (section 4.1)")
        notes.append(text)
        warnings.warn(f"{source or 'capture'}: {text}", stacklevel=3)
    if outside:
        notes.append(f"{outside} DATA frame(s) addressed outside the {cap_bytes}-byte sample memory and the "
                     f"{step_bytes}-byte step memory were ignored")
    if errors:
        notes.append(f"{len(errors)} framing error(s) in the capture (their bytes were not used)")
    slot_ok = covered.reshape(-1, 4).all(axis=1)
    slot_reason = np.full(slot_ok.size, _R_NOT_RECEIVED, dtype=np.int8)
    slot_reason[unplaced.reshape(-1, 4).any(axis=1) & ~slot_ok] = _R_UNPLACED
    step_reason = np.full(step_bytes, _R_NOT_RECEIVED, np.int8)
    step_reason[step_unplaced & ~step_covered] = _S_UNPLACED
    header = _interrupted_run(header, step_memory, source, notes)
    steps = _assemble_steps(header, step_memory, step_covered, step_reason, source, notes)
    return _assemble(header, memory, slot_ok, slot_reason, source, "wire capture", notes, steps)


def _place(pieces: list[tuple[int, bytes]], memory: np.ndarray, covered: np.ndarray, step_memory: np.ndarray,
           step_covered: np.ndarray) -> int:
    """Write ``(address, bytes)`` pieces into the sample or the step memory and mark them covered; return how many
    were addressed outside both."""
    outside = 0
    for address, chunk_bytes in pieces:
        where = memory_region(address, len(chunk_bytes), sample_memory_bytes=covered.size,
                              step_memory_bytes=step_covered.size)
        if where is None:
            outside += 1
            continue
        region, offset = where
        target, seen = (memory, covered) if region == "samples" else (step_memory, step_covered)
        target[offset: offset + len(chunk_bytes)] = np.frombuffer(chunk_bytes, dtype=np.uint8)
        seen[offset: offset + len(chunk_bytes)] = True
    return outside


def _header_boundaries(data: bytes, frames: list, errors: list
                       ) -> tuple[list[tuple[int, bytes, bool]], np.ndarray]:
    """Where a device header starts in a capture: ``(frame offset, header bytes, salvaged)`` of the headers
    that can be read, in stream order, and the frame offsets of those that cannot.

    An intact HEADER frame gives its payload (``salvaged`` False). In the bytes of no intact frame, a damaged
    HEADER frame is looked for: the magic ``GLOG`` (its payload) or a sync with type 0x86. Its 256 bytes are
    used (``salvaged`` True) only when they pass the header's own CRC-16 and every rule of ``PROTOCOL.md``
    section 2 and LOGGING is clear (version 2 keeps the journal, which a decoder would then need, outside
    that CRC); otherwise it is unreadable: the DATA frames after it belong to a header nobody can read, and
    are not used under an earlier one. Vectorised, so that a hostile file full of ``GLOG`` costs little.
    """
    n = len(data)
    known: dict[int, tuple[bytes, bool]] = {}
    for fr in frames:
        if fr.type == _TYPE_HEADER and len(fr.payload) == HEADER_SIZE:
            known[fr.offset] = (bytes(fr.payload), False)
    b = np.frombuffer(data, dtype=np.uint8)
    at = np.flatnonzero(np.all([b[k: n - 3 + k] == MAGIC[k] for k in range(4)], axis=0)) if n >= 4 else \
        np.zeros(0, np.int64)
    typed = [e.offset + 6 for e in errors
             if data[e.offset: e.offset + 2] == SYNC and data[e.offset + 2: e.offset + 3] == bytes([_TYPE_HEADER])]
    if typed:
        at = np.sort(np.concatenate([at, np.asarray(typed, dtype=np.int64)]))
        at = at[np.r_[True, at[1:] != at[:-1]]]
    # not inside an intact frame (intact frames do not overlap: the parser consumed each)
    starts = np.array([fr.offset for fr in frames], dtype=np.int64)
    ends = starts + np.array([8 + len(fr.payload) for fr in frames], dtype=np.int64)
    k = np.searchsorted(starts, at, side="right") - 1
    at = at[(at < n) & ~((k >= 0) & (at < ends[np.maximum(k, 0)] if ends.size else False))]
    # the fixed bytes of section 2 (a known header version, protocol 1, 1-8 axes: 3 or a channel map's, P32)
    # before any CRC or parse
    idx = np.flatnonzero(at + HEADER_SIZE <= n)
    w = at[idx]
    idx = idx[np.isin(b[w + 4], KNOWN_HEADER_VERSIONS) & (b[w + 5] == 1) & (b[w + 17] >= 1) & (b[w + 17] <= 8)
              & (b[w + 18] == 1)]
    readable = np.zeros(at.size, dtype=bool)
    for i in idx.tolist():
        payload_at = int(at[i])
        raw = data[payload_at: payload_at + HEADER_SIZE]
        if _closed_header(raw):
            known[payload_at - 6] = (raw, True)
            readable[i] = True
    unreadable = at[~readable] - 6
    return [(off, raw, salvaged) for off, (raw, salvaged) in sorted(known.items())], unreadable


def _closed_header(raw: bytes) -> bool:
    """``raw`` is a header that a salvage may use: its own CRC-16 verifies, it parses, and it is version 1 or has
    LOGGING clear (section 2)."""
    if crc16_xmodem(crc_span(raw[:-2])) != int.from_bytes(raw[-2:], "big"):
        return False
    try:
        h = DeviceHeader.from_bytes(raw)
    except ProtocolError:
        return False
    return h.header_version == 1 or not h.logging


def _header_key(header_bytes: bytes) -> bytes:
    """The bytes that name a memory's state: the whole header, or with LOGGING clear (version 2) the part its
    CRC covers (the journal is then meaningless, section 2.4)."""
    if len(header_bytes) == HEADER_SIZE and header_bytes[4] != 1 and not header_bytes[19] & _FLAG_LOGGING:
        return crc_span(header_bytes[:-2]) + header_bytes[-2:]
    return header_bytes


def _combined_header(data: bytes, unreadable: np.ndarray) -> bytes | None:
    """A header put together from two damaged HEADER frames (section 4.1): where the copies differ, each choice
    of bytes is tried; it is used only when exactly one choice passes the header's own CRC-16, a copy's frame
    CRC-16 (over that copy's type, seq and length) and the rules of section 2 (LOGGING clear). None otherwise."""
    copies = [int(off) for off in unreadable.tolist() if off >= 0 and off + FRAME_OVERHEAD + HEADER_SIZE <= len(data)]
    for i, a in enumerate(copies):
        for b in copies[i + 1:]:
            found = _combine_pair(data, a, b)
            if found is not None:
                return found
    return None


def _combine_pair(data: bytes, a: int, b: int) -> bytes | None:
    pa = np.frombuffer(data, np.uint8, HEADER_SIZE, a + 6)
    pb = np.frombuffer(data, np.uint8, HEADER_SIZE, b + 6)
    differ = np.flatnonzero(pa != pb)
    if not 0 < differ.size <= COMBINE_MAX_DIFFERING_BYTES:
        return None
    heads = [(data[o + 2: o + 6], int.from_bytes(data[o + 6 + HEADER_SIZE: o + 8 + HEADER_SIZE], "big")) for o in (a, b)]
    good = set()
    trial = pa.copy()
    for choice in range(1 << differ.size):
        pick = np.array([(choice >> k) & 1 for k in range(differ.size)], dtype=bool)
        trial[differ] = np.where(pick, pb[differ], pa[differ])
        raw = trial.tobytes()
        if any(crc16_xmodem(raw, crc16_xmodem(head)) == stored for head, stored in heads) and _closed_header(raw):
            good.add(raw)
    return good.pop() if len(good) == 1 else None


class _CaptureBlocks:
    """The 64-sample blocks of a capture's DATA_BLOCKS frames that verify under the decoded header."""

    def __init__(self) -> None:
        self.pieces: list[tuple[int, bytes]] = []
        self.salvaged = 0
        self.foreign = 0
        self.unplaced = 0  #: intact frames whose blocks verify, but whose memory state no readable header proves
        self.unplaced_pieces: list[tuple[int, bytes]] = []

    def take(self, pieces: list[tuple[int, bytes]], belongs: bool) -> None:
        """The verified blocks of an intact frame: used when it belongs to the header, else counted (those that
        verify all the same are kept apart, to say why the samples they carry are missing)."""
        if belongs:
            self.pieces += pieces
        elif pieces:
            self.unplaced += 1
            self.unplaced_pieces += pieces
        else:
            self.foreign += 1


def _belongs_to(header_bytes: bytes, known: list, unreadable: np.ndarray):
    """``belongs(offset)``: a DATA_BLOCKS frame at ``offset`` belongs to ``header_bytes`` (section 4.1).

    It does when the nearest header before it or after it is readable and of the same memory state. It also does
    when both are damaged but the nearest readable headers on both sides are of that state and it is closed
    (version 2, LOGGING clear): such a state never comes back once the memory changed (START draws a new recording
    number and nonce, ERASE zeroes the counters), so every header between is of it too (a retried stream whose
    header copy and the copy before it were both damaged)."""
    key = _header_key(header_bytes)
    h_off = np.array([off for off, _, _ in known] + unreadable.tolist(), dtype=np.int64)
    h_ok = np.array([_header_key(h) == key for _, h, _ in known] + [False] * unreadable.size, dtype=bool)
    order = np.argsort(h_off, kind="stable")
    h_off, h_ok = h_off[order], h_ok[order]
    closed = len(header_bytes) == HEADER_SIZE and header_bytes[4] != 1 and not header_bytes[19] & _FLAG_LOGGING
    r_off = np.array([off for off, _, _ in known], dtype=np.int64)
    r_ok = np.array([_header_key(h) == key for _, h, _ in known], dtype=bool)

    def belongs(offset: int) -> bool:
        k = int(np.searchsorted(h_off, offset, side="right")) - 1
        if (k >= 0 and h_ok[k]) or (k + 1 < h_off.size and h_ok[k + 1]):
            return True
        j = int(np.searchsorted(r_off, offset, side="right")) - 1
        return bool(closed and j >= 0 and j + 1 < r_off.size and r_ok[j] and r_ok[j + 1])

    return belongs


def _capture_blocks(data: bytes, frames: list, errors: list, known: list, unreadable: np.ndarray,
                    header_bytes: bytes) -> _CaptureBlocks:
    """Blocks of intact DATA_BLOCKS frames, and of damaged ones found again inside their frames (section 4.1).

    A frame belongs to the header when the nearest device header before it or after it (the copy a DUMP_BLOCKS
    stream ends with) is readable and of the same memory state; every block must verify under that header's
    ``binding``. A damaged frame is looked for at each sync with type 0x8A in the errors and where an intact
    frame ends and no intact frame follows (a damaged sync); its blocks are tried at the addresses its own
    address field and its intact neighbours imply, for the extent its length field and the next intact frame
    imply.
    """
    out = _CaptureBlocks()
    binding = header_binding(header_bytes)
    belongs = _belongs_to(header_bytes, known, unreadable)
    intact = [fr for fr in frames if fr.type == _TYPE_DATA_BLOCKS and payload_data_bytes(len(fr.payload))]
    spans = []  # (stream offset, end, first address, data bytes) of the intact DATA_BLOCKS frames
    for fr in intact:
        address = int.from_bytes(fr.payload[:ADDRESS_BYTES], "little")
        spans.append((fr.offset, fr.offset + FRAME_OVERHEAD + len(fr.payload), address,
                      payload_data_bytes(len(fr.payload))))
        out.take(salvage_blocks(binding, fr.payload[ADDRESS_BYTES:], [address]).pieces(), belongs(fr.offset))
    starts_all = np.array([fr.offset for fr in frames], dtype=np.int64)
    ends_all = starts_all + np.array([FRAME_OVERHEAD + len(fr.payload) for fr in frames], dtype=np.int64)
    starts_set = set(starts_all.tolist())
    if not _holds_blocks(data, frames, errors):  # a capture of protocol version 1: decoded as before
        return out
    todo = {e.offset for e in errors if data[e.offset: e.offset + 2] == SYNC}
    todo |= {int(e) for e in ends_all.tolist() if e < len(data) and e not in starts_set}
    ends_of_streams = [(fr.offset, int.from_bytes(fr.payload[:4], "little"), int.from_bytes(fr.payload[8:10], "little"))
                       for fr in frames if fr.type == _TYPE_DUMP_END and len(fr.payload) == 10]
    lengths = [FRAME_OVERHEAD + len(fr.payload) for fr in intact]
    frame_bytes = max(set(lengths), key=lengths.count) if lengths else 0  # the stream's usual frame
    done: set[int] = set()
    while todo:
        s = min(todo)
        todo.discard(s)
        done.add(s)
        if s in starts_set or not belongs(s):
            continue
        found, ends = _salvage_frame(data, s, starts_all, spans, binding, frame_bytes, ends_of_streams)
        out.salvaged += len(found)
        out.pieces += found
        if found:  # the next frame may be damaged too, its sync included: look where this one ends
            todo |= {e for e in ends if e < len(data) and e not in done}
    return out


def _holds_blocks(data: bytes, frames: list, errors: list) -> bool:
    """The capture is of DUMP_BLOCKS streams: an intact DATA_BLOCKS frame, a damaged one whose sync and type
    survived, or a HEADER frame followed by DUMP_END (how a DUMP_BLOCKS stream ends)."""
    if any(fr.type == _TYPE_DATA_BLOCKS for fr in frames):
        return True
    if any(data[e.offset: e.offset + 3] == SYNC + bytes([_TYPE_DATA_BLOCKS]) for e in errors):
        return True
    return any(a.type == _TYPE_HEADER and b.type == _TYPE_DUMP_END for a, b in zip(frames, frames[1:]))


def _salvage_frame(data: bytes, s: int, starts_all: np.ndarray, spans: list, binding: int, frame_bytes: int,
                   ends_of_streams: list) -> tuple[list, set[int]]:
    """The verified blocks of a damaged DATA_BLOCKS frame starting at stream offset ``s``, and the ends tried
    (its length field's when the frame it gives ends where the next frame starts, else that, the stream's usual
    frame length and the next intact frame; in that case only the blocks before the first bad one are kept).
    Addresses tried: its address field, the intact DATA_BLOCKS frames before and after it, and the first address
    of the stream of the next intact DUMP_END."""
    k = int(np.searchsorted(starts_all, s, side="right"))
    next_start = int(starts_all[k]) if k < starts_all.size else len(data)
    length = int.from_bytes(data[s + 4: s + 6], "little") if s + 6 <= len(data) else 0
    end = s + FRAME_OVERHEAD + length
    # its length field ends it where the next frame (or the capture) starts: no byte dropped or inserted inside
    whole = bool(payload_data_bytes(length)) and end <= next_start and (
        end == next_start or end == len(data) or data[end: end + 2] == SYNC  # the next frame: its sync or its type
        or data[end + 2: end + 3] in (bytes([_TYPE_HEADER]), bytes([_TYPE_DUMP_END]), bytes([_TYPE_DATA_BLOCKS])))
    extents = {end} if whole else {next_start}
    for size in (() if whole else (FRAME_OVERHEAD + length, frame_bytes)):
        if size > FRAME_OVERHEAD and payload_data_bytes(size - FRAME_OVERHEAD) and s + size <= next_start:
            extents.add(s + size)
    before = [sp for sp in spans if sp[1] <= s]
    after = [sp for sp in spans if sp[0] >= s + FRAME_OVERHEAD]
    found: dict[int, bytes] = {}
    for end in sorted(extents):
        body = data[s + 6 + ADDRESS_BYTES: end - 2]
        n_data = payload_data_bytes(ADDRESS_BYTES + len(body)) or 0
        addresses = [int.from_bytes(data[s + 6: s + 10], "little")] if s + 10 <= len(data) else []
        if before:
            prev_end = before[-1][2] + before[-1][3]
            addresses += [prev_end, prev_end + before[-1][3]]
        if after:
            addresses.append(after[0][2] - n_data)
        stream_end = next((e for e in ends_of_streams if e[0] > s), None)
        if stream_end is not None:  # the stream's first frame
            addresses.append(stream_end[1])
        got = salvage_blocks(binding, body, addresses)
        # a frame whose extent is uncertain (bytes dropped or inserted, or its length field hit) may be shifted
        # after its first bad block: only the blocks before it are certain to be where they verify
        for address, chunk in (got if whole else got.leading()).pieces():
            found.setdefault(address, chunk)
    return list(found.items()), extents


def _checked_data_frames(frames: list) -> tuple[list, int]:
    """The DATA frames to use, and how many were rejected: in a capture holding DATA_CRC frames (a DUMP_CHECKED
    stream, section 4) a DATA frame is used only when the next intact frame is a DATA_CRC with its address and
    the CRC-32 of its data bytes; in one without (DUMP, READ) on its CRC-16 (as a host without DUMP_CHECKED)."""
    checked = any(fr.type == _TYPE_DATA_CRC for fr in frames)
    out, rejected = [], 0
    for k, fr in enumerate(frames):
        if fr.type != _TYPE_DATA or len(fr.payload) < 4:
            continue
        if checked:
            nxt = frames[k + 1] if k + 1 < len(frames) else None
            if (nxt is None or nxt.type != _TYPE_DATA_CRC or len(nxt.payload) != 8
                    or nxt.payload[:4] != fr.payload[:4]
                    or int.from_bytes(nxt.payload[4:], "little") != crc32(fr.payload[4:])):
                rejected += 1
                continue
        out.append(fr)
    return out, rejected


def _recording_text(header_bytes: bytes) -> str:
    """``recording N of device D`` (section 2.4) of a HEADER frame's bytes, for messages."""
    try:
        h = DeviceHeader.from_bytes(header_bytes)
    except ProtocolError:
        return "an invalid header"
    return (f"recording {h.recording_number} (nonce 0x{h.recording_nonce:08x}) of device {h.device_id}"
            if h.header_version != 1 else f"an unnumbered recording of device {h.device_id} (header version 1)")


def _frames_of_header(known: list[tuple[int, bytes, bool]], unreadable: np.ndarray, header_bytes: bytes,
                      data_frames: list) -> tuple[list, int, int]:
    """The DATA frames that follow a header of the same state as ``header_bytes`` (the memory it describes),
    how many others there were, and how many damaged HEADER frames that do not verify there were: frames
    under another header belong to another recording (or another state of the memory), frames under a
    damaged one to a header nobody can read, frames before the first HEADER frame to no known one (section 4)."""
    key = _header_key(header_bytes)
    starts = np.concatenate([np.array([off for off, _, _ in known], dtype=np.int64), unreadable.astype(np.int64)])
    same = np.concatenate([np.array([_header_key(h) == key for _, h, _ in known], dtype=bool),
                           np.zeros(unreadable.size, dtype=bool)])
    order = np.argsort(starts, kind="stable")
    starts, same = starts[order], same[order]
    offsets = np.array([fr.offset for fr in data_frames], dtype=np.int64)
    k = np.searchsorted(starts, offsets, side="right") - 1
    keep = (k >= 0) & same[np.maximum(k, 0)]
    return [fr for fr, ok in zip(data_frames, keep.tolist()) if ok], int((~keep).sum()), int(unreadable.size)


# ------------------------------------------------------------------------------------ interrupted runs
def _interrupted_run(header, step_memory, source: str | None, notes: list[str]):
    """The header to decode with, and what a power loss cost (``PROTOCOL.md`` section 2.4), said in a note
    and a warning.

    A header with ``LOGGING`` set was read while a run was in progress or after a power loss cut it (the data
    EEPROM as it was left): version 2 is recovered from its page-commit journal, exactly as the device does
    at power-up (``DeviceHeader.recovered``); version 1 has no journal, so the run's samples are lost and,
    in OVERWRITE mode, every stored sample may have been overwritten by them (reported missing); version 3
    keeps its journal in the step EEPROM's ring (section 2.7), which no input holds, so no page of the run is
    recovered. A header with ``POWER_LOST`` (a device that powered up after the cut) needs no recovery, only
    the report (at most two pages lost in version 3).
    """
    if header.logging and header.header_version == 1:
        text = (f"the header (version 1) has LOGGING set: a run started at sample {header.run_start_sample} was "
                "in progress or cut by a power loss, and version 1 has no commit journal: its samples are lost"
                + (", and in OVERWRITE mode it may have overwritten any stored sample: all are reported missing"
                   if header.overwrite else " (stop-when-full: the samples before it are intact)"))
        notes.append(text)
        warnings.warn(f"{source or 'input'}: {text}", stacklevel=4)
        return header
    ring = header.header_version == HEADER_VERSION_RING
    if header.logging:
        header = header.recovered()
        header.torn_step_records = torn_step_records(header, np.asarray(step_memory, np.uint8))
        notes.append("the header has LOGGING set (read during a run, or left so by a power loss): recovered "
                     + ("from its page-commit journal as the device does at power-up" if not ring else
                        "without its journal ring (header version 3 keeps it in the step EEPROM, not in the input): "
                        "no page of the run is recovered"))
    if header.power_lost:
        last = int(header.samples_written) - 1
        text = (f"recording {header.recording_number} (device {header.device_id}) was cut by a power loss: its "
                f"samples {header.run_start_sample} … {last} (to the last committed page) are recovered "
                f"({int(header.samples_written) - int(header.run_start_sample)} samples); the samples it took "
                f"after sample {last} (at most {'two' if ring else 'one'} {PAGE_SAMPLES}-sample "
                f"page{'s' if ring else ''}) were lost")
        if header.torn_slot_numbers().size:
            text += (f"; the {header.torn_slots} oldest stored samples were in the page{'s' if ring else ''} in "
                     "flight and are reported missing")
        if header.torn_step_records:
            text += (f"; the {header.torn_step_records} oldest stored step record(s) were overwritten by records "
                     "after the last commit and are dropped")
        notes.append(text)
        warnings.warn(f"{source or 'input'}: {text}", stacklevel=4)
    return header


# ------------------------------------------------------------------------------------------------ common
def _slots_from_bytes(byte_ok: np.ndarray, byte_reason: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-slot validity (all four bytes ok) and reason (that of the first bad byte)."""
    n = byte_ok.size // 4
    ok4 = byte_ok[: 4 * n].reshape(n, 4)
    r4 = byte_reason[: 4 * n].reshape(n, 4)
    return ok4.all(axis=1), r4[np.arange(n), np.argmin(ok4, axis=1)]


def _assemble_steps(header, step_memory: np.ndarray, byte_ok: np.ndarray, byte_reason: np.ndarray,
                    source: str | None, notes: list[str]) -> tuple[np.ndarray, np.ndarray, list[RecordGap]]:
    """The stored step records in ring order, keeping only those received intact with a matching CRC.

    Parameters
    ----------
    step_memory
        ``(20 · step_capacity,)`` uint8, the step memory from its address 0 (bytes not received: anything).
    byte_ok
        ``(20 · step_capacity,)`` bool: the byte was received intact.
    byte_reason
        ``(20 · step_capacity,)`` index into :data:`STEP_REASONS` of a byte that is not ok.

    Returns
    -------
    records, numbers, losses
        The usable records (:data:`~gaitlog.protocol.steps.STEP_RECORD_DTYPE`, ring order), their absolute record
        numbers, and the runs of dropped records with their reason. A note (and a warning) counts the drops.
    """
    n = int(header.n_steps_stored)
    if n == 0:
        return np.zeros(0, STEP_RECORD_DTYPE), np.zeros(0, np.int64), []
    records, crc_ok, slots = stored_step_records(header, step_memory)
    ok_rows = np.asarray(byte_ok, bool).reshape(-1, STEP_RECORD_SIZE)[slots]
    bytes_ok = ok_rows.all(axis=1)
    reason = np.where(bytes_ok, _S_CRC, np.asarray(byte_reason).reshape(-1, STEP_RECORD_SIZE)[slots][
        np.arange(n), np.argmin(ok_rows, axis=1)]).astype(np.int64)
    usable = bytes_ok & crc_ok
    lost_to_run = np.zeros(n, dtype=bool)
    lost_to_run[: min(int(header.torn_step_records), n)] = True  # oldest first (section 2.4)
    if header.logging:  # version 1, cut: records of the lost run overwrote counted ones (their end_sample tells)
        lost_to_run |= records["end_sample"].astype(np.int64) >= int(header.run_start_sample)
    reason[lost_to_run] = _S_TORN
    usable &= ~lost_to_run
    numbers = int(header.first_step_number) + np.arange(n, dtype=np.int64)
    losses = [RecordGap(g.first_sample_number, g.last_sample_number, g.reason)
              for g in gaps_from_mask(usable, numbers, reason, STEP_REASONS)]
    dropped = n - int(usable.sum())
    if dropped:
        why = Counter(STEP_REASONS[k] for k in reason[~usable].tolist())
        text = (f"{dropped} of the {n} stored step records dropped (never repaired): "
                + "; ".join(f"{c} {r}" for r, c in why.items()))
        notes.append(text)
        warnings.warn(f"{source or 'input'}: {text}", stacklevel=4)
    return records[usable], numbers[usable], losses


def _assemble(header, memory: np.ndarray, slot_ok: np.ndarray, slot_reason: np.ndarray | None,
              source: str | None, kind: str, notes: list[str],
              steps: tuple[np.ndarray, np.ndarray, list[RecordGap]] | None = None) -> Recording:
    """Restore ring order and unpack: ``PROTOCOL.md`` section 2 (derived quantities) and section 1.

    ``slot_ok[k]``: all four bytes of slot ``k`` were received intact; ``slot_reason[k]``: index into
    :data:`REASONS` of a bad slot (None: reason 0 everywhere). Slots beyond ``memory`` are truncated.
    """
    capacity = int(header.capacity_samples)
    n = int(header.n_stored)
    first = int(header.first_slot)
    n_avail = min(memory.size // 4, capacity, slot_ok.size)
    if n_avail == capacity:
        words_all = memory[: 4 * capacity].view("<u4")
        ok_all = slot_ok[:capacity]
        reason_all = slot_reason[:capacity] if slot_reason is not None else None
    else:
        words_all = np.zeros(capacity, dtype="<u4")
        words_all[:n_avail] = memory[: 4 * n_avail].view("<u4")
        ok_all = np.zeros(capacity, dtype=bool)
        ok_all[:n_avail] = slot_ok[:n_avail]
        reason_all = np.full(capacity, _R_TRUNCATED, dtype=np.int8)
        if slot_reason is not None:
            reason_all[:n_avail] = slot_reason[:n_avail]
        else:
            reason_all[:n_avail] = 0
    torn = header.torn_slot_numbers()
    if torn.size or (header.logging and header.overwrite):  # section 2.4: the page in flight / no journal
        ok_all = ok_all.copy()
        reason_all = np.zeros(capacity, np.int8) if reason_all is None else reason_all.copy()
        if header.logging:
            ok_all[:] = False
            reason_all[:] = _R_NO_JOURNAL
        ok_all[torn] = False
        reason_all[torn] = _R_TORN
    # Ring order: slot (first + i) mod capacity for i = 0 .. n-1 (contiguous pieces, no fancy index).
    head = min(n, capacity - first)
    order = [slice(first, first + head)]
    if n > head:
        order.append(slice(0, n - head))
    words = np.concatenate([words_all[s] for s in order]) if n else np.zeros(0, "<u4")
    valid = np.concatenate([ok_all[s] for s in order]) if n else np.zeros(0, bool)
    if reason_all is None:
        reason = np.zeros(n, dtype=np.int8)
    else:
        reason = np.concatenate([reason_all[s] for s in order]) if n else np.zeros(0, np.int8)
    codes, flags = unpack_words(words)
    codes = np.asarray(codes, dtype=np.uint16)
    flags = np.asarray(flags, dtype=np.uint8)
    adc_bits = int(header.adc_bits)
    if adc_bits < 10 and n:
        out_of_range = (codes > (1 << adc_bits) - 1).any(axis=1) & valid
        if out_of_range.any():
            reason[out_of_range] = _R_RANGE
            valid &= ~out_of_range
            notes.append(f"{int(out_of_range.sum())} sample(s) with codes above the {adc_bits}-bit ADC range "
                         "reported missing")
    if not valid.all():
        codes = codes.copy()
        flags = flags.copy()
        codes[~valid] = 0
        flags[~valid] = 0
    first_sn = int(header.first_sample_number)
    sample_numbers = first_sn + np.arange(n, dtype=np.int64)
    gaps = gaps_from_mask(valid, sample_numbers, reason, REASONS)
    step_records, step_numbers, step_losses = steps if steps is not None else (None, None, [])
    rec = Recording(codes=codes, valid=valid, flags=flags, sample_numbers=sample_numbers,
                    sampling_rate_hz=float(header.sampling_rate_hz), start_time_s=float(header.sample_time_s(0)),
                    header=header, gaps=gaps, adc_bits=adc_bits, source=source,
                    notes=[f"decoded from a {kind}"] + notes, step_records=step_records,
                    step_record_numbers=step_numbers, step_losses=step_losses)
    rec.notes.append(rec.default_calibration()[1])
    cfg = getattr(header, "step_config", None)
    if cfg is not None and cfg.older_algorithm:
        rec.notes.append(f"step records (their on-line lengths) written by {cfg.older_algorithm}; "
                         f"this host's replay is version {int(ONLINE_ALGORITHM_VERSION)}")
    return rec


def output_paths(prefix: str | os.PathLike[str]) -> dict[str, Path]:
    """``PREFIX.npz``, ``PREFIX.csv`` and ``PREFIX.steps.csv`` (a ``.csv``/``.npz`` suffix of ``prefix`` is dropped)."""
    prefix = Path(prefix)
    if prefix.suffix in (".csv", ".npz"):
        prefix = prefix.with_suffix("")
    return {"npz": prefix.with_name(prefix.name + ".npz"), "csv": prefix.with_name(prefix.name + ".csv"),
            "steps_csv": prefix.with_name(prefix.name + ".steps.csv")}


def save_decoded(recording: Recording, prefix: str | os.PathLike[str], calibration=None, *,
                 steps_csv: bool = True) -> list[Path]:
    """Write ``PREFIX.npz``, ``PREFIX.csv`` and, with ``steps_csv`` and step records, ``PREFIX.steps.csv``.

    Each file is written atomically, and all or none: a failure removes the files this call wrote. Returns the
    paths written.
    """
    paths = output_paths(prefix)
    parent = paths["npz"].parent
    if parent and not parent.exists():
        raise HostError(f"output directory {parent} does not exist")
    written: list[Path] = []
    try:
        recording.save_npz(paths["npz"])
        written.append(paths["npz"])
        recording.to_csv(paths["csv"], calibration)
        written.append(paths["csv"])
        if steps_csv and recording.n_step_records:
            recording.to_steps_csv(paths["steps_csv"])
            written.append(paths["steps_csv"])
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return written


def save_outputs(recording: Recording, prefix: str | os.PathLike[str], calibration=None) -> tuple[Path, Path]:
    """Write ``PREFIX.npz`` and ``PREFIX.csv`` (atomically each; the CSV only after the NPZ succeeded)."""
    npz, csv = save_decoded(recording, prefix, calibration, steps_csv=False)
    return npz, csv
