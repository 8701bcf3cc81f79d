"""Header version 3's page-commit journal entry in PIC16 assembly (journal.asm), run in gpsim.

Independent truth: the Python model's entry (protocol/journal_ring.py entry_bytes, ring_address, its CRC-16 from
binascii's), against the bytes the MSSP sends and the bytes gpsim's EEPROM holds afterwards (read back over I2C);
a deliberately broken copy of the routine must be caught.
"""

from __future__ import annotations

import pytest

from gaitlog.firmware_sim.budget import JOURNAL_ENTRY_CYCLES_ESTIMATE, logging_cycles
from gaitlog.firmware_sim.pic import gpsim_journal as gj
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.protocol.journal_ring import COMMIT_PAGES, RING_PAGES, entry_bytes, parse_entry, ring_address

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")

#: (commit, steps, recording_number, recording_nonce): the doc's example, the ring's first and last page, a
#: recording number past the ring's length, a saturated step count, all bits set, and commits past 2^31.
ENTRIES = [(4, 3, 7, 0x1234ABCD), (2, 0, 0, 0), (190, 65_535, 95, 0xFFFFFFFF), (0x7FFFFFFE, 65_536, 96, 0xDEADBEEF),
           (0xFFFFFFFE, 0x12345678, 0xFFFFFFFF, 1), (1000, 70_000, 123_456_789, 0x0BADF00D),
           (2 * RING_PAGES, 12, 1, 0x80000000)]


@needs_gpsim
@pytest.mark.parametrize("m, steps, number, nonce", ENTRIES)
def test_the_entry_is_the_models_on_the_bus_and_in_the_eeprom(m, steps, number, nonce):
    run = gj.run_journal_entry(m, steps=steps, recording_number=number, recording_nonce=nonce)
    want = entry_bytes(m, steps=steps, recording_number=number, recording_nonce=nonce)
    assert run.sent[0] == 0xA0                                  # the step EEPROM's block 0, a write
    assert run.address == ring_address(m, recording_number=number)
    assert run.data == want and run.read_back == want
    assert parse_entry(run.read_back) == (m, min(steps, 0xFFFF), number, nonce)
    assert run.polls >= 1 and set(run.sent[3 + 16:]) == {0xA0}   # then acknowledge polling
    assert 2_500 < run.cycles < 4_000


@needs_gpsim
def test_a_broken_crc_is_caught(monkeypatch):
    """One CRC step wrong in the routine (x >> 3 taken as x >> 4): the bytes sent differ from the model's in the
    CRC only."""
    real, src = gj.copy_sources, (gl.PIC_DIR / "journal.asm").read_text()
    marker = "        andlw   0x1F\n        xorwf   JR_CRC_H, F"
    assert src.count(marker) == 1, "the test's marker moved"

    def broken(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / "journal.asm").write_text(src.replace(marker, "        andlw   0x0F\n        xorwf   JR_CRC_H, F"))

    monkeypatch.setattr(gj, "copy_sources", broken)
    run = gj.run_journal_entry(4, steps=3, recording_number=7, recording_nonce=0x1234ABCD)
    want = entry_bytes(4, steps=3, recording_number=7, recording_nonce=0x1234ABCD)
    assert run.data[:14] == want[:14] and run.data[14:] != want[14:]
    with pytest.raises(gl.PicError, match="not the model's"):
        gj.journal_entry_cycles()


@needs_gpsim
def test_the_budgets_page_commit_is_the_measured_entry():
    """The budget's page commit per sample: the entry measured in gpsim, one every 2 pages of 32 samples, labelled
    measured; without gpsim the estimate, labelled estimated, within 10 % of the measured figure."""
    cycles = gj.journal_entry_cycles()
    per_sample, how = logging_cycles(journal_entry_cycles=cycles)["page commit"]
    assert per_sample == pytest.approx(cycles / (COMMIT_PAGES * 32))
    assert "measured in gpsim" in how
    estimate, how = logging_cycles()["page commit"]
    assert "estimated" in how and estimate == JOURNAL_ENTRY_CYCLES_ESTIMATE / 64
    assert abs(JOURNAL_ENTRY_CYCLES_ESTIMATE / cycles - 1) < 0.1
    print(f"journal entry: {cycles:,.1f} cycles measured, {cycles / 64:.1f} a sample "
          f"(estimate {JOURNAL_ENTRY_CYCLES_ESTIMATE:,.0f}, {estimate:.1f} a sample)")
