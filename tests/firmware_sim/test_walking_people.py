"""The ``"people"`` population: its extra trunk motion keeps the world exact, and its gait laws are its own."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from gaitlog.firmware_sim.world.base import Motion
from gaitlog.firmware_sim.world.subject import Subject, random_subjects
from gaitlog.firmware_sim.world.walk_plan import POPULATION_PLANS, WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.units import STANDARD_GRAVITY_M_S2

PLAN = WalkPlan(corridor_length_m=10.0, speeds=("preferred",), initial_stand_s=2.0, final_stand_s=1.0,
                lap_marks_m=(0.0, 20.0), **POPULATION_PLANS["people"])


@pytest.fixture(scope="module")
def people() -> tuple[Subject, Motion]:
    subject = random_subjects(4, seed=3, population="people")[3]
    return subject, Walking(subject=subject, walk_plan=PLAN, seed=9, include_trajectory=True).render(1000.0)


def test_people_draws_extend_the_v1_draws_and_v1_is_unchanged() -> None:
    v1, v1_again, ppl = (random_subjects(5, seed=2), random_subjects(5, seed=2, population="v1"),
                         random_subjects(5, seed=2, population="people"))
    assert v1 == v1_again
    for a, b in zip(v1, ppl):
        # drawn before the people overrides: identical
        assert (a.pendulum_ratio, a.mounting_rotation_deg, a.double_support_fraction) == (
            b.pendulum_ratio, b.mounting_rotation_deg, b.double_support_fraction)
        assert a.ml_harmonics_m_s2 == () and a.cadence_law_spm is None and a.vertical_asymmetry == 0.0
        assert len(b.ml_harmonics_m_s2) == 9 and len(b.ap_harmonics_m_s2) == 3 and b.cadence_law_spm is not None
    with pytest.raises(ValueError, match="unknown population"):
        random_subjects(1, population="martians")


def test_extra_trunk_motion_still_double_integrates_to_the_truth(people) -> None:
    """ML stride harmonics with step-varying gain and AP harmonics are exact derivatives of the positions."""
    _, motion = people
    tr, steps, t = motion.truth["trajectory"], motion.truth["steps"], motion.t_s
    acc_w = np.einsum("nij,nj->ni", tr["world_from_device"], motion.acc_g) * STANDARD_GRAVITY_M_S2
    acc_w[:, 2] -= STANDARD_GRAVITY_M_S2
    for i in range(2, steps["heel_strike_s"].size - 2, 3):
        i0 = int(np.ceil(steps["heel_strike_s"][i] * 1000.0))
        i1 = int(np.floor(steps["next_heel_strike_s"][i] * 1000.0))
        v = tr["sensor_velocity_m_s"][i0] + cumulative_trapezoid(acc_w[i0:i1], t[i0:i1], axis=0, initial=0.0)
        p = tr["sensor_position_m"][i0] + cumulative_trapezoid(v, t[i0:i1], axis=0, initial=0.0)
        np.testing.assert_allclose(v, tr["sensor_velocity_m_s"][i0:i1], atol=3e-4)
        np.testing.assert_allclose(p, tr["sensor_position_m"][i0:i1], atol=2e-5)


def test_lateral_acceleration_is_not_a_sway(people) -> None:
    """At the preferred rate the stride harmonics 3 and 5 of the lateral CoM acceleration are as the subject
    says (amplitude in m/s^2), i.e. comparable to the stride-frequency sway, not ~0 as in a pure sway."""
    subject, motion = people
    tr, steps = motion.truth["trajectory"], motion.truth["steps"]
    steady = np.flatnonzero(steps["phase"] == "steady")
    hs = steps["heel_strike_s"]
    i = steady[len(steady) // 2 - 1]
    k0, k1 = int(round(hs[i] * 1000)), int(round(hs[i + 2] * 1000))         # one stride on the way out
    y = tr["com_position_m"][k0:k1, 1]
    n = y.size
    amp_pos = 2 * np.abs(np.fft.rfft(y - y.mean()))[1:7] / n                 # lateral position harmonics 1..6
    w = 2 * np.pi / ((k1 - k0) / 1000.0)
    amp_acc = amp_pos * (w * np.arange(1, 7)) ** 2
    scale = subject.preferred_speed_m_s / subject.preferred_speed_m_s      # preferred speed: amplitude_scale 1
    gain_tol = 0.6                                                           # step gains exp(N(0, ~0.3)) apply
    for k in (3, 5):
        expected = subject.ml_harmonics_m_s2[k - 2] * scale
        assert expected * (1 - gain_tol) < amp_acc[k - 1] < expected * (1 + gain_tol) + 0.05, (k, amp_acc)
    assert amp_acc[2] > 0.3 * amp_acc[0]


def test_step_length_follows_the_cadence_law_not_the_walk_ratio() -> None:
    s = dataclasses.replace(Subject(), height_m=1.72, cadence_law_spm=(72.0, 33.0))
    v = np.array([0.8, 1.1, 1.4, 1.7])
    cadence = 72.0 + 33.0 * v
    np.testing.assert_allclose(s.step_length_m(v), 60.0 * v / cadence)
    walk_ratio = s.step_length_m(v) / cadence                                # constant under Sekiya's law
    assert np.ptp(walk_ratio) / walk_ratio.mean() > 0.15
    # step length linear in step duration (not in step frequency, M5's model)
    dur = s.step_length_m(v) / v
    fit = np.polyfit(dur, s.step_length_m(v), 1)
    np.testing.assert_allclose(np.polyval(fit, dur), s.step_length_m(v), atol=1e-12)
    assert s.preferred_stride_rate_rad_s == pytest.approx(np.pi * 1.35 / float(s.step_length_m(1.35)))


def test_steady_steps_walk_the_drawn_law(people) -> None:
    subject, motion = people
    st = motion.truth["steps"]
    steady = st["phase"] == "steady"
    dur = st["next_heel_strike_s"][steady] - st["heel_strike_s"][steady]
    v = subject.preferred_speed_m_s
    assert np.mean(st["length_m"][steady]) == pytest.approx(float(subject.step_length_m(v)), rel=0.06)
    assert 60.0 / np.mean(dur) == pytest.approx(60.0 * v / float(subject.step_length_m(v)), rel=0.06)
