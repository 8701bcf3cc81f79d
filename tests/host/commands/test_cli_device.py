"""`gaitlog device`: every action against the in-process emulator (emu://, persist=1 to see what it changed) and
a served device (TCP, state kept between commands), and bad input: clear one-line error, exit 1, nothing changed."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.transport import serve_tcp
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.cli import main
from gaitlog.protocol.image import parse_image

N_SAMPLES = 500
START_S = 1_700_000_000


@pytest.fixture
def image(tmp_path):
    """A logger (id 7) that recorded 500 samples, saved as an image."""
    rng = np.random.default_rng(1)
    logger = Logger(device_id=7)
    logger.record(Motion(acc_g=0.1 * rng.standard_normal((N_SAMPLES, 3)) + [0, 0, 1], sampling_rate_hz=50.0),
                  start_time_s=START_S)
    path = tmp_path / "dev.glimg"
    logger.save_image(path)
    return path


def _header(path):
    return parse_image(path.read_bytes(), source=str(path)).header


def _device(capsys, *argv):
    code = main(["device", *argv])
    out, err = capsys.readouterr()
    return code, out, err


class _Terminal(io.StringIO):
    """A stdin that is a terminal and answers ``text``."""

    def isatty(self) -> bool:
        return True


def test_identify_text_and_json(image, capsys):
    code, out, err = _device(capsys, "identify", "--port", f"emu://{image}")
    assert code == 0 and err == ""
    assert "logger 7 on emu://" in out and "10-bit ADC at 50 Hz" in out
    code, out, _ = _device(capsys, "identify", "--port", f"emu://{image}", "--json")
    ident = json.loads(out)
    assert code == 0
    assert ident["device_id"] == 7 and ident["sampling_rate_hz"] == 50.0 and ident["adc_bits"] == 10
    assert ident["capacity_samples"] == 65536 and ident["firmware_version"] == "1.3"


def test_status_json_counts_what_was_recorded(image, capsys):
    code, out, _ = _device(capsys, "status", "--port", f"emu://{image}", "--json")
    status = json.loads(out)
    assert code == 0
    assert status["state"] == "idle" and not status["logging"]
    assert status["samples_stored"] == N_SAMPLES and status["samples_written"] == N_SAMPLES
    assert status["calibration_set"] is False and status["device_id"] == 7
    code, out, _ = _device(capsys, "status", "--port", f"emu://{image}")
    assert f"{N_SAMPLES} samples stored of 65536" in out and "calibration slot: empty" in out


def test_start_writes_the_run_start_and_quiet_prints_nothing(image, capsys):
    code, out, _ = _device(capsys, "start", "--port", f"emu://{image}?persist=1", "--start-time", "1800000000",
                           "--overwrite")
    assert code == 0 and "logger 7 is logging since 2027-01-15T08:00:00+00:00" in out
    assert "overwrites the oldest samples" in out
    header = _header(image)
    assert header.start_time_s == 1_800_000_000 and header.run_start_sample == N_SAMPLES and header.overwrite
    code, out, _ = _device(capsys, "stop", "--port", f"emu://{image}", "-q")
    assert code == 0 and out == ""


def test_erase_with_yes_empties_the_memory(image, capsys):
    code, out, _ = _device(capsys, "erase", "--port", f"emu://{image}?persist=1", "--yes")
    assert code == 0 and f"erased {N_SAMPLES} stored samples" in out
    header = _header(image)
    assert header.samples_written == 0 and header.n_stored == 0 and header.device_id == 7


def test_erase_asks_and_erases_on_yes(image, capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", _Terminal("y\n"))
    code, out, _ = _device(capsys, "erase", "--port", f"emu://{image}?persist=1")
    assert code == 0 and "[y/N]" in out and _header(image).samples_written == 0


@pytest.mark.parametrize("answer", ["n\n", "\n", "maybe\n"])
def test_erase_not_confirmed_changes_nothing(image, capsys, monkeypatch, answer):
    before = image.read_bytes()
    monkeypatch.setattr("sys.stdin", _Terminal(answer))
    code, _, err = _device(capsys, "erase", "--port", f"emu://{image}?persist=1")
    assert code == 1 and err.strip() == "gaitlog device erase: error: erase not confirmed: nothing erased"
    assert image.read_bytes() == before


def test_erase_refused_without_terminal_and_without_yes(image, capsys, monkeypatch):
    before = image.read_bytes()
    monkeypatch.setattr("sys.stdin", io.StringIO("y\n"))  # piped input is not a confirmation
    code, out, err = _device(capsys, "erase", "--port", f"emu://{image}?persist=1")
    assert code == 2 and out == ""                       # a missing --yes is a usage error
    assert "erase needs a confirmation" in err and "--yes" in err and len(err.strip().splitlines()) == 1
    assert image.read_bytes() == before


def _counts_calibration(tmp_path, offset=(512.0, 500.25, 530.5), unit="counts"):
    cal = AccCalibration.from_parameters(offset=list(offset), scale_per_g=[256.0, 250.0, 260.0], input_unit=unit)
    path = tmp_path / "cal.json"
    cal.save(path)
    return path, cal


def test_set_calibration_stores_the_fixed_point_slot(image, tmp_path, capsys):
    path, cal = _counts_calibration(tmp_path)
    code, out, _ = _device(capsys, "set-calibration", str(path), "--port", f"emu://{image}?persist=1")
    assert code == 0 and "stored in logger 7" in out and "512.000, 500.250, 530.500 counts" in out
    stored = _header(image).calibration
    assert stored.valid
    np.testing.assert_allclose(stored.offset_counts, [512.0, 500.25, 530.5], atol=2.0**-16)
    np.testing.assert_allclose(stored.matrix_g_per_count, cal.matrix, atol=2.0**-30)
    code, out, _ = _device(capsys, "set-calibration", "--nominal", "--port", f"emu://{image}?persist=1")
    assert code == 0 and "cleared" in out and not _header(image).calibration.valid


@pytest.mark.parametrize("content, message", [
    ("{not json", "not valid JSON"),
    (None, "cannot read accelerometer calibration"),
    ("g", "only a calibration of ADC counts"),
    ("far", "does not fit the logger's calibration slot"),
])
def test_set_calibration_bad_input_changes_nothing(image, tmp_path, capsys, content, message):
    before = image.read_bytes()
    if content == "g":
        path, _ = _counts_calibration(tmp_path, offset=(0.0, 0.0, 0.0), unit="g")
    elif content == "far":
        path, _ = _counts_calibration(tmp_path, offset=(40_000.0, 0.0, 0.0))  # outside Q15.16's ±32768
    else:
        path = tmp_path / "cal.json"
        if content is not None:
            path.write_text(content)
    code, out, err = _device(capsys, "set-calibration", str(path), "--port", f"emu://{image}?persist=1")
    assert code == 1 and out == "" and message in err and len(err.strip().splitlines()) == 1
    assert image.read_bytes() == before


@pytest.mark.parametrize("port, message", [
    ("/nonexistent/ttyX", "cannot open port '/nonexistent/ttyX'"),
    ("emu://?colour=red", "unknown option 'colour'"),
    ("emu://?persist=1", "persist=1 needs an image"),
])
def test_no_device_or_wrong_port(capsys, port, message):
    for action in ("identify", "status", "start", "stop"):
        code, out, err = _device(capsys, action, "--port", port)
        assert code == 1 and out == "" and message in err and len(err.strip().splitlines()) == 1


def test_missing_port_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["device", "status"])
    assert exc.value.code == 2 and "--port" in capsys.readouterr().err


def test_a_served_device_through_a_session(tmp_path, capsys):
    """start -> status -> refusals while logging -> stop -> status, on one device kept between commands."""
    logger = Logger(device_id=9)
    path, _ = _counts_calibration(tmp_path)
    with serve_tcp(logger) as server:
        port = server.url
        assert _device(capsys, "start", "--port", port)[0] == 0
        status = json.loads(_device(capsys, "status", "--port", port, "--json")[1])
        assert status["logging"] and status["state"] == "logging" and logger.firmware.ring.logging
        code, _, err = _device(capsys, "start", "--port", port)
        assert code == 1 and "already logging" in err and "nothing changed" in err
        code, _, err = _device(capsys, "erase", "--port", port, "--yes")
        assert code == 1 and "is logging: stop it first" in err
        code, _, err = _device(capsys, "set-calibration", str(path), "--port", port)
        assert code == 1 and "BUSY" in err and not logger.header.calibration.valid
        code, out, _ = _device(capsys, "stop", "--port", port)
        assert code == 0 and "stopped logging" in out and not logger.firmware.ring.logging
        status = json.loads(_device(capsys, "status", "--port", port, "--json")[1])
        assert status["state"] == "idle" and status["samples_written"] == logger.header.samples_written
        assert _device(capsys, "set-calibration", str(path), "--port", port)[0] == 0
        assert logger.header.calibration.valid
