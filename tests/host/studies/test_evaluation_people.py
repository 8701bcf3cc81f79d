"""``gaitlog evaluate sim --population people``: the paper's evaluation on the walker tuned to real people.

Figures stated in the README (4 subjects, seed 0), measured by ``gaitlog evaluate sim DIR --subjects 4
--population people --protocol compact --laps mark``. They differ from the ``v1`` walkers' where the walker
differs: M5's single-speed spread (step length not the walk-ratio law any more), M3's (the people population's
wider deviation from the pendulum model) and M4's (range^(1/4) since on-line algorithm version 4: 6.6 % where
range^(1/2) gave 4.8 %).
"""

from __future__ import annotations

import pytest

from gaitlog.firmware_sim.world.walk_plan import POPULATION_PLANS
from gaitlog.host.cli import main
from gaitlog.host.studies import evaluation
from gaitlog.host.studies.evaluation import SimulatedEvaluation


def test_the_people_population_walks_the_papers_protocol_with_its_own_habits(monkeypatch) -> None:
    jobs: list = []
    monkeypatch.setattr(evaluation, "map_subjects", lambda job, js, **kw: jobs.extend(js) or [])
    monkeypatch.setattr(evaluation, "pool_event_scores", lambda ev: {})
    SimulatedEvaluation(n_subjects=2, seed=1, population="people").run()
    assert len(jobs) == 2
    for subject, _seed, plan, *_ in jobs:
        assert subject.cadence_law_spm is not None and subject.ml_harmonics_m_s2
        assert plan.turn_radius_m == POPULATION_PLANS["people"]["turn_radius_m"]
        assert plan.corridor_length_m == 100.0 and len(plan.speeds) == 4          # the paper's protocol
    jobs.clear()
    SimulatedEvaluation(n_subjects=1, seed=1, population="v1").run()
    assert jobs[0][2] is None and jobs[0][0].cadence_law_spm is None           # v1: the paper's default plan


def test_unknown_population_is_refused(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["evaluate", "sim", "out", "--population", "martians"])
    assert "invalid choice" in capsys.readouterr().err


@pytest.mark.slow
def test_readme_figures_of_the_people_population() -> None:
    ev = SimulatedEvaluation(n_subjects=4, seed=0, workers=2, population="people").run()
    s = {(r["mode"], r["estimator"]): r for r in ev.summary_}
    # M5: the median stays near 100 % but single-speed K spreads it (IQR 8.0 %, max 122 %; v1: 2.1 %)
    assert s[("single-speed", "M5")]["iqr"] == pytest.approx(0.080, abs=0.005)
    assert s[("single-speed", "M5")]["max"] == pytest.approx(1.217, abs=0.01)
    assert s[("multi-speed", "M5")]["iqr"] == pytest.approx(0.029, abs=0.003)
    # M3 (no K) 97.6 %, IQR 7.9 %; M1 single-speed 98.2 %
    assert s[("single-speed", "M3")]["median"] == pytest.approx(0.976, abs=0.003)
    assert s[("single-speed", "M3")]["iqr"] == pytest.approx(0.079, abs=0.005)
    assert s[("single-speed", "M1")]["median"] == pytest.approx(0.982, abs=0.003)
    # M4 = K range^(1/4), Weinberg's (on-line algorithm version 4, no stop rule): single-speed IQR 6.6 %, multi-speed
    # 7.1 % (4.8 % and 4.9 % with range^(1/2) and the stop rule of versions 2-3)
    assert s[("single-speed", "M4")]["iqr"] == pytest.approx(0.066, abs=0.004)
    assert s[("multi-speed", "M4")]["iqr"] == pytest.approx(0.071, abs=0.004)
    assert ev.events_["heel_strike"].f1 == pytest.approx(0.965, abs=0.005)


def test_compare_refuses_a_population_for_a_recording(tmp_path, capsys) -> None:
    assert main(["compare", str(tmp_path / "rec.npz"), "--population", "people"]) == 2  # a usage error
    assert "--population: only with --simulate" in capsys.readouterr().err
