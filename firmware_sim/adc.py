"""The PIC16F877's 10-bit A/D converter behind an amplifier front end, sampled by a timer.

Front end (assumed; the paper gives no schematic): the ADXL202 XFILT/YFILT outputs (0 g at ``Vs/2``,
~312 mV/g at 5 V) fed straight into a 0-5 V converter would use only ~256 of the 1024 codes
(HARDWARE.md). A non-inverting stage around the 0 g level fixes that:
``v_adc = ref_v + gain · (v_sensor − ref_v)`` with ``gain`` 4 (a standard resistor ratio) and ``ref_v`` =
2.5 V, so ±2 g spans ±2.496 V around mid-scale: 255.6 codes/g, 0 g at code 512. Both are parameters; so
are ``vref_low_v``/``vref_high_v`` (VREF- and VREF+ on RA2/RA3), the number of bits and the rate.

Quantiser: ideal, ``code = floor((v − VREF-) / (VREF+ − VREF-) · 2^bits)`` clipped to ``0 … 2^bits − 1``
(input beyond the references gives the end codes; the amplifier output is also limited to the reference
span, as a rail-to-rail op-amp on the same supply would be).

Timer: the sample clock runs at ``sampling_rate_hz · (1 + timer_error_ppm·1e-6)``; sample ``k`` is taken at
``t_first + k / rate_actual``. Sample-and-hold: the fine-grid analog signal is linearly interpolated at the
sample instants (it is band-limited by the sensor filter, well below the fine-grid rate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.protocol.adc_bits import check_adc_bits

#: The logger's sample-timer rate unless told otherwise (Alvarez et al. 2006: 50 Hz), Hz.
DEFAULT_SAMPLING_RATE_HZ = 50.0

__all__ = ["DEFAULT_SAMPLING_RATE_HZ", "Adc"]


@dataclass(frozen=True)
class Adc:
    """A/D converter settings.

    Parameters
    ----------
    adc_bits
        Resolution, 1 … 10 (codes are stored right-justified in 10-bit fields).
    sampling_rate_hz
        Nominal sample rate of the timer, Hz.
    vref_low_v, vref_high_v
        Converter reference span (VREF-, VREF+), V.
    gain
        Front-end gain around ``ref_v``.
    ref_v
        Front-end reference (the sensor's nominal 0 g level), V.
    timer_error_ppm
        Frequency error of the sample timer (crystal tolerance), parts per million.

    Examples
    --------
    >>> adc = Adc()
    >>> adc.convert(np.array([[2.5, 2.5 + 0.312, 2.5 - 0.312]])).tolist()
    [[512, 767, 256]]
    >>> adc.convert(np.array([[0.0, 5.0, 9.0]])).tolist()
    [[0, 1023, 1023]]
    """

    adc_bits: int = 10
    sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ
    vref_low_v: float = 0.0
    vref_high_v: float = 5.0
    gain: float = 4.0
    ref_v: float = 2.5
    timer_error_ppm: float = 0.0

    def __post_init__(self) -> None:
        check_adc_bits(self.adc_bits, what="ADC bits (10-bit storage fields)", error=DeviceError)
        if not (self.sampling_rate_hz > 0 and np.isfinite(self.sampling_rate_hz)):
            raise DeviceError(f"ADC sampling_rate_hz must be > 0, got {self.sampling_rate_hz!r}")
        if not self.vref_high_v > self.vref_low_v:
            raise DeviceError(f"VREF+ ({self.vref_high_v} V) must be above VREF- ({self.vref_low_v} V)")
        if not (self.gain > 0 and abs(self.timer_error_ppm) < 1e5):
            raise DeviceError("ADC gain must be > 0 and the timer error below 1e5 ppm")

    @property
    def n_codes(self) -> int:
        """Number of codes, ``2^bits``."""
        return 1 << int(self.adc_bits)

    @property
    def actual_rate_hz(self) -> float:
        """Rate of the real sample timer, ``sampling_rate_hz · (1 + ppm·1e-6)``."""
        return self.sampling_rate_hz * (1.0 + self.timer_error_ppm * 1e-6)

    @property
    def lsb_v(self) -> float:
        """Size of one code at the converter input, V."""
        return (self.vref_high_v - self.vref_low_v) / self.n_codes

    def sample_times_s(self, t_first_s: float, t_last_s: float) -> np.ndarray:
        """Instants ``t_first + k / actual_rate`` up to and including ``t_last_s`` (tolerance 1e-9 s)."""
        period = 1.0 / self.actual_rate_hz
        n = int(np.floor((t_last_s - t_first_s) / period + 1e-9)) + 1 if t_last_s >= t_first_s else 0
        return t_first_s + np.arange(n) * period

    def convert(self, sensor_v: np.ndarray) -> np.ndarray:
        """Codes (``uint16``, same shape) of sensor voltages through the front end and the quantiser."""
        v = self.ref_v + self.gain * (np.asarray(sensor_v, dtype=np.float64) - self.ref_v)
        codes = np.floor((v - self.vref_low_v) / self.lsb_v)
        return np.clip(codes, 0, self.n_codes - 1).astype(np.uint16)

    def hold(self, sensor_v: np.ndarray, sampling_rate_hz: float, t0_s: float, times_s: np.ndarray) -> np.ndarray:
        """Sample-and-hold: the fine-grid signal ``sensor_v`` ``(n, 3)`` (rate ``sampling_rate_hz``, first sample at
        ``t0_s``) linearly interpolated at ``times_s``; returns ``(len(times_s), 3)`` volts."""
        v = np.asarray(sensor_v, dtype=np.float64)
        x = (np.asarray(times_s, dtype=np.float64) - t0_s) * sampling_rate_hz
        if v.shape[0] < 2:
            return np.repeat(v[:1], len(x), axis=0)
        vt = v.T  # axis-major: contiguous rows when v is the transposed output of the sensor model
        r = np.rint(x)
        if x.size and np.all(np.abs(x - r) < 1e-6) and r[0] >= 0 and r[-1] < v.shape[0]:
            i = r.astype(np.int64)  # instants on the fine grid: no interpolation
            step = i[1] - i[0] if i.size > 1 else 1
            if step > 0 and np.array_equal(i, i[0] + step * np.arange(i.size)):
                return vt[:, i[0]:i[-1] + 1:step].T  # a strided view, no gather
            return vt[:, i].T
        i = np.clip(np.floor(x).astype(np.int64), 0, v.shape[0] - 2)
        frac = np.clip(x - i, 0.0, 1.0)
        return (vt[:, i] * (1.0 - frac) + vt[:, i + 1] * frac).T

    def sample(self, sensor_v: np.ndarray, sampling_rate_hz: float, t0_s: float, times_s: np.ndarray) -> np.ndarray:
        """:meth:`hold` then :meth:`convert`: ``(len(times_s), 3)`` ``uint16`` codes."""
        return self.convert(self.hold(sensor_v, sampling_rate_hz, t0_s, times_s))
