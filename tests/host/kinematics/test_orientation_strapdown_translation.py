"""Gravity removal, double integration and cycle drift removal (Morris 1973) against analytic and simulator truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.rigid_body import RigidBodyShank
from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.strapdown import (
    CycleTranslation,
    cumulative_trapezoid_m,
    remove_cycle_drift,
    remove_gravity,
)
from gaitlog.units import STANDARD_GRAVITY_M_S2


def test_remove_gravity_against_scipy_rotation() -> None:
    rot = Rotation.random(50, random_state=1)
    rng = np.random.default_rng(1)
    a_space = rng.normal(size=(50, 3))  # m/s²
    f_body = rot.inv().apply(a_space / STANDARD_GRAVITY_M_S2 + [0, 0, 1])  # what the accelerometer reads, g
    np.testing.assert_allclose(remove_gravity(f_body, rot.as_matrix()), a_space, atol=1e-13)
    with pytest.raises(HostError, match="need acc_g"):
        remove_gravity(f_body, rot.as_matrix()[:10])


def test_bias_gives_bt2_over_2_and_cycle_drift_removal_cancels_it() -> None:
    rate, period = 1000, 1.0
    t = np.arange(int(period * rate) + 1) / rate
    w = 2 * np.pi / period
    # periodic truth: p = A (1 − cos wt) per axis, a = A w² cos wt, v(0) = 0
    amp = np.array([0.02, 0.01, 0.03])
    a_true = amp * w**2 * np.cos(w * t)[:, None]
    p_true = amp * (1 - np.cos(w * t))[:, None]
    biased = a_true + 0.1
    raw = CycleTranslation(remove_drift=False).integrate(biased, sampling_rate_hz=rate)
    np.testing.assert_allclose(raw.position_m_[-1] - p_true[-1], 0.05, rtol=1e-3)  # b T² / 2
    fixed = CycleTranslation().integrate(biased, sampling_rate_hz=rate)
    assert np.abs(fixed.position_m_ - p_true).max() < 1e-5
    assert np.abs(fixed.velocity_m_s_ - amp * w * np.sin(w * t)[:, None]).max() < 1e-4


def test_cycle_translation_of_the_simulated_shank() -> None:
    src = RigidBodyShank(n_cycles=1)
    m = src.render(1000)
    tr = m.truth
    acc = remove_gravity(m.acc_g, tr["dcm"])
    np.testing.assert_allclose(acc, tr["acceleration_m_s2"], atol=1e-12)
    disp = tr["position_m"][-1] - tr["position_m"][0]
    out = CycleTranslation(cycle_displacement_m=disp).integrate(acc + [0.1, -0.05, 0.2], sampling_rate_hz=1000)
    assert np.abs(out.position_m_ - (tr["position_m"] - tr["position_m"][0])).max() < 1e-5
    assert np.abs(out.velocity_m_s_ - tr["velocity_m_s"]).max() < 1e-4
    # open walking axis: the initial velocity is then needed and used
    open_fwd = CycleTranslation(closed_axes=(1, 2), initial_velocity_m_s=tr["velocity_m_s"][0]).integrate(
        acc, sampling_rate_hz=1000
    )
    assert np.abs(open_fwd.position_m_[:, 0] - (tr["position_m"][:, 0] - tr["position_m"][0, 0])).max() < 1e-4


def test_helpers() -> None:
    x = np.arange(5.0)[:, None] * [1.0, 2.0]
    np.testing.assert_allclose(remove_cycle_drift(x, end_minus_start=[4.0, 0.0]), np.c_[np.arange(5.0), np.zeros(5)])
    np.testing.assert_allclose(cumulative_trapezoid_m(np.ones(11), 10.0), np.linspace(0, 1, 11))
    with pytest.raises(HostError, match="at least 2 samples"):
        remove_cycle_drift(np.zeros(1))
    with pytest.raises(HostError, match="non-finite acceleration at sample 3"):
        CycleTranslation().integrate(np.r_[np.zeros((3, 3)), [[np.nan, 0, 0]]], sampling_rate_hz=10)
