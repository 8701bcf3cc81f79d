"""Two-link motion source: truth consistency checked against scipy Rotation and finite differences."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.base import Motion, MotionSource
from gaitlog.firmware_sim.world.two_link import HALL_SENSOR_TO_LINK, TwoLinkJoint


def test_truth_matrices_match_scipy_euler() -> None:
    r = TwoLinkJoint().render_rates(2_000)
    tr = r.truth
    lam_a = Rotation.from_euler("YX", tr["link_a_angles_rad"]).as_matrix()
    np.testing.assert_allclose(tr["ta"], np.swapaxes(lam_a, 1, 2), atol=1e-14)
    rel = Rotation.from_euler("YXZ", tr["joint_angles_rad"]).as_matrix()  # λB = λA · Ry Rx Rz
    np.testing.assert_allclose(tr["tb"], np.swapaxes(lam_a @ rel, 1, 2), atol=1e-14)
    np.testing.assert_allclose(tr["joint_matrix"], tr["tb"] @ np.swapaxes(tr["ta"], 1, 2), atol=1e-14)
    np.testing.assert_allclose(np.degrees(tr["joint_angles_rad"][-1]), [40.0, -20.0, 15.0], atol=1e-12)
    assert np.all(tr["joint_angles_rad"][: r.pretest_samples] == 0)


def test_sensor_rates_are_link_rates_in_sensor_axes() -> None:
    src = TwoLinkJoint(noise_rad_s=0.0)
    r = src.render_rates(20_000)
    tr = r.truth
    s = HALL_SENSOR_TO_LINK
    assert np.linalg.det(s) == 1.0
    np.testing.assert_allclose((r.rate_a_rad_s - tr["offset_a_rad_s"]) @ s.T, tr["omega_a_link_rad_s"], atol=1e-14)
    # body rate of B from finite differences of the truth matrix: [ω×] = λᵀ λ̇
    lam = np.swapaxes(tr["tb"], 1, 2)
    fd = np.swapaxes(lam[1:-1], 1, 2) @ (lam[2:] - lam[:-2]) * (20_000 / 2)
    w = tr["omega_b_link_rad_s"][1:-1]
    t = tr["t_s"][1:-1]
    smooth = (np.abs(t - src.pretest_s) > 2e-4) & (np.abs(t - src.pretest_s - src.move_s) > 2e-4)  # q̈ jumps
    fd_w = np.stack([fd[:, 2, 1], fd[:, 0, 2], fd[:, 1, 0]], axis=1)
    np.testing.assert_allclose(fd_w[smooth], w[smooth], atol=2e-4)


def test_seeded_noise_and_motion_source_protocol() -> None:
    a = TwoLinkJoint(noise_rad_s=0.01, seed=3).render_rates(1_000)
    b = TwoLinkJoint(noise_rad_s=0.01, seed=3).render_rates(1_000)
    np.testing.assert_array_equal(a.rate_a_rad_s, b.rate_a_rad_s)
    assert isinstance(TwoLinkJoint(), MotionSource)
    m = TwoLinkJoint().render(1_000)
    assert isinstance(m, Motion) and m.acc_g.shape == (221, 3)
    np.testing.assert_allclose(np.linalg.norm(m.acc_g, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(m.acc_g[0], [0, 0, 1], atol=1e-15)
    assert m.truth["pretest_samples"] == 21
