"""The paper's evaluation on the real IPOL recordings replayed through the emulated logger (50 Hz, 10 bits), with
the logger's on-line step algorithm on; the offline chain and the on-line algorithm in float and in fixed point
with ONE K per subject (fitted on trial 1 with the offline chain).

``gaitlog evaluate ipol`` runs once (module fixture, ~40 s of CPU); every figure is computed here from the CSVs it writes (not by the code under
test) and pinned near what is measured. Every step between the trial boundaries is summed (U-turn included), K
is the first trial's alone (the K prior's gain has a 95 % subject-bootstrap interval that includes zero), short
gaps are interpolated (``gaitlog.host.gait.gaps``). M5's interquartile range misses issue 4's 0.10 (strict
expected failure): with K fitted on one 20 m trial at one speed, even the *reference* step events give M5 an IQR
of 0.109. Issue 12's M4 IQR <= 0.06, best IQR <= 0.05 and M3 within 1 +- 0.05 are strict expected failures
under these rules (their reasons say by how much).

The constants chosen on these trials (:mod:`gaitlog.host.studies.tuning`: the heel-strike rule, ``hs_delay_s``,
the stop rule, ``prominence_fraction``, M4's exponent) are chosen leave-one-subject-out by the command: every
offline-chain figure is cross-validated; the on-line chains run the shipped defaults (cross-validated only for
the subject whose fold chose them). K is fitted per subject on trial 1 and scored on the others, never on the
trial it scores.
"""

from __future__ import annotations

import csv
import re
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.cli import main
from gaitlog.host.gait.k_prior import LOWER_BACK_PRIOR

pytestmark = pytest.mark.slow  # ~5 s: 52 trials through the emulated logger, once per module


@pytest.fixture(scope="module")
def folder(shared_data):
    f = shared_data / "ipol-lowerback-dev"
    if not f.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    return f


@pytest.fixture(scope="module")
def ipol(folder, tmp_path_factory):
    import contextlib
    import io

    out = tmp_path_factory.mktemp("ipol") / "eval.csv"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["evaluate", "ipol", str(folder), "--out", str(out)]) == 0
    assert out.with_suffix(".png").stat().st_size > 1000
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(out.with_name("eval_steps.csv"), newline="") as fh:
        steps = list(csv.DictReader(fh))
    with open(out.with_name("eval_events.csv"), newline="") as fh:
        events = list(csv.DictReader(fh))
    return SimpleNamespace(rows=rows, steps=steps, events=events, text=text.getvalue())


def ratios(rows, name, arithmetic="offline", k_from="offline", variant="main"):
    return np.array([float(r["ratio"]) for r in rows if r["estimator"] == name and r["arithmetic"] == arithmetic
                     and r["k_from"] == k_from and r["variant"] == variant])


def ratio_pairs(rows, name, a, b):
    by = {(r["subject"], r["trial"], r["arithmetic"]): float(r["ratio"]) for r in rows
          if r["estimator"] == name and r["k_from"] == "offline" and r["variant"] == "main"}
    keys = sorted({k[:2] for k in by})
    return np.array([by[k + (a,)] for k in keys]), np.array([by[k + (b,)] for k in keys])


def iqr(x):
    q1, q3 = np.percentile(x, [25, 75])
    return q3 - q1


def test_csv_layout(ipol) -> None:
    rows = ipol.rows
    assert list(rows[0]) == ["subject", "trial", "estimator", "arithmetic", "k_from", "uturn", "lengths_source",
                             "variant", "walked_distance_m", "distance_m", "ratio", "steps", "reference_steps", "steps_outside_k_range",
                             "cross_validated"]
    kinds = {(r["arithmetic"], r["k_from"], r["variant"], r["uturn"], r["lengths_source"]) for r in rows}
    assert kinds == {("offline", "offline", "main", "include", "subject-height"),
                     ("online-float", "offline", "main", "include", "subject-height"),
                     ("online-fixed", "offline", "main", "include", "subject-height"),
                     ("online-fixed", "own", "main", "include", "subject-height"),
                     ("offline", "offline", "uturn-exclude", "exclude", "subject-height"),
                     ("offline", "offline", "height-unknown", "include", "assumed-height"),
                     ("offline", "offline", "m4-per-fold", "include", "subject-height"),
                     ("offline", "offline", "m3-single-support-speed", "include", "subject-height"),
                     ("offline", "offline", "k-prior", "include", "subject-height"),
                     ("offline", "offline", "m4-range-share", "include", "subject-height"),
                     ("offline", "offline", "m4-duration-share", "include", "subject-height"),
                     ("online-fixed", "offline", "m4-range-share", "include", "subject-height"),
                     ("online-fixed", "offline", "m4-duration-share", "include", "subject-height"),
                     ("offline", "offline", "baseline", "include", "subject-height")} | {
        ("online-fixed", "offline", v, "include", "subject-height")
        for v in ("stop-v3", "prominence-fixed", "m4-quarter", "m4-half")}
    # 52 trials - 9 calibration trials, 5 estimators, 17 kinds; the baseline's M2 and M4
    assert len(rows) == 17 * 5 * 43 + 2 * 43
    for r in rows:
        assert r["walked_distance_m"] == "20"        # the IPOL protocol's, no JSON of the dev set states another
        assert float(r["distance_m"]) == pytest.approx(20.0 * float(r["ratio"]), rel=1e-3)


