"""ADXL202E assembly: noise density (Welch), -3 dB bandwidth = 5 uF / C, clipping, static errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import SensorModel


def _g(sensor: SensorModel, volts: np.ndarray) -> np.ndarray:
    """Volts back to g for an ideal assembly (0 g at Vs/2, nominal sensitivity)."""
    return (volts - sensor.supply_v / 2) / sensor.sensitivity_v_per_g


def test_noise_density_matches_200_ug_per_root_hz() -> None:
    rate = 500.0
    sensor = SensorModel.ideal(seed=11)
    n = int(400 * rate)
    v = sensor.respond(np.zeros((n, 3)), rate)
    f, pxx = signal.welch(_g(sensor, v), fs=rate, nperseg=4096, axis=0)
    band = (f >= 0.5) & (f <= 8.0)
    fc = 5e-6 / 0.25e-6  # 20 Hz for the default 0.25 uF
    expected = (200e-6) ** 2 / (1.0 + (f[band] / fc) ** 2)  # one-sided PSD through the one-pole filter
    ratio = np.sqrt(pxx[band].mean(axis=0) / expected.mean())
    np.testing.assert_allclose(ratio, 1.0, atol=0.05)


@pytest.mark.parametrize("cap_f, sampling_rate_hz", [(0.25e-6, 500.0), (0.1e-6, 1000.0), (0.47e-6, 500.0)])
def test_minus_3_db_point_is_5uF_over_C(cap_f: float, sampling_rate_hz: float) -> None:
    fc = 5e-6 / cap_f
    sensor = SensorModel.ideal(noise_density_g_rthz=0.0, filter_capacitance_f=cap_f, internal_rate_hz=sampling_rate_hz)
    t = np.arange(int(20 * sampling_rate_hz)) / sampling_rate_hz
    # exact at the cut-off (pre-warped bilinear filter); within 3 % of the analog RC up to 2 fc
    # (bilinear frequency warping; fc is at most a tenth of the internal rate here)
    for f, gain, tol in ((fc, 1 / np.sqrt(2), 0.005), (2 * fc, 1 / np.sqrt(5), 0.03), (fc / 10, 1 / np.sqrt(1.01), 0.005)):
        x = 0.5 * np.sin(2 * np.pi * f * t)
        out = _g(sensor, sensor.respond(np.c_[x, x, x], sampling_rate_hz))
        tail = slice(len(t) // 2, None)  # steady state
        amp = np.sqrt(2) * out[tail].std(axis=0)
        np.testing.assert_allclose(amp / 0.5, gain, rtol=tol)


def test_clipping_at_plus_minus_2_g() -> None:
    sensor = SensorModel.ideal(noise_density_g_rthz=0.0)
    acc = np.tile([3.0, -5.0, 1.5], (2000, 1))
    out = _g(sensor, sensor.respond(acc, 500.0))
    np.testing.assert_allclose(out[-1], [2.0, -2.0, 1.5], atol=1e-9)


def test_static_errors_follow_the_model() -> None:
    sensor = SensorModel.draw(seed=7, noise_density_g_rthz=0.0)
    acc = np.array([0.3, -0.6, 0.75])
    v = sensor.respond(np.tile(acc, (3000, 1)), 500.0)[-1]
    # independent evaluation of v = Vs/2 + S (1 + e) (b + u . a) for each axis
    for j in range(3):
        expected = 2.5 + 0.312 * (1 + sensor.sensitivity_error[j]) * (sensor.offset_g[j] + sensor.axes[j] @ acc)
        assert v[j] == pytest.approx(expected, abs=1e-9)


def test_drawn_parameters_are_seeded_and_within_tolerance() -> None:
    a, b, c = SensorModel.draw(seed=1), SensorModel.draw(seed=1), SensorModel.draw(seed=2)
    np.testing.assert_array_equal(a.axes, b.axes)
    assert not np.allclose(a.offset_g, c.offset_g)
    for s in (SensorModel.draw(seed=k) for k in range(50)):
        assert np.all(np.abs(s.offset_g) <= 0.10)
        assert np.all(np.abs(s.sensitivity_error) <= 0.05)
        assert np.all(np.abs(s.cutoff_hz / 20.0 - 1) <= 0.15 + 1e-12)
        ang = np.degrees(np.arccos(np.abs(np.diag(s.axes))))
        assert np.all(ang[:2] <= np.sqrt(3) * 1.0 + 0.02) and ang[2] <= np.sqrt(3) * 3.0 + 1e-9
        # part A's two axes share a die: their non-orthogonality is tiny
        assert abs(90.0 - np.degrees(np.arccos(s.axes[0] @ s.axes[1]))) <= 0.0101


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(DeviceError, match="axes"):
        SensorModel(axes=np.eye(3) * 2)
    with pytest.raises(DeviceError, match="Nyquist"):
        SensorModel(filter_capacitance_f=0.01e-6)  # 500 Hz filter on a 500 Hz grid
    with pytest.raises(DeviceError, match="shape"):
        SensorModel().respond(np.zeros((10, 2)), 500.0)


def test_noise_at_the_sample_instants_is_the_rc_filtered_process() -> None:
    """White noise of density d through a one-pole RC: rms d sqrt(pi fc / 2), correlation exp(-dt / tau)."""
    sensor = SensorModel.ideal(seed=4)
    fc = 20.0
    sigma = 200e-6 * np.sqrt(np.pi / 2 * fc)
    t = np.arange(200_000) / 50.0
    x = sensor.noise_g(t)
    np.testing.assert_allclose(x.std(axis=0), sigma, rtol=0.02)
    lag1 = [np.corrcoef(x[:-1, j], x[1:, j])[0, 1] for j in range(3)]
    np.testing.assert_allclose(lag1, np.exp(-2 * np.pi * fc / 50.0), atol=0.01)
    # irregular instants (per-sample recursion): same law; very close instants are strongly correlated
    ti = np.sort(np.random.default_rng(1).uniform(0.0, 2000.0, 40_000))
    xi = sensor.noise_g(ti)
    np.testing.assert_allclose(xi.std(axis=0), sigma, rtol=0.03)
    close = np.flatnonzero(np.diff(ti) < 0.1 / (2 * np.pi * fc))
    assert np.corrcoef(xi[close, 0], xi[close + 1, 0])[0, 1] > 0.8
