"""The recipe baseline (:mod:`gaitlog.host.gait.recipe`) against analytic walks: a centre of mass moving as
``z = (h/2) cos(2 pi f t)`` has per-step excursion h, step frequency f, and an acceleration whose 3 Hz low-pass
keeps it whole (f = 1.8 Hz)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.host.gait.recipe import RecipeBaseline, _joint_correction_excursion_m
from gaitlog.units import STANDARD_GRAVITY_M_S2

FS_HZ = 50.0


def walk(h_m: float, f_hz: float, *, seconds: float = 12.0, tilt_deg: float = 20.0) -> np.ndarray:
    """``(n, 3)`` g: 1 s standing, then the vertical sinusoid, on a sensor tilted by ``tilt_deg``."""
    t = np.arange(int(seconds * FS_HZ)) / FS_HZ
    w = 2 * np.pi * f_hz
    a = np.where(t >= 1.0, -(h_m / 2) * w * w * np.cos(w * (t - 1.0)), 0.0) / STANDARD_GRAVITY_M_S2
    up = 1.0 + a
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    return np.c_[up * c, np.zeros_like(t), up * s]


def test_joint_correction_removes_a_constant_and_a_ramp() -> None:
    """A period of a cosine position (v = 0 at both ends, x equal) plus an offset and a drift in acceleration:
    the excursion is the cosine's peak-to-peak."""
    dt = 0.002
    t = np.arange(0, 1.0 + dt / 2, dt)
    w = 2 * np.pi
    a = -0.02 * w * w * np.cos(w * t) + 0.3 + 0.8 * t          # x = 0.02 cos(w t): ptp 0.04 over a full period
    assert _joint_correction_excursion_m(a, dt) == pytest.approx(0.04, rel=2e-3)


@pytest.mark.parametrize("h_m, f_hz", [(0.04, 1.8), (0.03, 1.6)])
def test_recipe_recovers_steps_and_excursion(h_m, f_hz) -> None:
    leg = 0.9
    acc = walk(h_m, f_hz)
    valid = np.ones(acc.shape[0], bool)
    valid[200:203] = valid[300] = False                    # gaps are interpolated
    acc[~valid] = np.nan
    rec = RecipeBaseline(leg_length_m=leg).estimate(acc, valid, sampling_rate_hz=FS_HZ)
    n_expected = int(11.0 * f_hz) - 1                        # peaks one step apart over 11 s of walking
    assert abs(rec.step_end_.size - n_expected) <= 1
    inner = rec.length_m_["M2"][1:-1]
    want = 2 * np.sqrt(2 * leg * h_m - h_m ** 2)
    # at 50 Hz the peaks bound windows of whole samples, up to half a sample off the true period: each step
    # within 5 % (measured -4.0 % to +2.5 %), their mean within 1.5 % (what a distance sums)
    np.testing.assert_allclose(inner, want, rtol=0.05)
    assert np.mean(inner) == pytest.approx(want, rel=0.015)
    rng = h_m / 2 * (2 * np.pi * f_hz) ** 2 * 2               # peak-to-peak acceleration, m/s^2
    np.testing.assert_allclose(rec.length_m_["M4"][1:-1], rng ** 0.25, rtol=0.01)


def test_standing_gives_no_step() -> None:
    acc = walk(0.0, 1.8)
    acc += np.random.default_rng(0).normal(0, 0.002, acc.shape)
    rec = RecipeBaseline(leg_length_m=0.9).estimate(acc, np.ones(acc.shape[0], bool), sampling_rate_hz=FS_HZ)
    assert rec.step_end_.size == 0 and rec.length_m_["M2"].size == 0
