"""The logging interrupt's cycles per sample, and what is left of each sample period to the on-line step algorithm.

The interrupt's model (:func:`logging_cycles`): per sample, the ADC conversions (acquisition and 12 TAD per channel,
DS30292 section 11, calibrated against the assembly measured in gpsim: :data:`ADC_CALIBRATION`), packing and storing
the sample, the EEPROM page write and the header version 3 journal entry, each with where its figure comes from;
:data:`CONFIGURATIONS`, the loggers of the seed papers. :func:`algorithm_cycles_per_sample` is the period
(``fosc / 4 / fs``) minus that interrupt: the on-line algorithm's budget
(:mod:`gaitlog.firmware_sim.algorithms.online` reports its backlog against it).

The rest of the budget (RAM, cycles measured, program words, storage, endurance) is
:mod:`gaitlog.firmware_sim.budget`, which re-exports these names; this module is apart so that running the on-line
algorithm does not load the whole budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gaitlog.firmware_sim.eeprom import PAGE_BYTES
from gaitlog.firmware_sim.fixedpoint import DEFAULT_FOSC_HZ, I2C_BYTE_CYCLES, cycles_per_sample_available
from gaitlog.protocol.journal_ring import COMMIT_PAGES, ENTRY_BYTES_V3

__all__ = ["ADC_CALIBRATION", "ADC_CONVERSION_TAD", "ADC_TAD_MIN_S", "CONFIGURATIONS", "JOURNAL_ENTRY_CYCLES_ESTIMATE",
           "LOGGING_CYCLES", "LoggerConfig", "adc_acquisition_s", "adc_channel_cycles", "adc_max_sampling_rate_hz",
           "adc_tad_s", "algorithm_cycles_per_sample", "logged_channel_cycles", "logging_cycles",
           "logging_cycles_per_sample"]

#: ADC (DS30292 section 11): TAD >= 1.6 us from 2, 8 or 32 Tosc; 12 TAD per 10-bit conversion; acquisition
#: TACQ = amplifier settling 2 us + temperature term 1.25 us + CHOLD (120 pF) x (RIC 1 kOhm + RSS 7 kOhm
#: + source) x ln(2047) (eq. 11-1: 19.72 us with 10 kOhm, the datasheet's largest recommended source).
ADC_TAD_MIN_S = 1.6e-6
ADC_CONVERSION_TAD = 12


def adc_acquisition_s(source_impedance_ohm: float) -> float:
    """Acquisition time of one channel (DS30292 eq. 11-1).

    >>> round(adc_acquisition_s(10e3) * 1e6, 2), round(adc_acquisition_s(32e3) * 1e6, 2)
    (19.72, 39.85)
    """
    return 2e-6 + 1.25e-6 + 120e-12 * (1e3 + 7e3 + source_impedance_ohm) * math.log(2047)


def adc_tad_s(fosc_hz: float) -> float:
    """The shortest legal ADC clock period: 2, 8 or 32 Tosc, at least 1.6 us (RC above 32 Tosc's reach).

    >>> round(adc_tad_s(18.432e6) * 1e6, 3), round(adc_tad_s(20e6) * 1e6, 3), round(adc_tad_s(4e6) * 1e6, 3)
    (1.736, 1.6, 2.0)
    """
    for n in (2, 8, 32):
        if n / fosc_hz >= ADC_TAD_MIN_S * (1 - 1e-9):
            return n / fosc_hz
    raise ValueError(f"no ADC clock of 2, 8 or 32 Tosc reaches 1.6 us at {fosc_hz / 1e6:g} MHz")


def adc_channel_cycles(fosc_hz: float, source_impedance_ohm: float) -> float:
    """Instruction cycles of one busy-waited channel: acquisition + 12 TAD conversion.

    >>> round(adc_channel_cycles(18.432e6, 32e3), 1)
    279.6
    """
    return (adc_acquisition_s(source_impedance_ohm) + ADC_CONVERSION_TAD * adc_tad_s(fosc_hz)) * fosc_hz / 4.0


def adc_max_sampling_rate_hz(adc_channels: int, fosc_hz: float, source_impedance_ohm: float) -> float:
    """The fastest sampling of ``adc_channels`` channels by the one converter, doing nothing else.

    >>> round(adc_max_sampling_rate_hz(6, 20e6, 10e3))
    4282
    """
    per = adc_acquisition_s(source_impedance_ohm) + ADC_CONVERSION_TAD * adc_tad_s(fosc_hz)
    return 1.0 / (adc_channels * per)


@dataclass(frozen=True)
class LoggerConfig:
    """A logger configuration to budget: sampling, channels, crystal, on-line estimator, and its source."""

    name: str
    sampling_rate_hz: float
    adc_channels: int
    fosc_hz: float = DEFAULT_FOSC_HZ
    online_estimator: bool = True
    source_impedance_ohm: float = 32e3
    source: str = ""

    @property
    def bytes_per_sample(self) -> int:
        """Stored bytes per sample: one 32-bit word per three 10-bit channels (the P32 packing)."""
        return 4 * math.ceil(self.adc_channels / 3)


#: The configurations of the seed papers.
CONFIGURATIONS: dict[str, LoggerConfig] = {c.name: c for c in (
    LoggerConfig("alvarez-50", 50.0, 3, source="Alvarez et al. 2006: PIC16F877, two ADXL202 (3 axes, 32 kOhm "
                 "outputs), 50 Hz, 10-bit ADC, on-line step estimator"),
    LoggerConfig("alvarez-100", 100.0, 3, source="the Alvarez logger at 100 Hz"),
    LoggerConfig("morris-5", 100.0, 5, online_estimator=False, source_impedance_ohm=10e3,
                 source="Morris 1973: five uniaxial accelerometers on a shank platform, sampled at 10 ms "
                        "intervals; kinematics computed off line (source impedance assumed 10 kOhm)"),
    LoggerConfig("morris-6", 100.0, 6, online_estimator=False, source_impedance_ohm=10e3,
                 source="Morris 1973 with a sixth accelerometer (the platform's six motion parameters)"),
    LoggerConfig("hall", 10_000.0, 6, fosc_hz=20e6, online_estimator=False, source_impedance_ohm=10e3,
                 source="Hall et al. 1997: two triaxial angular rate sensors (head, thorax) sampled at 10 kHz; "
                        "the PIC's fastest crystal, 20 MHz (source impedance assumed 10 kOhm)"),
)}


#: The logging interrupt's ADC calibrated against the assembly measured in gpsim (``gaitlog budget --measure``,
#: ``firmware_sim/pic/logger.asm`` adc_convert): name -> (value, why). Without it the model put the interrupt
#: 10.5 % (108 cycles) below gpsim's 1,027; with it 1.8 % below (the rest: the acquisition loop's 3-cycle steps
#: and the context save, estimates).
ADC_CALIBRATION: dict[str, tuple[float, str]] = {
    "settle_tad": (2.0, "TAD the converter needs after a conversion before the next acquisition starts (DS30292 "
                        "section 11); the assembly waits them with the acquisition time, which the model had left out"),
    "read_cycles": (14.0, "cycles per channel besides acquisition and conversion: polling GO/DONE in a 3-cycle loop, "
                          "reading ADRESH:ADRESL across the bank switch, the call and the channel select (measured in "
                          "gpsim: 110 cycles from one channel's GO to the next channel's select, of which 96 are the "
                          "12 TAD conversion)"),
}


def logged_channel_cycles(config: LoggerConfig) -> float:
    """Cycles of one channel in the logging interrupt: :func:`adc_channel_cycles` with :data:`ADC_CALIBRATION`.

    >>> round(logged_channel_cycles(CONFIGURATIONS["alvarez-50"]), 1)
    309.6
    """
    tad_cycles = adc_tad_s(config.fosc_hz) * config.fosc_hz / 4.0
    return (adc_channel_cycles(config.fosc_hz, config.source_impedance_ohm)
            + ADC_CALIBRATION["settle_tad"][0] * tad_cycles + ADC_CALIBRATION["read_cycles"][0])


#: The header version 3 journal entry's cycles without gpsim (``docs/topics/eeprom-endurance.md``): its page write,
#: control, address and 16 bytes, at the assembly's I2C byte, and a CRC-16 over 14 bytes at about 60 cycles a
#: byte (estimated; ``gaitlog budget --measure`` measures ``firmware_sim/pic/journal.asm`` in gpsim instead).
JOURNAL_ENTRY_CYCLES_ESTIMATE = (3 + ENTRY_BYTES_V3) * I2C_BYTE_CYCLES + (ENTRY_BYTES_V3 - 2) * 60.0


def logging_cycles(config: LoggerConfig | None = None, *,
                   journal_entry_cycles: float | None = None) -> dict[str, tuple[float, str]]:
    """The logging interrupt's cycles per sample (besides the algorithm), with where each comes from.
    ``journal_entry_cycles``: header version 3's journal entry measured in gpsim (``firmware_sim/pic/journal.asm``,
    :func:`gaitlog.firmware_sim.pic.gpsim_journal.journal_entry_cycles`); None: the estimate
    :data:`JOURNAL_ENTRY_CYCLES_ESTIMATE`."""
    c = config or CONFIGURATIONS["alvarez-50"]
    per = logged_channel_cycles(c)
    words = c.bytes_per_sample // 4
    samples_per_page = PAGE_BYTES / c.bytes_per_sample
    entry = JOURNAL_ENTRY_CYCLES_ESTIMATE if journal_entry_cycles is None else float(journal_entry_cycles)
    how = ("estimated: its page write of 19 bytes at the I2C byte's cycles and a CRC-16 over 14 bytes"
           if journal_entry_cycles is None else
           "measured in gpsim: firmware_sim/pic/journal.asm, the page write streamed with its CRC-16 and the "
           "acknowledge polling of its write cycle")
    return {
        "ADC": (c.adc_channels * per,
                f"{c.adc_channels} conversions of {per:.0f} cycles: "
                f"{adc_acquisition_s(c.source_impedance_ohm) * 1e6:.1f} us "
                f"acquisition ({c.source_impedance_ohm / 1e3:g} kOhm source) + 12 TAD of "
                f"{adc_tad_s(c.fosc_hz) * 1e6:.3f} us, busy-waiting (computed; DS30292 eq. 11-1), + 2 TAD before the "
                f"acquisition and {ADC_CALIBRATION['read_cycles'][0]:g} cycles of polling and reading (calibrated "
                "against gpsim)"),
        "pack and store": (60.0 * words, f"estimate: {words} P32 word(s) into the page buffer, counters"),
        "page write": ((PAGE_BYTES + 3) * I2C_BYTE_CYCLES / samples_per_page,
                       f"one 128-byte page + control and address every {samples_per_page:g} samples, busy-waiting "
                       "I2C (computed)"),
        "page commit": (entry / (COMMIT_PAGES * samples_per_page),
                        f"header version 3: a 16-byte journal entry every {COMMIT_PAGES} pages "
                        f"({COMMIT_PAGES * samples_per_page:g} samples), {entry:,.0f} cycles ({how})"),
        "interrupt entry and exit": (20.0, "estimate: context save and restore"),
    }


#: The logging interrupt's cycles per sample of the Alvarez logger (:func:`logging_cycles`).
LOGGING_CYCLES: dict[str, tuple[float, str]] = logging_cycles()


def logging_cycles_per_sample(config: LoggerConfig | None = None, *, journal_entry_cycles: float | None = None
                              ) -> float:
    """Cycles the logging interrupt takes per sample (:func:`logging_cycles`).

    >>> round(logging_cycles_per_sample())
    1593
    """
    return float(sum(c for c, _ in logging_cycles(config, journal_entry_cycles=journal_entry_cycles).values()))


def algorithm_cycles_per_sample(sampling_rate_hz: float, fosc_hz: float = DEFAULT_FOSC_HZ,
                                config: LoggerConfig | None = None) -> float:
    """Cycles per sample period left to the on-line step algorithm: the period minus the logging interrupt.

    >>> round(algorithm_cycles_per_sample(50.0))
    90567
    """
    if config is None:
        config = LoggerConfig("alvarez", float(sampling_rate_hz), 3, fosc_hz=float(fosc_hz))
    return cycles_per_sample_available(sampling_rate_hz, fosc_hz) - logging_cycles_per_sample(config)
