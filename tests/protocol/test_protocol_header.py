"""Device header and calibration slot (PROTOCOL.md 2, 2.1) against a hand-written struct.pack layout."""

from __future__ import annotations

import binascii
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import (
    CAPACITY_SAMPLES,
    HEADER_SIZE,
    MEMORY_BYTES,
    CalibrationSlot,
    DeviceHeader,
    HeaderFlag,
)
from gaitlog.protocol.steps import StepConfig


def _ref_header(**f: int) -> bytes:
    """Header bytes written field by field from the section-2 table (independent of construct)."""
    cal = f.pop("cal", bytes(64))
    step_cfg = f.pop("step_cfg", bytes(32))
    body = struct.pack(
        "<4sBBHIIBBBBIIIIII",
        b"GLOG", f["header_version"], f["protocol_version"], f["firmware_version"], f["device_id"],
        f["sampling_rate_millihz"], f["adc_bits"], f["axes"], f["packing"], f["flags"], f["start_time_s"],
        f["capacity_samples"], f["write_index"], f["samples_written"], f["adc_vref_mv"], f["run_start_sample"],
    )
    body += struct.pack("<IHH", f.get("steps_written", 0), f.get("step_write_index", 0), f.get("step_capacity", 0))
    body += bytes(12) + cal + step_cfg + bytes(94)
    assert len(body) == 254
    return body + struct.pack(">H", binascii.crc_hqx(body, 0))


BASE = dict(header_version=1, protocol_version=1, firmware_version=0x0102, device_id=42, sampling_rate_millihz=50000,
            adc_bits=10, axes=3, packing=1, flags=0, start_time_s=1_700_000_000, capacity_samples=65536,
            write_index=100, samples_written=100, adc_vref_mv=5000, run_start_sample=40)


def test_constants() -> None:
    assert (HEADER_SIZE, CAPACITY_SAMPLES, MEMORY_BYTES) == (256, 65536, 262144)


def test_header_matches_reference_layout() -> None:
    h = DeviceHeader(**BASE)
    assert h.to_bytes() == _ref_header(**BASE)
    back = DeviceHeader.from_bytes(_ref_header(**BASE))
    for k, v in BASE.items():
        assert getattr(back, k) == v
    assert back.n_stored == 100 and back.first_slot == 0 and back.first_sample_number == 0
    assert back.sampling_rate_hz == 50.0 and not back.wrapped and not back.logging and not back.overwrite
    assert back.start_time.year == 2023 and back.start_time.utcoffset().total_seconds() == 0
    assert not back.calibration.valid
    np.testing.assert_array_equal(back.calibration.offset_counts, [512, 512, 512])


def test_wrapped_ring_rules() -> None:
    cap = 1000
    h = DeviceHeader(**{**BASE, "capacity_samples": cap, "samples_written": 2500, "write_index": 500,
                        "flags": int(HeaderFlag.WRAPPED | HeaderFlag.OVERWRITE), "run_start_sample": 0})
    h2 = DeviceHeader.from_bytes(h.to_bytes())
    assert h2.n_stored == 1000 and h2.first_slot == 500 and h2.first_sample_number == 1500
    slots = h2.stored_slots()
    assert slots[0] == 500 and slots[499] == 999 and slots[500] == 0 and slots[-1] == 499
    assert h2.sample_time_s(1500) == pytest.approx(1_700_000_000 + 30.0)
    np.testing.assert_array_equal(h2.sample_numbers()[[0, -1]], [1500, 2499])


def test_full_stop_when_full_memory_is_consistent() -> None:
    # a memory filled in stop-when-full mode: samples_written == capacity, write_index wrapped to 0
    h = DeviceHeader(**{**BASE, "capacity_samples": 64, "samples_written": 64, "write_index": 0,
                        "flags": int(HeaderFlag.FULL_STOPPED)})
    h2 = DeviceHeader.from_bytes(h.to_bytes())
    assert h2.n_stored == 64 and h2.first_slot == 0 and h2.used_bytes == 256


def _crc(data: bytes) -> bytes:
    return struct.pack(">H", binascii.crc_hqx(data, 0))


def _corrupt(raw: bytes, offset: int, value: bytes) -> bytes:
    b = bytearray(raw)
    b[offset : offset + len(value)] = value
    b[254:256] = struct.pack(">H", binascii.crc_hqx(bytes(b[:254]), 0))
    return bytes(b)


GOOD = _ref_header(**BASE)


