"""Wire captures with a damaged HEADER frame, or DATA frames a DUMP_CHECKED stream's DATA_CRC does not confirm
(PROTOCOL.md section 4, "Decoding a capture"): what can be verified is decoded, the rest reported missing,
never a wrong sample. Truth is the emulated device's memory (its firmware's own stream is the capture)."""

from __future__ import annotations

import warnings
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.host.files.decode import decode_bytes
from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import FrameType, build_payload, encode_frame, parse_stream
from tests.host.link.test_link_emu import smooth_motion

N = 3000
HEADER_FRAME = 6 + 256 + 2


def _logger(seed: int = 1, n: int = N, *, journal_ring: bool | None = None) -> tuple[Logger, np.ndarray]:
    logger = Logger(device_id=5, journal_ring=journal_ring)
    result = logger.record(smooth_motion(n, seed), start_time_s=1_700_000_000)
    return logger, np.asarray(result.codes)


def _session(logger: Logger, length: int, command: FrameType = FrameType.DUMP, chunk: int = 1024) -> bytes:
    """The device's bytes of READ_HEADER, then DUMP (or DUMP_CHECKED) of the first ``length`` bytes."""
    fw = logger.firmware
    out = fw.receive(encode_frame(FrameType.READ_HEADER, 1), now_s=0.0)
    payload = build_payload(command, address=0, length=length, chunk=chunk)
    return out + fw.receive(encode_frame(command, 2, payload), now_s=0.0)


def _decode(data: bytes):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = decode_bytes(data, source="cap.bin")
    return rec, " | ".join(str(w.message) for w in caught)


@pytest.mark.parametrize("journal_ring", [True, False], ids=["header-v3", "header-v2"])
@pytest.mark.parametrize(("where", "why"), [(4, "the frame's length field"), (200, "the journal (LOGGING clear)"),
                                            (262, "the frame's CRC-16")])
def test_a_damaged_header_frame_whose_header_verifies_is_used(where: int, why: str, journal_ring: bool) -> None:
    """On both header versions (3, the default logger's: its journal area unused; 2)."""
    logger, codes = _logger(journal_ring=journal_ring)
    assert logger.header.header_version == (3 if journal_ring else 2)
    capture = bytearray(_session(logger, 4 * N))
    capture[where] ^= 0x5A  # outside the bytes the header's own CRC-16 covers (0-159 of the payload)
    frames, _ = parse_stream(bytes(capture))
    assert FrameType.HEADER not in [f.type for f in frames]  # the frame itself is damaged
    rec, said = _decode(bytes(capture))
    assert "HEADER frame at offset 0 is damaged" in said and "passed its own CRC-16" in said, why
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    assert rec.header.to_bytes()[:160] == logger.header.to_bytes()[:160]


def test_a_damaged_header_frame_whose_header_does_not_verify_is_refused() -> None:
    logger, _ = _logger()
    capture = bytearray(_session(logger, 4 * N))
    capture[6 + 30] ^= 0x01  # write_index: inside the header's CRC
    with pytest.raises(ProtocolError, match="no intact HEADER frame .* the 1 damaged one\\(s\\) do not verify"):
        decode_bytes(bytes(capture), source="cap.bin")


def test_data_after_a_damaged_header_of_another_recording_is_not_used() -> None:
    """Recording a, then recording b whose HEADER frame is damaged beyond verification: b's DATA frames are
    not decoded as a's samples (before this rule: every frame of b overwrote a's samples at its address)."""
    la, ca = _logger(1)
    lb, _ = _logger(2)
    a = _session(la, 4 * N)
    b = bytearray(_session(lb, 4 * 2000))
    b[6 + 60] ^= 0xFF  # inside b's header CRC: b cannot be read
    rec, said = _decode(a + bytes(b))
    assert rec.header.recording_nonce == la.header.recording_nonce
    assert "under 1 damaged HEADER frame(s) that do not verify" in said
    assert rec.valid.all()  # a's frames came first and are all there: b's did not overwrite them
    np.testing.assert_array_equal(rec.codes, ca)
    # the same with b's HEADER frame's sync and type lost too: its magic still marks it
    b[0:3] = b"\x00\x00\x00"
    rec, _ = _decode(a + bytes(b))
    np.testing.assert_array_equal(rec.codes[rec.valid], ca[rec.valid])
    assert rec.valid.all()


def _forged(frame: bytes, at: int) -> bytes:
    """``frame`` with the byte at ``at`` changed and its CRC-16 recomputed: a damage CRC-16 lets through."""
    f = bytearray(frame)
    f[at] ^= 0x10
    f[-2:] = crc16_xmodem(bytes(f[2:-2])).to_bytes(2, "big")
    return bytes(f)


