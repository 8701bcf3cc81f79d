"""gaitlog.host.accelerometer.static_windows: rest detection against the pose session's own truth (hold windows of the motion)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.host.accelerometer.static_windows import (
    StaticWindowDetector,
    StaticWindowError,
    find_static_windows,
)

RATE_HZ = 50.0


def session(n_poses: int = 12, hold_s: float = 5.0, move_s: float = 2.0, noise_g: float = 0.002, seed: int = 0,
            q_g: float = 0.0):
    motion = CalibrationPoses(n_poses=n_poses, hold_s=hold_s, move_s=move_s, seed=seed).render(RATE_HZ)
    rng = np.random.default_rng(seed)
    acc = motion.acc_g + noise_g * rng.standard_normal(motion.acc_g.shape)
    if q_g:
        acc = np.floor(acc / q_g) * q_g
    return acc, motion.truth


def inside(win, holds_s, slack_s=0.0):
    t0, t1 = win.start / RATE_HZ, win.stop / RATE_HZ
    return any(h0 - slack_s <= t0 and t1 <= h1 + slack_s for h0, h1 in holds_s)


def test_finds_every_hold_and_only_holds():
    acc, truth = session()
    det = StaticWindowDetector().detect(acc, sampling_rate_hz=RATE_HZ)
    holds = truth["hold_windows_s"]
    assert len(det.windows_) == len(holds)
    for win, (h0, h1), up in zip(det.windows_, holds, truth["specific_force_g"], strict=True):
        assert h0 <= win.start / RATE_HZ and win.stop / RATE_HZ <= h1 + 1e-9  # entirely inside its hold
        assert win.n_samples >= (3.0 - 0.5) * RATE_HZ
        np.testing.assert_allclose(win.mean, up, atol=4 * 0.002 / np.sqrt(win.n_samples))
        assert np.all(win.sd > 0)
    assert det.rejected_ == []
    np.testing.assert_allclose(det.noise_floor_, 0.002, rtol=0.15)


def test_quantised_holds_are_kept():
    """10-bit codes (3.9 mg) with 1 mg noise: the SD of a hold depends on where its level sits in a code; the
    threshold allows for the code step so no hold is lost."""
    acc, truth = session(noise_g=0.001, q_g=4 / 1024)
    det = StaticWindowDetector().detect(acc, sampling_rate_hz=RATE_HZ)
    assert len(det.windows_) == len(truth["hold_windows_s"])
    np.testing.assert_allclose(det.code_step_, 4 / 1024, rtol=1e-9)


def test_rejects_stuck_segments_with_zero_sd():
    acc, truth = session()
    h0, h1 = truth["hold_windows_s"][3]
    i0, i1 = int(h0 * RATE_HZ), int(h1 * RATE_HZ)
    acc[i0:i1, 1] = acc[i0, 1]  # axis y frozen during hold 3
    det = StaticWindowDetector().detect(acc, sampling_rate_hz=RATE_HZ)
    assert len(det.windows_) == len(truth["hold_windows_s"]) - 1
    (win, reason), = det.rejected_
    assert "constant (SD = 0) on axis y" in reason and i0 <= win.start < win.stop <= i1


def test_rejects_near_duplicate_orientations_keeping_the_longer_hold():
    from scipy.spatial.transform import Rotation

    rots = Rotation.from_rotvec([[0, 0, 0], [1.5, 0, 0], [0.03, 0, 0], [0, 1.5, 0]])  # pose 2 is 1.7 deg from 0
    motion = CalibrationPoses(orientations=rots, hold_s=4.0, move_s=2.0).render(RATE_HZ)
    acc = motion.acc_g + 0.002 * np.random.default_rng(0).standard_normal(motion.acc_g.shape)
    acc = np.vstack([acc, np.tile(acc[-1], (100, 1)) + 0.002 * np.random.default_rng(1).standard_normal((100, 3))])
    det = StaticWindowDetector(min_angle_deg=5.0).detect(acc, sampling_rate_hz=RATE_HZ)
    assert len(det.windows_) == 3
    reasons = [r for _, r in det.rejected_]
    assert len(reasons) == 1 and reasons[0].startswith("near-duplicate orientation: 1.7 deg")
    # with a 1 deg threshold both are kept
    assert len(StaticWindowDetector(min_angle_deg=1.0).detect(acc, sampling_rate_hz=RATE_HZ).windows_) == 4


def test_rejects_norm_above_limit_and_slow_drift():
    rng = np.random.default_rng(4)
    n = 400
    still = np.tile([0.0, 0.0, 2.5], (n, 1)) + 0.002 * rng.standard_normal((n, 3))
    n_drift = 3000
    ang = np.linspace(0, np.radians(8), n_drift)  # 8 deg over 60 s: a 3 s SD stays at the noise, not a pose
    drift = np.c_[np.sin(ang), np.zeros(n_drift), np.cos(ang)] + 0.002 * rng.standard_normal((n_drift, 3))
    move = rng.uniform(-1, 1, (50, 3))
    det = StaticWindowDetector().detect(np.vstack([still, move, drift]), sampling_rate_hz=RATE_HZ)
    reasons = [r for _, r in det.rejected_]
    assert det.windows_ == []
    assert reasons[0] == "|mean| = 2.50 g is not below 2.0 g"
    assert len(reasons) == 2 and ("drifts by" in reasons[1] or "still after removing" in reasons[1])


def test_windows_never_span_missing_samples():
    acc, truth = session()
    h0, h1 = truth["hold_windows_s"][5]
    mid = int((h0 + h1) / 2 * RATE_HZ)
    acc[mid, :] = np.nan  # a gap in the middle of hold 5: it splits into two halves shorter than 3 s
    det = StaticWindowDetector().detect(acc, sampling_rate_hz=RATE_HZ)
    assert len(det.windows_) == len(truth["hold_windows_s"]) - 1
    assert all(not (w.start <= mid < w.stop) for w in det.windows_)
    assert all(np.isfinite(w.mean).all() for w in det.windows_)


def test_counts_with_estimated_nominal_map():
    acc, truth = session(noise_g=0.002)
    counts = np.floor(512 + 255.6 * acc)
    det = StaticWindowDetector().detect(counts, sampling_rate_hz=RATE_HZ, unit_per_g=None)
    assert len(det.windows_) == len(truth["hold_windows_s"])
    assert abs(det.unit_per_g_[0] - 255.6) < 0.05 * 255.6 and np.all(np.abs(det.zero_ - 512) < 40)


def test_short_recordings_and_bad_arguments():
    assert find_static_windows(np.zeros((10, 3)), RATE_HZ) == []
    with pytest.raises(StaticWindowError, match=r"shape \(n, 3\)"):
        find_static_windows(np.zeros((10, 2)), RATE_HZ)
    with pytest.raises(StaticWindowError, match="sampling rate"):
        find_static_windows(np.zeros((10, 3)), 0.0)
    with pytest.raises(StaticWindowError, match="under 2 samples"):
        find_static_windows(np.zeros((10, 3)), 0.1)
