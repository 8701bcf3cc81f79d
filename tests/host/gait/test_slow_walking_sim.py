"""Slow, short-stepped walking (step <= 0.35 m, cadence <= 90 /min): steps counted and M3 per bout.

We have no real recording of such walking: the walkers are simulated (``gaitlog.firmware_sim.world``), logged as the
device would (10 bits, 50 Hz, nominal +-2 g) and run through both chains (the offline chain and the on-line
algorithm in fixed point). The truth is the simulator's heel strikes and step lengths. Targets (issue 12):
step count within 10 %, M3's per-bout mean step length within 1 +- 0.15 of the true mean.

Measured with the default rule (on-line algorithm version 3: foot-flats need 0.25 of the recent step amplitude
within 0.25-0.5 m/s^2, the 0.5 cap until a step is seen; gaitlog.firmware_sim.algorithms.parameters notes): steps
-3.1..-2.1 % offline, -2.8..+0.4 % on-line fixed; M3 per-bout ratio medians 1.115-1.149 offline, 1.105-1.130
on-line fixed (M3's own bias on short steps: the pendulum of a 0.3 m step plus a whole foot length). The fixed
0.5 m/s^2 threshold of versions 1-2 misses 17-25 % of these steps (strict xfail: the rule is what counts them;
the 3 Hz first harmonic of a 0.30-0.35 m step rises 0.3-0.8 m/s^2, less at the bout's start, end and turn).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.parameters import EventParameters
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.gait.events import GaitEventDetector
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.protocol.steps import StepConfig

pytestmark = pytest.mark.slow

#: 20 m out and back twice, standing between (two bouts of ~20 m each way).
PLAN = WalkPlan(corridor_length_m=20.0, speeds=("preferred", "preferred"), rest_s=8.0, rest_postures=("standing",),
                initial_stand_s=6.0, final_stand_s=3.0, lap_marks_m=(0.0, 40.0))
#: (height m, speed m/s, step m, seed): cadences 70-90 /min.
WALKERS = ((1.60, 0.42, 0.30, 11), (1.75, 0.50, 0.34, 12), (1.85, 0.45, 0.35, 13))


def _walk(height_m: float, speed_m_s: float, step_m: float, seed: int):
    subject = Subject.from_height(height_m, preferred_speed_m_s=speed_m_s,
                                  walk_ratio_m_spm=step_m * step_m / (60.0 * speed_m_s), slow_speed_factor=0.9)
    motion = Walking(subject=subject, walk_plan=PLAN, seed=seed).render(500.0)
    codes = np.clip(np.floor(512.0 + motion.acc_g[::10] * 256.0), 0, 1023).astype(np.int64)
    return subject, motion.truth["steps"], codes


#: Measured (default rule): chain -> per walker (step count error, M3 per-bout ratio median).
MEASURED = {"offline": ((-0.021, 1.1151), (-0.031, 1.1338), (-0.028, 1.1489)),
            "online-fixed": ((-0.028, 1.1053), (-0.028, 1.1247), (0.004, 1.1301))}


@pytest.mark.parametrize("rule", [
    "default",
    pytest.param("fixed-0.5", marks=pytest.mark.xfail(strict=True, reason="issue 12: 17-25 % missed at 0.5 m/s^2"))])
@pytest.mark.parametrize("walker", WALKERS, ids=[f"{w[2]:.2f}m-{w[1]:.2f}m_s" for w in WALKERS])
@pytest.mark.parametrize("chain", ["offline", "online-fixed"])
def test_slow_short_steps_are_counted_and_measured(walker: tuple, chain: str, rule: str) -> None:
    subject, truth, codes = _walk(*walker)
    events = EventParameters() if rule == "default" else EventParameters(min_prominence_m_s2=0.5)
    true_hs = np.unique(np.round(np.concatenate([truth["heel_strike_s"], truth["next_heel_strike_s"]]), 4))
    cadence = 60.0 / np.median(np.diff(truth["heel_strike_s"]))
    assert np.median(truth["length_m"]) <= 0.36 and cadence <= 90.0, (np.median(truth["length_m"]), cadence)
    if chain == "offline":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = StepPipeline(leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m,
                                 detector=GaitEventDetector(events)).run(
                (codes + 0.5 - 512.0) / 256.0, sampling_rate_hz=50.0).steps_
    else:
        cfg = StepConfig(step_format=1, leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m)
        table = StepTable.from_online(OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg,
                                                                   events=events).run(codes))
    count_error = (table.n_steps - true_hs.size) / true_hs.size
    assert abs(count_error) <= 0.10, (table.n_steps, true_hs.size)
    # M3 per bout: mean of the measured steps against the true mean step of that excursion
    t_ff = table.time_s(table.foot_flat)
    ratios = []
    for k in np.unique(truth["excursion"]):
        on = truth["excursion"] == k
        lo, hi = truth["heel_strike_s"][on].min(), truth["next_heel_strike_s"][on].max()
        m3 = table.length_m["M3"][(t_ff >= lo) & (t_ff <= hi + 0.5)]
        ratios.append(np.nanmean(m3) / np.mean(truth["length_m"][on]))
    assert abs(np.median(ratios) - 1.0) <= 0.15, ratios
    if rule == "default":
        count_measured, m3_measured = MEASURED[chain][WALKERS.index(walker)]
        assert count_error == pytest.approx(count_measured, abs=0.005)
        assert np.median(ratios) == pytest.approx(m3_measured, abs=0.005)
    counts = table.event_counts()
    assert counts["heel_strike_found"] >= 0.95 * counts["steps"], counts
    assert counts["m3_filled"] <= 0.10 * counts["windows"], counts


def test_estimate_counts_slow_steps_by_default(tmp_path) -> None:
    """``gaitlog estimate`` (the offline chain) counts the slowest walker's steps within 10 %, with no option."""
    import json
    from contextlib import redirect_stdout
    from io import StringIO

    from gaitlog.host.cli import main

    subject, truth, codes = _walk(*WALKERS[0])
    true_n = np.unique(np.round(np.concatenate([truth["heel_strike_s"], truth["next_heel_strike_s"]]), 4)).size
    csv = tmp_path / "slow.csv"
    np.savetxt(csv, (codes + 0.5 - 512.0) / 256.0, delimiter=",", header="x_g,y_g,z_g", comments="", fmt="%.6f")
    buf = StringIO()
    with warnings.catch_warnings(), redirect_stdout(buf):
        warnings.simplefilter("ignore")
        assert main(["estimate", str(csv), "--rate", "50", "--height", "1.60", "--json"]) == 0
    n = json.loads(buf.getvalue())["arithmetic"]["float"]["n_steps"]
    assert abs(n - true_n) <= 0.10 * true_n, (n, true_n)
