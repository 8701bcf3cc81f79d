"""Calibration of the emulated 10-bit logger: a pose session recorded through sensor, ADC, firmware and memory.

Truth is the emulator's own sensor and ADC parameters, mapped to counts by the front-end equations of
``firmware_sim/sensor.py`` and ``firmware_sim/adc.py`` (not by the code under test):

- sensor output ``v = V0 + S (1 + e_j) (b_j + u_j . a)`` V, front end ``v_adc = ref + G (v - ref)``,
  ideal floor quantiser ``code = floor((v_adc - VREF-) / span * 2^bits)``; with the sensor noise dithering it,
  the mean code is the continuous value minus 1/2, so
- offset (counts) ``= (ref + G (V0 + S (1 + e_j) b_j - ref) - VREF-) / span * 2^bits - 1/2``,
- scale (counts per g) ``= G S (1 + e_j) / span * 2^bits`` (255.6 nominal: one LSB = 3.9 mg),
- angles ``theta_ij = asin(u_i . u_j)`` from the rows ``u_j`` of the sensor's misalignment matrix.

The bound is eq (9) of ``host/accelerometer/calibration.py`` evaluated for the recorded poses: sensor noise
``sigma_s = density * sqrt(pi/2 * f_c)`` (first-order filter; 1.1 mg at 200 ug/sqrt(Hz), 20 Hz), times 1.08 for
the filter's correlation of neighbouring 50 Hz samples (rho = exp(-2 pi f_c / 50 Hz) = 0.08,
sqrt((1 + rho) / (1 - rho))); quantisation ``q^2/12`` with ``q`` one LSB; ``N`` the samples of the shortest hold;
bias ``beta`` of eq (8) evaluated with 0.9 sigma_s (the sample-and-hold interpolation can lower the noise by up
to 6 %, which raises the bias). For the 24 poses held 5 s below: sigma_p = 0.115 mg, beta = 0.32 mg, and the
bound is 0.9 mg on the offsets, 0.11 % on the scales and 0.12 deg on the angles (the worst-case bias term
dominates; the errors found are ~0.03 mg, 0.01 % and 0.02 deg).

With a noiseless sensor the quantisation is deterministic: every hold reads one constant code per axis, its
error (up to q/2 = 1.95 mg per axis) does not average out, and rest detection cannot tell such a hold from a
stuck sensor, so it is refused (last test).
"""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim import device
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.accelerometer.fit import AccCalibrator, parameter_bounds


def truth_in_counts(truth) -> dict[str, np.ndarray]:
    s, a = truth["sensor"], truth["adc"]
    span_v = a["vref_high_v"] - a["vref_low_v"]
    codes_per_v = 2 ** a["adc_bits"] / span_v
    gain = np.asarray(s["gain_v_per_g"])
    v0 = s["supply_v"] / 2
    offset = (a["ref_v"] + a["gain"] * (v0 + gain * np.asarray(s["offset_g"]) - a["ref_v"]) - a["vref_low_v"]) \
        * codes_per_v - 0.5
    scale = a["gain"] * gain * codes_per_v
    u = np.asarray(s["axes"])
    g = u @ u.T
    angles = np.degrees(np.arcsin([g[0, 1], g[0, 2], g[1, 2]]))
    return {"offset": offset, "scale": scale, "angles_deg": angles, "axes": u}


def bound_for(truth, cal_windows, poses_up, scale) -> dict[str, np.ndarray]:
    s = truth["sensor"]
    sigma_s = s["noise_density_g_rthz"] * np.sqrt(np.pi / 2 * np.asarray(s["cutoff_hz"]))  # (3,) g
    rho = np.exp(-2 * np.pi * np.asarray(s["cutoff_hz"]) / truth["adc"]["sampling_rate_hz"])
    q = 1.0 / scale  # g per count
    n = min(w.n_samples for w in cal_windows)
    sigma_p = float(np.max(np.sqrt((sigma_s**2 + q**2 / 12) / n) * np.sqrt((1 + rho) / (1 - rho))))
    sig_lo = 0.9 * sigma_s
    beta = float(np.max(q / np.pi * np.exp(-2 * np.pi**2 * sig_lo**2 / q**2)))
    pose_g = poses_up @ np.asarray(s["axes"]).T
    return parameter_bounds(pose_g, noise_g=sigma_p, bias_g=beta) | {"sigma_p": sigma_p, "beta": beta}


@pytest.fixture(scope="module")
def recorded():
    sensor = SensorModel.draw(seed=7)
    logger = device.Logger(sensor=sensor, device_id=7)
    poses = CalibrationPoses(n_poses=24, hold_s=5.0, move_s=2.0, seed=2)
    res = logger.record(poses)
    return logger, res


