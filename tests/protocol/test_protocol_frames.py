"""Frames (PROTOCOL.md section 3): layout against struct.pack, payload round trips, resynchronisation."""

from __future__ import annotations

import binascii
import random
import struct
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.protocol.data_blocks import blocks_payload
from gaitlog.protocol.frames import (
    FRAME_STRUCT,
    MAX_PAYLOAD,
    ErrorCode,
    Frame,
    FrameError,
    FrameParser,
    FrameType,
    PayloadError,
    build_payload,
    encode_frame,
    parse_payload,
    parse_stream,
)
from gaitlog.protocol.header import CalibrationSlot, DeviceHeader
from gaitlog.protocol.steps import StepConfig


def _ref_frame(t: int, seq: int, payload: bytes) -> bytes:
    body = struct.pack("<BBH", t, seq, len(payload)) + payload
    return b"\xa5\x5a" + body + struct.pack(">H", binascii.crc_hqx(body, 0))


@given(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=MAX_PAYLOAD))
@settings(deadline=None, max_examples=50)
def test_encode_matches_reference_and_parses(t: int, seq: int, payload: bytes) -> None:
    wire = encode_frame(t, seq, payload)
    assert wire == _ref_frame(t, seq, payload)
    assert wire == FRAME_STRUCT.build(dict(body=dict(value=dict(type=t, seq=seq, payload=payload))))
    parsed = FRAME_STRUCT.parse(wire)
    assert (parsed.body.value.type, parsed.body.value.seq, parsed.body.value.payload) == (t, seq, payload)
    frames, errors = parse_stream(wire)
    assert frames == [Frame(t, seq, payload, 0)] and errors == []


def test_encode_rejects() -> None:
    with pytest.raises(Exception, match=f"exceeds the maximum {MAX_PAYLOAD}"):
        encode_frame(FrameType.DATA, 0, bytes(MAX_PAYLOAD + 1))
    with pytest.raises(Exception, match="seq 256"):
        encode_frame(FrameType.DATA, 256)


PAYLOAD_CASES = [
    (FrameType.IDENTIFY, {}, b""),
    (FrameType.GET_STATUS, {}, b""),
    (FrameType.START, dict(start_time_s=0x01020304, mode=1), struct.pack("<IB", 0x01020304, 1)),
    (FrameType.STOP, {}, b""),
    (FrameType.ERASE, {}, b"ERASE"),
    (FrameType.READ_HEADER, {}, b""),
    (FrameType.READ, dict(address=262140, length=4), struct.pack("<IH", 262140, 4)),
    (FrameType.DUMP, dict(address=0, length=262144, chunk=2048), struct.pack("<IIH", 0, 262144, 2048)),
    (FrameType.XDUMP, {}, b""),
    (FrameType.INFO, dict(device_id=5, firmware_version=0x0102, protocol_version=1, adc_bits=10,
                          sampling_rate_millihz=50000, capacity_samples=65536, packing=1, memory_bytes=262144),
     struct.pack("<IHBBIIBI", 5, 0x0102, 1, 10, 50000, 65536, 1, 262144)),
    (FrameType.STATUS, dict(state=2, flags=0x11, samples_written=65536, write_index=0),
     struct.pack("<BBII", 2, 0x11, 65536, 0)),
    (FrameType.DATA, dict(address=8, data=b"\x01\x02\x03\x04"), struct.pack("<I", 8) + b"\x01\x02\x03\x04"),
    (FrameType.DUMP_END, dict(address=0, length=4096, frames=2), struct.pack("<IIH", 0, 4096, 2)),
    (FrameType.ACK, dict(command=FrameType.STOP), b"\x04"),
    (FrameType.NAK, dict(command=0x42, error=ErrorCode.UNKNOWN_COMMAND), b"\x42\x02"),
]


