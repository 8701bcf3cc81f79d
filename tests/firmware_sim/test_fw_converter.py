"""The PIC16F877's converter as its data sheet describes it, each effect against an analytic truth: the
acquisition-time formula and its half-LSB settling criterion, the channel skew of sequential sampling on a known
sine, the settling error of a full-scale step, INL and DNL measured by the standard ramp-histogram test, offset
and gain error; and the default converter is today's, code for code."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitlog.firmware_sim.adc import (
    HOLD_CAPACITANCE_F,
    INTERCONNECT_RESISTANCE_OHM,
    SAMPLING_SWITCH_RESISTANCE_OHM,
    Adc,
    TransferCurve,
    pic_acquisition_time_s,
)
from gaitlog.firmware_sim.errors import DeviceError


def _ramp_histogram(curve: TransferCurve, per_code: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """The histogram test: a slow linear ramp over the whole span, codes counted. Returns the measured code
    widths (LSB) of codes 1 .. n-2 and the measured transitions (the ramp input where each code begins)."""
    n = curve.n_codes
    x = (np.arange(n * per_code) + 0.5) / per_code            # uniform over [0, n)
    codes = curve.quantise(x)
    counts = np.bincount(codes, minlength=n)
    widths = counts[1:-1] / per_code
    first = np.searchsorted(codes, np.arange(1, n), side="left")   # codes never decrease on a ramp
    return widths, x[np.minimum(first, x.size - 1)] - 0.5 / per_code


def test_default_converter_is_floor_and_clip_code_for_code() -> None:
    rng = np.random.default_rng(0)
    v = rng.uniform(-0.5, 5.5, (5000, 3))
    adc = Adc()
    expected = np.clip(np.floor((2.5 + 4.0 * (v - 2.5)) / (5.0 / 1024)), 0, 1023).astype(np.uint16)
    np.testing.assert_array_equal(adc.convert(v), expected)
    assert adc.ideal and adc.channel_delays_s(3).tolist() == [0.0, 0.0, 0.0] and adc.settling_fraction == 0.0
    # an ideal transfer curve, reached by the other path, is the same floor
    x = rng.uniform(-3, 1030, 5000)
    np.testing.assert_array_equal(TransferCurve(10).quantise(x),
                                  np.searchsorted(np.arange(1, 1024, dtype=float), x, side="right"))


def test_acquisition_time_is_the_datasheet_formula() -> None:
    """DS30292C's example: 19.72 us for 10 kOhm at 50 C; at the formula's T_ACQ (25 C: no T_COFF) the capacitor
    keeps exactly 1/2047 of a step: half a 10-bit LSB of a full-scale step, for any source impedance."""
    assert pic_acquisition_time_s(10e3) == pytest.approx(19.72e-6, abs=0.005e-6)
    assert pic_acquisition_time_s(32e3) == pytest.approx(39.85e-6, abs=0.01e-6)      # HARDWARE.md: ~39.9 us
    for r_ohm in (0.0, 2.5e3, 10e3, 32e3):
        adc = Adc(acquisition_time_s=pic_acquisition_time_s(r_ohm, temperature_c=25.0), source_impedance_ohm=r_ohm)
        assert adc.settling_fraction == pytest.approx(1 / 2047, rel=1e-9)
    # too short an acquisition for 32 kOhm: the data sheet's 19.72 us leaves exp(-17.72 us / (120 pF * 40 kOhm))
    adc = Adc(acquisition_time_s=19.72e-6, source_impedance_ohm=32e3)
    tau = HOLD_CAPACITANCE_F * (INTERCONNECT_RESISTANCE_OHM + SAMPLING_SWITCH_RESISTANCE_OHM + 32e3)
    assert adc.settling_fraction == pytest.approx(math.exp(-17.72e-6 / tau), rel=1e-9)
    assert 0.02 < adc.settling_fraction < 0.03


def test_settling_error_of_a_full_scale_step() -> None:
    """x at 0 V, y and z at full scale (VREF+): x's acquisition starts from z's voltage and keeps eps of the
    5 V step: 1024 / 2047 = 0.5 LSB at the data sheet's T_ACQ; y starts from x's held value."""
    r_ohm = 10e3
    adc = Adc(acquisition_time_s=pic_acquisition_time_s(r_ohm, temperature_c=25.0), source_impedance_ohm=r_ohm,
              gain=1.0)
    x = adc.input_lsb(np.array([[0.0, 5.0, 5.0]] * 4))
    eps = 1 / 2047
    assert x[0, 0] == pytest.approx(1024 * eps)
    assert x[0, 1] == pytest.approx(1024 - (1024 - 1024 * eps) * eps)
    assert x[0, 2] == pytest.approx(1024 - (1024 - x[0, 1]) * eps)
    # a long source impedance: x is pulled 2.5 % of the way to z, i.e. 26 codes of a full-scale step
    slow = Adc(acquisition_time_s=19.72e-6, source_impedance_ohm=32e3, gain=1.0)
    codes = slow.convert(np.array([[0.0, 5.0, 5.0]]))
    assert codes[0, 0] == math.floor(1024 * slow.settling_fraction) and codes[0, 0] > 20


def test_settling_through_an_unbuffered_adxl202_filter_capacitor() -> None:
    """32 kOhm with 0.25 uF at the pin: the charge is shared first (the hold capacitor keeps C_H / (C_H + C_S) of
    the step), then both recharge through R_S: eps = C_H / (C_H + C_S) exp(-t / (R_S (C_S + C_H))), 50x less
    than the one-pole model's; a vanishing C_S gives the one-pole model back."""
    t_s = 19.72e-6 - 2e-6
    adc = Adc(acquisition_time_s=19.72e-6, source_impedance_ohm=32e3, source_capacitance_f=0.25e-6)
    c_h, c_s = HOLD_CAPACITANCE_F, 0.25e-6
    expected = c_h / (c_h + c_s) * math.exp(-t_s / (32e3 * (c_s + c_h)))
    assert adc.settling_fraction == pytest.approx(expected, rel=1e-3)
    one_pole = Adc(acquisition_time_s=19.72e-6, source_impedance_ohm=32e3)
    assert one_pole.settling_fraction > 50 * adc.settling_fraction
    tiny = Adc(acquisition_time_s=19.72e-6, source_impedance_ohm=32e3, source_capacitance_f=1e-16)
    assert tiny.settling_fraction == pytest.approx(one_pole.settling_fraction, rel=1e-4)


