"""The paper's evaluation on simulated subjects: sections, fractions, matching, rows, CSV, figure."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.errors import HostError
from gaitlog.host.gait.sections import MODES, section_fractions, sections_from_marks
from gaitlog.host.studies.compare import match_events
from gaitlog.host.studies.evaluation import (
    ESTIMATORS,
    ROW_COLUMNS,
    SimulatedEvaluation,
    evaluate_recording,
    format_summary,
    paper_pattern,
    summarise,
)
from gaitlog.host.studies.simulation import SimulatedRecording

#: 60 m corridor: marks 10, 30 | 50-70 holds the turn | 70, 90, 110; first 40 m = calibration.
SHORT = WalkPlan(corridor_length_m=60.0, speeds=("preferred", "fast"), rest_s=8.0,
                        rest_postures=("standing",), initial_stand_s=6.0, final_stand_s=2.0,
                        lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 90.0, 110.0, 120.0))


def ideal_logger(motion, *, sampling_rate_hz: float = 50.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stand-in for the device: nominal +-2 g, 10-bit quantisation, 50 Hz (no sensor filter, no errors)."""
    step = int(round(motion.sampling_rate_hz / sampling_rate_hz))
    acc = motion.acc_g[::step]
    times = motion.t_s[::step]
    codes = np.clip(np.floor(512.0 + acc * 256.0), 0, 1023)
    g = (codes + 0.5 - 512.0) / 256.0
    k = np.searchsorted(times, motion.marker_times_s, side="left")
    return g, times, times[k]


@pytest.fixture(scope="module")
def short_recording() -> SimulatedRecording:
    subject = Subject()
    m = Walking(subject=subject, walk_plan=SHORT, seed=4).render(500.0)
    g, times, marks = ideal_logger(m)
    return SimulatedRecording(subject, 4, g, np.ones(len(g), bool), 50.0, float(times[0]), marks,
                              dict(m.truth), False)


def test_match_events_examples() -> None:
    it, jd = match_events(np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.03, 2.99, 3.5]), 0.04)
    assert it.tolist() == [0, 2] and jd.tolist() == [1, 2]
    assert match_events(np.array([]), np.array([1.0]), 0.04)[0].size == 0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.3, 0.8), min_size=1, max_size=40), st.floats(-0.039, 0.039), st.integers(0, 2**31))
def test_match_events_recovers_shifted_copies(gaps, shift, seed) -> None:
    """Events >= 0.3 s apart, detected with a common shift < tol plus drops: every kept one matches."""
    t = np.cumsum(gaps)
    rng = np.random.default_rng(seed)
    keep = rng.random(t.size) < 0.8
    it, jd = match_events(t, t[keep] + shift, 0.04)
    assert it.tolist() == np.flatnonzero(keep).tolist()
    assert jd.tolist() == list(range(int(keep.sum())))


def _table(starts: np.ndarray, ends: np.ndarray, lengths: np.ndarray) -> StepTable:
    sampling_rate_hz = 100.0
    ff = np.round(ends * sampling_rate_hz).astype(np.int64)
    start = np.where(np.isfinite(starts), np.round(np.nan_to_num(starts) * sampling_rate_hz), -1).astype(np.int64)
    n = ff.size
    raw = {e: lengths.copy() for e in ESTIMATORS}
    return StepTable(sampling_rate_hz, 0.0, ff, ff - 5, np.full(n, -1), start, np.zeros(n, np.int64), (ff - start) / sampling_rate_hz,
                     np.zeros(n, np.int64), {}, np.zeros(n), raw, dict(raw))


def test_section_fractions_are_the_overlap_of_each_window() -> None:
    starts = np.array([0.0, 0.5, 1.0, 1.5])
    ends = starts + 0.5
    tab = _table(starts, ends, np.full(4, 0.7))
    f = section_fractions(tab, 0.6, 1.75)
    np.testing.assert_allclose(f, [0.0, 0.8, 1.0, 0.5])
    w = section_fractions(tab, 0.6, 1.75, edge="whole")
    np.testing.assert_allclose(w, [0.0, 1.0, 1.0, 0.0])  # midpoints 0.25, 0.75, 1.25, 1.75 (excluded)
    # A windowless first step gets the median duration.
    tab2 = _table(np.array([np.nan, 0.5]), np.array([0.5, 1.0]), np.full(2, 0.7))
    np.testing.assert_allclose(section_fractions(tab2, 0.0, 0.25), [0.5, 0.0])
    with pytest.raises(ValueError, match="edge"):
        section_fractions(tab, 0.0, 1.0, edge="half")