def test_device_records_equal_the_host_replay(ipol) -> None:
    """Issue 10 (a): every trial's stored step records are the host's replay byte for byte (1,982 records)."""
    m = re.search(r"device step records = host replay, byte for byte: (\d+) of (\d+) trials, (\d+) of (\d+) records",
                  ipol.text)
    assert m, ipol.text
    a, b, c, d = map(int, m.groups())
    assert a == b == 52 and c == d and d >= 1900


def test_device_records_are_the_algorithm_run_here(folder) -> None:
    """The same, checked without gaitlog.host.files.replay on three trials: the algorithm built here from the header's
    configuration, run over the stored codes, gives the stored records field by field."""
    from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
    from gaitlog.host.files.ipol import list_trials
    from gaitlog.host.studies.ipol_evaluation import replay_trial
    from gaitlog.protocol.steps import STEP_RECORD_DTYPE

    for path in list_trials(folder)[:3]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            rt = replay_trial(path)
        h = rt.header
        assert h.step_config.enabled and not h.step_config.calibrated
        alg = OnlineStepAlgorithm(sampling_rate_hz=h.sampling_rate_hz, step_config=h.step_config,
                                  calibration=h.calibration, arithmetic="fixed", adc_bits=h.adc_bits)
        mine = alg.run(rt.codes).to_records(int(rt.sample_numbers[0]))
        dev = rt.device_records
        assert dev.size == mine.size > 20, path.name
        for name in STEP_RECORD_DTYPE.names:
            if name != "record_crc":
                np.testing.assert_array_equal(dev[name], mine[name], err_msg=f"{path.name}: {name}")


def test_arithmetic_share_per_step(ipol) -> None:
    """Issue 10 (c): on-line fixed vs on-line float, same codes, same K, per step: median |d| <= 0.1 mm
    (0.015-0.063 mm measured) and at most 1 % of a step (0.29 %); events differ on 6 of 1,981 matched steps."""
    measured_mm = {"M1": 0.057, "M2": 0.028, "M3": 0.026, "M4": 0.023, "M5": 0.012}
    st = ipol.steps
    same = np.array([r["same_events_arithmetic"] == "1" for r in st])
    matched = np.array([int(r["online_fixed_step"]) >= 0 for r in st])
    assert matched.sum() >= 0.99 * len(st) and len(st) > 1900
    assert (matched & ~same).sum() <= 0.01 * matched.sum()
    for e in ESTIMATORS:
        k = e.lower()
        x = np.array([float(r[f"{k}_online_fixed_m"] or "nan") for r in st])
        y = np.array([float(r[f"{k}_online_float_m"] or "nan") for r in st])
        g = same & np.isfinite(x) & np.isfinite(y)
        assert g.sum() > 1500, e
        d = np.abs(x[g] - y[g])
        assert 1e3 * np.median(d) <= 0.1, e
        assert 1e3 * np.median(d) == pytest.approx(measured_mm[e], rel=0.2), e
        assert np.max(d / y[g]) <= 0.01, e
        assert np.max(d / y[g]) <= 0.004, e                 # measured 0.29 % at most (M1)


def test_arithmetic_share_in_distance(ipol) -> None:
    """Per trial, |ratio fixed - ratio float| median ~1e-4; at most 0.017 (M1, one trial: 0.0034 when the U-turn
    steps were left out); the same steps counted."""
    for e in ESTIMATORS:
        a, b = ratio_pairs(ipol.rows, e, "online-fixed", "online-float")
        assert a.size == 43
        assert np.median(np.abs(a - b)) <= 3e-4, e
        assert np.max(np.abs(a - b)) <= 0.02, e
    steps = {(r["subject"], r["trial"], r["arithmetic"]): r["steps"] for r in ipol.rows if r["k_from"] == "offline"}
    for (s, t, a), n in steps.items():
        if a == "online-fixed":
            assert n == steps[(s, t, "online-float")], (s, t)


