"""A damaged capture's frames found again (``gaitlog.protocol.capture_salvage``), on streams built here from the
declarations: the truth is the header and the memory the stream was built from. A block is found again at its
own address with its own bytes, or not at all."""

from __future__ import annotations

import numpy as np

from gaitlog.protocol.capture_salvage import BlocksFrames, combined_header, find_header_copies, state_key
from gaitlog.protocol.data_blocks import BLOCK_BYTES, blocks_payload, header_binding
from gaitlog.protocol.frames import FrameType, build_payload, encode_frame, parse_stream
from gaitlog.protocol.header import DeviceHeader, HeaderFlag

HEADER = DeviceHeader(capacity_samples=1024, samples_written=700, write_index=700, device_id=3,
                      recording_number=2, recording_nonce=0x1234ABCD).to_bytes()
MEMORY = np.random.default_rng(5).integers(0, 256, 4 * 700, dtype=np.uint8).tobytes()
CHUNK = 4 * BLOCK_BYTES  # four blocks a frame


def _stream() -> tuple[bytes, list[int]]:
    """READ_HEADER's HEADER frame, then a DUMP_BLOCKS stream: DATA_BLOCKS frames, the header's copy, DUMP_END;
    and the stream offset of each DATA_BLOCKS frame."""
    header_frame = encode_frame(FrameType.HEADER, 1, build_payload(FrameType.HEADER, header=HEADER))
    parts, offsets, at = [header_frame], [], len(header_frame)
    for k, address in enumerate(range(0, len(MEMORY), CHUNK)):
        frame = encode_frame(FrameType.DATA_BLOCKS, 2 + k, blocks_payload(header_binding(HEADER), address,
                                                                          MEMORY[address: address + CHUNK]))
        parts.append(frame)
        offsets.append(at)
        at += len(frame)
    parts.append(header_frame)
    parts.append(encode_frame(FrameType.DUMP_END, 9, build_payload(FrameType.DUMP_END, address=0,
                                                                   length=len(MEMORY), frames=len(offsets))))
    return b"".join(parts), offsets


def _salvaged(data: bytes) -> dict[int, bytes]:
    frames, errors = parse_stream(data)
    return dict(BlocksFrames(data, frames, errors).salvage(header_binding(HEADER), lambda offset: True))


def test_a_frame_whose_sync_is_hit_gives_all_its_blocks_at_their_addresses() -> None:
    data, offsets = _stream()
    damaged = bytearray(data)
    damaged[offsets[1]] ^= 0xFF  # the sync of the frame carrying bytes 1024-2047
    found = _salvaged(bytes(damaged))
    assert sorted(found) == [1024, 1280, 1536, 1792]
    assert all(found[a] == MEMORY[a: a + BLOCK_BYTES] for a in found)
    assert _salvaged(data) == {}  # an intact stream has nothing to salvage


def test_a_dropped_byte_keeps_only_the_blocks_before_it() -> None:
    data, offsets = _stream()
    damaged = bytearray(data)
    del damaged[offsets[1] + 10 + 258 * 2 + 7]  # inside block 2 of that frame: blocks 2 and 3 are shifted
    found = _salvaged(bytes(damaged))
    assert sorted(found) == [1024, 1280]
    assert all(found[a] == MEMORY[a: a + BLOCK_BYTES] for a in found)


def test_a_damaged_header_frame_is_read_only_when_its_header_verifies() -> None:
    data, _ = _stream()
    outside_crc = bytearray(data)
    outside_crc[3] ^= 0x01  # the frame's seq: the frame fails, the header inside still verifies
    frames, errors = parse_stream(bytes(outside_crc))
    copies, unreadable = find_header_copies(bytes(outside_crc), frames, errors)
    assert [(offset, raw == HEADER, salvaged) for offset, raw, salvaged in copies][0] == (0, True, True)
    assert unreadable.size == 0
    inside_crc = bytearray(data)
    inside_crc[6 + 30] ^= 0x01  # write_index, inside the header's own CRC
    frames, errors = parse_stream(bytes(inside_crc))
    copies, unreadable = find_header_copies(bytes(inside_crc), frames, errors)
    assert unreadable.tolist() == [0] and [offset for offset, _, _ in copies] != [0]


def test_two_damaged_copies_are_put_together_and_one_is_not_enough() -> None:
    data, _ = _stream()
    frames, _ = parse_stream(data)
    copies = [fr.offset for fr in frames if fr.type == FrameType.HEADER]
    damaged = bytearray(data)
    for k, offset in enumerate(copies):
        damaged[offset + 6 + 30 + k] ^= 0x10  # inside each copy's own CRC, at different bytes
    assert combined_header(bytes(damaged), np.array(copies)) == HEADER
    assert combined_header(bytes(damaged), np.array(copies[:1])) is None


def test_the_state_key_of_a_closed_header_ignores_its_journal() -> None:
    journal_changed = bytearray(HEADER)
    journal_changed[200] ^= 0xFF  # the journal area, outside the CRC of version 2 and later
    assert state_key(bytes(journal_changed)) == state_key(HEADER)
    logging = DeviceHeader.from_bytes(HEADER)
    logging.flags |= int(HeaderFlag.LOGGING)
    raw = logging.to_bytes()
    changed = bytearray(raw)
    changed[200] ^= 0xFF
    assert state_key(bytes(changed)) != state_key(raw)