def test_sequential_sampling_skews_the_channels_of_a_known_sine() -> None:
    """One 5 Hz sine on all three inputs: channel c is held T_ACQ + c (T_ACQ + 14 T_AD) after the tick, so its
    fitted phase leads channel 0's by 2 pi f c period (the skew, an analytic phase)."""
    f_hz, fine_hz, rate_hz = 5.0, 200_000.0, 50.0
    t = np.arange(int(2.0 * fine_hz)) / fine_hz
    v = np.repeat((2.5 + 0.2 * np.sin(2 * np.pi * f_hz * t))[:, None], 3, axis=1)
    adc = Adc(sampling_rate_hz=rate_hz, acquisition_time_s=pic_acquisition_time_s(32e3))
    period = adc.acquisition_time_s + 14 * 1.6e-6
    assert adc.channel_period_s == pytest.approx(period)
    ticks = adc.sample_times_s(0.0, 1.9)
    held = adc.hold(v, fine_hz, 0.0, ticks)
    design = np.column_stack([np.sin(2 * np.pi * f_hz * ticks), np.cos(2 * np.pi * f_hz * ticks)])
    phase = [np.arctan2(*np.linalg.lstsq(design, held[:, c] - 2.5, rcond=None)[0][::-1]) for c in range(3)]
    for c in range(3):
        expected = 2 * np.pi * f_hz * (adc.acquisition_time_s + c * period)
        assert phase[c] == pytest.approx(expected, abs=1e-6)
    # the default converter holds all three at the tick
    np.testing.assert_array_equal(Adc(sampling_rate_hz=rate_hz).hold(v, fine_hz, 0.0, ticks)[:, 0],
                                  Adc(sampling_rate_hz=rate_hz).hold(v, fine_hz, 0.0, ticks)[:, 2])


