"""Morris' and Hall's instruments on the emulated logger: simulated motion -> sensor -> ADC -> memory image ->
decode -> kinematics, against the simulation's truth (issue 16, item 5).

The error figures (README, "Morris and Hall on the logger") come from ``benchmarks/logger_instrument_errors.py``
over 12 seeds; the bound of each run is ``noise-free + 3σ + offset + drift`` from the sensor model
(:mod:`gaitlog.host.kinematics.logger_error_budget`: noise through the platform's pseudo-inverse integrated twice for
Morris, once for Hall; offsets and drifts at their tolerances). Here: the CLI chain for one seed of each, the
library chain over 12 seeds pinned to the README's figures, and the refusals with their closest fit.
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.budget import instrument_fit
from gaitlog.firmware_sim.channel_sensors import ChannelSensors
from gaitlog.firmware_sim.device import Logger
from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.kinematics.logger_instruments import (
    check_fits,
    decoded_columns,
    instrument_config,
    record_instrument,
    sensor_recording,
)
from gaitlog.host.kinematics.sensor_csv import read_sensor_csv
from gaitlog.protocol.channel_map import ANGULAR_RATE, SPECIFIC_FORCE, Channel, ChannelMap
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import DeviceHeader

ROOT = Path(__file__).resolve().parents[3]
_SPEC = importlib.util.spec_from_file_location("logger_instrument_errors",
                                               ROOT / "benchmarks" / "logger_instrument_errors.py")
errors = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(errors)

#: README figures over 12 seeds: (median, worst) error, degrees.
README_FIGURES = {"morris-5": (17.1, 21.4), "morris-6": (5.43, 11.3), "hall": (0.337, 0.533)}


def _table(path: Path) -> dict[str, np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    names = lines[0].split(",")
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    return {n: data[:, i] for i, n in enumerate(names)}


def _dcm(cols: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.stack([[cols[f"{prefix}{i + 1}{j + 1}"] for j in range(3)] for i in range(3)]).transpose(2, 0, 1)


# ---------------------------------------------------------------------------------------------- the CLI chain
def test_morris_record_decode_kinematics_cli(tmp_path: Path) -> None:
    image = tmp_path / "morris.glimg"
    assert main(["record", "--motion", "morris", "--out", str(image), "--start-time", "0", "--seed", "3", "-q"]) == 0
    assert main(["decode", str(image), "--out", str(tmp_path / "dec"), "-q"]) == 0
    rec = read_sensor_csv(tmp_path / "dec.csv")
    assert rec.sampling_rate_hz == pytest.approx(100.0) and list(rec.channels) == [f"acc{i}" for i in range(1, 6)]
    out = tmp_path / "k"
    assert main(["kinematics", "morris", str(tmp_path / "dec.csv"), "--platform",
                 str(tmp_path / "morris_platform.json"), "--out", str(out), "-q"]) == 0
    est, truth = _table(out / "morris_orientation.csv"), _table(tmp_path / "morris_truth.csv")
    idx = np.rint(est["time_s"] * 100.0).astype(int)  # both count from the first stored frame
    assert np.allclose(truth["time_s"][idx], est["time_s"], atol=1e-6)
    lam, true = _dcm(est, "dcm"), _dcm(truth, "dcm")[idx]
    heading = lam[0] @ true[0].T  # accelerometers cannot sense the heading: aligned at the cycle start
    err = np.degrees(Rotation.from_matrix(np.swapaxes(lam, 1, 2) @ (heading @ true)).magnitude().max())
    lib, free, bound, _ = errors.run_once("morris", {"n_accelerometers": 5}, 3, tmp_path)
    assert err == pytest.approx(lib, rel=1e-3)  # the CLI's files and the library's chain agree
    assert err <= bound and abs(err - free) > 0.1  # the sensors' errors are on, within the stated bound
    for name in ("morris_angular_velocity.png", "morris_dcm.png", "morris_translation.png",
                 "morris_stick_figure.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(out / "morris_animation.gif") as gif:  # the animation plays: several frames, one drawn
        assert gif.n_frames > 10
        gif.seek(gif.n_frames // 2)
        frame = np.asarray(gif.convert("L"))
        assert frame.std() > 5  # not blank


def test_hall_record_decode_kinematics_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    image = tmp_path / "hall.glimg"
    assert main(["record", "--motion", "hall", "--out", str(image), "-q"]) == 1  # 10 kHz: refused
    assert "closest configuration that fits: 6 channels at 1882 Hz" in capsys.readouterr().err
    assert not image.exists()
    assert main(["record", "--motion", "hall", "--logger-rate", "1880", "--out", str(image), "--seed", "2",
                 "-q"]) == 0
    assert main(["decode", str(image), "--out", str(tmp_path / "dec"), "-q"]) == 0
    out = tmp_path / "k"
    assert main(["kinematics", "hall", str(tmp_path / "dec.csv"), "--platform", str(tmp_path / "hall_platform.json"),
                 "--out", str(out), "-q"]) == 0
    est, truth = _table(out / "hall_joint_angles.csv"), _table(tmp_path / "hall_truth.csv")
    got = np.column_stack([est["flexion_deg"], est["version_deg"], est["axial_rotation_deg"]])
    want = np.degrees(np.column_stack([truth["phi_rad"], truth["theta_rad"], truth["psi_rad"]]))
    err = float(np.abs(got - want).max())
    lib, _, bound, _ = errors.run_once("hall", {"sampling_rate_hz": 1880.0}, 2, tmp_path)
    assert err == pytest.approx(lib, rel=1e-3) and err <= bound
    assert np.abs(want).max() > 30  # a real motion, not a rest
    assert (out / "hall_joint_angles.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------------------ the figures the README states
@pytest.mark.parametrize(("name", "instrument", "kwargs"), [
    ("morris-5", "morris", {"n_accelerometers": 5}),
    ("morris-6", "morris", {"n_accelerometers": 6}),
    ("hall", "hall", {"sampling_rate_hz": 1880.0}),
])
def test_errors_with_noise_within_the_stated_figures(tmp_path: Path, name: str, instrument: str, kwargs: dict) -> None:
    rows = [errors.run_once(instrument, kwargs, seed, tmp_path) for seed in range(12)]
    err = np.array([r[0] for r in rows])
    assert (err <= np.array([r[2] for r in rows])).all()
    median, worst = README_FIGURES[name]
    assert np.median(err) == pytest.approx(median, rel=0.02)
    assert err.max() == pytest.approx(worst, rel=0.02)
    assert np.ptp(err) > 0.05 * worst  # the noise and offsets are on: the seeds differ


def test_the_axial_rate_assumption_costs_what_the_sixth_accelerometer_saves(tmp_path: Path) -> None:
    five = errors.run_once("morris", {"n_accelerometers": 5}, 0, tmp_path)[1]
    six = errors.run_once("morris", {"n_accelerometers": 6}, 0, tmp_path)[1]
    assert six < 3.0 and five > 15.0  # noise-free: ω3 = 0 is most of the five-accelerometer error


def test_accelerometer_offsets_are_what_morris_cannot_afford(tmp_path: Path) -> None:
    # the same parts with a 10 mg offset, an uncalibrated ADXL202's scale: the orientation is lost
    li = record_instrument("morris", seed=1)
    bad = ChannelSensors(li.sensors.range, li.sensors.noise_density, li.sensors.bandwidth_hz,
                         np.array([10e-3, -10e-3, 10e-3, -10e-3, 10e-3]), li.sensors.drift_per_s, seed=1)
    bound = errors.run_once("morris", {"n_accelerometers": 5}, 1, tmp_path)[2]
    li_bad = record_instrument("morris", seed=1, sensors=bad)
    rec = sensor_recording(decode_file(li_bad.logger.save_image(tmp_path / "bad.glimg")))
    from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
    from gaitlog.host.kinematics.reports import morris_errors, truth_from_columns

    cycles = analyse_morris_recording(rec, li_bad.platform)
    err = max(morris_errors(c, truth_from_columns(errors._Truth(li_bad.truth)))["orientation_deg"] for c in cycles)
    assert err > 2 * bound


# ------------------------------------------------------------------------------------------- the decoded dump
def test_dump_decodes_to_exactly_the_stored_codes(tmp_path: Path) -> None:
    cmap = ChannelMap(tuple(Channel(i, SPECIFIC_FORCE, f"acc{i + 1}", 4.0) for i in range(5)))
    logger = Logger(sampling_rate_hz=100.0, channel_map=cmap, device_id=9)
    codes = np.random.default_rng(4).integers(0, 1024, (300, 5))
    assert logger.record_frames(codes, start_time_s=1_700_000_000) == 300
    rec = decode_file(logger.save_image(tmp_path / "m.glimg"))
    assert isinstance(rec.header.calibration, ChannelMap) and rec.header.axes == 5
    assert rec.header.n_stored == 600  # two P32 words a frame of five channels
    t, cols = decoded_columns(rec)
    np.testing.assert_array_equal(t, np.arange(300) / 100.0)
    want = (codes + 0.5 - 512) * 4.0 / 512  # PROTOCOL.md 2.6, written out here
    np.testing.assert_array_equal(np.column_stack(list(cols.values())), want)
    assert list(cols) == [f"acc{i}_g" for i in range(1, 6)]


def test_record_refusals_name_the_reason_and_the_closest_fit() -> None:
    with pytest.raises(HostError, match=r"12 channels, the PIC16F877 has 8 analog inputs.*closest configuration that "
                                        r"fits: 6 channels at 1882 Hz"):
        check_fits("hall", 12, 1900.0)
    with pytest.raises(HostError, match=r"9 channels.*closest configuration that fits: 8 channels"):
        check_fits("morris", 9, 100.0)
    with pytest.raises(HostError, match=r"ADC: 6 channels.*EEPROM.*closest configuration that fits: 6 channels at "
                                        r"1882 Hz") as info:
        check_fits("hall", 6, 10_000.0)
    assert "cycles" in str(info.value)
    check_fits("morris", 6, 100.0)  # Morris' platform fits
    check_fits("hall", 6, 1882.0)   # the closest fit does fit
    short, fastest = instrument_fit(instrument_config("morris", 8, 100.0))
    assert short == [] and fastest == 100.0
    with pytest.raises(HostError, match="EEPROM"):  # memory bandwidth: 8 channels at 2 kHz
        check_fits("morris", 8, 3000.0)


def test_cli_refuses_gravity_channels_and_too_fast(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "h.glimg"
    assert main(["record", "--motion", "hall", "--gravity-channels", "--logger-rate", "2000", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "8 analog inputs" in err and "drop --gravity-channels" in err and "Traceback" not in err
    assert main(["record", "--motion", "walk", "--logger-rate", "2000", "--out", str(out)]) == 2    # usage
    assert "only for --motion morris or hall" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


# -------------------------------------------------------------------------------------- the header, additive
def test_channel_map_header_rules_and_old_headers() -> None:
    cmap = ChannelMap((Channel(0, SPECIFIC_FORCE, "acc1", 4.0), Channel(3, ANGULAR_RATE, "A_x", 30.0)))
    h = DeviceHeader(axes=2, calibration=cmap)
    back = DeviceHeader.from_bytes(h.to_bytes())
    assert back.calibration == cmap and back.axes == 2 and not back.calibration.valid
    with pytest.raises(ProtocolError, match="axes"):
        DeviceHeader(axes=3, calibration=cmap).to_bytes()
    with pytest.raises(ProtocolError, match="other counts need a channel map"):
        DeviceHeader(axes=5).to_bytes()
    with pytest.raises(ProtocolError, match="sampled twice"):
        ChannelMap((Channel(1, SPECIFIC_FORCE, "a", 4.0), Channel(1, SPECIFIC_FORCE, "b", 4.0)))
    with pytest.raises(ProtocolError, match="1..8"):
        ChannelMap(tuple(Channel(i % 8, SPECIFIC_FORCE, f"a{i}", 4.0) for i in range(9)))
    # a three-axis header is unchanged byte for byte (the map is an addition)
    plain = DeviceHeader()
    assert plain.to_bytes()[17] == 3 and plain.to_bytes()[64] in (0, 1)
    assert DeviceHeader.from_bytes(plain.to_bytes()).to_bytes() == plain.to_bytes()


def test_record_frames_stops_at_whole_frames_when_memory_is_full() -> None:
    li = record_instrument("morris", seed=0, n_accelerometers=6, duration_s=2.56)
    logger = li.logger
    assert li.n_frames == li.n_taken == 256
    assert logger.header.samples_written % 2 == 0
    small = replace(instrument_config("morris", 6, 100.0))
    assert small.bytes_per_sample == 8


def test_gait_commands_refuse_an_instruments_dump(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    image = tmp_path / "m.glimg"
    assert main(["record", "--motion", "morris", "--out", str(image), "-q"]) == 0
    assert main(["estimate", str(image), "--out", str(tmp_path / "e")]) == 1
    err = capsys.readouterr().err
    assert "channel map" in err and "gaitlog kinematics" in err and "Traceback" not in err
    with pytest.raises(HostError, match="not the logger's three accelerometer axes"):
        decode_file(image).acc_g()
