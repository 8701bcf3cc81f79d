"""Does a kinematics instrument fit the logger? A channel map on the PIC16F877's analog inputs, checked.

The logger (Alvarez et al. 2006) samples three channels (two ADXL202) at 50 Hz. Morris' platform needs five
or six single-axis accelerometers at 100 Hz, Hall's two triaxial rate sensors six channels at 10 kHz. This
module states what the hardware allows for a channel map of up to the PIC's eight analog inputs (AN0-AN7)
at a rate, and the closest configuration that fits when it does not. It is the check a ``record`` of such an
instrument must pass; the sampling path itself (sensor -> ADC -> memory -> dump with a channel map) is not
built here.

Limits (sources; *estimate* where the figure is how such firmware is written, not a datasheet value):

- ADC (PIC16F877, DS30292): ``T_AD >= 1.6 µs`` -- at 18.432 MHz the clock ``Fosc/32`` gives 1.736 µs; a
  10-bit conversion takes 12 ``T_AD`` (20.8 µs); after switching channel the hold capacitor needs the
  acquisition time ``T_ACQ`` = 19.72 µs (the datasheet's worked example); the interrupt reads the result and
  selects the next channel in about 40 instruction cycles (8.7 µs, *estimate*). Per channel: 49.3 µs, all
  channels of one sample inside one sample period.
- Memory bandwidth (24LC1025, DS21941): a 128-byte page goes over I2C at 400 kHz (131 bytes x 9 clocks,
  2.95 ms) then a write cycle of up to 5 ms: 16.1 kB/s sustained.
- Storage: 262,144 bytes (two 24LC1025); samples packed as the logger packs its three axes, three 10-bit
  channels per 32-bit word: ``4·ceil(channels/3)`` bytes per sample.

Examples
--------
>>> morris = check_fit(InstrumentPlan(("acc1", "acc2", "acc3", "acc4", "acc5"), 100.0))
>>> morris.fits, round(morris.duration_s)
(True, 328)
>>> hall = check_fit(InstrumentPlan(("Ax", "Ay", "Az", "Bx", "By", "Bz"), 10_000.0))
>>> hall.fits, round(hall.max_rate_hz)
(False, 2013)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from firmware_sim.eeprom import DEVICE_BYTES, PAGE_BYTES
from firmware_sim.fixedpoint import DEFAULT_FOSC_HZ

__all__ = [
    "ANALOG_INPUTS",
    "FitReport",
    "InstrumentPlan",
    "adc_time_per_channel_s",
    "check_fit",
    "memory_bytes_per_s",
]

#: Analog inputs of the PIC16F877 (RA0-RA3, RA5, RE0-RE2).
ANALOG_INPUTS = 8
#: Sample memory: two 24LC1025.
MEMORY_BYTES = 2 * DEVICE_BYTES
_T_AD_MIN_S = 1.6e-6
_T_ACQ_S = 19.72e-6
_CONVERSION_T_AD = 12
_ISR_CYCLES_PER_CHANNEL = 40  # estimate: read ADRESH/ADRESL, store, select the next channel, start
_I2C_HZ = 400_000.0
_PAGE_WRITE_S = 0.005
_BITS_PER_WORD = 32


def adc_time_per_channel_s(fosc_hz: float = DEFAULT_FOSC_HZ) -> float:
    """Acquisition + conversion + interrupt work for one channel, s (module notes)."""
    divisor = next((d for d in (2, 8, 32) if d / fosc_hz >= _T_AD_MIN_S), 32)
    t_ad = divisor / fosc_hz
    return _T_ACQ_S + _CONVERSION_T_AD * t_ad + _ISR_CYCLES_PER_CHANNEL * 4.0 / fosc_hz


def memory_bytes_per_s() -> float:
    """Sustained write bandwidth to the 24LC1025 pages, bytes/s (module notes)."""
    page_s = (PAGE_BYTES + 3) * 9 / _I2C_HZ + _PAGE_WRITE_S
    return PAGE_BYTES / page_s


@dataclass(frozen=True)
class InstrumentPlan:
    """A channel map: one name per analog input used (in AN order), the rate and the ADC resolution."""

    channels: tuple[str, ...]
    sampling_rate_hz: float
    adc_bits: int = 10

    @property
    def bytes_per_sample(self) -> int:
        """Bytes of one sample of every channel, packed ``floor(32/bits)`` channels per 32-bit word."""
        per_word = _BITS_PER_WORD // self.adc_bits
        return 4 * math.ceil(len(self.channels) / per_word)


@dataclass(frozen=True)
class FitReport:
    """Verdict on an :class:`InstrumentPlan`: ``fits``, the reasons it does not, the fastest rate that fits
    with these channels, the record length that fits in memory at the planned rate."""

    fits: bool
    reasons: list[str] = field(default_factory=list)
    max_rate_hz: float = 0.0
    duration_s: float = 0.0

    def message(self, plan: InstrumentPlan) -> str:
        """One line: why not, and the closest configuration that fits."""
        if self.fits:
            return (f"{len(plan.channels)} channels at {plan.sampling_rate_hz:g} Hz fit: "
                    f"{self.duration_s:.0f} s of memory")
        return (f"{len(plan.channels)} channels at {plan.sampling_rate_hz:g} Hz do not fit the PIC16F877 logger: "
                f"{'; '.join(self.reasons)}; closest that fits: {min(len(plan.channels), ANALOG_INPUTS)} channels at "
                f"{math.floor(self.max_rate_hz):d} Hz")


def check_fit(plan: InstrumentPlan, *, fosc_hz: float = DEFAULT_FOSC_HZ) -> FitReport:
    """Check ``plan`` against the analog inputs, the ADC time per sample and the memory bandwidth."""
    n = len(plan.channels)
    reasons = []
    if not 1 <= n <= ANALOG_INPUTS:
        reasons.append(f"{n} channels, the PIC16F877 has {ANALOG_INPUTS} analog inputs")
    if len(set(plan.channels)) != n:
        reasons.append(f"a channel is mapped twice: {list(plan.channels)}")
    if plan.adc_bits != 10:
        reasons.append(f"the PIC16F877's converter has 10 bits, not {plan.adc_bits}")
    if not (math.isfinite(plan.sampling_rate_hz) and plan.sampling_rate_hz > 0):
        return FitReport(False, [*reasons, f"sampling rate {plan.sampling_rate_hz!r} Hz"], 0.0, 0.0)
    n_eff = max(min(n, ANALOG_INPUTS), 1)
    t_ch = adc_time_per_channel_s(fosc_hz)
    adc_rate = 1.0 / (n_eff * t_ch)
    mem_rate = memory_bytes_per_s() / plan.bytes_per_sample
    if plan.sampling_rate_hz > adc_rate:
        reasons.append(f"ADC: {n_eff} conversions x {t_ch * 1e6:.1f} µs = {n_eff * t_ch * 1e6:.0f} µs per sample, "
                       f"the sample period is {1e6 / plan.sampling_rate_hz:.0f} µs")
    if plan.sampling_rate_hz > mem_rate:
        need = plan.bytes_per_sample * plan.sampling_rate_hz
        reasons.append(f"memory: {plan.bytes_per_sample} bytes x {plan.sampling_rate_hz:g} Hz = {need / 1e3:.1f} kB/s, "
                       f"the EEPROM pages take {memory_bytes_per_s() / 1e3:.1f} kB/s")
    return FitReport(not reasons, reasons, min(adc_rate, mem_rate),
                     MEMORY_BYTES / (plan.bytes_per_sample * plan.sampling_rate_hz))