def test_inl_bow_measured_on_a_ramp() -> None:
    """INL of 1 LSB without DNL: the ramp histogram's cumulative width error (end-point fit) peaks at 1 LSB,
    and the curve's shape is the same device's at 8 and 10 bits."""
    curve = TransferCurve(10, inl_lsb=1.0, seed=4)
    widths, _ = _ramp_histogram(curve)
    inl = np.concatenate([[0.0], np.cumsum(widths - 1.0)])    # transition k - k, from the first
    inl -= np.linspace(0.0, inl[-1], inl.size)                  # end-point fit
    assert np.max(np.abs(inl)) == pytest.approx(1.0, abs=0.02)
    assert np.max(np.abs(widths - 1.0)) < 0.02                 # a smooth bow: no code-to-code error
    small = TransferCurve(8, inl_lsb=1.0, seed=4)
    k10 = curve.transitions_lsb - np.arange(1, 1024)
    k8 = small.transitions_lsb - np.arange(1, 256)
    np.testing.assert_allclose(k8, np.interp(np.linspace(0, 1, 255), np.linspace(0, 1, 1023), k10), atol=0.01)
    # another device has another bow
    assert not np.allclose(TransferCurve(10, inl_lsb=1.0, seed=5).transitions_lsb, curve.transitions_lsb)


def test_dnl_measured_on_a_ramp() -> None:
    """DNL of 1 LSB: each transition jitters uniformly by +-1/2, so a code width is 1 + (e_k+1 - e_k): within
    +-1 LSB (monotonic), standard deviation sqrt(2/12) = 0.408 LSB, mean 1."""
    widths, _ = _ramp_histogram(TransferCurve(10, dnl_lsb=1.0, seed=2))
    dnl = widths - 1.0
    assert np.all(dnl >= -1.0 - 1e-9) and np.all(dnl <= 1.0 + 1e-9)
    assert np.std(dnl) == pytest.approx(math.sqrt(2 / 12), rel=0.07)
    assert abs(np.mean(dnl)) < 0.01


def test_offset_and_gain_error_on_a_ramp() -> None:
    """Offset: the first transition at 1 + offset; gain: the last at 2^bits - 1 + offset + gain; the end-point
    line gives them back, and floor((x - a) / b) is then the converter."""
    curve = TransferCurve(10, offset_error_lsb=2.0, gain_error_lsb=-3.0)
    _, transitions = _ramp_histogram(curve, per_code=100)
    assert transitions[0] == pytest.approx(1.0 + 2.0, abs=0.011)
    assert transitions[-1] == pytest.approx(1023.0 + 2.0 - 3.0, abs=0.011)
    a, b = curve.linear()
    assert a == pytest.approx(2.0 + 3.0 / 1022) and b == pytest.approx(1.0 - 3.0 / 1022)
    x = np.random.default_rng(1).uniform(0.0, 1020.0, 20000)
    np.testing.assert_array_equal(curve.quantise(x), np.clip(np.floor((x - a) / b), 0, 1023))


def test_datasheet_converter_and_its_limits() -> None:
    a = Adc.datasheet(seed=3)
    assert a.acquisition_time_s == pytest.approx(pic_acquisition_time_s(10e3)) and a.sequential
    assert (a.inl_lsb, a.dnl_lsb, abs(a.offset_error_lsb), abs(a.gain_error_lsb)) == (1.0, 1.0, 2.0, 1.0)
    assert set(a.effects()) == {"acquisition_time_s", "source_impedance_ohm", "source_capacitance_f", "inl_lsb",
                                "dnl_lsb", "offset_error_lsb", "gain_error_lsb", "linearity_seed"}
    with pytest.raises(DeviceError, match="DNL"):
        Adc(dnl_lsb=1.5)
    with pytest.raises(DeviceError, match="do not fit"):
        Adc(sampling_rate_hz=1000.0, acquisition_time_s=900e-6)
    with pytest.raises(DeviceError, match="12 channels"):                  # an instrument's many channels
        Adc(sampling_rate_hz=2000.0, acquisition_time_s=19.72e-6).channel_delays_s(12)
