"""Power loss during logging (PROTOCOL.md 2.4): the page-commit journal, the emulator's cut model, recovery at
power-up and by the decoder, and a campaign of random cuts in both memory modes (the full 1,000-cut campaign
is ``benchmarks/power_cut_campaign.py``). On header version 2 (``Logger(journal_ring=False)``), whose journal
in the data EEPROM bounds a loss to one page; the default, version 3, in ``test_fw_journal_ring.py``."""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger, PowerCut
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.host.files.decode import REASONS, decode_bytes
from gaitlog.protocol.commit_journal import (
    ENTRY_BYTES,
    JOURNAL_ENTRIES,
    empty_journal,
    last_commit,
    torn_step_records,
    with_commit,
)
from gaitlog.protocol.header import PAGE_SAMPLES, DeviceHeader, HeaderFlag
from gaitlog.protocol.image import build_image
from gaitlog.protocol.steps import empty_step_records, pack_step_records

ROOT = Path(__file__).resolve().parents[2]


def _campaign():
    spec = importlib.util.spec_from_file_location("power_cut_campaign", ROOT / "benchmarks" / "power_cut_campaign.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass needs its module registered
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("m", [1, 2, 14, 15, 16, 29, 300])
def test_a_torn_entry_never_claims_a_commit(m):
    """Every byte of the entry of commit m + 1 torn to every value: the journal proves m, or m + 1 only when the
    torn byte holds its new value and the bytes before it were written (the commit did arrive)."""
    before = empty_journal()
    for k in range(1, m + 1):
        before = with_commit(before, k, steps=3 * k)
    after = with_commit(before, m + 1, steps=3 * (m + 1))
    assert last_commit(before) == (m, 3 * m) and last_commit(after) == (m + 1, 3 * (m + 1))
    base = ENTRY_BYTES * (m % JOURNAL_ENTRIES)
    order = [base + i for i in (4, 5, 3, 2, 1, 0) if before[base + i] != after[base + i]]
    for j, pos in enumerate(order):
        for value in range(256):
            torn = bytearray(before)
            for p in order[:j]:
                torn[p] = after[p]
            torn[pos] = value
            got = last_commit(bytes(torn))
            complete = all(torn[p] == after[p] for p in order)
            assert got == ((m + 1, 3 * (m + 1)) if complete else (m, 3 * m)), (j, value)


def test_record_with_a_power_cut_in_a_page_write(tmp_path):
    """The Logger API on header version 2: a run of real motion cut inside a page write; the device recovers to
    the last committed page, the image decodes exactly those samples and says what was lost."""
    motion = CalibrationPoses(n_poses=4, hold_s=3.0, move_s=1.0)
    logger = Logger(device_id=5, image_path=tmp_path / "d.glimg", journal_ring=False)
    first = logger.record(motion)
    n_cut = PAGE_SAMPLES - first.n_samples % PAGE_SAMPLES + 7 * PAGE_SAMPLES  # its last sample completes a page
    res = logger.record(motion, power_cut=PowerCut(at_sample=n_cut, at_byte=77))
    h = logger.header
    s0 = first.n_samples
    assert h.power_lost and not h.logging and h.recording_number == 2
    lost = res.n_taken - (h.samples_written - s0)
    assert lost == PAGE_SAMPLES and h.samples_written % PAGE_SAMPLES == 0  # the torn page, nothing more
    with pytest.warns(UserWarning, match="cut by a power loss"):
        rec = decode_bytes((tmp_path / "d.glimg").read_bytes())
    assert rec.valid.all() and rec.n_samples == h.samples_written
    np.testing.assert_array_equal(rec.codes[:s0], first.codes)
    np.testing.assert_array_equal(rec.codes[s0:], res.codes[: h.samples_written - s0])
    assert any(f"samples {s0} … {h.samples_written - 1}" in n for n in rec.notes)
    # the next run clears POWER_LOST and numbers itself 3
    logger.record(motion)
    assert not logger.header.power_lost and logger.header.recording_number == 3


def test_wrapped_memory_reports_the_torn_page_of_old_samples():
    """Header version 2, OVERWRITE over a wrapped memory, cut in the page write: the 32 oldest slots (the page in
    flight) are reported missing with that reason, every other sample is exact; the raw data EEPROM (LOGGING set)
    decodes the same."""
    logger = Logger(device_id=2, overwrite=True, journal_ring=False)
    fw = logger.firmware
    codes = np.stack([np.arange(70_000) % 1024, np.arange(70_000) // 1024, np.full(70_000, 1)], axis=1)
    fw.start_logging(start_time_s=1, overwrite=True)
    fw.log_samples(codes)
    fw.stop_logging()
    fw.start_logging(start_time_s=2, overwrite=True)
    n = PAGE_SAMPLES - logger.header.write_index % PAGE_SAMPLES + 3 * PAGE_SAMPLES
    fw.log_samples(np.stack([np.arange(n), np.zeros(n, int), np.full(n, 2)], axis=1))
    logger.ring.power_cut(5)
    raw = logger.data_eeprom.read()
    assert DeviceHeader.from_bytes(raw).logging
    logger.power_up()
    h = logger.header
    assert h.flags & HeaderFlag.POWER_LOST and h.torn_slots == PAGE_SAMPLES and h.samples_written == 70_000 + n - 32
    for header_bytes in (h.to_bytes(), raw):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec = decode_bytes(build_image(header_bytes, logger.memory, step_memory=logger.step_memory))
        assert (~rec.valid).sum() == PAGE_SAMPLES and not rec.valid[:PAGE_SAMPLES].any()
        torn_reason = [r for r in REASONS if r.startswith("slot of the page in flight when a power loss cut a run")]
        assert [g.reason for g in rec.gaps] == torn_reason
        new = rec.sample_numbers >= 70_000
        assert (rec.codes[new, 2] == 2).all() and (rec.codes[~new & rec.valid, 2] == 1).all()


def test_version_1_header_with_logging_reports_every_sample_of_a_ring_missing():
    """No journal in header version 1: nothing of an OVERWRITE memory can be trusted after a cut run."""
    h = DeviceHeader(header_version=1, flags=int(HeaderFlag.LOGGING | HeaderFlag.OVERWRITE), samples_written=100,
                     write_index=100, run_start_sample=100)
    with pytest.warns(UserWarning, match="version 1"):
        rec = decode_bytes(build_image(h.to_bytes(), bytes(262144)))
    assert rec.n_samples == 100 and not rec.valid.any()


def test_power_cut_campaign():
    """A smaller campaign (the README's script runs 1,000): 0 wrong samples, at most one page lost, every loss
    reported exactly, and the cuts fall in every phase of a page commit and of a header commit."""
    campaign = _campaign()
    res = campaign.run_campaign(120, seed=3)
    assert res.failures == [] and res.ok
    assert res.wrong_samples == 0 and res.misreported == 0
    assert res.max_lost_samples == PAGE_SAMPLES and res.max_torn_slots == PAGE_SAMPLES  # the bound is reached
    assert {"between samples", "in the page write", "in the journal write"} <= set(res.cut_kinds)
    # and inside header commits (PROTOCOL.md 2.5): the slot write, and the data EEPROM write after it
    assert {"in START's header commit (slot)", "in START's header commit (data EEPROM)",
            "in STOP's header commit (slot)", "in STOP's header commit (data EEPROM)"} <= set(res.cut_kinds)


def test_step_records_after_the_last_commit_are_dropped_from_a_wrapped_step_ring():
    """A ring of 8 records holding records 6-13; the cut run stored records 14, 15 (committed with its first page:
    journal steps 2), then 16, 17 and a torn 18 over the slots of records 8, 9, 10. Recovery counts 16 records,
    and the 3 oldest slots hold records that are not the ones counted there: dropped with that reason."""
    def rec(numbers):
        r = empty_step_records(len(numbers))
        r["end_sample"] = 2 * np.asarray(numbers)
        return pack_step_records(r)

    slots = {s: r for s, r in zip(range(8), [8, 9, 10, 11, 12, 13, 6, 7])}  # records 6-13 before the run
    slots.update({6: 14, 7: 15, 0: 16, 1: 17})
    steps = bytearray(b"".join(rec([slots[s]]) for s in range(8)))
    steps[2 * 20 + 3] ^= 0xFF  # record 18 torn over record 10
    h = DeviceHeader(capacity_samples=64, samples_written=10, write_index=10, run_start_sample=10,
                     flags=int(HeaderFlag.LOGGING), step_capacity=8, steps_written=14, step_write_index=6,
                     commit_journal=with_commit(empty_journal(), 1, steps=2))
    r = h.recovered()
    assert (r.samples_written, r.steps_written, r.step_write_index, r.power_lost) == (32, 16, 0, True)
    assert torn_step_records(r, bytes(steps)) == 3
    memory = bytes(4 * 64)
    with pytest.warns(UserWarning, match="3 oldest stored step record"):
        got = decode_bytes(build_image(h.to_bytes(), memory, step_memory=bytes(steps)))
    assert got.step_record_numbers.tolist() == [11, 12, 13, 14, 15]
    assert (got.step_records["end_sample"] == 2 * got.step_record_numbers).all()
    assert [(g.first_record_number, g.last_record_number) for g in got.step_losses] == [(8, 10)]
    assert got.step_losses[0].reason.startswith("overwritten by a record a power loss left uncommitted")
