"""gaitlog.host.studies.compare on a simulated walk: the emulated logger, gravity and the world's truth are the references.

The comparison's rule is tested here with its reason: one K (fitted on the offline chain) for every chain.
A 2 % scale error injected into the fixed-point chain alone shows up in full in the arithmetic share, and a
K refitted per arithmetic would have hidden it.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.host.files.replay import online_step_table
from gaitlog.host.gait.k_calibration import calibrate_on_sections
from gaitlog.host.gait.sections import calibration_sets, sections_from_marks
from gaitlog.host.studies.compare import (
    bootstrap_budget,
    compare_recording,
    compare_walk,
    match_steps,
    segment_distances,
    step_differences,
    truth_table,
)
from gaitlog.host.studies.simulation import AnalogWalk

SAMPLING_RATE_HZ = 50.0
#: The scale error injected into the fixed-point chain.
SCALE = 1.02


class ScaledFixed(OnlineStepAlgorithm):
    """The firmware's algorithm whose fixed-point lengths come out 2 % long (a wrong constant, say)."""

    @staticmethod
    def _scaled(steps):
        steps.lengths = np.floor(steps.lengths * SCALE + 0.5).astype(np.int64)
        return steps

    def feed(self, codes, *, offset=0):
        return self._scaled(super().feed(codes, offset=offset))

    def flush(self, *, offset=0):
        return self._scaled(super().flush(offset=offset))


@pytest.fixture(scope="module")
def walk() -> SimpleNamespace:
    """A 60 m corridor out and back at two speeds (two straight evaluated sections per excursion)."""
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walk_plan import WalkPlan

    subject = random_subjects(2, seed=5)[1]
    walk_plan = WalkPlan(corridor_length_m=60.0, speeds=("preferred", "fast"), rest_s=10.0,
                               rest_postures=("standing",), lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 90.0, 110.0,
                                                                         120.0))
    aw = AnalogWalk(subject=subject, seed=7, walk_plan=walk_plan).run()
    sw = aw.sample(SAMPLING_RATE_HZ)
    return SimpleNamespace(subject=subject, walk_plan=walk_plan, aw=aw, sw=sw, wc=compare_walk(sw, subject, adc_bits=10),
                           scaled=compare_walk(sw, subject, adc_bits=10, fixed_algorithm=ScaledFixed))


@pytest.mark.parametrize("adc_bits", [8, 10])
def test_codes_are_what_the_emulated_logger_stores(walk, adc_bits) -> None:
    from gaitlog.firmware_sim.adc import Adc
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.sensor import SensorModel
    from gaitlog.firmware_sim.world.walking import Walking
    from gaitlog.protocol.packing import FLAG_MARK

    logger = Logger(sensor=SensorModel.draw(seed=walk.aw.sensor_.seed - 1), adc=Adc(adc_bits=adc_bits, sampling_rate_hz=SAMPLING_RATE_HZ))
    res = logger.record(Walking(subject=walk.subject, walk_plan=walk.walk_plan, seed=7))
    np.testing.assert_array_equal(walk.sw.codes(adc_bits), np.asarray(res.codes, np.int64))
    np.testing.assert_allclose(walk.sw.times_s, res.sample_times_s, atol=1e-12)
    marks = np.asarray(res.sample_times_s)[(np.asarray(res.flags) & FLAG_MARK) != 0]
    np.testing.assert_allclose(walk.sw.mark_times_s, marks, atol=1e-12)


@pytest.mark.parametrize("adc_bits", [8, 10, 12])
def test_calibration_gives_one_g_at_rest(walk, adc_bits) -> None:
    """The device calibration (sensor truth) on codes and on the analog samples: |a| = 1 g while standing."""
    rests = walk.sw.truth["rests"]
    t = walk.sw.times_s
    sel = np.zeros(t.size, bool)
    for a, b in zip(rests["t_start_s"], rests["t_stop_s"]):
        sel |= (t > a + 1.0) & (t < b - 1.0)
    assert sel.sum() > 100
    cal = walk.sw.calibration(adc_bits)
    lsb_g = 4.0 / 2**adc_bits
    for c, tol in ((walk.sw.codes(adc_bits), 3e-3 + lsb_g / 2), (walk.sw.ideal_codes(adc_bits), 3e-3)):
        norm = np.linalg.norm(cal.apply(c[sel]), axis=1)
        assert abs(np.median(norm) - 1.0) < tol


