"""Step 6 of the on-line algorithm (the step record, ``firmware_sim/pic/step_record.asm``) in gpsim, against the
model's ``_finalise``.

Independent truths: the kernel's own run (:meth:`OnlineStepAlgorithm.run`: the trace's records must be its),
the record format of ``gaitlog.protocol.steps`` (its own golden vectors), the Q formats of ``formats.py``, the
PIC's 8-level stack (a bench one level deeper must overflow), and deliberately broken copies of the assembly
that must be caught and named.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import arithmetic as ar
from gaitlog.firmware_sim.algorithms import formats, kernel
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.probe import finalise_calls
from gaitlog.firmware_sim.fixedpoint import new_counters
from gaitlog.firmware_sim.pic import gpsim_steps as gs
from gaitlog.firmware_sim.pic.gpsim_bench import PIC_DIR
from gaitlog.firmware_sim.pic.gpsim_logger import PicError
from gaitlog.protocol.steps import STEP_RECORD_OFFSETS, StepConfig, StepFlag, pack_step_records

needs_gpsim = pytest.mark.skipif(gs.missing_tools() is not None, reason=f"{gs.missing_tools()}")

#: The walker of the conftest walk, raw (K = 1: records flagged UNCALIBRATED).
RAW = StepConfig(step_format=3, leg_length_m=0.9, foot_length_m=0.26)
#: Calibrated constants that make lengths saturate and M5 negative (clipped to 0) on a stomping signal.
EXTREME = StepConfig(step_format=3, leg_length_m=1.99, foot_length_m=1.99, calibrated=True, k_m1=1.99, k_m2=1.99,
                     k_m4=1.99, k1_m5_m_s=3000.0, k2_m5_m=0.1)
#: A leg shorter than the excursions: M1, M2, M3 impossible.
SHORT_LEG = StepConfig(step_format=3, leg_length_m=0.05, foot_length_m=1.9, calibrated=True, k_m1=1.1, k_m2=1.0,
                       k_m4=0.5, k1_m5_m_s=-3.0, k2_m5_m=0.1)


def _algo(cfg: StepConfig) -> OnlineStepAlgorithm:
    return OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg)


def _stomping(n: int = 3000) -> np.ndarray:
    """Vertical codes that clip the ADC at 1.8 steps a second (a_v and the FIR pairs saturate), with a stop."""
    t = np.arange(n) / 50.0
    s = np.sin(2 * np.pi * 1.8 * t)
    z = 768 + 600 * np.sign(s) * (np.abs(s) > 0.3) + np.random.default_rng(1).normal(0, 40, n)
    codes = np.clip(np.column_stack([512 + 80 * np.sin(np.pi * 1.8 * t), np.full(n, 512), z]), 0, 1023)
    codes[n // 2:n // 2 + 200] = (512, 512, 768)
    return codes.astype(np.int64)


@pytest.fixture(scope="module")
def walk_trace(simulated_walk):
    algo = _algo(RAW)
    return algo, finalise_calls(algo, simulated_walk[0])


# ---------------------------------------------------------------------------------------------------------
# without gpsim: the model's side and the assembly's constants


def test_trace_is_the_kernels_run(simulated_walk, walk_trace):
    """The traced run writes exactly the records of the kernel's own run, one call per record."""
    _, tr = walk_trace
    ref = _algo(RAW).run(simulated_walk[0]).to_records(0)
    assert len(tr.e) == ref.size > 1000
    assert tr.records.tobytes() == pack_step_records(ref)
    # the inputs are the records': e is each end (16-bit), a window's start its end minus the duration
    assert np.array_equal(tr.e, tr.records["end_sample"] & 0xFFFF)
    win = tr.records["duration_samples"] > 0
    assert np.array_equal((tr.e[win] - tr.last[win]) & 0xFFFF, tr.records["duration_samples"][win])
    assert np.all(tr.m_abs >= tr.records["end_sample"])
    assert np.any(tr.flags & 128) and np.any(~tr.flags & 128)        # steps before and after the run is 2^15 old


