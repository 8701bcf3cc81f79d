"""Header version 3 (PROTOCOL.md 2.7): the page-commit journal in a ring of the step EEPROM.

The lifetime is measured from the emulated EEPROMs' write-cycle counters, and a power cut at every byte of
a commit (the sample page write and the entry's page write) is checked against an uncut twin of the logger:
the recovered samples are exactly the twin's, and at most two pages are lost."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger, PowerCut
from gaitlog.firmware_sim.eeprom import DATA_EEPROM_ENDURANCE_CYCLES, ENDURANCE_CYCLES
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.host.files.decode import decode_bytes
from gaitlog.protocol.header import PAGE_SAMPLES, DeviceHeader
from gaitlog.protocol.journal_ring import (
    ENTRY_BYTES_V3,
    RING_FIRST_BYTE,
    RING_PAGE_BYTES,
    RING_PAGES,
    entry_bytes,
    last_ring_commit,
    parse_entry,
)
from tests.firmware_sim.test_fw_power_loss import _campaign

SAMPLE_RATE_HZ = 50.0
TEN_YEARS_8H_S = 10 * 365 * 8 * 3600.0
RING_FIRST_PAGE = RING_FIRST_BYTE // RING_PAGE_BYTES


def _codes(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 1024, size=(n, 3))


def _logging(n_samples: int, *, overwrite: bool) -> Logger:
    logger = Logger(journal_ring=True, overwrite=overwrite)
    fw = logger.firmware
    fw.start_logging(start_time_s=1000, overwrite=overwrite)
    fw.log_samples(_codes(n_samples))
    return logger


def test_journal_ring_lasts_ten_years_by_the_counted_cycles():
    """Continuous logging over three laps of the ring: each ring page's counted write cycles per second of
    logging, against the 24LC1025's endurance, last 10 years at 8 h a day; the data EEPROM takes no write
    while logging (START and STOP only)."""
    laps = 3
    n = laps * RING_PAGES * 2 * PAGE_SAMPLES
    logger = Logger(journal_ring=True, overwrite=True)
    fw = logger.firmware
    fw.start_logging(start_time_s=0, overwrite=True)
    data_after_start = logger.data_eeprom.wear.copy()
    ring_before = logger.step_eeprom.wear[RING_FIRST_PAGE:RING_FIRST_PAGE + RING_PAGES].copy()
    for a in range(0, n, 50):  # one second at a time, as the timer delivers them
        fw.log_samples(_codes(50, seed=a)[: n - a])
    ring = logger.step_eeprom.wear[RING_FIRST_PAGE:RING_FIRST_PAGE + RING_PAGES] - ring_before
    assert (logger.data_eeprom.wear == data_after_start).all()   # no data EEPROM write while logging
    assert ring.tolist() == [laps] * RING_PAGES                  # every second page commit: one ring page write
    per_s = ring.max() / (n / SAMPLE_RATE_HZ)
    assert ENDURANCE_CYCLES / per_s >= TEN_YEARS_8H_S
    assert ENDURANCE_CYCLES / per_s == pytest.approx(1.229e8, rel=1e-3)   # 11.7 years at 8 h a day
    fw.stop_logging()
    run = logger.data_eeprom.wear - data_after_start
    assert run.max() <= 1 and (logger.data_eeprom.wear[160:254] == 0).all()  # STOP; the journal area never


def test_data_eeprom_takes_a_header_commit_per_start_and_stop_only():
    """A START/STOP pair costs the worst data EEPROM byte at most 2 cycles: 50,000 runs, 13.7 a day for ten
    years, however long they are."""
    logger = Logger(journal_ring=True, overwrite=True)
    fw = logger.firmware
    before = logger.data_eeprom.wear.copy()
    for run in range(5):
        fw.start_logging(start_time_s=100 * run, overwrite=True)
        fw.log_samples(_codes(1000 + 7 * run, seed=run))
        fw.stop_logging()
    per_run = (logger.data_eeprom.wear - before).max() / 5
    assert per_run <= 2
    assert DATA_EEPROM_ENDURANCE_CYCLES / per_run / (10 * 365) == pytest.approx(13.7, abs=0.01)


def _cut_case(n_samples: int, overwrite: bool):
    logger = _logging(n_samples, overwrite=overwrite)
    return logger, logger.ring.in_flight_bytes(), logger.ring._commits


@pytest.mark.parametrize("n_samples,overwrite", [
    (6 * PAGE_SAMPLES, False),              # commit 6: an entry after it
    (7 * PAGE_SAMPLES, False),              # commit 7: no entry after it
    (2 * PAGE_SAMPLES, False),              # commit 2: the run's first entry
    (65536 + 10 * PAGE_SAMPLES, True),      # wrapped, entry after the page
    (65536 + 11 * PAGE_SAMPLES, True),      # wrapped, no entry
])
def test_power_cut_at_every_byte_of_a_commit(n_samples, overwrite):
    """Every byte of the last commit (sample page, then the entry) torn: power-up recovers a prefix of the
    samples the uncut twin holds, loses at most two pages, and exactly the pages the design says."""
    base, n_bytes, m = _cut_case(n_samples, overwrite)
    assert n_bytes == RING_PAGE_BYTES + (ENTRY_BYTES_V3 if m % 2 == 0 else 0)
    twin = copy.deepcopy(base)
    twin.firmware.stop_logging()
    truth = twin.header
    for at_byte in range(n_bytes + 1):
        logger = copy.deepcopy(base)
        logger.ring.power_cut(at_byte)
        logger.power_up()
        h = logger.header
        lost = truth.samples_written - h.samples_written
        if at_byte == n_bytes:
            expected = PAGE_SAMPLES * (m % 2)
        elif at_byte < RING_PAGE_BYTES:
            expected = PAGE_SAMPLES * (1 + (m - 1) % 2)
        else:
            expected = 2 * PAGE_SAMPLES
        assert h.power_lost and not h.logging
        assert lost == expected <= 2 * PAGE_SAMPLES, at_byte
        assert h.write_index == h.samples_written % h.capacity_samples
        slots = h.stored_slots()
        good = np.setdiff1d(slots, h.torn_slot_numbers()) if overwrite else slots
        if overwrite:
            assert h.torn_slots == 2 * PAGE_SAMPLES - h.write_index % PAGE_SAMPLES
        else:
            assert h.torn_slots == 0
        mine = np.frombuffer(logger.memory, "<u4")[good]
        theirs = np.frombuffer(twin.memory, "<u4")[good]
        np.testing.assert_array_equal(mine, theirs)
        DeviceHeader.from_bytes(h.to_bytes())  # the recovered header validates


def test_a_torn_entry_never_claims_its_commit():
    """Entry m torn at every byte to every value over the entry it overwrites (m − 192, the same run): the
    ring proves m − 2 unless every byte of m arrived."""
    rn, nonce, m = 5, 0xCAFEF00D, 200
    ring = [b"\xff" * ENTRY_BYTES_V3] * RING_PAGES
    for k in range(2, m, 2):
        page = (rn + k // 2 - 1) % RING_PAGES
        ring[page] = entry_bytes(k, steps=k // 3, recording_number=rn, recording_nonce=nonce)
    page = (rn + m // 2 - 1) % RING_PAGES
    old, new = ring[page], entry_bytes(m, steps=m // 3, recording_number=rn, recording_nonce=nonce)
    assert parse_entry(old)[0] == m - 2 * RING_PAGES
    for j in range(ENTRY_BYTES_V3):
        for value in range(256):
            torn = bytearray(old)
            torn[:j] = new[:j]
            torn[j] = value
            got = last_ring_commit(ring[:page] + [bytes(torn)] + ring[page + 1:], recording_number=rn,
                                   recording_nonce=nonce)
            assert got == ((m, m // 3) if bytes(torn) == new else (m - 2, (m - 2) // 3)), (j, value)


def test_header_version_3_is_the_default_and_version_2_selectable(tmp_path):
    """A new logger has header version 3 (its data EEPROM takes header commits only); ``journal_ring=False``
    builds one of version 2, whose journal is in the data EEPROM. A device built from an image keeps the
    image's header version unless one is asked for, and one asked for refuses an image of the other."""
    default = _logging(4 * PAGE_SAMPLES, overwrite=False)
    assert (default.header.header_version, default.header.step_capacity) == (3, 2662)
    assert default.header.commit_journal == Logger(journal_ring=False).header.commit_journal   # untouched
    assert (Logger().header.header_version, Logger(journal_ring=True).header.header_version) == (3, 3)
    v2 = Logger(journal_ring=False, overwrite=False)
    v2.firmware.start_logging(start_time_s=0, overwrite=False)
    v2.firmware.log_samples(_codes(4 * PAGE_SAMPLES))
    assert (v2.header.header_version, v2.header.step_capacity) == (2, 3276)
    assert v2.ring.ring_journal is False and (v2.step_eeprom.memory[RING_FIRST_BYTE:65536] == 0xFF).all()
    assert v2.header.commit_journal != default.header.commit_journal   # four commits journalled
    v2.firmware.stop_logging()
    default.firmware.stop_logging()
    for lg, name, version, cap in ((v2, "v2.glimg", 2, 3276), (default, "v3.glimg", 3, 2662)):
        path = lg.save_image(tmp_path / name)
        for back in (Logger.from_image(path), Logger(image_path=path)):
            assert (back.header.header_version, back.header.step_capacity) == (version, cap)
            assert back.header.to_bytes() == lg.header.to_bytes() and back.memory == lg.memory
        other = version == 2   # journal_ring=True for the version-2 image, False for the version-3 one
        with pytest.raises(DeviceError, match=f"image holds {cap} step records; this device {5938 - cap}"):
            Logger.from_image(path, journal_ring=other)