# measured median |ratio on-line float - ratio offline| per trial (43 trials, one K from the offline chain)
ALGORITHM_SHARE = {"M1": 0.0109, "M2": 0.0096, "M3": 0.0086, "M4": 0.0040, "M5": 0.0014}


@pytest.mark.parametrize("name", ESTIMATORS)
def test_algorithm_share_in_distance(ipol, name) -> None:
    """Issue 10 (c): on-line float vs offline float, one K: median |d ratio| <= 0.01 for M2 and M4; all five
    pinned near what is measured (steps counted differently by one or two, in a few trials, make the max)."""
    a, b = ratio_pairs(ipol.rows, name, "online-float", "offline")
    med = float(np.median(np.abs(a - b)))
    if name in ("M2", "M4"):
        assert med <= 0.01
    assert med == pytest.approx(ALGORITHM_SHARE[name], abs=0.002)
    printed = ipol.text.split("on-line float vs offline, distance ratio per trial")[1].split("\n")[0]
    # the CSV's ratios are rounded (6 digits): a median on a rounding tie may print 1e-4 apart
    assert float(printed.split(f"{name} ")[1].split()[0]) == pytest.approx(med, abs=0.00006)


@pytest.mark.parametrize("arithmetic", ["online-float", "online-fixed"])
@pytest.mark.parametrize("name, measured", [("M2", 1.003), ("M4", 0.992)])
def test_calibrated_online_median(ipol, arithmetic, name, measured) -> None:
    """Issue 10 (c): the on-line algorithm with the offline chain's K: M2 and M4 median ratio within 1 +- 0.03."""
    med = np.median(ratios(ipol.rows, name, arithmetic))
    assert abs(med - 1.0) <= 0.03
    assert med == pytest.approx(measured, abs=0.005)


@pytest.mark.parametrize("name, measured", [("M1", 1.028), ("M2", 1.003), ("M4", 0.994), ("M5", 1.017)])
def test_own_k_as_the_device_would_be_used(ipol, name, measured) -> None:
    """The on-line fixed algorithm with its own K (a different K: fitted on its own records of trial 1)."""
    assert "a different K, not a comparison" in ipol.text
    r = ratios(ipol.rows, name, "online-fixed", "own")
    assert r.size == 43
    assert np.median(r) == pytest.approx(measured, abs=0.005)
    if name == "M4":
        assert iqr(r) == pytest.approx(0.1165, abs=0.005)


# The documentation's IPOL table (docs/validation/ipol.md): median ratio, IQR (and min, max offline) with the
# offline chain's K (the first trial's, no prior), every step between the trial boundaries summed
README_TABLE = {
    "offline": {"M1": (1.019, 0.072, 0.901, 1.098), "M2": (1.003, 0.056, 0.880, 1.105),
                "M3": (1.088, 0.081, 0.971, 1.201), "M4": (0.996, 0.101, 0.857, 1.117),
                "M5": (1.011, 0.165, 0.780, 1.233)},
    "online-fixed": {"M1": (1.020, 0.078), "M2": (1.003, 0.055), "M3": (1.083, 0.081), "M4": (0.992, 0.101),
                     "M5": (1.000, 0.179)},
}


@pytest.mark.parametrize("arithmetic", list(README_TABLE))
@pytest.mark.parametrize("name", ESTIMATORS)
def test_readme_table(ipol, arithmetic, name) -> None:
    r = ratios(ipol.rows, name, arithmetic)
    want = README_TABLE[arithmetic][name]
    got = (np.median(r), iqr(r), r.min(), r.max())[:len(want)]
    np.testing.assert_allclose(got, want, atol=0.0015)


