"""24LC1025 page wrap and 64 KiB read boundary, data EEPROM, ring buffer order and full-memory modes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.eeprom import DataEeprom, Eeprom24LC1025, EepromBank
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.ring_buffer import MemoryFullError, RingBuffer
from gaitlog.protocol.header import DeviceHeader


def test_page_write_wraps_within_the_page_and_counts_wear() -> None:
    e = Eeprom24LC1025(page_write_time_s=0.005)
    data = bytes(range(1, 21))
    e.page_write(256 + 120, data, now_s=0.0)  # page 2 holds 256..383
    mem = e.memory
    assert bytes(mem[376:384]) == data[:8]
    assert bytes(mem[256:268]) == data[8:]  # wrapped to the page start, not into page 3
    assert mem[384] == 0xFF and mem[268] == 0xFF
    assert e.wear[2] == 1 and e.wear.sum() == 1
    with pytest.raises(DeviceError, match="busy"):
        e.page_write(0, b"x", now_s=0.004)  # write cycle not finished: no acknowledge
    e.page_write(0, b"x", now_s=0.005)
    assert e.write_time_s == pytest.approx(0.010)
    with pytest.raises(DeviceError):
        e.page_write(0, bytes(129), now_s=1.0)


def test_sequential_read_rolls_over_at_the_64k_block_and_the_bank_re_addresses() -> None:
    bank = EepromBank()
    rng = np.random.default_rng(0)
    content = rng.integers(0, 256, bank.size_bytes, dtype=np.uint8)
    bank.load(content)
    dev0 = bank.devices[0]
    # the raw part: reading past 0xFFFF continues at 0x0000 of the same block
    raw = dev0.sequential_read(65536 - 4, 8)
    assert raw == content[65532:65536].tobytes() + content[0:4].tobytes()
    raw_b1 = dev0.sequential_read(131072 - 2, 4)
    assert raw_b1 == content[131070:131072].tobytes() + content[65536:65538].tobytes()
    # the bank re-addresses at every block boundary, across devices too
    before = bank.read_transactions
    got = bank.read(65536 - 10, 131072 + 20)
    assert got == content[65526:65526 + 131092].tobytes()
    assert bank.read_transactions - before == 4  # 10 bytes, 64K, 64K, 10 bytes
    with pytest.raises(DeviceError):
        bank.read(bank.size_bytes - 2, 4)


def test_data_eeprom_writes_only_changed_bytes() -> None:
    d = DataEeprom(byte_write_time_s=0.004)
    assert d.read(0, 4) == b"\xff" * 4
    d.write(10, b"abc")
    d.write(10, b"abd")
    assert d.read(10, 3) == b"abd"
    assert d.wear[10:13].tolist() == [1, 1, 2]
    assert d.write_time_s == pytest.approx(4 * 0.004)


def _ring(capacity: int = 65536) -> RingBuffer:
    return RingBuffer(EepromBank(), DataEeprom(), DeviceHeader(capacity_samples=capacity))


def test_overwrite_mode_wraps_and_keeps_the_newest_in_order() -> None:
    rb = _ring()
    rb.start(start_time_s=0, overwrite=True)
    total = 65536 + 1000 + 7
    words = (np.arange(total, dtype=np.uint64) * 2654435761 % (1 << 30)).astype(np.uint32)
    assert rb.append(words[:50_001]) == 50_001
    assert rb.append(words[50_001:]) == total - 50_001
    rb.stop()
    h = rb.header
    assert h.wrapped and h.samples_written == total and h.write_index == total % 65536
    np.testing.assert_array_equal(rb.words_in_order(), words[-65536:])
    # memory slot k holds the word whose absolute number is congruent to k
    mem = np.frombuffer(rb.read_bytes(0, 4 * 65536), dtype="<u4")
    assert mem[0] == words[65536] and mem[1006] == words[65536 + 1006] and mem[1007] == words[1007]
    # the committed header in the data EEPROM is the RAM header
    assert DeviceHeader.from_bytes(rb.data_eeprom.read()).samples_written == total


def test_stop_when_full_stops_and_refuses_to_start_again() -> None:
    rb = _ring()
    rb.start(start_time_s=5, overwrite=False)
    assert rb.append(np.arange(70_000, dtype=np.uint32)) == 65536
    h = rb.header
    assert not h.logging and h.full_stopped and not h.wrapped and h.samples_written == 65536
    np.testing.assert_array_equal(rb.words_in_order(), np.arange(65536, dtype=np.uint32))
    assert rb.append(np.arange(3, dtype=np.uint32)) == 0
    with pytest.raises(MemoryFullError):
        rb.start(start_time_s=6, overwrite=False)
    rb.start(start_time_s=6, overwrite=True)  # ring mode may continue
    assert rb.append(np.array([7], dtype=np.uint32)) == 1
    rb.stop()
    assert rb.header.wrapped and rb.words_in_order()[-1] == 7
    rb.erase()
    assert rb.header.samples_written == 0 and rb.header.flags == 0


def test_runs_that_stop_mid_page_continue_in_place() -> None:
    rb = _ring()
    for run, n in enumerate([5, 40, 1, 31, 100]):
        rb.start(start_time_s=run, overwrite=False)
        assert rb.header.run_start_sample == sum([5, 40, 1, 31, 100][:run])
        rb.append(np.full(n, run, dtype=np.uint32))
        rb.stop()
    expected = np.concatenate([np.full(n, k, dtype=np.uint32) for k, n in enumerate([5, 40, 1, 31, 100])])
    np.testing.assert_array_equal(rb.words_in_order(), expected)


@settings(max_examples=40, deadline=None)
@given(
    sizes=st.lists(st.integers(min_value=0, max_value=40_000), min_size=1, max_size=12),
    stops=st.lists(st.booleans(), min_size=12, max_size=12),
    overwrite=st.booleans(),
)
def test_ring_store_then_read_back_is_identity(sizes: list[int], stops: list[bool], overwrite: bool) -> None:
    """Encoder (blocks of words stored in runs) / decoder (words in ring order) round trip."""
    capacity = 65536
    rb = _ring(capacity)
    rng = np.random.default_rng(sum(sizes))
    sent: list[np.ndarray] = []
    rb.start(start_time_s=0, overwrite=overwrite)
    for size, stop in zip(sizes, stops):
        w = rng.integers(0, 2**32, size, dtype=np.uint32)
        n = rb.append(w)
        sent.append(w[:n])
        if stop and rb.logging:
            rb.stop()
            if rb.full and not overwrite:
                break
            rb.start(start_time_s=0, overwrite=overwrite)
    rb.stop()
    allw = np.concatenate(sent) if sent else np.zeros(0, np.uint32)
    np.testing.assert_array_equal(rb.words_in_order(), allw[-capacity:])
    assert rb.header.samples_written == allw.size
