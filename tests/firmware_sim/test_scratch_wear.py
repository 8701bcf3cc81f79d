"""The scratch ring's page writes: one aligned page write per flush unit, spread evenly over the ring, counted
by the step EEPROM's model; the design's count at every rate."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.device import Logger
from gaitlog.protocol.steps import StepConfig

CONFIG = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
RING_SAMPLES = kernel.SCRATCH_RING_BYTES // kernel.SCRATCH_SAMPLE_BYTES


def test_the_ring_ends_at_the_header_slots() -> None:
    assert (kernel.SCRATCH_FIRST_BYTE, kernel.SCRATCH_RING_BYTES, kernel.SCRATCH_PAGES) == (65536, 65024, 508)
    assert RING_SAMPLES == 32_512


@pytest.mark.parametrize("rate_hz, flush", [(25.0, 8), (50.0, 16), (100.0, 32)])
def test_whole_laps_wear_every_page_alike(rate_hz: float, flush: int) -> None:
    """Two laps of the ring: every page takes 2 x 128 / (2 flush) writes, one per flush (design: the flush
    unit is the largest power of two within the delay line, 2 r3 + 1 a_v, and half a page)."""
    alg = OnlineStepAlgorithm(sampling_rate_hz=rate_hz, step_config=CONFIG)
    c = alg.config.counts
    assert int(alg.config.cfg_i[kernel.CI_FLUSH]) == flush and flush <= 2 * c.r3 + 1 < 2 * flush
    codes = np.full((2 * RING_SAMPLES, 3), 512, np.int64)
    cut = 12_345                                        # any blocks: the count follows the samples
    alg.feed(codes[:cut])
    alg.feed(codes[cut:])
    wear = alg.scratch_page_writes
    assert wear.sum() == 2 * RING_SAMPLES // flush
    assert (wear == 2 * 128 // (2 * flush)).all()


def test_the_device_counts_them_from_each_runs_start_page() -> None:
    """The firmware adds the kernel's page writes to the step EEPROM's page counters (block 1), each run from
    the page its first sample points to: two runs of 1,000 samples wear pages 512-527, then 527-542."""
    logger = Logger(device_id=2, step_config=CONFIG)
    codes = np.full((1000, 3), 512, np.int64)
    for _ in range(2):
        logger.firmware.start_logging(start_time_s=0, overwrite=False)
        logger.firmware.log_samples(codes)
        logger.firmware.stop_logging()
    wear = logger.step_eeprom.wear.astype(np.int64)
    scratch = wear[512:1020]
    assert scratch.sum() == 2 * (1000 // 16)             # 62 page writes a run
    first = np.zeros(508, np.int64)
    np.add.at(first, np.arange(62) * 32 // 128, 1)        # run 1: 32-byte units from byte 0
    second = np.roll(first, 2000 // 128)                  # run 2 starts at sample 1000: byte 2000, page 15
    assert np.array_equal(scratch, first + second)
