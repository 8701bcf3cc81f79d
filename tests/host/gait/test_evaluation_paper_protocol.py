"""The paper's protocol as run (Alvarez et al. 2006, II-C) and its evaluation side by side with the paper.

Five-minute rests with the logger stopped (one logging run per excursion in one memory), laps timed by an
observer's stopwatch and anchored on the recording by the host, subjects of the paper's heights; bootstrap
intervals over subjects; M5 with the generating heel-strike intervals.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.stopwatch import Stopwatch
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walk_plan import (
    PAPER_HEIGHTS_M,
    PAPER_REST_S,
    POPULATION_PLANS,
    WalkPlan,
)
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.gait.sections import MODES
from gaitlog.host.gait.stopwatch_laps import lap_table, set_off_times
from gaitlog.host.studies.evaluation import (
    BOOT_STATISTICS,
    SimulatedEvaluation,
    SubjectResult,
    bootstrap_summary,
    format_m5_question,
    format_paper_table,
    m5_timing_question,
    paper_claims,
    summarise,
)
from gaitlog.host.studies.simulation import (
    at_paper_heights,
    record_subject,
    simulated_population,
)

RATE_HZ = 50.0


# ---------------------------------------------------------------------------------------------------------
# The protocol and the logger's memory


def test_the_papers_rests_fit_in_memory_only_with_the_logger_stopped() -> None:
    """Four excursions and three 5-minute rests: ~27 min kept running, over the 64K samples (21.8 min at 50 Hz);
    one run per excursion holds the four excursions with room to spare."""
    capacity = Logger().header.capacity_samples
    sub = at_paper_heights(random_subjects(1, seed=2, population="people"), seed=2)[0]
    paper = WalkPlan.paper(**POPULATION_PLANS["people"])
    runs = Walking(subject=sub, walk_plan=paper, seed=5).logger_spans()
    kept = Walking(subject=sub, walk_plan=WalkPlan(rest_s=PAPER_REST_S, **POPULATION_PLANS["people"]),
                   seed=5).logger_spans()
    assert len(runs) == 4 and len(kept) == 1
    assert (kept[0][1] - kept[0][0]) * RATE_HZ > capacity
    logged = sum(b - a for a, b in runs)
    assert logged * RATE_HZ < 0.75 * capacity
    gaps = [b[0] - a[1] for a, b in pairwise(runs)]
    assert min(gaps) > PAPER_REST_S - 10.0          # the rests (minus the standing lead and tail) are not logged


def test_paper_plan_and_heights() -> None:
    p = WalkPlan.paper()
    assert (p.rest_s, p.logger_runs, p.corridor_length_m, p.speeds) == (
        300.0, "per-excursion", 100.0, ("preferred", "fast", "slow", "medium"))
    subs = random_subjects(12, seed=4, population="people")
    scaled = at_paper_heights(subs, seed=4)
    lo, hi = PAPER_HEIGHTS_M
    assert all(lo <= s.height_m <= hi for s in scaled)
    for a, b in zip(subs, scaled, strict=True):
        assert b.leg_length_m / b.height_m == pytest.approx(a.leg_length_m / a.height_m)
        assert b.preferred_speed_m_s ** 2 / b.height_m == pytest.approx(a.preferred_speed_m_s ** 2 / a.height_m)
    assert [s.height_m for s in at_paper_heights(subs[:3], seed=4)] == [s.height_m for s in scaled[:3]]
    _, plan = simulated_population(2, seed=4, population="people", protocol="paper")
    assert plan.logger_runs == "per-excursion" and plan.turn_radius_m == POPULATION_PLANS["people"]["turn_radius_m"]
    with pytest.raises(HostError, match="protocol must be one of"):
        simulated_population(1, protocol="lab")


def test_bad_logger_runs_refused() -> None:
    with pytest.raises(ValueError, match="logger_runs"):
        WalkPlan(logger_runs="sometimes")


# ---------------------------------------------------------------------------------------------------------
# The observer's stopwatch and its placement on the recording


def test_stopwatch_errors_have_the_modelled_statistics() -> None:
    n = 4000
    laps = {"excursion": np.repeat(np.arange(n), 2), "time_s": np.tile([10.0, 30.0], n) + np.repeat(
        100.0 * np.arange(n), 2), "distance_m": np.tile([0.0, 20.0], n), "speed_label": np.full(2 * n, "fast")}
    exc = {"t_start_s": 10.0 + 100.0 * np.arange(n)}
    sw = Stopwatch()
    sheet = sw.time_laps(laps, exc, seed=3)
    assert np.all(sheet["split_s"][::2] == 0.0)                      # the 0 m lap is the start
    delay = sheet["start_walk_s"] - exc["t_start_s"]
    assert np.mean(delay) == pytest.approx(sw.start_delay_s, abs=0.005)
    err = sheet["split_s"][1::2] - (20.0 - delay)                   # split = press - start
    assert np.mean(err) == pytest.approx(0.0, abs=0.005)
    assert np.std(err) == pytest.approx(np.hypot(sw.split_sd_s, sw.resolution_s / np.sqrt(12)), rel=0.05)
    assert np.allclose(sheet["split_s"] * 100, np.round(sheet["split_s"] * 100))


def _standing_then_walking(onsets_s: list[float], n_s: float = 12.0) -> tuple[np.ndarray, list[tuple[int, int]]]:
    rng = np.random.default_rng(0)
    parts, rows, row = [], [], 0
    for t_on in onsets_s:
        t = np.arange(int(n_s * RATE_HZ)) / RATE_HZ
        acc = np.tile([0.05, 0.0, 1.0], (t.size, 1)) + rng.normal(0, 0.003, (t.size, 3))
        walking = t >= t_on
        acc[walking, 2] += 0.25 * np.sin(2 * np.pi * 1.8 * (t[walking] - t_on))
        parts.append(acc)
        rows.append((row, row + t.size))
        row += t.size
    return np.concatenate(parts), rows


def test_set_off_is_found_where_the_walker_leaves_standing() -> None:
    acc, rows = _standing_then_walking([3.0, 4.5])
    t = set_off_times(acc, np.ones(len(acc), bool), rows, sampling_rate_hz=RATE_HZ)
    assert t - np.array([3.0, 12.0 + 4.5]) == pytest.approx([0.0, 0.0], abs=0.08)   # an abrupt set-off
    sheet = {"excursion": np.array([0, 0, 1, 1]), "split_s": np.array([0.0, 15.2, 0.0, 14.1]),
             "distance_m": np.array([10.0, 30.0, 10.0, 30.0]), "speed_label": np.array(["slow", "slow", "fast", "fast"])}
    laps = lap_table(sheet, t)
    assert laps["time_s"] == pytest.approx([t[0], t[0] + 15.2, t[1], t[1] + 14.1])
    with pytest.raises(HostError, match="2 excursions for 1 logging runs"):
        lap_table(sheet, t[:1])


def test_set_off_refuses_runs_it_cannot_anchor() -> None:
    acc, rows = _standing_then_walking([0.0])
    with pytest.raises(HostError, match="not standing still"):
        set_off_times(acc, np.ones(len(acc), bool), rows, sampling_rate_hz=RATE_HZ)
    acc, rows = _standing_then_walking([99.0])
    with pytest.raises(HostError, match="never sets off"):
        set_off_times(acc, np.ones(len(acc), bool), rows, sampling_rate_hz=RATE_HZ)
    valid = np.ones(len(acc), bool)
    valid[10] = False
    with pytest.raises(HostError, match="no 1 s of valid standing"):
        set_off_times(acc, valid, rows, sampling_rate_hz=RATE_HZ)


@pytest.fixture(scope="module")
def paper_recordings():
    subs, plan = simulated_population(1, seed=1, population="people", protocol="paper")
    return (record_subject(subs[0], seed=1000, walk_plan=plan, laps="stopwatch"),
            record_subject(subs[0], seed=1000, walk_plan=plan, laps="mark"))


def test_paper_recording_is_four_runs_on_the_host_clock(paper_recordings) -> None:
    sw, mark = paper_recordings
    assert len(sw.run_rows) == 4 and sw.acc_g.shape == mark.acc_g.shape
    laps = sw.truth["laps"]["time_s"]
    assert np.isfinite(laps).all()                                    # every lap falls inside a logged run
    rows = np.asarray(sw.run_rows)
    k = np.round(laps * sw.sampling_rate_hz).astype(int)
    assert np.all(((k[:, None] >= rows[:, 0]) & (k[:, None] < rows[:, 1])).any(axis=1))
    rests = sw.truth["rests"]                  # on the host clock only the run's tail, the gap and the next lead
    assert np.all(rests["t_stop_s"] - rests["t_start_s"] < 10.0)
    assert mark.mark_times_s - laps == pytest.approx(np.zeros(laps.size), abs=1.0 / RATE_HZ + 1e-9)
    assert sw.mark_times_s.size == 0 and sw.lap_sheet is not None
    # the host's anchored laps: the start press and the detected set-off are both a few tenths of a second late
    anchored = lap_table(sw.lap_sheet, set_off_times(sw.acc_g, sw.valid, sw.run_rows,
                                                     sampling_rate_hz=sw.sampling_rate_hz))["time_s"]
    assert np.abs(anchored - laps).max() < 0.5
    assert np.median(np.abs(anchored - laps)) < 0.15


# ---------------------------------------------------------------------------------------------------------
# Intervals, the paper side by side, M5's question (synthetic results: known answers)


def _result(i: int, ratios: dict[tuple[str, str], np.ndarray], m5: dict | None = None) -> SubjectResult:
    rows = [{"mode": mode, "estimator": est, "ratio": float(r)} for (mode, est), v in ratios.items() for r in v]
    return SubjectResult(f"s{i}", rows, {}, {}, m5=m5 or {})


def test_bootstrap_summary_values_are_summarise_and_intervals_cover_them() -> None:
    rng = np.random.default_rng(1)
    res = [_result(i, {(m, e): 1.0 + 0.01 * i + rng.normal(0, 0.03, 20) for m in MODES for e in ("M1", "M2")})
           for i in range(6)]
    boot = bootstrap_summary(res, n_resamples=300)
    summ = {(r["mode"], r["estimator"]): r for r in summarise([r for s in res for r in s.rows])}
    assert len(boot) == 2 * 2 * len(BOOT_STATISTICS)
    for b in boot:
        assert b["value"] == pytest.approx(summ[(b["mode"], b["estimator"])][b["statistic"]])
        assert b["ci_low"] <= b["value"] <= b["ci_high"]
    same = [_result(i, {("single-speed", "M1"): np.array([0.9, 1.0, 1.1])}) for i in range(4)]
    for b in bootstrap_summary(same, n_resamples=50):                 # identical subjects: nothing to resample
        assert b["ci_low"] == pytest.approx(b["value"]) and b["ci_high"] == pytest.approx(b["value"])


def _boot_rows(figures: dict[tuple[str, str], tuple[float, float, float, float]]) -> list[dict]:
    out = []
    for (mode, est), (med, iqr, lo, hi) in figures.items():
        for stat, v in zip(("median", "iqr", "min", "max", "q1", "q3"), (med, iqr, lo, hi, med - iqr / 2,
                                                                       med + iqr / 2), strict=True):
            out.append({"mode": mode, "estimator": est, "statistic": stat, "value": v, "ci_low": v - 0.005,
                        "ci_high": v + 0.005, "n_subjects": 20})
    return out


def test_paper_claims_judge_the_stated_findings() -> None:
    paperlike = {("single-speed", "M1"): (1.03, 0.10, 0.8, 1.40), ("single-speed", "M2"): (1.02, 0.05, 0.9, 1.1),
                 ("single-speed", "M3"): (1.02, 0.06, 0.9, 1.1), ("single-speed", "M4"): (1.02, 0.05, 0.9, 1.1),
                 ("single-speed", "M5"): (0.99, 0.09, 0.8, 1.2),
                 ("multi-speed", "M1"): (1.02, 0.06, 0.9, 1.2), ("multi-speed", "M2"): (1.01, 0.04, 0.9, 1.1),
                 ("multi-speed", "M3"): (1.02, 0.06, 0.9, 1.1), ("multi-speed", "M4"): (1.01, 0.04, 0.9, 1.1),
                 ("multi-speed", "M5"): (0.98, 0.08, 0.8, 1.2)}
    verdicts = [v for *_, v in paper_claims(_boot_rows(paperlike))]
    assert all(v.startswith("agrees") for v in verdicts), verdicts
    worse = dict(paperlike)
    worse[("multi-speed", "M4")] = (0.96, 0.07, 0.8, 1.1)            # multi-speed M4 wider and off-centre
    claims = {c: v for c, _, _, v in paper_claims(_boot_rows(worse))}
    assert claims["multi-speed: M1-M4 medians 100-105 %"] == "disagrees (M4 outside)"
    assert claims["multi-speed K improves M1, M2, M4 (median and spread)"] == (
        "disagrees (M4: IQR and median not better)")
    text = format_paper_table(_boot_rows(paperlike))
    assert "single-speed M1" in text and "max ~140" in text and "98" in text


def test_m5_question_recovers_a_known_timing_share() -> None:
    """Detected = exact + independent timing noise of variance v: the share is v / (var(exact) + v)."""
    rng = np.random.default_rng(2)
    res = []
    for i in range(20):
        m5: dict = {"timing_error_s": rng.normal(0, 0.02, 200)}
        for mode in MODES:
            exact = rng.normal(0, 0.04, 400)
            sec_exact = rng.normal(1.0, 0.03, 40)
            m5[mode] = {"step_exact": exact, "step_detected": exact + rng.normal(0, 0.04, 400),
                        "section_exact": sec_exact, "section_detected": sec_exact + rng.normal(0, 0.003, 40)}
        res.append(_result(i, {}, m5))
    q = m5_timing_question(res, n_resamples=200)
    by = {(r["mode"], r["level"]): r for r in q["rows"]}
    for mode in MODES:
        assert by[(mode, "step")]["timing_share"] == pytest.approx(0.5, abs=0.07)
        r = by[(mode, "step")]
        assert r["timing_share_low"] < r["timing_share"] < r["timing_share_high"] < r["timing_share_low"] + 0.1
        assert by[(mode, "section")]["timing_share"] == pytest.approx(0.01, abs=0.04)     # IQR-based: noisier
    assert q["answer"] == {"step": "partly", "section": "no"}
    assert q["timing"]["rms_ms"] == pytest.approx(20.0, rel=0.03)
    assert q["timing"]["sampling_rms_ms"] == pytest.approx(1e3 / 50 / np.sqrt(6))
    assert "per 20 m section no" in format_m5_question(q)


# ---------------------------------------------------------------------------------------------------------
# The command and its figures


def test_stopwatch_laps_need_the_papers_protocol(tmp_path, capsys) -> None:
    assert main(["evaluate", "sim", str(tmp_path / "o"), "--protocol", "compact", "--laps", "stopwatch"]) == 2  # a usage error
    assert "--laps stopwatch: only with --protocol paper" in capsys.readouterr().err
    with pytest.raises(HostError, match="stopwatch laps need"):
        SimulatedEvaluation(n_subjects=1, laps="stopwatch").run()
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_printed_figures_of_three_people_walkers_on_the_papers_protocol() -> None:
    """``SimulatedEvaluation(n_subjects=3, seed=0, population="people", protocol="paper", laps="stopwatch")``
    (the first 3 of the README's 20-subject run; ~40 s on 2 workers). Measured: single-speed M1 98.0 %, IQR 5.3 %,
    max 108.4 %; multi-speed M5 100.2 %, IQR 3.5 %; M3 97.4 %, IQR 6.6 %."""
    ev = SimulatedEvaluation(n_subjects=3, seed=0, workers=2, population="people", protocol="paper",
                             laps="stopwatch", n_resamples=500).run()
    s = {(r["mode"], r["estimator"]): r for r in ev.summary_}
    assert s[("single-speed", "M1")]["median"] == pytest.approx(0.980, abs=0.003)
    assert s[("single-speed", "M1")]["iqr"] == pytest.approx(0.053, abs=0.003)
    assert s[("single-speed", "M1")]["max"] == pytest.approx(1.084, abs=0.005)
    assert s[("single-speed", "M3")]["median"] == pytest.approx(0.974, abs=0.003)
    assert s[("single-speed", "M3")]["iqr"] == pytest.approx(0.066, abs=0.004)
    assert s[("multi-speed", "M5")]["median"] == pytest.approx(1.002, abs=0.003)
    assert s[("multi-speed", "M5")]["iqr"] == pytest.approx(0.035, abs=0.003)
    assert s[("multi-speed", "M2")]["median"] == pytest.approx(0.997, abs=0.003)
    b = {(r["mode"], r["estimator"], r["statistic"]): r for r in ev.bootstrap_}
    assert b[("single-speed", "M1", "median")]["ci_low"] == pytest.approx(0.961, abs=0.005)
    assert b[("single-speed", "M1", "median")]["ci_high"] == pytest.approx(0.991, abs=0.005)
    verdicts = {c: v for c, _, _, v in paper_claims(ev.bootstrap_)}
    # M4 left the band with Weinberg's 1/4 (on-line algorithm version 4's M4 exponent)
    assert verdicts["multi-speed: M1-M4 medians 100-105 %"] == "disagrees (M1, M3, M4 outside)"
    assert verdicts["single-speed: M1 worst case ~140 %"] == "disagrees"
    assert verdicts["multi-speed: M5 has the lowest median (98 %)"] == "disagrees (not the lowest)"
    assert len(ev.results_[0].rows) == 2 * 5 * 24      # 4 excursions x 6 straight sections after calibration
    m5 = {(r["mode"], r["level"]): r for r in ev.m5_["rows"]}
    assert m5[("multi-speed", "step")]["timing_share"] == pytest.approx(0.306, abs=0.02)
    assert m5[("multi-speed", "section")]["iqr_exact"] == pytest.approx(0.037, abs=0.003)
    assert ev.m5_["timing"]["rms_ms"] == pytest.approx(23.4, abs=1.5)