def test_sections_from_marks_pair_laps_and_flag_the_turn(short_recording: SimulatedRecording) -> None:
    rec = short_recording
    secs = sections_from_marks(rec.mark_times_s, rec.truth["laps"], corridor_length_m=60.0)
    assert [(s.excursion, s.start_m, s.end_m, s.turn) for s in secs[:5]] == [
        (0, 10.0, 30.0, False), (0, 30.0, 50.0, False), (0, 50.0, 70.0, True), (0, 70.0, 90.0, False),
        (0, 90.0, 110.0, False)]
    assert len(secs) == 10 and {s.speed_label for s in secs} == {"preferred", "fast"}
    with pytest.raises(HostError, match="MARK samples"):
        sections_from_marks(rec.mark_times_s[:-1], rec.truth["laps"])
    with pytest.raises(HostError, match="does not follow lap"):
        sections_from_marks(rec.mark_times_s + 0.5, rec.truth["laps"])


def test_evaluate_recording_rows_and_truth_check(short_recording: SimulatedRecording) -> None:
    res = evaluate_recording(short_recording, corridor_length_m=60.0)
    assert any("walk-ratio fallback" in w for w in res.warnings)  # single-speed M5: recorded, not raised
    # evaluated: 70-90 and 90-110 of both excursions (10-30, 30-50 calibrate, 50-70 turns) x 2 modes x 5
    assert len(res.rows) == 2 * 2 * 2 * 5
    assert set(res.rows[0]) == set(ROW_COLUMNS)
    assert {r["mode"] for r in res.rows} == set(MODES)
    # The world's own step lengths cut by the same rule give the corridor distance (turn excluded).
    np.testing.assert_allclose(res.truth_ratio, 1.0, atol=0.01)
    # Calibrated estimators are within 15 % on the ideal logger; K is per subject (not 1).
    for r in res.rows:
        if r["estimator"] != "M3":
            assert r["ratio"] == pytest.approx(1.0, abs=0.15), r
    assert res.calibrations["single-speed"].mode == "single-speed"
    assert res.calibrations["multi-speed"].n_sections == 2
    assert res.calibrations["single-speed"].k_m2 > 1.1
    # M3 is not calibrated: identical in both modes.
    m3 = {mode: [r["ratio"] for r in res.rows if r["estimator"] == "M3" and r["mode"] == mode] for mode in MODES}
    assert m3["single-speed"] == m3["multi-speed"]
    assert res.events["heel_strike"].n_truth == short_recording.truth["steps"]["heel_strike_s"].size + 2


def test_summary_table_csv_and_pattern() -> None:
    rng = np.random.default_rng(0)
    rows = []
    spread = {"M1": 0.08, "M2": 0.04, "M3": 0.05, "M4": 0.04, "M5": 0.06}
    for mode in MODES:
        for est in ESTIMATORS:
            s = spread[est] * (0.6 if mode == "multi-speed" and est != "M3" else 1.0)
            for v in 1.0 + s * rng.standard_normal(200):
                rows.append({"mode": mode, "estimator": est, "ratio": float(v)})
    summ = summarise(rows)
    assert len(summ) == 10
    r = next(x for x in summ if x["mode"] == "single-speed" and x["estimator"] == "M1")
    v = np.array([x["ratio"] for x in rows if x["mode"] == "single-speed" and x["estimator"] == "M1"])
    assert r["median"] == pytest.approx(np.median(v)) and r["max"] == pytest.approx(v.max())
    assert r["iqr"] == pytest.approx(np.subtract(*np.percentile(v, [75, 25])))
    pat = paper_pattern(summ)
    assert pat["m1_widest"][0] and pat["multi_narrower"][0] and pat["m3_comparable"][0]
    text = format_summary(summ)
    assert "single-speed M1" in text.replace("  ", " ") or "single-speed M1" in text
    assert len(text.splitlines()) == 11


def test_simulated_evaluation_is_seeded_parallel_safe_and_writes(tmp_path) -> None:
    """Two subjects through the emulated Logger: same rows with 1 or 2 workers; atomic CSV and PNG."""
    a = SimulatedEvaluation(n_subjects=2, seed=3, walk_plan=SHORT, workers=1).run()
    b = SimulatedEvaluation(n_subjects=2, seed=3, walk_plan=SHORT, workers=2).run()
    assert a.rows_ == b.rows_ and len(a.rows_) > 0
    assert a.events_["heel_strike"].n_truth > 0
    out = tmp_path / "rows.csv"
    a.write_csv(out, summary_path=tmp_path / "summary.csv")
    got = list(csv.DictReader(io.StringIO(out.read_text())))
    assert len(got) == len(a.rows_) and tuple(got[0]) == ROW_COLUMNS
    assert float(got[0]["ratio"]) == pytest.approx(a.rows_[0]["ratio"], rel=1e-5)
    from gaitlog.host.studies.plots import plot_boxplots

    png = plot_boxplots(a.rows_, tmp_path / "fig.png", title="test")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig.png", "rows.csv", "summary.csv"]
    paths = a.write_outputs(tmp_path / "out")
    assert all(p.stat().st_size > 0 for p in paths.values())


def test_plot_refuses_empty() -> None:
    from gaitlog.host.studies.plots import render_boxplots_png

    with pytest.raises(ValueError, match="no section"):
        render_boxplots_png([])


def test_bad_population_size() -> None:
    with pytest.raises(HostError, match="n_subjects"):
        SimulatedEvaluation(n_subjects=0).run()


