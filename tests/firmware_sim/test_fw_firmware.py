"""The UART command handler against PROTOCOL.md section 3-5, decoded independently with struct/binascii."""

from __future__ import annotations

import binascii
import io
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.protocol.raw_dump import parse_raw_dump

# --- an independent, minimal implementation of the frame layout (section 3) --------------------------


def frame(ftype: int, seq: int, payload: bytes = b"") -> bytes:
    body = struct.pack("<BBH", ftype, seq, len(payload)) + payload
    return b"\xa5\x5a" + body + struct.pack(">H", binascii.crc_hqx(body, 0))


def frames_of(data: bytes) -> list[tuple[int, int, bytes]]:
    """Split a clean response stream into (type, seq, payload); assert every CRC."""
    out, i = [], 0
    while i < len(data):
        assert data[i:i + 2] == b"\xa5\x5a", f"no sync at {i}"
        t, s, n = struct.unpack_from("<BBH", data, i + 2)
        body = data[i + 2:i + 6 + n]
        (crc,) = struct.unpack_from(">H", data, i + 6 + n)
        assert crc == binascii.crc_hqx(body, 0)
        out.append((t, s, data[i + 6:i + 6 + n]))
        i += 8 + n
    return out


def one(data: bytes) -> tuple[int, int, bytes]:
    f = frames_of(data)
    assert len(f) == 1, f
    return f[0]


ACK, NAK = 0x90, 0x91
BAD_CRC, UNKNOWN, BAD_LENGTH, BAD_ADDRESS, BUSY, BAD_ARGUMENT, MEMORY_FULL = range(1, 8)


@pytest.fixture()
def logger() -> Logger:
    lg = Logger(sensor=SensorModel.ideal(seed=3), device_id=0x1234)
    lg.record(CalibrationPoses(n_poses=3, hold_s=3.0, move_s=1.0))  # 550 samples
    return lg


def send(lg: Logger, data: bytes, now_s: float = 0.0) -> bytes:
    return lg.firmware.receive(data, now_s)



def _trailer_checks(got: bytes, body_bytes: int) -> bool:
    """After the body: the check trailer (section 5.1), which verifies every body byte, then padding."""
    dump = parse_raw_dump(got)
    return dump.verified and bool(dump.byte_ok.all()) and dump.body.size == body_bytes and \
        got[body_bytes:body_bytes + 4] == b"GLCK"

def test_identify_and_status(logger: Logger) -> None:
    t, s, p = one(send(logger, frame(0x01, 9)))
    assert (t, s) == (0x81, 9)
    dev, fw, proto, bits, rate, cap, packing, mem = struct.unpack("<IHBBIIBI", p)
    assert (dev, fw, proto, bits, rate, cap, packing, mem) == (0x1234, 0x0103, 2, 10, 50_000, 65536, 1, 262144)  # wire protocol 2 (DUMP_BLOCKS)
    t, s, p = one(send(logger, frame(0x02, 10)))
    state, flags, written, windex = struct.unpack("<BBII", p)
    assert (t, s, state, written, windex, flags & 0x04) == (0x82, 10, 0, 550, 550, 0)