def test_assembly_formats_are_the_models():
    text = (PIC_DIR / "step_record.asm").read_text()
    found = {m.group(1): int(m.group(2)) for m in re.finditer(r"^F_(\w+)_BITS\s+equ\s+\.(\d+)", text, re.M)}
    want = {"ACC": formats.F_ACC, "LP": formats.F_LP, "FIR": formats.F_FIR, "POS2": formats.F_POS2,
            "EXC": formats.F_EXC, "EXC2": formats.F_EXC2, "TWO_LEN": formats.F_TWO_LEN, "STEP": formats.F_STEP,
            "K": formats.F_K, "K4": formats.F_K4, "ROOT": formats.F_ROOT, "M5": formats.F_M5}
    assert found == want
    ram = (PIC_DIR / "step_record_ram.inc").read_text()
    assert int(re.search(r"^CFG_W3\s+equ\s+\.(\d+)", ram, re.M).group(1)) == gs.CFG_W3
    flags = {m.group(1): int(m.group(2)) for m in re.finditer(r"^SF_(\w+)\s+equ\s+(\d+)", ram, re.M)}
    assert {k: 1 << v for k, v in flags.items()} == {f.name: int(f) for f in StepFlag if f.name in flags}
    assert len(flags) == 6


def test_config_bytes_layout_and_limits():
    algo = _algo(EXTREME)
    b = gs.config_bytes(algo.config.cfg_i, algo.config.cfg_v)
    c = algo.config.counts
    assert len(b) == gs.CFG_W3 + 2 * (c.r3 + c.r10 + c.r5 + 3) <= 256
    assert b[:8] == [c.r3, c.r10, c.r5, c.max_step, c.hs_before, c.hs_after, c.hs_delay, c.to_span]
    assert b[16] | b[17] << 8 == EXTREME.raw["leg_length_q15"]              # 2 l in UQ2.14 = l in UQ1.15
    fast = OnlineStepAlgorithm(sampling_rate_hz=100.0, step_config=RAW)           # r3 = 18: no room
    with pytest.raises(ValueError, match="RAM map holds"):
        gs.config_bytes(fast.config.cfg_i, fast.config.cfg_v)


# ---------------------------------------------------------------------------------------------------------
# gpsim


@needs_gpsim
def test_walk_records_identical(walk_trace):
    """The first 40 steps and 40 steps of the run after it is 2^15 samples old (F_OLD: indices may wrap), every
    byte of every record, and the state each call leaves."""
    algo, tr = walk_trace
    old = np.flatnonzero(tr.flags & 128)
    pick = np.concatenate([np.arange(40), old[:40]])
    v = gs.compare(tr.subset(pick), algo.config)
    assert v.summary() == "step records       80 of 80 identical"
    assert v.identical and v.state_identical
    assert np.all(v.pic_cycles > 10_000)
    assert v.bench.gpsim_runs >= 2 and v.bench.ram_bytes == {"bank 2": 32, "bank 3": 32, "bank 0 alias": 6}


@needs_gpsim
@pytest.mark.parametrize("cfg, flag", [(EXTREME, StepFlag.SATURATED), (SHORT_LEG, StepFlag.IMPOSSIBLE)])
def test_saturations_and_impossible_steps_identical(cfg, flag):
    algo = _algo(cfg)
    tr = finalise_calls(algo, _stomping())
    f = tr.records["flags"]
    assert np.count_nonzero(f & flag) > 50                           # the path is exercised
    if flag == StepFlag.SATURATED:
        assert np.any((tr.sticky == 0) & ((f & flag) != 0))          # saturated inside the step itself
    v = gs.compare(tr, algo.config)
    assert v.identical, v.summary()


@needs_gpsim
def test_a_broken_rounding_is_caught_and_named(walk_trace):
    algo, tr = walk_trace
    src = (PIC_DIR / "step_record.asm").read_text()
    bad = src.replace("        movlw   F_K_BITS\n        call    ushr_r", "        movlw   F_K_BITS - 1\n        call    ushr_r")
    assert bad != src
    v = gs.compare(tr.subset(np.arange(1, 6)), algo.config, overrides={"step_record.asm": bad})
    assert not v.identical and v.n_identical == 0
    d = v.differences[0]
    assert d.step == 0 and d.field == "length_m1_q14"
    assert d.pic in (2 * d.model, 2 * d.model - 1, 65535)
    assert str(d).startswith(f"step 0 (end_sample {int(tr.records['end_sample'][1])}): length_m1_q14 is ")


