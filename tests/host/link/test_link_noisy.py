"""The dump over a bad line (issue 13, items 3 and 6): end-to-end CRC-32 check, streams ended by the host,
noise in both directions with drops and inserts, signals, timeouts.

Truth is the device's own record of what it stored (``RecordResult``) or its memory, never the host's output.
The long version (100 full dumps at 1e-3) is ``benchmarks/soak_link_dump.py``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.host.link.memory_dump import best_chunk, dump_memory
from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.frames import FrameType, build_payload, encode_frame, parse_payload, parse_stream

sys.path.insert(0, str(Path(__file__).parent))
from test_link_emu import record_image  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
N_SAMPLES = 3000


@pytest.fixture(scope="module")
def image(tmp_path_factory):
    path = tmp_path_factory.mktemp("noisy") / "small.glimg"
    _, result = record_image(path, N_SAMPLES, seed=3)
    return path, np.asarray(result.codes)


def _exact(path: Path, codes: np.ndarray) -> bool:
    rec = decode_file(path)
    return bool(np.asarray(rec.valid).all()) and np.array_equal(rec.codes, codes)


def _both_ways(p: float, seed: int) -> str:
    return "&".join([f"{k}={p}" for k in ("corrupt", "drop", "insert")]
                    + [f"h2d_{k}={p}" for k in ("corrupt", "drop", "insert")] + [f"seed={seed}"])


def test_dump_is_bit_exact_at_1e_2_byte_errors_both_ways_with_drops_and_inserts(image, tmp_path):
    """1e-2 errors per byte in each direction (a third each corrupted, dropped, preceded by an inserted byte):
    the start-up commands and the dump all get through; every sample exact, none missing."""
    path, codes = image
    out = tmp_path / "noisy.glimg"
    with LoggerLink(f"emu://{path}?{_both_ways(0.01 / 3, 5)}", timeout_s=0.5) as link:
        dump = dump_memory(link, out, progress=False)
        assert link.serial.faults.n_corrupted > 20 and link.serial.h2d_faults.delivered > 500
    meta = dump.metadata_
    assert dump.complete_ and _exact(out, codes)
    assert meta["frames_damaged"] > 50 and meta["last_chunk_bytes"] <= 256  # the chunk followed the line


class ForgingLine:
    """A line fault no CRC-16 can see: change a data byte of the first ``n`` DATA frames and write a CRC-16 that
    fits the damage (the 1-in-65,536 case, made certain)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.forged = 0

    def apply(self, data: bytes) -> bytes:
        if self.forged < self.n and data[:3] in (b"\xa5\x5a\x87", b"\xa5\x5a\x8a") and len(data) > 20:
            body = bytearray(data[2:-2])
            body[4 + 4 + 7] ^= 0x40  # a byte of the data, after type, seq, length and the address
            self.forged += 1
            return b"\xa5\x5a" + bytes(body) + crc16_xmodem(bytes(body)).to_bytes(2, "big")
        return data


def test_data_frames_passing_their_crc16_are_caught_by_the_device_crc32_or_block_check(image, tmp_path):
    """DATA_BLOCKS (protocol version 2): the forged frame passes its CRC-16, its block's CRC-16/UMTS fails."""
    path, codes = image
    out = tmp_path / "forged.glimg"
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        link.serial._faults = forging = ForgingLine(3)
        dump = dump_memory(link, out, progress=False)
    assert forging.forged == 3 and dump.metadata_["crc32_mismatches"] == 3
    assert dump.complete_ and _exact(out, codes)


