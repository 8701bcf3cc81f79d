"""The paper's evaluation on the real IPOL recordings replayed through the emulated logger (50 Hz, 10 bits), with
the logger's on-line step algorithm on; the offline chain and the on-line algorithm in float and in fixed point
with ONE K per subject (fitted on trial 1 with the offline chain).

``gaitlog evaluate ipol`` runs once (module fixture, ~5 s); every figure is computed here from the CSVs it
writes (not by the code under test) and pinned near what is measured. M5's interquartile range misses
issue 4's 0.10 with the offline chain (0.149: a strict expected failure): with K fitted on one 20 m trial at
one speed, even the *reference* step events give M5 an IQR of 0.109 on these trials (walk-ratio model; 0.119
for a constant step length), so no detector can reach 0.10. Issue 12's IQR <= 0.06 for calibrated M2 and M4,
with K shrunk toward the other subjects' K (the K prior), is met by M2 (0.048) and M4 (0.0585).

The constants chosen on these trials (the heel-strike rule, ``hs_delay_s``, the stop rule's ``stop_prominence_m_s2`` and M4's exponent,
:mod:`gaitlog.host.studies.tuning`) are chosen leave-one-subject-out by the command: every offline-chain figure is
cross-validated (measured: the defaults in 8 of 9 folds, ``hs_delay_s`` 0.06 s when subject 1 is held out, M4's
exponent 1/2 in 9 of 9), the on-line chains run the shipped defaults (cross-validated for the other 8 subjects). The on-line algorithm's gravity time constant comes from a
ripple rule, ``firmware_sim/algorithms/parameters.py``; K is fitted per subject on trial 1 and scored on the
others, never on the trial it scores, and shrunk toward the median K of the other subjects with a weight chosen
on them.
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
                             "variant", "distance_m", "ratio", "steps", "reference_steps", "steps_outside_k_range",
                             "cross_validated"]
    kinds = {(r["arithmetic"], r["k_from"], r["variant"], r["uturn"], r["lengths_source"]) for r in rows}
    assert kinds == {("offline", "offline", "main", "exclude", "subject-height"),
                     ("online-float", "offline", "main", "exclude", "subject-height"),
                     ("online-fixed", "offline", "main", "exclude", "subject-height"),
                     ("online-fixed", "own", "main", "exclude", "subject-height"),
                     ("offline", "offline", "uturn-include", "include", "subject-height"),
                     ("offline", "offline", "height-unknown", "exclude", "assumed-height"),
                     ("offline", "offline", "no-prior", "exclude", "subject-height")}
    assert len(rows) == 7 * 5 * 43                  # 52 trials - 9 calibration trials, 5 estimators, 7 kinds
    for r in rows:
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
    measured_mm = {"M1": 0.063, "M2": 0.030, "M3": 0.026, "M4": 0.039, "M5": 0.015}
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
    """Per trial, |ratio fixed - ratio float| median ~1e-4, at most 0.0035 (M1); the same steps counted."""
    for e in ESTIMATORS:
        a, b = ratio_pairs(ipol.rows, e, "online-fixed", "online-float")
        assert a.size == 43
        assert np.median(np.abs(a - b)) <= 3e-4, e
        assert np.max(np.abs(a - b)) <= 0.005, e
    steps = {(r["subject"], r["trial"], r["arithmetic"]): r["steps"] for r in ipol.rows if r["k_from"] == "offline"}
    for (s, t, a), n in steps.items():
        if a == "online-fixed":
            assert n == steps[(s, t, "online-float")], (s, t)


# measured median |ratio on-line float - ratio offline| per trial (43 trials, one K from the offline chain)
ALGORITHM_SHARE = {"M1": 0.0126, "M2": 0.0097, "M3": 0.0081, "M4": 0.0078, "M5": 0.0029}


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
@pytest.mark.parametrize("name, measured", [("M2", 1.005), ("M4", 0.989)])
def test_calibrated_online_median(ipol, arithmetic, name, measured) -> None:
    """Issue 10 (c): the on-line algorithm with the offline chain's K: M2 and M4 median ratio within 1 +- 0.03."""
    med = np.median(ratios(ipol.rows, name, arithmetic))
    assert abs(med - 1.0) <= 0.03
    assert med == pytest.approx(measured, abs=0.005)