@needs_gpsim
def test_a_broken_crc_is_caught(walk_trace):
    algo, tr = walk_trace
    src = (PIC_DIR / "step_record.asm").read_text()
    bad = src.replace("        movlw   0x21\n        xorwf   TMP0, F", "        movlw   0x23\n        xorwf   TMP0, F")
    assert bad != src
    v = gs.compare(tr.subset(np.arange(3)), algo.config, overrides={"step_record.asm": bad})
    assert [d.field for d in v.differences] == ["record_crc"] * 3
    assert STEP_RECORD_OFFSETS["record_crc"] == (18, 2)


def test_stack_levels_counts_every_path():
    """A CALL adds a level, a GOTO does not, a skip takes both ways (hand-assembled words)."""
    mem = {0: 0x2005, 1: 0x1803, 2: 0x2008, 3: 0x0008, 5: 0x2006, 6: 0x0008, 8: 0x2009, 9: 0x200A, 10: 0x0008}
    assert gs.stack_levels(mem, 0) == 4               # 0 -> (skip) CALL 8 -> CALL 9 -> CALL 10
    assert gs.stack_levels(mem, 5) == 2
    with pytest.raises(ValueError, match="computed jump"):
        gs.stack_levels({0: 0x0782}, 0)               # ADDWF PCL, F


@needs_gpsim
def test_finalise_stays_within_four_stack_levels(walk_trace):
    """finalise's deepest path, kernels included, is 4 levels (its own return address included); a helper one
    level deeper is found. (gpsim 0.31 neither stops nor warns at a 16F877 stack overflow: the bound is static,
    over the assembled program's every path.)"""
    algo, tr = walk_trace
    sub = tr.subset(np.arange(1, 3))
    bench = gs.run_bench(sub, algo.config.cfg_i, algo.config.cfg_v, calibrated=False)
    assert bench.stack_levels == 4
    src = (PIC_DIR / "step_record.asm").read_text()
    deeper = src.replace("        call    pendulum\n", "        call    pendulum_deeper\n", 1) + \
        "\npendulum_deeper:\n        call    pendulum\n        return\n"
    assert gs.finalise_stack_levels() == 4
    assert gs.finalise_stack_levels(overrides={"step_record.asm": deeper}) == 5
    with pytest.raises(PicError):                  # and in gpsim the 9th return address is lost: it derails
        gs.run_bench(sub, algo.config.cfg_i, algo.config.cfg_v, calibrated=False,
                     overrides={"step_record.asm": deeper}, timeout_s=120)


@needs_gpsim
def test_m4_with_weinbergs_exponent(walk_trace):
    """p = 1/4 (configuration byte 2): K4 times the nearest root of the nearest root of the range, as kernel.py
    computes it for M4_EXPONENT_EIGHTHS = 2 (written here from ``arithmetic`` on the model's ranges)."""
    algo, tr = walk_trace
    sub = tr.subset(np.arange(1, 21))
    bench = gs.run_bench(sub, algo.config.cfg_i, algo.config.cfg_v, calibrated=False, m4_eighths=2)
    k4 = int(algo.config.cfg_v[kernel.CV["K4"]])
    cnt = new_counters()
    want = []
    for rng in sub.extras[:, 3].tolist():
        root2 = ar.sqrt(rng, formats.F_LP, formats.F_ROOT, True, cnt)
        root4 = ar.sqrt(root2, formats.F_ROOT, formats.F_ROOT, True, cnt)
        want.append(ar.mul(k4, formats.F_STEP, root4, formats.F_ROOT, formats.F_STEP, formats.U16, cnt))
    got = bench.records[:, 14].astype(int) | bench.records[:, 15].astype(int) << 8
    assert got.tolist() == want
    model = sub.records.view(np.uint8).reshape(-1, 20)
    assert np.array_equal(bench.records[:, :14], model[:, :14]) and np.array_equal(bench.records[:, 16:18],
                                                                                   model[:, 16:18])


