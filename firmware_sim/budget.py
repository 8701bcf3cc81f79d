"""Does it fit? The logger's RAM and cycles with the on-line step algorithm, against the PIC16F877.

RAM (368 bytes of general-purpose registers): the algorithm's declared state and temporaries
(:mod:`firmware_sim.algorithms.state`, checked against the kernel's code) plus the firmware's own variables
while logging (:data:`FIRMWARE_RAM`): the sample page buffer (``firmware_sim.ring_buffer``: one 128-byte
EEPROM page), the header counters that change while logging, the UART receiver and transmitter, the AN617
maths registers, the interrupt context, the I2C driver and the step record's CRC. Items marked *estimate*
are counted from how such firmware is written, not from code in this repository.

Cycles per sample: the fixed-point kernel counts its primitives and I2C bytes on the real data path
(:class:`firmware_sim.algorithms.online.CycleStats`: mean, worst sample, worst backlog); the logging
interrupt's own work per sample is :data:`LOGGING_CYCLES`. Available: ``fosc / 4 / fs`` (92,160 at
50 Hz with the 18.432 MHz crystal). The algorithm runs in the main loop, after the interrupt: a sample
that costs more than one period (the end of a long step: two passes over its samples read back from the
scratch EEPROM) is absorbed as long as the backlog stays bounded; the page buffer holds 32 samples.

Examples
--------
>>> r = ram_budget(50.0)
>>> r.total_bytes <= PIC_RAM_BYTES, r.algorithm_bytes, r.firmware_bytes
(True, 186, 179)
>>> ram_budget(100.0).fits
False
"""

from __future__ import annotations

from dataclasses import dataclass

from firmware_sim.algorithms.parameters import (
    EventParameters,
    OnlineParameters,
    SampleCounts,
)
from firmware_sim.algorithms.state import (
    CALLS,
    persistent_bytes,
    temporaries_bytes,
    variables,
)
from firmware_sim.fixedpoint import (
    CYCLES,
    DEFAULT_FOSC_HZ,
    I2C_BYTE_CYCLES,
    cycles_per_sample_available,
)
from firmware_sim.ring_buffer import WORDS_PER_PAGE

__all__ = ["PIC_RAM_BYTES", "FIRMWARE_RAM", "LOGGING_CYCLES", "RamItem", "RamBudget", "CycleBudget",
           "ram_budget", "cycle_budget", "logging_cycles_per_sample",
           "algorithm_cycles_per_sample"]

#: General-purpose RAM of the PIC16F877 (DS30292: 368 x 8; the largest contiguous bank block is 96 bytes).
PIC_RAM_BYTES = 368


@dataclass(frozen=True)
class RamItem:
    """One block of RAM: name, bytes, where the figure comes from."""

    name: str
    bytes: int
    source: str


#: The firmware's own variables while logging.
FIRMWARE_RAM: tuple[RamItem, ...] = (
    RamItem("sample page buffer", 4 * WORDS_PER_PAGE,
            "implemented: firmware_sim.ring_buffer collects one 128-byte EEPROM page (32 P32 samples)"),
    RamItem("header counters", 4 + 2 + 1 + 4 + 2,
            "implemented: samples_written (u32), write_index (16 bits suffice for 65,536 slots), flags, "
            "steps_written (u32), step_write_index (u16); the rest of the header stays in the data EEPROM"),
    RamItem("UART receiver", 9,
            "estimate: hunt state, length (2), count (2), type, seq, CRC-16 register (2); payloads of the "
            "commands a logging device accepts are empty, the others are answered BUSY unbuffered"),
    RamItem("UART transmitter", 4, "estimate: field pointer, count, CRC-16 register (2); answers built on the fly"),
    RamItem("AN617 maths registers", 12, "estimate: AARG (4), BARG (2), REM (2), TEMP (2), loop count, sign"),
    RamItem("interrupt context", 4, "estimate: W, STATUS, PCLATH, FSR"),
    RamItem("I2C driver", 5, "estimate: state, 17-bit address (3), byte count"),
    RamItem("step record CRC", 2, "estimate: CRC-16 register while the record is streamed to the step EEPROM"),
    RamItem("sample timer and marker", 2, "estimate: sample flag, marker-button debounce"),
)

#: The logging interrupt's cycles per sample (besides the algorithm).
LOGGING_CYCLES: dict[str, tuple[float, str]] = {
    "ADC": (3 * 276, "3 conversions: 40 us acquisition (32 kOhm ADXL202 output) + 12 TAD of 1.74 us at 18.432 MHz "
                     "(32 Tosc), busy-waiting (computed; HARDWARE.md)"),
    "pack and store": (60, "estimate: P32 word into the page buffer, counters"),
    "page write": ((4 * WORDS_PER_PAGE + 3) * I2C_BYTE_CYCLES / WORDS_PER_PAGE,
                   "one 128-byte page + control and address every 32 samples, busy-waiting I2C (computed)"),
    "interrupt entry and exit": (20, "estimate: context save and restore"),
}


def logging_cycles_per_sample() -> float:
    """Cycles the logging interrupt takes per sample (:data:`LOGGING_CYCLES`).

    >>> round(logging_cycles_per_sample())
    1313
    """
    return float(sum(c for c, _ in LOGGING_CYCLES.values()))