def test_one_k_fitted_on_the_offline_chain_is_used_by_every_chain(walk) -> None:
    """K comes from the offline chain's calibration sections, and the on-line algorithm applies that K: its
    calibrated lengths are K times the raw lengths of an uncalibrated run (to the Q1.15 rounding of K)."""
    wc, s = walk.wc, walk.subject
    for mode in ("single-speed", "multi-speed"):
        for chain in ("ideal", "offline", "online-float", "online-fixed", "exact-timing"):
            assert wc.runs[chain].calibrations[mode] is wc.calibrations[mode]
    pools = calibration_sets([x for x in _sections(walk)])
    k = calibrate_on_sections(wc.runs["offline"].table, pools["multi-speed"], leg_length_m=s.leg_length_m,
                              foot_length_m=s.foot_length_m)
    assert k.k_m2 == wc.calibrations["multi-speed"].k_m2 and k.k1_m5_m_s == wc.calibrations["multi-speed"].k1_m5_m_s
    raw, _ = online_step_table(walk.sw.codes(10), sampling_rate_hz=SAMPLING_RATE_HZ, leg_length_m=s.leg_length_m,
                               foot_length_m=s.foot_length_m, adc_calibration=walk.sw.calibration(10),
                               arithmetic="float", t0_s=float(walk.sw.times_s[0]))
    cal = wc.runs["online-float"].tables["multi-speed"]
    assert cal.n_steps == raw.n_steps
    for est, kk in (("M1", k.k_m1), ("M2", k.k_m2), ("M4", k.k_m4)):
        g = np.isfinite(raw.raw_m[est]) & np.isfinite(cal.length_m[est])
        assert g.sum() > 250
        np.testing.assert_allclose(cal.length_m[est][g], kk * raw.raw_m[est][g], rtol=2 ** -15 / kk + 1e-9)
    m5 = k.k1_m5_m_s / raw.duration_s + k.k2_m5_m
    g = np.isfinite(m5) & np.isfinite(cal.length_m["M5"])
    np.testing.assert_allclose(cal.length_m["M5"][g], m5[g], atol=2e-4)


def _sections(walk):
    return sections_from_marks(walk.sw.mark_times_s, walk.sw.truth["laps"], sampling_rate_hz=SAMPLING_RATE_HZ)


def test_arithmetic_share_done_criteria(walk) -> None:
    """Issue 10: the on-line algorithm in fixed vs float point, same codes, same K: per step median |d| <=
    0.1 mm (0.04-0.06 mm measured) and at most 1 % of a step (0.04 %); no saturation; rare event differences."""
    wc = walk.wc
    m = wc.matches["arithmetic"]
    fl = wc.runs["online-float"].tables["multi-speed"]
    assert m.n_matched >= 0.99 * fl.n_steps
    assert m.n_different_events <= max(2, 0.01 * fl.n_steps)      # counted, and rare (1 measured)
    rows = [r for r in wc.step_diffs if r["share"] == "arithmetic"]
    assert [r["estimator"] for r in rows] == list(ESTIMATORS)
    for r in rows:
        assert r["pair"] == "online-fixed - online-float"
        assert r["n"] >= 0.95 * np.count_nonzero(np.isfinite(fl.length_m[r["estimator"]])), r
        assert r["median_abs_mm"] <= 0.1, r
        assert r["max_rel"] <= 0.01, r
    assert wc.saturation == ""
    assert wc.runs["online-fixed"].saturated == 0 and wc.runs["online-fixed"].wrapped == 0


def test_every_chain_has_most_steps_and_the_adc_and_algorithm_cost_more_than_the_arithmetic(walk) -> None:
    steps = walk.wc.steps
    for est in ("m1", "m2", "m4"):
        i, o, f, x = (steps[f"{est}_{k}_m"] for k in ("ideal", "offline", "online_float", "online_fixed"))
        g = np.isfinite(i) & np.isfinite(o) & np.isfinite(f) & np.isfinite(x)
        assert g.mean() > 0.9   # (the split x - i = (o - i) + (f - o) + (x - f) is an identity: not tested)
    d = {(r["share"], r["estimator"]): r for r in walk.wc.step_diffs}
    for est in ("M1", "M2", "M4"):
        assert d[("adc", est)]["median_abs_mm"] > d[("arithmetic", est)]["median_abs_mm"], est
        assert d[("algorithm", est)]["median_abs_mm"] > 10 * d[("arithmetic", est)]["median_abs_mm"], est


