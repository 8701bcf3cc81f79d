"""Calibration poses: truth checked with scipy Rotation; an ideal logger reads 1 g in every hold."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.base import MotionSource
from gaitlog.firmware_sim.world.poses import CalibrationPoses


def test_poses_is_a_motion_source_and_seeded() -> None:
    src = CalibrationPoses(seed=5)
    assert isinstance(src, MotionSource)
    a, b = src.render(100.0), CalibrationPoses(seed=5).render(100.0)
    np.testing.assert_array_equal(a.acc_g, b.acc_g)
    c = CalibrationPoses(seed=6).render(100.0)
    assert not np.allclose(a.truth["specific_force_g"], c.truth["specific_force_g"])


def test_default_24_poses_are_well_spread_and_truth_matches_rotations() -> None:
    m = CalibrationPoses().render(200.0)
    q = m.truth["orientations_xyzw"]
    up = m.truth["specific_force_g"]
    assert q.shape == (24, 4) and up.shape == (24, 3)
    rot = Rotation.from_quat(q)
    # the specific force in device axes, turned into the world, points straight up with 1 g
    np.testing.assert_allclose(rot.apply(up), np.tile([0.0, 0.0, 1.0], (24, 1)), atol=1e-12)
    np.testing.assert_allclose(m.truth["gravity_g"], -up)
    # well spread: every pair of "up" directions at least 30 degrees apart, mean close to 0
    cosines = up @ up.T
    np.fill_diagonal(cosines, -1.0)
    assert np.degrees(np.arccos(cosines.max())) > 30.0
    assert np.linalg.norm(up.mean(axis=0)) < 0.1


def test_holds_are_static_at_the_pose_vector_and_moves_are_smooth() -> None:
    rate = 200.0
    src = CalibrationPoses(n_poses=6, hold_s=3.0, move_s=1.5, seed=2)
    m = src.render(rate)
    holds = m.truth["hold_windows_s"]
    np.testing.assert_allclose(np.diff(holds, axis=1), 3.0)
    assert m.duration_s == pytest.approx(6 * 3.0 + 5 * 1.5)
    for i, (t0, t1) in enumerate(holds):
        sel = (m.t_s >= t0) & (m.t_s < t1)
        np.testing.assert_allclose(m.acc_g[sel], np.tile(m.truth["specific_force_g"][i], (sel.sum(), 1)), atol=1e-12)
    # gravity only: the norm stays 1 g throughout, and no sample-to-sample jump is large
    np.testing.assert_allclose(np.linalg.norm(m.acc_g, axis=1), 1.0, atol=1e-12)
    assert np.abs(np.diff(m.acc_g, axis=0)).max() < 0.05
    np.testing.assert_allclose(m.marker_times_s, holds[1:, 0])


def test_explicit_orientations_and_bad_parameters() -> None:
    rots = Rotation.from_euler("x", [[0.0], [90.0], [180.0]], degrees=True)
    m = CalibrationPoses(orientations=rots, hold_s=3.0, move_s=1.0).render(50.0)
    np.testing.assert_allclose(m.truth["specific_force_g"], [[0, 0, 1], [0, 1, 0], [0, 0, -1]], atol=1e-12)
    with pytest.raises(DeviceError, match="hold_s"):
        CalibrationPoses(hold_s=2.0).render(50.0)
    with pytest.raises(DeviceError, match="move_s"):
        CalibrationPoses(move_s=0.0).render(50.0)


def test_ideal_logger_reads_one_g_in_every_hold() -> None:
    sensor = SensorModel.ideal(noise_density_g_rthz=0.0)
    adc = Adc()
    logger = Logger(sensor=sensor, adc=adc)
    src = CalibrationPoses(n_poses=24, hold_s=3.0, move_s=1.0, seed=4)
    res = logger.record(src)
    # invert the ideal front end independently: code k covers [k, k+1) LSB; take the bin centre
    counts_per_g = adc.gain * sensor.sensitivity_v_per_g / (5.0 / 1024)
    acc = (res.codes.astype(float) + 0.5 - 512.0) / counts_per_g
    t = res.sample_times_s
    for (t0, t1), up in zip(res.truth["hold_windows_s"], res.truth["specific_force_g"]):
        sel = (t >= t0 + 0.5) & (t < t1)  # let the 20 Hz sensor filter settle after the move
        assert sel.sum() >= 120
        np.testing.assert_allclose(np.linalg.norm(acc[sel], axis=1), 1.0, atol=0.008)
        np.testing.assert_allclose(acc[sel], np.tile(up, (sel.sum(), 1)), atol=0.004)
    # the marker flag is set on the first sample at or after each pose change
    marked = res.sample_times_s[(res.flags & 2) > 0]
    np.testing.assert_allclose(marked, res.truth["hold_windows_s"][1:, 0], atol=1 / 50)
