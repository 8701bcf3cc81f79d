"""The logger's per-sample path in PIC16 assembly (firmware_sim/pic/logger.asm) in gpsim, against the model.

Independent truths: the P32 words of ``gaitlog.protocol.packing`` (its own golden vectors in PROTOCOL.md), the
fixed-point kernel's state after its first sample (for the probe), the kernel itself fed one sample at a time
(steps 4-5: y3, the detector's state, finalise's calls), the datasheet's timer and ADC arithmetic, and
deliberately broken copies of the assembly that must be caught.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from gaitlog.firmware_sim.algorithms.formats import F_ACC, F_GRAV
from gaitlog.firmware_sim.algorithms.probe import (
    calibrated_axes,
    front_operation_counts,
    gravity_states,
    vertical_acceleration,
)
from gaitlog.firmware_sim.budget import adc_acquisition_s, adc_tad_s
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.packing import FLAG_MARK, FLAG_SESSION_START
from gaitlog.protocol.steps import STEP_RECORD_DTYPE

#: Device calibration slots (PROTOCOL.md 2.1), as the firmware receives them: the nominal map, a plausible
#: device (offsets off 512, scale and cross-axis terms), and one that saturates the offset subtraction, the
#: 32-bit sums and the 16-bit result.
SLOTS = {
    "nominal": CalibrationSlot.nominal(10),
    "device": CalibrationSlot(np.array([505.25, 519.5, 498.0]),
                              np.array([[0.0039, 0.0001, -0.00005], [0.00002, 0.00385, 0.0001],
                                        [-0.0001, 0.00003, 0.00395]])),
    "extreme": CalibrationSlot(np.array([-1024.0, 1023.96875, 3.125]),
                               np.array([[0.99, 0.99, 0.99], [-0.99, -0.99, -0.99], [0.0, -0.0001, 0.99]])),
}
CALS = {k: CalibrationQ.from_protocol(v) for k, v in SLOTS.items()}

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")


def test_timer_setup_is_the_sample_period():
    t = gl.timer_setup(50.0)
    assert (t.prescale, t.ccpr1, t.period_cycles) == (2, 46080, 92160)
    assert gl.timer_setup(100.0).prescale == 1
    with pytest.raises(ValueError, match="whole number"):
        gl.timer_setup(71.0)                     # 64,901.4 cycles
    with pytest.raises(ValueError, match="do not fit"):
        gl.timer_setup(8.0)                      # 576,000 cycles > 8 x 65,535


def test_acquisition_delay_covers_tacq_and_2_tad():
    need = (adc_acquisition_s(32e3) + 2 * adc_tad_s(18.432e6)) * 18.432e6 / 4
    n = gl.acquisition_loops()
    assert 3 * n + 1 >= need > 3 * (n - 1) + 1


@pytest.mark.parametrize("name", SLOTS)
def test_probe_is_the_kernels_step_1(name):
    """The kernel's gravity state after a run's first sample is its calibrated axes in the gravity format."""
    from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
    from gaitlog.firmware_sim.algorithms.state import G1
    from gaitlog.protocol.steps import StepConfig

    rng = np.random.default_rng(5)
    codes = np.vstack([rng.integers(0, 1024, (40, 3)), [[0, 0, 0], [1023, 1023, 1023], [512, 512, 512]]])
    algo = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
                                                                              foot_length_m=0.26),
                               calibration=SLOTS[name])
    probe = calibrated_axes(codes, CALS[name])
    if name == "extreme":
        assert np.any(np.abs(probe) == 32767) and np.any(probe == -32768)      # the saturations are exercised
    for i, c in enumerate(codes):
        algo.reset()
        try:
            algo.feed(c.reshape(1, 3))
        except ValueError:                  # the extreme slot: step 3 refuses |g| beyond 16 bits, after step 2
            assert name == "extreme"
        assert np.array_equal(algo._st_v[G1:G1 + 3], probe[i] << (F_GRAV - F_ACC)), i


def test_gravity_and_a_v_probes_are_the_kernels_steps_2_3(simulated_walk):
    """The kernel's G1, G2 after 1, 2, 3, 50, 64, 65 and 900 samples of a walk, and the a_v it stored in its
    scratch ring for the last of them, are the probes'."""
    from gaitlog.firmware_sim.algorithms import kernel
    from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
    from gaitlog.firmware_sim.algorithms.state import G1, G2
    from gaitlog.protocol.steps import StepConfig

    codes = simulated_walk[0][:900]
    algo = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
                                                                              foot_length_m=0.26),
                               calibration=SLOTS["device"])
    shift = int(algo.config.cfg_i[kernel.CI_G_SHIFT])
    f = calibrated_axes(codes, CALS["device"])
    probe = gravity_states(f, shift)
    probe_av = vertical_acceleration(f, probe[:, 3:], int(algo.config.cfg_v[kernel.CV_G_MIN]))
    done = 0
    for upto in (1, 2, 3, 50, 64, 65, 900):
        algo.feed(codes[done:upto], offset=done)
        done = upto
        state = np.concatenate([algo._st_v[G1:G1 + 3], algo._st_v[G2:G2 + 3]])
        assert np.array_equal(state, probe[upto - 1]), upto
        assert algo._scr[(upto - 1) % algo._scr.shape[0]] == probe_av[upto - 1], upto   # the scratch ring: a_v
    assert shift == 6 and not np.array_equal(probe[-1], probe[-2]) and np.count_nonzero(probe_av) > 800
    assert algo.config.cfg_v[kernel.CV_G_MIN] == gl.PicLogger().min_gravity_raw