def test_start_stop_and_their_naks(logger: Logger) -> None:
    assert one(send(logger, frame(0x03, 1, struct.pack("<I", 5))))[2] == bytes([0x03, BAD_LENGTH])
    assert one(send(logger, frame(0x03, 2, struct.pack("<IB", 5, 2))))[2] == bytes([0x03, BAD_ARGUMENT])
    assert one(send(logger, frame(0x03, 3, struct.pack("<IB", 1_700_000_000, 0)))) == (ACK, 3, b"\x03")
    state = struct.unpack("<BBII", one(send(logger, frame(0x02, 4)))[2])[0]
    assert state == 1
    # BUSY while logging: READ (sample or step memory), DUMP, XDUMP, ERASE, SET_CALIBRATION, SET_STEP_CONFIG, START
    for cmd, payload in ((0x07, struct.pack("<IH", 0, 4)), (0x07, struct.pack("<IH", 0x01000000, 20)),
                         (0x08, struct.pack("<IIH", 0, 4, 4)), (0x09, b""), (0x05, b"ERASE"), (0x0A, bytes(64)),
                         (0x0B, bytes(32)), (0x03, struct.pack("<IB", 0, 0))):
        assert one(send(logger, frame(cmd, 5, payload))) == (NAK, 5, bytes([cmd, BUSY]))
    # IDENTIFY, STATUS and READ_HEADER still answer while logging
    assert one(send(logger, frame(0x06, 6)))[0] == 0x86
    assert one(send(logger, frame(0x04, 7))) == (ACK, 7, b"\x04")
    assert one(send(logger, frame(0x04, 8))) == (ACK, 8, b"\x04")  # STOP when idle: still ACK
    assert logger.header.start_time_s == 1_700_000_000 and logger.header.run_start_sample == 550


def test_memory_full_in_stop_mode() -> None:
    lg = Logger(sensor=SensorModel.ideal(), overwrite=False)
    lg.record(CalibrationPoses(n_poses=24, hold_s=52.0, move_s=3.0))  # more than 65,536 samples
    assert lg.header.full_stopped
    assert struct.unpack("<BBII", one(send(lg, frame(0x02, 1)))[2])[0] == 2  # full-stopped
    assert one(send(lg, frame(0x03, 2, struct.pack("<IB", 0, 0)))) == (NAK, 2, bytes([0x03, MEMORY_FULL]))
    assert one(send(lg, frame(0x03, 3, struct.pack("<IB", 0, 1)))) == (ACK, 3, b"\x03")  # ring mode is fine


def test_erase_guard(logger: Logger) -> None:
    assert one(send(logger, frame(0x05, 1, b"ERASX"))) == (NAK, 1, bytes([0x05, BAD_ARGUMENT]))
    assert one(send(logger, frame(0x05, 2, b"ERAS"))) == (NAK, 2, bytes([0x05, BAD_LENGTH]))
    assert logger.header.samples_written == 550
    assert one(send(logger, frame(0x05, 3, b"ERASE"))) == (ACK, 3, b"\x05")
    assert logger.header.samples_written == 0


def test_read_header_and_read(logger: Logger) -> None:
    t, s, p = one(send(logger, frame(0x06, 1)))
    assert t == 0x86 and len(p) == 256 and p[:4] == b"GLOG"
    # header version 3, the default (version 2's layout, the journal in the step EEPROM): CRC over bytes 0-159
    assert p[4] == 3 and struct.unpack(">H", p[254:256])[0] == binascii.crc_hqx(p[:160], 0)
    assert struct.unpack_from("<II", p, 28) == (550, 550)  # write_index, samples_written
    mem = logger.memory
    t, s, p = one(send(logger, frame(0x07, 2, struct.pack("<IH", 100, 4096))))
    assert t == 0x87 and struct.unpack_from("<I", p)[0] == 100 and p[4:] == mem[100:4196]
    last = 262144 - 8
    assert one(send(logger, frame(0x07, 3, struct.pack("<IH", last, 8))))[2][4:] == mem[last:]
    assert one(send(logger, frame(0x07, 4, struct.pack("<IH", last, 9)))) == (NAK, 4, bytes([0x07, BAD_ADDRESS]))
    assert one(send(logger, frame(0x07, 5, struct.pack("<IH", 0, 0)))) == (NAK, 5, bytes([0x07, BAD_ARGUMENT]))
    assert one(send(logger, frame(0x07, 6, struct.pack("<IH", 0, 4097)))) == (NAK, 6, bytes([0x07, BAD_ARGUMENT]))
    assert one(send(logger, frame(0x07, 7, struct.pack("<I", 0)))) == (NAK, 7, bytes([0x07, BAD_LENGTH]))


