"""End to end: recorded -> image -> served on a pty -> `gaitlog dump` -> `gaitlog decode`, bit-identical to
what the device stored (its RecordResult); the same full memory received by lrzsz `rx`; CLI bad input.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.pty_server import serve_pty
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.cli import main
from gaitlog.host.files.recording import Recording

CAP = 65536
ROOT = Path(__file__).resolve().parents[1]


def motion(n: int, seed: int = 0) -> Motion:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    ph = rng.uniform(0, 2 * np.pi, 3)
    acc = np.c_[np.sin(0.05 * t + ph[0]), 0.6 * np.sin(0.031 * t + ph[1]), np.cos(0.05 * t + ph[0])]
    acc += 0.3 * np.sin(2 * np.pi * 1.3 * t[:, None] + ph)
    return Motion(acc_g=acc, sampling_rate_hz=50.0, marker_times_s=np.array([1.0, 7.5]))


def recorded(tmp: Path, n: int, *, overwrite: bool = False, seed: int = 0):
    logger = Logger(overwrite=overwrite)
    result = logger.record(motion(n, seed), start_time_s=1_700_000_000)
    path = tmp / "recorded.glimg"
    logger.save_image(path)
    codes = np.asarray(result.codes)[-CAP:]
    flags = np.asarray(result.flags)[-CAP:]
    return path, codes, flags, np.asarray(result.sample_numbers)[-CAP:]


@pytest.mark.parametrize("n, overwrite", [(4000, False), (CAP + 2500, True)], ids=["plain", "wrapped"])
def test_round_trip_over_pty_is_bit_identical(tmp_path, capsys, n, overwrite):
    image, codes, flags, numbers = recorded(tmp_path, n, overwrite=overwrite)
    with serve_pty(Logger.from_image(image)) as server:
        server_path = server.path
        assert main(["dump", "--port", server_path, "--out", str(tmp_path / "d.glimg"), "--quiet"]) == 0
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "dec")]) == 0
    rec = Recording.load(tmp_path / "dec.npz")
    assert rec.valid.all() and rec.gaps == []
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)
    np.testing.assert_array_equal(rec.sample_numbers, numbers)
    cols = Recording.read_csv(tmp_path / "dec.csv")
    np.testing.assert_array_equal(cols["x_counts"], codes[:, 0])
    np.testing.assert_array_equal(cols["z_counts"], codes[:, 2])
    np.testing.assert_array_equal(cols["valid"], 1)
    assert "0 gap(s)" in capsys.readouterr().out


def xdump_with_rx(port: str, target: Path, rx) -> Path:
    """Arm XDUMP with a command frame, then let lrzsz `rx` receive the raw dump on the same pty."""
    import serial

    from gaitlog.protocol.frames import FrameParser, encode_frame

    with serial.Serial(port, 115200, timeout=2.0) as ser:
        ser.write(encode_frame(0x09, 77))
        parser, frames = FrameParser(), []
        while not frames:
            data = ser.read(1)
            assert data, "no ACK to XDUMP"
            frames = [f for f in parser.feed(data) if hasattr(f, "payload")]
        assert frames[0].type == 0x90 and frames[0].seq == 77
    fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
    try:
        rx.run(target, fd)
    finally:
        os.close(fd)
    return target


def test_full_memory_dump_and_rx_give_the_same_samples(tmp_path, lrzsz_rx):
    image, codes, flags, numbers = recorded(tmp_path, CAP, seed=5)
    assert len(codes) == CAP and numbers[-1] == CAP - 1
    with serve_pty(Logger.from_image(image)) as server:
        assert main(["dump", "--port", server.path, "--out", str(tmp_path / "d.glimg"), "--quiet"]) == 0
        rx_file = xdump_with_rx(server.path, tmp_path / "rx.bin", lrzsz_rx)
    raw = rx_file.read_bytes()
    assert len(raw) % 1024 == 0 and raw[256 + 4 * CAP: 256 + 4 * CAP + 4] == b"GLCK"  # body, check trailer
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["decode", str(rx_file), "--out", str(tmp_path / "b"), "--quiet"]) == 0
    a = Recording.load(tmp_path / "a.npz")
    b = Recording.load(tmp_path / "b.npz")
    for rec in (a, b):
        assert rec.n_samples == CAP and rec.valid.all()
        np.testing.assert_array_equal(rec.codes, codes)
        np.testing.assert_array_equal(rec.flags, flags)
    np.testing.assert_array_equal(a.sample_numbers, b.sample_numbers)


# ------------------------------------------------------------------------------------------------ CLI errors
def _no_outputs(directory: Path, keep: set[str]) -> bool:
    return {p.name for p in directory.iterdir()} == keep


def test_decode_bad_inputs_exit_1_without_output(tmp_path, capsys):
    image, *_ = recorded(tmp_path, 500)
    good = image.read_bytes()
    # both copies of the preamble (start and end) damaged: nothing left to place the blocks
    cases = {"magic.glimg": b"XXXX" + good[4:-276] + b"XXXX" + good[-272:], "trunc.glimg": good[:200],
             "empty.glimg": b""}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    keep = {p.name for p in tmp_path.iterdir()}
    for name in cases:
        assert main(["decode", str(tmp_path / name), "--out", str(tmp_path / "out")]) == 1
        err = capsys.readouterr().err
        assert name in err and "offset" in err, err
        assert _no_outputs(tmp_path, keep)
    assert main(["decode", str(tmp_path / "nope.glimg"), "--out", str(tmp_path / "out")]) == 1
    assert "nope.glimg" in capsys.readouterr().err
    assert _no_outputs(tmp_path, keep)


def test_dump_missing_port_exit_1_without_output(tmp_path, capsys):
    assert main(["dump", "--port", "/dev/ttyDOESNOTEXIST9", "--out", str(tmp_path / "x.glimg")]) == 1
    assert "/dev/ttyDOESNOTEXIST9" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_info_image_and_port(tmp_path, capsys):
    image, *_ = recorded(tmp_path, 700)
    assert main(["info", str(image)]) == 0
    out = capsys.readouterr().out
    assert "samples written  700" in out and "700 of 700 stored samples valid" in out
    assert main(["info", "--port", f"emu://{image}"]) == 0
    out = capsys.readouterr().out
    assert "state            idle, 700 samples written" in out


def test_serve_command_prints_a_pty_and_stops_on_ctrl_c(tmp_path):
    image, codes, *_ = recorded(tmp_path, 600)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog", "serve", str(image), "--pty"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        port = proc.stdout.readline().strip()
        assert port.startswith("/dev/")
        assert main(["dump", "--port", port, "--out", str(tmp_path / "d.glimg"), "--quiet"]) == 0
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "d"), "--quiet"]) == 0
    np.testing.assert_array_equal(Recording.load(tmp_path / "d.npz").codes, codes)


def test_record_command_and_demo(tmp_path, capsys):
    assert main(["record", "--motion", "poses", "--poses", "4", "--start-time", "0", "--out",
                 str(tmp_path / "p.glimg"), "--quiet"]) == 0
    assert (tmp_path / "p.glimg").exists()
    assert main(["record", "--motion", "replay", "--out", str(tmp_path / "q.glimg")]) == 2
    assert not (tmp_path / "q.glimg").exists()
    capsys.readouterr()
    assert main(["demo", "--out", str(tmp_path / "demo"), "--poses", "4"]) == 0  # tmp_path is not empty
    out = capsys.readouterr().out
    assert "bit-identical to what the device recorded: True" in out
    assert "[summary]" in out and "0 gap(s)" in out
    assert "[calibrate] skipped: 4 poses" in out
    for name in ("recorded.glimg", "dumped.glimg", "dumped.glimg.json", "decoded.csv", "decoded.npz"):
        assert (tmp_path / "demo" / name).exists(), name


def test_demo_calibrates_the_dumped_poses(tmp_path, capsys):
    """The default demo fits the 9-parameter model on what it dumped: every pose reads 1 g within 2 mg."""
    assert main(["demo", "--out", str(tmp_path / "new")]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "new" / "calibration.json").exists()
    worst = out.split("worst | |a| - 1 g | over the poses: ")[1]
    nominal_mg = float(worst.split(" mg with the nominal map")[0])
    calibrated_mg = float(worst.split(", ")[1].split(" mg calibrated")[0])
    assert calibrated_mg < 2.0 < nominal_mg


def test_round_trip_over_tcp(tmp_path):
    from gaitlog.firmware_sim.transport import serve_tcp

    image, codes, flags, numbers = recorded(tmp_path, 3000, seed=8)
    with serve_tcp(Logger.from_image(image), save_on_stop=False) as server:
        assert server.url.startswith("socket://127.0.0.1:")
        assert main(["dump", "--port", server.url, "--out", str(tmp_path / "t.glimg"), "--quiet"]) == 0
    assert main(["decode", str(tmp_path / "t.glimg"), "--out", str(tmp_path / "t"), "--quiet"]) == 0
    rec = Recording.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.sample_numbers, numbers)