def algorithm_cycles_per_sample(sampling_rate_hz: float, fosc_hz: float = DEFAULT_FOSC_HZ) -> float:
    """Cycles per sample period left to the on-line step algorithm: the period minus the logging interrupt.

    >>> round(algorithm_cycles_per_sample(50.0))
    90847
    """
    return cycles_per_sample_available(sampling_rate_hz, fosc_hz) - logging_cycles_per_sample()


@dataclass(frozen=True)
class RamBudget:
    """RAM of the logger with the on-line algorithm at one sampling rate."""

    sampling_rate_hz: float
    algorithm: tuple[RamItem, ...]
    firmware: tuple[RamItem, ...]

    @property
    def algorithm_bytes(self) -> int:
        """The algorithm's state and temporaries."""
        return sum(i.bytes for i in self.algorithm)

    @property
    def firmware_bytes(self) -> int:
        """The firmware's own variables."""
        return sum(i.bytes for i in self.firmware)

    @property
    def total_bytes(self) -> int:
        """Everything."""
        return self.algorithm_bytes + self.firmware_bytes

    @property
    def fits(self) -> bool:
        """Within the PIC16F877's 368 bytes."""
        return self.total_bytes <= PIC_RAM_BYTES

    def lines(self) -> list[str]:
        """A printed table."""
        out = [f"RAM at {self.sampling_rate_hz:g} Hz (PIC16F877: {PIC_RAM_BYTES} bytes)"]
        for i in self.algorithm + self.firmware:
            out.append(f"  {i.name:<44s} {i.bytes:4d}  {i.source}")
        verdict = "fits" if self.fits else "DOES NOT FIT"
        out.append(f"  {'total':<44s} {self.total_bytes:4d}  {verdict} ({PIC_RAM_BYTES - self.total_bytes:+d} bytes)")
        if not self.fits:
            out.append(f"  what must give: {self.total_bytes - PIC_RAM_BYTES} bytes, e.g. a 64-byte sample page buffer "
                       f"(half-page writes: twice the sample EEPROM's write cycles) saves 64")
        return out


def ram_budget(sampling_rate_hz: float, *, events: EventParameters | None = None,
               online: OnlineParameters | None = None) -> RamBudget:
    """The RAM budget at ``sampling_rate_hz`` (the delay line grows with the rate)."""
    c = SampleCounts.at(events or EventParameters(), online or OnlineParameters(), sampling_rate_hz)
    line, med = 2 * c.r3 + 1, c.median_steps
    persistent = [RamItem(f"algorithm: {v.name}", v.bytes, f"implemented: {v.note}")
                  for v in variables(line_length=line, median_steps=med)]
    temps = temporaries_bytes(median_steps=med)
    chain, f = [], "process"
    while CALLS[f]:
        f = max(CALLS[f], key=lambda g: temporaries_bytes(median_steps=med, entry=g))
        chain.append(f)
    algorithm = tuple(persistent) + (RamItem(
        "algorithm: temporaries", temps,
        "implemented: the largest chain of the kernel's declared frames, " + " > ".join(chain)),)
    assert sum(i.bytes for i in persistent) == persistent_bytes(line_length=line, median_steps=med)
    return RamBudget(float(sampling_rate_hz), algorithm, FIRMWARE_RAM)


@dataclass(frozen=True)
class CycleBudget:
    """Cycles per sample of the logger with the on-line algorithm (counted on a recording)."""

    sampling_rate_hz: float
    fosc_hz: float
    mean_algorithm: float
    worst_algorithm: int
    worst_backlog: int
    logging: float

    @property
    def available(self) -> float:
        """Cycles in one sample period."""
        return cycles_per_sample_available(self.sampling_rate_hz, self.fosc_hz)

    @property
    def mean_load(self) -> float:
        """Mean fraction of the CPU used (logging + algorithm)."""
        return (self.mean_algorithm + self.logging) / self.available

    @property
    def backlog_samples(self) -> float:
        """The most the algorithm lagged behind the sampling interrupt, in sample periods."""
        return self.worst_backlog / algorithm_cycles_per_sample(self.sampling_rate_hz, self.fosc_hz)

    @property
    def fits(self) -> bool:
        """The mean load is below 1 and the algorithm never lags a whole page buffer (32 samples)."""
        return self.mean_load < 1.0 and self.backlog_samples < WORDS_PER_PAGE

    def lines(self) -> list[str]:
        """A printed summary."""
        return [
            f"cycles at {self.sampling_rate_hz:g} Hz, {self.fosc_hz / 1e6:g} MHz: {self.available:,.0f} per sample",
            f"  logging interrupt            {self.logging:10,.0f}",
            f"  algorithm, mean              {self.mean_algorithm:10,.0f}   (load {100 * self.mean_load:.0f} %)",
            f"  algorithm, worst sample      {self.worst_algorithm:10,d}   "
            f"({self.worst_algorithm / self.available:.2f} periods)",
            f"  worst backlog                {self.worst_backlog:10,d}   ({self.backlog_samples:.2f} samples behind; "
            f"{'fits' if self.fits else 'DOES NOT FIT'})",
        ]


def cycle_budget(stats, sampling_rate_hz: float, *, fosc_hz: float = DEFAULT_FOSC_HZ) -> CycleBudget:
    """Cycle budget from a run's :class:`~firmware_sim.algorithms.online.CycleStats` (run with
    ``cycles_available =`` :func:`algorithm_cycles_per_sample`, as the firmware does)."""
    return CycleBudget(float(sampling_rate_hz), float(fosc_hz), stats.mean, int(stats.worst), int(stats.worst_backlog),
                       logging_cycles_per_sample())


assert "i2c_byte" in CYCLES
