"""Angular velocity from accelerometer pairs (Morris eqs 5-8) against the rigid-body simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.world.rigid_body import RigidBodyShank
from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.accelerometer_pairs import (
    AngularVelocityFromAccelerometers,
    gravity_from_pivot,
)
from gaitlog.host.kinematics.orientation import initial_dcm_from_gravity
from gaitlog.units import STANDARD_GRAVITY_M_S2

GENTLE = dict(sagittal_deg=((1, 0.0, 20.0),), coronal_deg=((1, 0.0, 3.0),), axial_deg=((1, 0.0, 3.0),), n_cycles=1)


def _estimate(src: RigidBodyShank, sampling_rate_hz: float, **kw: object):
    rec = src.render_platform(sampling_rate_hz)
    tr = rec.motion.truth
    algo = AngularVelocityFromAccelerometers(positions_m=rec.positions_m, axes=rec.axes, **kw).estimate(
        rec.readings_g, sampling_rate_hz=sampling_rate_hz, omega0_rad_s=tr["omega_rad_s"][0]
    )
    return algo, rec, tr


def test_pair_difference_equation_5_holds_on_simulator_readings() -> None:
    """Δm = n·(ω̇ × t + ω × (ω × t)) for each parallel pair (eq 5), with the truth ω, ω̇."""
    rec = RigidBodyShank().render_platform(200)
    tr = rec.motion.truth
    w, al = tr["omega_rad_s"], tr["alpha_rad_s2"]
    for a, b in ((3, 0), (4, 1), (5, 1)):  # parallel pairs: same axis, different position
        n = rec.axes[a]
        assert np.array_equal(n, rec.axes[b])
        t = rec.positions_m[a] - rec.positions_m[b]
        pred = (np.cross(al, t) + np.cross(w, np.cross(w, t))) @ n / STANDARD_GRAVITY_M_S2
        np.testing.assert_allclose(rec.readings_g[:, a] - rec.readings_g[:, b], pred, atol=1e-14)


def test_six_accelerometers_give_omega_to_1e_5_at_1khz() -> None:
    algo, rec, tr = _estimate(RigidBodyShank(**GENTLE), 1000)
    err = np.abs(algo.omega_rad_s_ - tr["omega_rad_s"]).max()
    assert np.abs(tr["omega_rad_s"]).max() > 1.9  # a walking-like shank rate
    assert err < 2e-5  # notes: ~1e-5 rad/s
    # the origin force and the residuals are exact for a square, consistent platform
    np.testing.assert_allclose(algo.origin_specific_force_g_, rec.motion.acc_g, atol=1e-12)
    assert np.abs(algo.residual_g_).max() < 1e-12


def test_trapezoid_error_is_second_order() -> None:
    errs = []
    for rate in (100, 1000):
        algo, _, tr = _estimate(RigidBodyShank(**GENTLE), rate)
        errs.append(np.abs(algo.omega_rad_s_ - tr["omega_rad_s"]).max())
    assert errs[0] / errs[1] == pytest.approx(100, rel=0.05)


def test_angular_acceleration_is_exact_given_omega() -> None:
    algo, rec, tr = _estimate(RigidBodyShank(), 500)
    # α from the platform is exact when ω is; the small α error comes from ω's integration error only
    alpha_err = np.abs(algo.alpha_rad_s2_ - tr["alpha_rad_s2"]).max()
    omega_err = np.abs(algo.omega_rad_s_ - tr["omega_rad_s"]).max()
    assert alpha_err < 0.05 and omega_err < 5e-4


def test_five_accelerometers_planar_and_the_cost_of_omega3_zero() -> None:
    planar = RigidBodyShank(n_accelerometers=5, coronal_deg=(), axial_deg=(), n_cycles=1)
    algo, _, tr = _estimate(planar, 1000, fixed_zero_axes=(2,))
    assert np.abs(algo.omega_rad_s_ - tr["omega_rad_s"]).max() < 1e-4
    np.testing.assert_allclose(algo.alpha_rad_s2_, tr["alpha_rad_s2"], atol=1e-9)
    assert np.all(algo.omega_rad_s_[:, 2] == 0.0)
    # with transverse rotation present Morris' assumption ω3 = 0 costs accuracy
    algo3, _, tr3 = _estimate(RigidBodyShank(n_accelerometers=5, **GENTLE), 1000, fixed_zero_axes=(2,))
    assert np.abs(algo3.omega_rad_s_ - tr3["omega_rad_s"]).max() > 0.05


def test_rank_deficient_platform_and_bad_readings_are_rejected() -> None:
    src = RigidBodyShank(n_accelerometers=5)
    pos, axes = src.platform_geometry()
    with pytest.raises(HostError, match="does not determine"):
        AngularVelocityFromAccelerometers(positions_m=pos, axes=axes).estimate(np.zeros((10, 5)), sampling_rate_hz=100)
    algo = AngularVelocityFromAccelerometers(positions_m=pos, axes=axes, fixed_zero_axes=(2,))
    with pytest.raises(HostError, match=r"shape \(n, 5\)"):
        algo.estimate(np.zeros((10, 6)), sampling_rate_hz=100)
    bad = np.zeros((10, 5))
    bad[7, 0] = np.inf
    with pytest.raises(HostError, match="sample 7"):
        algo.estimate(bad, sampling_rate_hz=100)


def test_initial_dcm_at_foot_flat_from_the_pivot_constraint() -> None:
    """Eq (11): during foot-flat, f − (ω̇×r + ω×(ω×r)) is the up vector; the DCM from it matches the truth
    up to a rotation about the vertical (the heading is fixed by λ12 = 0)."""
    rec = RigidBodyShank().render_platform(1000)
    tr = rec.motion.truth
    k = 100  # 0.1 s: foot-flat
    assert tr["stance_intervals_s"][0, 0] <= k / 1000 <= tr["stance_intervals_s"][0, 1]
    up = gravity_from_pivot(rec.motion.acc_g[k], tr["omega_rad_s"][k], tr["alpha_rad_s2"][k], tr["origin_offset_m"])
    assert np.linalg.norm(up) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(up, tr["dcm"][k][2], atol=1e-12)
    lam = initial_dcm_from_gravity(up)
    rel = lam @ tr["dcm"][k].T  # must be a rotation about space axis 3
    np.testing.assert_allclose(rel[2], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(rel[:, 2], [0, 0, 1], atol=1e-12)