# ---- issue 4 "done means" on simulated subjects (depends on host/gait as well) --------------------------
# Measured with the world's contact timing taken from the IPOL lower-back recordings (double support 24 % of
# the step, centre of mass lowest ~40 ms after heel strike and ~100 ms before toe-off),
# single-stance arc from the same recordings (M3 with the paper's inputs ~1.0 of the step), default detector,
# SimulatedEvaluation(seed=0, population="v1"): 3 subjects (this fixture) / 6 subjects (the figures were
# measured on v1; on people, 4 subjects, heel-strike F1 is 0.965: tests/host/studies/test_evaluation_people.py).

FOOT_FLAT_REASON = (
    "the detector's foot-flat is the centre of mass's low point (Alvarez's null vertical velocity, 9 ms from "
    "it); the anatomical foot-flat (forefoot down, ~8 % of the gait cycle) comes ~30 ms later: median error "
    "29-32 ms")


@pytest.fixture(scope="module")
def population():
    return SimulatedEvaluation(n_subjects=3, seed=0, workers=2, population="v1").run()


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="F1 0.98997 (target 0.99): the on-line algorithm version 3 foot-flat rule "
                   "adds 2 heel strikes in sit-to-stand transitions before a walk (3 subjects)")
def test_done_steps_detected(population) -> None:
    """Heel strikes within 40 ms, F1 >= 0.99. Measured with the impact-band rule (``GaitEventDetector`` note 2):
    0.990 (3 subjects, this fixture) / 0.992 (6) / 0.989 (8); the misses are mostly turn steps and each
    excursion's closing contact (coming to a stop). The steepest-rise rule it replaced gave 0.70-0.86. Since
    the version 3 prominence (0.25 of the recent step amplitude within 0.25-0.5 m/s^2, for slow short steps):
    0.98997 (3 subjects: 3,247 detected, 3,208 matched of 3,234, against 3,245 and 3,208) / 0.9921 (6): the
    amplitude of the walk before a sitting rest keeps the threshold below 0.5 m/s^2, and the sit-to-stand
    ~2 s before the next walk passes it (6 subjects: 4 such heel strikes in 18 rests, 1 more in a U-turn)."""
    ev = population.events_["heel_strike"]
    assert (ev.n_detected, ev.n_matched) == (3247, 3208)       # what the strict xfail stands for
    assert ev.f1 >= 0.99


@pytest.mark.slow
def test_done_event_timing(population) -> None:
    """Heel strike, toe-off and foot-flat (as the centre of mass's low point) within 20 ms (median)."""
    ev = population.events_
    for name in ("heel_strike", "toe_off", "com_min"):
        assert ev[name].median_abs_error_s <= 0.020, (name, ev[name])
    assert ev["com_min"].f1 >= 0.95
    assert ev["heel_strike"].n_detected == pytest.approx(ev["heel_strike"].n_truth, rel=0.01)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=FOOT_FLAT_REASON)
def test_done_anatomical_foot_flat_timing(population) -> None:
    assert population.events_["foot_flat"].median_abs_error_s <= 0.020


@pytest.mark.slow
def test_done_paper_pattern(population) -> None:
    """M1 widest, multi-speed narrower, M3 (no K) comparable to calibrated M2/M4 (see ``paper_pattern``).

    It holds again with Weinberg's range^(1/4) (on-line algorithm version 4): the 'v1' walkers follow the walk-ratio
    law, whose pendulum range grows as the step length^4. With range^(1/2) (versions 2-3) it failed: single-speed
    M4's range (0.285) passed M1's (0.206) and multi-speed K did not narrow it. Figures measured with 1/2 follow.

    Measured (single-speed IQR M1/M2/M3/M4; multi-speed M4): 3 subjects 7.4/5.3/5.4/4.1 %, 4.3 %; 6 subjects
    7.5/5.5/8.5/4.3 %, 4.3 %; 8 subjects 7.9/5.8/8.7/4.7 %, 4.9 %. M1 and M2 narrow with multi-speed K; M4 does
    not narrow (within the 0.2 % tolerance for 3 and 6 subjects, just outside it for 8): one K for M4 cannot
    follow every speed better than the preferred-speed K. M3's IQR is at the 1.5 x limit for 6-8 subjects
    (1.55 x M2's for 6, 1.50 x for 8): its spread is the subjects' deviation from the pendulum model.
    """
    pat = paper_pattern(population.summary_)
    assert all(ok for ok, _ in pat.values()), pat


@pytest.mark.slow
def test_population_calibrated_estimators_are_unbiased(population) -> None:
    """Whatever the events, calibrated M2/M4/M5 are near 100 % per section (median within 3 %)."""
    for r in population.summary_:
        if r["estimator"] in ("M2", "M4", "M5"):
            assert r["median"] == pytest.approx(1.0, abs=0.03), r
    # per-subject K differs: the calibration is genuinely needed
    k = [res.calibrations["multi-speed"].k_m2 for res in population.results_]
    assert np.std(k) / np.mean(k) > 0.03