@needs_gpsim
@pytest.mark.parametrize("name", SLOTS)
def test_random_codes_identical(name):
    rng = np.random.default_rng(11)
    n = 700
    codes = rng.integers(0, 1024, (n, 3))
    codes[:4] = [[0, 0, 0], [1023, 1023, 1023], [1023, 0, 1023], [0, 1023, 0]]
    flags = np.zeros(n, np.int64)
    flags[[0, 450]] |= FLAG_SESSION_START          # two runs: two gpsim runs, each from START
    flags[[3, 31, 32, 333, 451]] |= FLAG_MARK       # the button on RB0 (a digital stimulus)
    # the extreme slot's |g| exceeds the model's 16-bit divisor: the model refuses a_v there, so it and steps 4-5
    # are left out
    r = gl.verify(codes, flags, CALS[name], a_v=name != "extreme")
    want = [("packed words", n, n), ("calibrated axes", n, n), ("gravity", n, n)]
    want += [("a_v", n, n), ("y3", n, n), ("detector", n, n)] if name != "extreme" else []
    assert [(s.name, s.n_identical, s.n_compared) for s in r.stages[:len(want)]] == want, r.format_table()
    assert r.identical, r.format_table()
    assert r.period_cycles == 92160
    assert r.acquisition_cycles_min >= r.acquisition_cycles_needed
    # a step record takes several sample periods; the page buffer lets the main loop fall up to 32 behind
    assert 0 < r.cycles["total in assembly"]["mean"] < 92160
    assert r.backlog_max < gl.PAGE_WORDS
    assert r.memory.ram_total_bytes <= 368 and r.memory.program_words <= 8192
    assert "of 700 samples identical" in r.format_table()


@needs_gpsim
def test_every_code_converts_exactly():
    """gpsim's converter, driven by the harness's analog stimuli, gives every one of the 1,024 codes on each
    channel (the packed words against pack_words: the codes themselves)."""
    k = np.arange(1024)
    codes = np.stack([k, 1023 - k, (7 * k + 3) % 1024], axis=1)
    flags = np.zeros(1024, np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["nominal"], a_v=False)
    assert r.stages[0].name == "packed words" and r.stages[0].identical, r.format_table()


