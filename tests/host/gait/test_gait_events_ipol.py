"""Heel-strike and toe-off against the foot-worn sensors of the real IPOL trials (lower back, replayed at 50 Hz
and 10 bits through the emulated logger).

The reference is independent of the code under test: the JSON's ``LeftFootEvents``/``RightFootEvents``
come from sensors on the feet. Measured with the default detector (52 trials, 1,774 reference events each):
heel strikes within 40 ms F1 0.752 (0.754 before the stop rule), median |error| 20 ms (the steepest-rise rule:
F1 0.569, 30 ms); toe-offs F1 0.577, median |error| 20 ms (-20 ms bias: one sample at 50 Hz).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # ~5 s: 52 trials through the emulated logger


@pytest.fixture(scope="module")
def matched(shared_data) -> dict[str, dict[str, float]]:
    folder = shared_data / "ipol-lowerback-dev"
    if not folder.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    from gaitlog.host.files.ipol import list_trials, read_trial
    from gaitlog.host.gait.anthropometry import anatomical_lengths
    from gaitlog.host.gait.pipeline import StepPipeline
    from gaitlog.host.studies.compare import match_events
    from gaitlog.host.studies.ipol_evaluation import replay_trial

    counts = {"heel_strike": [0, 0, 0], "toe_off": [0, 0, 0]}     # matched, reference, detected
    errors: dict[str, list[float]] = {"heel_strike": [], "toe_off": []}
    for path in list_trials(folder):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            rt = replay_trial(path)
            leg, foot = anatomical_lengths(height_m=rt.height_m)
            ev = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
                rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s).events_
        trial = read_trial(path)
        lo, hi = trial.trial_bounds
        toe_offs, heel_strikes = trial.foot_events()
        for name, ref, found in (("heel_strike", heel_strikes, ev.heel_strike_), ("toe_off", toe_offs, ev.toe_off_)):
            ref_s = np.array([rt.seconds(i) for i in ref[(ref >= lo) & (ref <= hi)]])
            det_s = found[found >= 0] / rt.sampling_rate_hz + rt.t0_s
            det_s = np.sort(det_s[(det_s >= ref_s.min() - 0.3) & (det_s <= ref_s.max() + 0.3)])
            it, jd = match_events(ref_s, det_s, 0.04)
            counts[name][0] += it.size
            counts[name][1] += ref_s.size
            counts[name][2] += det_s.size
            it, jd = match_events(ref_s, det_s, 0.15)                # timing error of every event found
            errors[name] += (det_s[jd] - ref_s[it]).tolist()
    return {name: {"f1": 2 * c[0] / (c[1] + c[2]), "n_ref": c[1],
                   "median_abs_s": float(np.median(np.abs(errors[name]))),
                   "median_s": float(np.median(errors[name]))} for name, c in counts.items()}


def test_heel_strike_is_found_at_the_impact(matched) -> None:
    hs = matched["heel_strike"]
    assert hs["n_ref"] > 1500
    assert hs["f1"] >= 0.70, hs
    assert hs["median_abs_s"] <= 0.025, hs
    assert abs(hs["median_s"]) <= 0.020, hs


def test_toe_off_timing(matched) -> None:
    to = matched["toe_off"]
    assert to["f1"] >= 0.50, to
    assert to["median_abs_s"] <= 0.030, to
    assert abs(to["median_s"]) <= 0.030, to


@pytest.fixture(scope="module")
def sections(shared_data) -> dict:
    """Per trial (all 52), the offline chain's steps within the trial section (the evaluation's rule), with the
    shipped defaults (no stop rule) and with the stop rule of on-line algorithm versions 1-3; whether the trial's last reference heel strike has a detected
    step within 0.15 s."""
    folder = shared_data / "ipol-lowerback-dev"
    if not folder.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    from gaitlog.firmware_sim.algorithms.parameters import EventParameters
    from gaitlog.host.files.ipol import list_trials
    from gaitlog.host.gait.events import GaitEventDetector
    from gaitlog.host.gait.pipeline import StepPipeline
    from gaitlog.host.studies.compare import match_events
    from gaitlog.host.studies.ipol_evaluation import replay_trial, trial_steps

    rules = {"default": EventParameters(), "stop-v3": EventParameters(stop_prominence_m_s2=0.2)}
    out: dict = {name: {"counts": {}, "errors": [], "last_missed": 0} for name in rules}
    for path in list_trials(folder):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            rt = replay_trial(path)
        _, hs_ref = rt.reference_event_times_s()
        for name, params in rules.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                table = StepPipeline(leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m,
                                     detector=GaitEventDetector(params)).run(
                    rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s).steps_
            sec, _ = trial_steps(rt, table, uturn="include")
            o = out[name]
            for k, v in sec.event_counts().items():
                o["counts"][k] = o["counts"].get(k, 0) + v
            o["errors"].append(sec.n_steps - rt.reference_steps())
            ir, _ = match_events(hs_ref, np.sort(sec.event_time_s()), 0.15)
            o["last_missed"] += int(hs_ref.size - 1 not in set(ir.tolist()))
    for o in out.values():
        o["errors"] = np.array(o["errors"])
    return out


def test_events_found_and_filled_per_step(sections) -> None:
    """Measured (52 trials, offline): 1,792 steps, every one with a heel strike; 1,765 with a window, toe-off
    found in 1,747 of them, M3 measured in 1,694 and filled with the bout median in 71 (4.0 %)."""
    c = sections["default"]["counts"]
    assert c["heel_strike_found"] == c["steps"] > 1700, c
    assert 0.97 <= c["toe_off_found"] / c["windows"] <= 1.0, c
    assert 0.02 <= c["m3_filled"] / c["windows"] <= 0.06, c
    assert c["single_support"] + c["m3_filled"] == c["windows"]


def test_step_count_per_trial(sections) -> None:
    """Per 20 m trial (52): median |error| 1 step, median signed error 0 (measured without the stop rule, the
    default since on-line algorithm version 4: MEASURED_DEFAULT; with the stop rule of versions 1-3 (0.2 m/s^2):
    MEASURED_STOP)."""
    e = sections["default"]["errors"]
    assert e.size == 52
    assert np.median(np.abs(e)) <= 1 and np.median(e) == 0, e
    assert np.abs(e).max() <= 3, e
    for name, (exact, lo, hi, total) in (("default", MEASURED_DEFAULT), ("stop-v3", MEASURED_STOP)):
        e = sections[name]["errors"]
        assert (int(np.sum(e == 0)), int(e.min()), int(e.max()), int(np.abs(e).sum())) == (exact, lo, hi, total), name


#: Measured per-trial step-count errors of the offline chain on the 52 trials: (trials exact, min, max, sum of
#: |errors|), without the stop rule (the default) and with the stop rule of versions 1-3.
MEASURED_DEFAULT = (18, -3, 2, 46)
MEASURED_STOP = (19, -2, 2, 42)


def test_stop_rule_finds_the_last_step(sections) -> None:
    """The step that brings the walker to a stop (the trial's last foot-sensor heel strike): without a detected
    step within 0.15 s in 15 of 52 trials with the stop rule of versions 1-3, 25 without it (the default: it
    does not help the count, docs/topics/accuracy.md)."""
    assert sections["stop-v3"]["last_missed"] <= 17, sections["stop-v3"]["last_missed"]
    assert sections["default"]["last_missed"] >= 22, sections["default"]["last_missed"]