def _ipol_codes(shared_data, tmp_path, name: str):
    from gaitlog.host.cli import main
    from gaitlog.host.files.decode import decode_file

    trial = shared_data / "ipol-lowerback-dev" / "GaitData" / f"{name}_lb.txt"
    if not trial.exists():
        pytest.skip(f"{trial} not present")
    image = tmp_path / f"{name}.glimg"
    assert main(["record", "--motion", "replay", str(trial), "--steps", "off", "--start-time", "0",
                 "--out", str(image), "-q"]) == 0
    rec = decode_file(image)
    assert rec.sampling_rate_hz == 50.0 and np.all(rec.valid)
    return rec.codes, int(rec.sample_numbers[0])


@needs_gpsim
@pytest.mark.parametrize("name", ["1-1", "6-5"])
def test_ipol_trials_replayed_at_50_hz(shared_data, tmp_path, name):
    """Every record of the trial, the model's scratch ring as large as the 24xx256's (16,384 samples)."""
    codes, first = _ipol_codes(shared_data, tmp_path, name)
    v = gs.verify_steps(gs.with_scratch_ring(_algo(RAW)), codes, first_sample_number=first)
    assert v.n_steps > 30
    assert v.identical, v.summary()


@needs_gpsim
def test_ipol_trial_with_the_emulators_scratch_ring(shared_data, tmp_path):
    """The emulator's own 256-sample ring (online._scratch_size) holds what every step of this trial reads: its
    latest step is finalised 24 samples after its foot-flat, and a window longer than max_step reads nothing."""
    codes, first = _ipol_codes(shared_data, tmp_path, "6-5")
    v = gs.verify_steps(_algo(RAW), codes, first_sample_number=first)
    assert v.identical, v.summary()


@needs_gpsim
def test_the_program_memory_reader_gives_the_same_records(walk_trace):
    """The test build's scratch reader (a table in program memory) and the I2C bus read the same samples."""
    algo, tr = walk_trace
    sub = tr.subset(np.arange(1, 11))
    cfg = algo.config
    i2c = gs.run_bench(sub, cfg.cfg_i, cfg.cfg_v, calibrated=False)
    table = gs.run_bench(sub, cfg.cfg_i, cfg.cfg_v, calibrated=False, reader="table")
    assert np.array_equal(i2c.records, table.records)
    assert np.array_equal(i2c.records, sub.records.view(np.uint8).reshape(-1, 20))
    assert np.all(i2c.cycles > table.cycles + 50_000)                  # the bus costs: ~135 cycles a byte
    with pytest.raises(ValueError, match="reader"):
        gs.run_bench(sub, cfg.cfg_i, cfg.cfg_v, reader="spi")


@needs_gpsim
def test_no_heel_strike_in_a_young_run():
    """A heel strike before sample 0 (a young run, hs_delay of 1.2 s): -128 and NO_HEEL_STRIKE, as the model."""
    algo = _algo(RAW)
    algo.config.cfg_i[kernel.CI_HS_DELAY] = 60
    tr = finalise_calls(algo, _stomping(1200))
    assert np.count_nonzero(tr.records["flags"] & StepFlag.NO_HEEL_STRIKE) >= 2
    assert np.all(tr.records["heel_strike_samples"][(tr.records["flags"] & StepFlag.NO_HEEL_STRIKE) != 0] == -128)
    v = gs.compare(tr, algo.config)
    assert v.identical, v.summary()


@needs_gpsim
def test_across_the_16_bit_index_wrap(simulated_walk):
    """A run of 79,844 samples (the walk twice): the steps around sample 65,536, where e, s and m wrap (one
    window starts before the wrap and ends after it)."""
    codes = np.concatenate([simulated_walk[0], simulated_walk[0]])
    algo = gs.with_scratch_ring(_algo(RAW))
    tr = finalise_calls(algo, codes)
    near = np.flatnonzero((tr.m_abs >= 65536 - 200) & (tr.m_abs < 65536 + 600))
    sub = tr.subset(near)
    assert np.any(sub.last > sub.e) and np.any(sub.m < sub.e) and near.size > 10
    v = gs.compare(sub, algo.config)
    assert v.identical, v.summary()
