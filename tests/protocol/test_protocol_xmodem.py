"""XMODEM-1K/CRC sender (PROTOCOL.md section 5) against independent receivers: PyPI ``xmodem`` and lrzsz ``rx``."""

from __future__ import annotations

import binascii
import io
import logging
import os
import random
import select
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from xmodem import XMODEM

from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.raw_dump import TRAILER_GAP_BYTES, build_trailer, raw_dump_bytes
from gaitlog.protocol.xmodem import (
    ACK,
    CAN,
    CRC_REQUEST,
    EOT,
    NAK,
    PAD,
    XmodemSender,
    build_block,
    parse_block,
)

logging.getLogger("xmodem").setLevel(logging.CRITICAL)


def _pypi_receive(payload: bytes, corrupt_rate: float = 0.0, seed: int = 0) -> tuple[bytes | None, XmodemSender]:
    """Run the PyPI receiver against our sender over an in-memory line (synchronous: no threads, no sleeps).

    The sender -> receiver direction corrupts bytes at ``corrupt_rate`` (flips, drops, inserts)."""
    rng = random.Random(seed)
    sender = XmodemSender(payload, max_retries=50)
    line = bytearray()

    def putc(data: bytes, timeout: float = 1) -> int:
        out = bytearray(sender.receive(data))
        if corrupt_rate:
            i = 0
            while i < len(out):
                if rng.random() < corrupt_rate:
                    kind = rng.randrange(3)
                    if kind == 0:
                        out[i] ^= 1 << rng.randrange(8)
                    elif kind == 1:
                        del out[i]
                        continue
                    else:
                        out.insert(i, rng.randrange(256))
                        i += 1
                i += 1
        line.extend(out)
        return len(data)

    def getc(size: int, timeout: float = 1) -> bytes | None:
        if not line:
            return None  # a timeout
        chunk = bytes(line[:size])
        del line[:size]
        return chunk

    stream = io.BytesIO()
    modem = XMODEM(getc, putc, mode="xmodem1k")
    n = modem.recv(stream, crc_mode=1, retry=60, timeout=0, delay=0, quiet=1)
    return (stream.getvalue() if n is not None else None), sender


@given(st.binary(max_size=5000))
@settings(max_examples=30, deadline=None)
def test_pypi_receiver_gets_exact_payload(body: bytes) -> None:
    payload = raw_dump_bytes(bytes(range(256)), body)
    trailer = build_trailer(bytes(range(256)) + body)
    tail = trailer + bytes([PAD]) * TRAILER_GAP_BYTES + trailer
    assert len(payload) % 1024 == 0 and payload[256 + len(body) :].rstrip(bytes([PAD])) == tail.rstrip(bytes([PAD]))
    got, sender = _pypi_receive(payload)
    assert got == payload
    assert sender.done and sender.failed is None and sender.retransmissions == 0


def test_raw_dump_layout_with_step_memory() -> None:
    header, samples, steps = bytes(range(256)), bytes(4 * 100), bytes(range(200)) * 3  # 30 records
    payload = raw_dump_bytes(header, samples, steps)
    body = header + samples + steps
    tail = build_trailer(body) + bytes([PAD]) * TRAILER_GAP_BYTES + build_trailer(body)
    assert len(payload) == 2048 and payload[: len(body)] == body  # body, trailer twice, padding
    assert payload[len(body) :] == tail + bytes([PAD]) * (2048 - len(body) - len(tail))
    assert raw_dump_bytes(header, samples) == raw_dump_bytes(header, samples, b"")
    with pytest.raises(ProtocolError, match="not whole 20-byte records"):
        raw_dump_bytes(header, samples, bytes(30))


def test_pypi_receiver_through_a_noisy_line() -> None:
    payload = raw_dump_bytes(bytes(256), random.Random(1).randbytes(60_000))
    got, sender = _pypi_receive(payload, corrupt_rate=2e-4, seed=3)
    assert got == payload
    assert sender.done and sender.retransmissions > 0


def test_block_layout_matches_reference() -> None:
    data = bytes(range(200))
    blk = build_block(0x1FF, data)
    body = data + b"\x1a" * 824
    assert blk == b"\x02\xff\x00" + body + binascii.crc_hqx(body, 0).to_bytes(2, "big")
    assert parse_block(blk) == (0xFF, body)


