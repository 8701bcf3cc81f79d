"""``gaitlog pic verify``: the PIC16 assembly in gpsim against the model, on recordings the decoder reads."""

from __future__ import annotations

import json

import pytest

from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.host.cli import main

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")
IPOL_TRIAL = "ipol-lowerback-dev/GaitData/1-1_lb.txt"


@pytest.fixture(scope="module")
def walk_image(tmp_path_factory):
    out = tmp_path_factory.mktemp("pic") / "walk.glimg"
    assert main(["record", "--motion", "walk", "--corridor-length", "10", "--steps", "off", "--start-time", "0",
                 "--out", str(out), "-q"]) == 0
    return out


@needs_gpsim
def test_verify_simulated_walk(walk_image, capsys):
    assert main(["pic", "verify", str(walk_image), "--limit", "600"]) == 0
    out = capsys.readouterr().out
    assert "packed words       600 of 600 samples identical" in out
    assert "calibrated axes    600 of 600 samples identical" in out
    assert "gravity            600 of 600 samples identical" in out
    assert "a_v                600 of 600 samples identical" in out
    assert "y3                 600 of 600 samples identical" in out
    assert "detector           600 of 600 samples identical" in out
    assert "finalise calls" in out and "step 5 (foot-flat detector)" in out
    assert "92,160 available" in out


@needs_gpsim
def test_verify_json(walk_image, capsys):
    assert main(["pic", "verify", str(walk_image), "--limit", "100", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["identical"] and [s["n_identical"] for s in doc["stages"]][:6] == [100] * 6
    assert doc["stages"][6]["name"] == "finalise calls"
    assert doc["ram_total_bytes"] <= 368 and doc["period_cycles"] == 92160
    assert doc["cycles_measured"]["total in assembly"]["worst"] < 92160


@needs_gpsim
def test_verify_ipol_trial(shared_data, tmp_path, capsys):
    trial = shared_data / IPOL_TRIAL
    if not trial.exists():
        pytest.skip(f"{trial} not present")
    image = tmp_path / "ipol.glimg"
    assert main(["record", "--motion", "replay", str(trial), "--steps", "off", "--start-time", "0",
                 "--out", str(image), "-q"]) == 0
    capsys.readouterr()
    assert main(["pic", "verify", str(image), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    n = doc["n_samples"]
    assert n > 1000 and [s["n_identical"] for s in doc["stages"]][:6] == [n] * 6
    assert doc["identical"] and doc["stages"][6]["n_identical"] > 25          # finalise's calls, all identical


@needs_gpsim
def test_a_difference_exits_1_and_names_it(walk_image, tmp_path, monkeypatch, capsys):
    bad = tmp_path / "logger.asm"
    bad.write_text(gl.LOGGER_ASM.read_text().replace("bsf     T_L, 6", "bsf     T_L, 7"))
    monkeypatch.setattr(gl, "LOGGER_ASM", bad)
    assert main(["pic", "verify", str(walk_image), "--limit", "50"]) == 1
    out = capsys.readouterr().out
    assert "packed words       49 of 50 samples identical; first difference: sample 0, byte 3" in out


def test_without_gpsim_exit_1(walk_image, monkeypatch, capsys):
    monkeypatch.setattr(gl, "missing_tools", lambda: "gpsim not installed")
    assert main(["pic", "verify", str(walk_image)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip() == "gaitlog pic verify: error: pic verify needs gputils and gpsim: gpsim not installed"


@pytest.mark.parametrize("argv", [["pic", "check", "x.glimg"], ["pic", "verify", "x.glimg", "--limit", "0"],
                                  ["pic", "verify"]])
def test_bad_usage_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert capsys.readouterr().out == ""


def test_missing_file_exit_1(tmp_path, capsys):
    assert main(["pic", "verify", str(tmp_path / "none.glimg")]) == 1
    err = capsys.readouterr().err
    assert "none.glimg" in err and "no such file" in err


@needs_gpsim
def test_readme_figures_of_the_quick_start_walk(tmp_path, capsys):
    """The README's quick start: ``gaitlog record --motion walk --height 1.75`` then ``gaitlog pic verify``: 59 of
    59 step records identical, worst sample 639,396 cycles (gpsim counts cycles exactly), at most 8 samples
    waiting, 368 of 368 bytes of RAM from gpasm's listing."""
    walk = tmp_path / "walk.glimg"
    assert main(["record", "--motion", "walk", "--height", "1.75", "--out", str(walk), "-q"]) == 0
    assert main(["pic", "verify", str(walk), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    records = next(s for s in got["stages"] if s["name"] == "step records")
    assert got["identical"] and records["n_compared"] == records["n_identical"] == 59
    assert got["cycles_measured"]["total in assembly"]["worst"] == pytest.approx(639_396, rel=0.001)
    assert got["backlog_max_samples"] == 8
    assert got["ram_total_bytes"] == 368
