"""M1-M5 against analytic results: sinusoidal CoM with known excursion, exact pendulum geometry."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.host.errors import HostError
from gaitlog.host.gait.anthropometry import anatomical_lengths
from gaitlog.host.gait.estimators.cadence import CadenceM5
from gaitlog.host.gait.estimators.pendulum import PendulumDriftM2, PendulumM1, pendulum_length_m
from gaitlog.host.gait.estimators.two_phase import TwoPhasePendulumM3
from gaitlog.host.gait.estimators.weinberg import WeinbergM4


def com_sinusoid(sampling_rate_hz: float, step_s: float, n: int, amp_m: float):
    """z = -A cos(2 pi t / T): lowest with zero velocity at every foot-flat k*T; excursion 2A per step."""
    t = np.arange(int(round(n * step_s * sampling_rate_hz)) + 1) / sampling_rate_hz
    w = 2 * np.pi / step_s
    a = amp_m * w * w * np.cos(w * t)
    ff = np.round(np.arange(n + 1) * step_s * sampling_rate_hz).astype(int)
    return t, a, ff


@pytest.mark.parametrize("amp_m", [0.01, 0.025])
def test_m1_m2_recover_known_excursion(amp_m: float) -> None:
    sampling_rate_hz, l = 200.0, 0.92
    t, a, ff = com_sinusoid(sampling_rate_hz, 0.5, 10, amp_m)
    h = 2 * amp_m
    truth = 2 * np.sqrt(2 * l * h - h * h)
    for cls in (PendulumM1, PendulumDriftM2):
        est = cls(k=1.0).estimate(a, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz, leg_length_m=l)
        assert np.allclose(est.vertical_excursion_m_, h, atol=2e-4)
        assert np.allclose(est.step_length_m_, truth, rtol=3e-3)
    k = PendulumM1(k=1.3).estimate(a, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz, leg_length_m=l)
    assert np.allclose(k.step_length_m_, 1.3 * truth, rtol=3e-3)


def test_m2_drift_correction_removes_offset_and_velocity_error() -> None:
    """An accelerometer offset of 0.3 m/s^2 ruins M1 (h grows by b T^2 / 2) but not M2 (c1 = -mean(a))."""
    sampling_rate_hz, l, amp = 200.0, 0.9, 0.02
    t, a, ff = com_sinusoid(sampling_rate_hz, 0.55, 8, amp)
    biased = a + 0.3
    m1 = PendulumM1().estimate(biased, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz, leg_length_m=l)
    m2 = PendulumDriftM2().estimate(biased, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz,
                                    leg_length_m=l)
    assert np.allclose(m2.vertical_excursion_m_, 2 * amp, atol=3e-4)
    assert np.all(np.abs(m1.vertical_excursion_m_ - 2 * amp) > 0.01)


def test_integrals_skip_missing_samples_without_inventing_them() -> None:
    sampling_rate_hz, l, amp = 100.0, 0.9, 0.02
    t, a, ff = com_sinusoid(sampling_rate_hz, 0.5, 6, amp)
    valid = np.ones(t.size, bool)
    valid[np.random.default_rng(0).choice(np.arange(1, t.size - 1), 15, replace=False)] = False
    valid[ff] = True
    a_missing = np.where(valid, a, 1e9)  # values at missing samples must never be read
    m2 = PendulumDriftM2().estimate(a_missing, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz,
                                    leg_length_m=l, valid=valid)
    assert np.allclose(m2.vertical_excursion_m_, 2 * amp, atol=1.5e-3)


def two_phase_step(sampling_rate_hz: float, l: float, theta0: float, t_ds: float, t_ss: float):
    """One step: double support as a parabola (concave up), single support as an exact inverted pendulum
    z = l cos(theta), theta swept linearly from -theta0 to +theta0; C1-continuous, zero vertical velocity
    at both foot-flats, symmetric (z at both ends equal)."""
    om = 2 * theta0 / t_ss
    v_to = l * np.sin(theta0) * om           # rising speed at toe-off
    k = v_to / (2 * t_ds)
    T = 2 * t_ds + t_ss
    t = np.arange(int(round(T * sampling_rate_hz)) + 1) / sampling_rate_hz
    a = np.empty_like(t)
    ds1, ss = t < t_ds, (t >= t_ds) & (t <= t_ds + t_ss)
    a[ds1] = 2 * k
    a[~ds1 & ~ss] = 2 * k
    theta = -theta0 + om * (t[ss] - t_ds)
    a[ss] = -l * np.cos(theta) * om * om
    return t, a, int(round(t_ds * sampling_rate_hz)), int(round((t_ds + t_ss) * sampling_rate_hz))


def test_m3_equals_pendulum_chord_plus_foot() -> None:
    sampling_rate_hz, l, theta0, foot = 1000.0, 0.9, np.radians(17.0), 0.19
    t, a, to, hs = two_phase_step(sampling_rate_hz, l, theta0, t_ds=0.06, t_ss=0.42)
    m3 = TwoPhasePendulumM3().estimate(a, step_start=[0], step_end=[t.size - 1], step_toe_off=[to],
                                       step_heel_strike=[hs], sampling_rate_hz=sampling_rate_hz, leg_length_m=l,
                                       foot_length_m=foot)
    chord = 2 * l * np.sin(theta0)            # geometry, independent of eq (1)
    # 1 % on h1: trapezoidal quadrature of the acceleration steps at toe-off and heel-strike
    assert m3.single_support_excursion_m_[0] == pytest.approx(l * (1 - np.cos(theta0)), rel=1e-2)
    assert m3.step_length_m_[0] == pytest.approx(chord + foot, rel=4e-3)


def test_m3_missing_events_give_nan() -> None:
    sampling_rate_hz, l = 1000.0, 0.9
    t, a, to, hs = two_phase_step(sampling_rate_hz, l, 0.3, 0.06, 0.42)
    m3 = TwoPhasePendulumM3().estimate(a, step_start=[0], step_end=[t.size - 1], step_toe_off=[-1],
                                       step_heel_strike=[hs], sampling_rate_hz=sampling_rate_hz, leg_length_m=l,
                                       foot_length_m=0.2)
    assert np.isnan(m3.step_length_m_[0]) and m3.n_no_events_ == 1


def test_impossible_excursion_is_nan_counted_and_warned() -> None:
    s, bad = pendulum_length_m(np.array([0.05, 2.0, -0.01, np.nan]), 0.9)
    assert np.isfinite(s[0]) and np.isnan(s[1:]).all() and bad == 2
    sampling_rate_hz = 100.0
    t, a, ff = com_sinusoid(sampling_rate_hz, 0.5, 2, 1.0)  # 2 m excursion > 2 l
    with pytest.warns(UserWarning, match="impossible"):
        m1 = PendulumM1().estimate(a, step_start=ff[:-1], step_end=ff[1:], sampling_rate_hz=sampling_rate_hz, leg_length_m=0.9)
    assert np.isnan(m1.step_length_m_).all() and m1.n_impossible_ == 2


@pytest.mark.parametrize("exponent", [0.25, M4_EXPONENT])
def test_m4_weinberg_power_of_lowpassed_range(exponent: float) -> None:
    sampling_rate_hz, f, amp = 100.0, 0.5, 1.5
    t = np.arange(int(8 * sampling_rate_hz)) / sampling_rate_hz
    a = amp * np.sin(2 * np.pi * f * t)
    sigma = np.sqrt(np.log(2)) / (2 * np.pi * 3.0)
    gain = np.exp(-0.5 * (2 * np.pi * f * sigma) ** 2)   # Gaussian low-pass response at f
    m4 = WeinbergM4(k=0.45, exponent=exponent).estimate(a, step_start=[200], step_end=[400],
                                                        sampling_rate_hz=sampling_rate_hz)
    assert m4.acc_range_m_s2_[0] == pytest.approx(2 * amp * gain, rel=2e-3)
    assert m4.step_length_m_[0] == pytest.approx(0.45 * (2 * amp * gain) ** exponent, rel=1e-3)


def test_m5_line() -> None:
    m5 = CadenceM5(k1_m_s=0.25, k2_m=0.2).estimate(step_duration_s=np.array([0.5, 0.625, 0.0, np.nan]))
    assert m5.step_length_m_[:2] == pytest.approx([0.7, 0.6])
    assert np.isnan(m5.step_length_m_[2:]).all()


def test_estimators_reject_bad_input() -> None:
    a = np.zeros(100)
    with pytest.raises(ValueError, match="leg_length_m"):
        PendulumM1().estimate(a, step_start=[0], step_end=[50], sampling_rate_hz=50.0, leg_length_m=-1.0)
    with pytest.raises(ValueError, match="outside"):
        PendulumDriftM2().estimate(a, step_start=[0], step_end=[500], sampling_rate_hz=50.0, leg_length_m=0.9)
    with pytest.raises(ValueError, match="end after"):
        PendulumM1().estimate(a, step_start=[10], step_end=[10], sampling_rate_hz=50.0, leg_length_m=0.9)


def test_anthropometry_rules_and_errors() -> None:
    leg, foot = anatomical_lengths(height_m=1.75)
    assert leg == pytest.approx(0.530 * 1.75) and foot == pytest.approx(0.73 * 0.152 * 1.75, abs=1e-3)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        anatomical_lengths()
    assert any("no height" in str(x.message) for x in w)
    with pytest.raises(HostError, match="metres"):
        anatomical_lengths(height_m=175.0)


def test_window_without_measured_samples_is_nan_and_others_stay_aligned() -> None:
    sampling_rate_hz, l, amp = 100.0, 0.9, 0.02
    t, a, ff = com_sinusoid(sampling_rate_hz, 0.5, 4, amp)
    valid = np.ones(t.size, bool)
    valid[ff[1] + 1:ff[2]] = False            # everything between two foot-flats lost
    start = np.array([ff[0], ff[1] + 5, ff[2], ff[3]])
    end = np.array([ff[1], ff[2] - 5, ff[3], ff[4]])
    m2 = PendulumDriftM2().estimate(a, step_start=start, step_end=end, sampling_rate_hz=sampling_rate_hz,
                                    leg_length_m=l, valid=valid)
    h = m2.vertical_excursion_m_
    assert np.isnan(h[1])
    assert np.allclose(h[[0, 2, 3]], 2 * amp, atol=1e-3)


@pytest.mark.parametrize("rule", ["single-support-speed", "end-speed"])
def test_m3_double_support_rules_on_an_exact_pendulum(rule) -> None:
    """The double support covered at the single support's mean speed (chord / T_ss) or at the pendulum's speed
    where single support ends (l omega cos theta0, the arc's tangent): geometry, not eq (1)."""
    sampling_rate_hz, l, theta0, t_ds, t_ss = 1000.0, 0.9, np.radians(17.0), 0.06, 0.42
    t, a, to, hs = two_phase_step(sampling_rate_hz, l, theta0, t_ds=t_ds, t_ss=t_ss)
    m3 = TwoPhasePendulumM3(double_support=rule).estimate(
        a, step_start=[0], step_end=[t.size - 1], step_toe_off=[to], step_heel_strike=[hs],
        sampling_rate_hz=sampling_rate_hz, leg_length_m=l, foot_length_m=0.19)
    chord, om = 2 * l * np.sin(theta0), 2 * theta0 / t_ss
    expected = chord * 2 * t_ds / t_ss if rule == "single-support-speed" else l * om * np.cos(theta0) * 2 * t_ds
    assert m3.double_support_length_m_[0] == pytest.approx(expected, rel=1e-2)
    # 1 % on S1: h1's quadrature (above), S1 ~ sqrt(h1)
    assert m3.pendulum_length_m_[0] == pytest.approx(chord, rel=1e-2)
    assert m3.step_length_m_[0] == pytest.approx(m3.pendulum_length_m_[0] + m3.double_support_length_m_[0])


def test_m3_rejects_an_unknown_double_support_rule() -> None:
    with pytest.raises(ValueError, match="double_support"):
        TwoPhasePendulumM3(double_support="toe")
