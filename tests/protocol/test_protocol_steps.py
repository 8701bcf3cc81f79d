"""Per-step records, step-memory addressing and the step configuration block (PROTOCOL.md 2.2, 2.3),
against layouts written here with struct.pack and binascii.crc_hqx."""

from __future__ import annotations

import binascii
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.protocol.crc import crc16_xmodem_rows
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.steps import (
    STEP_ADDRESS_BASE,
    STEP_CAPACITY_RECORDS,
    STEP_CONFIG_SIZE,
    STEP_MEMORY_BYTES,
    STEP_RECORD_DTYPE,
    STEP_RECORD_SIZE,
    STEP_RECORD_STRUCT,
    StepConfig,
    StepFlag,
    build_step_record,
    empty_step_records,
    memory_region,
    pack_step_records,
    parse_step_record,
    step_lengths_m,
    unpack_step_records,
)

FIELDS = ("end_sample", "duration_samples", "toe_off_samples", "heel_strike_samples", "flags",
          "length_m1_q14", "length_m2_q14", "length_m3_q14", "length_m4_q14", "length_m5_q14")


def _ref_record(*values: int) -> bytes:
    """One record from the section-2.3 table: little-endian body, big-endian CRC-16/XMODEM of bytes 0-17."""
    body = struct.pack("<IBBbBHHHHH", *values)
    assert len(body) == 18
    return body + struct.pack(">H", binascii.crc_hqx(body, 0))


def test_constants() -> None:
    assert (STEP_RECORD_SIZE, STEP_CAPACITY_RECORDS, STEP_MEMORY_BYTES) == (20, 3276, 65520)
    assert STEP_MEMORY_BYTES <= 65536 < STEP_MEMORY_BYTES + STEP_RECORD_SIZE  # the ring fills one 64 KiB block
    assert STEP_ADDRESS_BASE == 0x01000000 > 4 * 2**20  # above any legal sample memory
    assert STEP_CONFIG_SIZE == 32
    hand = np.dtype([("end_sample", "<u4"), ("duration_samples", "u1"), ("toe_off_samples", "u1"),
                     ("heel_strike_samples", "i1"), ("flags", "u1"), ("length_m1_q14", "<u2"),
                     ("length_m2_q14", "<u2"), ("length_m3_q14", "<u2"), ("length_m4_q14", "<u2"),
                     ("length_m5_q14", "<u2"), ("record_crc", ">u2")])
    assert STEP_RECORD_DTYPE == hand and STEP_RECORD_DTYPE.itemsize == 20
    assert [f.value for f in StepFlag] == [1, 2, 4, 8, 16, 32, 64]


def test_record_matches_reference_layout() -> None:
    values = (123_456, 54, 21, -3, int(StepFlag.SATURATED | StepFlag.UNCALIBRATED), 11469, 11000, 0, 0, 65535)
    ref = _ref_record(*values)
    assert ref[:4] == bytes.fromhex("40e20100") and ref[6] == 0xFD  # -3 as i8
    rec = empty_step_records(1)
    for name, v in zip(FIELDS, values):
        rec[name] = v
    assert pack_step_records(rec) == ref
    assert build_step_record(**dict(zip(FIELDS, values))) == ref
    assert parse_step_record(ref) == dict(zip(FIELDS, values))
    back, ok = unpack_step_records(ref)
    assert ok.tolist() == [True] and [int(back[n][0]) for n in FIELDS] == list(values)
    assert int(back["record_crc"][0]) == binascii.crc_hqx(ref[:18], 0)
    assert step_lengths_m(back)[0].tolist() == [11469 / 16384, 11000 / 16384, 0.0, 0.0, 65535 / 16384]


@st.composite
def record_arrays(draw: st.DrawFn) -> np.ndarray:
    n = draw(st.integers(0, 40))
    rec = empty_step_records(n)
    for name in STEP_RECORD_DTYPE.names[:-1]:
        info = np.iinfo(STEP_RECORD_DTYPE[name])
        rec[name] = draw(st.lists(st.integers(int(info.min), int(info.max)), min_size=n, max_size=n))
    rec["record_crc"] = draw(st.lists(st.integers(0, 65535), min_size=n, max_size=n))  # ignored by pack
    return rec