def test_readme_states_the_pinned_table() -> None:
    """The documentation's IPOL table says what :data:`README_TABLE` pins (its rows, to the printed 3 decimals)."""
    text = (Path(__file__).resolve().parents[3] / "docs" / "validation" / "ipol.md").read_text(encoding="utf-8")
    table = text.split("| estimator | offline: median ratio | IQR | min – max | on-line fixed: median | IQR |")[1]
    for name in ESTIMATORS:
        row = next(ln for ln in table.splitlines() if ln.startswith(f"| {name} "))
        cells = [c.strip() for c in row.strip("|").split("|")]
        off, fx = README_TABLE["offline"][name], README_TABLE["online-fixed"][name]
        first = [c.split(" [")[0] for c in cells[1:6]]       # medians and IQRs carry their 95 % intervals
        assert first == [f"{off[0]:.3f}", f"{off[1]:.3f}", f"{off[2]:.3f} – {off[3]:.3f}", f"{fx[0]:.3f}",
                         f"{fx[1]:.3f}"], name
        assert all(re.fullmatch(r"[0-9.]+ \[[0-9.]+, [0-9.]+\]", cells[j]) for j in (1, 2, 4, 5)), row


@pytest.mark.xfail(strict=True, reason="with Weinberg's 1/4 (the exponent 1/2 did not pass the rule for choices), "
                   "the on-line M4 IQR is 0.1007 [0.056, 0.142]: over 0.10 by less than its interval is wide")
def test_online_m4_iqr_meets_the_target(ipol) -> None:
    """Issue 4's 0.10: with the offline chain's K, the on-line algorithm's M4 IQR (0.1007; offline 0.1008)."""
    assert iqr(ratios(ipol.rows, "M4", "online-fixed")) <= 0.10


@pytest.mark.parametrize("name", ["M2", "M4", "M5"])
def test_calibrated_median(ipol, name) -> None:
    assert abs(np.median(ratios(ipol.rows, name)) - 1.0) <= 0.03


def test_m2_iqr(ipol) -> None:
    assert iqr(ratios(ipol.rows, "M2")) <= 0.10


@pytest.mark.xfail(strict=True, reason="with Weinberg's 1/4 M4's IQR is 0.1008 [0.054, 0.139] (the exponent chosen "
                   "per fold, not kept by the rule for choices: 0.092)")
def test_m4_iqr(ipol) -> None:
    """Issue 4's 0.10 (missed by 0.001: 0.1008)."""
    assert iqr(ratios(ipol.rows, "M4")) <= 0.10


@pytest.mark.parametrize("name", [
    "M2", pytest.param("M4", marks=pytest.mark.xfail(strict=True, reason=(
        "M4's IQR is 0.101 with the first trial's K and Weinberg's 1/4 (the K prior, 0.062, and the exponent "
        "chosen per fold, 0.092, are not kept: their gains' 95 % subject-bootstrap intervals include zero)")))])
def test_issue12_calibrated_iqr(ipol, name) -> None:
    """Issue 12: calibrated M2 and M4, median within 1 +- 0.02 (met: 1.003, 0.996) and IQR <= 0.06 (M2 0.056 met,
    M4 0.101 missed), K per subject from its first trial, every step of the trial summed."""
    r = ratios(ipol.rows, name)
    assert abs(np.median(r) - 1.0) <= 0.02
    assert iqr(r) <= 0.06


@pytest.mark.xfail(strict=True, reason="the best calibrated IQR is M2's 0.056 with the first trial's K (0.044 with the "
                   "K prior, not kept: its gain's interval includes zero)")
def test_issue12_best_calibrated_iqr(ipol) -> None:
    """Issue 12: the best calibrated estimator's IQR <= 0.05 (M2 0.056, M1 0.072, M4 0.101, M5 0.165)."""
    assert min(iqr(ratios(ipol.rows, e)) for e in ("M1", "M2", "M4", "M5")) <= 0.05


@pytest.mark.xfail(strict=True, reason="M3 without K reads long through its double-support term (the foot length, "
                   "0.111 x height, where the trials' distance asks for 0.145 m a step; the pendulum term is right "
                   "within 1.5 %, host/studies/ipol_m3.py): with every step summed, median 1.088 (offline), 1.083 "
                   "(on-line fixed); the double support at the single support's speed 0.980 but IQR 0.091")
@pytest.mark.parametrize("arithmetic", ["offline", "online-fixed"])
def test_issue12_m3_without_k(ipol, arithmetic) -> None:
    """Issue 12: M3 without K, median within 1 +- 0.05 and IQR <= 0.08."""
    r = ratios(ipol.rows, "M3", arithmetic)
    assert abs(np.median(r) - 1.0) <= 0.05 and iqr(r) <= 0.08


@pytest.mark.xfail(reason="M5 calibrated on one speed: IQR >= 0.109 even with reference step events", strict=True)
def test_m5_iqr(ipol) -> None:
    assert iqr(ratios(ipol.rows, "M5")) <= 0.10