@settings(deadline=None)
@given(st.integers(0, 1000), st.binary(max_size=1024))
def test_block_round_trip(n: int, data: bytes) -> None:
    blk, back = parse_block(build_block(n, data))
    assert blk == n % 256 and back == data + bytes([PAD]) * (1024 - len(data))


@settings(deadline=None)
@given(st.binary(min_size=1, max_size=1024), st.integers(0, 1028), st.integers(0, 7))
def test_block_bit_flip_is_detected(data: bytes, pos: int, bit: int) -> None:
    b = bytearray(build_block(1, data))
    b[pos] ^= 1 << bit
    with pytest.raises(ProtocolError):
        parse_block(bytes(b))


def test_parse_block_rejects() -> None:
    with pytest.raises(ProtocolError, match="starts with 0x03"):
        parse_block(b"\x03" + bytes(1028))
    with pytest.raises(ProtocolError, match="1028 bytes"):
        parse_block(build_block(1, b"")[:-1])
    b = bytearray(build_block(1, b""))
    b[2] = 0
    with pytest.raises(ProtocolError, match="complement"):
        parse_block(bytes(b))


def test_sender_state_machine_edges() -> None:
    s = XmodemSender(bytes(2000))
    assert s.receive(b"xyz") == b"" and s.state == "wait_start"
    first = s.receive(CRC_REQUEST)
    assert first[:3] == b"\x02\x01\xfe"
    assert s.receive(CRC_REQUEST) == first  # receiver missed block 1 and asks again
    assert s.receive(NAK) == first
    second = s.receive(ACK)
    assert second[:3] == b"\x02\x02\xfd"
    assert s.receive(CRC_REQUEST) == b""  # 'C' is only meaningful before block 1 is acknowledged
    assert s.receive(ACK) == EOT
    assert s.receive(NAK) == EOT  # some receivers NAK the first EOT
    assert s.receive(ACK) == b"" and s.done and s.blocks_acked == 2

    s = XmodemSender(b"x")
    assert s.receive(NAK) == CAN + CAN and "checksum mode" in s.failed

    s = XmodemSender(b"x", max_retries=2)
    s.receive(CRC_REQUEST)
    s.receive(NAK)
    s.receive(NAK)
    assert s.receive(NAK) == CAN + CAN and "after 2 retransmissions" in s.failed

    s = XmodemSender(b"x")
    s.receive(CRC_REQUEST)
    assert s.receive(CAN + CAN) == b"" and "cancelled" in s.failed and s.finished

    s = XmodemSender(b"")
    assert s.receive(CRC_REQUEST) == EOT


def test_sender_timeouts() -> None:
    s = XmodemSender(b"x", start_timeout_s=60, ack_timeout_s=10)
    assert s.poll(100.0) == b"" and s.poll(159.0) == b""
    assert s.poll(160.5) == CAN + CAN and "within 60 s" in s.failed
    s = XmodemSender(b"x", ack_timeout_s=10)
    block = s.receive(CRC_REQUEST)
    s.poll(0.0)
    assert s.poll(5.0) == b"" and s.poll(10.5) == block and s.retransmissions == 1


def test_lrzsz_rx_receives_exact_payload(tmp_path: Path, lrzsz_rx) -> None:
    payload = raw_dump_bytes(bytes(range(256)), random.Random(5).randbytes(20_000))
    out = tmp_path / "dump.bin"
    proc = lrzsz_rx.popen(out)
    sender = XmodemSender(payload)
    deadline = time.monotonic() + 20
    assert proc.stdout is not None and proc.stdin is not None
    fd = proc.stdout.fileno()
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.2)
            if ready:
                data = os.read(fd, 4096)
                if not data:
                    break
                reply = sender.receive(data)
                if reply:
                    proc.stdin.write(reply)
                    proc.stdin.flush()
        proc.wait(timeout=5)
    finally:
        if proc.poll() is None:
            proc.kill()
    stderr = proc.stderr.read() if proc.stderr is not None else b""
    lrzsz_rx.check(proc.returncode, stderr)
    assert sender.done, sender.failed
    assert out.read_bytes() == payload