def test_checked_capture_uses_a_data_frame_only_with_its_data_crc() -> None:
    logger, codes = _logger()
    capture = _session(logger, 4 * N, FrameType.DUMP_CHECKED, chunk=1024)
    rec = decode_bytes(capture, source="cap.bin")
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    first_data = HEADER_FRAME  # the stream's first DATA frame follows the HEADER frame (no ACK before it)
    assert capture[first_data + 2] == FrameType.DATA, capture[HEADER_FRAME: HEADER_FRAME + 16].hex()
    data_len = 6 + 4 + 1024 + 2
    # a DATA frame damaged in a way its CRC-16 passes: the device's CRC-32 in DATA_CRC rejects it
    forged = capture[:first_data] + _forged(capture[first_data: first_data + data_len], 6 + 4 + 100) + \
        capture[first_data + data_len:]
    rec, said = _decode(forged)
    assert any("1 DATA frame(s) of a DUMP_CHECKED stream not used" in n for n in rec.notes), said
    assert not rec.valid[:256].any() and rec.valid[256:].all()
    np.testing.assert_array_equal(rec.codes[256:], codes[256:])
    # its DATA_CRC frame damaged: the DATA frame cannot be verified end to end, so it is not used
    crc_at = first_data + data_len
    assert capture[crc_at + 2] == FrameType.DATA_CRC
    broken = bytearray(capture)
    broken[crc_at + 8] ^= 0x01
    rec, _ = _decode(bytes(broken))
    assert not rec.valid[:256].any() and rec.valid[256:].all()


# ------------------------------------------------------------------ protocol version 2: DUMP_BLOCKS captures
@pytest.fixture(scope="module")
def walk_capture():
    """A 2 x 20 m walk (step algorithm on) dumped by `gaitlog dump`'s library through the emulator with a capture:
    (capture bytes, truth codes in ring order, offset of the end of the first frame)."""
    import io

    from gaitlog.host.link.logger_link import LoggerLink
    from gaitlog.host.link.memory_dump import dump_memory
    from tests.test_end_to_end_steps import CONFIG, START_S, walking

    logger = Logger(device_id=9, step_config=CONFIG)
    result = logger.record(walking(), start_time_s=START_S)
    codes = np.asarray(result.codes)
    capture = io.BytesIO()
    with TemporaryDirectory() as tmp:
        image = Path(tmp) / "walk.glimg"
        logger.save_image(image)
        with LoggerLink(f"emu://{image}", timeout_s=0.5, capture=capture) as link:
            dump_memory(link, Path(tmp) / "d.glimg", progress=False)
    data = capture.getvalue()
    frames, errors = parse_stream(data)
    assert errors == [] and FrameType.DATA_BLOCKS in [f.type for f in frames]
    assert [f.type for f in frames].count(FrameType.HEADER) >= 2  # the header travels at least twice
    return data, codes, frames[1].offset


def test_20_walk_captures_with_5_flipped_bytes_lose_at_most_64_samples_a_byte_and_say_it(walk_capture, tmp_path,
                                                                                          capsys) -> None:
    from gaitlog.host.cli import main
    from gaitlog.host.files.recording import Recording

    data, codes, start = walk_capture
    assert 1900 <= codes.shape[0] <= 2100  # a 2 x 20 m walk at 50 Hz
    rng = np.random.default_rng(32)
    worst = 0
    for i in range(20):
        damaged = bytearray(data)
        for p in rng.choice(np.arange(start, len(data)), 5, replace=False).tolist():
            damaged[p] ^= int(rng.integers(1, 256))
        path = tmp_path / f"cap{i}.bin"
        path.write_bytes(bytes(damaged))
        code = main(["decode", str(path), "--out", str(tmp_path / f"d{i}"), "-q", "--max-missing", "100"])
        err = capsys.readouterr().err
        assert code == 0
        rec = Recording.load(tmp_path / f"d{i}.npz")
        assert not (rec.valid & (rec.codes != codes).any(axis=1)).any()  # 0 wrong samples
        lost = int((~rec.valid).sum())
        assert lost <= 64 * 5
        worst = max(worst, lost)
        if lost:  # every loss said, once, with its count
            line = [x for x in err.splitlines() if "samples missing" in x]
            assert len(line) == 1 and f"{lost:,} of {codes.shape[0]:,} samples missing" in line[0]
        else:
            assert "samples missing" not in err
    assert worst > 0  # the damage did cost something (the test can fail)