def test_dump_streams_data_frames_then_dump_end(logger: Logger) -> None:
    mem = logger.memory
    out = frames_of(send(logger, frame(0x08, 42, struct.pack("<IIH", 1000, 10_000, 4096))))
    assert [f[0] for f in out] == [0x87, 0x87, 0x87, 0x88]
    assert [f[1] for f in out[:3]] == [0, 1, 2] and out[3][1] == 42
    got = b""
    for k, (_, _, p) in enumerate(out[:3]):
        assert struct.unpack_from("<I", p)[0] == 1000 + 4096 * k
        got += p[4:]
    assert got == mem[1000:11000]
    assert struct.unpack("<IIH", out[3][2]) == (1000, 10_000, 3)
    # the whole memory in 2048-byte chunks: 128 DATA frames, seq wraps mod 256 only beyond
    out = frames_of(send(logger, frame(0x08, 1, struct.pack("<IIH", 0, 262144, 2048))))
    assert len(out) == 129 and b"".join(p[4:] for _, _, p in out[:-1]) == mem
    assert one(send(logger, frame(0x08, 2, struct.pack("<IIH", 0, 262145, 2048)))) == (NAK, 2, bytes([0x08, BAD_ADDRESS]))
    assert one(send(logger, frame(0x08, 3, struct.pack("<IIH", 0, 16, 0)))) == (NAK, 3, bytes([0x08, BAD_ARGUMENT]))


def test_dump_seq_wraps_mod_256(logger: Logger) -> None:
    out = frames_of(send(logger, frame(0x08, 7, struct.pack("<IIH", 0, 300 * 16, 16))))
    assert [f[1] for f in out[:-1]] == [k % 256 for k in range(300)]


def test_set_calibration(logger: Logger) -> None:
    slot = bytearray(64)
    slot[0] = 1
    struct.pack_into("<3i", slot, 4, *(int(512.25 * 65536),) * 3)
    struct.pack_into("<9i", slot, 16, *[int(2**30 / 256) if i % 4 == 0 else 0 for i in range(9)])
    assert one(send(logger, frame(0x0A, 1, bytes(slot)))) == (ACK, 1, b"\x0a")
    hdr = one(send(logger, frame(0x06, 2)))[2]
    assert hdr[64:128] == bytes(slot) and hdr[19] & 0x08
    bad = bytearray(slot)
    bad[0] = 7
    assert one(send(logger, frame(0x0A, 3, bytes(bad)))) == (NAK, 3, bytes([0x0A, BAD_ARGUMENT]))
    assert one(send(logger, frame(0x0A, 4, bytes(63)))) == (NAK, 4, bytes([0x0A, BAD_LENGTH]))


def test_unknown_command_bad_crc_and_framing(logger: Logger) -> None:
    assert one(send(logger, frame(0x55, 1))) == (NAK, 1, bytes([0x55, UNKNOWN]))
    assert one(send(logger, frame(0x81, 2))) == (NAK, 2, bytes([0x81, UNKNOWN]))  # a response type
    bad = bytearray(frame(0x02, 3))
    bad[-1] ^= 0x40
    assert one(send(logger, bytes(bad))) == (NAK, 3, bytes([0x02, BAD_CRC]))
    # a corrupted length field: header not intact, silence; the next frame is answered
    bad = bytearray(frame(0x02, 4))
    bad[4] = 3
    assert send(logger, bytes(bad)) == b""
    assert logger.firmware._rx  # waiting for 3 more bytes that never come
    assert one(send(logger, frame(0x02, 5), now_s=1.0))[1] == 5  # inter-byte timeout dropped the stale part
    # a length above 4100: framing error, nothing allocated, the hunt goes on
    huge = b"\xa5\x5a\x07\x01" + struct.pack("<H", 60000)
    assert one(send(logger, huge + b"junk" + frame(0x01, 6), now_s=2.0))[:2] == (0x81, 6)


