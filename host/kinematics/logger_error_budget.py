"""What the logger's sensors cost Morris' and Hall's kinematics: error figures from the sensor model.

An instrument recorded by the emulated logger (:mod:`gaitlog.host.kinematics.logger_instruments`) reaches the
kinematics with three sensor errors besides the method's own (Morris' ω3 = 0, the filters' lag) and the
ADC's quantisation, which a recording without sensor errors keeps (``noise_free_deg`` below, measured):

noise
    White per channel, ``σ² = noise_rms² + q²/12`` (``noise_rms`` of
    :attr:`gaitlog.firmware_sim.channel_sensors.ChannelSensors.noise_rms`; ``q = full scale / 2^(b−1)`` the ADC step,
    counted again because the noise dithers it). Morris: the angular acceleration comes from the pseudo-inverse
    of the platform's design matrix ``H⁺`` (:class:`gaitlog.host.kinematics.accelerometer_pairs.AngularVelocityFromAccelerometers`),
    so ``σα = g0·sqrt(Σ_j H⁺_kj² σ_j²)`` rad/s², white at ``dt``; integrated twice over a cycle ``T`` it leaves an
    orientation error of scale ``σα·√dt·T^1.5/√3`` (the end-point standard deviation of an integrated random
    walk). Hall: each link's rate noise integrates once, ``σ·√(dt·T)``, for the two links ``√2`` times that.
offset
    What the static calibration (Morris) or the pre-test window (Hall) leaves. Morris: ``b`` through ``H⁺``
    is a constant angular acceleration, ``½·g0·|H⁺|·|b|·T²``. Hall: the pre-test mean removes the offset up to
    the noise over its ``n`` samples, ``σ/√n`` per link, integrated over ``T``.
drift
    A ramp ``d·t``: Morris ``g0·|H⁺|·|d|·T³/6``; Hall, from the middle of the pre-test window,
    ``½·|d|·(T − t_pre/2)²`` per link.

The stated bound of a recording's worst orientation (Morris) or joint-angle (Hall) error is
``noise_free_deg + K_SIGMA · noise + offset + drift`` with the offsets and drifts at their tolerances
(:class:`gaitlog.firmware_sim.channel_sensors.SensorSpec`) and :data:`K_SIGMA` = 3 (the noise's contribution is a
maximum over a cycle, not an end point: 3 scales hold it in every run measured, README).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gaitlog.firmware_sim.channel_sensors import ChannelSensors
from gaitlog.host.kinematics.accelerometer_pairs import AngularVelocityFromAccelerometers
from gaitlog.host.kinematics.platform_description import HallPlatform, MorrisPlatform
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["K_SIGMA", "ErrorBudget", "channel_noise_sd", "hall_error_budget", "morris_error_budget"]

#: Noise scales allowed in the bound (module notes).
K_SIGMA = 3.0


@dataclass(frozen=True)
class ErrorBudget:
    """The sensor errors' parts of an angle error, degrees: the noise's scale (one standard deviation), the
    offsets' and the drifts' worst cases."""

    noise_deg: float
    offset_deg: float
    drift_deg: float

    def bound_deg(self, noise_free_deg: float) -> float:
        """``noise_free_deg + K_SIGMA · noise + offset + drift``."""
        return float(noise_free_deg + K_SIGMA * self.noise_deg + self.offset_deg + self.drift_deg)


def channel_noise_sd(sensors: ChannelSensors, adc_bits: int) -> np.ndarray:
    """``(N,)`` white noise per channel in its unit: the sensor's and the ADC step's ``q/√12``."""
    q = sensors.range / float(1 << (int(adc_bits) - 1))
    return np.sqrt(sensors.noise_rms**2 + q**2 / 12.0)


def morris_error_budget(platform: MorrisPlatform, sensors: ChannelSensors, *, adc_bits: int, sampling_rate_hz: float,
                        cycle_s: float, offset_g: np.ndarray, drift_g_per_s: np.ndarray) -> ErrorBudget:
    """Morris' orientation error parts over a cycle of ``cycle_s`` (module notes); ``offset_g`` and
    ``drift_g_per_s`` ``(N,)``: the tolerances (worst case)."""
    _, pinv, _, _ = AngularVelocityFromAccelerometers(positions_m=platform.positions_m, axes=platform.axes,
                                                      fixed_zero_axes=platform.assume_zero_rate_axes)._design()
    p = pinv[3:]
    g0 = STANDARD_GRAVITY_M_S2
    sd = channel_noise_sd(sensors, adc_bits)
    sigma_alpha = g0 * np.sqrt((p**2 * sd**2).sum(axis=1)).max()
    t = float(cycle_s)
    noise = sigma_alpha * math.sqrt(1.0 / sampling_rate_hz) * t**1.5 / math.sqrt(3.0)
    offset = 0.5 * g0 * (np.abs(p) @ np.abs(offset_g)).max() * t**2
    drift = g0 * (np.abs(p) @ np.abs(drift_g_per_s)).max() * t**3 / 6.0
    return ErrorBudget(*np.degrees([noise, offset, drift]).tolist())


def hall_error_budget(platform: HallPlatform, sensors: ChannelSensors, *, adc_bits: int, sampling_rate_hz: float,
                      duration_s: float, drift_rad_s2: np.ndarray) -> ErrorBudget:
    """Hall's joint-angle error parts over a test of ``duration_s`` (module notes); ``drift_rad_s2`` ``(6,)``:
    the tolerances."""
    sd = float(channel_noise_sd(sensors, adc_bits).max())
    dt, t = 1.0 / sampling_rate_hz, float(duration_s)
    n_pre = max(1, math.floor(platform.pretest_s * sampling_rate_hz) + 1)
    noise = math.sqrt(2.0) * sd * math.sqrt(dt * t)
    offset = 2.0 * sd / math.sqrt(n_pre) * t
    drift = 2.0 * 0.5 * float(np.abs(drift_rad_s2).max()) * (t - platform.pretest_s / 2.0) ** 2
    return ErrorBudget(*np.degrees([noise, offset, drift]).tolist())