def test_against_the_world_truth(walk) -> None:
    """Steps found and timed against the world's truth; section ratios near 1 with the offline chain's K."""
    wc = walk.wc
    fl = wc.runs["offline"].table
    found = wc.steps["truth_step"] >= 0
    assert found.mean() >= 0.97
    assert wc.timing["median_abs_ms"] <= 20.0      # one sample at 50 Hz
    st = walk.sw.truth["steps"]
    exact, idx = truth_table(fl, st)
    k = np.flatnonzero((idx >= 0) & np.isfinite(fl.duration_s))
    np.testing.assert_allclose(exact.duration_s[k], np.asarray(st["next_foot_flat_s"])[idx[k]]
                               - np.asarray(st["foot_flat_s"])[idx[k]])
    np.testing.assert_allclose(exact.raw_m["M5"][k], 1.0 / exact.duration_s[k])
    ratios = [r for r in wc.segments if r["mode"] == "multi-speed" and r["estimator"] in ("M2", "M4", "M5")]
    assert len(ratios) == 3 * 4                      # 2 evaluated straight sections per excursion
    for r in ratios:
        assert abs(r["ratio_online_fixed"] - 1.0) < 0.10, r
        assert abs(r["ratio_online_fixed"] - r["ratio_online_float"]) < 0.002, r
        assert abs(r["ratio_online_float"] - r["ratio_offline"]) < 0.02, r
    d = {(r["pair"], r["estimator"]): r for r in wc.step_diffs}
    assert d[("ideal - truth", "M2")]["median_abs_mm"] < 80.0
    assert d[("online-fixed - truth", "M2")]["n"] >= 0.9 * fl.n_steps


def test_a_scale_error_of_the_fixed_chain_is_flagged(walk) -> None:
    """2 % too long in fixed point only: the arithmetic share jumps from ~0.05 mm to 2 % of a step (~14 mm)
    and the section ratio difference to ~0.02; the ADC and algorithm shares do not move."""
    base = {(r["share"], r["estimator"]): r for r in walk.wc.step_diffs}
    hit = {(r["share"], r["estimator"]): r for r in walk.scaled.step_diffs}
    fl = walk.wc.runs["online-float"].tables["multi-speed"]
    for est in ESTIMATORS:
        step_m = float(np.nanmedian(fl.length_m[est]))
        assert base[("arithmetic", est)]["median_abs_mm"] < 0.1, est
        assert hit[("arithmetic", est)]["median_abs_mm"] == pytest.approx(1e3 * (SCALE - 1) * step_m, rel=0.15), est
        assert hit[("arithmetic", est)]["bias_mm"] > 0.9 * 1e3 * (SCALE - 1) * step_m, est
        for share in ("adc", "algorithm"):
            assert hit[(share, est)]["median_abs_mm"] == base[(share, est)]["median_abs_mm"]
        for mode in ("single-speed", "multi-speed"):
            d0 = _ratio_diff(walk.wc.segments, mode, est)
            d1 = _ratio_diff(walk.scaled.segments, mode, est)
            assert np.median(np.abs(d0)) < 0.001, (mode, est)
            assert np.median(d1) == pytest.approx(SCALE - 1, abs=0.003), (mode, est)


def _ratio_diff(segments, mode, est, a="online_fixed", b="online_float"):
    return np.array([s[f"ratio_{a}"] - s[f"ratio_{b}"] for s in segments
                     if s["mode"] == mode and s["estimator"] == est])