@settings(deadline=None, max_examples=200)
@given(record_arrays())
def test_pack_unpack_round_trip_property(rec: np.ndarray) -> None:
    raw = pack_step_records(rec)
    # the numpy fast path equals the construct declaration and the struct.pack reference, record by record
    ref = b"".join(_ref_record(*(int(r[n]) for n in FIELDS)) for r in rec)
    assert raw == ref
    assert raw == b"".join(STEP_RECORD_STRUCT.build(dict(body=dict(value={n: int(r[n]) for n in FIELDS})))
                           for r in rec)
    back, ok = unpack_step_records(raw)
    assert ok.all() and back.shape == rec.shape
    for name in FIELDS:
        assert np.array_equal(back[name], rec[name])
    assert pack_step_records(back) == raw


def test_pack_accepts_other_byte_orders_and_rejects_other_arrays() -> None:
    rec = empty_step_records(2)
    rec["end_sample"] = [7, 70000]
    native = rec.astype([(n, STEP_RECORD_DTYPE[n].newbyteorder("=")) for n in STEP_RECORD_DTYPE.names])
    assert pack_step_records(native) == pack_step_records(rec)
    with pytest.raises(ProtocolError, match="structured array with the fields"):
        pack_step_records(np.zeros(3, dtype=np.uint32))


