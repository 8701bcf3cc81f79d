"""host.sweep on one subject and a short protocol: the physics of quantisation and timing are the references."""

from __future__ import annotations

import numpy as np
import pytest

from host.sweep import AdcRateSweep, format_m5, format_summary


@pytest.fixture(scope="module")
def sweep() -> AdcRateSweep:
    from firmware_sim.world.gait_protocol import WalkingProtocol

    protocol = WalkingProtocol(corridor_length_m=60.0, speeds=("preferred", "fast"), rest_s=10.0,
                               rest_postures=("standing",), lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 90.0, 110.0,
                                                                         120.0))
    return AdcRateSweep(n_subjects=1, seed=2, bits=(8, 10, 12), rates_hz=(25.0, 100.0), protocol=protocol).run()


def row(sweep, bits, rate, est, mode="multi-speed"):
    return next(r for r in sweep.summary_ if r["bits"] == bits and r["rate_hz"] == rate and r["estimator"] == est
                and r["mode"] == mode)


def test_every_configuration_is_there(sweep) -> None:
    assert {(r.bits, r.rate_hz) for r in sweep.results_} == {(b, f) for b in (8, 10, 12) for f in (25.0, 100.0)}
    assert len(sweep.summary_) == 6 * 2 * 5
    text = format_summary(sweep.summary_) + format_m5(sweep.m5_)
    assert "multi-speed calibration" in text and "M5 (float chain, 10-bit codes)" in text


@pytest.mark.parametrize("est", ["M1", "M2"])
@pytest.mark.parametrize("rate", [25.0, 100.0])
def test_adc_share_shrinks_with_bits(sweep, est, rate) -> None:
    """Quantisation error per step: two more bits, a quarter of the LSB; the median falls by ~2-8x."""
    e8, e10, e12 = (row(sweep, b, rate, est)["adc_step_mm"] for b in (8, 10, 12))
    assert e8 > e10 > e12 > 0
    assert 2.0 < e8 / e10 < 8.0 and 2.0 < e10 / e12 < 8.0


def test_arithmetic_share_is_below_a_millimetre_everywhere(sweep) -> None:
    for r in sweep.summary_:
        assert r["arith_step_mm"] <= 1.0, r
        assert r["saturated"] == 0, r
        if r["estimator"] != "M3":          # M3's single-support excursion can flip on near-ties at 25 Hz
            assert r["arith_step_max_rel"] <= 0.01, r


def test_step_timing_error_falls_with_the_rate(sweep) -> None:
    rows = {(r["mode"], r["rate_hz"]): r for r in sweep.m5_["rows"]}
    assert set(rows) == {(m, f) for m in ("single-speed", "multi-speed") for f in (25.0, 100.0)}
    # duration error against the world's truth: the sample period dominates at 25 Hz (40 ms)
    assert rows[("multi-speed", 25.0)]["timing_rms_ms"] > rows[("multi-speed", 100.0)]["timing_rms_ms"]
    for r in rows.values():
        assert 0.0 <= r["timing_share"] <= 1.0
        assert r["std_timing"] <= r["std"] + 1e-12 or r["timing_share"] > 0.5
    assert sweep.m5_["verdict"] == ""              # no 50 Hz configuration, no verdict


def test_m5_answer_with_50_hz() -> None:
    from host.sweep import ConfigResult, m5_timing_answer

    rng = np.random.default_rng(0)
    model = rng.normal(1.0, 0.03, 40)               # per-section model error, the same at every rate
    results = []
    for rate, timing in ((25.0, 0.004), (50.0, 0.002), (100.0, 0.001)):
        tim = rng.normal(0.0, timing, 40)
        segs = [dict(mode="multi-speed", estimator="M5", ratio_float=m + t, ratio_exact_timing=m)
                for m, t in zip(model, tim)]
        results.append(ConfigResult("S00", 10, rate, [], segs, dict(rms_ms=1000 / rate / 6 ** 0.5), "", 0, 0, 0.0))
    ans = m5_timing_answer(results)
    share = {r["rate_hz"]: r["timing_share"] for r in ans["rows"]}
    assert share[25.0] > share[50.0] > share[100.0]
    assert share[50.0] == pytest.approx(0.002 ** 2 / 0.03 ** 2, rel=0.6)
    assert ans["verdict"].startswith("no:")
