"""The ADXL202's noise beyond white and its temperature drift, against analytic truth: the 1/f part's spectral
slope and level (density d^2 f_c / f), the white part left as it was, the drift of offset and sensitivity over
a temperature ramp as the data sheet's coefficients say; the logger records them in its truth; off by default."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.channel_sensors import ChannelSensors
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.sensor import (
    ADXL202_OFFSET_TEMPCO_G_PER_C,
    ADXL202_SENSITIVITY_TEMPCO_PER_C,
    SensorModel,
    TemperatureProfile,
    datasheet_tempcos,
    flicker_noise,
)
from gaitlog.firmware_sim.world.base import Motion

DENSITY_G_RTHZ = 200e-6


def _psd(x: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    return signal.welch(x, fs=rate_hz, nperseg=1 << 13, axis=0)


def test_flicker_noise_has_a_one_over_f_spectrum() -> None:
    """Density d^2 f_c / f between the synthesis' corners: log-log slope -1 (within 0.1) over two decades, and
    the level within 20 % at every band of a third of a decade."""
    rate_hz, corner_hz = 50.0, 2.0
    t = np.arange(1 << 18) / rate_hz                                          # 87 minutes
    x = flicker_noise(t, np.full(3, DENSITY_G_RTHZ), corner_hz, 1e-3, np.full(3, 20.0), np.random.default_rng(1))
    f, p = _psd(x, rate_hz)
    band = (f >= 0.02) & (f <= 2.0)
    slope = np.polyfit(np.log(f[band]), np.log(p[band].mean(axis=1)), 1)[0]
    assert slope == pytest.approx(-1.0, abs=0.1)
    edges = np.logspace(np.log10(0.02), np.log10(2.0), 7)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (f >= lo) & (f < hi)
        measured = p[sel].mean() / np.mean(DENSITY_G_RTHZ ** 2 * corner_hz / f[sel])
        assert measured == pytest.approx(1.0, rel=0.2), (lo, hi)


def test_sensor_noise_is_white_above_the_corner_and_one_over_f_below() -> None:
    """The sensor's noise at 50 Hz: the white part through the 20 Hz RC, sampled (an AR(1) process, a =
    exp(-2 pi f_-3dB / fs): density (2 / fs) sigma^2 (1 - a^2) / (1 - 2 a cos(2 pi f / fs) + a^2), its aliases
    included), plus d^2 f_c / f; within 20 % from a decade below the corner to a decade above."""
    s = SensorModel.ideal(flicker_corner_hz=1.0, seed=3)
    rate_hz = 50.0
    t = np.arange(1 << 18) / rate_hz
    n = s.noise_g(t) + s.flicker_g(t)
    f, p = _psd(n, rate_hz)
    a = np.exp(-2 * np.pi * s.cutoff_hz[0] / rate_hz)
    sigma2 = s.noise_rms_g[0] ** 2
    for f0 in (0.1, 1.0, 10.0):
        sel = (f > f0 / 1.3) & (f < f0 * 1.3)
        white = 2 / rate_hz * sigma2 * (1 - a * a) / (1 - 2 * a * np.cos(2 * np.pi * f[sel] / rate_hz) + a * a)
        expected = np.mean(white + DENSITY_G_RTHZ ** 2 * 1.0 / f[sel])
        assert p[sel].mean() / expected == pytest.approx(1.0, rel=0.2), f0
    # white noise alone is the stream it always was; without a corner there is no 1/f part
    np.testing.assert_array_equal(SensorModel.ideal(flicker_corner_hz=1.0, seed=3).noise_g(t[:100]),
                                  SensorModel.ideal(seed=3).noise_g(t[:100]))
    assert not np.any(SensorModel.ideal(seed=3).flicker_g(t[:100]))


def test_temperature_drift_of_offset_and_sensitivity() -> None:
    """At 1 g on z and 0 g on x, over a ramp 25 -> 50 C: x moves by S (1 + a_s dT) a_b dT, z by
    S ((1 + a_s dT)(1 + b + a_b dT) - (1 + b)); both vanish at 25 C."""
    tc = datasheet_tempcos(5)
    assert np.all(np.abs(tc["offset_tempco_g_per_c"]) == ADXL202_OFFSET_TEMPCO_G_PER_C)
    assert np.all(np.abs(tc["sensitivity_tempco_per_c"]) == ADXL202_SENSITIVITY_TEMPCO_PER_C)
    s = SensorModel.ideal(noise_density_g_rthz=0.0, temperature=TemperatureProfile.ramp(25.0, 50.0, 100.0), **tc)
    v0 = s.static_v(np.tile([0.0, 0.0, 1.0], (3, 1)))
    elapsed = np.array([0.0, 50.0, 100.0])
    v = s.drifted_v(v0, elapsed)
    dt = np.array([0.0, 12.5, 25.0])
    a_b, a_s = tc["offset_tempco_g_per_c"], tc["sensitivity_tempco_per_c"]
    sens = s.sensitivity_v_per_g
    np.testing.assert_allclose(v[:, 0] - 2.5, sens * (1 + a_s[0] * dt) * a_b[0] * dt, atol=1e-12)
    np.testing.assert_allclose(v[:, 2] - v0[:, 2], sens * ((1 + a_s[2] * dt) * (1 + a_b[2] * dt) - 1), atol=1e-12)
    assert abs(v[-1, 0] - 2.5) == pytest.approx(0.312 * 0.05 * (1 + a_s[0] * 25), rel=1e-9)   # 50 mg: 15.6 mV


def test_logger_records_the_drift_and_its_parameters() -> None:
    """A still device (1 g on z) over a 25 -> 50 C ramp: the x codes at the end sit 50 mg x 255.6 codes/g = 12.8
    codes from the start, in the tempco's direction; the truth records every new parameter."""
    tc = datasheet_tempcos(2)
    sensor = SensorModel.ideal(noise_density_g_rthz=0.0, temperature=TemperatureProfile.ramp(25.0, 50.0, 20.0), **tc)
    n = 500 * 20 + 1
    motion = Motion(acc_g=np.tile([0.0, 0.0, 1.0], (n, 1)), sampling_rate_hz=500.0)
    res = Logger(sensor=sensor, adc=Adc()).record(motion)
    codes = np.asarray(res.codes, float)
    drift = codes[-5:, 0].mean() - codes[:5, 0].mean()
    assert drift == pytest.approx(np.sign(tc["offset_tempco_g_per_c"][0]) * 0.05 * 255.6, abs=1.0)
    truth = res.truth["sensor"]
    assert truth["temperature_profile"] == {"times_s": [0.0, 20.0], "temperatures_c": [25.0, 50.0]}
    np.testing.assert_array_equal(truth["offset_tempco_g_per_c"], tc["offset_tempco_g_per_c"])
    assert truth["flicker_corner_hz"] == 0.0
    assert res.truth["adc"]["inl_lsb"] == 0.0 and res.truth["adc"]["channel_delays_s"] == [0.0, 0.0, 0.0]


