"""Header slots (PROTOCOL.md 2.5): the worked example parsed from the spec and checked with a CRC written here,
the slot order, torn slots, the roll-forward rule, and the emulated device powering up from a cut header commit."""

from __future__ import annotations

import binascii
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import DeviceHeader, HeaderFlag
from gaitlog.protocol.header_slots import (
    SLOT_ADDRESSES,
    SLOT_BYTES,
    committed_header,
    newest_slot,
    next_sequence,
    parse_slot,
    slot_bytes,
    slot_for,
)

SPEC = (Path(__file__).resolve().parents[2] / "protocol" / "PROTOCOL.md").read_text(encoding="utf-8")


def _hex(text: str) -> bytes:
    out = bytearray()
    for line in text.strip().splitlines():
        m = re.match(r"^([0-9a-f]{4}):\s*(.*)$", line.strip())
        assert m and int(m.group(1), 16) == len(out)
        for tok in m.group(2).split():
            val, _, count = tok.partition("*")
            out += bytes([int(val, 16)]) * int(count or 1)
    return bytes(out)


def _example_header(name: str) -> bytes:
    m = re.search(rf"```example {re.escape(name)}\n.*?hex:\n(.*?)```", SPEC, re.DOTALL)
    assert m, name
    return _hex(m.group(1))


def _slot_example() -> tuple[dict[str, str], bytes]:
    m = re.search(r"```header-slot-example\n(.*?)hex:\n(.*?)```", SPEC, re.DOTALL)
    assert m, "PROTOCOL.md 2.5 has no header-slot-example block"
    fields = dict(line.split(": ", 1) for line in m.group(1).strip().splitlines())
    return fields, _hex(m.group(2))


def test_spec_example_layout_and_crcs():
    fields, data = _slot_example()
    header = _example_header(fields["header"])
    sequence = int(fields["sequence"])
    assert len(data) == SLOT_BYTES == 168
    assert data[:160] == header[:160] and data[160:162] == header[254:256]
    assert struct.unpack_from("<I", data, 162)[0] == sequence
    assert binascii.crc_hqx(data[:166], 0) == int.from_bytes(data[166:168], "big")
    assert binascii.crc_hqx(header[:160], 0) == int.from_bytes(header[254:256], "big")  # the header's own CRC
    assert SLOT_ADDRESSES[slot_for(sequence)] == int(fields["address"], 16)
    # the code builds and parses the same bytes
    assert slot_bytes(header, sequence=sequence) == data
    assert parse_slot(data) == (header[:160] + header[254:256], sequence)


def test_newest_slot_in_serial_number_order():
    h = bytes(range(256))
    a, b = slot_bytes(h, sequence=7), slot_bytes(h[::-1], sequence=8)
    assert newest_slot([a, b])[1] == 8 and newest_slot([b, a])[1] == 8
    wrap_old, wrap_new = slot_bytes(h, sequence=0xFFFFFFFE), slot_bytes(h, sequence=next_sequence(0xFFFFFFFE))
    assert newest_slot([wrap_old, wrap_new])[1] == 1 and slot_for(0xFFFFFFFE) != slot_for(1)
    assert parse_slot(b"\x00" * SLOT_BYTES) is None  # zeros have a valid CRC-16 but sequence 0 is never written
    assert newest_slot([b"\xff" * SLOT_BYTES, a])[1] == 7
    assert newest_slot([b"\xff" * SLOT_BYTES] * 2) is None


@pytest.mark.parametrize("at", [0, 1, 80, 159, 160, 161, 162, 165, 166, 167])
def test_a_slot_torn_at_any_byte_is_never_taken_for_the_new_header(at):
    """A slot write cut at byte ``at``: the bytes before it new, the byte torn, the rest from two commits ago.
    The newest slot is then the other one (the previous commit), never the torn one."""
    old2 = bytes([0x11]) * 160 + b"\x00" * 96
    prev = bytes([0x22]) * 160 + b"\x00" * 96
    new = bytes([0x33]) * 160 + b"\x00" * 96
    s_old2, s_prev, s_new = slot_bytes(old2, sequence=5), slot_bytes(prev, sequence=6), slot_bytes(new, sequence=7)
    torn = bytearray(s_old2)
    torn[:at] = s_new[:at]
    torn[at] = s_new[at] ^ 0xA5
    newest = newest_slot([bytes(torn), s_prev])
    assert newest is not None and newest[1] == 6 and newest[0][:160] == prev[:160]


def test_roll_forward_keeps_the_data_eeprom_journal():
    header = _example_header("device-header-power-lost")
    slot = slot_bytes(header, sequence=43)
    torn = bytearray(header)
    torn[:80] = b"\xee" * 80  # a data EEPROM commit cut half-way (and a different journal area)
    torn[170] = 0x77
    got = committed_header(bytes(torn), [b"\xff" * SLOT_BYTES, slot])
    assert got.rolled_forward and got.sequence == 43
    assert got.header[:160] == header[:160] and got.header[254:] == header[254:] and got.header[170] == 0x77
    same = committed_header(header, [slot, b"\xff" * SLOT_BYTES])
    assert not same.rolled_forward and same.header == header
    assert committed_header(bytes(torn), [b"\x00" * SLOT_BYTES] * 2).header == bytes(torn)  # no valid slot


def _cut_start(at_part: str) -> tuple[Logger, bytes, int]:
    logger = Logger(device_id=5)
    logger.firmware.start_logging(start_time_s=100, overwrite=True)
    logger.firmware.log_samples(np.full((70, 3), 512))
    logger.firmware.stop_logging()
    before = logger.data_eeprom.read()
    logger.firmware.start_logging(start_time_s=200, overwrite=True)
    order = logger.ring.header_write_order()
    pick = {"slot": lambda w, i: w == "s", "data": lambda w, i: w == "d" and i < 160}[at_part]
    at = [k for k, (w, i) in enumerate(order) if pick(w, i)]
    at = at[len(at) // 2]
    assert logger.ring.power_cut_header(at) == ("slot" if at_part == "slot" else "data EEPROM")
    return logger, before, int(logger.header.recording_number)


def test_device_rolls_a_start_cut_after_its_slot_forward():
    logger, _, number = _cut_start("data")
    with pytest.raises(ProtocolError):  # the data EEPROM alone is torn: only the slot saves the header
        DeviceHeader.from_bytes(logger.data_eeprom.read(), source="data EEPROM")
    logger.power_up()
    h = logger.header
    assert h.recording_number == number and h.power_lost and not h.logging and h.samples_written == 70
    assert logger.data_eeprom.read()[:160] == h.to_bytes()[:160]  # rolled forward and committed


def test_device_keeps_the_old_header_when_the_cut_tears_the_slot():
    logger, before, number = _cut_start("slot")
    logger.power_up()
    h = logger.header.to_bytes()
    assert h[:160] == before[:160] and h[254:] == before[254:]
    assert logger.header.recording_number == number - 1 and not logger.header.power_lost
    assert logger.header.flags & int(HeaderFlag.LOGGING) == 0


def test_power_up_without_any_valid_header_is_a_device_error():
    logger = Logger(device_id=5)
    logger.data_eeprom.memory[:] = 0xFF
    for a in SLOT_ADDRESSES:
        logger.step_eeprom.memory[a:a + SLOT_BYTES] = 0xFF
    with pytest.raises(DeviceError, match="power-up"):
        logger.power_up()
