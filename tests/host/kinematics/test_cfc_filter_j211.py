"""SAE J211 CFC filter: coefficients vs scipy.signal.butter, response at the notes' frequencies, zero lag."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, freqz

from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.cfc_filter import cfc_coefficients, cfc_filter, cfc_min_rate_hz


@pytest.mark.parametrize(("cfc", "sampling_rate_hz"), [(180, 10_000), (60, 1_000), (600, 20_000), (1000, 50_000), (180, 750)])
def test_coefficients_equal_scipy_butter(cfc: float, sampling_rate_hz: float) -> None:
    b, a = cfc_coefficients(cfc, sampling_rate_hz)
    b_ref, a_ref = butter(2, 2.0775 * cfc, fs=sampling_rate_hz)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-15)


def _amplitude_db(f_hz: float, sampling_rate_hz: float = 10_000, cfc: float = 180) -> tuple[float, float]:
    """Amplitude (dB) and lag (samples) of a filtered sinusoid, measured in the middle of the record."""
    t = np.arange(20_000) / sampling_rate_hz
    x = np.sin(2 * np.pi * f_hz * t)
    y = cfc_filter(x, cfc, sampling_rate_hz)
    mid = slice(5_000, 15_000)
    # least-squares fit of a sin + b cos: amplitude and phase
    basis = np.stack([np.sin(2 * np.pi * f_hz * t[mid]), np.cos(2 * np.pi * f_hz * t[mid])], axis=1)
    coef, *_ = np.linalg.lstsq(basis, y[mid], rcond=None)
    return 20 * np.log10(np.hypot(*coef)), np.arctan2(coef[1], coef[0])


@pytest.mark.parametrize(("f_hz", "db"), [(180, -0.448), (300, -2.994), (600, -17.87)])
def test_cfc180_response_at_10khz(f_hz: float, db: float) -> None:
    got, phase = _amplitude_db(f_hz)
    assert got == pytest.approx(db, abs=0.005)
    assert abs(phase) < 1e-9  # zero lag
    # and the same from the coefficients: |H|² of one pass
    b, a = cfc_coefficients(180, 10_000)
    _, h = freqz(b, a, worN=[f_hz], fs=10_000)
    assert 20 * np.log10(np.abs(h[0]) ** 2) == pytest.approx(db, abs=0.005)


def test_minus_3db_near_five_thirds_cfc() -> None:
    b, a = cfc_coefficients(180, 10_000)
    f = np.linspace(200, 400, 20_001)
    _, h = freqz(b, a, worN=f, fs=10_000)
    f3 = f[np.argmin(np.abs(20 * np.log10(np.abs(h) ** 2) + 3.0103))]
    assert f3 == pytest.approx(5 / 3 * 180, rel=0.02)


def test_zero_lag_on_a_pulse_and_multichannel() -> None:
    sampling_rate_hz = 10_000
    t = np.arange(4_000) / sampling_rate_hz
    pulse = np.exp(-(((t - 0.2) / 0.004) ** 2))
    data = np.stack([pulse, 2 * pulse, -pulse], axis=1)
    out = cfc_filter(data, 180, sampling_rate_hz)
    assert out.shape == data.shape
    assert np.argmax(out[:, 0]) == np.argmax(pulse)
    np.testing.assert_allclose(out[:, 1], 2 * out[:, 0], atol=1e-12)
    np.testing.assert_allclose(cfc_filter(data.T, 180, sampling_rate_hz, axis=1), out.T, atol=1e-12)
    np.testing.assert_allclose(cfc_filter(np.full(100, 3.0), 180, sampling_rate_hz), 3.0, atol=1e-12)  # DC passes


@pytest.mark.parametrize("sampling_rate_hz", [747.9, 500, 50])
def test_rejects_invalid_rates(sampling_rate_hz: float) -> None:
    assert cfc_min_rate_hz(180) == pytest.approx(747.9)
    with pytest.raises(HostError, match=r"CFC 180 filter is invalid at .* must exceed 747.9 Hz"):
        cfc_filter(np.zeros(100), 180, sampling_rate_hz)


def test_rejects_bad_arguments() -> None:
    with pytest.raises(HostError, match="channel class"):
        cfc_coefficients(0, 10_000)
    with pytest.raises(HostError, match="sampling rate"):
        cfc_coefficients(180, float("nan"))
    with pytest.raises(HostError, match="NaN"):
        cfc_filter(np.array([0.0, np.nan] * 10), 180, 10_000)
    with pytest.raises(HostError, match="more than 9 samples"):
        cfc_filter(np.zeros(5), 180, 10_000)
