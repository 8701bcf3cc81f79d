"""M3's terms against the IPOL trials (:mod:`gaitlog.host.studies.ipol_m3`), on the dev subjects.

Independent truth: the study's foot rule re-runs M3 on the chain's windows and must give ``gaitlog evaluate
ipol``'s M3 main rows ratio for ratio (a separate code path: the pipeline's own M3); the trials' 20 m. The figures
of ``docs/validation/ipol.md`` (M3 without K, by term) are pinned near what is measured.
"""

from __future__ import annotations

import pytest

from gaitlog.host.studies.ipol_evaluation import IpolEvaluation
from gaitlog.host.studies.ipol_m3 import M3Decomposition


@pytest.fixture(scope="module")
def m3(shared_data):
    folder = shared_data / "ipol-lowerback-dev"
    if not folder.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    evaluation = IpolEvaluation(arithmetic=("offline",)).run(folder)
    return evaluation, M3Decomposition().run(evaluation)


@pytest.mark.slow
def test_foot_rule_is_evaluate_ipols_m3(m3) -> None:
    evaluation, d = m3
    ref = {(r["subject"], r["trial"]): r["ratio"] for r in evaluation.result_.rows
           if r["estimator"] == "M3" and r["arithmetic"] == "offline" and r["k_from"] == "offline"
           and r["variant"] == "main"}
    mine = {(r["subject"], r["trial"]): r["ratio"] for r in d.rows("foot")}
    assert mine.keys() == ref.keys() and len(ref) == 43
    assert max(abs(mine[k] - ref[k]) for k in ref) < 1e-9
    assert d.figures_[("foot", "include")]["median"][0] == pytest.approx(1.088, abs=0.002)
    assert d.figures_[("foot", "exclude")]["median"][0] == pytest.approx(1.022, abs=0.002)


@pytest.mark.slow
def test_the_double_support_term_carries_the_long_reading(m3) -> None:
    """docs/validation/ipol.md: the distance asks for the pendulum as it is (a ~ 1) and a shorter double support
    (b ~ 0.145 m a step against S2 = 0.18-0.20 m); every subject's implied D* is below the foot length, the
    short steppers' most; the turn's steps have a shorter pendulum term but the same S2."""
    _, d = m3
    assert d.regression_["a"] == pytest.approx(0.985, abs=0.01)
    assert d.regression_["b"] == pytest.approx(0.145, abs=0.005)
    ratios = [s["implied_double_support_m"] / s["foot_length_m"] for s in d.subjects_]
    assert len(ratios) == 9 and max(ratios) < 0.95 and min(ratios) > 0.5
    assert d.groups_[("step / height", "below")]["implied_per_foot"] < d.groups_[("step / height", "above")][
        "implied_per_foot"]
    straight, turn = d.parts_["straight"], d.parts_["turn"]
    assert (straight["steps"], turn["steps"]) == (1351, 115)
    assert straight["pendulum_m"] == pytest.approx(0.456, abs=0.002)
    assert turn["pendulum_m"] == pytest.approx(0.330, abs=0.002)
    assert straight["m3_m"] == pytest.approx(0.648, abs=0.002)
    assert straight["trial_mean_step_m"] == pytest.approx(0.587, abs=0.002)
    for part in (straight, turn):     # the foot length: each subject's, the same on every step
        assert part["double_support_m_foot"] == pytest.approx(0.192, abs=0.001)
    for s in d.subjects_:
        assert s["turn_pendulum_m"] < 0.85 * s["straight_pendulum_m"], s["subject"]
        # the straight steps read between their sum over 20 m and their mean over 20 m / steps
        assert s["ratio_foot_straight"] < s["straight_step_ratio_foot"]
    assert d.correlations_[("step_per_height", "ratio_foot")][1] < 0 < d.correlations_[("step_per_height",
                                                                                         "ratio_foot")][2]


@pytest.mark.slow
def test_no_double_support_rule_passes_the_rule_for_choices(m3) -> None:
    """Neither alternative's gain interval lies above zero in both figures (median |log ratio| and IQR), so M3's
    foot length stays; the single support's speed halves the median |log ratio| inside the noise, the pendulum's
    end speed reads short by ~14 %."""
    _, d = m3
    ss = d.figures_[("single-support-speed", "include")]
    assert ss["median"][0] == pytest.approx(0.980, abs=0.003)
    assert ss["abs_log"][0] == pytest.approx(0.049, abs=0.003)
    assert ss["gain_abs_log"][1] < 0 < ss["gain_abs_log"][2] and ss["gain_iqr"][1] < 0 < ss["gain_iqr"][2]
    end = d.figures_[("end-speed", "include")]
    assert end["median"][0] == pytest.approx(0.856, abs=0.003)
    assert end["gain_abs_log"][2] < 0
    # the fitted comparison (the foot length scaled per fold, not shipped): |log ratio| passes, the IQR does not
    fitted = d.figures_[("foot-scaled-per-fold", "include")]
    assert fitted["median"][0] == pytest.approx(0.994, abs=0.003)
    assert fitted["gain_abs_log"][1] > 0 and fitted["gain_iqr"][1] < 0 < fitted["gain_iqr"][2]
    assert all(0.69 < c < 0.74 for c in d.fold_scales_.values())
