"""The on-line algorithm keeps its sample indices in 16 bits, as the PIC does: a ring-mode run longer than 65,536
samples gives the records of the same signal where its indices do not wrap."""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.algorithms import state
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.firmware import step_algorithm_for
from gaitlog.protocol.steps import StepConfig, pack_step_records

#: The slots that hold sample indices (16-bit words in ``state``).
INDEX_SLOTS = [state.INDEX_SLOTS[name] for name in ("N", "MXPOS", "PEND", "LAST", "RAW")]
#: Where the expectation's indices wrap: a sample inside the walk's third bout.
WRAP_B = 25_600


def test_index_slots_are_the_declared_16_bit_words() -> None:
    widths = {v.name: v.word_bytes for v in state.variables(line_length=19, median_steps=7)}
    assert state.INDEX_MODULUS == 65536 and all(widths[n] * 8 == state.INDEX_BITS for n in ("N", "PEND", "LAST"))
    assert state.since(3, 65533) == 6 and state.since(65533, 3) == -6 and state.since(0, 0) == 0


def _ring_mode_device_records(codes: np.ndarray, config: StepConfig) -> tuple[bytes, object]:
    """The emulated logger in overwrite mode, fed ``codes`` page by page; its step records in order."""
    logger = Logger(device_id=9, step_config=config, overwrite=True)
    fw = logger.firmware
    fw.start_logging(start_time_s=0, overwrite=True)
    for a in range(0, codes.shape[0], 32):
        fw.log_samples(codes[a:a + 32])
    fw.stop_logging()
    records, ok = logger.steps.records_in_order()
    assert ok.all()
    return records.tobytes(), logger.header


def test_ring_mode_run_across_the_16_bit_wrap(simulated_walk: tuple) -> None:
    """Two copies of a walk (79,844 samples) on the device in ring mode: its kernel's indices wrap at sample
    65,536 (and the sample memory, 65,536 samples, overwrites its oldest). The expectation is the same signal
    with the algorithm's index state moved by 39,936 (a multiple of the emulator's scratch ring) at sample
    20,000: there the indices wrap at sample 25,600, inside a walk, and run straight through 65,536. Every
    record must be the same, byte for byte (absolute end samples, the toe-off and heel strike, flags, lengths,
    CRC): none depends on where the 16-bit indices wrap."""
    walk, subject = simulated_walk
    codes = np.concatenate([walk, walk])
    config = StepConfig(step_format=1, leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m)
    device, header = _ring_mode_device_records(codes, config)
    assert codes.shape[0] > state.INDEX_MODULUS and header.samples_written == codes.shape[0]

    alg = step_algorithm_for(header)
    size = alg._scr.shape[0]
    shift = state.INDEX_MODULUS - WRAP_B
    assert shift % size == 0                       # the scratch ring's slots stay where they are
    first = alg.feed(codes[:20_000])
    alg._st_i[INDEX_SLOTS] = (alg._st_i[INDEX_SLOTS] + shift) & state.INDEX_MASK
    rest = alg.feed(codes[20_000:])
    steps = type(first).concatenate([first, rest, alg.flush()])
    expected = pack_step_records(steps.to_records(0))

    assert len(device) == len(expected) and len(device) // 20 > 2000
    got = np.frombuffer(device, np.uint8).reshape(-1, 20)
    want = np.frombuffer(expected, np.uint8).reshape(-1, 20)
    differ = np.flatnonzero((got != want).any(axis=1))
    assert differ.size == 0, f"{differ.size} records differ, the first at {differ[:1]}"
    # records near either wrap (the device's at sample 65,536, the expectation's at 25,600), with windows
    for wrap in (state.INDEX_MODULUS, WRAP_B):
        near = (np.abs(steps.end - wrap) < 100) & (steps.duration > 0)
        assert np.count_nonzero(near) >= 3, wrap
