"""Event detection and the float pipeline on synthetic trunk acceleration with known events."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.ndimage import gaussian_filter1d

from gaitlog.firmware_sim.algorithms.parameters import EventParameters
from gaitlog.host.gait.axes import body_axes
from gaitlog.host.gait.events import GaitEventDetector
from gaitlog.host.gait.masked_filter import (
    gaussian_sigma_s,
    gaussian_smooth,
    masked_gaussian_lowpass,
)
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.units import STANDARD_GRAVITY_M_S2

G = STANDARD_GRAVITY_M_S2


def synthetic_walk(sampling_rate_hz: float = 50.0, step_s: float = 0.55, n_steps: int = 30, amp_m: float = 0.02,
                   stand_s: float = 2.0, seed: int = 0, impact_delay_s: float = 0.04):
    """Vertical acceleration: sinusoidal CoM (lowest at foot-flat) + an impact pulse peaking
    ``impact_delay_s`` after heel strike (heel strike 80 ms before foot-flat) + an unloading dip at toe-off
    (100 ms after foot-flat)."""
    rng = np.random.default_rng(seed)
    walk_s = n_steps * step_s
    t = np.arange(int((2 * stand_s + walk_s) * sampling_rate_hz)) / sampling_rate_hz
    tw = t - stand_s
    inside = (tw >= 0) & (tw <= walk_s)
    w = 2 * np.pi / step_s
    a = np.where(inside, amp_m * w * w * np.cos(w * tw), 0.0)  # z = -A cos(w t): lowest at t = k * step
    ff_t = stand_s + step_s * np.arange(0, n_steps + 1)
    hs_t = ff_t - 0.08
    to_t = ff_t + 0.10
    for th in hs_t:   # impact: Gaussian pulse (sigma 15 ms) peaking impact_delay_s after contact
        a += 3.0 * np.exp(-0.5 * ((t - th - impact_delay_s) / 0.015) ** 2)
    for tt in to_t:
        a -= 3.0 * np.exp(-0.5 * ((t - tt) / 0.03) ** 2)
    a += rng.normal(0, 0.05, t.size)
    return t, a, ff_t, hs_t, to_t


def test_masked_lowpass_cutoff_is_minus_3db() -> None:
    sampling_rate_hz = 200.0
    t = np.arange(4000) / sampling_rate_hz
    for f in (1.0, 3.0):
        x = np.sin(2 * np.pi * 3.0 * t)
        y = masked_gaussian_lowpass(x, None, cutoff_hz=f, sampling_rate_hz=sampling_rate_hz)
        gain = np.std(y[500:-500]) / np.std(x[500:-500])
        expected = np.exp(-0.5 * (2 * np.pi * 3.0 * gaussian_sigma_s(f)) ** 2)
        assert gain == pytest.approx(expected, rel=2e-3)
    assert gaussian_sigma_s(3.0) == pytest.approx(np.sqrt(np.log(2)) / (2 * np.pi * 3.0))


@settings(max_examples=300, deadline=None)
@given(x=arrays(np.float64, st.integers(1, 400), elements=st.floats(-1e6, 1e6, allow_nan=False)),
       sigma=st.floats(0.05, 40.0))
def test_gaussian_smooth_is_scipy_gaussian_filter1d_to_the_bit(x, sigma) -> None:
    """The numpy Gaussian (the estimate path imports no scipy) against scipy as the oracle, bit for bit."""
    expected = gaussian_filter1d(x, sigma, mode="constant", truncate=4.0)
    np.testing.assert_array_equal(gaussian_smooth(x, sigma), expected)


def test_masked_lowpass_ignores_missing_samples() -> None:
    x = np.full(200, 2.0)
    valid = np.ones(200, bool)
    valid[50:52] = False
    x[50:52] = 1e6  # garbage where missing must not leak
    y = masked_gaussian_lowpass(x, valid, cutoff_hz=3.0, sampling_rate_hz=50.0)
    assert np.allclose(y, 2.0)
    valid[100:160] = False  # a long gap: NaN inside, no invented values
    y = masked_gaussian_lowpass(x, valid, cutoff_hz=3.0, sampling_rate_hz=50.0)
    assert np.isnan(y[130])


def test_foot_flat_is_the_lowest_point_of_a_sinusoidal_com() -> None:
    sampling_rate_hz, step_s = 50.0, 0.55
    t = np.arange(int(20 * sampling_rate_hz)) / sampling_rate_hz
    w = 2 * np.pi / step_s
    a = 0.02 * w * w * np.cos(w * t)             # z = -A cos(w t): lowest (zero velocity) at k * step_s
    det = GaitEventDetector().detect(a, sampling_rate_hz=sampling_rate_hz)
    ff = det.foot_flat_ / sampling_rate_hz
    k = np.round(ff / step_s)
    assert ff.size >= 34
    assert np.max(np.abs(ff - k * step_s)) <= 0.5 / sampling_rate_hz + 1e-9


def test_heel_strike_and_toe_off_on_synthetic_signal() -> None:
    sampling_rate_hz = 50.0
    t, a, ff_t, hs_t, to_t = synthetic_walk(sampling_rate_hz=sampling_rate_hz)
    det = GaitEventDetector().detect(a, sampling_rate_hz=sampling_rate_hz)
    assert det.foot_flat_.size == ff_t.size
    hs = det.heel_strike_ / sampling_rate_hz
    assert np.median(np.abs(hs - hs_t)) <= 1.0 / sampling_rate_hz + 1e-9
    to = det.toe_off_ / sampling_rate_hz
    assert np.median(np.abs(to - to_t)) <= 2.0 / sampling_rate_hz + 1e-9
    # all consecutive foot-flats form steps of one bout
    assert det.step_start_.size == ff_t.size - 1
    assert np.all(det.bout_ == 0)


def test_heel_strike_is_the_impact_not_the_steeper_push_off() -> None:
    """A broad push-off peaking 40 ms before contact whose rise is steeper than the impact's: the steepest rise of the
    10 Hz signal (the rule the impact band replaced) lands on the push-off, the impact band on the impact."""
    sampling_rate_hz = 50.0
    t, a, ff_t, hs_t, _ = synthetic_walk(sampling_rate_hz=sampling_rate_hz)
    for th in hs_t:
        a += 10.0 * np.exp(-0.5 * ((t - th + 0.04) / 0.06) ** 2)
    det = GaitEventDetector().detect(a, sampling_rate_hz=sampling_rate_hz)
    grad = np.gradient(masked_gaussian_lowpass(a, None, cutoff_hz=10.0, sampling_rate_hz=sampling_rate_hz))
    steepest = np.array([f - 10 + int(np.argmax(grad[f - 10:f + 1])) for f in det.foot_flat_]) / sampling_rate_hz
    assert np.median(steepest - hs_t) < -0.06
    assert np.median(np.abs(det.heel_strike_ / sampling_rate_hz - hs_t)) <= 1.0 / sampling_rate_hz + 1e-9


@pytest.mark.parametrize("delay_s", [0.02, 0.06])
def test_heel_strike_delay_is_a_parameter(delay_s: float) -> None:
    sampling_rate_hz = 50.0
    t, a, ff_t, hs_t, _ = synthetic_walk(sampling_rate_hz=sampling_rate_hz, impact_delay_s=delay_s)
    hs = GaitEventDetector(EventParameters(hs_delay_s=delay_s)).detect(a, sampling_rate_hz=sampling_rate_hz).heel_strike_ / sampling_rate_hz
    assert np.median(np.abs(hs - hs_t)) <= 1.0 / sampling_rate_hz + 1e-9
    shifted = GaitEventDetector(EventParameters(hs_delay_s=delay_s + 0.04)).detect(a, sampling_rate_hz=sampling_rate_hz).heel_strike_ / sampling_rate_hz
    assert np.median(hs - shifted) == pytest.approx(0.04, abs=1e-9)


def test_events_standing_still_gives_no_step() -> None:
    rng = np.random.default_rng(1)
    det = GaitEventDetector().detect(rng.normal(0, 0.02, 1000), sampling_rate_hz=50.0)
    assert det.foot_flat_.size == 0 and det.step_start_.size == 0


def test_long_gap_splits_bouts_and_short_gaps_do_not() -> None:
    sampling_rate_hz = 50.0
    t, a, ff_t, *_ = synthetic_walk(sampling_rate_hz=sampling_rate_hz, seed=3)
    valid = np.ones(t.size, bool)
    rng = np.random.default_rng(3)
    valid[rng.choice(t.size, 40, replace=False)] = False      # isolated lost samples
    mid = int((ff_t[14] + 0.27) * sampling_rate_hz)
    valid[mid:mid + 10] = False                                  # 0.2 s gap > max_gap_s
    a = np.where(valid, a, np.nan)
    det = GaitEventDetector().detect(a, sampling_rate_hz=sampling_rate_hz, valid=valid)
    assert np.unique(det.bout_).size == 2
    assert det.step_start_.size == det.foot_flat_.size - 2


def test_detect_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="one-dimensional"):
        GaitEventDetector().detect(np.zeros((10, 3)), sampling_rate_hz=50.0)
    with pytest.raises(ValueError, match="sampling_rate_hz"):
        GaitEventDetector().detect(np.zeros(10), sampling_rate_hz=0.0)


def test_body_axes_recovers_vertical_of_tilted_device() -> None:
    from scipy.spatial.transform import Rotation

    sampling_rate_hz = 50.0
    t, a, *_ = synthetic_walk(sampling_rate_hz=sampling_rate_hz)
    world = np.zeros((t.size, 3))
    world[:, 2] = 1.0 + a / G                                   # specific force, z up
    world[:, 0] = 0.1 * np.sin(2 * np.pi * t / 0.55)            # AP at step frequency
    rot = Rotation.from_euler("xyz", [35, -10, 5], degrees=True)  # mounting tilt
    dev = rot.inv().apply(world)
    ax = body_axes(dev, sampling_rate_hz=sampling_rate_hz)
    core = slice(200, t.size - 200)
    assert np.allclose(ax.acc_v_m_s2[core], a[core] - np.mean(a[core]), atol=0.12)
    assert abs(np.corrcoef(ax.acc_ap_m_s2[core], world[core, 0])[0, 1]) > 0.95


def test_pipeline_on_synthetic_walk_counts_steps_and_length() -> None:
    sampling_rate_hz = 50.0
    t, a, ff_t, *_ = synthetic_walk(sampling_rate_hz=sampling_rate_hz, amp_m=0.02)
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 1.0 + a / G
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pipe = StepPipeline(leg_length_m=0.9, foot_length_m=0.2).run(acc, sampling_rate_hz=sampling_rate_hz)
    st = pipe.steps_
    assert st.n_steps == ff_t.size
    assert np.isnan(st.length_m["M2"][0])  # first step of the bout: no window
    d, filled = st.distance_m("M2")
    assert filled == 1
    assert np.isnan(st.length_m["M4"]).all() and np.isnan(st.length_m["M5"]).all()  # no K given
    assert st.to_csv_text().count("\n") == st.n_steps + 1


def test_pipeline_rejects_bad_shapes() -> None:
    p = StepPipeline(leg_length_m=0.9, foot_length_m=0.2)
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        p.run(np.zeros((10, 2)), sampling_rate_hz=50.0)
    with pytest.raises(ValueError, match="valid"):
        p.run(np.zeros((10, 3)), sampling_rate_hz=50.0, valid=np.ones(9, bool))