def test_drift_and_flicker_are_off_by_default_and_draws_unchanged() -> None:
    a, b = SensorModel.draw(seed=4), SensorModel.draw(seed=4, temperature_drift=True)
    np.testing.assert_array_equal(a.offset_g, b.offset_g)
    np.testing.assert_array_equal(a.axes, b.axes)
    assert not a.drifts and not np.any(a.offset_tempco_g_per_c) and np.any(b.offset_tempco_g_per_c)
    v = np.full((4, 3), 2.6)
    assert a.drifted_v(v, np.arange(4.0)) is v


def test_instrument_channels_get_flicker_and_the_converter_effects() -> None:
    """ChannelSensors: a 1/f corner adds low-frequency noise to the channels that have one; an INL of 1 LSB
    moves codes by at most ~1 code."""
    s = ChannelSensors(np.array([4.0, 4.0]), np.full(2, 200e-6), np.full(2, 50.0), np.zeros(2), np.zeros(2),
                       seed=1, flicker_corner_hz=np.array([0.0, 5.0]))
    t = np.arange(20000) / 100.0
    n = s.noise(t)
    white = ChannelSensors(s.range, s.noise_density, s.bandwidth_hz, s.offset, s.drift_per_s, seed=1).noise(t)
    np.testing.assert_array_equal(n[:, 0], white[:, 0])
    f, p_flicker = signal.welch(n[:, 1] - white[:, 1], fs=100.0, nperseg=1 << 12)
    _, p_white = signal.welch(white[:, 1], fs=100.0, nperseg=1 << 12)
    low = (f > 0.05) & (f < 0.2)                                 # f_c / f = 25 .. 100 there
    assert p_flicker[low].mean() > 10 * p_white[low].mean()
    quiet = s.without_errors()
    values = np.column_stack([np.linspace(-3, 3, 4000)] * 2)
    _, ideal = quiet.sample(values, 1000.0, 0.0, quiet.adc(100.0))
    _, real = quiet.sample(values, 1000.0, 0.0, quiet.adc(100.0, inl_lsb=1.0, linearity_seed=3))
    assert 0 < np.abs(real.astype(int) - ideal.astype(int)).max() <= 2