def test_m3_uncalibrated_median(ipol) -> None:
    assert abs(np.median(ratios(ipol.rows, "M3")) - 1.0) <= 0.10
    assert abs(np.median(ratios(ipol.rows, "M3", variant="uturn-exclude")) - 1.0) <= 0.05


@pytest.mark.parametrize("arithmetic", ["offline", "online-fixed"])
def test_step_count_median_error(ipol, arithmetic) -> None:
    """Issue 12's target: median |error| <= 1 step per 20 m trial, median signed error 0 (measured offline, cross-
    validated: 1 and 0, errors -1..+2, sum of |errors| 36; on-line algorithm version 3 1 and 0, errors -2..+2,
    22 of 43 trials at or below 0, sum of |errors| 40 (version 2, a fixed foot-flat prominence: 41; version 1
    without the prior typical step and the above-zero rule: +1, -2..+3, 44); 2.86 % in median."""
    rows = [r for r in ipol.rows if r["estimator"] == "M2" and r["arithmetic"] == arithmetic
            and r["k_from"] == "offline" and r["variant"] == "main"]
    d = np.array([int(r["steps"]) - int(r["reference_steps"]) for r in rows])
    err = np.abs(d) / np.array([int(r["reference_steps"]) for r in rows])
    assert np.median(err) <= 0.03
    assert np.median(np.abs(d)) <= 1 and np.median(d) == 0
    assert np.abs(d).max() <= 3
    if arithmetic == "online-fixed":           # the README's on-line figures
        assert (d.min(), d.max()) == (-2, 2) and np.abs(d).sum() == pytest.approx(36, abs=2)
    else:                                      # 36 and -1..+2 before the short gaps were interpolated
        assert (d.min(), d.max()) == (-2, 2) and np.abs(d).sum() == pytest.approx(37, abs=2)


def test_constants_are_chosen_leave_one_subject_out(ipol) -> None:
    """Issue 12 (5): the heel-strike rule, hs_delay_s, prominence_fraction and M4's exponent are chosen per
    held-out subject on the other eight; the command says which figures are cross-validated. Measured: the impact
    rule in 9 of 9 folds, hs_delay_s 0.04 s in 8 and 0.06 s in 1 (subject 1 held out), prominence_fraction 0.2 in 8
    and 0 in 1, M4's exponent 1/2 in 7 and 3/8 in 2 (the m4-per-fold rows; the main rows use the shipped 1/4): the
    on-line rows (the shipped prominence_fraction 0.25) are marked not cross-validated for every subject."""
    t = ipol.text
    assert "chosen leave-one-subject-out" in t and "criterion: heel strikes within 40 ms" in t
    assert "heel_strike_rule (default 'impact'" in t and "'impact' in 9 of 9 folds" in t
    line = t.split("hs_delay_s (default 0.04")[1].split("\n")[0]
    assert "0.04 in 8 of 9 folds" in line and "0.06 in 1 of 9 folds" in line
    line = t.split("m4_exponent (default 0.25")[1].split("\n")[0]
    assert "criterion: IQR of the calibrated distance ratio" in line and "as the main rows use it" in line
    assert "0.5 in 7 of 9 folds, 0.375 in 2 of 9 folds" in line      # the m4-per-fold rows; the main rows: 1/4
    assert "stop_prominence_m_s2 (" not in t                            # off, no longer tuned (the rule's verdict)
    assert "cross-validated: every offline-chain figure" in t
    assert "prominence_fraction (default 0.25" in t and "by step count): 0.2 in 8 of 9 folds, 0.0 in 1 of 9 folds" in t
    not_cv = {(r["subject"], r["arithmetic"]) for r in ipol.rows if r["cross_validated"] == "0" and r["variant"] == "main"}
    # the on-line chains run the shipped defaults, which no fold chose (prominence_fraction)
    assert not_cv == {(s, a) for s in "123456789" for a in ("online-float", "online-fixed")}
    # the on-line rules' variants were chosen on these trials: never cross-validated
    assert all(r["cross_validated"] == "0" for r in ipol.rows if r["arithmetic"] == "online-fixed"
               and r["variant"] != "main")
    assert all(r["cross_validated"] == "1" for r in ipol.rows if r["arithmetic"] == "offline")


