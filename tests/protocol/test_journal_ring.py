"""PROTOCOL.md 2.7: the journal ring's entry and the spec's worked example, checked against an independent
parse (struct and binascii's CRC-16/XMODEM), and recovery of a version-3 header."""

from __future__ import annotations

import binascii
import re
import struct
from pathlib import Path

import pytest

from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import DeviceHeader, HeaderFlag
from gaitlog.protocol.journal_ring import (
    ENTRY_BYTES_V3,
    RING_FIRST_BYTE,
    RING_PAGES,
    STEP_CAPACITY_RECORDS_V3,
    entry_bytes,
    last_ring_commit,
    parse_entry,
    ring_address,
)

SPEC = (Path(__file__).resolve().parents[2] / "protocol" / "PROTOCOL.md").read_text(encoding="utf-8")


def _example() -> tuple[dict[str, str], bytes]:
    m = re.search(r"```journal-ring-example\n(.*?)hex:\n(.*?)```", SPEC, re.DOTALL)
    assert m, "PROTOCOL.md 2.7 has no journal-ring-example block"
    fields = dict(line.split(": ", 1) for line in m.group(1).strip().splitlines())
    data = bytes.fromhex("".join(line.split(":", 1)[1] for line in m.group(2).strip().splitlines()))
    return fields, data


def test_spec_example_layout_and_crc():
    fields, data = _example()
    m, steps = int(fields["commit"]), int(fields["steps"])
    rn, nonce = int(fields["recording_number"]), int(fields["recording_nonce"], 16)
    assert len(data) == ENTRY_BYTES_V3 == 16
    assert struct.unpack_from("<IHII", data) == (m, steps, rn, nonce)
    assert binascii.crc_hqx(data[:14], 0) == int.from_bytes(data[14:16], "big")
    assert 0xD000 + 128 * ((rn + m // 2 - 1) % 96) == int(fields["address"], 16) == ring_address(m, recording_number=rn)
    assert entry_bytes(m, steps=steps, recording_number=rn, recording_nonce=nonce) == data
    assert parse_entry(data) == (m, steps, rn, nonce)


def test_layout_constants_match_the_spec():
    """The ring is the last 96 pages of block 0; the step ring in front of it holds 2662 records."""
    assert RING_FIRST_BYTE == 0xD000 and RING_PAGES == 96
    assert STEP_CAPACITY_RECORDS_V3 == 2662 and 20 * 2662 <= 0xD000 < 20 * 2663
    assert "at most 2662" in SPEC and "0xD000–0xFFFF" in SPEC


def test_the_newest_entry_of_the_run_wins_over_other_runs_and_laps():
    ring = [b"\xff" * 16] * RING_PAGES
    for m in range(2, 2 * RING_PAGES + 60, 2):  # one and a half laps of run 3
        ring[(3 + m // 2 - 1) % RING_PAGES] = entry_bytes(m, steps=m, recording_number=3, recording_nonce=9)
    assert last_ring_commit(ring, recording_number=3, recording_nonce=9) == (2 * RING_PAGES + 58, 2 * RING_PAGES + 58)
    assert last_ring_commit(ring, recording_number=3, recording_nonce=10) == (0, 0)   # same number, other nonce
    misplaced = list(ring)
    misplaced[0] = entry_bytes(10_000, steps=1, recording_number=3, recording_nonce=9)  # not its page
    assert last_ring_commit(misplaced, recording_number=3, recording_nonce=9)[0] == 2 * RING_PAGES + 58


def _v3_logging(**kw) -> DeviceHeader:
    h = DeviceHeader(header_version=3, capacity_samples=65536, step_capacity=2662, recording_number=4,
                     recording_nonce=77, flags=int(HeaderFlag.LOGGING | HeaderFlag.OVERWRITE | HeaderFlag.WRAPPED),
                     samples_written=70_000, write_index=70_000 % 65536, **kw)
    h.validate()
    return h


def test_version_3_recovery_from_the_ring_and_its_torn_slots():
    h = _v3_logging()
    r = DeviceHeader.from_bytes(h.recovered((6, 2)).to_bytes())  # round trip through the bytes validates
    c = 32 - 70_000 % 32 + 5 * 32
    assert r.samples_written == 70_000 + c and r.power_lost and not r.logging and r.header_version == 3
    assert r.torn_slots == 64 - r.write_index % 32
    nothing = h.recovered()  # no ring given: the empty journal area proves no commit
    assert nothing.samples_written == 70_000


def test_version_3_limits():
    with pytest.raises(ProtocolError, match="2662"):
        DeviceHeader(header_version=3, step_capacity=2663).validate()
    DeviceHeader(header_version=2, step_capacity=3276).validate()
    h = _v3_logging()
    with pytest.raises(ProtocolError, match="torn_slots"):
        h.replace(torn_slots=65 - h.write_index % 32).validate()
    with pytest.raises(ProtocolError, match="torn_slots"):
        h.replace(header_version=2, step_capacity=3276, torn_slots=33 - h.write_index % 32).validate()