def test_ten_bit_pose_session_recovers_the_sensor_within_the_lsb_bound(recorded):
    logger, res = recorded
    assert logger.adc.adc_bits == 10
    run = AccCalibrator().calibrate(res.codes.astype(float), sampling_rate_hz=logger.adc.sampling_rate_hz,
                                    input_unit="counts", zero=512.0, unit_per_g=256.0, valid_range=(0, 1023))
    cal = run.calibration_
    assert cal.n_poses == 24
    t = truth_in_counts(res.truth)
    b = bound_for(res.truth, run.windows_, res.truth["specific_force_g"], t["scale"])
    off_err_g = np.abs(cal.offset - t["offset"]) / t["scale"]
    scale_err = np.abs(cal.scale_per_g / t["scale"] - 1)
    ang_err = np.abs(cal.angles_deg - t["angles_deg"])
    print(f"\nper-pose noise sigma_p {b['sigma_p'] * 1e3:.3f} mg, quantisation bias beta {b['beta'] * 1e3:.3f} mg")
    print(f"offset error (mg)  {(off_err_g * 1e3).round(3)}  bound {(b['offset_g'] * 1e3).round(3)}")
    print(f"scale error (%)    {(scale_err * 100).round(4)}  bound {(b['scale'] * 100).round(4)}")
    print(f"angle error (deg)  {ang_err.round(4)}  bound {b['angles_deg'].round(4)}")
    print(f"true angles {t['angles_deg'].round(3)} deg, true offsets {t['offset'].round(2)} counts")
    assert (off_err_g < b["offset_g"]).all()
    assert (scale_err < b["scale"]).all()
    assert (ang_err < b["angles_deg"]).all()
    # the bound is tight enough to mean something: below one LSB on the offsets
    assert (b["offset_g"] < 1.0 / t["scale"]).all()
    # calibrated fresh orientations read 1 g; the truth maps counts -> g through the sensor geometry
    rng = np.random.default_rng(0)
    up = rng.standard_normal((500, 3))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    counts = t["offset"] + t["scale"] * (up @ t["axes"].T)
    err = np.abs(np.linalg.norm(cal.apply(counts, unit="counts"), axis=1) - 1)
    print(f"max ||a| - 1| on 500 fresh orientations: {err.max() * 1e3:.3f} mg")
    assert err.max() < 2e-3


def test_cli_on_the_emulated_recording_and_header_slot(recorded, tmp_path, capsys):
    from gaitlog.host.cli import main
    from gaitlog.host.files.recording import Recording

    logger, res = recorded
    rec = Recording.from_arrays(res.codes, flags=res.flags, sampling_rate_hz=logger.adc.sampling_rate_hz,
                                header=logger.header, adc_bits=logger.adc.adc_bits)
    valid = rec.valid.copy()
    valid[1000:1010] = False  # a gap inside the recording: those samples are skipped, not refused
    rec = Recording.from_arrays(res.codes, valid=valid, flags=res.flags, sampling_rate_hz=logger.adc.sampling_rate_hz,
                                header=logger.header, adc_bits=logger.adc.adc_bits)
    npz = tmp_path / "poses.npz"
    rec.save_npz(npz)
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(npz), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "model: 9-param" in text and "10-bit" in text
    cal = AccCalibration.load(out)
    t = truth_in_counts(res.truth)
    assert cal.input_unit == "counts" and cal.n_poses >= 23
    assert (np.abs(cal.offset - t["offset"]) / t["scale"] < 1e-3).all()
    # the device header carries the constants (PROTOCOL.md 2.1) and gives the same g within Q-format rounding
    slot = cal.to_header_calibration()
    from gaitlog.protocol.header import CalibrationSlot

    back = CalibrationSlot.from_bytes(slot.to_bytes())
    np.testing.assert_allclose(back.apply(res.codes[:100]), cal.apply(res.codes[:100]), atol=1e-6)
    # --units describes a CSV: a logger recording states its own (counts): exit 1, no file
    out2 = tmp_path / "cal2.json"
    assert main(["calibrate", str(npz), "--out", str(out2), "--units", "g"]) == 1
    assert "--units applies to a CSV input only" in capsys.readouterr().err and not out2.exists()


def test_noiseless_sensor_holds_look_stuck_and_are_refused():
    from gaitlog.host.accelerometer.calibration import CalibrationError

    sensor = SensorModel.draw(seed=7, noise_density_g_rthz=0.0)
    logger = device.Logger(sensor=sensor, device_id=8)
    res = logger.record(CalibrationPoses(n_poses=12, hold_s=4.0, move_s=2.0, seed=2))
    run = AccCalibrator()
    with pytest.raises(CalibrationError, match=r"found 0 static poses .*12 rejected"):
        run.calibrate(res.codes.astype(float), sampling_rate_hz=50.0, input_unit="counts", zero=512.0,
                      unit_per_g=256.0)
    assert all("constant (SD = 0)" in reason for _, reason in run.detector_.rejected_)


def test_cli_takes_the_memory_image_directly(recorded, tmp_path, capsys):
    from gaitlog.host.cli import main

    logger, res = recorded
    image = logger.save_image(tmp_path / "poses.glimg")
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(image), "--out", str(out)]) == 0
    assert "static poses: 24 used" in capsys.readouterr().out
    cal = AccCalibration.load(out)
    t = truth_in_counts(res.truth)
    assert (np.abs(cal.offset - t["offset"]) / t["scale"] < 1e-3).all()