def test_a_k_refitted_per_arithmetic_would_hide_the_scale_error(walk) -> None:
    """The reason for the rule: K refitted on each arithmetic's own raw lengths absorbs the 2 % (K' = K / 1.02),
    and the scaled fixed chain's distances agree with the float chain's again, for every estimator with a K
    (M5 keeps 12 %: its refitted slope absorbs the scale, its intercept K2 does not). Only M3, which has no
    K, would still show it."""
    s, sw = walk.subject, walk.sw
    sections = _sections(walk)
    pools = calibration_sets(sections)
    calib = {(x.excursion, x.index) for pool in pools["multi-speed"] for x in pool}
    evaluated = [x for x in sections if (x.excursion, x.index) not in calib and not x.turn]
    kw = dict(sampling_rate_hz=SAMPLING_RATE_HZ, leg_length_m=s.leg_length_m, foot_length_m=s.foot_length_m,
              adc_calibration=sw.calibration(10), t0_s=float(sw.times_s[0]))
    codes = sw.codes(10)
    dist = {}
    for name, ar, alg in (("float", "float", OnlineStepAlgorithm), ("scaled", "fixed", ScaledFixed)):
        raw, _ = online_step_table(codes, arithmetic=ar, algorithm=alg, **kw)
        own_k = calibrate_on_sections(raw, pools["multi-speed"], leg_length_m=s.leg_length_m,
                                      foot_length_m=s.foot_length_m)
        table, _ = online_step_table(codes, arithmetic=ar, algorithm=alg, k_fit=own_k, **kw)
        dist[name] = segment_distances(table, evaluated)
    real = np.array([x.real_m for x in evaluated])[:, None]
    refit = np.median(np.abs(dist["scaled"] - dist["float"]) / real, axis=0)
    for j, est in enumerate(ESTIMATORS):
        one_k = np.median(np.abs(_ratio_diff(walk.scaled.segments, "multi-speed", est)))
        if est == "M3":
            assert refit[j] == pytest.approx(SCALE - 1, abs=0.003)
        else:
            assert one_k == pytest.approx(SCALE - 1, abs=0.003), est
            left = 0.2 if est == "M5" else 0.05                # hidden: what is left of the 2 %
            assert refit[j] < left * (SCALE - 1), (est, refit[j])


def _table(ff, st, hs=None) -> StepTable:
    n = len(ff)
    hs = np.full(n, -1) if hs is None else np.asarray(hs)
    return StepTable(SAMPLING_RATE_HZ, 0.0, np.asarray(ff), hs, np.full(n, -1), np.asarray(st), np.zeros(n, np.int64),
                     (np.asarray(ff) - np.asarray(st)) / SAMPLING_RATE_HZ, np.zeros(n, np.int64), {}, np.zeros(n),
                     {}, {e: np.asarray(ff, float) / 100 for e in ESTIMATORS})


def test_match_steps_counts_different_events() -> None:
    a = _table([50, 80, 110, 140, 300], [20, 50, 80, 110, 140], hs=[40, 70, 100, 130, 280])
    b = _table([50, 80, 111, 140, 200], [20, 50, 80, 111, 140], hs=[40, 71, 100, 130, 190])
    m = match_steps(a, b)
    assert m.a.tolist() == [0, 1, 2, 3] and m.b.tolist() == [0, 1, 2, 3]
    assert m.same_events.tolist() == [True, False, False, False]      # heel strike, foot-flat, window start
    assert m.only_a.tolist() == [4] and m.only_b.tolist() == [4]
    assert m.n_different_events == 5
    assert m.a_of_b(5).tolist() == [0, 1, 2, 3, -1] and m.b_of_a(5).tolist() == [0, 1, 2, 3, -1]
    rows = step_differences(a, b, m, pair="a - b")
    assert rows[0]["n"] == 1 and rows[0]["median_abs_mm"] == 0.0
    rows = step_differences(a, b, m, only_same_events=False)
    assert rows[0]["n"] == 4 and rows[0]["max_abs_mm"] == pytest.approx(10.0)


