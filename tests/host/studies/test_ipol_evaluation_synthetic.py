"""The IPOL evaluation path on a synthetic folder (runs without the real recordings).

Two trials of one subject walking 20 m at the same pace, written in the IPOL layout (100 Hz, m/s^2, lost
packets, JSON in packet indices, no height): K fitted on trial 1 must give ratio ~1 on trial 2, steps
counted against the JSON heel strikes, lost packets never used.
"""

from __future__ import annotations

import csv
import json
import warnings

import numpy as np
import pytest

from gaitlog.host.cli import main
from gaitlog.host.studies.ipol_evaluation import evaluate_folder, replay_trial
from gaitlog.units import STANDARD_GRAVITY_M_S2

G = STANDARD_GRAVITY_M_S2


def write_ipol_trial(folder, subject, trial, *, n_steps=34, step_s=0.55, seed=0, lose=0.03):
    rng = np.random.default_rng(seed)
    sampling_rate_hz = 100.0
    stand = 3.0
    t = np.arange(int((2 * stand + n_steps * step_s) * sampling_rate_hz)) / sampling_rate_hz
    tw = t - stand
    inside = (tw >= 0) & (tw <= n_steps * step_s)
    w = 2 * np.pi / step_s
    a = np.where(inside, 0.02 * w * w * np.cos(w * tw), 0.0)
    for k in range(n_steps + 1):
        a += 3.0 * np.exp(-0.5 * ((tw - k * step_s + 0.06) / 0.02) ** 2)
    a += rng.normal(0, 0.05, t.size)
    up = G + a
    tilt = np.radians(25.0)
    acc = np.c_[up * np.cos(tilt), rng.normal(0, 0.02, t.size), up * np.sin(tilt)]
    keep = rng.random(t.size) > lose
    keep[:5] = keep[-5:] = True
    rows = [f"{i}.0\t{x:.6f}\t{y:.6f}\t{z:.6f}\t0\t0\t0" for i, (x, y, z) in enumerate(acc) if keep[i]]
    text = "Acquisition frequency: 100 Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\n"
    (folder / f"{subject}-{trial}_lb.txt").write_text(text + "\n".join(rows) + "\n")
    hs = np.round((stand + step_s * np.arange(1, n_steps + 1) - 0.06) * sampling_rate_hz).astype(int)
    to = hs - int(0.4 * sampling_rate_hz)
    start, end = int(to[0]), int(hs[-1])
    meta = {"Subject": subject, "Trial": trial, "TrialBoundaries": [start, end],
            "UTurnBoundaries": [int(hs[n_steps // 2] + 5), int(hs[n_steps // 2] + 6)],
            "LeftFootEvents": [[int(a_), int(b)] for a_, b in zip(to[0::2], hs[0::2])],
            "RightFootEvents": [[int(a_), int(b)] for a_, b in zip(to[1::2], hs[1::2])]}
    (folder / f"{subject}-{trial}.json").write_text(json.dumps(meta))
    return keep


def test_synthetic_folder_ratio_one_and_no_invented_samples(tmp_path) -> None:
    keep = write_ipol_trial(tmp_path, 1, 1, seed=1)
    write_ipol_trial(tmp_path, 1, 2, seed=2)
    rt = replay_trial(tmp_path / "1-1_lb.txt")
    # a logger sample at packet 2k is missing exactly when packet 2k was lost
    lost_even = ~keep[0::2][: rt.valid.size]
    assert np.array_equal(~rt.valid[: lost_even.size], lost_even)
    assert np.isnan(rt.acc_g[~rt.valid]).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = evaluate_folder(tmp_path)
    # one scored trial: 5 estimators x 3 arithmetics with the offline K, + 5 on-line fixed rows with its own K,
    # + the offline chain with the U-turn left out, with the height unknown (here it is: no height in the JSON),
    # with M4's exponent chosen in the fold and with M3's double support at the single support's speed (no k-prior
    # rows: one subject has no other subject to shrink toward),
    # the on-line fixed chain with each of its rules' simpler or former choices, the offline chain with each of M4's
    # length rules, and the recipe baseline's M2 and M4
    assert res.n_trials == 1 and len(res.rows) == 82
    base = {r["estimator"]: r["ratio"] for r in res.rows[80:]}
    assert [r["variant"] for r in res.rows[80:]] == ["baseline"] * 2 and set(base) == {"M2", "M4"}
    assert [(r["arithmetic"], r["variant"]) for r in res.rows[60:80:5]] == [
        ("online-fixed", "m4-range-share"), ("online-fixed", "m4-duration-share"),
        ("offline", "m4-range-share"), ("offline", "m4-duration-share")]
    assert all(r["ratio"] == pytest.approx(1.0, abs=0.03) for r in res.rows[60:80] if r["estimator"] == "M4")
    # the on-line rows of M4's length rules differ from the on-line fixed chain's in M4 alone
    assert [r["ratio"] for r in res.rows[10:15] if r["estimator"] != "M4"] == [
        r["ratio"] for r in res.rows[60:65] if r["estimator"] != "M4"]
    assert all(v == pytest.approx(1.0, abs=0.03) for v in base.values()), base
    assert [(r["arithmetic"], r["k_from"], r["variant"]) for r in res.rows[:60:5]] == [
        ("offline", "offline", "main"), ("online-float", "offline", "main"), ("online-fixed", "offline", "main"),
        ("online-fixed", "own", "main"), ("offline", "offline", "uturn-exclude"),
        ("offline", "offline", "height-unknown"), ("offline", "offline", "m4-per-fold"),
        ("offline", "offline", "m3-single-support-speed"), ("online-fixed", "offline", "stop-v3"),
        ("online-fixed", "offline", "prominence-fixed"),
        ("online-fixed", "offline", "m4-quarter"), ("online-fixed", "offline", "m4-half")]
    assert res.priors == {} and res.calibrations[1].shrinkage is None
    # the m4-per-fold rows differ from the main ones in M4 alone, and so do the on-line m4-quarter rows from the
    # on-line fixed chain's (its M4 computed from the records' ranges instead of in fixed point)
    assert [r["ratio"] for r in res.rows[:5] if r["estimator"] != "M4"] == [
        r["ratio"] for r in res.rows[30:35] if r["estimator"] != "M4"]
    assert [r["ratio"] for r in res.rows[10:15] if r["estimator"] != "M4"] == [
        r["ratio"] for r in res.rows[50:55] if r["estimator"] != "M4"]
    assert res.rows[53]["ratio"] == pytest.approx(res.rows[13]["ratio"], abs=1e-4)
    # the m3-single-support-speed rows differ from the main ones in M3 alone
    assert [r["ratio"] for r in res.rows[:5] if r["estimator"] != "M3"] == [
        r["ratio"] for r in res.rows[35:40] if r["estimator"] != "M3"]
    assert res.rows[37]["estimator"] == "M3" and res.rows[37]["ratio"] != res.rows[2]["ratio"]
    assert {r["lengths_source"] for r in res.rows} == {"assumed-height"}
    res.rows = [r for r in res.rows if r["variant"] == "main"]
    for arith, k_from in (("offline", "offline"), ("online-fixed", "offline"), ("online-fixed", "own")):
        by = {r["estimator"]: r for r in res.rows if r["arithmetic"] == arith and r["k_from"] == k_from}
        for name in ("M1", "M2", "M4", "M5"):
            assert by[name]["ratio"] == pytest.approx(1.0, abs=0.03), (arith, k_from, name)
        assert by["M2"]["reference_steps"] == 34
        assert abs(by["M2"]["steps"] - 34) <= 1
    # the logger ran its on-line algorithm: its records are the host's replay, byte for byte
    assert [c["trial"] for c in res.replay_checks] == ["1-1_lb.txt", "1-2_lb.txt"]
    assert all(c["n_identical"] == c["n_compared"] == c["n_device"] > 30 for c in res.replay_checks)
    # one K for every arithmetic: the offline chain's
    assert set(res.calibrations) == set(res.calibrations_own) == {1}


def test_cli_evaluate_writes_csv_and_figure(tmp_path, capsys) -> None:
    write_ipol_trial(tmp_path, 2, 1, seed=3)
    write_ipol_trial(tmp_path, 2, 2, seed=4)
    out = tmp_path / "out" / "eval.csv"
    out.parent.mkdir()
    assert main(["evaluate", "ipol", str(tmp_path), "--out", str(out), "--adc-bits", "10", "--logger-rate", "50"]) == 0
    text = capsys.readouterr().out
    assert "M3" in text and "median" in text
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert "height UNKNOWN" in text and "chosen leave-one-subject-out" in text and "heel strike F1" in text
    rows = [r for r in rows if r["variant"] == "main"]
    assert [r["estimator"] for r in rows] == ["M1", "M2", "M3", "M4", "M5"] * 4
    assert [r["arithmetic"] for r in rows] == ["offline"] * 5 + ["online-float"] * 5 + ["online-fixed"] * 10
    assert [r["k_from"] for r in rows] == ["offline"] * 15 + ["own"] * 5
    assert "device step records = host replay, byte for byte: 2 of 2 trials" in text
    assert "a different K, not a comparison" in text
    assert out.with_suffix(".png").stat().st_size > 1000
    with open(out.with_name("eval_steps.csv"), newline="") as fh:
        steps = list(csv.DictReader(fh))
    assert {r["trial"] for r in steps} == {"1", "2"} and len(steps) > 60
    with pytest.raises(SystemExit) as usage:            # the logger stores 10-bit codes: a usage error
        main(["evaluate", "ipol", str(tmp_path), "--out", str(out), "--adc-bits", "12", "--force"])
    assert usage.value.code == 2


def test_unreadable_trial_and_single_trial_subject_are_skipped_and_listed(tmp_path, capsys) -> None:
    write_ipol_trial(tmp_path, 3, 1, seed=5)
    write_ipol_trial(tmp_path, 3, 2, seed=6)
    write_ipol_trial(tmp_path, 3, 3, seed=7)
    (tmp_path / "3-3.json").write_text("{}")            # no TrialBoundaries
    write_ipol_trial(tmp_path, 4, 1, seed=8)            # a subject with one trial
    out = tmp_path / "eval.csv"
    assert main(["evaluate", "ipol", str(tmp_path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "skipped: 3-3_lb.txt" in text and "skipped: subject 4: only one trial" in text
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {(r["subject"], r["trial"]) for r in rows} == {("3", "2")}


def test_device_records_that_differ_are_an_error(tmp_path, monkeypatch, capsys) -> None:
    """A logger whose stored records differ from the host's replay (here one M2 length, CRC recomputed: a
    firmware bug) stops the evaluation with an error naming the trial and the record; nothing is written."""
    import gaitlog.host.studies.ipol_evaluation as ie
    from gaitlog.protocol.steps import STEP_RECORD_DTYPE, pack_step_records

    write_ipol_trial(tmp_path, 5, 1, seed=9)
    write_ipol_trial(tmp_path, 5, 2, seed=10)
    real = ie.replay_trial

    def tampered(path, **kw):
        rt = real(path, **kw)
        if path.name != "5-2_lb.txt":
            return rt
        rec = rt.device_records.copy()
        rec["length_m2_q14"][4] += 1
        rec = np.frombuffer(pack_step_records(rec), dtype=STEP_RECORD_DTYPE).copy()
        object.__setattr__(rt, "device_records", rec)
        return rt

    monkeypatch.setattr(ie, "replay_trial", tampered)
    out = tmp_path / "eval.csv"
    assert main(["evaluate", "ipol", str(tmp_path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "5-2_lb.txt" in err and "1 DIFFERENT" in err and "length_m2_q14: device" in err
    assert not out.exists() and not out.with_suffix(".png").exists()
