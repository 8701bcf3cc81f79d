"""The Logger: record path, flags, wrapped memory, memory-image persistence."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import DeviceHeader


def _still(acc: list[float], seconds: float, rate: float = 500.0, **kw: object) -> Motion:
    n = int(seconds * rate)
    return Motion(acc_g=np.tile(acc, (n, 1)), sampling_rate_hz=rate, **kw)  # type: ignore[arg-type]


def test_record_stores_the_expected_codes_flags_and_numbers() -> None:
    lg = Logger(sensor=SensorModel.ideal(noise_density_g_rthz=0.0))
    res = lg.record(_still([0.0, 1.0, -0.5], 10.0, marker_times_s=[2.0, 2.01, 7.3]), start_time_s=1_600_000_000)
    expected = [math.floor((2.5 + 4 * 0.312 * a) / 5 * 1024) for a in (0.0, 1.0, -0.5)]
    assert res.n_samples == 500 and res.n_taken == 500
    assert (res.codes == expected).all()
    assert res.flags[0] == 1  # SESSION_START
    assert np.flatnonzero(res.flags & 2).tolist() == [100, 101, 365]  # MARK at or after each press
    np.testing.assert_allclose(res.sample_times_s[:3], [0.0, 0.02, 0.04])
    assert res.sample_numbers.tolist() == list(range(500))
    h = lg.header
    assert (h.samples_written, h.write_index, h.start_time_s, h.logging) == (500, 500, 1_600_000_000, False)
    assert res.truth["sensor"]["noise_density_g_rthz"] == 0.0 and res.truth["adc"]["adc_bits"] == 10


def test_second_run_appends_and_overwrite_wraps_in_order() -> None:
    lg = Logger(sensor=SensorModel.ideal(), overwrite=True)
    r1 = lg.record(CalibrationPoses(n_poses=24, hold_s=40.0, move_s=2.0, seed=1), start_time_s=100)
    r2 = lg.record(_still([0.0, 0.0, 1.0], 600.0), start_time_s=5000)
    h = lg.header
    assert h.wrapped and h.samples_written == r1.n_taken + r2.n_taken
    assert h.run_start_sample == r1.n_taken and h.start_time_s == 5000
    # ring order: the tail of run 1, then run 2 (its first sample carries SESSION_START)
    mem = np.frombuffer(lg.memory, dtype="<u4")
    ordered = mem[h.stored_slots()]
    n2 = r2.n_samples
    codes2 = np.c_[ordered[-n2:] & 1023, (ordered[-n2:] >> 10) & 1023, (ordered[-n2:] >> 20) & 1023]
    np.testing.assert_array_equal(codes2, r2.codes)
    assert ordered[-n2] >> 30 == 1
    keep1 = 65536 - n2
    codes1 = np.c_[ordered[:keep1] & 1023, (ordered[:keep1] >> 10) & 1023, (ordered[:keep1] >> 20) & 1023]
    np.testing.assert_array_equal(codes1, r1.codes[-keep1:])


def test_stop_when_full_refuses_a_new_record() -> None:
    lg = Logger(sensor=SensorModel.ideal(), overwrite=False)
    res = lg.record(CalibrationPoses(n_poses=24, hold_s=52.0, move_s=3.0))
    assert res.n_samples == 65536 < res.n_taken and lg.header.full_stopped
    with pytest.raises(DeviceError, match="ERASE"):
        lg.record(_still([0, 0, 1], 1.0))
    lg.erase()
    assert lg.record(_still([0, 0, 1], 1.0)).n_samples == 50


def test_motion_at_another_rate_is_resampled() -> None:
    lg = Logger(sensor=SensorModel.ideal(noise_density_g_rthz=0.0))
    res = lg.record(_still([0.0, 0.0, 1.0], 4.0, rate=100.0))
    assert res.truth["motion_sampling_rate_hz"] == 500.0 and res.n_samples == 200
    assert (res.codes[:, 2] == 767).all()


def test_image_round_trip_and_persistence(tmp_path: Path) -> None:
    path = tmp_path / "dev.glimg"
    lg = Logger(device_id=77, image_path=path, overwrite=True)
    lg.record(CalibrationPoses(n_poses=24, hold_s=30.0, move_s=2.0), start_time_s=123)
    lg.record(CalibrationPoses(n_poses=24, hold_s=30.0, move_s=2.0, seed=9), start_time_s=456)
    assert path.exists() and lg.header.wrapped
    back = Logger.from_image(path)
    assert back.memory == lg.memory
    assert back.header.to_bytes() == lg.header.to_bytes()
    # the same file used as a device's memory between runs: the next record continues after the last
    again = Logger(image_path=path, device_id=77, overwrite=True)
    n_before = again.header.samples_written
    again.record(_still([0, 0, 1], 2.0), start_time_s=789)
    assert again.header.samples_written == n_before + 100
    assert Logger.from_image(path).header.samples_written == n_before + 100
    assert not list(tmp_path.glob(".*tmp"))  # atomic writes leave no temporary files


def test_bad_image_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.glimg"
    bad.write_bytes(b"GLIX" + bytes(100))
    with pytest.raises(DeviceError, match="bad.glimg"):
        Logger.from_image(bad)
    with pytest.raises(DeviceError, match="cannot read"):
        Logger.from_image(tmp_path / "missing.glimg")


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_samples=st.integers(0, 65536), wrapped=st.booleans(),
       start=st.integers(0, 2**32 - 1))
def test_image_save_load_property(tmp_path_factory: pytest.TempPathFactory, seed: int, n_samples: int,
                                  wrapped: bool, start: int) -> None:
    """Encoder (save_image) / decoder (from_image): arbitrary memory and header come back bit-identical."""
    rng = np.random.default_rng(seed)
    lg = Logger(device_id=seed % 1000)
    written = n_samples + (65536 + int(rng.integers(0, 65536)) if wrapped else 0)
    header = DeviceHeader(device_id=seed % 1000, samples_written=written, write_index=written % 65536,
                          flags=(0x03 if wrapped else 0), start_time_s=start)
    lg._load(header, rng.integers(0, 256, 262144, dtype=np.uint8), source="test")
    path = tmp_path_factory.mktemp("img") / "x.glimg"
    lg.save_image(path)
    back = Logger.from_image(path)
    assert back.memory == lg.memory and back.header.to_bytes() == lg.header.to_bytes()


# ------------------------------------------------------------------------- the step memory (section 2.3)
def _steps(n: int) -> bytes:
    from gaitlog.protocol.steps import empty_step_records, pack_step_records

    rec = empty_step_records(n)
    rec["end_sample"] = 27 * np.arange(n)
    rec["length_m2_q14"] = 11000
    return pack_step_records(rec)


def test_logger_has_step_memory_and_config() -> None:
    from gaitlog.protocol.steps import StepConfig

    cfg = StepConfig(step_format=4, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1,
                     m4_exponent=0.25)   # as firmware 1.3 stores it
    lg = Logger(step_config=cfg)
    h = lg.header
    # header version 3, the default: the step ring in front of the journal ring (version 2: 3276, 65,520 bytes)
    assert (h.header_version, h.step_capacity, h.steps_written, h.step_write_index) == (3, 2662, 0, 0)
    assert lg.step_config == cfg and lg.data_eeprom.read(128, 32) == cfg.to_bytes()
    assert len(lg.step_memory) == 53240 and set(lg.step_memory) == {0xFF}
    assert len(Logger(journal_ring=False).step_memory) == 65520
    lg.step_config = StepConfig.off()
    assert lg.data_eeprom.read(128, 32) == bytes(32)
    lg.step_config = cfg
    lg.firmware.start_logging(start_time_s=0, overwrite=True)
    with pytest.raises(DeviceError, match="SET_STEP_CONFIG while logging"):
        lg.step_config = StepConfig.off()
    assert lg.firmware.log_steps(_steps(4)) == 4
    lg.firmware.stop_logging()
    assert lg.step_memory[:80] == _steps(4)
    lg.erase()  # forgets the records, keeps the configuration
    assert lg.header.steps_written == 0 and lg.header.step_config == cfg
    assert lg.data_eeprom.read(44, 4) == bytes(4) and lg.data_eeprom.read(128, 32) == cfg.to_bytes()
    with pytest.raises(ProtocolError, match="leg_length_q15"):
        Logger(step_config=StepConfig(step_format=1))


def test_image_carries_the_step_memory(tmp_path: Path) -> None:
    from gaitlog.protocol.image import parse_image
    from gaitlog.protocol.steps import StepConfig

    cfg = StepConfig(step_format=4, leg_length_m=0.875, m4_exponent=0.25)
    lg = Logger(device_id=5, sensor=SensorModel.ideal(), step_config=cfg)
    lg.firmware.start_logging(start_time_s=1000, overwrite=True)
    lg.firmware.log_samples(np.full((300, 3), 512))
    lg.firmware.log_steps(_steps(3400))  # wraps the step ring (2662 records)
    lg.firmware.stop_logging()
    path = lg.save_image(tmp_path / "s.glimg")
    raw = path.read_bytes()
    assert raw[4] == 3 and int.from_bytes(raw[8:12], "little") == 262144 + 53240
    c = parse_image(raw)
    records, ok = c.step_records()
    assert ok.all() and records["end_sample"].tolist() == (27 * np.arange(738, 3400)).tolist()
    back = Logger.from_image(path)
    assert back.step_memory == lg.step_memory and back.memory == lg.memory
    assert back.header.to_bytes() == lg.header.to_bytes() and back.step_config == cfg.quantised()
    # the restored device goes on where the image left off
    back.firmware.start_logging(start_time_s=2000, overwrite=True)
    assert back.firmware.log_steps(_steps(1)) == 1
    back.firmware.stop_logging()
    assert (back.header.steps_written, back.header.step_write_index) == (3401, 739)


def test_version_1_image_restores_with_an_empty_step_memory(tmp_path: Path) -> None:
    from gaitlog.protocol.image import build_image

    old = DeviceHeader(device_id=9, samples_written=100, write_index=100)  # no step memory: image version 1
    memory = np.random.default_rng(0).integers(0, 256, 262144, dtype=np.uint8)
    path = tmp_path / "old.glimg"
    path.write_bytes(build_image(old, memory, image_version=1))
    assert path.read_bytes()[4] == 1
    lg = Logger.from_image(path)
    assert lg.memory == memory.tobytes() and lg.header.samples_written == 100
    assert (lg.header.step_capacity, lg.header.steps_written) == (3276, 0) and set(lg.step_memory) == {0xFF}
    lg.save_image(path)  # saved back as version 3
    assert path.read_bytes()[4] == 3 and Logger.from_image(path).header.to_bytes() == lg.header.to_bytes()


def test_image_with_other_step_capacity_is_refused(tmp_path: Path) -> None:
    from gaitlog.protocol.image import build_image

    h = DeviceHeader(step_capacity=100, steps_written=5, step_write_index=5)
    path = tmp_path / "x.glimg"
    path.write_bytes(build_image(h, bytes(262144), step_memory=bytes(2000)))
    with pytest.raises(DeviceError, match="image holds 100 step records; this device 3276"):
        Logger.from_image(path)