@pytest.mark.parametrize(("ftype", "fields", "payload"), PAYLOAD_CASES, ids=[c[0].name for c in PAYLOAD_CASES])
def test_payload_layouts(ftype: FrameType, fields: dict, payload: bytes) -> None:
    assert build_payload(ftype, **fields) == payload
    parsed = parse_payload(Frame(ftype, 0, payload))
    assert parsed == fields
    if (fields or ftype == FrameType.ERASE) and ftype != FrameType.DATA:
        with pytest.raises(PayloadError) as info:
            parse_payload(Frame(ftype, 0, payload[:-1], offset=10))
        assert info.value.error_code == ErrorCode.BAD_LENGTH and info.value.offset == 14
    if ftype != FrameType.DATA:
        with pytest.raises(PayloadError) as info:
            parse_payload(Frame(ftype, 0, payload + b"\x00"))
        assert info.value.error_code == ErrorCode.BAD_LENGTH


def test_header_and_calibration_payloads() -> None:
    h = DeviceHeader(device_id=9, samples_written=10, write_index=10)
    p = build_payload(FrameType.HEADER, header=h)
    assert p == h.to_bytes()
    assert parse_payload(Frame(FrameType.HEADER, 0, p))["header"].device_id == 9
    bad = bytearray(p)
    bad[10] ^= 1
    with pytest.raises(Exception, match="CRC mismatch") as info:
        parse_payload(Frame(FrameType.HEADER, 0, bytes(bad), offset=100))
    assert info.value.offset == 100 + 6 + 254
    cal = CalibrationSlot(np.array([510.0, 511.0, 512.5]), np.eye(3) / 256, True)
    p = build_payload(FrameType.SET_CALIBRATION, calibration=cal)
    assert p == cal.to_bytes()
    back = parse_payload(Frame(FrameType.SET_CALIBRATION, 0, p))["calibration"]
    np.testing.assert_array_equal(back.offset_counts, cal.offset_counts)
    with pytest.raises(PayloadError) as info:
        parse_payload(Frame(FrameType.SET_CALIBRATION, 0, b"\x05" + p[1:]))
    assert info.value.error_code == ErrorCode.BAD_ARGUMENT and info.value.offset == 6


def test_set_step_config_payload() -> None:
    cfg = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1)
    p = build_payload(FrameType.SET_STEP_CONFIG, step_config=cfg)
    ref = struct.pack("<BBHHHHHii12x", 1, 1, 29491, 6554, 36045, 0, 0, 0, 0)
    assert p == ref and build_payload(FrameType.SET_STEP_CONFIG, step_config=ref) == ref
    assert encode_frame(FrameType.SET_STEP_CONFIG, 3, p) == _ref_frame(0x0B, 3, ref)
    assert parse_payload(Frame(FrameType.SET_STEP_CONFIG, 0, p)) == {"step_config": cfg.quantised()}
    with pytest.raises(PayloadError, match="leg_length_q15") as info:
        build_payload(FrameType.SET_STEP_CONFIG, step_config=StepConfig(step_format=1))
    assert info.value.error_code == ErrorCode.BAD_ARGUMENT and info.value.offset == 2
    assert parse_payload(Frame(FrameType.ACK, 0, b"\x0b")) == {"command": FrameType.SET_STEP_CONFIG}


@pytest.mark.parametrize(
    ("payload", "code", "offset"),
    [
        (b"\x05" + bytes(31), ErrorCode.BAD_ARGUMENT, 106),  # unknown step_format
        (b"\x01\x80\x00\x70" + bytes(28), ErrorCode.BAD_ARGUMENT, 107),  # reserved step_flags bit
        (b"\x01\x01" + bytes(30), ErrorCode.BAD_ARGUMENT, 108),  # format 1 with leg length 0
        (b"\x02\x00" + bytes(30), ErrorCode.BAD_ARGUMENT, 108),  # format 2 with leg length 0
        (b"\x03\x00" + bytes(30), ErrorCode.BAD_ARGUMENT, 108),  # format 3 with leg length 0
        (b"\x04\x00" + bytes(30), ErrorCode.BAD_ARGUMENT, 108),  # format 4 with leg length 0
        (b"\x04\x00\x00\x70" + bytes(16) + b"\x05" + bytes(11), ErrorCode.BAD_ARGUMENT, 126),  # M4 exponent 5/8
        (bytes(31), ErrorCode.BAD_LENGTH, 104),
        (bytes(33), ErrorCode.BAD_LENGTH, 104),
    ],
)
def test_set_step_config_rejections(payload: bytes, code: ErrorCode, offset: int) -> None:
    with pytest.raises(PayloadError) as info:
        parse_payload(Frame(FrameType.SET_STEP_CONFIG, 0, payload, offset=100))
    assert info.value.error_code == code and info.value.offset == offset