def test_inter_byte_timeout_and_split_frames(logger: Logger) -> None:
    f = frame(0x02, 9)
    assert send(logger, f[:5], now_s=10.0) == b""
    assert one(send(logger, f[5:], now_s=10.09))[1] == 9  # 90 ms gap: still one frame
    assert send(logger, f[:5], now_s=20.0) == b""
    assert send(logger, f[5:], now_s=20.2) == b""  # 200 ms gap: the partial frame was dropped
    assert one(send(logger, f, now_s=20.3))[1] == 9


@settings(max_examples=60, deadline=None)
@given(cuts=st.lists(st.integers(min_value=0, max_value=40), max_size=6),
       junk=st.binary(max_size=20).filter(lambda b: b"\xa5" not in b and b"XDUMP" not in b))
def test_split_commands_give_the_same_answers(cuts: list[int], junk: bytes) -> None:
    """Decoder property: a command stream split anywhere (within the timeout) is answered the same."""
    lg = Logger(sensor=SensorModel.ideal())
    stream = junk + frame(0x01, 1) + frame(0x02, 2) + frame(0x07, 3, struct.pack("<IH", 8, 16)) + frame(0x06, 4)
    whole = Logger(sensor=SensorModel.ideal()).firmware.receive(stream, 0.0)
    pieces, last = [], 0
    for c in sorted(set(cuts)):
        pieces.append(stream[last:c])
        last = c
    pieces.append(stream[last:])
    got = b"".join(lg.firmware.receive(p, 0.01 * k) for k, p in enumerate(pieces))
    assert got == whole
    assert [f[1] for f in frames_of(got)] == [1, 2, 3, 4]


def _xmodem_receive(lg: Logger, arm: bytes) -> tuple[bytes, bytes]:
    """Receive XDUMP with the PyPI ``xmodem`` package, in-process over a sans-I/O loop."""
    from xmodem import XMODEM

    first = lg.firmware.receive(arm, 0.0)
    pending = bytearray()
    clock = [0.0]

    def putc(data: bytes, timeout: float = 1) -> int:
        clock[0] += 0.001
        pending.extend(lg.firmware.receive(bytes(data), clock[0]))
        return len(data)

    def getc(size: int, timeout: float = 1) -> bytes | None:
        if not pending:
            return None
        chunk = bytes(pending[:size])
        del pending[:size]
        return chunk

    out = io.BytesIO()
    modem = XMODEM(getc, putc, mode="xmodem1k")
    assert modem.recv(out, crc_mode=1, retry=4, timeout=0.1, quiet=True) is not None
    return first, out.getvalue()


@pytest.mark.parametrize("arm", ["frame", "ascii"])
def test_xdump_received_by_pypi_xmodem(logger: Logger, arm: str) -> None:
    first, got = _xmodem_receive(logger, frame(0x09, 5) if arm == "frame" else b"\r\nXDUMP\r")
    assert first == (frame(0x90, 5, b"\x09") if arm == "frame" else b"")
    header = one(send(logger, frame(0x06, 1)))[2]
    used = 4 * 550
    assert got[:256] == header and got[256:256 + used] == logger.memory[:used]
    assert len(got) % 1024 == 0 and _trailer_checks(got, 256 + used)
    assert not logger.firmware.in_transfer
    assert one(send(logger, frame(0x02, 2)))[0] == 0x82  # back in command mode


# --- the step memory (section 2.3): SET_STEP_CONFIG, READ/DUMP at 0x01000000, ERASE, XDUMP ------------------
STEP_BASE = 0x01000000
#: The default logger's step ring (header version 3: in front of the journal ring): 2662 records, 53,240 bytes.
STEP_CAP = 2662
STEP_BYTES = 20 * STEP_CAP


