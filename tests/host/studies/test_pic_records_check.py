"""The PIC firmware's step records on every IPOL trial and on 20 simulated subjects, byte for byte against the model.

Independent truths: the fixed-point kernel (the golden model) fed each run, checked here against the kernel fed one
sample at a time (``detector_trace``, what ``gaitlog pic verify`` compares with); deliberately broken copies of the
assembly that the records-only check must catch; the page buffer's 32 samples, which a too-short sampling period
must overrun.
"""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.kernel import SCRATCH_RING_SAMPLES
from gaitlog.firmware_sim.algorithms.probe import detector_trace, step_records
from gaitlog.firmware_sim.algorithms.state import F_LAST
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.host.files.decode import decode_file
from gaitlog.host.studies.pic_records import check_records, simulated_inputs
from gaitlog.host.studies.pic_runs import assembly_input
from gaitlog.protocol.packing import FLAG_SESSION_START

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")

#: The IPOL lower-back trials of the development data in ../shared/data. Another lab's folder in the same layout
#: is checked trial for trial as well; only the counts pinned below are the development data's.
IPOL_TRIALS = 52
#: Simulated subjects (evaluate sim's population, seed 0).
SUBJECTS = 20
#: Step records compared: the IPOL trials' (81,939 samples) and the simulated subjects' (42,490 samples), as
#: many as the model makes (measured), STOP's included: 5 IPOL trials end with a pending step, no subject does.
IPOL_RECORDS, SUBJECT_RECORDS = 1941, 1216


@pytest.fixture(scope="module")
def ipol_inputs(shared_data, tmp_path_factory):
    """Every IPOL trial as ``gaitlog record --motion replay FILE --steps off --start-time 0`` stores it."""
    from gaitlog.host.cli import main

    files = sorted((shared_data / "ipol-lowerback-dev" / "GaitData").glob("*_lb.txt"))
    if not files:
        pytest.skip("no IPOL lower-back trial in ipol-lowerback-dev/GaitData")
    out = tmp_path_factory.mktemp("ipol-glimg")
    inputs = []
    for f in files:
        image = out / (f.stem + ".glimg")
        assert main(["record", "--motion", "replay", str(f), "--steps", "off", "--start-time", "0",
                     "--out", str(image), "-q"]) == 0
        inputs.append(assembly_input(decode_file(image), f.stem, None))
    return inputs


@needs_gpsim
def test_every_ipol_trial_and_20_simulated_subjects_give_the_models_records(ipol_inputs):
    """Every trial (52 in the development data) and 20 subjects through gpsim (two processes at a time), at the
    real 50 Hz period: every step record identical, STOP's included, none lost to the page buffer, and as many as
    measured."""
    subjects = simulated_inputs(SUBJECTS)
    check = check_records(ipol_inputs + subjects, workers=2)
    assert check.identical, "\n".join(check.differences())
    assert [r.period_cycles for r in check.results] == [gl.timer_setup(50.0).period_cycles] * len(check.results)
    n_ipol = len(ipol_inputs)
    ipol = sum(r.records.n_compared for r in check.results[:n_ipol])
    sim = sum(r.records.n_compared for r in check.results[n_ipol:])
    assert all(r.records.n_compared > 10 for r in check.results), [r.records.n_compared for r in check.results]
    print(f"records check: {check.n_samples:,} samples, {ipol} + {sim} records, {check.wall_s:.1f} s, "
          f"backlog at most {max(r.backlog_max for r in check.results)}")
    assert sim == SUBJECT_RECORDS
    if n_ipol == IPOL_TRIALS:       # the development data's trials
        assert ipol == IPOL_RECORDS


