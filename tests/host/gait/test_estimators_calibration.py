"""K calibration: single-speed, multi-speed, the M5 fallback, JSON round trip and bad input."""

from __future__ import annotations

import dataclasses

import json
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.host.errors import HostError
from gaitlog.host.gait.k_calibration import KFit, calibrate
from gaitlog.host.gait.pipeline import apply_calibration


def table(raw_len: float, step_s: float, n: int, *, nan_first: bool = True) -> StepTable:
    """A step table with constant raw lengths and durations (first step without window, as in a bout)."""
    dur = np.full(n, step_s)
    raw = np.full(n, raw_len)
    if nan_first:
        dur[0] = np.nan
        raw[0] = np.nan
    ff = np.arange(n) * 25 + 100
    z = np.zeros(n, np.int64)
    return StepTable(50.0, 0.0, ff, ff - 3, ff - 20, ff - 25, z, dur, z,
                     {"M1": raw, "M2": raw, "M3": raw}, raw * 4,
                     {"M1": raw, "M2": raw * 0.8, "M3": raw, "M4": raw * 2, "M5": 1.0 / dur}, {})


def test_single_speed_k_reproduces_distance_and_m5_falls_back() -> None:
    t = table(0.5, 0.55, 30)
    cal = calibrate([(t, 18.0)], leg_length_m=0.9, foot_length_m=0.2)
    assert any("walk-ratio fallback" in n for n in cal.notes)   # returned, not warned
    assert cal.mode == "single-speed" and cal.m5_fallback and cal.k2_m5_m == 0.0
    assert cal.k_m1 == pytest.approx(18.0 / (30 * 0.5))
    assert cal.k_m2 == pytest.approx(18.0 / (30 * 0.4))
    t.length_m = apply_calibration(t, cal)
    for name in ("M1", "M2", "M4", "M5"):
        assert t.distance_m(name)[0] == pytest.approx(18.0)   # fitted on it: exact


def test_multi_speed_fits_the_m5_line() -> None:
    k1, k2 = 0.3, 0.15            # S = K1 / T + K2
    sections = []
    for step_s in (0.45, 0.55, 0.65):
        n = 40
        s = k1 / step_s + k2
        sections.append((table(0.5, step_s, n, nan_first=False), n * s))
    cal = calibrate(sections, leg_length_m=0.9, foot_length_m=0.2)
    assert cal.notes == []                                    # no fallback
    assert cal.mode == "multi-speed" and not cal.m5_fallback
    assert cal.k1_m5_m_s == pytest.approx(k1, rel=1e-9) and cal.k2_m5_m == pytest.approx(k2, abs=1e-9)


def test_two_sections_at_the_same_speed_still_fall_back() -> None:
    sections = [(table(0.5, 0.55, 20), 11.0), (table(0.5, 0.552, 20), 11.0)]
    cal = calibrate(sections, leg_length_m=0.9, foot_length_m=0.2)
    assert any("do not span speeds" in n for n in cal.notes)
    assert cal.m5_fallback and np.isfinite(cal.k1_m5_m_s) and cal.mode == "single-speed"


def test_calibration_errors() -> None:
    with pytest.raises(HostError, match="at least one"):
        calibrate([], leg_length_m=0.9, foot_length_m=0.2)
    with pytest.raises(HostError, match="distance must be positive"):
        calibrate([(table(0.5, 0.5, 5), -3.0)], leg_length_m=0.9, foot_length_m=0.2)
    empty = table(0.5, 0.5, 5).select(np.zeros(5, bool))
    with pytest.raises(HostError, match="no step"):
        calibrate([(empty, 10.0)], leg_length_m=0.9, foot_length_m=0.2)
    allnan = table(np.nan, 0.5, 5)
    with pytest.raises(HostError, match="no measurable"):
        calibrate([(allnan, 10.0)], leg_length_m=0.9, foot_length_m=0.2)


def test_json_round_trip_and_version_check(tmp_path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate([(table(0.5, 0.55, 30), 18.0)], leg_length_m=0.9, foot_length_m=0.2, subject="s1")
    p = tmp_path / "k.json"
    cal.save(p)
    back = KFit.load(p)
    assert back == cal
    d = json.loads(p.read_text())
    assert d["format_version"] == "1.3" and d["cal_type"] == "gaitlog.KCalibration"
    assert d["m4_exponent"] == M4_EXPONENT
    assert d["calibrated_range"]["duration_s"] == [0.55, 0.55]
    d["format_version"] = "9.9"
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match=r"format_version.*'9\.9' \(written by a newer gaitlog"):
        KFit.load(p)
    d["format_version"] = "0.9"
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match=r"'0\.9' \(re-run 'gaitlog calibrate-k'\)"):
        KFit.load(p)
    d["format_version"] = "1.3"
    d["calibrated_range"] = {"duration_s": [0.5, 0.6]}
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match="key 'calibrated_range' must map"):
        KFit.load(p)
    del d["calibrated_range"], d["m4_exponent"], d["shrinkage"]
    d["format_version"] = "1.0"
    d["k_m1"] = "one"
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match="key 'k_m1' must be a number"):
        KFit.load(p)
    p.write_text("{not json")
    with pytest.raises(HostError, match="not valid JSON"):
        KFit.load(p)
    with pytest.raises(HostError, match="cannot read"):
        KFit.load(tmp_path / "missing.json")


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@given(k=st.tuples(finite, finite, finite, finite, finite),
       n=st.integers(1, 10_000),
       label=st.text(max_size=20))