def _step_bytes(first: int, n: int) -> bytes:
    """Records numbered first .. first+n-1, built with pack_step_records; the CRC checked here by crc_hqx."""
    from gaitlog.protocol.steps import empty_step_records, pack_step_records

    rec = empty_step_records(n)
    k = np.arange(first, first + n)
    rec["end_sample"] = 27 * k
    rec["duration_samples"] = 27
    rec["length_m1_q14"] = 11000 + k % 100
    data = pack_step_records(rec)
    assert all(struct.unpack_from(">H", data, 20 * i + 18)[0] == binascii.crc_hqx(data[20 * i:20 * i + 18], 0)
               for i in range(n))
    return data


def _log_steps(lg: Logger, data: bytes) -> int:
    lg.firmware.start_logging(start_time_s=0, overwrite=True)
    n = lg.firmware.log_steps(data)
    lg.firmware.stop_logging()
    return n


def test_log_steps_only_while_logging(logger: Logger) -> None:
    assert logger.firmware.log_steps(_step_bytes(0, 3)) == 0 and logger.header.steps_written == 0
    assert _log_steps(logger, _step_bytes(0, 3)) == 3
    hdr = one(send(logger, frame(0x06, 1)))[2]
    assert struct.unpack_from("<IHH", hdr, 44) == (3, 3, STEP_CAP)  # committed at STOP
    assert logger.data_eeprom.read(44, 8) == hdr[44:52]
    # STATUS and INFO are unchanged by the step memory
    assert struct.unpack("<BBII", one(send(logger, frame(0x02, 2)))[2])[2:] == (550, 550)
    assert struct.unpack("<IHBBIIBI", one(send(logger, frame(0x01, 3)))[2])[-1] == 262144


def test_set_step_config(logger: Logger) -> None:
    # as firmware 1.3 stores it: on-line algorithm version 4, M4's exponent 2/8 (its default, byte 20)
    block = struct.pack("<BBHHHHHiiB11x", 4, 1, 29491, 6554, 36045, 32768, 16384, 19661, -13107, 2)
    # step_format 1 or 2 (a host that knows an older version) turns the algorithm on: stored as 4, the version
    # it runs, with M4's exponent not given (byte 20 is reserved below version 4): the default
    older = b"\x01" + block[1:20] + bytes(12)
    assert one(send(logger, frame(0x0B, 1, older))) == (ACK, 1, b"\x0b")
    assert one(send(logger, frame(0x06, 2)))[2][128:160] == block
    assert one(send(logger, frame(0x0B, 1, b"\x02" + older[1:]))) == (ACK, 1, b"\x0b")
    hdr = one(send(logger, frame(0x06, 2)))[2]
    assert hdr[128:160] == block and logger.data_eeprom.read(128, 32) == block
    assert logger.step_config.raw["k2_m5_q16"] == -13107
    assert one(send(logger, frame(0x0B, 1, block))) == (ACK, 1, b"\x0b")
    assert one(send(logger, frame(0x06, 2)))[2][128:160] == block
    refused = (b"\x05" + block[1:], block[:1] + b"\x03" + block[2:], b"\x01\x00\x00\x00" + block[4:],
               b"\x04\x00\x00\x00" + block[4:], block[:20] + b"\x05" + block[21:])
    # unknown format, reserved flag bit, format 1 or 4 with leg length 0, M4's exponent 5/8
    for seq, bad in enumerate(refused, 3):
        assert one(send(logger, frame(0x0B, seq, bad))) == (NAK, seq, bytes([0x0B, BAD_ARGUMENT]))
    assert one(send(logger, frame(0x0B, 8, block[:31]))) == (NAK, 8, bytes([0x0B, BAD_LENGTH]))
    assert one(send(logger, frame(0x06, 8)))[2][128:160] == block  # the refused blocks changed nothing
    # ERASE clears the step counters, not the configuration
    _log_steps(logger, _step_bytes(0, 5))
    assert one(send(logger, frame(0x05, 9, b"ERASE"))) == (ACK, 9, b"\x05")
    hdr = one(send(logger, frame(0x06, 10)))[2]
    assert struct.unpack_from("<IHH", hdr, 44) == (0, 0, STEP_CAP) and hdr[128:160] == block
    assert logger.data_eeprom.read(0, 256) == hdr