def test_whole_run_records_are_the_sample_at_a_time_kernels(ipol_inputs):
    """step_records (the kernel fed each run whole, then its STOP) gives detector_trace's records (one sample at
    a time, flush at each run's end), across a second START too: both runs end with a pending foot-flat, so
    each STOP's record is among them."""
    run = ipol_inputs[0]
    codes = np.concatenate([run.codes, run.codes[:700]])
    starts = [0, run.codes.shape[0]]
    whole = step_records(codes, run.calibration_q, 50.0, starts, scratch_ring=SCRATCH_RING_SAMPLES)
    trace = detector_trace(codes, run.calibration_q, 50.0, starts, scratch_ring=SCRATCH_RING_SAMPLES)
    assert set(trace.calls[:, 0].tolist()) >= {starts[1], codes.shape[0]}, "a run's STOP finalised nothing"
    assert whole.shape[0] > 40 and np.array_equal(whole, trace.records)


@needs_gpsim
def test_a_record_reading_past_the_last_flush_needs_the_rings_tail(ipol_inputs, monkeypatch):
    """Trial 8-3's 21st record (end sample 871, its call at N = 895): M4's range reads a_v up to e + R3 = 880,
    past the last scratch flush (864-879). fin_join writes the ring's tail first (the one call of the first
    1,000 samples whose reads reach it), and the records are the model's; without that write the reader gets
    the ring's older bytes and M4 comes out 1 LSB short."""
    run = next((r for r in ipol_inputs if r.source == "8-3_lb"), None)
    if run is None:
        pytest.skip("IPOL trial 8-3 (development data) is not in the folder")
    codes, flags = run.codes[:1000], run.flags[:1000]
    ci = gl.PicLogger().config.cfg_i
    r3 = int(ci[kernel.CI_R3])
    calls = detector_trace(codes, run.calibration_q, 50.0).calls
    tail = [e for i, e, s, m, fl in calls.tolist() if i < codes.shape[0]
            and kernel.scratch_tail_write(e, s if fl & F_LAST else -1, m + 1 + r3, ci)]
    assert tail == [871]
    assert gl.verify_records(codes, flags, run.calibration_q).identical
    real, src = gl.copy_sources, (gl.PIC_DIR / "step_join.asm").read_text()
    assert src.count("fin_join:\n") == 1, "the test's marker moved"

    def no_tail(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / "step_join.asm").write_text(src.replace("fin_join:\n", "fin_join:\n        goto    fj_inputs\n"))

    monkeypatch.setattr(gl, "copy_sources", no_tail)
    d = gl.verify_records(codes, flags, run.calibration_q).records.first_difference
    assert d == {"record": 20, "sample": 871, "field": "length_m4_q14", "gpsim": 18426, "model": 18427}


@needs_gpsim
def test_a_broken_step_record_is_caught(simulated_walk, monkeypatch):
    """The step record's duration byte off by one in step_record.asm: the records-only check names the first
    record and its field."""
    real = gl.copy_sources
    src = (gl.PIC_DIR / "step_record.asm").read_text()
    marker = "        movwf   REC_DUR\n"
    assert src.count(marker) == 1, "the test's marker moved"

    def broken(build_dir, main_asm):
        real(build_dir, main_asm)
        (build_dir / "step_record.asm").write_text(src.replace(marker, marker + "        incf    REC_DUR, F\n"))

    monkeypatch.setattr(gl, "copy_sources", broken)
    codes = simulated_walk[0][550:1100]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify_records(codes, flags, nominal_calibration_q())
    d = r.records.first_difference
    assert not r.identical and r.records.n_identical < r.records.n_compared and r.records.n_compared > 5
    assert d is not None and d["field"] == "duration_samples" and d["gpsim"] == d["model"] + 1


@needs_gpsim
def test_a_page_buffer_overrun_fails_the_check(simulated_walk):
    """A sampling period the main loop cannot keep up with (a step record takes several): the backlog reaches the
    page buffer's 32 samples and the check fails even where the records it got are the model's."""
    codes = simulated_walk[0][550:900]
    flags = np.zeros(len(codes), np.int64)
    flags[0] = FLAG_SESSION_START
    r = gl.verify_records(codes, flags, nominal_calibration_q(), period_cycles=8_000)
    assert r.period_cycles == 8_000 and r.backlog_max >= gl.PAGE_WORDS and not r.identical
