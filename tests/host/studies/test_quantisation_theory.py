"""The quantisation theory's closed forms against independent truth: a pure sine through an ideal converter,
white noise through the Gaussian low-pass and the double integral."""

from __future__ import annotations

import math

import numpy as np

from gaitlog.host.studies.quantisation_theory import (
    FF_CUTOFF_HZ,
    fir_noise_gain,
    median_abs_of_mixture,
    position_error_variance,
    uniform_variance,
)
from gaitlog.host.gait.masked_filter import masked_gaussian_lowpass


def test_a_sine_through_the_converter_has_q_squared_over_12() -> None:
    """A 1.3 Hz sine of 300 LSB sampled at 50 Hz (incommensurate: the error visits every phase of the step),
    floored and re-centred: the error's variance is 1/12 LSB^2 within 2 %, its mean 0 within 0.01 LSB."""
    t = np.arange(200_000) / 50.0
    x = 512.0 + 300.0 * np.sin(2 * np.pi * 1.3 * t + 0.1)
    err = (np.floor(x) + 0.5) - x
    assert abs(np.mean(err)) < 0.01
    assert abs(np.var(err) / uniform_variance(1.0) - 1.0) < 0.02


def test_the_lowpass_passes_sum_w_squared_of_the_sines_quantisation_error() -> None:
    """The same sine with the sensor's noise (0.3 LSB rms: the error white) through the chains' 3 Hz Gaussian (the
    filter M4's range is taken on): its variance is ``sum w^2 / 12`` within 5 %. (Without noise the error of the
    sine alone is correlated near its peaks, where it crosses few codes per sample: 7 % less.)"""
    rate = 50.0
    t = np.arange(100_000) / rate
    x = 512.0 + 300.0 * np.sin(2 * np.pi * 1.3 * t + 0.1) + 0.3 * np.random.default_rng(0).standard_normal(t.size)
    err = (np.floor(x) + 0.5) - x
    y = masked_gaussian_lowpass(err, None, cutoff_hz=FF_CUTOFF_HZ, sampling_rate_hz=rate)
    measured = np.var(y[100:-100])
    assert abs(measured / (fir_noise_gain(FF_CUTOFF_HZ, rate) / 12.0) - 1.0) < 0.05


def test_double_integral_variance_is_the_random_walks() -> None:
    """Without drift correction, the end of the double integral of white noise has variance ``n^3 / 3`` sample
    periods^4 (continuous limit); Monte Carlo of the trapezoids at the n/4, 3n/4 pair agrees within 5 %."""
    n = 60
    rng = np.random.default_rng(1)
    a = rng.standard_normal((20_000, n + 1))
    v = np.concatenate([np.zeros((a.shape[0], 1)), np.cumsum(0.5 * (a[:, 1:] + a[:, :-1]), axis=1)], axis=1)
    p = np.concatenate([np.zeros((a.shape[0], 1)), np.cumsum(0.5 * (v[:, 1:] + v[:, :-1]), axis=1)], axis=1)
    mc = np.var(p[:, n // 4] - p[:, 3 * n // 4])
    assert abs(mc / position_error_variance(n, 1.0, corrected=False) - 1.0) < 0.05
    big = 2000
    assert abs(position_error_variance(big, 1.0, corrected=False, ends=True) / (big ** 3 / 3) - 1.0) < 0.01
    # drift corrected: c1 and c2 pin the error at both ends, far less than the uncorrected
    assert position_error_variance(n, 1.0, corrected=True) < 0.2 * position_error_variance(n, 1.0, corrected=False)


def test_median_of_a_mixture() -> None:
    rng = np.random.default_rng(2)
    s = np.array([0.5, 1.0, 2.0, 4.0])
    draws = np.abs(rng.standard_normal((200_000, 4)) * s).ravel()
    assert abs(median_abs_of_mixture(s) / np.median(draws) - 1.0) < 0.01
    biased = np.abs(rng.standard_normal(200_000) + 1.5)
    assert abs(median_abs_of_mixture(np.array([1.0]), 1.5) / np.median(biased) - 1.0) < 0.01
    assert math.isnan(median_abs_of_mixture(np.array([np.nan])))