def test_k_prior_is_chosen_leave_one_subject_out_and_the_shipped_one_is_reproduced(ipol) -> None:
    """Issue 12 (4, 5): the k-prior rows shrink each subject's K toward the median K of the other subjects, with
    d0 chosen on them (nested); not in the main rows (its gain's interval includes zero). The prior learned on all
    nine under the evaluation's scoring (every step summed; printed, never used to score) is what gaitlog ships."""
    line = ipol.text.split("k_prior_distance_m (")[1].split("\n")[0]
    assert "criterion: mean squared log distance ratio" in line
    assert all(f"{e} " in line and "of 9 folds" in line for e in ("M1", "M2", "M4"))
    assert "(not kept: its gain's interval includes zero)" in ipol.text
    shipped = ipol.text.split("learned on every subject (shipped as LOWER_BACK_PRIOR")[1].split("\n")[0]
    p = LOWER_BACK_PRIOR
    assert ("d0 " + ", ".join(f"{e} {p.distance_m[e]:g} m" for e in ("M1", "M2", "M4"))) in shipped
    assert f"population K: M1 {p.k_m1:.4f}, M2 {p.k_m2:.4f}, M4 {p.k_m4_per_leg:.4f} x leg length" in shipped


def event_line(text, label):
    line = text.split(label)[1].split("\n")[0]
    hs = re.search(r"heel strike F1 ([0-9.]+) \((\d+) of (\d+) reference", line)
    to = re.search(r"toe-off F1 ([0-9.]+) \((\d+) of (\d+),", line)
    return float(hs.group(1)), int(hs.group(3)), float(to.group(1)), line


def test_event_timing_is_printed_by_the_command(ipol) -> None:
    """Issue 12 (5): HS and TO F1 within 40 ms and median |error| against the foot sensors, printed by evaluate
    ipol: cross-validated offline HS F1 0.722 (in-sample with the shipped defaults 0.753), TO 0.576; on-line
    fixed HS 0.734, TO 0.623; median |error| 20 ms (one sample at 50 Hz)."""
    hs, n, to, line = event_line(ipol.text, "offline, constants chosen leave-one-subject-out [cross-validated]: ")
    assert n == 1774 and hs == pytest.approx(0.722, abs=0.01) and to == pytest.approx(0.576, abs=0.01)
    assert "median |error| 20 ms" in line
    hs_in, _, _, _ = event_line(ipol.text, "offline, shipped defaults (in-sample): ")
    assert hs_in == pytest.approx(0.753, abs=0.01) and hs_in >= hs          # in-sample is the optimistic one
    hs, _, to, _ = event_line(ipol.text, "on-line fixed, shipped defaults: ")
    assert hs == pytest.approx(0.734, abs=0.01) and to == pytest.approx(0.623, abs=0.01)


def test_events_found_and_filled_per_trial(ipol) -> None:
    """Per trial, the steps with a heel strike found, a toe-off found and filled are printed and written
    (<CSV>_events.csv), and agree; measured offline 1,784 steps, HS on all, TO on 1,759, M3 filled on 73 (1,793,
    1,749 and 96 before the short gaps were interpolated)."""
    ev = [r for r in ipol.events if r["chain"] == "offline"]
    assert len(ev) == 52 and len([r for r in ipol.events if r["chain"] == "online-fixed"]) == 52
    n = sum(int(r["steps"]) for r in ev)
    to = sum(int(r["toe_off_found"]) for r in ev)
    filled = sum(int(r["m3_filled"]) for r in ev)
    assert n == pytest.approx(1784, abs=20) and to == pytest.approx(1759, abs=20)
    assert filled == pytest.approx(73, abs=15)
    assert f"offline, all trials: {n} steps, heel strike found on" in ipol.text
    assert f"toe-off on {to}, M3 filled on {filled}" in ipol.text
    # the rest of the recordings (not scored): measured offline 204, on-line fixed 195, 67 foot-sensor heel strikes
    outside = {c: sum(int(r["steps_outside"]) for r in ipol.events if r["chain"] == c)
               for c in ("offline", "online-fixed")}
    ref = sum(int(r["hs_reference_outside"]) for r in ev)
    assert ref == 67 and outside["offline"] == pytest.approx(196, abs=6)
    assert outside["online-fixed"] == pytest.approx(181, abs=6)
    assert (f"foot-sensor heel strikes {ref}, detected steps offline {outside['offline']}, online-fixed "
            f"{outside['online-fixed']}") in ipol.text
    r = ev[1]
    assert re.search(rf"^{r['subject']}-{r['trial']}\s+{r['steps']}\s+{r['heel_strike_found']}\s+{r['toe_off_found']}"
                     rf"\s+{r['m3_filled']}\s", ipol.text, re.M)


