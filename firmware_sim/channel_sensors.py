"""Single-axis analog sensors on the logger's analog inputs: an instrument's accelerometers and rate sensors.

Each channel ``j`` reads ``x_j = LPF_j(clip(u_j, ±range_j)) + LPF_j(n_j) + b_j + d_j · t`` in its unit (g or
rad/s), where ``u_j`` is the true value along its sensing axis, ``range_j`` the sensing element's full scale,
``LPF_j`` a single-pole low-pass at ``bandwidth_hz`` (the part's output filter: 5 µF / C on an ADXL202, the
demodulator filter on a rate sensor), ``n_j`` white noise of density ``noise_density`` (unit/√Hz, drawn
exactly at the sample instants: :meth:`SensorModel.noise_g <gaitlog.firmware_sim.sensor.SensorModel.noise_g>`'s
Ornstein-Uhlenbeck law), ``b_j`` the offset and ``d_j`` its drift (a temperature ramp) from the start of the
recording. The conditioning amplifier maps ``±range_j`` onto the converter's span (``v = ref + span/2 ·
x / range``, zero at mid-scale), so the channel map's full scale (``gaitlog.protocol.channel_map``) is the range, and
:class:`gaitlog.firmware_sim.adc.Adc` (gain 1) quantises. The accelerometers and the rate sensors are the same model
with different parameters, as their datasheets describe them by the same four figures.

Beyond them (off by default): 1/f noise below a corner ``flicker_corner`` per channel (density ``d² (1 +
f_c / f)``: :func:`gaitlog.firmware_sim.sensor.flicker_noise`, its own seeded stream), and the converter's
effects (sequential sampling of the channels, settling, INL/DNL, offset and gain error: :meth:`ChannelSensors.adc`
passes them to :class:`gaitlog.firmware_sim.adc.Adc`).

Examples
--------
>>> s = ChannelSensors.ideal([4.0, 30.0], noise=False)
>>> adc = s.adc(100.0)
>>> t, codes = s.sample(np.array([[0.0, 15.0]] * 200), 1000.0, 0.0, adc)
>>> codes[-1].tolist()
[512, 768]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import FLICKER_LOW_HZ, flicker_noise, flicker_rng, ou_noise

__all__ = ["ACCELEROMETER", "RATE_SENSOR", "ChannelSensors", "SensorSpec"]


@dataclass(frozen=True)
class SensorSpec:
    """A sensor type's figures and the tolerances its parts are drawn within (uniform).

    ``range`` full scale (unit), ``noise_density`` unit/√Hz, ``bandwidth_hz`` −3 dB, ``offset_tol`` ±unit,
    ``drift_tol`` ±unit/s, ``source`` where the figures come from.
    """

    range: float
    noise_density: float
    bandwidth_hz: float
    offset_tol: float
    drift_tol: float
    source: str


#: Morris' accelerometers as an ADXL202E-class part (the logger's own sensor, HARDWARE.md): 200 µg/√Hz, a
#: ±4 g conditioned range (his shank peaks near 3 g), 50 Hz bandwidth (C = 0.1 µF) for 100 Hz sampling; the
#: offset left after a static calibration ±0.5 mg and a drift of ±0.2 mg/s (*assumptions*). Morris' method
#: needs that calibration: a pair difference over his 5 cm baseline turns an offset ``b`` into an angular
#: acceleration ``√2·b·g / 0.05 m`` that integrates twice, so ±1 mg costs up to ~18° of orientation over a
#: cycle and an uncalibrated ±10 mg ~120° (README, "Morris and Hall on the logger").
ACCELEROMETER = SensorSpec(4.0, 200e-6, 50.0, 0.5e-3, 0.2e-3,
                           "ADXL202E-class: 200 ug/rtHz (datasheet), +-4 g conditioned, 50 Hz (C = 0.1 uF); "
                           "residual offset +-0.5 mg and drift +-0.2 mg/s after calibration (assumed)")
#: Hall's angular-rate sensors: ±30 rad/s (his neck test peaks near 24 rad/s), 1.5e-4 rad/s/√Hz (his 0.01 rad/s
#: rms over a 5 kHz band), 400 Hz bandwidth for ~2 kHz sampling, offset ±0.05 rad/s (removed by the pre-test
#: window) and drift ±0.02 rad/s per s (*assumptions* of a rate gyro of the period).
RATE_SENSOR = SensorSpec(30.0, 1.5e-4, 400.0, 0.05, 0.02,
                         "rate gyro: +-30 rad/s, 1.5e-4 rad/s/rtHz (Hall's 0.01 rad/s over 5 kHz), 400 Hz; offset "
                         "+-0.05 rad/s, drift +-0.02 rad/s/s (assumed)")


@dataclass(frozen=True, eq=False)
class ChannelSensors:
    """``N`` single-axis sensors (module notes); every parameter an ``(N,)`` array in the channel's unit
    (``flicker_corner_hz``: the 1/f corners, Hz, default none)."""

    range: np.ndarray
    noise_density: np.ndarray
    bandwidth_hz: np.ndarray
    offset: np.ndarray
    drift_per_s: np.ndarray
    seed: int = 0
    flicker_corner_hz: np.ndarray | None = None
    _rng: np.random.Generator = field(init=False, repr=False)
    _flicker_rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = np.asarray(self.range).size
        if self.flicker_corner_hz is None:
            object.__setattr__(self, "flicker_corner_hz", np.zeros(n))
        for name in ("range", "noise_density", "bandwidth_hz", "offset", "drift_per_s", "flicker_corner_hz"):
            a = np.array(getattr(self, name), dtype=np.float64).reshape(-1)
            if a.shape != (n,) or not np.isfinite(a).all():
                raise DeviceError(f"ChannelSensors.{name}: expected {n} finite values, got {a!r}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if np.any(self.range <= 0) or np.any(self.bandwidth_hz <= 0) or np.any(self.noise_density < 0):
            raise DeviceError("ChannelSensors: ranges and bandwidths must be > 0, noise densities >= 0")
        if np.any(self.flicker_corner_hz < 0):
            raise DeviceError("ChannelSensors: 1/f corners must be >= 0 Hz")
        object.__setattr__(self, "_rng", np.random.default_rng(self.seed))
        object.__setattr__(self, "_flicker_rng", flicker_rng(self.seed))

    @property
    def n_channels(self) -> int:
        """Number of channels."""
        return int(self.range.size)

    @classmethod
    def ideal(cls, ranges: list[float], *, noise: bool = True, bandwidth_hz: float = 50.0) -> ChannelSensors:
        """Sensors without offset or drift (noise density 200 µ-unit/√Hz when ``noise``)."""
        n = len(ranges)
        return cls(np.array(ranges, float), np.full(n, 200e-6 if noise else 0.0), np.full(n, bandwidth_hz),
                   np.zeros(n), np.zeros(n))

    @classmethod
    def draw(cls, specs: list[SensorSpec], *, seed: int = 0, noise: bool = True) -> ChannelSensors:
        """One part per spec, offsets and drifts drawn uniformly within the tolerances (seeded)."""
        rng = np.random.default_rng(seed)
        off = np.array([rng.uniform(-s.offset_tol, s.offset_tol) for s in specs])
        drift = np.array([rng.uniform(-s.drift_tol, s.drift_tol) for s in specs])
        return cls(np.array([s.range for s in specs]),
                   np.array([s.noise_density if noise else 0.0 for s in specs]),
                   np.array([s.bandwidth_hz for s in specs]), off, drift, seed=seed + 1)

    def without_errors(self) -> ChannelSensors:
        """The same parts (range, bandwidth) without noise, offset or drift: what is left is the ADC's
        quantisation and the filter's lag."""
        z = np.zeros(self.n_channels)
        return ChannelSensors(self.range, z, self.bandwidth_hz, z, z, seed=self.seed, flicker_corner_hz=z)

    @property
    def noise_rms(self) -> np.ndarray:
        """``(N,)`` output noise rms: white noise through the one-pole filter, ``d · sqrt(π/2 · f_-3dB)``."""
        return self.noise_density * np.sqrt(np.pi / 2.0 * self.bandwidth_hz)

    def adc(self, sampling_rate_hz: float, adc_bits: int = 10, **effects: float) -> Adc:
        """The converter behind these channels: 0-5 V span, the conditioning already done (gain 1); ``effects``:
        the converter's (:class:`gaitlog.firmware_sim.adc.Adc` fields ``acquisition_time_s``, ``inl_lsb``...)."""
        return Adc(adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz, gain=1.0, ref_v=2.5, **effects)

    def noise(self, times_s: np.ndarray) -> np.ndarray:
        """Filtered white noise ``(n, N)`` drawn exactly at the instants ``times_s`` (:func:`gaitlog.firmware_sim.sensor.
        ou_noise`), plus the 1/f part of the channels with a corner."""
        white = ou_noise(times_s, self.noise_rms, self.bandwidth_hz, self._rng)
        if not np.any(self.flicker_corner_hz):
            return white
        return white + flicker_noise(times_s, self.noise_density, self.flicker_corner_hz, FLICKER_LOW_HZ,
                                     self.bandwidth_hz, self._flicker_rng)

    def sample(self, values: np.ndarray, sampling_rate_hz: float, t0_s: float, adc: Adc) -> tuple[np.ndarray, np.ndarray]:
        """Sensor -> conditioning -> sample-and-hold -> ADC.

        Parameters
        ----------
        values
            ``(n, N)`` true values along each sensing axis on a fine regular grid (``sampling_rate_hz``, well
            above the bandwidths), first sample at ``t0_s``.
        adc
            The converter (:meth:`adc`); its timer gives the sample instants.

        Returns
        -------
        times_s, codes
            ``(m,)`` sample instants and ``(m, N)`` ``uint16`` codes.
        """
        u = np.asarray(values, dtype=np.float64)
        if u.ndim != 2 or u.shape[1] != self.n_channels:
            raise DeviceError(f"values must have shape (n, {self.n_channels}), got {u.shape}")
        if np.any(self.bandwidth_hz >= sampling_rate_hz / 2):
            raise DeviceError(f"fine grid of {sampling_rate_hz:g} Hz too coarse for a {self.bandwidth_hz.max():g} Hz "
                              "sensor bandwidth")
        x = np.clip(u, -self.range, self.range).T.copy()
        for j in range(self.n_channels):  # the output filter, settled on the first value (powered on before)
            b, a = signal.butter(1, self.bandwidth_hz[j], btype="low", fs=sampling_rate_hz)
            x[j], _ = signal.lfilter(b, a, x[j], zi=signal.lfilter_zi(b, a) * x[j, 0])
        times = adc.sample_times_s(t0_s, t0_s + (u.shape[0] - 1) / sampling_rate_hz)
        held = adc.hold(x.T, sampling_rate_hz, t0_s, times)
        held = held + self.noise(times) + self.offset + np.outer(times - t0_s, self.drift_per_s)
        span = adc.vref_high_v - adc.vref_low_v
        volts = adc.vref_low_v + span / 2.0 * (1.0 + held / self.range)
        return times, adc.convert(volts)

    def truth(self) -> dict[str, object]:
        """Every parameter, for the ground truth."""
        return {"range": self.range.tolist(), "noise_density": self.noise_density.tolist(),
                "bandwidth_hz": self.bandwidth_hz.tolist(), "offset": self.offset.tolist(),
                "drift_per_s": self.drift_per_s.tolist(), "noise_rms": self.noise_rms.tolist(), "seed": self.seed,
                "flicker_corner_hz": self.flicker_corner_hz.tolist()}