def test_firmware_dump_checked_sends_the_crc32_of_its_memory_and_a_command_ends_the_stream():
    logger = Logger()
    memory = logger.memory
    fw = logger.firmware
    cmd = encode_frame(FrameType.DUMP_CHECKED, 9, build_payload(FrameType.DUMP_CHECKED, address=1000, length=10000,
                                                                 chunk=4096))
    frames, errors = parse_stream(fw.receive(cmd, 0.0))  # unpaced: the whole stream at once
    assert errors == [] and [f.type for f in frames] == [0x87, 0x89] * 3 + [0x88]
    for data, check in zip(frames[0:6:2], frames[1:6:2]):
        d, c = parse_payload(data), parse_payload(check)
        assert d["address"] == c["address"] and d["data"] == memory[d["address"]:d["address"] + len(d["data"])]
        assert c["crc32"] == zlib.crc32(memory[c["address"]:c["address"] + len(d["data"])])  # independent CRC
    assert frames[-1].seq == 9 and fw.stats["crc32_bytes"] == 10000
    # paced, as on the line: frame by frame; an intact command in between ends the stream (no DUMP_END)
    fw.paced = True
    assert fw.receive(cmd, 1.0) == b"" and fw.streaming
    first = fw.transmit()
    assert parse_stream(first)[0][0].type == FrameType.DATA
    ack, _ = parse_stream(fw.receive(encode_frame(FrameType.ABORT, 10), 1.1))
    assert [(f.type, f.seq, f.payload) for f in ack] == [(0x90, 10, b"\x0c")]
    assert not fw.streaming and fw.transmit() == b"" and fw.stats["streams_aborted"] == 1
    assert parse_stream(fw.receive(encode_frame(FrameType.ABORT, 11), 1.2))[0][0].type == 0x90  # idle: ACK too


def test_the_next_command_after_an_abandoned_stream_is_answered_at_once(image):
    """The host walks away from a DUMP_CHECKED stream: the next command ends it (IDENTIFY is answered, not
    queued behind 10 kB of stale frames)."""
    path, _ = image
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        link.send(FrameType.DUMP_CHECKED, build_payload(FrameType.DUMP_CHECKED, address=0, length=12000, chunk=64))
        assert link.next_frame(0.5) is not None
        t0 = time.monotonic()
        assert link.identify()["capacity_samples"] == 65536
        assert time.monotonic() - t0 < 0.3
        fw = link.serial.device.firmware
        assert not fw.streaming and fw.stats["streams_aborted"] == 1
        link.abort()


def test_best_chunk_maximises_data_per_wire_byte():
    o = 28
    for p in (1e-4, 1e-3, 1e-2):
        c = np.arange(4, 4097, 4)
        eff = c / (c + o) * (1 - p) ** (c + o)
        assert abs(best_chunk(p) - c[np.argmax(eff)]) <= 4


def test_no_device_and_noise_get_different_messages(image):
    path, _ = image
    with LoggerLink(f"emu://{path}?cut_after=0", timeout_s=0.05) as link, \
            pytest.raises(HostError, match="not one byte received in 6 attempt"):
        link.identify()
    with LoggerLink(f"emu://{path}?corrupt=0.5&seed=1", timeout_s=0.05, deadline_s=0.5) as link, \
            pytest.raises(HostError, match="bytes arrived .* too noisy"):
        link.identify()


@pytest.mark.parametrize("value", ["nan", "inf", "0", "-1"])
def test_bad_timeout_is_one_line_error(image, tmp_path, value):
    for argv in (["dump", "--port", f"emu://{image[0]}", "--out", str(tmp_path / "x.glimg")],
                 ["device", "identify", "--port", f"emu://{image[0]}"]):
        done = subprocess.run([sys.executable, "-m", "gaitlog", *argv, f"--timeout={value}"], capture_output=True,
                              text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(ROOT)), cwd=tmp_path)
        assert done.returncode == 2 and done.stdout == ""
        assert done.stderr.count("\n") == 1 and "argument --timeout: must be a finite number" in done.stderr
    assert not (tmp_path / "x.glimg").exists()


@pytest.mark.parametrize("how", ["SIGTERM", "SIGINT in the background"])
def test_signal_saves_the_partial_state(image, tmp_path, how):
    """SIGTERM, and SIGINT when a shell started the dump in the background (SIGINT ignored on start), stop the
    dump with the partial state saved for --resume, like Ctrl-C in the foreground."""
    path, _ = image
    out = tmp_path / "sig.glimg"
    port = f"emu://{path}?{_both_ways(0.01 / 3, 2)}"  # slow enough (seconds) to be caught in the middle
    ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if how.startswith("SIGINT") else None
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog", "dump", "--port", port, "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ignore,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    state = tmp_path / "sig.glimg.part"
    deadline = time.monotonic() + 60
    while not state.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)  # the state is first written about a second after the first bytes arrived
    proc.send_signal(signal.SIGTERM if how == "SIGTERM" else signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert state.exists() and not out.exists() and "--resume" in err and "Traceback" not in err