@pytest.mark.parametrize("variant, measured", [("uturn-exclude", {"M2": (1.013, 0.067), "M3": (1.022, 0.059)}),
                                               ("height-unknown", {"M2": (1.003, 0.056), "M3": (1.084, 0.080)}),
                                               ("k-prior", {"M1": (1.014, 0.063), "M2": (1.000, 0.044),
                                                            "M4": (0.975, 0.062)}),
                                               ("m4-per-fold", {"M4": (0.997, 0.092)}),
                                               ("m4-range-share", {"M4": (0.990, 0.059)}),
                                               ("m4-duration-share", {"M4": (0.997, 0.071)})])
def test_uturn_both_ways_and_height_unknown(ipol, variant, measured) -> None:
    """Issue 12 (3): the offline chain also with the U-turn steps left out (M3, without K, then reads 1.023: with
    them it reads the turn as straight walking, 1.088), with the height unknown (a 1.70 m adult for everyone:
    these subjects are 1.63-1.80 m; K absorbs the lengths of M1/M2/M4), with K shrunk toward the other subjects'
    (the K prior: what it buys) and with Weinberg's 1/4 for M4."""
    for e, (med, q) in measured.items():
        r = ratios(ipol.rows, e, variant=variant)
        assert r.size == 43
        assert np.median(r) == pytest.approx(med, abs=0.003) and iqr(r) == pytest.approx(q, abs=0.003)
    assert "U-turn excluded (the other rule" in ipol.text and "height UNKNOWN: a 1.70 m adult assumed" in ipol.text
    assert "with the K prior: K from trial 1 shrunk" in ipol.text and "M4 with the exponent chosen per fold" in ipol.text


def test_steps_outside_the_calibrated_range_are_counted(ipol) -> None:
    """Issue 12 (4): K from one trial applied to the others: steps outside the range K was fitted on are counted
    per trial (measured offline: M2 261 of 1,472 steps, M4 389); never for M3 (no K)."""
    rows = [r for r in ipol.rows if r["arithmetic"] == "offline" and r["variant"] == "main"]
    assert all(r["steps_outside_k_range"] == "" for r in rows if r["estimator"] == "M3")
    total = {e: sum(int(r["steps_outside_k_range"]) for r in rows if r["estimator"] == e) for e in ("M2", "M4")}
    assert total["M2"] == pytest.approx(261, abs=25) and total["M4"] == pytest.approx(389, abs=30)
    assert re.search(rf"^M2 .*\s{total['M2']}/\d+$", ipol.text.split("arithmetic = offline")[1], re.M)


def test_nothing_saturates(ipol) -> None:
    assert "fixed-point saturation/wrap: none" in ipol.text


def test_baseline_row_and_the_choices_are_printed(ipol) -> None:
    """The recipe (gaitlog.host.gait.recipe) is scored beside the chain (measured: M2 1.006, IQR 0.055; M4 1.020,
    IQR 0.078), and each choice's gain over the simpler one is printed with its interval: on these nine subjects
    none excludes zero, the shipped chain's over the recipe included (M2 +0.002 [-0.025, +0.029])."""
    for e, (med, q) in {"M2": (1.006, 0.055), "M4": (1.020, 0.078)}.items():
        r = ratios(ipol.rows, e, variant="baseline")
        assert r.size == 43
        assert np.median(r) == pytest.approx(med, abs=0.003) and iqr(r) == pytest.approx(q, abs=0.003)
    assert "baseline, the recipe" in ipol.text
    choices = ipol.text.split("choices against the simpler one")[1].split("steps|err|")[0]
    for label in ("K prior", "M4's exponent chosen per fold", "the shipped chain against the recipe",
                  "U-turn steps left out", "prominence_fraction chosen", "on-line: the stop rule of versions 1-3",
                  "on-line: the adaptive foot-flat prominence", "on-line: M4's exponent 1/2 against",
                  "M3's double support at the single support's speed"):
        line = next(ln for ln in choices.splitlines() if label in ln)
        for m in re.finditer(r"(M\d|steps) ([+-][0-9.]+) \[([+-][0-9.]+), ([+-][0-9.]+)\] (kept|not kept)", line):
            gain, lo, hi = map(float, m.group(2, 3, 4))
            assert lo <= gain <= hi and (m.group(5) == "kept") == (lo > 0), line
        assert "not kept" in line


