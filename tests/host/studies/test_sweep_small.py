"""gaitlog.host.studies.sweep on one subject and a short protocol: the physics of quantisation and timing are the references."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.host.studies.sweep import AdcRateSweep, format_m5, format_summary


@pytest.fixture(scope="module")
def sweep() -> AdcRateSweep:
    from gaitlog.firmware_sim.world.walk_plan import WalkPlan

    walk_plan = WalkPlan(corridor_length_m=60.0, speeds=("preferred", "fast"), rest_s=10.0,
                               rest_postures=("standing",), lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 90.0, 110.0,
                                                                         120.0))
    ticks = []
    sw = AdcRateSweep(n_subjects=1, seed=2, adc_bits=(8, 10, 12), rates_hz=(25.0, 100.0), walk_plan=walk_plan).run(
        progress=lambda: ticks.append(len(ticks)))
    sw.ticks = ticks
    return sw


def row(sweep, adc_bits, rate, est, mode="multi-speed"):
    return next(r for r in sweep.summary_ if r["adc_bits"] == adc_bits and r["sampling_rate_hz"] == rate and r["estimator"] == est
                and r["mode"] == mode)


def test_every_configuration_is_there(sweep) -> None:
    assert sweep.ticks == [0]                   # progress: once per subject (all its configurations)
    assert {(r.adc_bits, r.sampling_rate_hz) for r in sweep.results_} == {(b, f) for b in (8, 10, 12) for f in (25.0, 100.0)}
    assert len(sweep.summary_) == 6 * 2 * 5
    text = format_summary(sweep.summary_) + format_m5(sweep.m5_)
    assert "multi-speed calibration" in text and "M5 (offline chain, 10-bit codes)" in text


@pytest.mark.parametrize("rate", [25.0, 100.0])
def test_adc_share_shrinks_with_bits(sweep, rate) -> None:
    """M2's quantisation error per step: two more bits, a quarter of the LSB; the median falls by ~2-8x."""
    e8, e10, e12 = (row(sweep, b, rate, "M2")["adc_step_mm"] for b in (8, 10, 12))
    assert e8 > e10 > e12 > 0
    assert 2.0 < e8 / e10 < 8.0 and 2.0 < e10 / e12 < 8.0


@pytest.mark.parametrize("rate", [25.0, 100.0])
def test_m1_adc_share_is_a_bias_of_where_one_g_falls(sweep, rate) -> None:
    """M1 has no drift correction: its quantisation error is dominated by the constant offset of 1 g from the
    nearest code, double-integrated over the step, which depends on where 1 g falls between codes rather than
    monotonically on the bit count. It still ends smaller at 12 bits than at 8, and stays below half an 8-bit
    LSB (7.8 mg = 0.077 m/s^2) integrated twice over a 0.6 s step: 0.5 * 0.077 * 0.36 = 14 mm."""
    e8, e10, e12 = (row(sweep, b, rate, "M1")["adc_step_mm"] for b in (8, 10, 12))
    assert e12 < e8
    assert max(e8, e10, e12) < 14.0


def test_arithmetic_share_is_a_tenth_of_a_millimetre_everywhere(sweep) -> None:
    """The on-line algorithm in fixed vs float point, one K per configuration: 0.01-0.11 mm per step (median)
    at every width and rate, at most 0.07 % of a step; nothing saturates."""
    for r in sweep.summary_:
        assert r["arith_step_mm"] <= 0.15, r
        assert r["arith_step_max_rel"] <= 0.002, r
        assert r["saturated"] == 0, r


@pytest.mark.parametrize("rate", [25.0, 100.0])
def test_algorithm_share_does_not_depend_on_the_adc(sweep, rate) -> None:
    """online-float - offline is the algorithms' difference (causal gravity, on-line events), not the
    converter's: the same within 10 % at 8, 10 and 12 bits, and tens of times the arithmetic's share."""
    for est in ("M1", "M2", "M4"):
        a = [row(sweep, b, rate, est)["algorithm_step_mm"] for b in (8, 10, 12)]
        assert max(a) <= 1.1 * min(a), (est, a)
        assert min(a) > 10 * max(row(sweep, b, rate, est)["arith_step_mm"] for b in (8, 10, 12)), est


def test_step_timing_error_falls_with_the_rate(sweep) -> None:
    rows = {(r["mode"], r["sampling_rate_hz"]): r for r in sweep.m5_["rows"]}
    assert set(rows) == {(m, f) for m in ("single-speed", "multi-speed") for f in (25.0, 100.0)}
    # duration error against the world's truth: the sample period dominates at 25 Hz (40 ms)
    assert rows[("multi-speed", 25.0)]["timing_rms_ms"] > rows[("multi-speed", 100.0)]["timing_rms_ms"]
    for r in rows.values():
        assert 0.0 <= r["timing_share"] <= 1.0
        # a sample period alone cannot exceed the measured duration error (detection adds to it)
        assert r["sampling_rms_ms"] <= r["timing_rms_ms"] + 1.0
    assert sweep.m5_["verdict"] == ""              # no 50 Hz configuration, no verdict


def _m5_results(timing_sd: dict[float, float], model_sd: float = 0.03) -> list:
    from gaitlog.host.studies.sweep import ConfigResult

    rng = np.random.default_rng(0)
    model = rng.normal(1.0, model_sd, 400)               # per-section model error, the same at every rate
    out = []
    for rate, sd in timing_sd.items():
        tim = rng.normal(0.0, sd, model.size)
        segs = [dict(mode="multi-speed", estimator="M5", ratio_offline=m + t, ratio_exact_timing=m)
                for m, t in zip(model, tim)]
        out.append(ConfigResult("S00", 10, rate, [], segs, dict(rms_ms=1000 / rate / 6 ** 0.5), "", 0, 0, 0.0))
    return out


def test_m5_answer_no_when_the_model_dominates() -> None:
    from gaitlog.host.studies.sweep import m5_timing_answer

    ans = m5_timing_answer(_m5_results({25.0: 0.004, 50.0: 0.002, 100.0: 0.001}))
    share = {r["sampling_rate_hz"]: r["timing_share"] for r in ans["rows"]}
    assert share[25.0] > share[50.0] > share[100.0] >= 0.0
    assert share[50.0] == pytest.approx(0.002 ** 2 / (0.03 ** 2 + 0.002 ** 2), abs=0.01)
    assert ans["verdict"].startswith("no:")


def test_m5_answer_yes_when_timing_dominates_and_a_faster_rate_helps() -> None:
    from gaitlog.host.studies.sweep import m5_timing_answer

    ans = m5_timing_answer(_m5_results({25.0: 0.08, 50.0: 0.04, 100.0: 0.02}, model_sd=0.01))
    assert ans["verdict"].startswith("yes:")
