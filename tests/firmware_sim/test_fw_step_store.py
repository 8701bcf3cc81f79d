"""The step store (PROTOCOL.md 2.3): page writes of 20-byte records over a 24LC1025, ring wrap-around."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.eeprom import Eeprom24LC1025
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.step_store import StepStore
from gaitlog.protocol.header import DeviceHeader, HeaderFlag
from gaitlog.protocol.steps import empty_step_records, pack_step_records


def _records(first: int, n: int) -> bytes:
    """Records numbered first .. first+n-1 (end_sample = 30 · number, lengths from the number)."""
    rec = empty_step_records(n)
    k = np.arange(first, first + n)
    rec["end_sample"] = 30 * k
    rec["duration_samples"] = 25 + k % 10
    rec["length_m1_q14"] = k % 65536
    return pack_step_records(rec)


def _store(capacity: int = 3276, page_write_time_s: float = 0.005) -> StepStore:
    return StepStore(Eeprom24LC1025(page_write_time_s=page_write_time_s), DeviceHeader(step_capacity=capacity))


def test_a_record_across_a_page_boundary_takes_two_page_writes() -> None:
    store = _store()
    data = _records(0, 7)
    for k in range(7):  # one record at a time, as the algorithm delivers them
        before = store.eeprom.wear.copy()
        assert store.append(data[20 * k:20 * k + 20]) == 1
        pages = np.flatnonzero(store.eeprom.wear != before).tolist()
        assert pages == ([0] if k < 6 else [0, 1]), k  # record 6 is bytes 120-139
    assert store.eeprom.memory[:140].tobytes() == data
    assert store.eeprom.wear[:3].tolist() == [7, 1, 0]
    assert store.eeprom.write_time_s == pytest.approx(8 * 0.005)  # 8 page writes
    assert store.header.steps_written == 7 and store.header.step_write_index == 7


def test_page_writes_wait_for_the_write_cycle() -> None:
    store = _store()
    store.eeprom.busy_until_s = 1.0  # a write cycle still running
    store.append(_records(0, 7))  # acknowledge polling, not a DeviceError
    assert store.eeprom.busy_until_s == pytest.approx(1.010)  # two page writes back to back
    with pytest.raises(DeviceError, match="busy"):  # the part itself refuses a write while busy
        store.eeprom.page_write(0, b"x", now_s=1.0)


def test_ring_wraps_and_overwrites_the_oldest() -> None:
    store = _store()
    rng = np.random.default_rng(4)
    total, written = 3276 + 1000, 0
    all_bytes = _records(0, total)
    while written < total:  # batches of random size, some crossing the end of the ring
        n = min(int(rng.integers(1, 400)), total - written)
        assert store.append(all_bytes[20 * written:20 * (written + n)]) == n
        written += n
    h = store.header
    assert (h.steps_written, h.step_write_index, h.n_steps_stored, h.first_step_slot) == (4276, 1000, 3276, 1000)
    mem = store.eeprom.memory
    # record number k lies in slot k mod 3276: the newest 3276 records, computed here slot by slot
    expect = bytearray(65520)
    for k in range(total - 3276, total):
        s = k % 3276
        expect[20 * s:20 * s + 20] = all_bytes[20 * k:20 * k + 20]
    assert mem[:65520].tobytes() == bytes(expect)
    assert (mem[65520:] == 0xFF).all()  # the rest of block 0 and the scratch block untouched
    assert store.eeprom.wear[512:].sum() == 0
    records, ok = store.records_in_order()
    assert ok.all() and records["end_sample"].tolist() == (30 * np.arange(1000, 4276)).tolist()


def test_ring_end_is_not_a_page_boundary() -> None:
    # 65520 = 511 · 128 + 112: the last record (slot 3275, bytes 65500-65519) ends inside page 511
    store = _store()
    store.header.steps_written = 3275
    store.header.step_write_index = 3275
    data = _records(3275, 3)  # slots 3275, 0, 1
    before = store.eeprom.wear.copy()
    assert store.append(data) == 3
    assert np.flatnonzero(store.eeprom.wear != before).tolist() == [0, 511]
    assert store.eeprom.memory[65500:65520].tobytes() == data[:20]
    assert store.eeprom.memory[:40].tobytes() == data[20:]
    assert (store.eeprom.memory[65520:65536] == 0xFF).all()
    assert store.header.step_write_index == 2 and store.header.steps_written == 3278


def test_saturated_counter_and_small_rings() -> None:
    store = _store(capacity=5)
    store.header.steps_written = 2**32 - 3
    store.header.step_write_index = (2**32 - 3) % 5
    assert store.append(_records(0, 4)) == 4
    assert store.header.steps_written == 2**32 - 1 and store.header.step_write_index == ((2**32 - 3) % 5 + 4) % 5
    assert store.append(_records(4, 10)) == 10  # a batch longer than the ring: the last 5 survive
    records, ok = store.records_in_order()
    assert ok.all() and records["end_sample"].tolist() == [270, 300, 330, 360, 390]


def test_no_step_memory_and_bad_input() -> None:
    store = _store(capacity=0)
    assert store.append(_records(0, 3)) == 0 and store.header.steps_written == 0
    assert store.size_bytes == 0 and store.contents() == b""
    assert store.eeprom.wear.sum() == 0
    with pytest.raises(DeviceError, match="not whole 20-byte records"):
        _store().append(bytes(30))
    with pytest.raises(DeviceError, match="at most 3276"):
        StepStore(Eeprom24LC1025(), DeviceHeader().replace(step_capacity=4000))
    with pytest.raises(DeviceError, match="outside"):
        _store().read_bytes(65510, 20)


def test_read_bytes_and_erase() -> None:
    store = _store()
    data = _records(0, 10)
    store.append(data)
    assert store.read_bytes(20, 40) == data[20:60]
    store.header.flags |= int(HeaderFlag.LOGGING)
    with pytest.raises(DeviceError, match="ERASE while logging"):
        store.erase()
    store.header.flags &= ~int(HeaderFlag.LOGGING)
    store.erase()
    assert store.header.steps_written == 0 and store.header.step_write_index == 0
    assert store.records_in_order()[0].size == 0
    assert store.read_bytes(0, 200) == data  # ERASE leaves the bytes: the header says none is meaningful