def test_m3_double_support_row(ipol) -> None:
    """docs/validation/ipol.md: M3 with the double support covered at the single support's speed (no foot length,
    no constant) reads 0.980, IQR 0.091 (the main rows: 1.088, 0.081); the other estimators are the main rows'."""
    r = ratios(ipol.rows, "M3", variant="m3-single-support-speed")
    assert r.size == 43
    assert np.median(r) == pytest.approx(0.980, abs=0.003) and iqr(r) == pytest.approx(0.091, abs=0.003)
    assert np.array_equal(ratios(ipol.rows, "M2", variant="m3-single-support-speed"), ratios(ipol.rows, "M2"))
    assert "M3's double support covered at the single support's speed" in ipol.text


@pytest.mark.parametrize("variant, label, measured", [
    ("m4-range-share", "M4: a step below the trial's median range counts its share",
     dict(iqr=(+0.042, -0.006, +0.082), log=(+0.023, -0.002, +0.045))),
    ("m4-duration-share", "M4: Weinberg's length times the step's share of the trial's median duration",
     dict(iqr=(+0.030, -0.020, +0.068), log=(+0.015, -0.003, +0.043)))])
def test_m4_step_rules_do_not_pass_the_rule_for_choices(ipol, variant, label, measured) -> None:
    """M4 with a weak (or short) step counted as its share of the trial's typical step, no constant: it narrows M4
    (IQR 0.101 -> 0.059 and 0.071), but neither gain's 95 % subject-bootstrap interval excludes zero, in IQR or in
    the median |log ratio|, so the main rows keep Weinberg's length. The rows differ from the main ones in M4
    alone, and the printed gain is the CSV's IQR difference."""
    main_, rule = ({(r["subject"], r["trial"], r["estimator"]): float(r["ratio"]) for r in ipol.rows
                    if r["arithmetic"] == "offline" and r["variant"] == v} for v in ("main", variant))
    assert main_.keys() == rule.keys()
    assert all(rule[k] == main_[k] for k in main_ if k[2] != "M4")
    assert sum(rule[k] != main_[k] for k in main_ if k[2] == "M4") > 40
    line = next(ln for ln in ipol.text.split("choices against the simpler one")[1].splitlines() if label in ln)
    m = re.search(r"M4 ([+-][0-9.]+) \[([+-][0-9.]+), ([+-][0-9.]+)\] not kept, M4 median \|log ratio\| "
                  r"([+-][0-9.]+) \[([+-][0-9.]+), ([+-][0-9.]+)\] not kept", line)
    assert m, line
    got = tuple(map(float, m.groups()))
    assert got == pytest.approx(measured["iqr"] + measured["log"], abs=0.004)
    assert got[1] < 0 < got[0] < got[2] and got[4] < 0 < got[3] < got[5]
    assert got[0] == pytest.approx(iqr(ratios(ipol.rows, "M4")) - iqr(ratios(ipol.rows, "M4", variant=variant)),
                                   abs=0.001)
    log_gain = (np.median(np.abs(np.log(ratios(ipol.rows, "M4"))))
                - np.median(np.abs(np.log(ratios(ipol.rows, "M4", variant=variant)))))
    assert got[3] == pytest.approx(log_gain, abs=0.001)


@pytest.mark.parametrize("variant, measured", [("m4-range-share", (0.988, 0.068, 0.0041)),
                                               ("m4-duration-share", (0.991, 0.070, 0.0045))])
def test_m4_step_rules_on_the_logger_records(ipol, variant, measured) -> None:
    """The same rules applied on the host to the on-line fixed chain's records (each carries its range and duration),
    K the offline chain's fitted with the rule: the logger need not change. They stay as close to the offline chain
    as Weinberg's length does (median |ratio difference| 0.0040), well within 0.01; and their gains over the
    logger's own M4 are inside the noise too (printed)."""
    med, q, share = measured
    r = ratios(ipol.rows, "M4", "online-fixed", variant=variant)
    assert r.size == 43
    assert np.median(r) == pytest.approx(med, abs=0.003) and iqr(r) == pytest.approx(q, abs=0.003)
    d = np.abs(r - ratios(ipol.rows, "M4", variant=variant))         # the same (subject, trial) order
    assert np.median(d) == pytest.approx(share, abs=0.001) and np.median(d) < 0.01
    label = {"m4-range-share": "counted as its share of a typical step",
             "m4-duration-share": "median duration"}[variant]
    line = next(ln for ln in ipol.text.splitlines() if ln.startswith("  on-line: M4") and label in ln)
    m = re.search(r"M4 ([+-][0-9.]+) \[([+-][0-9.]+), ([+-][0-9.]+)\] not kept", line)
    assert m and float(m.group(2)) < 0 < float(m.group(3)), line
