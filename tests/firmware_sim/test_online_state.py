"""The on-line algorithm's RAM is what the kernel implements: every local is declared, the call graph is
the code's, every persistent slot is used and nothing beyond; the budget against the PIC16F877."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import kernel, state
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.budget import (
    PIC_RAM_BYTES,
    cycle_budget,
    logging_cycles_per_sample,
    ram_budget,
)
from gaitlog.firmware_sim.fixedpoint import cycles_per_sample_available
from gaitlog.protocol.steps import StepConfig

ARRAYS = {"codes", "cfg_i", "cfg_v", "st_i", "st_v", "line", "durs", "scr", "out_i", "out_v", "cnt", "cyc"}


def kernel_functions() -> dict[str, object]:
    return {name: getattr(kernel, name) for name in state.FRAMES}


def test_every_local_and_argument_of_the_kernel_is_declared() -> None:
    compiled = {n for n in dir(kernel) if hasattr(getattr(kernel, n), "py_func")}
    assert compiled == set(state.FRAMES), "a compiled kernel function without a declared frame (or the reverse)"
    for name, fn in kernel_functions().items():
        names = set(fn.py_func.__code__.co_varnames) - ARRAYS
        assert names == set(state.FRAMES[name]), (name, names ^ set(state.FRAMES[name]))


def test_call_graph_is_the_codes() -> None:
    for name, fn in kernel_functions().items():
        called = {n for n in fn.py_func.__code__.co_names if n in state.FRAMES}
        assert called == set(state.CALLS[name]), (name, called)


def test_walk_writes_every_persistent_slot_and_nothing_else(simulated_walk: tuple) -> None:
    codes, _ = simulated_walk
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
                                                                            foot_length_m=0.2))
    # one canary slot beyond the declared ones in each state array
    alg._st_i = np.full(state.N_INDICES + 1, -7, np.int64)
    alg._st_v = np.full(state.N_VALUES + 1, -7, np.int64)
    alg.reset()
    alg._st_i[-1] = alg._st_v[-1] = -7
    touched_i = np.zeros(state.N_INDICES + 1, bool)
    touched_v = np.zeros(state.N_VALUES + 1, bool)
    for block in np.array_split(codes, 200):
        before_i, before_v = alg._st_i.copy(), alg._st_v.copy()
        alg.feed(block)
        touched_i |= alg._st_i != before_i
        touched_v |= alg._st_v != before_v
    assert touched_i[:-1].all() and touched_v[:-1].all()
    assert alg._st_i[-1] == -7 and alg._st_v[-1] == -7
    assert np.count_nonzero(alg._durs) == alg._durs.size


def test_ram_fits_at_50_hz_and_says_what_must_give_at_100_hz() -> None:
    r50 = ram_budget(50.0)
    assert r50.fits and r50.total_bytes == 368 and r50.algorithm_bytes == 186
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
                                                                            foot_length_m=0.2))
    assert alg.ram_bytes() == r50.algorithm_bytes
    r100 = ram_budget(100.0)
    assert not r100.fits and r100.total_bytes == 404
    assert any("what must give: 36 bytes" in line for line in r100.lines())
    assert ram_budget(25.0).total_bytes <= PIC_RAM_BYTES


def test_cycles_fit_at_50_hz(simulated_walk: tuple) -> None:
    codes, _ = simulated_walk
    budget = cycles_per_sample_available(50.0) - logging_cycles_per_sample()
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, cycles_available=budget,
                              step_config=StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2))
    alg.run(codes)
    cb = cycle_budget(alg.cycles, 50.0)
    assert cb.fits
    assert 15_000 <= cb.mean_algorithm <= 27_000          # 24.8k on this walker (gpsim-measured kernel costs)
    # the end of a step evaluates its filters again on the a_v read back from the scratch ring (no RAM to keep
    # them, and no EEPROM wear to write them): 6.0 samples behind at worst, the page buffer holds 32
    assert cb.backlog_samples < 8.0
    assert cb.worst_algorithm > cb.available * 0.5         # the end of a step is the expensive sample


@pytest.mark.parametrize("name", sorted(state.FRAMES))
def test_frames_have_reasons(name: str) -> None:
    for var, (size, why) in state.FRAMES[name].items():
        assert why and size >= -1, (name, var)