def test_read_and_dump_step_memory(logger: Logger) -> None:
    data = _step_bytes(0, 10)
    _log_steps(logger, data)
    t, s, p = one(send(logger, frame(0x07, 1, struct.pack("<IH", STEP_BASE + 20, 60))))
    assert (t, s) == (0x87, 1) and struct.unpack_from("<I", p)[0] == STEP_BASE + 20 and p[4:] == data[20:80]
    step_memory = logger.step_memory
    assert len(step_memory) == STEP_BYTES and step_memory[:200] == data
    last = STEP_BASE + STEP_BYTES - 20
    assert one(send(logger, frame(0x07, 2, struct.pack("<IH", last, 20))))[2][4:] == step_memory[-20:]
    # ranges that are not inside one region: NAK BAD_ADDRESS
    for seq, (address, length) in enumerate(((last, 21), (STEP_BASE - 4, 8), (262144, 16), (STEP_BASE + STEP_BYTES, 1),
                                             (0x02000000, 4)), 3):
        assert one(send(logger, frame(0x07, seq, struct.pack("<IH", address, length)))) == (
            NAK, seq, bytes([0x07, BAD_ADDRESS])), (address, length)
    # DUMP of the whole step memory in chunks of whole records: addresses as requested
    out = frames_of(send(logger, frame(0x08, 20, struct.pack("<IIH", STEP_BASE, STEP_BYTES, 2040))))
    assert len(out) == 27 + 1 and out[-1] == (0x88, 20, struct.pack("<IIH", STEP_BASE, STEP_BYTES, 27))
    assert [struct.unpack_from("<I", p)[0] for _, _, p in out[:-1]] == [STEP_BASE + 2040 * k for k in range(27)]
    assert b"".join(p[4:] for _, _, p in out[:-1]) == step_memory
    assert one(send(logger, frame(0x08, 21, struct.pack("<IIH", 262144 - 8, 16 + STEP_BASE, 4096)))) == (
        NAK, 21, bytes([0x08, BAD_ADDRESS]))
    assert one(send(logger, frame(0x08, 22, struct.pack("<IIH", STEP_BASE, STEP_BYTES + 1, 4096)))) == (
        NAK, 22, bytes([0x08, BAD_ADDRESS]))


def test_step_ring_wraps_through_the_firmware(logger: Logger) -> None:
    data = _step_bytes(0, STEP_CAP + 500)
    assert _log_steps(logger, data[:20 * 2500]) == 2500
    assert _log_steps(logger, data[20 * 2500:]) == 662
    hdr = one(send(logger, frame(0x06, 1)))[2]
    assert struct.unpack_from("<IHH", hdr, 44) == (3162, 500, STEP_CAP)
    out = frames_of(send(logger, frame(0x08, 2, struct.pack("<IIH", STEP_BASE, STEP_BYTES, 4080))))
    mem = b"".join(p[4:] for _, _, p in out[:-1])
    # ring order by hand: the oldest record (number 500) is in slot 500, the newest (3161) in slot 499
    ordered = mem[20 * 500:] + mem[:20 * 500]
    assert ordered == data[20 * 500:]


def test_xdump_carries_the_stored_step_records(logger: Logger) -> None:
    _log_steps(logger, _step_bytes(0, 40))
    _, got = _xmodem_receive(logger, frame(0x09, 5))
    header = one(send(logger, frame(0x06, 1)))[2]
    used = 4 * 550
    assert got[:256] == header and got[256:256 + used] == logger.memory[:used]
    assert got[256 + used:256 + used + 800] == _step_bytes(0, 40)
    assert len(got) % 1024 == 0 and _trailer_checks(got, 256 + used + 800)