@pytest.mark.parametrize(
    ("data", "offset", "match"),
    [
        (b"GLOX" + GOOD[4:], 0, "magic"),
        (GOOD[:100], 100, "truncated"),
        (GOOD[:254] + b"\x00\x00", 254, "header_crc: CRC mismatch"),
        (_corrupt(GOOD, 4, b"\x04")[:254] + _crc(_corrupt(GOOD, 4, b"\x04")[:160]), 4, "unknown header version 4"),
        (_corrupt(GOOD, 5, b"\x07"), 5, "unknown protocol version 7 .this decoder knows 1"),
        (_corrupt(GOOD, 12, bytes(4)), 12, "sample rate 0"),
        (_corrupt(GOOD, 16, b"\x0b"), 16, "adc_bits"),
        (_corrupt(GOOD, 17, b"\x02"), 17, "axes"),
        (_corrupt(GOOD, 18, b"\x02"), 18, "packing"),
        (_corrupt(GOOD, 24, bytes(4)), 24, "capacity_samples"),
        (_corrupt(GOOD, 24, struct.pack("<I", 2**20 + 1)), 24, "capacity_samples"),
        (_corrupt(GOOD, 28, struct.pack("<I", 70000)), 28, "write_index"),
        (_corrupt(GOOD, 28, struct.pack("<I", 99)), 32, "samples_written"),
        (_corrupt(GOOD, 32, struct.pack("<I", 70000)), 32, "exceed capacity"),
        (_corrupt(GOOD, 19, b"\x02"), 32, "WRAPPED set but only 100"),
        (_corrupt(GOOD, 40, struct.pack("<I", 101)), 40, "run_start_sample"),
        (_corrupt(GOOD, 64, b"\x03"), 64, "unknown calibration format 3"),
        (_corrupt(GOOD, 64, b"\x02"), 65, "channel map: 0 channels"),  # cal_format 2: section 2.6
        (_corrupt(GOOD, 64, b"\x01"), 64, "CAL_VALID"),
        (_corrupt(GOOD, 19, b"\x08"), 64, "CAL_VALID"),
    ],
)
def test_header_rejections_name_field_and_offset(data: bytes, offset: int, match: str) -> None:
    with pytest.raises(ProtocolError, match=match) as info:
        DeviceHeader.from_bytes(data, source="dev.bin")
    assert info.value.offset == offset
    assert info.value.source == "dev.bin" and "dev.bin" in str(info.value)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (dict(device_id=2**32), "device_id"),
        (dict(device_id=-1), "device_id"),
        (dict(adc_bits=0), "adc_bits"),
        (dict(flags=256), "flags"),
        (dict(firmware_version=1.5), "firmware_version"),
    ],
)
def test_to_bytes_rejects_bad_fields(change: dict, match: str) -> None:
    with pytest.raises(ProtocolError, match=match):
        DeviceHeader(**{**BASE, **change}).to_bytes()


def test_calibration_slot_reference_layout() -> None:
    off = np.array([511.5, -3.25, 1000.0])
    mat = np.array([[0.004, 1e-5, 0.0], [0.0, -0.0039, 2e-6], [1.9, 0.0, 0.00391]])
    raw = CalibrationSlot(off, mat, True).to_bytes()
    ref = struct.pack("<B3x3i9i12x", 1, *(int(round(v * 65536)) for v in off),
                      *(int(round(v * 2**30)) for v in mat.ravel()))
    assert raw == ref
    assert CalibrationSlot(off, mat, False).to_bytes() == bytes(64)


