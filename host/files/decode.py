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
from gaitlog.protocol.capture_salvage import (
    PAYLOAD_AT,
    BlocksFrames,
    closed_state,
    combined_header,
    find_header_copies,
    state_key,
)
from gaitlog.protocol.commit_journal import torn_step_records
from gaitlog.protocol.crc import crc32
from gaitlog.protocol.data_blocks import header_binding, verified_blocks
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import PAYLOAD_OFFSETS, PAYLOAD_STRUCTS, FrameType, parse_payload, parse_stream
from gaitlog.protocol.header import HEADER_SIZE, PAGE_SAMPLES, DeviceHeader
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

_TYPE_DATA = int(FrameType.DATA)
_TYPE_DATA_CRC = int(FrameType.DATA_CRC)
_DATA_AT = PAYLOAD_OFFSETS[FrameType.DATA]["data"]  # a DATA payload's address field is before it
_DATA_CRC_BYTES = PAYLOAD_STRUCTS[FrameType.DATA_CRC].sizeof()


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
    known, unreadable, combined = _capture_headers(data, frames, errors, source)
    header_offset, header_bytes, salvaged = known[-1]
    try:
        header = DeviceHeader.from_bytes(header_bytes, source=source)
    except ProtocolError as err:
        raise err.at(offset=header_offset + PAYLOAD_AT) from err
    notes: list[str] = []
    if salvaged:  # a damaged copy's header, or one put together from two of them
        _tell(notes, source, _repaired_header_text(len(known), header_offset, combined))
    data_frames, rejected = _checked_data_frames(frames)
    if rejected:
        notes.append(f"{rejected} DATA frame(s) of a DUMP_CHECKED stream not used: their DATA_CRC frame was damaged, "
                     "or its CRC-32 differs from the bytes received (section 4)")
    data_frames, foreign, unknown = _frames_of_header(known, unreadable, header_bytes, data_frames)
    if foreign:
        _tell(notes, source, _foreign_frames_text(known, header_offset, header_bytes, foreign, unknown))
    blocks = _capture_blocks(data, frames, errors, known, unreadable, header_bytes)
    received, unplaced = _CaptureMemory(header), _CaptureMemory(header)
    outside = received.place(_data_frame_pieces(data_frames)) + received.place(blocks.pieces)
    unplaced.place(blocks.unplaced_pieces)  # where only blocks of frames no readable header places were received
    if blocks.salvaged:
        notes.append(f"{blocks.salvaged} 64-sample block(s) kept from damaged DATA_BLOCKS frames (their checks verify "
                     "at their addresses under this header, section 4.1)")
    if blocks.foreign:
        notes.append(f"{blocks.foreign} DATA_BLOCKS frame(s) under another header were not used")
    if blocks.unplaced:
        _tell(notes, source, f"{blocks.unplaced} DATA_BLOCKS frame(s) not used although their blocks verify under "
              "this header's binding: each lies between damaged header copies that do not verify, with no readable "
              "copy of this header on both sides, so the memory state it was read from is not proven (section 4.1)")
    if outside:
        notes.append(f"{outside} DATA frame(s) addressed outside the {received.covered.size}-byte sample memory and "
                     f"the {received.step_covered.size}-byte step memory were ignored")
    if errors:
        notes.append(f"{len(errors)} framing error(s) in the capture (their bytes were not used)")
    slot_ok, slot_reason, step_reason = received.reasons(unplaced)
    header = _interrupted_run(header, received.step_memory, source, notes)
    steps = _assemble_steps(header, received.step_memory, received.step_covered, step_reason, source, notes)
    return _assemble(header, received.memory, slot_ok, slot_reason, source, "wire capture", notes, steps)


def _tell(notes: list[str], source: str | None, text: str) -> None:
    """A note of the capture, said in a warning too (its stack level: the caller of :func:`decode_bytes`, when
    called from :func:`_decode_capture`)."""
    notes.append(text)
    warnings.warn(f"{source or 'capture'}: {text}", stacklevel=4)


