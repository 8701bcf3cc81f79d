"""The PIC firmware's RAM map from gpasm's listing (:mod:`gaitlog.firmware_sim.pic.ram_map`): the whole firmware
in the PIC16F877's 368 bytes, its own variable groups named, no overlap but the documented overlays; and the
header counters the map holds, run in gpsim against the model's header arithmetic."""

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.probe import detector_trace
from gaitlog.firmware_sim.budget import FIRMWARE_RAM, PIC_RAM_BYTES
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.firmware_sim.pic.ram_map import FIRMWARE_GROUPS
from gaitlog.protocol.header import CAPACITY_SAMPLES
from tests.firmware_sim.test_pic_logger import CALS

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason="gputils/gpsim not installed")


@needs_gpsim
def test_the_whole_firmware_fits_with_its_groups_named():
    """368 bytes at most, the parts still in the model reserved at the model's sizes, the header counters there."""
    m = gl.memory_map()
    assert m.ram_problems == ()
    assert m.ram_total_bytes <= PIC_RAM_BYTES
    model = {i.name: i.bytes for i in FIRMWARE_RAM}
    assert m.ram_groups["UART receiver"] == model["UART receiver"] == 9
    assert m.ram_groups["UART transmitter"] == model["UART transmitter"] == 4
    assert m.ram_groups["I2C page write"] == model["I2C driver"] == 5
    assert m.ram_groups["header counters"] == 4 + 4          # samples_written (u32), steps_written (u32)
    assert set(m.ram_groups) == set(FIRMWARE_GROUPS)
    assert "UART receiver 9 (reserved" in m.ram_line() and "header counters 8" in m.ram_line()


def _edited_map(monkeypatch, old: str, new: str) -> gl.MemoryMap:
    """memory_map() with logger_ram.inc's ``old`` replaced by ``new`` in the assembled copy."""
    copy = gl.copy_sources

    def edited(folder, *a, **k):
        copy(folder, *a, **k)
        inc = folder / "logger_ram.inc"
        text = inc.read_text()
        assert old in text
        inc.write_text(text.replace(old, new))

    monkeypatch.setattr(gl, "copy_sources", edited)
    return gl.memory_map()


@needs_gpsim
def test_a_missing_group_is_named(monkeypatch):
    m = _edited_map(monkeypatch, "        UART_TX:.4 ", "        ; UART_TX:.4 ")
    assert any("UART transmitter" in p and "not in the RAM map" in p for p in m.ram_problems)


@needs_gpsim
def test_a_group_smaller_than_the_models_is_named(monkeypatch):
    m = _edited_map(monkeypatch, "        I2C_PW:.5 ", "        I2C_PW:.4 ")
    assert any("I2C page write take 4 bytes, less than the model's 5" in p for p in m.ram_problems)


@needs_gpsim
def test_an_undocumented_overlap_is_named(monkeypatch):
    alias = "B0              equ     FX_L"
    m = _edited_map(monkeypatch, alias, alias + "\nSPARE           equ     AV_L")
    assert m.ram_problems == ("alias SPARE of AV_L is not a documented overlay",)
    bits = "AF_LOOK_MAX     equ     0"
    m = _edited_map(monkeypatch, bits, "        cblock  0xEE\n        EXTRA\n        endc\n" + bits)
    assert any("share 0x0EE" in p for p in m.ram_problems)


@needs_gpsim
@pytest.mark.parametrize("overwrite", [True, False])
def test_header_counters_across_the_capacity(simulated_walk, overwrite):
    """samples_written (32 bits, write_index its low half) and steps_written, kept by the interrupt and fin_join,
    as the model's header counts them (Ring.append, StepStore.append); a run that fills the memory in
    stop-when-full mode ends with the sample that fills it."""
    codes = simulated_walk[0][:900]
    first = 3 * CAPACITY_SAMPLES - 150 if overwrite else CAPACITY_SAMPLES - 700
    h = gl.PicLogger(overwrite=overwrite, steps_written=0xFFFFFFFE)
    run = h.run_header(codes, CALS["device"], first_sample_number=first)
    taken = codes.shape[0] if overwrite else CAPACITY_SAMPLES - first
    assert run.samples_processed == taken and run.overwrite == overwrite
    assert run.samples_written == first + taken and run.write_index == (first + taken) % CAPACITY_SAMPLES
    steps = detector_trace(codes[:taken], CALS["device"]).records.shape[0]
    assert steps >= 2
    assert run.steps_written == min(0xFFFFFFFE + steps, 0xFFFFFFFF)      # saturating (u32)


@needs_gpsim
def test_samples_written_saturates_while_write_index_goes_on(simulated_walk):
    first = 0xFFFFFFFF - 100
    run = gl.PicLogger().run_header(simulated_walk[0][:300], CALS["nominal"], first_sample_number=first)
    assert run.samples_processed == 300
    assert run.samples_written == 0xFFFFFFFF and run.write_index == (first + 300) % CAPACITY_SAMPLES
