"""Rigid-body shank source: truth checked against scipy Rotation, finite differences and rigid-body physics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.base import Motion, MotionSource
from gaitlog.firmware_sim.world.rigid_body import RigidBodyShank, rotation_chain
from gaitlog.units import STANDARD_GRAVITY_M_S2


def test_rotation_chain_matches_scipy_and_finite_differences() -> None:
    rng = np.random.default_rng(2)
    t = np.linspace(0, 1, 20_001)
    h = t[1]
    c = rng.normal(size=(4, 3))
    q = c[0] + c[1] * np.sin(3 * t[:, None]) + c[2] * t[:, None] ** 2
    qd = 3 * c[1] * np.cos(3 * t[:, None]) + 2 * c[2] * t[:, None]
    qdd = -9 * c[1] * np.sin(3 * t[:, None]) + 2 * c[2]
    dcm, w, al = rotation_chain("zyx", q, qd, qdd)
    np.testing.assert_allclose(dcm, Rotation.from_euler("ZYX", q).as_matrix(), atol=1e-14)
    fd = np.swapaxes(dcm[1:-1], 1, 2) @ (dcm[2:] - dcm[:-2]) / (2 * h)
    np.testing.assert_allclose(np.stack([fd[:, 2, 1], fd[:, 0, 2], fd[:, 1, 0]], 1), w[1:-1], atol=1e-6)
    np.testing.assert_allclose((w[2:] - w[:-2]) / (2 * h), al[1:-1], atol=1e-6)


def test_truth_is_consistent() -> None:
    src = RigidBodyShank()
    m = src.render(2_000)
    tr = m.truth
    h = 1 / 2_000
    np.testing.assert_allclose(tr["dcm"], Rotation.from_euler("YXZ", tr["angles_rad"]).as_matrix(), atol=1e-14)
    p, v, a = tr["position_m"], tr["velocity_m_s"], tr["acceleration_m_s2"]
    np.testing.assert_allclose((p[2:] - p[:-2]) / (2 * h), v[1:-1], atol=2e-5)
    # acceleration is continuous but the jerk jumps at the swing ends: first-order FD error there
    np.testing.assert_allclose((v[2:] - v[:-2]) / (2 * h), a[1:-1], atol=0.03)
    np.testing.assert_allclose((tr["omega_rad_s"][2:] - tr["omega_rad_s"][:-2]) / (2 * h), tr["alpha_rad_s2"][1:-1], atol=1e-3)
    # stance: the pivot is at rest and the origin moves on a sphere about it (Morris eq 11)
    t = m.t_s
    for start, end in tr["stance_intervals_s"]:
        inside = (t >= start) & (t <= end)
        assert np.ptp(tr["pivot_m"][inside], axis=0).max() == 0.0
        np.testing.assert_allclose(np.linalg.norm(p[inside] - tr["pivot_m"][inside], axis=1), 0.2, atol=1e-12)
    # one stride per cycle
    n_cycle = round(src.cycle_s * 2_000)
    np.testing.assert_allclose(tr["pivot_m"][n_cycle] - tr["pivot_m"][0], [1.4, 0, 0], atol=1e-12)
    np.testing.assert_allclose(tr["dcm"][n_cycle], tr["dcm"][0], atol=1e-12)


def test_specific_force_convention_and_platform_readings() -> None:
    still = RigidBodyShank(sagittal_deg=(), coronal_deg=(), axial_deg=(), stride_m=0.0, lift_m=0.0)
    m = still.render(50)
    np.testing.assert_allclose(m.acc_g, np.tile([0, 0, 1.0], (m.n_samples, 1)), atol=1e-15)
    src = RigidBodyShank()
    rec = src.render_platform(10_000)
    tr = rec.motion.truth
    np.testing.assert_allclose(rec.readings_g[:, :3], rec.motion.acc_g, atol=1e-15)
    # accelerometer 3 (axis e1 at d·e3), from the space-frame acceleration of its own point
    d = src.arm_m
    r_i = np.array([0, 0, d])
    lam = tr["dcm"]
    pt = tr["position_m"] + lam @ r_i
    a_space = np.gradient(np.gradient(pt, 1e-4, axis=0), 1e-4, axis=0)
    f_body = np.einsum("nji,nj->ni", lam, a_space / STANDARD_GRAVITY_M_S2 + [0, 0, 1])
    inner = slice(5, -5)
    np.testing.assert_allclose(rec.readings_g[inner, 3], f_body[inner, 0], atol=3e-3)
    assert rec.readings_g.shape == (tr["t_s"].size, 6)
    assert RigidBodyShank(n_accelerometers=5).render_platform(50).readings_g.shape[1] == 5
    with pytest.raises(ValueError, match="5 or 6"):
        RigidBodyShank(n_accelerometers=4).platform_geometry()
    assert isinstance(src, MotionSource) and isinstance(m, Motion)