@pytest.mark.parametrize("name, measured", [("M1", 1.002), ("M2", 1.004), ("M4", 0.988), ("M5", 0.992)])
def test_own_k_as_the_device_would_be_used(ipol, name, measured) -> None:
    """The on-line fixed algorithm with its own K (a different K: fitted on its own records of trial 1, shrunk
    toward the other subjects' own K)."""
    assert "a different K, not a comparison" in ipol.text
    r = ratios(ipol.rows, name, "online-fixed", "own")
    assert r.size == 43
    assert np.median(r) == pytest.approx(measured, abs=0.005)
    if name == "M4":
        assert iqr(r) == pytest.approx(0.0697, abs=0.005)


# The documentation's IPOL table (docs/validation/ipol.md): median ratio, IQR (and min, max offline) with the offline chain's K (shrunk toward the
# other subjects' K)
README_TABLE = {
    "offline": {"M1": (1.012, 0.078, 0.888, 1.117), "M2": (0.998, 0.048, 0.830, 1.088),
                "M3": (1.023, 0.061, 0.895, 1.150), "M4": (0.996, 0.058, 0.857, 1.087),
                "M5": (0.998, 0.152, 0.815, 1.237)},
    "online-fixed": {"M1": (1.015, 0.095), "M2": (1.005, 0.053), "M3": (1.027, 0.070), "M4": (0.989, 0.073),
                     "M5": (0.978, 0.160)},
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
    text = (Path(__file__).resolve().parents[2] / "docs" / "validation" / "ipol.md").read_text(encoding="utf-8")
    table = text.split("| estimator | offline: median ratio | IQR | min – max | on-line fixed: median | IQR |")[1]
    for name in ESTIMATORS:
        row = next(ln for ln in table.splitlines() if ln.startswith(f"| {name} "))
        cells = [c.strip() for c in row.strip("|").split("|")]
        off, fx = README_TABLE["offline"][name], README_TABLE["online-fixed"][name]
        assert cells[1:6] == [f"{off[0]:.3f}", f"{off[1]:.3f}", f"{off[2]:.3f} – {off[3]:.3f}", f"{fx[0]:.3f}",
                              f"{fx[1]:.3f}"], name


def test_online_m4_iqr_meets_the_target(ipol) -> None:
    """Issue 4's 0.10: with the offline chain's K, the on-line algorithm's M4 IQR is 0.073 (offline 0.0585); it
    was 0.110 with Weinberg's range^(1/4) and the stop rule."""
    assert iqr(ratios(ipol.rows, "M4", "online-fixed")) <= 0.10


@pytest.mark.parametrize("name", ["M2", "M4", "M5"])
def test_calibrated_median(ipol, name) -> None:
    assert abs(np.median(ratios(ipol.rows, name)) - 1.0) <= 0.03


def test_m2_iqr(ipol) -> None:
    assert iqr(ratios(ipol.rows, "M2")) <= 0.10


def test_m4_iqr(ipol) -> None:
    """Issue 4's 0.10: met since M4 is K range^(1/2) (0.0585 with the K prior, 0.076 without; 0.104 with
    Weinberg's range^(1/4))."""
    assert iqr(ratios(ipol.rows, "M4")) <= 0.10


@pytest.mark.parametrize("name", [
    "M2", "M4"])
def test_issue12_calibrated_iqr(ipol, name) -> None:
    """Issue 12: calibrated M2 and M4, median within 1 +- 0.02 (met: 0.998, 0.996) and IQR <= 0.06 (met: M2
    0.048, M4 0.0585), K per subject from its first trial shrunk toward the other subjects' (M4: 0.076 with the
    first trial's K alone; 0.0604 with the prior but M4's exponent chosen on unshrunk K, 3/8 for subject 7)."""
    r = ratios(ipol.rows, name)
    assert abs(np.median(r) - 1.0) <= 0.02
    assert iqr(r) <= 0.06


def test_issue12_best_calibrated_iqr(ipol) -> None:
    """Issue 12: the best calibrated estimator's IQR <= 0.05: M2's 0.048 with K shrunk toward the other
    subjects' K (0.064 with the first trial's K alone; M1 0.078, M4 0.0585, M5 0.152)."""
    assert min(iqr(ratios(ipol.rows, e)) for e in ("M1", "M2", "M4", "M5")) <= 0.05


@pytest.mark.parametrize("arithmetic", ["offline", "online-fixed"])
def test_issue12_m3_without_k(ipol, arithmetic) -> None:
    """Issue 12: M3 without K, median within 1 +- 0.05 and IQR <= 0.08 (measured offline 1.023, 0.061; on-line
    fixed 1.027, 0.070)."""
    r = ratios(ipol.rows, "M3", arithmetic)
    assert abs(np.median(r) - 1.0) <= 0.05 and iqr(r) <= 0.08


@pytest.mark.xfail(reason="M5 calibrated on one speed: IQR >= 0.109 even with reference step events", strict=True)
def test_m5_iqr(ipol) -> None:
    assert iqr(ratios(ipol.rows, "M5")) <= 0.10


def test_m3_uncalibrated_median(ipol) -> None:
    assert abs(np.median(ratios(ipol.rows, "M3")) - 1.0) <= 0.10


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
        assert (d.min(), d.max()) == (-2, 2) and np.abs(d).sum() == pytest.approx(40, abs=2)
    else:
        assert (d.min(), d.max()) == (-1, 2) and np.abs(d).sum() == pytest.approx(36, abs=2)


def test_constants_are_chosen_leave_one_subject_out(ipol) -> None:
    """Issue 12 (5): the heel-strike rule, hs_delay_s and M4's exponent are chosen per held-out subject on the
    other eight; the command says which figures are cross-validated. Measured: the impact rule in 9 of 9 folds,
    hs_delay_s 0.04 s in 8 and 0.06 s in 1 (subject 1 held out), M4's exponent 1/2 in 9 (chosen with K shrunk
    as it is used; 3/8 for subject 7 with K unshrunk): the on-line rows of subject 1 are marked not
    cross-validated."""
    t = ipol.text
    assert "chosen leave-one-subject-out" in t and "criterion: heel strikes within 40 ms" in t
    assert "heel_strike_rule (default 'impact'" in t and "'impact' in 9 of 9 folds" in t
    line = t.split("hs_delay_s (default 0.04")[1].split("\n")[0]
    assert "0.04 in 8 of 9 folds" in line and "0.06 in 1 of 9 folds" in line
    line = t.split("m4_exponent (default 0.5")[1].split("\n")[0]
    assert "criterion: IQR of the calibrated distance ratio" in line and "shrunk toward the" in line
    assert "0.5 in 9 of 9 folds" in line
    assert "stop_prominence_m_s2 (default 0.2" in t and "by step count): 0.2 in 9 of 9 folds" in t
    assert "cross-validated: every offline-chain figure" in t
    not_cv = {(r["subject"], r["arithmetic"]) for r in ipol.rows if r["cross_validated"] == "0"}
    assert not_cv == {("1", a) for a in ("online-float", "online-fixed")}
    assert all(r["cross_validated"] == "1" for r in ipol.rows if r["arithmetic"] == "offline")


def test_k_prior_is_chosen_leave_one_subject_out_and_the_shipped_one_is_reproduced(ipol) -> None:
    """Issue 12 (4, 5): each subject's K is shrunk toward the median K of the other subjects, with d0 chosen on
    them (nested); the prior learned on all nine (printed, never used to score) is what gaitlog ships.
    Measured folds: d0 M1 20-60 m, M2 20-80 m, M4 5-15 m."""
    line = ipol.text.split("k_prior_distance_m (")[1].split("\n")[0]
    assert "criterion: mean squared log distance ratio" in line
    assert all(f"{e} " in line and "of 9 folds" in line for e in ("M1", "M2", "M4"))
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
    (<CSV>_events.csv), and agree; measured offline 1,793 steps, HS on all, TO on 1,749, M3 filled on 96."""
    ev = [r for r in ipol.events if r["chain"] == "offline"]
    assert len(ev) == 52 and len([r for r in ipol.events if r["chain"] == "online-fixed"]) == 52
    n = sum(int(r["steps"]) for r in ev)
    to = sum(int(r["toe_off_found"]) for r in ev)
    filled = sum(int(r["m3_filled"]) for r in ev)
    assert n == pytest.approx(1793, abs=20) and to == pytest.approx(1749, abs=20) and filled == pytest.approx(96, abs=15)
    assert f"offline, all trials: {n} steps, heel strike found on" in ipol.text
    assert f"toe-off on {to}, M3 filled on {filled}" in ipol.text
    # the rest of the recordings (not scored): measured offline 202, on-line fixed 195, 67 foot-sensor heel strikes
    outside = {c: sum(int(r["steps_outside"]) for r in ipol.events if r["chain"] == c)
               for c in ("offline", "online-fixed")}
    ref = sum(int(r["hs_reference_outside"]) for r in ev)
    assert ref == 67 and outside["offline"] == pytest.approx(202, abs=6)
    assert outside["online-fixed"] == pytest.approx(195, abs=6)
    assert (f"foot-sensor heel strikes {ref}, detected steps offline {outside['offline']}, online-fixed "
            f"{outside['online-fixed']}") in ipol.text
    r = ev[1]
    assert re.search(rf"^{r['subject']}-{r['trial']}\s+{r['steps']}\s+{r['heel_strike_found']}\s+{r['toe_off_found']}"
                     rf"\s+{r['m3_filled']}\s", ipol.text, re.M)


@pytest.mark.parametrize("variant, measured", [("uturn-include", {"M2": (0.995, 0.053), "M3": (1.086, 0.083)}),
                                               ("height-unknown", {"M2": (0.996, 0.045), "M3": (1.018, 0.061)}),
                                               ("no-prior", {"M1": (1.037, 0.089), "M2": (1.008, 0.064),
                                                             "M4": (0.992, 0.076)})])
def test_uturn_both_ways_and_height_unknown(ipol, variant, measured) -> None:
    """Issue 12 (3): the offline chain also with the U-turn steps summed (M3, without K, then reads the turn as
    straight walking: 1.086) and with the height unknown (a 1.70 m adult for everyone: these subjects are
    1.63-1.80 m, so M3 barely moves; K absorbs most of the lengths of M1/M2/M4, the population K toward which
    it is shrunk the rest), and with the first trial's K alone (no prior: what the prior buys)."""
    for e, (med, q) in measured.items():
        r = ratios(ipol.rows, e, variant=variant)
        assert r.size == 43
        assert np.median(r) == pytest.approx(med, abs=0.003) and iqr(r) == pytest.approx(q, abs=0.003)
    assert "U-turn included (the other rule" in ipol.text and "height UNKNOWN: a 1.70 m adult assumed" in ipol.text
    assert "NO K prior: K from trial 1 alone" in ipol.text


def test_steps_outside_the_calibrated_range_are_counted(ipol) -> None:
    """Issue 12 (4): K from one trial applied to the others: steps outside the range K was fitted on are counted
    per trial (measured offline: M2 242 of 1,477 steps, M4 265); never for M3 (no K)."""
    rows = [r for r in ipol.rows if r["arithmetic"] == "offline" and r["variant"] == "main"]
    assert all(r["steps_outside_k_range"] == "" for r in rows if r["estimator"] == "M3")
    total = {e: sum(int(r["steps_outside_k_range"]) for r in rows if r["estimator"] == e) for e in ("M2", "M4")}
    assert total["M2"] == pytest.approx(242, abs=25) and total["M4"] == pytest.approx(265, abs=30)
    assert re.search(rf"^M2 .*\s{total['M2']}/\d+$", ipol.text.split("arithmetic = offline")[1], re.M)


def test_nothing_saturates(ipol) -> None:
    assert "fixed-point saturation/wrap: none" in ipol.text
