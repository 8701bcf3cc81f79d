"""The scratch ring's tail writes: the model counts the partial page writes the PIC makes (``fin_join`` before a
step record that reads past the last flush, ``step_flush`` at STOP) in its cycles and its wear.

Independent truth: the I2C page writes the assembly puts on the bus in gpsim (SSPBUF and SSPCON2 from its write
log, :meth:`~gaitlog.firmware_sim.pic.gpsim_logger.PicLogger.run_page_writes`), on IPOL trials and the simulated
walk: every page write's page, and each tail write's sample.
"""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.probe import scratch_writes
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.fixedpoint import OP_I2C, new_counters
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.host.files.decode import decode_file
from gaitlog.host.studies.pic_runs import assembly_input
from gaitlog.protocol.steps import StepConfig

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")
CONFIG = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
#: IPOL trials (development data) and their tail writes' sample counts, measured in gpsim: 4-1 and 4-4 have the
#: most of fin_join's; 1-1 ends with a pending step (STOP's tail write).
TRIALS = {"4-1_lb": [383, 479, 1023, 1167, 1199], "4-4_lb": [367, 687, 735, 879], "1-1_lb": [1519]}


def _gpsim_side(codes: np.ndarray, calibration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """gpsim's page writes: per ring page, the flushes' count (32 bytes), the tail writes' samples ``N`` (the
    block's first ring sample plus the samples written; the run starts at ring sample 0)."""
    w = gl.PicLogger().run_page_writes(codes, calibration)
    pages = np.zeros(kernel.SCRATCH_PAGES, np.int64)
    np.add.at(pages, w[:, 1] // 128, 1)
    tail = w[w[:, 2] < 2 * 16]
    return pages, (tail[:, 1] + tail[:, 2]) // kernel.SCRATCH_SAMPLE_BYTES, w


def _check(codes: np.ndarray, calibration, expected_tails: list[int] | None) -> None:
    wear, tails = scratch_writes(codes, calibration, 50.0, kernel.SCRATCH_RING_SAMPLES)
    pages, g_tails, w = _gpsim_side(codes, calibration)
    assert (w[:, 2] == 32).sum() == codes.shape[0] // 16
    assert g_tails.tolist() == tails.tolist()
    if expected_tails is not None:
        assert tails.tolist() == expected_tails
    assert np.array_equal(pages, wear)
    assert wear.sum() == codes.shape[0] // 16 + tails.size


@pytest.fixture(scope="module")
def ipol_runs(shared_data, tmp_path_factory):
    from gaitlog.host.cli import main

    folder = shared_data / "ipol-lowerback-dev" / "GaitData"
    out = tmp_path_factory.mktemp("ipol-tail")
    runs = {}
    for stem in TRIALS:
        f = folder / f"{stem}.txt"
        if not f.exists():
            pytest.skip(f"IPOL trial {stem} (development data) is not in {folder}")
        image = out / f"{stem}.glimg"
        assert main(["record", "--motion", "replay", str(f), "--steps", "off", "--start-time", "0",
                     "--out", str(image), "-q"]) == 0
        runs[stem] = assembly_input(decode_file(image), stem, None)
    return runs


@needs_gpsim
@pytest.mark.parametrize("stem", list(TRIALS))
def test_ipol_trials_page_writes_are_the_chips(ipol_runs, stem):
    """The model's page writes (flushes and tail writes, per page) and its tail writes' samples are those gpsim
    puts on the bus."""
    run = ipol_runs[stem]
    _check(run.codes, run.calibration_q, TRIALS[stem])


@needs_gpsim
def test_simulated_walk_page_writes_are_the_chips(simulated_walk):
    """1,500 samples of the simulated walk: no step reads past the last flush, STOP writes the tail (12 a_v)."""
    codes = simulated_walk[0][:1500]
    _check(codes, nominal_calibration_q(), [1500])


def test_a_tail_write_costs_its_bytes_on_the_bus():
    """The kernel prices a tail write as the bytes scr_write_w sends: the control byte, two address bytes and 2
    bytes for each of the newest N mod FLUSH a_v (7 at N = 87)."""
    ci = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=CONFIG).config.cfg_i
    out_i = np.zeros((1, len(kernel.OUT_I)), np.int64)
    cnt = new_counters()
    kernel._scratch_tail.py_func(16 * 5 + 7, ci, out_i, 0, cnt)
    assert cnt[OP_I2C] == 2 * 7 + kernel.I2C_WRITE_OVERHEAD
    assert out_i[0, kernel.O_TAIL] == 87


def test_the_device_counts_stops_tail_write(simulated_walk):
    """The firmware adds STOP's tail write to the step EEPROM's page counters: 1,500 samples, 93 flushes and the
    tail (samples 1,488-1,499) on the page the 94th flush would have written (the walk's last step is pending)."""
    logger = Logger(device_id=2, step_config=CONFIG)
    logger.firmware.start_logging(start_time_s=0, overwrite=False)
    logger.firmware.log_samples(simulated_walk[0][:1500])
    logger.firmware.stop_logging()
    scratch = logger.step_eeprom.wear.astype(np.int64)[512:1020]
    assert scratch.sum() == 1500 // 16 + 1
    assert scratch[2 * 1488 // 128] == 2                  # page 23: the 93rd flush (1,472-1,487) and the tail
