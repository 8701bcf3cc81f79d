"""Hall (1997) joint kinematics: eq (3)/(4) angles vs scipy Rotation, the full pipeline vs simulator truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.two_link import HALL_SENSOR_TO_LINK, TwoLinkJoint
from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.joints import (
    HallJointKinematics,
    apply_right_leg_convention,
    joint_angles_yxz,
    joint_matrix_yxz,
    remove_pretest_offset,
)


def test_round_trip_40_m25_10_and_scipy_reference() -> None:
    ang = np.radians([40.0, -25.0, 10.0])
    ta = Rotation.from_euler("ZYX", [20, 10, -5], degrees=True).as_matrix().T  # arbitrary link A
    t_joint = joint_matrix_yxz(ang)
    tb = t_joint @ ta
    t_rel = tb @ ta.T  # T = TB·TAᵀ
    got, lock = joint_angles_yxz(t_rel)
    np.testing.assert_allclose(got, ang, atol=1e-13)
    ref = Rotation.from_matrix(ta @ tb.T).as_euler("YXZ")
    np.testing.assert_allclose(got, ref, atol=1e-13)
    assert not lock


def test_eq3_matches_printed_entries_and_corrected_eq4() -> None:
    phi, theta, psi = np.radians([40.0, -25.0, 10.0])
    t = joint_matrix_yxz([phi, theta, psi])
    # (rows i_B, j_B, k_B; columns i_A, j_A, k_A) -- the dot products of eq (4)
    assert t[2, 1] == pytest.approx(-np.sin(theta))  # k_B·j_A
    assert np.arcsin(t[2, 0] / np.cos(theta)) == pytest.approx(phi)  # corrected: k_B·i_A
    assert np.arcsin(t[0, 1] / np.cos(theta)) == pytest.approx(psi)  # i_B·j_A
    assert np.arcsin(t[2, 1] / np.cos(theta)) != pytest.approx(phi)  # the printed k_B·j_A is wrong


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_angles_property_random_orientations(seed: int) -> None:
    rots = Rotation.random(2, random_state=seed).as_matrix()
    ta, tb = rots[0].T, rots[1].T
    got, lock = joint_angles_yxz(tb @ ta.T, gimbal_tol_rad=1e-6)
    if lock:
        return
    ref = Rotation.from_matrix(ta @ tb.T).as_euler("YXZ")
    np.testing.assert_allclose(got, ref, atol=1e-9)
    np.testing.assert_allclose(joint_matrix_yxz(got), tb @ ta.T, atol=1e-12)


def test_gimbal_lock_is_reported() -> None:
    t = joint_matrix_yxz(np.radians([[10.0, 89.9, 5.0], [10.0, 45.0, 5.0], [10.0, -90.0, 5.0]]))
    ang, lock = joint_angles_yxz(t, gimbal_tol_rad=np.radians(0.5))
    assert lock.tolist() == [True, False, True]
    # only φ ∓ ψ is defined at lock; the matrix is still reproduced
    np.testing.assert_allclose(joint_matrix_yxz(ang), t, atol=1e-6)


def test_right_leg_convention_negates_version_and_axial() -> None:
    np.testing.assert_array_equal(apply_right_leg_convention([10.0, -5.0, 3.0]), [10.0, 5.0, -3.0])


def test_pretest_offset_removal() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(100, 3)) * 0.001 + [0.1, -0.2, 0.3]
    out = remove_pretest_offset(x, 40)
    np.testing.assert_allclose(out[:40].mean(axis=0), 0.0, atol=1e-15)
    with pytest.raises(HostError, match="does not fit"):
        remove_pretest_offset(x, 101)


def _run(src: TwoLinkJoint, sampling_rate_hz: float = 10_000, **kw: object) -> tuple[HallJointKinematics, dict]:
    r = src.render_rates(sampling_rate_hz)
    algo = HallJointKinematics(
        sensor_to_link_a=r.truth["sensor_to_link_a"],
        sensor_to_link_b=r.truth["sensor_to_link_b"],
        pretest_samples=r.pretest_samples,
        **kw,
    ).compute(r.rate_a_rad_s, r.rate_b_rad_s, sampling_rate_hz=sampling_rate_hz)
    return algo, r.truth


def test_pipeline_recovers_truth_joint_angles() -> None:
    algo, truth = _run(TwoLinkJoint())
    err_deg = np.degrees(np.abs(algo.angles_rad_ - truth["joint_angles_rad"])).max()
    assert err_deg < 1e-3
    np.testing.assert_allclose(algo.ta_, truth["ta"], atol=1e-6)
    np.testing.assert_allclose(algo.tb_, truth["tb"], atol=1e-6)
    np.testing.assert_allclose(np.degrees(algo.angles_rad_[-1]), [40.0, -20.0, 15.0], atol=1e-3)
    assert not algo.gimbal_lock_.any()


def test_pipeline_with_noise_cfc180_and_right_leg() -> None:
    src = TwoLinkJoint(noise_rad_s=0.02, seed=5)
    algo, truth = _run(src, cfc=180, side="right")
    want = apply_right_leg_convention(truth["joint_angles_rad"])
    assert np.degrees(np.abs(algo.angles_rad_ - want)).max() < 0.05
    # without the offset removal the 0.01-0.025 rad/s offsets integrate to a visible error
    r = src.render_rates(10_000)
    raw = HallJointKinematics(
        sensor_to_link_a=HALL_SENSOR_TO_LINK, sensor_to_link_b=HALL_SENSOR_TO_LINK, side="right"
    ).compute(r.rate_a_rad_s, r.rate_b_rad_s, sampling_rate_hz=10_000)
    assert np.degrees(np.abs(raw.angles_rad_ - want)).max() > 0.1


def test_literal_summation_of_incremental_euler_angles_is_path_dependent() -> None:
    # straight line in angle space from 0 to (40, -20, 15) deg, constant link A
    n = 2001
    target = np.radians([40.0, -20.0, 15.0])
    ang = np.linspace(0, 1, n)[:, None] * target
    rate_b = np.empty((n, 3))
    # body rate of B = Ry(φ)Rx(θ)Rz(ψ) for a linear angle path, from scipy's finite rotation increments
    rots = Rotation.from_euler("YXZ", ang)
    inc = (rots[:-1].inv() * rots[1:]).as_rotvec() * (n - 1)  # rad per unit time, per step
    # feed piecewise-constant rates exactly reproducing each increment (trapezoid of equal neighbours)
    rate_b[0] = inc[0]
    for k in range(1, n):  # ω_k = 2·inc_{k-1} − ω_{k-1} makes (ω_{k-1}+ω_k)/2 = inc_{k-1}
        rate_b[k] = 2 * inc[k - 1] - rate_b[k - 1]
    zeros = np.zeros((n, 3))
    absolute = HallJointKinematics().compute(zeros, rate_b, sampling_rate_hz=n - 1)
    literal = HallJointKinematics(angle_mode="incremental_sum").compute(zeros, rate_b, sampling_rate_hz=n - 1)
    np.testing.assert_allclose(np.degrees(absolute.angles_rad_[-1]), [40.0, -20.0, 15.0], atol=1e-9)
    np.testing.assert_allclose(np.degrees(literal.angles_rad_[-1]), [41.4, -14.7, 21.9], atol=0.06)
    # planar motion: the two agree
    planar = np.zeros((n, 3))
    planar[:, 1] = 0.7
    a = HallJointKinematics().compute(zeros, planar, sampling_rate_hz=100).angles_rad_
    b = HallJointKinematics(angle_mode="incremental_sum").compute(zeros, planar, sampling_rate_hz=100).angles_rad_
    np.testing.assert_allclose(np.unwrap(a[:, 0]), b[:, 0], atol=1e-9)


def test_gimbal_lock_warns_in_pipeline() -> None:
    n = 200
    rate = np.zeros((n, 3))
    rate[:, 0] = np.pi / 2 / ((n - 1) / 100)  # version reaches 90 deg
    with pytest.warns(UserWarning, match="gimbal lock"):
        algo = HallJointKinematics().compute(np.zeros((n, 3)), rate, sampling_rate_hz=100)
    assert algo.gimbal_lock_[-1] and not algo.gimbal_lock_[0]


def test_bad_inputs_raise_clear_errors() -> None:
    z = np.zeros((10, 3))
    with pytest.raises(HostError, match="different lengths"):
        HallJointKinematics().compute(z, np.zeros((11, 3)), sampling_rate_hz=100)
    with pytest.raises(HostError, match="det -1"):
        HallJointKinematics(sensor_to_link_a=[[0, 1, 0], [0, 0, 1], [-1, 0, 0]]).compute(z, z, sampling_rate_hz=100)
    bad = z.copy()
    bad[4, 1] = np.nan
    with pytest.raises(HostError, match="sample 4"):
        HallJointKinematics().compute(bad, z, sampling_rate_hz=100)
    with pytest.raises(HostError, match="CFC 180 filter is invalid at 500 Hz"):
        HallJointKinematics(cfc=180).compute(np.zeros((100, 3)), np.zeros((100, 3)), sampling_rate_hz=500)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        HallJointKinematics().compute(z, z, sampling_rate_hz=100)