def test_saturation_is_reported_on_a_recording() -> None:
    """A calibration with 4x the gain drives the on-line algorithm's force past its format: counted and
    reported."""
    from gaitlog.protocol.header import CalibrationSlot

    t = np.arange(int(30 * SAMPLING_RATE_HZ)) / SAMPLING_RATE_HZ
    codes = np.full((t.size, 3), 512, np.int64)
    codes[:, 0] = np.clip(512 + 256 + np.round(250 * np.sign(np.sin(2 * np.pi * 1.8 * t))), 0, 1023)
    hot = CalibrationSlot(np.full(3, 512.0), np.eye(3) * 4 / 256, valid=True)
    res = compare_recording(codes, sampling_rate_hz=SAMPLING_RATE_HZ, leg_length_m=0.9, foot_length_m=0.26, adc_calibration=hot)
    assert res.saturated > 0 and "saturated" in res.saturation
    # with the nominal gain, a +-0.6 g square wave (a 3 Hz range below 16 m/s^2: uncalibrated M4's range^(1/2)
    # fits its record) saturates nothing
    codes[:, 0] = np.clip(512 + 256 + np.round(150 * np.sign(np.sin(2 * np.pi * 1.8 * t))), 0, 1023)
    ok = compare_recording(codes, sampling_rate_hz=SAMPLING_RATE_HZ, leg_length_m=0.9, foot_length_m=0.26)
    assert ok.saturation == "" and ok.saturated == 0


def test_online_runs_restart_at_run_starts_and_after_missing_samples(walk) -> None:
    """The on-line algorithm is never fed a hole: a missing sample ends a run (STOP) and the next present one
    starts a new run (START), as does a SESSION_START row; without either it is one run."""
    s = walk.subject
    codes = walk.sw.codes(10)[:3000]
    kw = dict(sampling_rate_hz=SAMPLING_RATE_HZ, leg_length_m=s.leg_length_m, foot_length_m=s.foot_length_m,
              adc_calibration=walk.sw.calibration(10))
    whole, _ = online_step_table(codes, **kw)
    alg = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=_config(s), calibration=walk.sw.calibration(10))
    lag = alg.config.counts.max_step + alg.config.counts.r3 + 2     # the longest a foot-flat waits to be final
    ref = StepTable.from_online(alg.run(codes, run_starts=np.array([1200])))
    split, _ = online_step_table(codes, run_starts=np.array([1200]), **kw)
    np.testing.assert_array_equal(split.foot_flat, ref.foot_flat)
    valid = np.ones(codes.shape[0], bool)
    valid[1195:1200] = False                  # a hole just before 1200: the runs are [0, 1195) and [1200, n)
    holed, _ = online_step_table(np.where(valid[:, None], codes, 0), valid=valid, **kw)
    np.testing.assert_array_equal(holed.foot_flat[holed.foot_flat >= 1200], ref.foot_flat[ref.foot_flat >= 1200])
    early = 1195 - lag
    np.testing.assert_array_equal(holed.foot_flat[holed.foot_flat < early], ref.foot_flat[ref.foot_flat < early])
    assert np.all((holed.foot_flat < 1195) | (holed.foot_flat >= 1200))
    assert whole.n_steps > 0 and np.unique(split.bout).size == np.unique(whole.bout).size + 1   # a new bout at 1200


def _config(s):
    from gaitlog.host.files.replay import step_config_for

    return step_config_for(leg_length_m=s.leg_length_m, foot_length_m=s.foot_length_m)


def test_bootstrap_intervals_cover_the_subjects(walk) -> None:
    """Two subjects whose arithmetic share differs by a known factor: the interval runs from one subject's
    median to the other's; a subject alone gives a point."""
    from dataclasses import replace

    wc = walk.wc
    double = replace(wc, step_deltas={k: 2 * v for k, v in wc.step_deltas.items()})
    rows = bootstrap_budget([wc, double], n_resamples=500, seed=1)
    r = next(x for x in rows if x["kind"] == "step" and x["share"] == "arithmetic" and x["estimator"] == "M2")
    one = 1e3 * np.median(np.abs(wc.step_deltas[("online-fixed - online-float", "M2")]))
    assert r["ci_low"] == pytest.approx(one) and r["ci_high"] == pytest.approx(2 * one)
    assert one < r["value"] < 2 * one and r["n_subjects"] == 2
    alone = bootstrap_budget([wc], n_resamples=50)
    sec = next(x for x in alone if x["kind"] == "section" and x["share"] == "arithmetic" and x["estimator"] == "M2"
               and x["mode"] == "multi-speed")
    assert sec["ci_low"] == sec["value"] == sec["ci_high"]
    assert sec["value"] == pytest.approx(np.median(_ratio_diff(wc.segments, "multi-speed", "M2")))