@pytest.mark.parametrize(
    ("frame", "code", "offset"),
    [
        (Frame(0x0F, 0, b""), ErrorCode.UNKNOWN_COMMAND, 2),
        (Frame(FrameType.DUMP_BLOCKS, 0, struct.pack("<IIH", 0, 10, 16385)), ErrorCode.BAD_ARGUMENT, 14),
        (Frame(FrameType.DATA_BLOCKS, 0, b"\x00" * (4 + 258 + 2)), ErrorCode.BAD_LENGTH, 4),
        (Frame(0x7F, 0, b"", offset=50), ErrorCode.UNKNOWN_COMMAND, 52),
        (Frame(FrameType.START, 0, struct.pack("<IB", 0, 2)), ErrorCode.BAD_ARGUMENT, 10),
        (Frame(FrameType.ERASE, 0, b"erase"), ErrorCode.BAD_ARGUMENT, 6),
        (Frame(FrameType.READ, 0, struct.pack("<IH", 0, 0)), ErrorCode.BAD_ARGUMENT, 10),
        (Frame(FrameType.READ, 0, struct.pack("<IH", 0, 4097)), ErrorCode.BAD_ARGUMENT, 10),
        (Frame(FrameType.DUMP, 0, struct.pack("<IIH", 0, 10, 0)), ErrorCode.BAD_ARGUMENT, 14),
        (Frame(FrameType.DUMP_CHECKED, 0, struct.pack("<IIH", 0, 10, 4097)), ErrorCode.BAD_ARGUMENT, 14),
        (Frame(FrameType.ABORT, 0, b"\x00"), ErrorCode.BAD_LENGTH, 4),
        (Frame(FrameType.DATA_CRC, 0, b"\x00" * 7), ErrorCode.BAD_LENGTH, 4),
        (Frame(FrameType.STATUS, 0, struct.pack("<BBII", 3, 0, 0, 0)), ErrorCode.BAD_ARGUMENT, 6),
        (Frame(FrameType.ACK, 0, b"\x81"), ErrorCode.BAD_ARGUMENT, 6),
        (Frame(FrameType.NAK, 0, b"\x01\x08"), ErrorCode.BAD_ARGUMENT, 7),
        (Frame(FrameType.DATA, 0, b"\x00\x00\x00"), ErrorCode.BAD_LENGTH, 4),
    ],
)
def test_payload_rejections(frame: Frame, code: ErrorCode, offset: int) -> None:
    """Unknown enum codes are rejected, never decoded as plain ints (cs.Enum would accept them)."""
    with pytest.raises(PayloadError) as info:
        parse_payload(frame)
    assert info.value.error_code == code
    assert info.value.offset == offset


def test_build_payload_rejects() -> None:
    with pytest.raises(PayloadError, match="missing"):
        build_payload(FrameType.READ, address=0)
    with pytest.raises(PayloadError, match="unexpected"):
        build_payload(FrameType.STOP, foo=1)
    with pytest.raises(PayloadError, match="StartMode"):
        build_payload(FrameType.START, start_time_s=0, mode=7)
    with pytest.raises(PayloadError, match="UNKNOWN|unknown frame type"):
        build_payload(0x33)
    with pytest.raises(PayloadError, match="exceeds 4096"):
        build_payload(FrameType.DATA, address=0, data=bytes(4097))