def _capture_headers(data: bytes, frames: list, errors: list, source: str | None
                     ) -> tuple[list[tuple[int, bytes, bool]], np.ndarray, bool]:
    """The device headers of a capture (:func:`~gaitlog.protocol.capture_salvage.find_header_copies`), the offsets
    of the damaged copies that do not verify, and whether the header was put together from two of them
    (:func:`~gaitlog.protocol.capture_salvage.combined_header`, when no copy can be read).

    Raises
    ------
    ProtocolError
        No header can be read nor put together: nothing places the samples.
    """
    known, unreadable = find_header_copies(data, frames, errors)
    if known:
        return known, unreadable, False
    combined = combined_header(data, unreadable)
    if combined is not None:
        return [(off, combined, True) for off in unreadable.tolist()], unreadable[:0], True
    damaged = unreadable.size
    raise ProtocolError(
        f"wire capture has no intact HEADER frame (type 0x86) among {len(frames)} intact frames and "
        f"{len(errors)} framing errors"
        + (f", and the {damaged} damaged one(s) do not verify (the header's own CRC-16 or the rules of section 2 "
           "fail, or LOGGING is set and its journal is outside that CRC)" if damaged else "")
        + ": cannot place the samples", offset=int(unreadable[0]) if damaged else 0, source=source)


def _repaired_header_text(n_copies: int, header_offset: int, combined: bool) -> str:
    """What the note says of a header read from a damaged HEADER frame, or put together from ``n_copies``."""
    if combined:
        return (f"every HEADER frame is damaged; the header was put together from {n_copies} damaged copies "
                "(each byte where they differ taken from the copy whose choice passes the header's CRC-16 and a "
                "copy's frame CRC-16)")
    return (f"the HEADER frame at offset {header_offset} is damaged (its frame CRC-16 or framing failed); the "
            "256-byte header it carries passed its own CRC-16 and every rule of section 2 (LOGGING clear: the "
            "journal outside that CRC is not used) and places the samples")


def _foreign_frames_text(known: list[tuple[int, bytes, bool]], header_offset: int, header_bytes: bytes, foreign: int,
                         unknown: int) -> str:
    """What the note says of the ``foreign`` DATA frames not used: under other headers, under ``unknown`` damaged
    ones, or before any."""
    others = {h for _, h, _ in known if state_key(h) != state_key(header_bytes)}
    ids = sorted({_recording_text(h) for h in others} - {_recording_text(header_bytes)})
    why = (f"{len(ids)} other recording(s) ({', '.join(ids)})" if ids else
           f"{len(others)} other state(s) of this recording's header" if others else "no known header")
    return (f"the capture spans {len(others) + unknown + 1} device headers: decoded "
            f"{_recording_text(header_bytes)} (HEADER frame at offset {header_offset}); {foreign} DATA frame(s) "
            f"under {why}"
            + (f", or under {unknown} damaged HEADER frame(s) that do not verify" if unknown else "")
            + ", or before any HEADER frame, were not used")


def _data_frame_pieces(data_frames: list) -> list[tuple[int, bytes]]:
    """``(address, bytes)`` of DATA frames (section 3.1)."""
    return [(int(fields["address"]), fields["data"]) for fields in map(parse_payload, data_frames)]