@pytest.mark.parametrize("bits", [1, 8, 10])
def test_nominal_map(bits: int) -> None:
    cal = CalibrationSlot.nominal(bits)
    full = 2**bits
    g = cal.apply(np.array([[0, full // 2, full - 1]]))
    assert g[0, 0] == -2.0 and g[0, 1] == 0.0 and g[0, 2] == pytest.approx(2.0 - 4.0 / full)


finite = st.floats(allow_nan=False, allow_infinity=False)


@settings(deadline=None)
@given(
    st.lists(st.floats(-32000, 32000), min_size=3, max_size=3),
    st.lists(st.floats(-1.99, 1.99), min_size=9, max_size=9),
)
def test_calibration_q_round_trip_within_quantisation(off: list[float], mat: list[float]) -> None:
    cal = CalibrationSlot(np.array(off), np.array(mat).reshape(3, 3), True)
    back = CalibrationSlot.from_bytes(cal.to_bytes())
    assert back.valid
    assert np.all(np.abs(back.offset_counts - cal.offset_counts) <= 2**-17)
    assert np.all(np.abs(back.matrix_g_per_count - cal.matrix_g_per_count) <= 2**-31)
    assert back.to_bytes() == cal.to_bytes()  # idempotent once quantised


@pytest.mark.parametrize(
    ("off", "mat", "match"),
    [
        ([40000.0, 0, 0], np.eye(3) * 0.004, "offset_q16"),
        ([0.0, 0, 0], np.eye(3) * 2.5, "matrix_q30"),
        ([np.nan, 0, 0], np.eye(3) * 0.004, "non-finite"),
    ],
)
def test_calibration_rejects_out_of_range(off: list, mat: np.ndarray, match: str) -> None:
    with pytest.raises(ProtocolError, match=match):
        CalibrationSlot(np.array(off), mat, True).to_bytes()


u32 = st.integers(0, 2**32 - 1)


@st.composite
def headers(draw: st.DrawFn) -> dict:
    cap = draw(st.integers(1, 2**20))
    wrapped = draw(st.booleans())
    if wrapped:
        sw = draw(st.integers(cap, 2**32 - 1))
        wi = sw % cap if sw != 2**32 - 1 else draw(st.integers(0, cap - 1))
    else:
        sw = draw(st.integers(0, cap))
        wi = sw % cap
    flags = draw(st.integers(0, 255)) & ~0x0A | (0x02 if wrapped else 0)
    cal = draw(st.booleans())
    step_cap = draw(st.sampled_from([0, 1, 7, 3276]) | st.integers(0, 3276))
    step_sw = draw(st.sampled_from([0, 2**32 - 1]) | st.integers(0, 2**32 - 1)) if step_cap else 0
    step_wi = (step_sw % step_cap if step_sw != 2**32 - 1 else draw(st.integers(0, step_cap - 1))) if step_cap else 0
    d = dict(header_version=1, protocol_version=1, firmware_version=draw(st.integers(0, 65535)),
             device_id=draw(u32), sampling_rate_millihz=draw(st.integers(1, 2**32 - 1)), adc_bits=draw(st.integers(1, 10)),
             axes=3, packing=1, flags=flags, start_time_s=draw(u32), capacity_samples=cap, write_index=wi,
             samples_written=sw, adc_vref_mv=draw(u32), run_start_sample=draw(st.integers(0, sw)),
             steps_written=step_sw, step_write_index=step_wi, step_capacity=step_cap)
    if cal:
        off = draw(st.lists(st.floats(-32000, 32000), min_size=3, max_size=3))
        mat = draw(st.lists(st.floats(-1.9, 1.9), min_size=9, max_size=9))
        d["cal"] = CalibrationSlot(np.array(off), np.array(mat).reshape(3, 3), True)
    return d


@settings(deadline=None)
@given(headers())
def test_header_round_trip_property(d: dict) -> None:
    cal = d.pop("cal", None)
    h = DeviceHeader(**d, calibration=cal)
    raw = h.to_bytes()
    n_steps = min(d["steps_written"], d["step_capacity"])
    assert h.n_steps_stored == n_steps and h.step_used_bytes == 20 * n_steps and len(h.step_slots()) == n_steps
    if n_steps:
        assert h.step_slots()[0] == (d["step_write_index"] if d["steps_written"] >= d["step_capacity"] else 0)
        assert ((h.step_slots()[-1] + 1) % d["step_capacity"] == d["step_write_index"]
                or d["steps_written"] == 2**32 - 1)
    ref_fields = dict(d)
    ref_fields["flags"] = d["flags"] | (0x08 if cal is not None else 0)
    assert raw == _ref_header(**ref_fields, cal=cal.to_bytes() if cal is not None else bytes(64))
    back = DeviceHeader.from_bytes(raw)
    assert back.to_bytes() == raw
    assert back.n_stored == min(d["samples_written"], d["capacity_samples"])
    assert back.calibration.valid == (cal is not None)


# ------------------------------------------------------------------------------------ step memory fields
STEPS = dict(BASE, steps_written=3300, step_write_index=24, step_capacity=3276)
CFG = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1, k_m2=1.0,
                 k_m4=0.5, k1_m5_m_s=0.3, k2_m5_m=0.2)
# the block of section 2.2 written with struct.pack, values rounded half up by hand
CFG_REF = struct.pack("<BBHHHHHii12x", 1, 1, 29491, 6554, 36045, 32768, 16384, 19661, 13107)
GOOD_STEPS = _ref_header(**STEPS, step_cfg=CFG_REF)


def test_step_fields_match_reference_layout() -> None:
    h = DeviceHeader(**STEPS, step_config=CFG)
    assert h.to_bytes() == GOOD_STEPS
    assert GOOD_STEPS[44:52] == bytes.fromhex("e40c0000 1800 cc0c") and GOOD_STEPS[128:160] == CFG_REF
    back = DeviceHeader.from_bytes(GOOD_STEPS)
    assert (back.steps_written, back.step_write_index, back.step_capacity) == (3300, 24, 3276)
    assert back.step_config == CFG.quantised() and back.step_config.raw["leg_length_q15"] == 29491
    # the derived rules of section 2.3
    assert back.n_steps_stored == 3276 and back.steps_wrapped and back.first_step_slot == 24
    assert back.first_step_number == 24 and back.step_used_bytes == 65520 == back.step_memory_bytes
    slots = back.step_slots()
    assert slots[0] == 24 and slots[3251] == 3275 and slots[3252] == 0 and slots[-1] == 23
    # not wrapped: oldest record in slot 0
    h2 = DeviceHeader(**{**STEPS, "steps_written": 100, "step_write_index": 100})
    assert (h2.n_steps_stored, h2.first_step_slot, h2.first_step_number, h2.step_used_bytes) == (100, 0, 0, 2000)
    assert not h2.steps_wrapped and h2.step_slots().tolist() == list(range(100))
    # no step memory: everything 0, the bytes of an old header
    old = DeviceHeader(**BASE)
    assert (old.step_capacity, old.n_steps_stored, old.step_memory_bytes, old.step_slots().size) == (0, 0, 0, 0)
    assert old.step_config == StepConfig.off() and old.to_bytes()[44:64] == bytes(20)


def test_saturated_step_counter_allows_any_index() -> None:
    h = DeviceHeader(**{**STEPS, "steps_written": 2**32 - 1, "step_write_index": 7})
    back = DeviceHeader.from_bytes(h.to_bytes())
    assert back.first_step_slot == 7 and back.n_steps_stored == 3276 and back.first_step_number == 2**32 - 1 - 3276


@pytest.mark.parametrize(
    ("data", "offset", "match"),
    [
        (_corrupt(GOOD_STEPS, 50, struct.pack("<H", 3277)), 50, "step_capacity: 3277 records do not fit"),
        (_corrupt(GOOD_STEPS, 48, struct.pack("<H", 3276)), 48, "step_write_index: 3276 not below step_capacity"),
        (_corrupt(GOOD_STEPS, 48, struct.pack("<H", 23)), 44, r"steps_written: 3300 records written but "
                                                              r"step_write_index 23 \(expected 24\)"),
        (_corrupt(GOOD_STEPS, 44, struct.pack("<I", 3299)), 44, "steps_written: 3299"),
        (_corrupt(GOOD, 44, struct.pack("<I", 5)), 44, "steps_written: 5 records written but step_capacity is 0"),
        (_corrupt(GOOD, 48, struct.pack("<H", 1)), 48, "step_write_index: 1 but step_capacity is 0"),
        (_corrupt(GOOD_STEPS, 128, b"\x05"), 128, "step_format: unknown step format 5"),
        (_corrupt(GOOD_STEPS, 129, b"\x03"), 129, "step_flags: reserved bits set in 0x03"),
        (_corrupt(GOOD_STEPS, 130, b"\x00\x00"), 130, "leg_length_q15: step_format 1 needs a leg length"),
    ],
)
def test_step_field_rejections_name_field_and_offset(data: bytes, offset: int, match: str) -> None:
    with pytest.raises(ProtocolError, match=match) as info:
        DeviceHeader.from_bytes(data, source="dev.bin")
    assert info.value.offset == offset and info.value.source == "dev.bin"


def test_step_reserved_bytes_are_ignored() -> None:
    assert DeviceHeader.from_bytes(_corrupt(GOOD_STEPS, 52, b"\xff" * 12)).step_capacity == 3276
    assert DeviceHeader.from_bytes(_corrupt(GOOD_STEPS, 148, b"\xff" * 12)).step_config == CFG.quantised()


@pytest.mark.parametrize(
    ("change", "offset", "match"),
    [
        (dict(step_capacity=70000), 50, "step_capacity"),
        (dict(steps_written=-1), 44, "steps_written"),
        (dict(step_write_index=3276), 48, "step_write_index"),
        (dict(step_config=StepConfig(step_format=1, leg_length_m=2.5)), 130, "leg_length_q15"),
        (dict(step_config=StepConfig(step_format=5)), 128, "step_format"),
        (dict(step_config="off"), 128, "must be a StepConfig"),
    ],
)
def test_to_bytes_rejects_bad_step_fields(change: dict, offset: int, match: str) -> None:
    with pytest.raises(ProtocolError, match=match) as info:
        DeviceHeader(**{**STEPS, **change}).to_bytes()
    assert info.value.offset == offset