u8 = st.integers(0, 255)
u16 = st.integers(0, 65535)
u32 = st.integers(0, 2**32 - 1)
FIELD_STRATEGIES = {
    FrameType.START: st.fixed_dictionaries(dict(start_time_s=u32, mode=st.sampled_from([0, 1]))),
    FrameType.READ: st.fixed_dictionaries(dict(address=u32, length=st.integers(1, 4096))),
    FrameType.DUMP: st.fixed_dictionaries(dict(address=u32, length=u32, chunk=st.integers(1, 4096))),
    FrameType.INFO: st.fixed_dictionaries(dict(device_id=u32, firmware_version=u16, protocol_version=u8,
                                               adc_bits=u8, sampling_rate_millihz=u32, capacity_samples=u32,
                                               packing=u8, memory_bytes=u32)),
    FrameType.STATUS: st.fixed_dictionaries(dict(state=st.sampled_from([0, 1, 2]), flags=u8,
                                                 samples_written=u32, write_index=u32)),
    FrameType.DATA: st.fixed_dictionaries(dict(address=u32, data=st.binary(max_size=4096))),
    FrameType.DUMP_END: st.fixed_dictionaries(dict(address=u32, length=u32, frames=u16)),
    FrameType.DUMP_CHECKED: st.fixed_dictionaries(dict(address=u32, length=u32, chunk=st.integers(1, 4096))),
    FrameType.DATA_CRC: st.fixed_dictionaries(dict(address=u32, crc32=u32)),
    FrameType.DUMP_BLOCKS: st.fixed_dictionaries(dict(address=u32, length=u32, chunk=st.integers(1, 16384))),
    FrameType.DATA_BLOCKS: st.builds(lambda a, d: dict(address=a, blocks=blocks_payload(0x1234, a, d)[4:]),
                                     st.integers(0, 2**32 - 2**15), st.binary(max_size=16384)),
    FrameType.ACK: st.fixed_dictionaries(dict(command=st.sampled_from([t for t in FrameType if t < 0x80]))),
    FrameType.NAK: st.fixed_dictionaries(dict(command=u8, error=st.sampled_from(list(ErrorCode)))),
}


@settings(deadline=None)
@given(st.sampled_from(list(FIELD_STRATEGIES)).flatmap(lambda t: st.tuples(st.just(t), FIELD_STRATEGIES[t])),
       u8)
def test_payload_round_trip_property(tf: tuple[FrameType, dict], seq: int) -> None:
    ftype, fields = tf
    wire = encode_frame(ftype, seq, build_payload(ftype, **fields))
    frames, errors = parse_stream(wire)
    assert errors == [] and len(frames) == 1
    assert parse_payload(frames[0]) == fields


# ---------------------------------------------------------------------------------------------- streams
def _random_frames(rng: random.Random, n: int, max_len: int = 300) -> list[bytes]:
    return [_ref_frame(rng.choice([0x87, 0x90, 0x82]), i % 256, rng.randbytes(rng.randint(0, max_len)))
            for i in range(n)]


def _check_coverage(items: list, total: int) -> None:
    """Every stream byte lies in a returned frame or a reported error; items come in stream order."""
    covered = np.zeros(total, bool)
    last = -1
    for x in items:
        span = len(x.payload) + 8 if isinstance(x, Frame) else x.length
        assert x.offset >= last
        last = x.offset
        covered[x.offset : x.offset + span] = True
    assert covered.all(), f"bytes not accounted for: {np.flatnonzero(~covered)[:10]}"


@given(st.lists(st.tuples(st.binary(max_size=40), st.integers(0, 2**32 - 1)), min_size=1, max_size=12),
       st.integers(1, 64))
@settings(deadline=None, max_examples=150)
def test_frames_survive_garbage_between_them(parts: list[tuple[bytes, int]], chunk: int) -> None:
    rng = random.Random(parts[0][1])
    originals = _random_frames(rng, len(parts), 64)
    stream = b""
    spans = []
    for (garbage, _), frame in zip(parts, originals):
        stream += garbage
        spans.append(len(stream))
        stream += frame
    parser = FrameParser()
    items: list = []
    for k in range(0, len(stream), chunk):
        items += parser.feed(stream[k : k + chunk])
        assert parser.buffered <= MAX_PAYLOAD + 8 + chunk
    items += parser.flush()
    frames = [x for x in items if isinstance(x, Frame)]
    assert [f.offset for f in frames] == spans
    assert [f.to_bytes() for f in frames] == originals
    _check_coverage(items, len(stream))
    assert sum(x.length for x in items if isinstance(x, FrameError) and x.reason == "garbage") <= sum(
        len(g) for g, _ in parts)