def test_kcalibration_json_round_trip_property(k, n, label) -> None:
    cal = KFit(k_m1=k[0], k_m2=k[1], k_m4=k[2], k1_m5_m_s=k[3], k2_m5_m=k[4], mode="single-speed",
                       m5_fallback=True, leg_length_m=0.9, foot_length_m=0.2, n_sections=1, n_steps=n,
                       distance_m=20.0, subject=label, notes=["x"])
    assert KFit.from_json(cal.to_json()) == cal


def test_a_format_1_0_file_is_read_without_a_range(tmp_path) -> None:
    """A K file written before the calibrated range was stored (format 1.0): read, range unknown, no step flagged."""
    cal = calibrate([(table(0.5, 0.55, 30), 18.0)], leg_length_m=0.9, foot_length_m=0.2)
    d = cal.to_dict()
    d["format_version"] = "1.0"
    del d["calibrated_range"], d["m4_exponent"], d["shrinkage"]
    p = tmp_path / "old.json"
    p.write_text(json.dumps(d))
    old = KFit.load(p)
    assert old.calibrated_range is None and old.k_m1 == cal.k_m1
    assert "unknown" in old.describe_range()
    assert not old.outside_range(table(0.9, 1.0, 10))["any"].any()
    d["calibrated_range"] = cal.calibrated_range
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match="calibrated_range' in a format 1.0 file"):
        KFit.load(p)


def test_a_format_1_1_file_keeps_weinbergs_exponent(tmp_path) -> None:
    """A K file written before M4's exponent was stored (format 1.1) was fitted with range^(1/4): it is read
    so, applied so on the host (from the step's range), and given to the logger with its exponent (on-line algorithm
    version 4 computes the configuration's, whole eighths up to 1/2; another is refused)."""
    cal = calibrate([(table(0.5, 0.55, 30), 18.0)], leg_length_m=0.9, foot_length_m=0.2)
    d = cal.to_dict()
    d["format_version"] = "1.1"
    del d["m4_exponent"], d["shrinkage"]
    p = tmp_path / "old.json"
    p.write_text(json.dumps(d))
    old = KFit.load(p)
    assert old.m4_exponent == 0.25 and old.k_m4 == cal.k_m4
    t = table(0.5, 0.55, 30)
    assert M4_EXPONENT == 0.25          # Weinberg's is the chain's again: the raw lengths are range^(1/4)
    np.testing.assert_allclose(apply_calibration(t, old)["M4"], apply_calibration(t, cal)["M4"])
    # a K fitted with another exponent (format 1.2 on) is applied with it, from the step's range
    half = dataclasses.replace(cal, m4_exponent=0.5)
    np.testing.assert_allclose(apply_calibration(t, half)["M4"][1:], cal.k_m4 * t.acc_range_m_s2[1:] ** 0.5)
    assert old.step_constants()["m4_exponent"] == 0.25
    assert cal.step_constants()["k_m4"] == cal.k_m4
    with pytest.raises(HostError, match="exponent 0.6; the logger computes whole eighths up to 4/8"):
        dataclasses.replace(cal, m4_exponent=0.6).step_constants()
    d["m4_exponent"] = 0.5
    p.write_text(json.dumps(d))
    with pytest.raises(HostError, match="'m4_exponent' in a format 1.1 file"):
        KFit.load(p)


def test_steps_outside_the_calibrated_range_are_flagged() -> None:
    """K fitted on 0.55 s steps of raw length 0.5 m: a walk with 0.8 s steps and one with longer excursions are
    outside the range for every estimator (duration) or for M1/M2/M4 only (their input and length); the
    calibration walk itself is inside everywhere."""
    cal = calibrate([(table(0.5, 0.55, 30), 18.0)], leg_length_m=0.9, foot_length_m=0.2)
    r = cal.calibrated_range
    assert r["duration_s"] == [0.55, 0.55] and r["h_m2_m"] == [0.5, 0.5]
    assert r["length_m2_m"][0] == pytest.approx(18.0 / 30 * 1.0)          # K2 * 0.4 m, K2 = 18 m / 30 steps
    same = table(0.5, 0.55, 30)
    same.length_m = apply_calibration(same, cal)
    assert not cal.outside_range(same)["any"].any()
    slow = table(0.5, 0.8, 10)
    slow.length_m = apply_calibration(slow, cal)
    out = cal.outside_range(slow)
    assert out["duration_s"][1:].all() and not out["duration_s"][0]          # the windowless step: not measured
    assert all(out[e][1:].all() for e in ("M1", "M2", "M4", "M5")) and out["length_m5_m"][1:].all()
    longer = table(0.7, 0.55, 10)
    longer.length_m = apply_calibration(longer, cal)
    out = cal.outside_range(longer)
    assert out["M1"][1:].all() and out["M2"][1:].all() and out["M4"][1:].all() and not out["M5"].any()
    assert "0.55-0.55 s" in cal.describe_range()


def test_distance_fills_unmeasured_steps_with_the_bout_median() -> None:
    t = table(0.5, 0.55, 6)                      # step 0 has no window (NaN)
    t.bout = np.array([0, 0, 0, 1, 1, 1])
    v = np.array([np.nan, 0.6, 0.8, np.nan, 0.4, 0.5])
    t.length_m = {"M2": v}
    d, n = t.distance_m("M2")
    assert n == 2 and d == pytest.approx(0.6 + 0.8 + 0.7 + 0.45 + 0.4 + 0.5)
    with pytest.raises(KeyError, match="unknown estimator"):
        t.distance_m("M9")
