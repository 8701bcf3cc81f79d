"""``gaitlog simulate --ipol-out``: simulated walks in the IPOL lower-back layout, and how real they look.

The export is checked against the world's truth and the project's own IPOL reader; the realism against the
real IPOL trials with ``../shared/tools/walking_stats.py`` (skipped when ``../shared`` is absent), statistic by
statistic with issue 14's criterion (:mod:`gaitlog.host.studies.realism`): the ones the walker fails today are strict
xfails, so a change of the world that fixes or breaks one shows here.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.cli import main
from gaitlog.host.files.ipol import list_trials, read_trial
from gaitlog.host.studies.realism import STATISTICS, judge
from gaitlog.host.studies.simulation import (
    IPOL_SAMPLING_RATE_HZ,
    export_ipol,
    ipol_trial,
    ipol_walk_plan,
)
from gaitlog.units import STANDARD_GRAVITY_M_S2
from tests.conftest import DATA_DIR


def test_an_exported_trial_reads_back_as_the_worlds_walk(tmp_path) -> None:
    names = export_ipol(tmp_path, 2, seed=5, trials=2)
    assert names == ["1-1", "1-2", "2-1", "2-2"]
    subject = random_subjects(2, seed=5, population="people")[1]
    trial = read_trial(tmp_path / "2-2_lb.txt")
    meta = trial.meta
    assert trial.sampling_rate_hz == IPOL_SAMPLING_RATE_HZ and trial.valid.all() and trial.first_counter == 0
    assert meta["Height"] == pytest.approx(100 * subject.height_m, abs=0.05)
    # the samples are the world's specific force at 100 Hz (written with 6 decimals in m/s^2)
    seed = meta["Simulated"]["seed"]
    motion = Walking(subject=subject, walk_plan=ipol_walk_plan(), seed=seed).render(IPOL_SAMPLING_RATE_HZ)
    np.testing.assert_allclose(trial.acc_g, motion.acc_g, atol=1e-6 / STANDARD_GRAVITY_M_S2)
    # every heel strike of the truth is one swing's end, feet alternate, toe-off before heel strike
    steps = motion.truth["steps"]
    swings = sorted([(to, hs, "L") for to, hs in meta["LeftFootEvents"]]
                    + [(to, hs, "R") for to, hs in meta["RightFootEvents"]], key=lambda e: e[1])
    truth_hs = np.rint(np.append(steps["heel_strike_s"], steps["next_heel_strike_s"][-1]) * 100).astype(int)
    assert [hs for _, hs, _ in swings] == list(truth_hs)
    assert all(a[2] != b[2] for a, b in zip(swings, swings[1:]))
    assert all(0 < hs - to < 100 for to, hs, _ in swings)                   # swings of 0.3-0.5 s
    assert [f for *_, f in swings[1:]] == [("R" if s == "L" else "L") for s in steps["side"]]
    # trial boundaries: first toe-off to last heel strike; the U-turn inside, at the far end of the corridor
    tb, ut = meta["TrialBoundaries"], meta["UTurnBoundaries"]
    assert tb == [swings[0][0], swings[-1][1]] and tb[0] < ut[0] < ut[1] < tb[1]
    exc = motion.truth["excursions"]
    assert ut == [round(exc["turn_start_s"][0] * 100), round(exc["turn_end_s"][0] * 100)]
    assert exc["corridor_distance_m"][0] == 20.0
    # quiet standing first: the first second reads 1 g
    assert np.linalg.norm(trial.acc_g[:100], axis=1) == pytest.approx(1.0, abs=1e-6)


def test_trials_of_a_subject_are_different_walks_and_reproducible() -> None:
    sub = random_subjects(1, seed=2, population="people")[0]
    a1, m1 = ipol_trial(sub, seed=1)
    a2, m2 = ipol_trial(sub, seed=1)
    _, mb = ipol_trial(sub, seed=2)
    assert np.array_equal(a1, a2) and m1 == m2
    assert m1["LeftFootEvents"] != mb["LeftFootEvents"]


def test_cli_writes_the_folder_and_refuses_to_overwrite_it(tmp_path, capsys) -> None:
    out = tmp_path / "GaitData"
    assert main(["simulate", "--ipol-out", str(out), "--subjects", "2", "--seed", "3"]) == 0
    assert [p.name for p in list_trials(tmp_path)] == ["1-1_lb.txt", "2-1_lb.txt"]
    assert "2 simulated trial(s)" in capsys.readouterr().out
    before = (out / "1-1_lb.txt").read_bytes()
    assert main(["simulate", "--ipol-out", str(out), "--subjects", "1", "--seed", "4"]) == 1
    assert "already holds trials" in capsys.readouterr().err
    assert (out / "1-1_lb.txt").read_bytes() == before
    with pytest.raises(SystemExit) as usage:
        main(["simulate", "--ipol-out", str(out), "--subjects", "0"])
    assert usage.value.code == 2 and "argument --subjects: must be a whole number 1..10000" in capsys.readouterr().err
    assert main(["simulate", "--ipol-out", str(out), "--subjects", "1", "--seed", "4", "--force", "-q"]) == 0
    assert capsys.readouterr().out == "" and (out / "1-1_lb.txt").read_bytes() != before
    assert json.loads((out / "1-1.json").read_text())["Simulated"]["seed"] >= 0


# --------------------------------------------------------------------------------------------- realism
STATS_TOOL = DATA_DIR.parent / "tools" / "walking_stats.py"
REAL = DATA_DIR / "ipol-lowerback-dev" / "GaitData"
N_SUBJECTS = 20
#: Checked statistics each population fails today on 20 subjects, seed 0 (as
#: benchmarks/bench_walking_realism.py). "v1" (the population of the other studies): step CV 0.074 vs 0.038
#: real, RMS AP 1.28 vs 1.65, RMS ML 0.61 vs 1.28, HR V 5.3 vs 4.2, HR AP 2.7 vs 3.4, HR ML 10.8 vs 1.9, ML
#: dominant frequency at 1.0 x stride vs 2.5, U-turn 2.3 s vs 1.6 s, PCA ratio 4.3 vs 1.6. "people": none
#: (nor on seeds 1-7).
FAILING_TODAY = {
    "v1": {"step_duration_cv", "rms_ap", "rms_ml", "hr_v", "hr_ap", "hr_ml", "fdom_ml_over_stride_freq",
           "dur_uturn_s", "ap_ml_var_ratio"},
    "people": set(),
}


@pytest.fixture(scope="module")
def walking_stats(tmp_path_factory) -> dict[str, dict[str, np.ndarray]]:
    """Per-trial statistics of ``N_SUBJECTS`` simulated subjects of each population and of the real trials."""
    if not (STATS_TOOL.is_file() and REAL.is_dir()):
        pytest.skip(f"{STATS_TOOL} or {REAL} not found (../shared beside the repository)")
    work = tmp_path_factory.mktemp("realism")
    sets = [f"real={REAL}"]
    for population in FAILING_TODAY:
        export_ipol(work / population / "GaitData", N_SUBJECTS, seed=0, population=population)
        sets.append(f"{population}={work / population / 'GaitData'}")
    subprocess.run([sys.executable, str(STATS_TOOL), str(work / "out"), *sets], check=True, capture_output=True)
    with open(work / "out" / "real_walking_stats.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {s: {k: np.array([float(r[k]) for r in rows if r["set"] == s]) for k, _, _ in STATISTICS}
            for s in ("real", *FAILING_TODAY)}


@pytest.mark.parametrize(("population", "key"), [
    pytest.param(p, k, marks=pytest.mark.xfail(strict=True, reason="not yet like people here (issue 14)"))
    if k in failing else (p, k)
    for p, failing in FAILING_TODAY.items() for k, _, checked in STATISTICS if checked])
def test_simulated_median_is_inside_the_real_band_and_near_the_real_median(walking_stats, population, key) -> None:
    assert walking_stats[population][key].size == N_SUBJECTS and walking_stats["real"][key].size >= 50
    v = judge(walking_stats[population][key], walking_stats["real"][key])
    assert v.passes, v


def test_the_tool_is_not_part_of_the_project() -> None:
    root = Path(__file__).resolve().parents[3]
    assert not list(root.rglob("walking_stats.py"))
