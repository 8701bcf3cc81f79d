"""Serving the device on a pty and on TCP: commands, wire-time pacing, fault injection, lrzsz rx."""

from __future__ import annotations

import binascii
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.pty_server import serve_pty
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.transport import FaultInjector, serve_tcp
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.protocol.raw_dump import parse_raw_dump


def frame(ftype: int, seq: int, payload: bytes = b"") -> bytes:
    body = struct.pack("<BBH", ftype, seq, len(payload)) + payload
    return b"\xa5\x5a" + body + struct.pack(">H", binascii.crc_hqx(body, 0))


def read_exact(port: serial.Serial, n: int, timeout_s: float = 10.0) -> bytes:
    out = bytearray()
    deadline = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < deadline:
        out += port.read(n - len(out))
    return bytes(out)


def dump_size(length: int, chunk: int) -> int:
    k = -(-length // chunk)
    return k * (8 + 4) + length + 8 + 10


@pytest.fixture(scope="module")
def full_logger() -> Logger:
    lg = Logger(sensor=SensorModel.ideal(seed=1), overwrite=True)
    lg.record(CalibrationPoses(n_poses=24, hold_s=52.0, move_s=3.0), start_time_s=1_000)
    assert lg.header.wrapped
    return lg



def _trailer_checks(got: bytes, body_bytes: int) -> bool:
    """After the body: the check trailer (section 5.1), which verifies every body byte, then padding."""
    dump = parse_raw_dump(got)
    return dump.verified and bool(dump.byte_ok.all()) and dump.body.size == body_bytes and \
        got[body_bytes:body_bytes + 4] == b"GLCK"

def test_pty_answers_and_dumps_the_whole_memory(full_logger: Logger) -> None:
    with serve_pty(full_logger, save_on_stop=False) as srv:
        assert Path(srv.path).exists()
        with serial.Serial(srv.path, 115200, timeout=0.5) as port:
            port.write(frame(0x01, 3))
            info = read_exact(port, 8 + 21)
            assert info[2:4] == b"\x81\x03"
            port.write(frame(0x08, 4, struct.pack("<IIH", 0, 262144, 2048)))
            data = read_exact(port, dump_size(262144, 2048))
    assert len(data) == dump_size(262144, 2048)
    body = b"".join(data[i + 10:i + 10 + 2048] for i in range(0, 128 * 2060, 2060))
    assert body == full_logger.memory
    assert srv.error is None


def test_tcp_serves_and_survives_reconnects(full_logger: Logger) -> None:
    with serve_tcp(full_logger, save_on_stop=False) as srv:
        assert srv.url.startswith("socket://127.0.0.1:")
        for seq in (1, 2):
            with serial.serial_for_url(srv.url, timeout=0.5) as port:
                port.write(frame(0x02, seq))
                status = read_exact(port, 18)
                assert status[2:4] == bytes([0x82, seq])
                assert struct.unpack_from("<I", status, 8)[0] == full_logger.header.samples_written


def test_wire_time_is_never_faster_than_the_line(full_logger: Logger) -> None:
    n = 11_520 * 2  # ~2 s of bytes at 115200 8N1
    with serve_pty(full_logger, wire_time=True, save_on_stop=False) as srv:
        with serial.Serial(srv.path, 115200, timeout=0.5) as port:
            t0 = time.monotonic()
            port.write(frame(0x08, 1, struct.pack("<IIH", 0, n, 2048)))
            data = read_exact(port, dump_size(n, 2048), timeout_s=20)
            elapsed = time.monotonic() - t0
    assert len(data) == dump_size(n, 2048)
    # a correctness bound, not a speed target: bytes cannot arrive before their wire time
    assert elapsed >= (len(data) - 64) * 10 / 115200


def test_fault_injection_corrupts_reported_positions_and_cuts(full_logger: Logger) -> None:
    n = 65536
    clean = full_logger.firmware.receive(frame(0x08, 1, struct.pack("<IIH", 0, n, 2048)), 0.0)
    faults = FaultInjector(corrupt_rate=0.001, seed=5)
    with serve_pty(full_logger, faults=faults, save_on_stop=False) as srv:
        with serial.Serial(srv.path, 115200, timeout=0.5) as port:
            port.write(frame(0x08, 1, struct.pack("<IIH", 0, n, 2048)))
            got = read_exact(port, len(clean))
    diff = np.flatnonzero(np.frombuffer(got, np.uint8) != np.frombuffer(clean, np.uint8))
    assert diff.tolist() == faults.corrupted_offsets and 30 < diff.size < 110
    cut = FaultInjector(cut_after_bytes=10_000)
    with serve_pty(full_logger, faults=cut, save_on_stop=False) as srv:
        with serial.Serial(srv.path, 115200, timeout=0.3) as port:
            port.write(frame(0x08, 2, struct.pack("<IIH", 0, n, 2048)))
            first = read_exact(port, len(clean), timeout_s=1.0)
            assert first == clean[:10_000]
            port.write(frame(0x02, 3))  # the link is back for the next command
            assert read_exact(port, 18)[2:4] == b"\x82\x03"


def test_tcp_cut_closes_the_connection(full_logger: Logger) -> None:
    with serve_tcp(full_logger, faults=FaultInjector(cut_after_bytes=5000), save_on_stop=False) as srv:
        with socket.create_connection((srv.host, srv.port), timeout=2.0) as sock:
            sock.sendall(frame(0x08, 1, struct.pack("<IIH", 0, 65536, 2048)))
            got = bytearray()
            while chunk := sock.recv(65536):  # until the server closes the connection
                got += chunk
            assert len(got) == 5000
        with serial.serial_for_url(srv.url, timeout=0.5) as port:  # a new connection works
            port.write(frame(0x02, 2))
            assert read_exact(port, 18)[2:4] == b"\x82\x02"


def test_xdump_full_memory_received_by_lrzsz_rx(full_logger: Logger, tmp_path: Path, lrzsz_rx) -> None:
    out = tmp_path / "dump.bin"
    with serve_pty(full_logger, save_on_stop=False) as srv:
        with serial.Serial(srv.path, 115200, timeout=0.5) as port:
            port.write(frame(0x09, 7))
            assert read_exact(port, 9) == frame(0x90, 7, b"\x09")
        fd = os.open(srv.path, os.O_RDWR | os.O_NOCTTY)
        try:
            lrzsz_rx.run(out, fd, timeout_s=60)  # the pty is rx's stdin and stdout
        finally:
            os.close(fd)
    got = out.read_bytes()
    header = full_logger.header.to_bytes()
    assert got[:256] == header
    assert got[256:256 + 262144] == full_logger.memory
    assert _trailer_checks(got, 256 + 262144)


def test_served_device_logs_in_real_time_after_start(tmp_path: Path) -> None:
    lg = Logger(sensor=SensorModel.ideal(), image_path=tmp_path / "live.glimg")
    with serve_tcp(lg) as srv:
        with serial.serial_for_url(srv.url, timeout=0.5) as port:
            port.write(frame(0x03, 1, struct.pack("<IB", 1_700_000_000, 0)))
            assert read_exact(port, 9) == frame(0x90, 1, b"\x03")
            time.sleep(0.5)
            port.write(frame(0x04, 2))
            assert read_exact(port, 9) == frame(0x90, 2, b"\x04")
            port.write(frame(0x02, 3))
            status = read_exact(port, 18)
    written = struct.unpack_from("<I", status, 8)[0]
    assert 20 <= written <= 40  # ~0.5 s at 50 Hz
    # the stopped server saved the image; the device lay still with +z up: z reads +1 g (code 767)
    back = Logger.from_image(tmp_path / "live.glimg")
    assert back.header.samples_written == written and back.header.start_time_s == 1_700_000_000
    words = np.frombuffer(back.memory[:4 * written], dtype="<u4")
    assert words[0] >> 30 == 1 and np.all(np.abs(((words >> 20) & 1023).astype(int) - 767) <= 2)


def test_tcp_serving_needs_no_tty_module() -> None:
    """``tty`` is POSIX-only: importing the transport and serving on TCP must work without it (Windows)."""
    code = ("import sys; sys.modules['tty'] = None\n"
            "from gaitlog.firmware_sim.device import Logger\n"
            "from gaitlog.firmware_sim.transport import serve_tcp\n"
            "with serve_tcp(Logger(), port=0) as server: print(server.url)\n")
    done = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])})
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("socket://127.0.0.1:")
