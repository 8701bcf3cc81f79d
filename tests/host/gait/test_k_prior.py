"""The K prior (gaitlog.host.gait.k_prior): shrinkage toward a population K, against the formula written out."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from gaitlog.host.errors import HostError
from gaitlog.host.gait.k_calibration import KFit, calibrate
from gaitlog.host.gait.k_prior import (
    LOWER_BACK_PRIOR,
    PRIOR_ESTIMATORS,
    KPrior,
    population_prior,
)
from gaitlog.host.gait.pipeline import apply_calibration
from tests.host.gait.test_estimators_calibration import table


def fit(raw_len: float = 0.5, distance_m: float = 18.0, leg: float = 0.9) -> KFit:
    return calibrate([(table(raw_len, 0.55, 30), distance_m)], leg_length_m=leg, foot_length_m=0.2)


def test_shrunk_k_is_the_distance_weighted_mean_of_fitted_and_population_k() -> None:
    k = fit()                                     # 18 m over 29 measured steps
    prior = KPrior(k_m1=1.0, k_m2=1.3, k_m4_per_leg=0.35, m4_exponent=k.m4_exponent,
                   distance_m={"M1": 6.0, "M2": 18.0, "M4": 54.0}, source="test")
    s = prior.shrink(k)
    d = 18.0
    assert s.k_m1 == pytest.approx((d * k.k_m1 + 6.0 * 1.0) / (d + 6.0))
    assert s.k_m2 == pytest.approx(0.5 * k.k_m2 + 0.5 * 1.3)
    assert s.k_m4 == pytest.approx(0.25 * k.k_m4 + 0.75 * 0.35 * 0.9)          # M4's population K scales with the leg
    assert (s.k1_m5_m_s, s.k2_m5_m) == (k.k1_m5_m_s, k.k2_m5_m)                  # M5 untouched
    assert s.shrinkage["fitted"] == {"M1": k.k_m1, "M2": k.k_m2, "M4": k.k_m4}
    assert s.shrinkage["weight"] == pytest.approx({"M1": 0.75, "M2": 0.5, "M4": 0.25})
    assert s.shrinkage["population"] == pytest.approx({"M1": 1.0, "M2": 1.3, "M4": 0.315})
    assert s.shrinkage["source"] == "test" and s.notes == k.notes       # recorded, not warned
    # the calibrated lengths' range follows K; the rest of the range does not move
    for e in PRIOR_ESTIMATORS:
        q = f"length_{e.lower()}_m"
        ratio = getattr(s, f"k_{e.lower()}") / getattr(k, f"k_{e.lower()}")
        assert s.calibrated_range[q] == pytest.approx([v * ratio for v in k.calibrated_range[q]])
    assert s.calibrated_range["duration_s"] == k.calibrated_range["duration_s"]
    # and the distance of the calibration walk scales by the same ratio (distances are linear in K)
    t = table(0.5, 0.55, 30)
    t.length_m = apply_calibration(t, s)
    assert t.distance_m("M2")[0] == pytest.approx(18.0 * s.k_m2 / k.k_m2)


def test_a_longer_calibration_walk_weighs_more_and_no_prior_changes_nothing() -> None:
    prior = dataclasses.replace(LOWER_BACK_PRIOR)
    short, long = fit(distance_m=10.0), fit(raw_len=0.5 * 4, distance_m=40.0)
    assert prior.weight("M2", 10.0) < prior.weight("M2", 40.0) < 1.0
    assert short.k_m2 == pytest.approx(long.k_m2)                       # same fitted K, different evidence
    assert abs(prior.shrink(short).k_m2 - prior.k_m2) < abs(prior.shrink(long).k_m2 - prior.k_m2)
    none = dataclasses.replace(prior, distance_m=dict.fromkeys(PRIOR_ESTIMATORS, 0.0))
    assert none.shrink(short) is short


def test_population_prior_is_the_median_and_m4_per_metre_of_leg() -> None:
    fits = [fit(raw_len=r, leg=leg) for r, leg in ((0.5, 0.8), (0.55, 0.9), (0.6, 1.0))]
    p = population_prior(fits, source="three")
    assert p.k_m2 == pytest.approx(np.median([f.k_m2 for f in fits]))
    assert p.k_m4_per_leg == pytest.approx(np.median([f.k_m4 / f.leg_length_m for f in fits]))
    assert p.population_k("M4", 0.85) == pytest.approx(p.k_m4_per_leg * 0.85)
    assert p.n_subjects == 3 and p.distance_m == dict.fromkeys(PRIOR_ESTIMATORS, 0.0)


def test_refusals() -> None:
    k = fit()
    with pytest.raises(HostError, match="no K"):
        population_prior([])
    with pytest.raises(HostError, match="different M4 exponents"):
        population_prior([k, dataclasses.replace(k, m4_exponent=0.5)])
    s = LOWER_BACK_PRIOR.shrink(k)
    with pytest.raises(HostError, match="already shrunk"):
        LOWER_BACK_PRIOR.shrink(s)
    with pytest.raises(HostError, match="not shrunk ones"):
        population_prior([s])
    with pytest.raises(HostError, match="M4's exponent 0.25, the K with 0.5"):
        LOWER_BACK_PRIOR.shrink(dataclasses.replace(k, m4_exponent=0.5))


def test_shrunk_k_file_round_trip_and_older_formats(tmp_path) -> None:
    s = LOWER_BACK_PRIOR.shrink(fit())
    p = tmp_path / "k.json"
    s.save(p)
    assert KFit.load(p) == s
    d = json.loads(p.read_text())
    assert d["format_version"] == "1.3" and d["shrinkage"]["source"] == LOWER_BACK_PRIOR.source
    bad = {**d, "shrinkage": {**d["shrinkage"], "weight": {"M1": 0.5}}}
    p.write_text(json.dumps(bad))
    with pytest.raises(HostError, match="key 'shrinkage' must map source to text"):
        KFit.load(p)
    old = {k: v for k, v in d.items() if k != "shrinkage"} | {"format_version": "1.2"}
    p.write_text(json.dumps(old))
    back = KFit.load(p)
    assert back.shrinkage is None and back.k_m2 == s.k_m2
    p.write_text(json.dumps(old | {"shrinkage": d["shrinkage"]}))
    with pytest.raises(HostError, match="key 'shrinkage' in a format 1.2 file"):
        KFit.load(p)


def test_the_shipped_prior_is_a_lower_back_population() -> None:
    """The values are pinned against ``gaitlog evaluate ipol``'s output by test_ipol_evaluation_real.py; here
    only that they are plausible: M2's K above 1 (the pendulum underestimates), M4's per metre of leg."""
    p = LOWER_BACK_PRIOR
    assert all(math.isfinite(v) for v in (p.k_m1, p.k_m2, p.k_m4_per_leg)) and p.n_subjects == 9
    assert 1.0 < p.k_m2 < 1.6 and 0.2 < p.k_m4_per_leg < 0.5
    assert all(d > 0 for d in p.distance_m.values())


def _transfers(first_k_error: list[float], later_ratio: list[float]) -> dict:
    """Subjects with the same true K (1.3 for M2) whose first trial measured it with ``first_k_error``; their
    other trials, scored with that K, come out at ``later_ratio``."""
    out = {}
    for s, (err, r) in enumerate(zip(first_k_error, later_ratio, strict=True)):
        k = dataclasses.replace(fit(), k_m1=1.1 * (1 + err), k_m2=1.3 * (1 + err), k_m4=0.3 * (1 + err))
        out[s] = (k, {e: [r, r] for e in PRIOR_ESTIMATORS})
    return out


def test_choose_prior_shrinks_fully_when_first_trials_are_noise_and_not_at_all_when_they_are_exact() -> None:
    """Analytic cases of the nested choice (gaitlog.host.studies.ipol_evaluation.choose_prior)."""
    from gaitlog.host.gait.k_prior import PRIOR_DISTANCE_CANDIDATES_M
    from gaitlog.host.studies.ipol_evaluation import choose_prior

    errors = [-0.06, -0.02, 0.0, 0.03, 0.07]
    # everybody has the same K: the first trial's deviation is pure noise, carried into the later ratios
    noise, _ = choose_prior(_transfers(errors, [1 + e for e in errors]), source="t")
    # (a strong prior, not the largest d0: the median of the *others* errs against each subject's own error, so
    # keeping a little of the first trial's K helps; measured 80 m: weight 0.18 at 18 m)
    assert all(noise.distance_m[e] >= 40.0 for e in PRIOR_ESTIMATORS)
    assert max(PRIOR_DISTANCE_CANDIDATES_M) > 40.0
    # the first trial measured each subject's own K exactly: the later ratios are 1, the prior can only hurt
    exact, _ = choose_prior(_transfers(errors, [1.0] * 5), source="t")
    assert all(exact.distance_m[e] == 0.0 for e in PRIOR_ESTIMATORS)
    assert exact.k_m2 == pytest.approx(1.3) and exact.n_subjects == 5       # the median of the subjects' K
