"""Fixed vs float on the real IPOL development trials (replayed at 50 Hz, 10 bits): issue 5's thresholds.

The reference is the float chain on the same codes; steps are matched by time; the distance ratios use
K fitted per arithmetic on each subject's first trial, as ``gaitlog evaluate ipol`` does.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest


@pytest.fixture(scope="module")
def folder(shared_data):
    f = shared_data / "ipol-lowerback-dev"
    if not f.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    return f


def test_distance_ratios_fixed_vs_float(folder) -> None:
    from host.ipol_evaluation import evaluate_folder

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = evaluate_folder(folder, arithmetic=("float", "fixed"))
    assert res.saturation == []
    assert set(res.calibrations) == set(res.calibrations_fixed)
    by = {(r["subject"], r["trial"], r["estimator"], r["arithmetic"]): r for r in res.rows}
    for est in ("M1", "M2", "M3", "M4", "M5"):
        keys = [k for k in by if k[2] == est and k[3] == "float"]
        assert len(keys) == res.n_trials
        d = np.array([by[k[:3] + ("fixed",)]["ratio"] - by[k]["ratio"] for k in keys])
        assert np.median(np.abs(d)) <= 0.005, est
        # the same steps are counted
        assert all(by[k[:3] + ("fixed",)]["steps"] == by[k]["steps"] for k in keys), est


def test_per_step_fixed_vs_float_on_every_trial(folder) -> None:
    from host.compare import compare_recording
    from host.estimators.anthropometry import anatomical_lengths
    from host.ipol import list_trials
    from host.ipol_evaluation import replay_trial

    n_steps = n_diff = 0
    worst_median_mm = worst_rel = 0.0
    for path in list_trials(folder):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            rt = replay_trial(path)
            leg, foot = anatomical_lengths(height_m=rt.height_m)
        res = compare_recording(rt.codes, sampling_rate_hz=rt.sampling_rate_hz, leg_length_m=leg,
                                foot_length_m=foot, valid=rt.valid, t0_s=rt.t0_s)
        assert res.saturation == "", path.name
        n_steps += res.float_table.n_steps
        n_diff += res.match.n_different_events
        for r in res.step_diffs:
            if r["estimator"] in ("M1", "M2", "M3") and r["n"]:      # no K: M4/M5 lengths are not defined
                worst_median_mm = max(worst_median_mm, r["median_abs_mm"])
                worst_rel = max(worst_rel, r["max_rel"])
    assert n_steps > 1000
    assert n_diff <= 0.01 * n_steps             # reported, and rare
    assert worst_median_mm <= 1.0
    assert worst_rel <= 0.01
