"""The README's error-budget figures, as ``gaitlog compare --simulate 4`` and ``gaitlog sweep`` give them.

Four simulated subjects (seed 0) walk the paper's protocol; one K per mode and configuration, fitted on the
offline chain, for every chain. The per-step and per-section figures are recomputed here from the CSVs the
commands write (not by the code under test) and pinned near what is measured. Each command runs once
(~10 s each on 2 workers).
"""

from __future__ import annotations

import contextlib
import csv
import io
from types import SimpleNamespace

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.cli import main


def _run(argv: list[str]) -> str:
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(argv) == 0
    return text.getvalue()


def _csv(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "sim.csv"
    text = _run(["compare", "--simulate", "4", "--population", "v1", "--workers", "2", "--out", str(out)])
    return SimpleNamespace(text=text, steps=_csv(out), segments=_csv(out.with_name("sim_segments.csv")),
                           budget=_csv(out.with_name("sim_budget.csv")))


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")                 # the default grid: 8/10/12 bits x 25/50/100 Hz, 4 subjects
    text = _run(["sweep", "--population", "v1", "--workers", "2", "--out", str(out)])
    return SimpleNamespace(text=text, summary=_csv(out / "summary.csv"), splits=_csv(out / "splits.csv"),
                           tasks=_csv(out / "tasks.csv"), m5=_csv(out / "m5_rate.csv"))


def _col(rows, name) -> np.ndarray:
    return np.array([float(r[name]) if r[name] != "" else np.nan for r in rows])


def _per_step_mm(rows, est, a, b, same) -> np.ndarray:
    e = est.lower()
    x, y = _col(rows, f"{e}_{a}_m"), _col(rows, f"{e}_{b}_m")
    g = np.array([r[same] == "1" for r in rows]) & np.isfinite(x) & np.isfinite(y)
    return 1e3 * np.abs(x[g] - y[g])


# pooled per-step median |a - b|, mm (4 subjects, ~4,300 steps; multi-speed K)
PER_STEP_MM = {
    ("offline", "ideal", "same_events_adc"): {"M1": 0.69, "M2": 0.27, "M4": 0.128},
    ("online_float", "offline", "same_events_algorithm"): {"M1": 10.7, "M2": 9.6, "M4": 3.79},
    ("online_fixed", "online_float", "same_events_arithmetic"): {"M1": 0.054, "M2": 0.028, "M4": 0.020},
}


@pytest.mark.parametrize("pair", list(PER_STEP_MM))
def test_the_error_split_per_step(simulated, pair) -> None:
    a, b, same = pair
    for est, measured in PER_STEP_MM[pair].items():
        d = _per_step_mm(simulated.steps, est, a, b, same)
        assert d.size > 3500, (pair, est)
        assert np.median(d) == pytest.approx(measured, rel=0.1), (pair, est)


def test_arithmetic_share_is_below_a_tenth_of_a_millimetre_and_the_adc_above_it(simulated) -> None:
    for est in ESTIMATORS:
        ar = np.median(_per_step_mm(simulated.steps, est, "online_fixed", "online_float", "same_events_arithmetic"))
        assert ar <= 0.1, est
        if est != "M5":                          # M5 reads only the step duration, which the ADC does not move
            assert np.median(_per_step_mm(simulated.steps, est, "offline", "ideal", "same_events_adc")) > ar, est


def test_the_error_split_per_section(simulated) -> None:
    """Multi-speed K, 96 sections: the arithmetic moves a section ratio by <= 2e-4, the algorithm by up to 0.03
    (its median +0.0007 ... +0.0035), the ADC by ~0 (median) and 0.012 at most (M1)."""
    seg = [r for r in simulated.segments if r["mode"] == "multi-speed"]
    for est, alg_median in (("M1", 0.0007), ("M2", 0.0035), ("M4", 0.0014)):
        s = [r for r in seg if r["estimator"] == est]
        assert len(s) == 96
        ar = _col(s, "ratio_online_fixed") - _col(s, "ratio_online_float")
        alg = _col(s, "ratio_online_float") - _col(s, "ratio_offline")
        adc = _col(s, "ratio_offline") - _col(s, "ratio_ideal")
        assert np.max(np.abs(ar)) <= 2e-4, est
        assert np.median(alg) == pytest.approx(alg_median, abs=0.001), est
        assert np.max(np.abs(alg)) <= 0.035, est
        assert abs(np.median(adc)) <= 1e-4 and np.max(np.abs(adc)) <= 0.015, est
    m2 = [r for r in seg if r["estimator"] == "M2"]
    q = {k: np.subtract(*np.percentile(_col(m2, f"ratio_{k}"), [75, 25])) for k in ("online_float", "offline")}
    assert q["online_float"] == pytest.approx(0.028, abs=0.002) and q["offline"] == pytest.approx(0.049, abs=0.002)


def test_event_differences_between_the_arithmetics_are_rare(simulated) -> None:
    st = simulated.steps
    matched = np.array([int(r["online_fixed_step"]) >= 0 for r in st])
    same = np.array([r["same_events_arithmetic"] == "1" for r in st])
    assert matched.sum() > 4000 and (matched & ~same).sum() <= 15


def test_bootstrap_intervals_are_written_and_printed(simulated) -> None:
    """95 % intervals over the 4 subjects (2000 resamples, seed 0): each contains its figure; the arithmetic
    share's is narrow (M2 0.026-0.030 mm), the algorithm's wide (M2 7.9-11.1 mm)."""
    rows = simulated.budget
    assert {r["kind"] for r in rows} == {"step", "section"} and all(r["n_subjects"] == "4" for r in rows)
    for r in rows:
        v, lo, hi = float(r["value"]), float(r["ci_low"]), float(r["ci_high"])
        assert lo - 1e-12 <= v <= hi + 1e-12, r
    by = {(r["kind"], r["share"], r["mode"], r["estimator"]): r for r in rows}
    ar = by[("step", "arithmetic", "multi-speed", "M2")]
    assert float(ar["ci_low"]) == pytest.approx(0.026, abs=0.003) and float(ar["ci_high"]) == pytest.approx(
        0.030, abs=0.003)
    alg = by[("step", "algorithm", "multi-speed", "M2")]
    assert float(alg["ci_low"]) == pytest.approx(7.9, rel=0.1) and float(alg["ci_high"]) == pytest.approx(11.1,
                                                                                                          rel=0.1)
    assert "95 % bootstrap intervals over 4 subject(s) (2000 resamples" in simulated.text
    assert "saturation/wrap in the fixed-point runs: none" in simulated.text


def _summary(sweep, adc_bits, rate, est, mode="multi-speed"):
    return next(r for r in sweep.summary if int(r["adc_bits"]) == adc_bits and float(r["sampling_rate_hz"]) == rate
                and r["estimator"] == est and r["mode"] == mode)


def test_sweep_adc_share_at_50_hz(sweep) -> None:
    """ADC share per step at 8 / 10 / 12 bits, 50 Hz: M1 2.9 / 0.71 / 0.18 mm (a quarter per two bits)."""
    for adc_bits, measured in ((8, 2.92), (10, 0.71), (12, 0.18)):
        assert float(_summary(sweep, adc_bits, 50.0, "M1")["adc_step_mm"]) == pytest.approx(measured, rel=0.1)


def test_sweep_arithmetic_share_everywhere(sweep) -> None:
    """The arithmetic share per step: 0.015-0.083 mm (median) in every configuration, nothing saturates; its
    largest relative difference is below 0.5 % everywhere but for M1 at 25 Hz / 8 bits: 2.2 % on one step (with
    the stop rule; before it, one 2 cm shuffle step at 25 Hz / 10 bits differed by 25 %, now 0.27 %)."""
    assert len(sweep.summary) == 9 * 2 * 5
    arith = np.array([float(r["arith_step_mm"]) for r in sweep.summary])
    assert arith.min() == pytest.approx(0.015, abs=0.003) and arith.max() == pytest.approx(0.083, abs=0.01)
    assert len(sweep.tasks) == 9 * 4
    for r in sweep.tasks:
        assert int(r["saturated"]) == 0 and int(r["wrapped"]) == 0, r
    worst_rel: dict[tuple, list[float]] = {}             # per configuration and estimator, over the subjects
    for r in sweep.splits:
        if r["share"] == "arithmetic":
            key = (r["adc_bits"], float(r["sampling_rate_hz"]), r["estimator"])
            worst_rel.setdefault(key, []).append(float(r["max_rel"] or "nan"))
    assert len(worst_rel) == 9 * 5
    for (adc_bits, rate, est), values in worst_rel.items():
        worst = float(np.nanmax(values))
        if (adc_bits, rate) == ("10", 25.0) and est in ("M1", "M2", "M4"):
            assert worst <= {"M1": 0.30, "M2": 0.035, "M4": 0.022}[est], (adc_bits, rate, est, worst)
        elif (adc_bits, rate, est) == ("8", 25.0, "M1"):
            assert worst <= 0.03, (adc_bits, rate, est, worst)
        else:
            assert worst <= 0.005, (adc_bits, rate, est, worst)


def test_sweep_m5_timing_answer(sweep) -> None:
    """M5 (offline chain, 10 bits, multi-speed K): IQR 0.0147 / 0.0141 / 0.0151 at 25 / 50 / 100 Hz, 0.0131 with
    the world's step durations and the same K: the 50 Hz step timing is not where M5's spread comes from (what it
    adds stays within 1 % from the lowest swept rate on)."""
    m5 = {(r["mode"], float(r["sampling_rate_hz"])): r for r in sweep.m5}
    for rate, measured in ((25.0, 0.0147), (50.0, 0.0141), (100.0, 0.0151)):
        assert float(m5[("multi-speed", rate)]["iqr"]) == pytest.approx(measured, abs=0.0005)
    assert float(m5[("multi-speed", 50.0)]["iqr_exact"]) == pytest.approx(0.0131, abs=0.0005)
    assert "M5's step-timing error does not matter from the lowest swept rate, 25 Hz, on" in sweep.text
