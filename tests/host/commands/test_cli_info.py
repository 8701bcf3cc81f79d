"""`gaitlog info` (--json, -q/-v, the words for a perfect dump's unwritten blocks), and -q/-v of dump and serve."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.cli import main
from gaitlog.protocol.image import build_image, parse_image

ROOT = Path(__file__).resolve().parents[3]
N_SAMPLES = 700


@pytest.fixture
def image(tmp_path):
    logger = Logger(device_id=5)
    logger.record(Motion(acc_g=np.tile([0.0, 0.0, 1.0], (N_SAMPLES, 1)), sampling_rate_hz=50.0), start_time_s=1_700_000_000)
    path = tmp_path / "rec.glimg"
    logger.save_image(path)
    return path


@pytest.fixture
def dumped(image, tmp_path, capsys):
    out = tmp_path / "d.glimg"
    assert main(["dump", "--port", f"emu://{image}", "--out", str(out), "-q"]) == 0
    assert capsys.readouterr().out == ""
    return out


def test_a_perfect_dump_calls_the_unwritten_memory_empty(dumped, capsys):
    assert main(["info", str(dumped)]) == 0
    out = capsys.readouterr().out
    assert "never received" not in out
    # 700 samples = 2800 bytes: blocks 0-2 of 1 KiB hold them; the rest of the 256 + 52 blocks (262,144 bytes of
    # samples and the 2662 step records of the default logger, header version 3) was never written
    assert "note: blocks 3-307 empty (never written by the logger, so not transferred)" in out


def test_a_block_lost_on_the_way_is_still_called_missing(image, tmp_path, capsys):
    contents = parse_image(image.read_bytes())
    region = np.concatenate([contents.memory, contents.step_memory]).tobytes()
    lossy = tmp_path / "lossy.glimg"
    lossy.write_bytes(build_image(contents.header, region, missing_blocks=[1, 5]))
    assert main(["info", str(lossy)]) == 0
    out, err = capsys.readouterr()
    assert err.startswith("gaitlog info: warning: ") and "not usable" in err and err.count("\n") == 2
    assert "samples missing" in err.splitlines()[1]  # the one line of losses, said by every command
    assert "note: block 1 marked missing (never received)" in out
    assert "note: block 5 empty (never written by the logger" in out


def test_info_json_of_a_file(dumped, capsys):
    assert main(["info", str(dumped), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["header"]["device_id"] == 5 and report["header"]["sampling_rate_hz"] == 50.0
    assert report["header"]["samples_stored"] == N_SAMPLES and report["header"]["firmware_version"] == "1.3"
    assert report["samples"] == {"n_stored": N_SAMPLES, "n_valid": N_SAMPLES, "duration_s": N_SAMPLES / 50.0,
                                 "gaps": []}
    assert any("empty (never written" in note for note in report["notes"])


def test_info_json_of_a_device(image, capsys):
    assert main(["info", "--port", f"emu://{image}", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["state"] == "idle" and report["device"]["sampling_rate_hz"] == 50.0
    assert report["header"]["samples_written"] == N_SAMPLES and report["device"]["device_id"] == 5


def test_info_quiet_prints_nothing_and_verbose_lists_every_gap(tmp_path, capsys):
    logger = Logger()
    logger.record(Motion(acc_g=np.tile([0.0, 0.0, 1.0], (12_800, 1)), sampling_rate_hz=50.0))  # 50 blocks of 256 samples
    contents = parse_image(logger.save_image(tmp_path / "full.glimg").read_bytes())
    holey = tmp_path / "holey.glimg"
    region = np.concatenate([contents.memory, contents.step_memory]).tobytes()
    holey.write_bytes(build_image(contents.header, region, missing_blocks=range(0, 50, 2)))  # 25 gaps
    assert main(["info", str(holey), "-q"]) == 0
    assert capsys.readouterr().out == ""
    assert main(["info", str(holey)]) == 0
    out = capsys.readouterr().out
    assert "25 gap(s)" in out and "... 5 more gap(s) (-v lists them all)" in out
    assert out.count("  gap: samples") == 20
    assert main(["info", str(holey), "-v"]) == 0
    assert capsys.readouterr().out.count("  gap: samples") == 25


def test_quiet_and_verbose_exclude_each_other(image, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["info", str(image), "-q", "-v"])
    assert exc.value.code == 2 and "not allowed with" in capsys.readouterr().err


def test_dump_verbose_reports_the_link(image, tmp_path, capsys):
    assert main(["dump", "--port", f"emu://{image}", "--out", str(tmp_path / "v.glimg"), "-v"]) == 0
    out = capsys.readouterr().out
    assert "link: " in out and "command retries" in out and "NAKs: none" in out


@pytest.mark.parametrize("flag, says_serving", [("-q", False), ("-v", True)])
def test_serve_quiet_and_verbose(image, flag, says_serving):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog", "serve", str(image), "--tcp", "0", flag],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("socket://127.0.0.1:")
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0
    assert ("serving" in err) == says_serving
    assert (f"logger 5: {N_SAMPLES} samples" in err) == says_serving