@needs_gpsim
def test_simulated_walk_identical(simulated_walk):
    codes = simulated_walk[0][:1500]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["device"])         # one run, one gpsim run
    assert r.identical, r.format_table()
    assert [s.n_compared for s in r.stages[:6]] == [1500] * 6
    calls = r.stages[6]
    assert calls.name == "finalise calls" and calls.n_compared > 25        # a walk's foot-flats, each one compared
    records = r.stages[7]                   # each call's 20-byte record, from the a_v the firmware wrote itself
    assert records.name == "step records" and records.n_compared == calls.n_compared and records.identical
    assert f"{records.n_compared} of {records.n_compared} records identical" in r.format_table()
    assert r.backlog_max < gl.PAGE_WORDS
    f = calibrated_axes(codes, CALS["device"])
    a_v = vertical_acceleration(f, gravity_states(f, 6)[:, 3:], gl.PicLogger().min_gravity_raw)
    assert np.count_nonzero(a_v) > 1400 and a_v.max() > 2000 and a_v.min() < -2000     # a walk, not zeros
    assert "finalise calls" in r.format_table() and r.cycles["step 5 (foot-flat detector)"]["worst"] > 0


@needs_gpsim
def test_a_broken_assembly_is_named(tmp_path, monkeypatch):
    """The S and M flag bits swapped in the packing: the first sample's byte 3 differs, and verify says so."""
    src = gl.LOGGER_ASM.read_text()
    assert src.count("bsf     T_L, 6") == 1
    bad = tmp_path / "logger.asm"
    bad.write_text(src.replace("bsf     T_L, 6", "bsf     T_L, 7"))
    monkeypatch.setattr(gl, "LOGGER_ASM", bad)
    codes = np.full((40, 3), 512)
    flags = np.zeros(40, np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, nominal_calibration_q())
    packed = r.stages[0]
    assert not r.identical and packed.n_identical == 39 and all(s.identical for s in r.stages[1:])
    assert packed.first_difference == {"sample": 0, "field": "byte 3", "gpsim": 0x80 | 0x20, "model": 0x40 | 0x20}
    assert "first difference: sample 0, byte 3" in r.format_table()


@needs_gpsim
def test_ipol_trial_identical(shared_data):
    """An IPOL trial replayed at 50 Hz through the logger (10-bit codes): every stage identical, finalise's
    calls and the step records too, STOP's included. (Under the current stop rule this trial's calls include no weak step.)"""
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.replay import Replay
    from gaitlog.firmware_sim.algorithms.probe import detector_trace
    from gaitlog.host.files.inputs import read_acceleration

    with pytest.warns(Warning, match="missing"):
        data = read_acceleration(shared_data / "ipol-lowerback-dev" / "GaitData" / "1-1_lb.txt")
    src = Replay.from_samples(data.g(), data.valid, sampling_rate_hz=data.sampling_rate_hz, source=data.source)
    codes = Logger().record(src).codes.astype(np.int64)
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, nominal_calibration_q(), source="1-1")
    assert r.identical, r.format_table()
    assert len(codes) > 1400 and r.stages[6].n_compared > 25
    assert r.stages[7].name == "step records" and r.stages[7].n_compared == r.stages[6].n_compared
    trace = detector_trace(codes, nominal_calibration_q())
    assert trace.calls.shape[0] == r.stages[7].n_compared == 36
    assert trace.calls[-1, 0] == len(codes)                  # the 36th is STOP's (kernel.flush), compared too
    assert len(r.stop_cycles) == 1 and r.stop_cycles[0] == pytest.approx(111_722, rel=0.01)      # measured
    assert "STOP (measured): a pending step finalised at the end of 1 run(s)" in r.format_table()


@needs_gpsim
def test_a_broken_detector_is_named(simulated_walk, monkeypatch):
    """The amplitude's exponential mean one shift too slow in steps.asm: y3 stays identical, the detector
    differs at the second confirmed peak, and verify names the sample and the variable (AMP)."""
    real = gl.copy_sources
    src = (gl.PIC_DIR / "steps.asm").read_text()
    marker = "        movlw   AMP_SHIFT\n"
    assert src.count(marker) == 1

    def broken(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / "steps.asm").write_text(src.replace(marker, "        movlw   AMP_SHIFT + 1\n"))

    monkeypatch.setattr(gl, "copy_sources", broken)
    codes = simulated_walk[0][:700]                 # the walk's first confirmed peaks come after 11 s
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["device"])
    by = {s.name: s for s in r.stages}
    assert all(by[k].identical for k in ("packed words", "calibrated axes", "gravity", "a_v", "y3")), r.format_table()
    d = by["detector"].first_difference
    assert not r.identical and d is not None and d["field"] == "amp", r.format_table()
    assert f"first difference: sample {d['sample']}, {d['field']}" in r.format_table()


