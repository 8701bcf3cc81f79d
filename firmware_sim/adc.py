"""The PIC16F877's 10-bit A/D converter behind an amplifier front end, sampled by a timer.

Front end (assumed; the paper gives no schematic): the ADXL202 XFILT/YFILT outputs (0 g at ``Vs/2``,
~312 mV/g at 5 V) fed straight into a 0-5 V converter would use only ~256 of the 1024 codes
(HARDWARE.md). A non-inverting stage around the 0 g level fixes that:
``v_adc = ref_v + gain · (v_sensor − ref_v)`` with ``gain`` 4 (a standard resistor ratio) and ``ref_v`` =
2.5 V, so ±2 g spans ±2.496 V around mid-scale: 255.6 codes/g, 0 g at code 512. Both are parameters; so
are ``vref_low_v``/``vref_high_v`` (VREF- and VREF+ on RA2/RA3), the number of bits and the rate.

Quantiser: ideal by default, ``code = floor((v − VREF-) / (VREF+ − VREF-) · 2^bits)`` clipped to
``0 … 2^bits − 1`` (input beyond the references gives the end codes; the amplifier output is also limited to
the reference span, as a rail-to-rail op-amp on the same supply would be).

Timer: the sample clock runs at ``sampling_rate_hz · (1 + timer_error_ppm·1e-6)``; sample ``k`` is taken at
``t_first + k / rate_actual``. Sample-and-hold: the fine-grid analog signal is linearly interpolated at the
sample instants (it is band-limited by the sensor filter, well below the fine-grid rate).

**The converter as the PIC16F87X data sheet describes it** (DS30292C, section 11 and the A/D characteristics
table). Every effect below is a parameter of :class:`Adc`, **off by default** (the defaults give today's ideal
converter, code for code); :meth:`Adc.datasheet` sets them at the data sheet's limits for one seeded device.

* *Sequential multiplexed sampling* (``acquisition_time_s`` > 0): one converter, one channel at a time. At each
  tick the firmware selects channel 0, waits the acquisition time ``T_ACQ``, converts (12 ``T_AD``, plus the
  2 ``T_AD`` wait before the next acquisition; ``T_AD`` = 1.6 µs at 20 MHz), selects the next channel, and so
  on: channel ``c`` is held at ``t + T_ACQ + c · (T_ACQ + 14 T_AD)``. The data sheet's ``T_ACQ = T_AMP + T_C +
  T_COFF`` with ``T_C = C_HOLD (R_IC + R_SS + R_S) ln 2047`` (:func:`pic_acquisition_time_s`) is 19.72 µs for a
  10 kΩ source at 50 °C and 39.8 µs for the ADXL202's 32 kΩ: a channel skew of 42.1 or 62.2 µs. ``0`` (the
  default) holds every channel at the tick instant (an ideal simultaneous sample-and-hold).
* *Settling error* (``source_impedance_ohm``, with sequential sampling): the 120 pF hold capacitor starts each
  acquisition at the previous channel's voltage and charges for ``T_ACQ − T_AMP`` through ``R_IC + R_SS + R_S``:
  the held voltage keeps the fraction ``ε = exp(−(T_ACQ − T_AMP) / (C_HOLD (R_IC + R_SS + R_S)))`` of the
  difference (:attr:`Adc.settling_fraction`; ``1/2047``, half a 10-bit LSB of a full-scale step, at the data
  sheet's ``T_ACQ`` for that ``R_S``). Channel 0's previous voltage is the last channel's (the capacitor tracks
  it between ticks). The model's front end is an amplifier (a low source impedance, default 0 Ω). An ADXL202
  output wired straight to the pin is its 32 kΩ with the filter capacitor ``C_S`` at the pin
  (``source_capacitance_f``): the two capacitors first share their charge through ``R_IC + R_SS``, then both
  recharge through ``R_S``; ``ε`` is then the hold capacitor's part of the solution of that two-capacitor network
  (a 2 x 2 matrix exponential), ``≈ C_HOLD / (C_HOLD + C_S)`` when ``C_S`` is large (4.8e-4 for 0.25 µF). The
  pin capacitor's own disturbance is assumed recovered by the next tick (``R_S C_S`` = 8 ms against 20 ms).
* *INL and DNL* (``inl_lsb``, ``dnl_lsb``; data sheet: both below ±1 LSB, monotonic): a seeded static transfer
  curve per device (:class:`TransferCurve`): a smooth bow of peak ``inl_lsb`` (``sin(m π u)``, ``m`` = 1, 2,
  3, with seeded amplitudes: zero at the end transitions) plus an independent uniform jitter of each code
  transition, ±``dnl_lsb``/2, so adjacent code widths differ from 1 LSB by less than ``dnl_lsb``.
* *Offset and gain error* (``offset_error_lsb``: the first transition's shift, data sheet < ±2 LSB;
  ``gain_error_lsb``: the end transition's error after the offset is removed, < ±1 LSB).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields, replace

import numpy as np

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sampling import DEFAULT_SAMPLING_RATE_HZ  # noqa: F401 -- defined there, used here too
from gaitlog.protocol.adc_bits import check_adc_bits

#: PIC16F87X A/D acquisition model (DS30292C section 11.1): hold capacitor, interconnect and sampling-switch
#: resistance (VDD = 5 V), amplifier settling, the hold's temperature coefficient above 25 °C.
HOLD_CAPACITANCE_F = 120e-12
INTERCONNECT_RESISTANCE_OHM = 1e3
SAMPLING_SWITCH_RESISTANCE_OHM = 7e3
AMPLIFIER_SETTLING_S = 2e-6
HOLD_TEMPCO_S_PER_C = 0.05e-6
#: ``T_C`` charges to within 1/2047 of a step (half a 10-bit LSB of full scale).
ACQUISITION_STEP_RATIO = 2047.0
#: ``T_AD`` at 20 MHz (32 T_OSC, the minimum 1.6 µs), and the ``T_AD`` from one channel's hold to the next
#: channel's acquisition: 12 to convert, 2 to wait.
TAD_S = 1.6e-6
TADS_PER_CHANNEL = 12 + 2
#: The largest source impedance the PIC16F87X data sheet recommends (its ``T_ACQ`` example's), Ω.
DATASHEET_SOURCE_IMPEDANCE_OHM = 10e3
#: The ADXL202's output resistance at XFILT/YFILT (HARDWARE.md).
ADXL202_OUTPUT_RESISTANCE_OHM = 32e3
#: PIC16F87X A/D characteristics (DS30292C, table "A/D converter characteristics"; *unverified* here, as
#: HARDWARE.md marks facts without a checked source): integral and differential error < ±1 LSB (monotonic, no
#: missing codes), offset < ±2 LSB, gain < ±1 LSB.
DATASHEET_INL_LSB = 1.0
DATASHEET_DNL_LSB = 1.0
DATASHEET_OFFSET_ERROR_LSB = 2.0
DATASHEET_GAIN_ERROR_LSB = 1.0
#: Widest converter a transfer curve is drawn for (the studies' hypothetical external converters).
MAX_CURVE_BITS = 16

__all__ = ["ADXL202_OUTPUT_RESISTANCE_OHM", "DEFAULT_SAMPLING_RATE_HZ", "Adc", "TransferCurve",
           "pic_acquisition_time_s"]


def pic_acquisition_time_s(source_impedance_ohm: float, *, temperature_c: float = 50.0) -> float:
    """The data sheet's minimum acquisition time ``T_ACQ = T_AMP + T_C + T_COFF``, s.

    ``T_C = C_HOLD (R_IC + R_SS + R_S) ln 2047``, ``T_COFF = (T − 25 °C) · 0.05 µs/°C`` (0 below 25 °C).

    >>> round(pic_acquisition_time_s(10e3) * 1e6, 2), round(pic_acquisition_time_s(32e3) * 1e6, 1)
    (19.72, 39.8)
    """
    if not (source_impedance_ohm >= 0 and math.isfinite(source_impedance_ohm)):
        raise DeviceError(f"source impedance must be >= 0 ohm, got {source_impedance_ohm!r}")
    r_ohm = INTERCONNECT_RESISTANCE_OHM + SAMPLING_SWITCH_RESISTANCE_OHM + source_impedance_ohm
    charge_s = HOLD_CAPACITANCE_F * r_ohm * math.log(ACQUISITION_STEP_RATIO)
    return AMPLIFIER_SETTLING_S + charge_s + max(temperature_c - 25.0, 0.0) * HOLD_TEMPCO_S_PER_C


@dataclass(frozen=True)
class TransferCurve:
    """A converter's static transfer curve: the input (in LSB, ``(v − VREF-) / lsb``) at which each code
    begins (module notes: offset, gain error, INL bow, DNL jitter; seeded per device).

    Transition ``k`` (code ``k − 1`` to ``k``, ``k = 1 … 2^bits − 1``) lies at ``T_k = k + offset + gain · u_k +
    inl · s(u_k) + e_k`` with ``u_k = (k − 1) / (2^bits − 2)``, ``s`` a seeded sum of ``sin(m π u)``, ``m = 1, 2,
    3``, scaled to peak 1 (zero at both end transitions), and ``e_k`` uniform in ±``dnl``/2 (zero at both
    ends). The ideal curve (everything 0) is ``floor``. The bow's shape depends on the seed only, so one
    device's INL has the same shape at every width.

    Examples
    --------
    >>> TransferCurve(10).quantise(np.array([-3.0, 0.2, 511.7, 1023.5, 2000.0])).tolist()
    [0, 0, 511, 1023, 1023]
    >>> TransferCurve(10, offset_error_lsb=2.0).quantise(np.array([2.9, 3.0])).tolist()
    [0, 1]
    """

    adc_bits: int
    inl_lsb: float = 0.0
    dnl_lsb: float = 0.0
    offset_error_lsb: float = 0.0
    gain_error_lsb: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        check_adc_bits(self.adc_bits, max_bits=MAX_CURVE_BITS, what="transfer curve bits", error=DeviceError)
        n = 1 << int(self.adc_bits)
        values = (self.inl_lsb, self.dnl_lsb, self.offset_error_lsb, self.gain_error_lsb)
        if not all(math.isfinite(v) for v in values):
            raise DeviceError(f"converter errors must be finite, got {values}")
        if not (0.0 <= self.inl_lsb <= n / 8 and 0.0 <= self.dnl_lsb <= 1.0):
            raise DeviceError(f"INL must be 0 .. {n / 8:g} LSB and DNL 0 .. 1 LSB (a monotonic converter), got "
                              f"{self.inl_lsb:g} and {self.dnl_lsb:g}")
        if abs(self.offset_error_lsb) > n / 4 or abs(self.gain_error_lsb) > n / 4:
            raise DeviceError(f"offset and gain errors must be within ±{n / 4:g} LSB, got {self.offset_error_lsb:g} "
                              f"and {self.gain_error_lsb:g}")

    @property
    def ideal(self) -> bool:
        """No error: the curve is ``floor`` (clipped)."""
        return self.inl_lsb == 0 and self.dnl_lsb == 0 and self.offset_error_lsb == 0 and self.gain_error_lsb == 0

    @property
    def n_codes(self) -> int:
        """``2^bits``."""
        return 1 << int(self.adc_bits)

    def at_bits(self, adc_bits: int) -> TransferCurve:
        """The same device's curve at another width (errors in LSB of that width, the bow's shape the same)."""
        return replace(self, adc_bits=int(adc_bits))

    @functools.cached_property
    def transitions_lsb(self) -> np.ndarray:
        """``(2^bits − 1,)`` increasing inputs, LSB, at which codes 1 … ``2^bits − 1`` begin."""
        n = self.n_codes
        k = np.arange(1, n, dtype=np.float64)
        u = (k - 1.0) / max(n - 2, 1)
        rng = np.random.default_rng(int(self.seed))
        amp = rng.standard_normal(3)            # drawn first: the bow's shape is the same at every width
        bow = sum(a * np.sin(m * np.pi * u) for m, a in zip((1, 2, 3), amp, strict=True))
        peak = float(np.max(np.abs(bow))) if bow.size else 0.0
        t = k + self.offset_error_lsb + self.gain_error_lsb * u
        if peak > 0:
            t = t + self.inl_lsb * bow / peak
        jitter = rng.uniform(-0.5, 0.5, k.size) * self.dnl_lsb
        jitter[[0, -1]] = 0.0
        t = np.maximum.accumulate(t + jitter)          # monotonic, as the data sheet guarantees
        t.setflags(write=False)
        return t

    def linear(self) -> tuple[float, float]:
        """``(a, b)``: the end-point line ``T_k ≈ a + b k`` (offset and gain; codes ≈ ``floor((x − a) / b)``)."""
        t = self.transitions_lsb
        b = (t[-1] - t[0]) / (t.size - 1) if t.size > 1 else 1.0
        return float(t[0] - b), float(b)

    def quantise(self, x_lsb: np.ndarray) -> np.ndarray:
        """Codes (``uint16``) of converter inputs in LSB (``(v − VREF-) / lsb``), any shape."""
        x = np.asarray(x_lsb, dtype=np.float64)
        if self.ideal:
            return np.clip(np.floor(x), 0, self.n_codes - 1).astype(np.uint16)
        return np.searchsorted(self.transitions_lsb, x, side="right").astype(np.uint16)


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
    acquisition_time_s
        Acquisition time before each channel's conversion, s; > 0 samples the channels one after the other
        (module notes); 0 (default): all channels held at the tick instant.
    source_impedance_ohm
        Source impedance each input is charged through (settling error; with sequential sampling only), Ω.
    source_capacitance_f
        Capacitance at the pin behind ``source_impedance_ohm`` (an unbuffered ADXL202's filter capacitor), F;
        0 (default): none, the data sheet's one-pole model.
    inl_lsb, dnl_lsb, offset_error_lsb, gain_error_lsb
        Static errors of the transfer curve (:class:`TransferCurve`), LSB; 0 by default.
    linearity_seed
        Seed of the device's INL bow and DNL jitter.

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
    acquisition_time_s: float = 0.0
    source_impedance_ohm: float = 0.0
    source_capacitance_f: float = 0.0
    inl_lsb: float = 0.0
    dnl_lsb: float = 0.0
    offset_error_lsb: float = 0.0
    gain_error_lsb: float = 0.0
    linearity_seed: int = 0

    def __post_init__(self) -> None:
        check_adc_bits(self.adc_bits, what="ADC bits (10-bit storage fields)", error=DeviceError)
        if not (self.sampling_rate_hz > 0 and np.isfinite(self.sampling_rate_hz)):
            raise DeviceError(f"ADC sampling_rate_hz must be > 0, got {self.sampling_rate_hz!r}")
        if not self.vref_high_v > self.vref_low_v:
            raise DeviceError(f"VREF+ ({self.vref_high_v} V) must be above VREF- ({self.vref_low_v} V)")
        if not (self.gain > 0 and abs(self.timer_error_ppm) < 1e5):
            raise DeviceError("ADC gain must be > 0 and the timer error below 1e5 ppm")
        if not (0.0 <= self.source_capacitance_f <= 1e-3):
            raise DeviceError(f"source capacitance must be 0 .. 1 mF, got {self.source_capacitance_f!r} F")
        if not (0.0 <= self.acquisition_time_s <= 1e-3 and 0.0 <= self.source_impedance_ohm <= 1e7):
            raise DeviceError(f"acquisition time must be 0 .. 1 ms and the source impedance 0 .. 10 Mohm, got "
                              f"{self.acquisition_time_s!r} s and {self.source_impedance_ohm!r} ohm")
        self.channel_delays_s(3)  # noqa: B018  (three channels fit in a sample period)
        self.transfer_curve  # noqa: B018  (checks the static errors)

    @classmethod
    def datasheet(cls, *, seed: int = 0, source_impedance_ohm: float = 0.0, **overrides: object) -> Adc:
        """A PIC16F877 at its data sheet's limits: sequential sampling after the data sheet's example ``T_ACQ``
        (19.72 µs, for its largest recommended source, 10 kΩ: what a firmware written from it waits), the
        settling error of ``source_impedance_ohm`` (0: the buffered front end), INL and DNL of ±1 LSB (shape
        seeded), offset ±2 LSB and gain ±1 LSB with seeded signs. ``overrides`` replace any field.

        >>> a = Adc.datasheet(seed=1)
        >>> (round(a.acquisition_time_s * 1e6, 2), a.inl_lsb, a.dnl_lsb, abs(a.offset_error_lsb), abs(a.gain_error_lsb))
        (19.72, 1.0, 1.0, 2.0, 1.0)
        """
        signs = np.random.default_rng(np.random.SeedSequence([int(seed), 877])).choice([-1.0, 1.0], 2)
        params: dict[str, object] = dict(
            acquisition_time_s=pic_acquisition_time_s(DATASHEET_SOURCE_IMPEDANCE_OHM),
            source_impedance_ohm=source_impedance_ohm, inl_lsb=DATASHEET_INL_LSB, dnl_lsb=DATASHEET_DNL_LSB,
            offset_error_lsb=float(signs[0]) * DATASHEET_OFFSET_ERROR_LSB,
            gain_error_lsb=float(signs[1]) * DATASHEET_GAIN_ERROR_LSB, linearity_seed=int(seed))
        params.update(overrides)
        return cls(**params)  # type: ignore[arg-type]

    @property
    def sequential(self) -> bool:
        """Channels converted one after the other (``acquisition_time_s`` > 0)."""
        return self.acquisition_time_s > 0.0

    @property
    def channel_period_s(self) -> float:
        """From one channel's hold to the next one's, s: ``T_ACQ + 14 T_AD`` (0 when simultaneous)."""
        return self.acquisition_time_s + TADS_PER_CHANNEL * TAD_S if self.sequential else 0.0

    def channel_delays_s(self, n_channels: int) -> np.ndarray:
        """``(n_channels,)`` hold instant of each channel after the tick, s (``T_ACQ + c · period``)."""
        if not self.sequential:
            return np.zeros(int(n_channels))
        delays = self.acquisition_time_s + self.channel_period_s * np.arange(int(n_channels))
        if delays[-1] + TADS_PER_CHANNEL * TAD_S >= 1.0 / self.actual_rate_hz:
            raise DeviceError(f"{n_channels} channels of {self.channel_period_s * 1e6:.1f} us do not fit in one "
                              f"{1e3 / self.actual_rate_hz:.3f} ms sample period")
        return delays

    @property
    def settling_fraction(self) -> float:
        """``ε``: the fraction of the previous channel's difference the hold capacitor keeps (module notes; 0
        when simultaneous)."""
        if not self.sequential:
            return 0.0
        charge_s = max(self.acquisition_time_s - AMPLIFIER_SETTLING_S, 0.0)
        r_hold_ohm = INTERCONNECT_RESISTANCE_OHM + SAMPLING_SWITCH_RESISTANCE_OHM
        if self.source_capacitance_f == 0.0 or self.source_impedance_ohm == 0.0:
            r_ohm = r_hold_ohm + (self.source_impedance_ohm if self.source_capacitance_f == 0.0 else 0.0)
            return math.exp(-charge_s / (HOLD_CAPACITANCE_F * r_ohm))
        # deviations from the source voltage of the pin (C_S) and the hold capacitor: d/dt e = A e, e(0) = (0, 1)
        c_s, c_h, r_s = self.source_capacitance_f, HOLD_CAPACITANCE_F, self.source_impedance_ohm
        a = np.array([[-1.0 / (r_s * c_s) - 1.0 / (r_hold_ohm * c_s), 1.0 / (r_hold_ohm * c_s)],
                      [1.0 / (r_hold_ohm * c_h), -1.0 / (r_hold_ohm * c_h)]])
        # e(t) = V exp(L t) V^-1 e(0): A's eigenvalues are real, negative and distinct (two RC poles)
        poles, vectors = np.linalg.eig(a)
        weights = np.linalg.solve(vectors, np.array([0.0, 1.0]))
        return float((vectors @ (np.exp(poles.real * charge_s) * weights.real))[1])

    @functools.cached_property
    def transfer_curve(self) -> TransferCurve:
        """The static transfer curve of this converter (:class:`TransferCurve`)."""
        return TransferCurve(int(self.adc_bits), self.inl_lsb, self.dnl_lsb, self.offset_error_lsb,
                             self.gain_error_lsb, int(self.linearity_seed))

    @property
    def ideal(self) -> bool:
        """Simultaneous sampling and an ideal transfer curve (the converter of the module's first notes)."""
        return not self.sequential and self.transfer_curve.ideal

    def effects(self) -> dict[str, float | int]:
        """The converter-effect parameters (those after ``timer_error_ppm``), for metadata and reports."""
        names = [f.name for f in fields(self)]
        return {n: getattr(self, n) for n in names[names.index("acquisition_time_s"):]}

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
        """Codes (``uint16``, same shape) of sensor voltages through the front end and the quantiser (rows:
        successive ticks, columns: channels in conversion order, for the settling error)."""
        if self.ideal:
            v = self.ref_v + self.gain * (np.asarray(sensor_v, dtype=np.float64) - self.ref_v)
            codes = np.floor((v - self.vref_low_v) / self.lsb_v)
            return np.clip(codes, 0, self.n_codes - 1).astype(np.uint16)
        return self.transfer_curve.quantise(self.input_lsb(sensor_v))

    def input_lsb(self, sensor_v: np.ndarray) -> np.ndarray:
        """The converter's input in LSB (``(v − VREF-) / lsb``) for sensor voltages ``(n, N)``: the front end,
        the rails (0 … ``2^bits``) and, when sequential, the settling error (module notes)."""
        v = self.ref_v + self.gain * (np.asarray(sensor_v, dtype=np.float64) - self.ref_v)
        x = np.clip((v - self.vref_low_v) / self.lsb_v, 0.0, float(self.n_codes))
        eps = self.settling_fraction
        if eps == 0.0 or x.ndim != 2 or x.shape[0] == 0:
            return x
        held = np.empty_like(x)
        prev = x[:, -1]                      # the capacitor tracked the last channel since the previous tick
        for c in range(x.shape[1]):          # channels in conversion order; each starts at the one before
            held[:, c] = x[:, c] + (prev - x[:, c]) * eps
            prev = held[:, c]
        return held

    def _hold_sequential(self, v: np.ndarray, sampling_rate_hz: float, t0_s: float, times_s: np.ndarray) -> np.ndarray:
        """:meth:`hold` with each channel at its own instant (linear interpolation on the fine grid)."""
        delays = self.channel_delays_s(v.shape[1])
        out = np.empty((times_s.size, v.shape[1]))
        for c in range(v.shape[1]):
            x = (times_s + delays[c] - t0_s) * sampling_rate_hz
            i = np.clip(np.floor(x).astype(np.int64), 0, v.shape[0] - 2)
            frac = np.clip(x - i, 0.0, 1.0)
            out[:, c] = v[i, c] * (1.0 - frac) + v[i + 1, c] * frac
        return out

    def hold(self, sensor_v: np.ndarray, sampling_rate_hz: float, t0_s: float, times_s: np.ndarray) -> np.ndarray:
        """Sample-and-hold: the fine-grid signal ``sensor_v`` ``(n, N)`` (rate ``sampling_rate_hz``, first sample at
        ``t0_s``) linearly interpolated at ``times_s`` (each channel at its own instant, :meth:`channel_delays_s`,
        when sequential); returns ``(len(times_s), N)`` volts."""
        v = np.asarray(sensor_v, dtype=np.float64)
        if self.sequential and v.shape[0] >= 2:
            return self._hold_sequential(v, sampling_rate_hz, t0_s, np.asarray(times_s, dtype=np.float64))
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
