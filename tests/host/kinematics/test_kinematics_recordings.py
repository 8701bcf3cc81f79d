"""Morris and Hall from recordings, end to end: simulated motion -> recording files -> CLI -> results vs truth.

Error figures and why (Morris, :func:`_noise_scale_deg`): the angular acceleration comes from differences of
accelerometers ``arm = 0.05 m`` apart, so a white reading noise ``σ`` (g) gives a white angular-acceleration
noise ``σα = g0·‖row of H⁺‖·σ``; integrated twice over a cycle ``T`` it leaves an orientation error of scale
``σα·√dt·T^1.5/√3`` (the unconstrained end-point standard deviation; the cycle constraints then pin the
ends). At Morris' 40 dB the sagittal channels (1.2 g RMS) carry 12 mg of noise: scale 12.8°, errors of 3-29°
over 12 seeds. At 60 dB: scale 1.3°, errors 0.4-1.8°. The bound used is 2.5 x the scale. Hall: 0.01 rad/s of
rate noise at 10 kHz over 0.2 s integrates to ~0.01°; the pre-test offset mean leaves 0.01/√201 rad/s, ~0.01°
over the test; the tilt from 201 gravity samples at 2 mg, ~0.01°: bound 0.05°.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.host.cli import main
from gaitlog.host.kinematics.accelerometer_pairs import AngularVelocityFromAccelerometers
from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
from gaitlog.host.kinematics.platform_description import HallPlatform, MorrisPlatform
from gaitlog.host.kinematics.sensor_csv import (
    SensorRecording,
    read_sensor_csv,
    split_unit,
    write_sensor_csv,
)
from gaitlog.host.kinematics.simulated_instruments import SimulatedInstrument, noise_sd_for_snr, simulate_morris
from gaitlog.units import STANDARD_GRAVITY_M_S2

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _table(path: Path) -> dict[str, np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    names = lines[0].split(",")
    data = np.array([[float(c) if c else np.nan for c in ln.split(",")] for ln in lines[1:]])
    return {n: data[:, i] for i, n in enumerate(names)}


def _dcm(cols: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.stack([[cols[f"{prefix}{i + 1}{j + 1}"] for j in range(3)] for i in range(3)]).transpose(2, 0, 1)


def _noise_scale_deg(platform: MorrisPlatform, clean_readings_g: np.ndarray, snr_db: float, rate_hz: float,
                     cycle_s: float) -> float:
    sd = noise_sd_for_snr(clean_readings_g, snr_db)
    _, pinv, _, _ = AngularVelocityFromAccelerometers(
        positions_m=platform.positions_m, axes=platform.axes, fixed_zero_axes=platform.assume_zero_rate_axes
    )._design()
    sigma_alpha = STANDARD_GRAVITY_M_S2 * np.sqrt((pinv[3:] ** 2 * sd**2).sum(axis=1))
    return float(np.degrees(sigma_alpha.max() * np.sqrt(1 / rate_hz) * cycle_s**1.5 / np.sqrt(3)))


def _morris_error_deg(out: Path, rec: Path) -> float:
    est = _table(out / "morris_orientation.csv")
    truth = _table(rec / "morris_truth.csv")
    idx = np.searchsorted(truth["time_s"], est["time_s"] - 1e-9)
    lam, true = _dcm(est, "dcm"), _dcm(truth, "dcm")[idx]
    heading = lam[0] @ true[0].T  # accelerometers cannot sense the heading: align it at the cycle start
    rel = np.swapaxes(lam, 1, 2) @ (heading @ true)
    return float(np.degrees(Rotation.from_matrix(rel).magnitude().max()))


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("rec")
    assert main(["kinematics", "simulate", "--write-recording", str(d), "-q"]) == 0
    return d


def test_simulate_writes_the_recordings_and_platforms(written: Path) -> None:
    names = sorted(p.name for p in written.iterdir())
    assert names == ["hall.csv", "hall_platform.json", "hall_truth.csv", "morris.csv", "morris_platform.json",
                     "morris_truth.csv"]
    rec = read_sensor_csv(written / "morris.csv")
    assert rec.sampling_rate_hz == pytest.approx(100.0)
    assert rec.t_s[-1] - rec.t_s[0] == pytest.approx(2.55)  # Morris' 2.56 s record
    plat = MorrisPlatform.load(written / "morris_platform.json")
    assert len(plat.sensors) == 5 and plat.assume_zero_rate_axes == (2,)  # as published
    hall = read_sensor_csv(written / "hall.csv")
    assert hall.sampling_rate_hz == pytest.approx(10_000.0)


def test_morris_from_the_recording_file_is_within_the_noise_figure(written: Path, tmp_path: Path) -> None:
    out = tmp_path / "m"
    assert main(["kinematics", "morris", str(written / "morris.csv"), "--platform",
                 str(written / "morris_platform.json"), "--out", str(out), "-q"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["morris_orientation.csv", "morris_angular_velocity.csv", "morris_translation.csv",
                            "morris_angular_velocity.png", "morris_dcm.png", "morris_translation.png",
                            "morris_stick_figure.png", "morris_animation.gif"])
    for p in out.glob("*.png"):
        assert p.read_bytes()[:8] == PNG_MAGIC
    # the animation plays: its frames read back as images (12.5 frames/s over a 1.1 s cycle)
    from PIL import Image

    with Image.open(out / "morris_animation.gif") as im:
        assert im.format == "GIF" and im.n_frames == 14
        im.seek(5)
        frame = np.asarray(im.convert("RGB"))
    assert frame.ndim == 3 and frame.std() > 0
    # 5 accelerometers at 40 dB: noise scale 12.8 deg plus the omega3 = 0 bias (16 deg noise-free)
    err = _morris_error_deg(out, written)
    assert err < 2.5 * 12.8 + 16.3
    t = _table(out / "morris_orientation.csv")["time_s"]
    assert 1.2 <= t[0] <= 1.35 and t[-1] - t[0] == pytest.approx(1.1, abs=0.02)  # foot-flat to foot-flat


@pytest.mark.parametrize(("snr_db", "seed"), [(40.0, 0), (60.0, 0), (60.0, 3)])
def test_six_accelerometers_error_follows_the_noise(tmp_path: Path, snr_db: float, seed: int) -> None:
    rec = tmp_path / "rec"
    assert main(["kinematics", "simulate", "--write-recording", str(rec), "--accelerometers", "6",
                 "--snr-db", str(snr_db), "--seed", str(seed), "-q"]) == 0
    out = tmp_path / "out"
    assert main(["kinematics", "morris", str(rec / "morris.csv"), "--platform", str(rec / "morris_platform.json"),
                 "--out", str(out), "--no-animation", "-q"]) == 0
    clean = simulate_morris(n_accelerometers=6, snr_db=None)
    readings = np.column_stack(list(clean.columns.values()))
    scale = _noise_scale_deg(clean.platform, readings, snr_db, 100.0, 1.1)
    assert scale == pytest.approx(12.8 if snr_db == 40 else 1.28, rel=0.02)
    err = _morris_error_deg(out, rec)
    assert err < 2.5 * scale


def _recording(sim: SimulatedInstrument) -> SensorRecording:
    ch, q = {}, {}
    for name, v in sim.columns.items():
        s, quantity, f = split_unit(name)
        ch[s], q[s] = v * f, quantity
    return SensorRecording(sim.t_s, ch, q, 100.0)


def _orientation_error_deg(sim: SimulatedInstrument) -> float:
    cyc = analyse_morris_recording(_recording(sim), sim.platform)[0]
    tr = sim.truth
    true = np.stack([[tr[f"dcm{i + 1}{j + 1}"] for j in range(3)] for i in range(3)]).transpose(2, 0, 1)
    true = true[cyc.start : cyc.stop + 1]
    rel = np.swapaxes(cyc.dcm, 1, 2) @ (cyc.dcm[0] @ true[0].T @ true)
    return float(np.degrees(Rotation.from_matrix(rel).magnitude().max()))


def test_what_morris_omega3_assumption_costs() -> None:
    """Noise off: six accelerometers recover the orientation to the trapezoid's error; five, with ω3 assumed
    zero, leave 3.1° when the shank has no axial rotation of its own (the ω3 of up to 0.21 rad/s left is the
    coupling of sagittal and coronal swing) and 16° with ±4° of axial rotation (0.42 rad/s)."""
    six = _orientation_error_deg(simulate_morris(n_accelerometers=6, snr_db=None))
    five_no_axial = _orientation_error_deg(simulate_morris(n_accelerometers=5, snr_db=None, axial_rotation=False))
    five = _orientation_error_deg(simulate_morris(n_accelerometers=5, snr_db=None))
    assert six < 0.1
    assert five_no_axial == pytest.approx(3.1, abs=0.3)
    assert five == pytest.approx(15.9, abs=0.5)


def test_fig4_before_and_after_the_drift_filter_differ_with_noise(written: Path, tmp_path: Path) -> None:
    out = tmp_path / "m"
    assert main(["kinematics", "morris", str(written / "morris.csv"), "--platform",
                 str(written / "morris_platform.json"), "--out", str(out), "--no-animation", "-q"]) == 0
    w = _table(out / "morris_angular_velocity.csv")
    raw, filt = w["omega2_before_drift_filter_rad_s"], w["omega2_rad_s"]
    assert filt[0] == pytest.approx(filt[-1], abs=1e-6)  # start = end after the filter
    assert abs(raw[-1] - raw[0]) > 0.01  # and not before it


def test_cycle_option_selects_and_matches_the_phase(written: Path, tmp_path: Path) -> None:
    out = tmp_path / "m"
    assert main(["kinematics", "morris", str(written / "morris.csv"), "--platform",
                 str(written / "morris_platform.json"), "--out", str(out), "--cycle", "1.27", "2.40",
                 "--no-animation", "--azimuth", "30", "--elevation", "20", "-q"]) == 0
    t = _table(out / "morris_orientation.csv")["time_s"]
    assert t[0] == pytest.approx(1.27)
    assert abs(t[-1] - 2.37) <= 0.03  # end moved to the start's phase (the true period is 1.1 s)


def test_hall_from_the_recording_file(written: Path, tmp_path: Path) -> None:
    out = tmp_path / "h"
    assert main(["kinematics", "hall", str(written / "hall.csv"), "--platform", str(written / "hall_platform.json"),
                 "--out", str(out), "-q"]) == 0
    est = _table(out / "hall_joint_angles.csv")
    truth = _table(written / "hall_truth.csv")
    got = np.radians(np.column_stack([est["flexion_deg"], est["version_deg"], est["axial_rotation_deg"]]))
    want = np.column_stack([truth["phi_rad"], truth["theta_rad"], truth["psi_rad"]])
    assert np.degrees(np.abs(got - want).max()) < 0.05
    # the initial A-B transformation is the pre-test posture (12°, 6° off neutral), not identity
    assert np.degrees(got[0]) == pytest.approx(np.degrees(want[0]), abs=0.05)
    assert abs(np.degrees(got[0, 0])) > 10


def test_hall_identity_start_is_wrong_and_spine_sequence(written: Path, tmp_path: Path) -> None:
    plat = json.loads((written / "hall_platform.json").read_text())
    plat["initial_joint_deg"] = [0.0, 0.0, 0.0]
    (tmp_path / "ident.json").write_text(json.dumps(plat))
    assert main(["kinematics", "hall", str(written / "hall.csv"), "--platform", str(tmp_path / "ident.json"),
                 "--out", str(tmp_path / "i"), "-q"]) == 0
    est = _table(tmp_path / "i" / "hall_joint_angles.csv")
    truth = _table(written / "hall_truth.csv")
    assert abs(est["flexion_deg"][-1] - np.degrees(truth["phi_rad"][-1])) > 5
    # spine: x - z' - y'' angles of the same joint
    plat["initial_joint_deg"] = None
    plat["sequence"] = "xzy"
    (tmp_path / "spine.json").write_text(json.dumps(plat))
    assert main(["kinematics", "hall", str(written / "hall.csv"), "--platform", str(tmp_path / "spine.json"),
                 "--out", str(tmp_path / "s"), "-q"]) == 0
    est = _table(tmp_path / "s" / "hall_joint_angles.csv")
    joint = np.stack([[truth[f"T{i + 1}{j + 1}"] for j in range(3)] for i in range(3)]).transpose(2, 0, 1)
    want = Rotation.from_matrix(np.swapaxes(joint, 1, 2)).as_euler("XZY", degrees=True)
    got = np.column_stack([est["tilt_deg"], est["rotation_deg"], est["flexion_deg"]])
    assert np.abs(got - want).max() < 0.05


def test_hall_printed_reflection_is_refused_with_the_reason(written: Path, tmp_path: Path) -> None:
    plat = json.loads((written / "hall_platform.json").read_text())
    plat["links"]["A"]["sensor_to_link"] = [[0, 1, 0], [0, 0, 1], [-1, 0, 0]]  # Hall eqs (5)-(6) as printed
    (tmp_path / "p.json").write_text(json.dumps(plat))
    with pytest.raises(Exception, match="determinant -1.*reflection"):
        HallPlatform.load(tmp_path / "p.json")


def test_bad_recordings_are_refused_without_output(written: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    plat = str(written / "morris_platform.json")
    cases = {
        "time_s,acc1,acc2\n0,1,2\n0.01,1,2\n": "does not state its unit",
        "time_s,acc1_g\n0,1\n0.01,1\n0.05,1\n0.06,1\n": "differs from the median",
        "time_s,acc1_g,acc2_g,acc3_g,acc4_g,acc6_g\n0,1,1,1,1,1\n0.01,1,1,1,1,1\n": "no column for sensor 'acc5'",
        "time_s,acc1_g,acc2_g\n0,1,x\n": "not a table",
    }
    for text, message in cases.items():
        (tmp_path / "r.csv").write_text(text)
        assert main(["kinematics", "morris", str(tmp_path / "r.csv"), "--platform", plat,
                     "--out", str(tmp_path / "o")]) == 1
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
        assert not (tmp_path / "o").exists()


def test_sensor_csv_round_trip_and_units(tmp_path: Path) -> None:
    t = np.arange(5) / 50.0
    write_sensor_csv(tmp_path / "a.csv", t, {"g1_deg_s": np.full(5, 90.0), "a1_m_s2": np.full(5, STANDARD_GRAVITY_M_S2),
                                             "a2_mg": np.full(5, 500.0)}, comment="two\nlines")
    rec = read_sensor_csv(tmp_path / "a.csv")
    assert rec.sampling_rate_hz == pytest.approx(50.0)
    np.testing.assert_allclose(rec.channels["g1"], np.pi / 2)
    np.testing.assert_allclose(rec.channels["a1"], 1.0)
    np.testing.assert_allclose(rec.channels["a2"], 0.5)
    assert rec.quantities == {"g1": "angular rate", "a1": "specific force", "a2": "specific force"}


def test_a_cycle_not_starting_in_foot_flat_is_flagged(written: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    args = ["kinematics", "morris", str(written / "morris.csv"), "--platform", str(written / "morris_platform.json"),
            "--no-animation"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert "warning" not in capsys.readouterr().out  # the cycle found starts in foot-flat
    assert main([*args, "--out", str(tmp_path / "b"), "--cycle", "0.8", "1.9"]) == 0  # mid-swing
    assert "not turning about a fixed pivot" in capsys.readouterr().out