@needs_gpsim
def test_lean_run_gives_the_calls_and_final_state(simulated_walk):
    """run_calls (the lean log for long runs) against the kernel fed one sample at a time."""
    from gaitlog.firmware_sim.algorithms.probe import detector_trace

    codes = simulated_walk[0][:800]
    calls, state, records = gl.PicLogger().run_calls(codes, CALS["device"])
    trace = detector_trace(codes, CALS["device"])
    assert calls.shape[0] >= 3 and np.array_equal(calls, trace.calls)
    assert np.array_equal(state, trace.state[-1])
    assert records.shape == trace.records.shape and np.array_equal(records, trace.records)


#: The wrap runs: 1,200 samples before the edge, 2,500 samples of walking.
WRAP_LEAD, WRAP_SAMPLES = 1200, 2500


def _wrap_run(walk, edge):
    from gaitlog.firmware_sim.algorithms.probe import detector_trace

    codes = walk[0][550:550 + WRAP_SAMPLES]              # walking from the first steps on
    run = gl.PicLogger().run_calls(codes, CALS["nominal"], start_n=edge - WRAP_LEAD)
    trace = detector_trace(codes, CALS["nominal"], start_n=edge - WRAP_LEAD)
    return run, trace


def _windows(records: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each record's window as the chip counts it (from N = 0 at START): its first and its end sample."""
    rec = np.frombuffer(records.tobytes(), STEP_RECORD_DTYPE)
    end = rec["end_sample"].astype(np.int64)
    return end - rec["duration_samples"].astype(np.int64), end


@needs_gpsim
@pytest.mark.parametrize("crossing", ["F_OLD", "wrap"])
def test_ring_mode_across_2_15_and_the_16_bit_wrap(simulated_walk, crossing):
    """A run that starts 1,200 samples before 2^15 (F_OLD: N may wrap from then on) or before 2^16 (N and the
    indices wrap) and walks on for 2,500 samples: every finalise call, every step record byte for byte (one of
    them with a window across the wrap), and the final detector state are the kernel's started at the same N
    (the test build's START_N), across the crossing; the first run also has a window across the scratch ring's
    end (the run's sample 32,512 from start page 0). Every record reads only a_v of its own run: the first ends
    62 samples after START, and its reads reach back hs_before + r5 = 15."""
    from gaitlog.firmware_sim.algorithms.probe import detector_trace
    from gaitlog.firmware_sim.algorithms.kernel import SCRATCH_RING_SAMPLES
    from gaitlog.firmware_sim.algorithms.state import F_OLD, INDEX_HALF, INDEX_MODULUS

    edge = INDEX_HALF if crossing == "F_OLD" else INDEX_MODULUS
    (calls, state, records), trace = _wrap_run(simulated_walk, edge)
    after = trace.calls[:, 0] >= WRAP_LEAD
    assert after.sum() > 20 and (~after).sum() > 20
    assert np.all(trace.calls[after, 4] & F_OLD)
    first, end = _windows(trace.records)
    if crossing == "wrap":
        assert np.any(trace.calls[:, 1] < trace.calls[:, 2])          # e wrapped past 0, its s did not
        assert np.any((first < edge) & (end >= edge))                 # a window across the wrap
    else:
        assert not np.any(trace.calls[~after, 4] & F_OLD)
        ring_end = SCRATCH_RING_SAMPLES                              # start page 0: the run's sample 32,512
        assert np.any((first < ring_end) & (end > ring_end))          # a window across the scratch ring's end
    assert calls.shape == trace.calls.shape, (calls.shape, trace.calls.shape)
    bad = np.flatnonzero(np.any(calls != trace.calls, axis=1))
    assert bad.size == 0, (calls[bad[:1]], trace.calls[bad[:1]])
    assert np.array_equal(state, trace.state[-1])
    assert records.shape == trace.records.shape and records.shape[0] > 40, (records.shape, trace.records.shape)
    bad = np.flatnonzero(np.any(records != trace.records, axis=1))
    assert bad.size == 0, (bad[:3], records[bad[:1]], trace.records[bad[:1]])
    assert first.min() >= edge - WRAP_LEAD + 15                       # no read before START


def test_scratch_offset_is_the_models_placement():
    """The assembly's ring offset K puts the 16-bit index j of the run's sample f at the model's ring sample
    (S + f) mod 32,512: at K + j, plus 32,512 when that is negative (a sample written before the ring's last
    wrap), for every sample up to 16,000 back from the newest, across the ring's end and the index's wrap."""
    from gaitlog.firmware_sim.algorithms.kernel import SCRATCH_RING_SAMPLES, scratch_ring_sample

    for start in (0, 64 * 500, 64 * 507, 123_456_789):
        for newest in (0, 5000, 32_511, 65_535, 65_536, 100_000):
            k = gl.scratch_offset(start, newest)
            f = np.arange(max(0, newest - 16_000), newest + 1)
            raw = (k + (f & 0xFFFF)) & 0xFFFF
            pos = np.where(raw & 0x8000, (raw + SCRATCH_RING_SAMPLES) & 0xFFFF, raw)
            assert np.array_equal(pos, [scratch_ring_sample(start, x) for x in f]), (start, newest)


#: A run of the walk whose start page puts the scratch ring's end inside a step's window.
RING_END_SAMPLES = 800


def _ring_end_run(walk):
    """The walk's first samples, with the run's start page chosen so that the ring's end (ring sample 32,512)
    falls on a page boundary (a multiple of 64 samples) well inside the window of the first record that has
    one (at 50 Hz: record 1, window 543-588, the ring's end at 576, start page 499): its passes read across it."""
    from gaitlog.firmware_sim.algorithms.kernel import SCRATCH_RING_SAMPLES, scratch_ring_sample
    from gaitlog.firmware_sim.algorithms.probe import detector_trace

    codes = walk[0][:RING_END_SAMPLES]
    trace = detector_trace(codes, CALS["device"])
    first, end = _windows(trace.records)
    inside = [(i, (e - 3) // 64 * 64) for i, (a, e) in enumerate(zip(first, end)) if (e - 3) // 64 * 64 > a + 2]
    assert inside, (first, end)
    rec, wrap = inside[0]
    start = SCRATCH_RING_SAMPLES - wrap                                  # S + wrap = 32,512
    assert scratch_ring_sample(start, wrap) == 0 and scratch_ring_sample(start, wrap - 1) == SCRATCH_RING_SAMPLES - 1
    return codes, trace, start, rec, wrap


@needs_gpsim
def test_the_ring_wraps_at_32512_inside_a_steps_window(simulated_walk, monkeypatch):
    """The run's start page puts the ring's end inside a step's window: the records are the model's, byte for
    byte. With the reader's reopening at the ring's end removed, the sequential read runs on past it (into the
    header slots on a 24LC1025; the 24xx256 rolls over to byte 0x7E00) and that record differs, with none but
    those whose reads come near the ring's end."""
    codes, trace, start, rec, wrap = _ring_end_run(simulated_walk)
    run = gl.PicLogger().run_calls(codes, CALS["device"], run_start_sample=start)
    assert np.array_equal(run.calls, trace.calls) and run.records.shape == trace.records.shape
    bad = np.flatnonzero(np.any(run.records != trace.records, axis=1))
    assert bad.size == 0, (bad, rec)

    real = gl.copy_sources
    src = (gl.PIC_DIR / "step_record.asm").read_text()
    reopen = "        call    scr_stop\n        goto    scr_at\n"
    assert src.count(reopen) == 1

    def no_reopen(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / "step_record.asm").write_text(src.replace(reopen, ""))

    monkeypatch.setattr(gl, "copy_sources", no_reopen)
    broken = gl.PicLogger().run_calls(codes, CALS["device"], run_start_sample=start)
    assert np.array_equal(broken.calls, trace.calls)
    bad = np.flatnonzero(np.any(broken.records != trace.records, axis=1))
    first, end = _windows(trace.records)
    # the reads of a record reach a filter radius (r3 = 9) and the heel strike's search beyond its window
    near = np.flatnonzero((first - 30 < wrap) & (end + 30 >= wrap))
    assert rec in bad and set(bad.tolist()) <= set(near.tolist()), (bad, near, rec)


def test_conversions_outside_their_stimulus_are_refused():
    p = gl.timer_setup(50.0).period_cycles
    ok = np.repeat(np.arange(4) + 1, 3) * p + np.tile([300, 500, 700], 4)
    gl._check_conversions(ok, 4, p)
    with pytest.raises(gl.PicError, match="sample 2's conversion"):
        gl._check_conversions(np.where(np.arange(12) == 7, ok + p, ok), 4, p)
    with pytest.raises(gl.PicError, match="converted 11 times"):
        gl._check_conversions(ok[:11], 4, p)
    assert math.isclose(p, 92160)


@needs_gpsim
@pytest.mark.parametrize("name", ["nominal", "device"])
def test_budget_model_within_10_percent_of_the_chip_on_steps_1_to_3(simulated_walk, name):
    """The model's mean estimate of steps 1-3 (primitive calls at the kernels' mean costs) against gpsim's
    measurement of the same samples, with the nominal calibration (zero cross-axis terms) and a device's; the
    worst-case cost table bounds every measured sample, and priced at it the mean is off by more than 10 %."""
    from gaitlog.firmware_sim.fixedpoint import CYCLES, OPS
    from gaitlog.firmware_sim.pic.chip_budget import chip_budget

    codes = simulated_walk[0][:1000]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    b = chip_budget(codes, flags, CALS[name])
    assert b.measured and b.memory.ram_total_bytes <= 368 and b.memory.program_words <= 8192
    steps = b.part("steps 1-3")
    measured, estimated = steps.measured_cycles.mean(), steps.estimated_cycles.mean()
    assert abs(estimated - measured) <= 0.10 * measured, (estimated, measured)
    total = b.part("total in assembly")
    assert np.array_equal(total.measured_cycles, b.part("sampling interrupt").measured_cycles
                          + b.part("steps 1-5").measured_cycles)
    assert 0 < (b.part("sampling interrupt").measured_cycles + steps.measured_cycles).max() \
        < gl.timer_setup(50.0).period_cycles
    s1, s23 = front_operation_counts(codes, CALS[name], 6, gl.PicLogger().min_gravity_raw)
    worst = np.array([CYCLES[k] for k in OPS])
    assert np.all(s1 @ worst >= b.part("step 1 (calibration)").measured_cycles)
    assert np.all(s23 @ worst >= b.part("steps 2-3 (gravity, a_v)").measured_cycles)
    assert ((s1 + s23) @ worst).mean() > 1.10 * measured


def test_budget_without_gpsim_gives_the_models_figures_marked_estimated(simulated_walk, monkeypatch):
    from gaitlog.firmware_sim.budget import interrupt_cycles_estimate
    from gaitlog.firmware_sim.pic.chip_budget import chip_budget

    monkeypatch.setattr(gl, "missing_tools", lambda: "gpsim not installed")
    b = chip_budget(simulated_walk[0][:200], np.zeros(200, np.int64), CALS["nominal"])
    assert not b.measured and b.memory is None
    doc = b.to_dict()
    assert doc["measured"] is False and doc["why_not_measured"] == "gpsim not installed"
    interrupt = doc["cycles_per_sample"]["sampling interrupt"]
    assert set(interrupt) == {"estimated"} and interrupt["estimated"]["mean"] == pytest.approx(interrupt_cycles_estimate())
    assert "not measured (gpsim not installed)" in b.lines()[0]


def test_chip_budget_backlog_is_lindleys_recursion():
    """The worst backlog against a loop over the samples (the independent form of the recursion)."""
    from gaitlog.firmware_sim.pic.chip_budget import STEPS, ChipBudget, CyclePart

    t = np.array([50.0, 150.0, 180.0, 20.0, 90.0, 300.0, 10.0])
    parts = tuple(CyclePart(n, t if n == "total in assembly" else np.zeros_like(t), t) for n in STEPS)
    b = ChipBudget("x", t.size, 50.0, parts, None, None, period_cycles=100.0)
    owed = worst = 0.0
    for x in t:
        owed = max(0.0, owed + x - 100.0)
        worst = max(worst, owed)
    assert b.worst_backlog_cycles == worst == 240.0


@needs_gpsim
def test_a_broken_scratch_write_is_caught(simulated_walk, monkeypatch):
    """scr_write puts each page of a_v one sample late in the ring: steps 1-5 and finalise's calls stay identical,
    the step records (read back from what the firmware wrote) differ, and verify names the record and field."""
    real = gl.copy_sources
    src = (gl.PIC_DIR / "step_join.asm").read_text()
    marker = "; j's place in the line: (LINE_POS - COUNT) mod LINE_LEN\n        sublw   LINE_LEN\n"
    assert src.count(marker) == 1

    def broken(build_dir, main_asm):          # the data one place earlier in the line: a_v[j - 1] at j
        real(build_dir, main_asm)
        (build_dir / "step_join.asm").write_text(src.replace(marker, marker.replace("LINE_LEN\n", "LINE_LEN - 1\n")))

    monkeypatch.setattr(gl, "copy_sources", broken)
    codes = simulated_walk[0][:900]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["device"])
    by = {s.name: s for s in r.stages}
    assert all(s.identical for s in r.stages if s.name != "step records"), r.format_table()
    d = by["step records"].first_difference
    assert not r.identical and d is not None and d["record"] == 0, r.format_table()
    assert f"first difference: record 0 (end sample {d['sample']}), {d['field']}" in r.format_table()


@needs_gpsim
def test_stop_between_two_runs(simulated_walk):
    """Two runs (S at 600), each in its own gpsim run: the first ends with its foot-flat at 588 pending, the
    second (walking on from its START) with one too. Each STOP's call carries its run's end (600, 900) and its
    record is the model's (kernel.flush); the first has a window (e - s = 45 samples): the whole step record,
    after the sampling stopped."""
    from gaitlog.firmware_sim.algorithms.probe import detector_trace

    codes = simulated_walk[0][:900]
    flags = np.zeros(len(codes), np.int64)
    flags[[0, 600]] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["device"])
    assert r.identical, r.format_table()
    trace = detector_trace(codes, CALS["device"], run_starts=[0, 600])
    assert trace.calls[:2, 0].tolist() == [569, 600] and trace.calls[1, 1:3].tolist() == [588, 543]
    assert trace.calls[-1, 0] == 900 and r.stages[7].n_identical == r.stages[7].n_compared == 12
    assert r.stop_cycles == (pytest.approx(631_072, rel=0.01), pytest.approx(487_159, rel=0.01))     # measured


#: The STOP path broken two ways in steps.asm / logger.asm: (file, marker, replacement).
STOP_MUTANTS = {
    # no kernel.flush at STOP: the run's last call and record are missing on the PIC's side
    "no flush": ("logger.asm", "        call    step_flush\n", "        nop\n"),
    # STOP finalises without first writing the delay line's newest N mod FLUSH a_v to the scratch ring
    "no partial block": ("steps.asm", "        bsf     PCLATH, 3\n        call    scr_write_w\n", ""),
}


@needs_gpsim
@pytest.mark.parametrize("mutant", STOP_MUTANTS)
def test_a_broken_stop_is_named(simulated_walk, monkeypatch, mutant):
    """STOP (kernel.flush) finalises the pending foot-flat: 600 samples of the walk end 12 samples after one
    (e = 588, its record reads a_v up to the run's last sample, after the last flush at 592). Without the
    flush, the last call and record are missing and verify names them; without the partial block, the call is
    identical and the record, read from a ring that lacks samples 592-599, differs in a named field."""
    real = gl.copy_sources
    name, marker, repl = STOP_MUTANTS[mutant]
    src = (gl.PIC_DIR / name).read_text()
    assert src.count(marker) == 1

    def broken(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / name).write_text(src.replace(marker, repl))

    monkeypatch.setattr(gl, "copy_sources", broken)
    codes = simulated_walk[0][:600]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify(codes, flags, CALS["device"])
    by = {s.name: s for s in r.stages}
    table = r.format_table()
    assert all(by[k].identical for k in ("packed words", "calibrated axes", "gravity", "a_v", "y3", "detector")), table
    calls, records = by["finalise calls"], by["step records"]
    assert calls.n_compared == records.n_compared == 2 and records.n_identical == 1, table
    d = records.first_difference
    if mutant == "no flush":
        assert calls.n_identical == 1 and calls.first_difference["field"] == "call", table
        assert (d["record"], d["sample"], d["gpsim"], d["model"]) == (1, 588, "none", "a record"), table
        assert "first difference: record 1 (end sample 588), record: gpsim none, model a record" in table
        assert r.stop_cycles == ()
    else:
        assert calls.identical and (d["record"], d["sample"]) == (1, 588), table
        assert f"first difference: record 1 (end sample 588), {d['field']}: gpsim {d['gpsim']}" in table
        assert len(r.stop_cycles) == 1 and r.stop_cycles[0] > 50_000            # the step record itself


def test_page_2_renames_every_kernel_label():
    """Page 2's copy of the kernels gets its own labels: every label of the kernel files is renamed there, and
    removed again after page 2."""
    import re

    names = set(re.findall(r"^#define\s+(\w+)\s+\1_p2$", (gl.PIC_DIR / "page2_names.inc").read_text(), re.M))
    undone = set(re.findall(r"^#undefine\s+(\w+)$", (gl.PIC_DIR / "page2_names_end.inc").read_text(), re.M))
    labels = set()
    for k in ("mul", "div", "shift", "sat", "sqrt"):
        labels |= set(re.findall(r"^([A-Za-z_]\w*):?(?=\s|$)", (gl.PIC_DIR / f"{k}.asm").read_text(), re.M))
    assert labels and labels <= names and names == undone


@needs_gpsim
def test_stack_stays_within_eight_levels(tmp_path):
    """The static stack bound over every path of the production build (gpsim 0.31 does not report the 16F877's
    overflow). Each page's code calls only within its page, so each is analysed on its own; the main loop
    reaches the step record through finalise's CALL below stage_fir and confirmed (2 levels), and the
    interrupt may come on top of the deepest path."""
    from gaitlog.firmware_sim.pic import gpsim_steps as gs

    build = gl._assemble(tmp_path, gl.PicLogger()._defines(0), test=False)
    mem, sym = gs.program_words(tmp_path / "logger.hex"), build.symbols

    def levels(entry: str, page: int) -> int:
        return gs.stack_levels({a - page: w for a, w in mem.items() if page <= a < page + 0x800},
                               sym[entry] - page)

    isr = levels("isr", 0)
    step_record = levels("finalise_p2", 0x1000)
    assert (isr, step_record, levels("scr_write", 0x800)) == (2, 4, 2)
    assert 1 + levels("stage_calibrate", 0) + isr <= 8
    assert 2 + step_record + isr == 8
    # STOP: the main loop calls step_flush, which calls scr_write_w (page 1) and finalise (whose jump to the step
    # record leaves page 0). Both stubbed with a RETURN, step_flush's own paths take 2 levels; each callee then
    # stands for its real depth (its return included): the step record's 4, scr_write_w's 2.
    stubbed = {a: w for a, w in mem.items() if a < 0x800}
    stubbed[sym["finalise"]] = stubbed[sym["scr_write_w"] & 0x7FF] = 0x0008
    flush = gs.stack_levels(stubbed, sym["step_flush"])
    assert (flush, levels("scr_write_w", 0x800)) == (2, 2)
    assert (flush - 1) + max(step_record, 2) + isr == 7