def _corrupt(stream: bytes, rng: random.Random, n_events: int) -> tuple[bytes, list[tuple[int, int]]]:
    """Flip bits, drop and insert bytes, maybe truncate; return the damaged stream and damaged ranges of the
    ORIGINAL stream."""
    data = bytearray(stream)
    damage = []
    positions = sorted(rng.sample(range(len(stream)), n_events), reverse=True)
    for p in positions:  # from the end, so earlier positions stay valid
        kind = rng.choice(["flip", "drop", "insert"])
        if kind == "flip":
            data[p] ^= 1 << rng.randrange(8)
        elif kind == "drop":
            del data[p]
        else:
            data[p:p] = rng.randbytes(rng.randint(1, 5))
        damage.append(p)
    if rng.random() < 0.3:
        cut = rng.randrange(len(data))
        del data[cut:]
        damage.append(("cut", cut))
    return bytes(data), damage


@pytest.mark.parametrize("seed", range(40))
def test_corrupted_stream_yields_only_exact_frames(seed: int) -> None:
    rng = random.Random(seed)
    originals = _random_frames(rng, 60, 200)
    stream = b"".join(originals)
    damaged, damage = _corrupt(stream, rng, rng.randint(1, 8))
    parser = FrameParser()
    items: list = []
    pos = 0
    while pos < len(damaged):
        step = rng.randint(1, 700)
        items += parser.feed(damaged[pos : pos + step])
        pos += step
    items += parser.flush()
    frames = [x for x in items if isinstance(x, Frame)]
    original_set = set(originals)
    assert all(f.to_bytes() in original_set for f in frames)  # nothing invented
    _check_coverage(items, len(damaged))
    # every original frame untouched by the damage (and not cut off) is found
    points = [d for d in damage if not isinstance(d, tuple)]
    cut = min([d[1] for d in damage if isinstance(d, tuple)], default=None)
    start = 0
    found = {f.to_bytes() for f in frames}
    for fr in originals:
        end = start + len(fr)
        touched = any(start <= p < end for p in points)
        lost_by_cut = cut is not None and end + sum(1 for p in points if p < end) * 5 > cut
        if not touched and not lost_by_cut:
            assert fr in found
        start = end
    assert len(frames) >= len(originals) - len(points) - (0 if cut is None else len(originals))


def test_absurd_length_does_not_allocate() -> None:
    parser = FrameParser()
    tracemalloc.start()
    try:
        out = parser.feed(b"\xa5\x5a\x87\x00\xff\xff" + b"\x00" * 10)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20_000
    assert out[0] == FrameError(0, "bad_length", 6, f"length field 65535 > {MAX_PAYLOAD}")
    # a legal but large length waits for its bytes without allocating them
    p2 = FrameParser()
    assert p2.feed(b"\xa5\x5a\x87\x00\x04\x10") == [] and p2.buffered == 6
    assert p2.flush()[0].reason == "truncated"


def test_frame_hidden_behind_corrupted_length_is_found() -> None:
    good = [_ref_frame(0x87, i, bytes([i]) * 20) for i in range(3)]
    bad = bytearray(good[0])
    bad[4] = 0x00
    bad[5] = 0x01  # claims 256 bytes: swallows the next two frames
    frames, errors = parse_stream(bytes(bad) + good[1] + good[2])
    assert [f.seq for f in frames] == [1, 2]
    assert errors[0].reason == "truncated" and errors[0].offset == 0


def test_truncated_mid_frame_and_lone_sync() -> None:
    wire = encode_frame(FrameType.DATA, 0, bytes(100))
    frames, errors = parse_stream(wire + wire[:50])
    assert len(frames) == 1 and errors == [FrameError(len(wire), "truncated", 50,
                                                      "stream ended inside a frame of length 100")]
    frames, errors = parse_stream(b"\xa5\x5a\x01")
    assert frames == [] and errors[0].reason == "truncated" and errors[0].length == 3


def test_salvage_blocks_ignores_one_or_two_bytes_after_the_last_block() -> None:
    """A damaged frame's extent may leave 1-2 bytes after its last whole block (a crash of the flip campaign)."""
    from gaitlog.protocol.data_blocks import salvage_blocks

    body = blocks_payload(0x1234, 512, bytes(range(256)) * 2)[4:]
    for extra in (b"", b"\x00", b"\x00\x00"):
        found = salvage_blocks(0x1234, body + extra, [512])
        assert found.addresses.tolist() == [512, 768] and found.data == bytes(range(256)) * 2
    assert salvage_blocks(0x1234, body, [256]).addresses.tolist() == []  # another address: nothing verifies
