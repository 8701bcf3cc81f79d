"""``gaitlog plot``: a PNG of the stated size, drawn from the data the overview returns; bad input -> exit 1
and no file."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from gaitlog.host.cli import main
from gaitlog.host.files.recording import Recording
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.host.studies.overview import recording_overview
from gaitlog.protocol.packing import FLAG_MARK


@pytest.fixture(scope="module")
def walk_npz(tmp_path_factory):
    """A simulated 1.75 m walker recorded by the emulated logger (on-line algorithm on), decoded."""
    d = tmp_path_factory.mktemp("walk")
    assert main(["record", "--motion", "walk", "--height", "1.75", "--out", str(d / "walk.glimg"), "--quiet"]) == 0
    assert main(["decode", str(d / "walk.glimg"), "--out", str(d / "walk")]) == 0
    return d / "walk.npz"


def png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_plot_writes_a_png_of_the_stated_size(walk_npz, tmp_path, capsys) -> None:
    out = tmp_path / "fig.png"
    assert main(["plot", str(walk_npz), "--out", str(out), "--start", "5", "--duration", "20",
                 "--size", "900x500"]) == 0
    assert png_size(out) == (900, 500)
    assert str(out) in capsys.readouterr().out
    default = walk_npz.with_suffix(".png")
    assert main(["plot", str(walk_npz)]) == 0
    assert png_size(default) == (1400, 700)


def test_overview_holds_the_chains_events_and_the_device_records(walk_npz) -> None:
    rec = Recording.load(walk_npz)
    sampling_rate_hz = rec.sampling_rate_hz
    cfg = rec.step_config
    ov = recording_overview(rec, leg_length_m=cfg.leg_length_m, foot_length_m=cfg.foot_length_m, start_s=5.0,
                            duration_s=20.0, estimators=["M1", "M3"])
    assert ov.window_s == (5.0, 25.0) and ov.time_s[0] == 5.0 and ov.time_s.size == 20 * sampling_rate_hz
    # the offline chain run independently here, on the whole recording; its events inside [5, 25) s
    steps = StepPipeline(leg_length_m=cfg.leg_length_m, foot_length_m=cfg.foot_length_m).run(
        rec.acc_g(), sampling_rate_hz=sampling_rate_hz, valid=rec.valid).steps_
    for name, idx in (("foot-flat", steps.foot_flat), ("heel-strike", steps.heel_strike),
                      ("toe-off", steps.toe_off)):
        t = idx[idx >= 0] / sampling_rate_hz
        np.testing.assert_array_equal(ov.events_s[name], t[(t >= 5.0) & (t < 25.0)])
    assert 25 <= ov.events_s["foot-flat"].size <= 50  # ~1.8 steps/s
    # the device's records, read straight from the file
    ends = (rec.step_records["end_sample"].astype(np.int64) - rec.sample_numbers[0]) / sampling_rate_hz
    np.testing.assert_array_equal(ov.events_s["device step"], ends[(ends >= 5.0) & (ends < 25.0)])
    assert set(ov.lengths_m) == {"M1", "M3", "M1 device", "M3 device"}
    # the legend says which lengths are calibrated and which raw (a logger without K)
    assert ov.length_kinds == {"M1": "host, no K", "M3": "host, no K", "M1 device": "device, raw K = 1",
                               "M3 device": "device, raw K = 1"}
    t1, m1 = ov.lengths_m["M1"]
    assert t1.size >= 20 and np.all((0.3 < m1) & (m1 < 1.2))
    assert "RecordingOverview(" in repr(ov) and "array" not in repr(ov)


def test_overview_gaps_and_marks() -> None:
    n, sampling_rate_hz = 3000, 50.0
    codes = np.full((n, 3), 512, np.int64)
    codes[:, 2] = 768 + (40 * np.sin(2 * np.pi * 1.8 * np.arange(n) / sampling_rate_hz)).astype(np.int64)
    valid = np.ones(n, bool)
    valid[1000:1010] = False
    valid[2990:] = False
    flags = np.zeros(n, np.uint8)
    flags[[500, 1500]] = FLAG_MARK
    rec = Recording.from_arrays(codes, valid=valid, flags=flags, sampling_rate_hz=sampling_rate_hz)
    ov = recording_overview(rec, leg_length_m=0.9, foot_length_m=0.2, start_s=10.0)
    assert ov.gaps_s == [(20.0, 20.2), (59.8, 60.0)]
    np.testing.assert_array_equal(ov.marks_s, [10.0, 30.0])
    assert np.isnan(ov.acc_g[(1000 - 500):(1010 - 500)]).all()
    assert ov.events_s["device step"].size == 0 and "M1 device" not in ov.lengths_m


@pytest.mark.parametrize(("extra", "message", "code"), [
    (["--start", "1e6"], "outside the recording", 1),        # wrong for this recording: a data error
    (["--estimators", "M1,M9"], "unknown M9", 2),             # wrong for any: a usage error
    (["--size", "big"], "--size", 2),
])
def test_bad_options_fail_without_a_file(walk_npz, tmp_path, capsys, extra, message, code) -> None:
    out = tmp_path / "fig.png"
    assert main(["plot", str(walk_npz), "--out", str(out), *extra]) == code
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_bad_input_fails_without_a_file_and_keeps_an_old_one(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a recording")
    out = tmp_path / "fig.png"
    out.write_bytes(b"old")
    assert main(["plot", str(bad), "--out", str(out)]) == 1
    assert "exists; give --force" in capsys.readouterr().err        # refused before the input is read
    assert main(["plot", str(bad), "--out", str(out), "--force"]) == 1
    err = capsys.readouterr().err
    assert "bad.npz" in err and "Traceback" not in err
    assert out.read_bytes() == b"old"
    assert main(["plot", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "x.png")]) == 1
    assert "no such file" in capsys.readouterr().err and not (tmp_path / "x.png").exists()