class _CaptureMemory:
    """The sample memory and the step memory as the frames of a capture carried them, and which bytes they
    carried (``covered``)."""

    def __init__(self, header: DeviceHeader) -> None:
        cap_bytes, step_bytes = int(header.capacity_samples) * 4, int(header.step_memory_bytes)
        self.memory = np.zeros(cap_bytes, dtype=np.uint8)
        self.covered = np.zeros(cap_bytes, dtype=bool)
        self.step_memory = np.full(step_bytes, 0xFF, dtype=np.uint8)
        self.step_covered = np.zeros(step_bytes, dtype=bool)

    def place(self, pieces: list[tuple[int, bytes]]) -> int:
        """Write ``(address, bytes)`` pieces into the sample or the step memory and mark them covered; return how
        many were addressed outside both."""
        outside = 0
        for address, chunk_bytes in pieces:
            where = memory_region(address, len(chunk_bytes), sample_memory_bytes=self.covered.size,
                                  step_memory_bytes=self.step_covered.size)
            if where is None:
                outside += 1
                continue
            region, offset = where
            target, seen = ((self.memory, self.covered) if region == "samples" else
                            (self.step_memory, self.step_covered))
            target[offset: offset + len(chunk_bytes)] = np.frombuffer(chunk_bytes, dtype=np.uint8)
            seen[offset: offset + len(chunk_bytes)] = True
        return outside

    def reasons(self, unplaced: _CaptureMemory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per sample slot whether it was received (all four bytes), and the reason of each slot and each step
        memory byte that was not: not received, or received only in frames ``unplaced`` holds."""
        slot_ok = self.covered.reshape(-1, 4).all(axis=1)
        slot_reason = np.full(slot_ok.size, _R_NOT_RECEIVED, dtype=np.int8)
        slot_reason[unplaced.covered.reshape(-1, 4).any(axis=1) & ~slot_ok] = _R_UNPLACED
        step_reason = np.full(self.step_covered.size, _R_NOT_RECEIVED, np.int8)
        step_reason[unplaced.step_covered & ~self.step_covered] = _S_UNPLACED
        return slot_ok, slot_reason, step_reason


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
    key = state_key(header_bytes)
    h_off = np.array([off for off, _, _ in known] + unreadable.tolist(), dtype=np.int64)
    h_ok = np.array([state_key(h) == key for _, h, _ in known] + [False] * unreadable.size, dtype=bool)
    order = np.argsort(h_off, kind="stable")
    h_off, h_ok = h_off[order], h_ok[order]
    closed = closed_state(header_bytes)
    r_off = np.array([off for off, _, _ in known], dtype=np.int64)
    r_ok = np.array([state_key(h) == key for _, h, _ in known], dtype=bool)

    def belongs(offset: int) -> bool:
        k = int(np.searchsorted(h_off, offset, side="right")) - 1
        if (k >= 0 and h_ok[k]) or (k + 1 < h_off.size and h_ok[k + 1]):
            return True
        j = int(np.searchsorted(r_off, offset, side="right")) - 1
        return bool(closed and j >= 0 and j + 1 < r_off.size and r_ok[j] and r_ok[j + 1])

    return belongs


def _capture_blocks(data: bytes, frames: list, errors: list, known: list, unreadable: np.ndarray,
                    header_bytes: bytes) -> _CaptureBlocks:
    """Blocks of intact DATA_BLOCKS frames, and of damaged ones found again (section 4.1,
    :class:`~gaitlog.protocol.capture_salvage.BlocksFrames`).

    A frame belongs to the header when the nearest device header before it or after it (the copy a DUMP_BLOCKS
    stream ends with) is readable and of the same memory state (:func:`_belongs_to`); every block must verify
    under that header's ``binding``.
    """
    out = _CaptureBlocks()
    binding = header_binding(header_bytes)
    belongs = _belongs_to(header_bytes, known, unreadable)
    stream = BlocksFrames(data, frames, errors)
    for fr in stream.intact:
        out.take(verified_blocks(binding, fr.payload).pieces(), belongs(fr.offset))
    found = stream.salvage(binding, belongs)
    out.salvaged += len(found)
    out.pieces += found
    return out


def _checked_data_frames(frames: list) -> tuple[list, int]:
    """The DATA frames to use, and how many were rejected: in a capture holding DATA_CRC frames (a DUMP_CHECKED
    stream, section 4) a DATA frame is used only when the next intact frame confirms it (:func:`_confirmed`); in
    one without (DUMP, READ) on its CRC-16 (as a host without DUMP_CHECKED)."""
    checked = any(fr.type == _TYPE_DATA_CRC for fr in frames)
    out, rejected = [], 0
    for k, fr in enumerate(frames):
        if fr.type != _TYPE_DATA or len(fr.payload) < _DATA_AT:
            continue
        if checked and not _confirmed(fr, frames[k + 1] if k + 1 < len(frames) else None):
            rejected += 1
            continue
        out.append(fr)
    return out, rejected


def _confirmed(data_frame, following) -> bool:
    """``following`` is a DATA_CRC frame with the DATA frame's address and the CRC-32 of its data bytes."""
    if following is None or following.type != _TYPE_DATA_CRC or len(following.payload) != _DATA_CRC_BYTES:
        return False
    check, sent = parse_payload(following), parse_payload(data_frame)
    return check["address"] == sent["address"] and check["crc32"] == crc32(sent["data"])


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
    key = state_key(header_bytes)
    starts = np.concatenate([np.array([off for off, _, _ in known], dtype=np.int64), unreadable.astype(np.int64)])
    same = np.concatenate([np.array([state_key(h) == key for _, h, _ in known], dtype=bool),
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