def test_crc_detects_every_single_bit_flip() -> None:
    raw = _ref_record(5000, 52, 20, -4, 0, 10000, 10100, 9000, 9500, 9800)
    for bit in range(8 * STEP_RECORD_SIZE):
        bad = bytearray(raw)
        bad[bit // 8] ^= 1 << (bit % 8)
        _, ok = unpack_step_records(bytes(bad))
        assert ok.tolist() == [False], bit
        with pytest.raises(ProtocolError, match="record_crc: CRC mismatch") as info:
            parse_step_record(bytes(bad), base_offset=100)
        assert info.value.offset == 118


def test_unpack_flags_only_the_damaged_record() -> None:
    rec = empty_step_records(5)
    rec["end_sample"] = np.arange(5) * 50
    raw = bytearray(pack_step_records(rec))
    raw[2 * 20 + 9] ^= 0x40
    _, ok = unpack_step_records(np.frombuffer(bytes(raw), np.uint8))
    assert ok.tolist() == [True, True, False, True, True]


def test_unpack_rejects_partial_records() -> None:
    with pytest.raises(ProtocolError, match="not a multiple of 20") as info:
        unpack_step_records(bytes(45), source="s.bin", base_offset=1000)
    assert info.value.offset == 1040 and "s.bin" in str(info.value)
    assert unpack_step_records(b"")[0].shape == (0,)


def test_crc_rows_equal_crc_hqx() -> None:
    rows = np.random.default_rng(3).integers(0, 256, (500, 18), dtype=np.uint8)
    assert crc16_xmodem_rows(rows).tolist() == [binascii.crc_hqx(r.tobytes(), 0) for r in rows]
    assert crc16_xmodem_rows(np.zeros((0, 18), np.uint8)).shape == (0,)


def test_full_store_round_trips() -> None:
    """A full store (3,276 records) fills the step memory and unpacks to itself (its speed: bench_protocol)."""
    rng = np.random.default_rng(1)
    rec = empty_step_records(STEP_CAPACITY_RECORDS)
    rec["end_sample"] = np.cumsum(rng.integers(40, 70, STEP_CAPACITY_RECORDS))
    raw = pack_step_records(rec)
    back, ok = unpack_step_records(raw)
    assert len(raw) == STEP_MEMORY_BYTES and ok.all()
    np.testing.assert_array_equal(back["end_sample"], rec["end_sample"])


def test_memory_region() -> None:
    kw = dict(sample_memory_bytes=262144, step_memory_bytes=STEP_MEMORY_BYTES)
    assert memory_region(0, 262144, **kw) == ("samples", 0)
    assert memory_region(262143, 1, **kw) == ("samples", 262143)
    assert memory_region(262143, 2, **kw) is None
    assert memory_region(STEP_ADDRESS_BASE, STEP_MEMORY_BYTES, **kw) == ("steps", 0)
    assert memory_region(STEP_ADDRESS_BASE + 65500, 20, **kw) == ("steps", 65500)
    assert memory_region(STEP_ADDRESS_BASE + 65500, 21, **kw) is None
    assert memory_region(STEP_ADDRESS_BASE - 1, 2, **kw) is None  # crosses into the step region
    assert memory_region(262144, 16, **kw) is None  # the gap between the regions
    assert memory_region(STEP_ADDRESS_BASE, 1, sample_memory_bytes=262144, step_memory_bytes=0) is None


# ---------------------------------------------------------------------------------------- configuration
def _ref_config(fmt: int, flags: int, leg: int, foot: int, k1: int, k2: int, k4: int, m5k1: int, m5k2: int) -> bytes:
    return struct.pack("<BBHHHHHii12x", fmt, flags, leg, foot, k1, k2, k4, m5k1, m5k2)


def test_config_matches_reference_layout() -> None:
    cfg = StepConfig(step_format=1, calibrated=True, leg_length_m=0.875, foot_length_m=0.25, k_m1=1.25, k_m2=0.5,
                     k_m4=0.625, k1_m5_m_s=-0.5, k2_m5_m=0.75)
    ref = _ref_config(1, 1, 28672, 8192, 40960, 16384, 20480, -32768, 49152)
    assert cfg.to_bytes() == ref and len(ref) == 32
    assert StepConfig.from_bytes(ref) == cfg  # exact in the Q formats
    assert cfg.raw == dict(step_format=1, step_flags=1, leg_length_q15=28672, foot_length_q15=8192,
                           k_m1_q15=40960, k_m2_q15=16384, k_m4_q15=20480, k1_m5_q16=-32768, k2_m5_q16=49152,
                           m4_exponent_eighths=0)
    assert StepConfig.off().to_bytes() == bytes(32) and not StepConfig.off().enabled and cfg.enabled
    # reserved bytes 20-31 are ignored by readers
    assert StepConfig.from_bytes(ref[:20] + b"\xff" * 12) == cfg


def test_config_rounds_half_up() -> None:
    lsb15, lsb16 = 2.0**-15, 2.0**-16
    cases = [  # value, stored integer = floor(x * 2^n + 0.5)
        ("leg_length_m", "leg_length_q15", 100.5 * lsb15, 101),
        ("leg_length_m", "leg_length_q15", 100.4999 * lsb15, 100),
        ("k_m1", "k_m1_q15", 0.5 * lsb15, 1),
        ("k1_m5_m_s", "k1_m5_q16", -0.5 * lsb16, 0),  # half up, not away from zero
        ("k1_m5_m_s", "k1_m5_q16", -1.5 * lsb16, -1),
        ("k2_m5_m", "k2_m5_q16", -1.5000001 * lsb16, -2),
    ]
    for attr, fieldname, x, q in cases:
        cfg = StepConfig(**{"step_format": 1, "leg_length_m": 0.9, attr: x})
        assert cfg.raw[fieldname] == q, (attr, x)
        assert getattr(cfg.quantised(), attr) == q * (lsb15 if fieldname.endswith("q15") else lsb16)


@pytest.mark.parametrize(
    ("changes", "offset", "match"),
    [
        (dict(step_format=5), 0, "step_format: unknown step format 5"),
        (dict(leg_length_m=2.0), 2, r"leg_length_q15: leg_length_m 2.0 outside the stored range 0 \.\.\. 1.99997"),
        (dict(leg_length_m=-0.001), 2, "leg_length_q15: leg_length_m -0.001 outside"),
        (dict(leg_length_m=1e-6), 2, "leg_length_q15: step_format 1 needs a leg length > 0"),
        (dict(foot_length_m=math.nan), 4, "foot_length_q15: non-finite foot_length_m nan"),
        (dict(k_m1=math.inf), 6, "k_m1_q15: non-finite"),
        (dict(k_m2=-1.0), 8, "k_m2_q15"),
        (dict(k_m4=2.5), 10, "k_m4_q15"),
        (dict(k1_m5_m_s=32768.0), 12, "k1_m5_q16: k1_m5_m_s 32768.0 outside the stored range -32768"),
        (dict(k2_m5_m=-32769.0), 16, "k2_m5_q16"),
        (dict(k2_m5_m="x"), 16, "k2_m5_q16: k2_m5_m must be a number"),
    ],
)
def test_config_writer_rejects(changes: dict, offset: int, match: str) -> None:
    base = dict(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
    with pytest.raises(ProtocolError, match=match) as info:
        StepConfig(**{**base, **changes}).to_bytes()
    assert info.value.offset == offset


def test_config_extremes_are_stored() -> None:
    top15 = (65535 - 0.5) / 32768  # largest value that rounds to 65535
    cfg = StepConfig(step_format=1, leg_length_m=top15, k1_m5_m_s=-32768.0, k2_m5_m=(2**31 - 1.5) / 65536)
    assert cfg.raw["leg_length_q15"] == 65535 and cfg.raw["k1_m5_q16"] == -(2**31)
    assert cfg.raw["k2_m5_q16"] == 2**31 - 1
    with pytest.raises(ProtocolError, match="leg_length_q15"):
        StepConfig(step_format=1, leg_length_m=65535.5 / 32768).to_bytes()


@pytest.mark.parametrize(
    ("data", "offset", "match"),
    [
        (_ref_config(5, 0, 29491, 0, 0, 0, 0, 0, 0), 0, "step_format: unknown step format 5"),
        (_ref_config(255, 0, 0, 0, 0, 0, 0, 0, 0), 0, "unknown step format 255"),
        (_ref_config(1, 0x02, 29491, 0, 0, 0, 0, 0, 0), 1, r"step_flags: reserved bits set in 0x02"),
        (_ref_config(0, 0x81, 0, 0, 0, 0, 0, 0, 0), 1, "step_flags: reserved bits"),
        (_ref_config(1, 1, 0, 6000, 0, 0, 0, 0, 0), 2, "leg_length_q15: step_format 1 needs a leg length"),
        (bytes(31), 0, "expected 32 bytes, found 31"),
    ],
)
def test_config_reader_rejects(data: bytes, offset: int, match: str) -> None:
    with pytest.raises(ProtocolError, match=match) as info:
        StepConfig.from_bytes(data, source="cfg", base_offset=128)
    assert info.value.offset == 128 + offset and info.value.source == "cfg"


def test_config_off_keeps_its_values() -> None:
    # format 0 with values (the algorithm switched off, the subject's data kept) round-trips
    cfg = StepConfig(step_format=0, calibrated=True, leg_length_m=0.9, k_m1=1.0).quantised()
    assert StepConfig.from_bytes(cfg.to_bytes()) == cfg and not cfg.enabled


finite = dict(allow_nan=False, allow_infinity=False)


@settings(deadline=None, max_examples=200)
@given(leg=st.floats(2.0**-15, 1.9999, **finite), foot=st.floats(0, 1.9999, **finite),
       k=st.lists(st.floats(0, 1.9999, **finite), min_size=3, max_size=3),
       m5=st.lists(st.floats(-32767.0, 32767.0, **finite), min_size=2, max_size=2), cal=st.booleans())
def test_config_quantisation_property(leg: float, foot: float, k: list[float], m5: list[float], cal: bool) -> None:
    cfg = StepConfig(step_format=1, calibrated=cal, leg_length_m=leg, foot_length_m=foot, k_m1=k[0], k_m2=k[1],
                     k_m4=k[2], k1_m5_m_s=m5[0], k2_m5_m=m5[1])
    q = StepConfig.from_bytes(cfg.to_bytes())
    assert q == cfg.quantised() and q.quantised() == q and q.calibrated == cal
    for attr, lsb in (("leg_length_m", 2.0**-15), ("foot_length_m", 2.0**-15), ("k_m1", 2.0**-15),
                      ("k_m2", 2.0**-15), ("k_m4", 2.0**-15), ("k1_m5_m_s", 2.0**-16), ("k2_m5_m", 2.0**-16)):
        err = getattr(q, attr) - getattr(cfg, attr)
        assert -lsb / 2 < err <= lsb / 2, attr  # half up: ties go up


def test_version_4_stores_m4s_exponent_in_eighths() -> None:
    """Byte 20 of a version-4 block is M4's exponent in eighths (0: not given, 1-4: 1/8 .. 1/2); in a block of
    versions 1-3 it was reserved and is ignored; 5/8 and odd fractions are refused, naming the field."""
    ref = bytearray(_ref_config(4, 0, 29491, 0, 0, 0, 0, 0, 0))
    ref[20] = 3
    assert StepConfig.from_bytes(bytes(ref)).m4_exponent == 0.375
    assert StepConfig(step_format=4, leg_length_m=0.9, m4_exponent=0.375).to_bytes() == bytes(ref)
    ref[0] = 3
    assert StepConfig.from_bytes(bytes(ref)).m4_exponent == 0.0
    with pytest.raises(ProtocolError, match="m4_exponent_eighths: m4_exponent must be 0") as info:
        StepConfig(step_format=4, leg_length_m=0.9, m4_exponent=0.3).to_bytes()
    assert info.value.offset == 20
    with pytest.raises(ProtocolError, match="m4_exponent_eighths"):
        StepConfig(step_format=4, leg_length_m=0.9, m4_exponent=0.625).to_bytes()