def test_a_damaged_block_costs_its_64_samples_and_its_neighbours_are_kept(walk_capture) -> None:
    data, codes, start = walk_capture
    frames, _ = parse_stream(data)
    f = next(fr for fr in frames if fr.type == FrameType.DATA_BLOCKS)
    damaged = bytearray(data)
    damaged[f.offset + 10 + 258 * 3 + 100] ^= 0x01  # block 3 of the first DATA_BLOCKS frame: samples 192-255
    damaged[f.offset + 3] ^= 0x40  # and its seq: framing, found again all the same
    rec, said = _decode(bytes(damaged))
    first = rec.header.first_slot
    lost = np.flatnonzero(~rec.valid)
    np.testing.assert_array_equal((first + lost) % rec.header.capacity_samples, np.arange(192, 256))
    np.testing.assert_array_equal(rec.codes[rec.valid], codes[rec.valid])
    assert "64-sample block(s) kept from damaged DATA_BLOCKS frames" in " ".join(rec.notes)


def test_both_header_copies_damaged_are_put_together(walk_capture) -> None:
    data, codes, _ = walk_capture
    frames, _ = parse_stream(data)
    headers = [fr for fr in frames if fr.type == FrameType.HEADER]
    damaged = bytearray(data)
    for k, fr in enumerate(headers):
        damaged[fr.offset + 6 + 30 + k] ^= 0x10  # inside each copy's own CRC, at different bytes
    rec, said = _decode(bytes(damaged))
    assert "put together from" in said
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)


def _blocks_stream(logger: Logger, seq: int, address: int, length: int, chunk: int) -> bytes:
    """The device's bytes of one DUMP_BLOCKS command: DATA_BLOCKS frames, the header's copy, DUMP_END."""
    payload = build_payload(FrameType.DUMP_BLOCKS, address=address, length=length, chunk=chunk)
    return logger.firmware.receive(encode_frame(FrameType.DUMP_BLOCKS, seq, payload), now_s=0.0)


def _damage_header_copy(stream: bytes, byte: int) -> bytes:
    """``stream`` with its HEADER frame's header byte ``byte`` (inside the header's own CRC) flipped: unreadable."""
    (header,) = [fr for fr in parse_stream(stream)[0] if fr.type == FrameType.HEADER]
    out = bytearray(stream)
    out[header.offset + 6 + byte] ^= 0x10
    return bytes(out)


def test_a_retried_stream_between_two_damaged_header_copies_is_used() -> None:
    """A noisy dump's pattern: a stream whose first frame and header copy are damaged, the host's retry of that
    frame whose header copy is damaged too, then a stream ending with an intact copy. The retry lies between two
    readable copies of the same closed header (only damaged ones between), so its blocks are used: nothing lost."""
    logger, codes = _logger(n=N)
    length = 4 * N
    first = _blocks_stream(logger, 2, 0, length, 1024)
    frames, _ = parse_stream(first)
    data0 = next(fr for fr in frames if fr.type == FrameType.DATA_BLOCKS)
    assert int.from_bytes(data0.payload[:4], "little") == 0
    first = bytearray(first)
    first[data0.offset + 6 + 4 + 10] ^= 0x01  # block 0 of the first frame: samples 0-63, only in the retry
    first = _damage_header_copy(bytes(first), 30)
    retry = _damage_header_copy(_blocks_stream(logger, 3, 0, 1024, 1024), 40)
    last = _blocks_stream(logger, 4, 1024, 1024, 1024)  # its header copy intact
    read_header = logger.firmware.receive(encode_frame(FrameType.READ_HEADER, 1), now_s=0.0)
    capture = read_header + first + retry + last
    # the truth of the pattern: the retry's only readable neighbours are the first and last copies
    assert [fr.offset for fr in parse_stream(capture)[0] if fr.type == FrameType.HEADER] == \
        [0, len(read_header) + len(first) + len(retry) + len(last) - 18 - HEADER_FRAME]
    rec, said = _decode(capture)
    assert rec.valid.all(), said
    np.testing.assert_array_equal(rec.codes, codes)
    # without the last stream the retry has no readable copy after it: samples 0-63 are reported missing, and why
    rec, said = _decode(read_header + first + retry)
    np.testing.assert_array_equal(np.flatnonzero(~rec.valid), np.arange(64))
    assert [(g.first_sample_number, g.last_sample_number) for g in rec.gaps] == [(0, 63)]
    assert rec.gaps[0].reason.startswith("received only in DATA_BLOCKS frames between damaged header copies")
    assert "1 DATA_BLOCKS frame(s) not used although their blocks verify" in said, said
    np.testing.assert_array_equal(rec.codes[rec.valid], codes[rec.valid])