def test_a_cut_in_stops_flush_keeps_the_last_entry():
    """The partial page STOP flushes is in flight, not the entry of the last journalled commit: a cut at any
    byte of the flush loses that partial page only (found by the power-cut campaign)."""
    base = _logging(4 * PAGE_SAMPLES + 5, overwrite=False)   # commits 1-4 journalled, 5 samples in the buffer
    base.firmware._end_steps()
    base.ring._flush()
    n = base.ring.in_flight_bytes()
    assert n == 4 * 5
    for at_byte in (0, n // 2, n - 1):
        logger = copy.deepcopy(base)
        logger.ring.power_cut(at_byte)
        logger.power_up()
        assert logger.header.samples_written == 4 * PAGE_SAMPLES and logger.header.power_lost


def test_campaign_on_header_version_3():
    """The power-cut campaign (benchmarks/power_cut_campaign.py --journal-ring), smaller: 0 wrong samples, at
    most two pages lost, every loss reported exactly; the bound is reached."""
    res = _campaign().run_campaign(80, seed=5, journal_ring=True)
    assert res.failures == [] and res.ok and res.wrong_samples == 0 and res.misreported == 0
    assert res.max_lost_samples == 2 * PAGE_SAMPLES
    assert {"in the page write", "in the journal write", "between samples"} <= set(res.cut_kinds)


def test_record_with_a_power_cut_decodes_and_says_two_pages(tmp_path):
    """The Logger API on header version 3: a run cut in the entry after a page; the image decodes the
    samples of the journalled commits, exactly those recorded, and says at most two pages were lost."""
    motion = CalibrationPoses(n_poses=4, hold_s=3.0, move_s=1.0)
    logger = Logger(journal_ring=True, image_path=tmp_path / "d.glimg")
    first = logger.record(motion)
    n_cut = PAGE_SAMPLES - first.n_samples % PAGE_SAMPLES + 9 * PAGE_SAMPLES   # commit 10: an entry after it
    res = logger.record(motion, power_cut=PowerCut(at_sample=n_cut, at_byte=RING_PAGE_BYTES + 3))
    h = logger.header
    assert h.power_lost and h.header_version == 3
    assert res.n_taken - (h.samples_written - first.n_samples) == 2 * PAGE_SAMPLES   # the entry torn: 9, 10
    with pytest.warns(UserWarning, match="at most two 32-sample pages"):
        rec = decode_bytes((tmp_path / "d.glimg").read_bytes())
    assert rec.valid.all() and rec.n_samples == h.samples_written
    np.testing.assert_array_equal(rec.codes[:first.n_samples], first.codes)
    np.testing.assert_array_equal(rec.codes[first.n_samples:], res.codes[: h.samples_written - first.n_samples])
    assert Logger.from_image(tmp_path / "d.glimg", journal_ring=True).header.to_bytes() == h.to_bytes()
