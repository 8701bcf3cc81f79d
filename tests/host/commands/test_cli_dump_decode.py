"""CLI of the dump path: `gaitlog dump` with --capture / --resume over emu://, `gaitlog decode` of a wire
capture and with --calibration, `gaitlog record --motion replay`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.cli import main
from gaitlog.host.files.recording import Recording
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.raw_dump import raw_dump_bytes
from gaitlog.units import STANDARD_GRAVITY_M_S2

CAP = 65536


def _image(tmp_path, n=CAP + 777, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    acc = np.c_[np.sin(0.03 * t), np.cos(0.03 * t), 0.5 + 0.2 * np.sin(0.4 * t)] + 0.05 * rng.standard_normal((n, 3))
    logger = Logger(overwrite=True)
    result = logger.record(Motion(acc_g=acc, sampling_rate_hz=50.0), start_time_s=1_700_000_000)
    path = tmp_path / "rec.glimg"
    logger.save_image(path)
    return path, np.asarray(result.codes), np.asarray(result.flags), np.asarray(result.sample_numbers)


def test_dump_capture_decodes_to_the_same_samples(tmp_path):
    image, codes, flags, numbers = _image(tmp_path)
    url = f"emu://{image}?corrupt=0.0005&seed=9"
    assert main(["dump", "--port", url, "--out", str(tmp_path / "d.glimg"), "--capture",
                 str(tmp_path / "wire.bin"), "--timeout", "0.2", "--quiet"]) == 0
    assert main(["decode", str(tmp_path / "wire.bin"), "--out", str(tmp_path / "w"), "--quiet"]) == 0
    rec = Recording.load(tmp_path / "w.npz")
    # the capture holds the damaged first pass and the re-reads: together every sample, exact
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)
    np.testing.assert_array_equal(rec.sample_numbers, numbers)


def test_cli_resume_after_cut(tmp_path, capsys):
    image, codes, flags, numbers = _image(tmp_path)
    out = tmp_path / "d.glimg"
    rc = main(["dump", "--port", f"emu://{image}?cut_after=150000", "--out", str(out), "--timeout", "0.1",
               "--quiet"])
    err = capsys.readouterr().err
    assert rc == 1 and "--resume" in err
    assert not out.exists() and (tmp_path / "d.glimg.part").exists()
    assert main(["dump", "--port", f"emu://{image}", "--out", str(out), "--resume"]) == 0
    assert "resumed" in capsys.readouterr().out
    meta = json.loads((tmp_path / "d.glimg.json").read_text())
    assert meta["resumed"] and meta["complete"] and meta["bytes_from_partial_state"] > 100_000
    assert main(["decode", str(out), "--out", str(tmp_path / "r"), "--quiet"]) == 0
    rec = Recording.load(tmp_path / "r.npz")
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.sample_numbers, numbers)  # none lost, none doubled


def test_decode_of_a_raw_dump_cut_before_its_trailer(tmp_path, capsys):
    rng = np.random.default_rng(5)
    codes = rng.integers(0, 1024, (600, 3))
    words = (codes[:, 0] | (codes[:, 1] << 10) | (codes[:, 2] << 20)).astype("<u4")
    h = DeviceHeader(capacity_samples=1024, samples_written=600, write_index=600)
    raw = tmp_path / "rx.bin"
    raw.write_bytes(raw_dump_bytes(h.to_bytes(), words.tobytes())[: 256 + 4 * 500])  # cut before its trailer
    assert main(["decode", str(raw), "--out", str(tmp_path / "d")]) == 1  # all missing: above --max-missing
    out, err = capsys.readouterr()
    assert "600 samples (0 valid, 600 missing)" in out and "its 500 samples present cannot be verified" in err
    assert "600 of 600 samples missing (100.0 %)" in err and "above --max-missing 5 %" in err
    assert not Recording.load(tmp_path / "d.npz").valid.any()
    assert main(["decode", str(raw), "--out", str(tmp_path / "a"), "--accept-unverified", "--max-missing", "20"]) == 0
    out, err = capsys.readouterr()
    assert "(500 valid, 100 missing)" in out and "500 samples and 0 step records UNVERIFIED" in err
    rec = Recording.load(tmp_path / "a.npz")
    np.testing.assert_array_equal(rec.codes[rec.valid], codes[:500])
    assert any("UNVERIFIED" in n for n in rec.notes)


def test_decode_with_calibration_file(tmp_path):

    image, codes, *_ = _image(tmp_path, n=2000)
    cal = AccCalibration.from_parameters(offset=[500, 510, 520], scale_per_g=[250, 260, 270], input_unit="counts")
    cal.save(tmp_path / "cal.json")
    assert main(["decode", str(image), "--out", str(tmp_path / "c"), "--calibration", str(tmp_path / "cal.json"),
                 "--quiet"]) == 0
    cols = Recording.read_csv(tmp_path / "c.csv")
    expected = (codes - np.array([500, 510, 520])) / np.array([250, 260, 270])  # scale in counts per g
    np.testing.assert_allclose(np.c_[cols["x_g"], cols["y_g"], cols["z_g"]], expected, atol=2e-6)


def test_record_replay_csv(tmp_path, capsys):
    t = np.arange(0, 60, 0.01)
    acc_ms2 = np.c_[np.zeros_like(t), STANDARD_GRAVITY_M_S2 * np.sin(0.1 * t), STANDARD_GRAVITY_M_S2 * np.cos(0.1 * t)]
    lines = ["time,ax,ay,az"] + [f"{a:.3f},{b:.5f},{c:.5f},{d:.5f}" for a, (b, c, d) in zip(t, acc_ms2)]
    (tmp_path / "walk.csv").write_text("\n".join(lines) + "\n")
    assert main(["record", "--motion", "replay", str(tmp_path / "walk.csv"), "--units", "m/s2", "--columns",
                 "ax,ay,az", "--start-time", "0", "--out", str(tmp_path / "r.glimg")]) == 0
    out, err = capsys.readouterr()
    assert "recorded" in out and "interpolated" not in err     # nothing was missing
    assert main(["decode", str(tmp_path / "r.glimg"), "--out", str(tmp_path / "r"), "--quiet"]) == 0
    rec = Recording.load(tmp_path / "r.npz")
    g = rec.acc_g()
    # about 1 g all along, turning from +z towards +y (sensor errors of a few per cent allowed)
    assert rec.n_samples == pytest.approx(3000, abs=60)
    # nominal map on an uncalibrated sensor (offsets up to 0.1 g, gains up to 5 %) plus noise
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=0.25)
    assert g[:100, 2].mean() > 0.85 and g[750:820, 1].mean() > 0.85  # sin(0.1 t) peaks at t = 15.7 s
    assert main(["record", "--motion", "replay", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "n.glimg")]) == 1
    assert "nope.csv" in capsys.readouterr().err and not (tmp_path / "n.glimg").exists()


def test_record_replay_says_how_many_samples_were_interpolated(tmp_path, capsys):
    from gaitlog.firmware_sim.world.replay import Replay
    from gaitlog.host.files.inputs import read_acceleration

    t = np.arange(0, 30, 0.01)
    keep = np.ones(t.size, bool)
    keep[500:530] = False                      # 30 rows lost: a hole in the time column
    keep[1200:1210] = False                    # and 10 more
    lines = ["time_s,x_g,y_g,z_g"] + [f"{a:.2f},0.0,{np.sin(0.1 * a):.5f},{np.cos(0.1 * a):.5f}"
                                      for a in t[keep]]
    path = tmp_path / "gappy.csv"
    path.write_text("\n".join(lines) + "\n")
    data = read_acceleration(path)
    assert data.n_samples == t.size and data.n_missing == 40
    replay = Replay.from_samples(data.acc_g, data.valid, sampling_rate_hz=data.sampling_rate_hz)
    assert replay.n_interpolated == 40
    assert replay.truth["filled_packets"].tolist() == [[500, 529], [1200, 1209]]
    assert main(["record", "--motion", "replay", str(path), "--start-time", "0", "--out",
                 str(tmp_path / "g.glimg")]) == 0
    err = capsys.readouterr().err
    assert f"40 of {t.size} samples" in err and "(1.33%)" in err and "interpolated" in err
    # -q: only the line that says which samples the input lacks
    assert main(["record", "--motion", "replay", str(path), "--start-time", "0", "-q", "--out",
                 str(tmp_path / "h.glimg")]) == 0
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "40 of 3,000 samples missing (1.3 %) at samples 500-529, " \
        "1,200-1,209" in err


def test_record_refuses_input_flags_without_a_replay(tmp_path, capsys):
    assert main(["record", "--motion", "walk", "--rate", "100", "--out", str(tmp_path / "w.glimg")]) == 2
    assert "--rate: only for --motion replay FILE" in capsys.readouterr().err
    assert not (tmp_path / "w.glimg").exists()
