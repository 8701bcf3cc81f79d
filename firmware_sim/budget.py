"""Does it fit? The logger's RAM and cycles with the on-line step algorithm, against the PIC16F877.

RAM (368 bytes of general-purpose registers): the algorithm's declared state and temporaries
(:mod:`gaitlog.firmware_sim.algorithms.state`, checked against the kernel's code) plus the firmware's own variables
while logging (:data:`FIRMWARE_RAM`): the sample page buffer (``gaitlog.firmware_sim.ring_buffer``: one 128-byte
EEPROM page), the header counters that change while logging, the UART receiver and transmitter, the AN617
maths registers, the interrupt context, the I2C driver and the step record's CRC. Items marked *estimate*
are counted from how such firmware is written, not from code in this repository.

Cycles per sample: the fixed-point kernel counts its primitives and I2C bytes on the real data path
(:class:`gaitlog.firmware_sim.algorithms.online.CycleStats`: mean, worst sample, worst backlog); the logging
interrupt's own work per sample is :data:`LOGGING_CYCLES`. Available: ``fosc / 4 / fs`` (92,160 at
50 Hz with the 18.432 MHz crystal). The algorithm runs in the main loop, after the interrupt: a sample
that costs more than one period (the end of a long step: its filters evaluated again and two passes over its
samples, read back from the scratch EEPROM) is absorbed as long as the backlog stays bounded; the page buffer
holds 32 samples.

Endurance (:func:`endurance_budget`): the write cycles the EEPROM models count per page (per byte in the PIC's
data EEPROM) over a run of continuous logging, the worst of each region against its endurance, in years of
logging 8 and 24 hours a day (``docs/topics/eeprom-endurance.md``).

Examples
--------
>>> r = ram_budget(50.0)
>>> r.total_bytes <= PIC_RAM_BYTES, r.algorithm_bytes, r.firmware_bytes
(True, 186, 182)
>>> ram_budget(100.0).fits
False
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import (
    EventParameters,
    OnlineParameters,
    SampleCounts,
)
from gaitlog.firmware_sim.algorithms.state import (
    CALLS,
    persistent_bytes,
    temporaries_bytes,
    variables,
)
from gaitlog.firmware_sim.algorithms.kernel import (
    SCRATCH_FIRST_BYTE,
    SCRATCH_PAGES,
    SCRATCH_RING_BYTES,
    SCRATCH_SAMPLE_BYTES,
)
from gaitlog.firmware_sim.eeprom import (
    DATA_EEPROM_ENDURANCE_CYCLES,
    DEVICE_BYTES,
    ENDURANCE_CYCLES,
    PAGE_BYTES,
)
from gaitlog.firmware_sim.fixedpoint import (
    CYCLES,
    OPS,
    DEFAULT_FOSC_HZ,
    I2C_BYTE_CYCLES,
    MEASURED_CYCLES,
    cycles_per_sample_available,
)
from gaitlog.firmware_sim.logging_cycles import (  # the interrupt's model: importable from here as before
    ADC_CALIBRATION,
    ADC_CONVERSION_TAD,
    CONFIGURATIONS,
    JOURNAL_ENTRY_CYCLES_ESTIMATE,
    LOGGING_CYCLES,
    LoggerConfig,
    adc_acquisition_s,
    adc_channel_cycles,
    adc_max_sampling_rate_hz,
    adc_tad_s,
    algorithm_cycles_per_sample,
    logged_channel_cycles,
    logging_cycles,
    logging_cycles_per_sample,
)
from gaitlog.firmware_sim.ring_buffer import WORDS_PER_PAGE
from gaitlog.firmware_sim.uart import UartTiming
from gaitlog.protocol.header import HEADER_SIZE, MEMORY_BYTES
from gaitlog.protocol.journal_ring import COMMIT_PAGES, RING_FIRST_BYTE, STEP_CAPACITY_RECORDS_V3

__all__ = ["PIC_RAM_BYTES", "PIC_PROGRAM_WORDS", "FIRMWARE_RAM", "LOGGING_CYCLES", "CONFIGURATIONS", "LoggerConfig",
           "RamItem", "RamBudget", "CycleBudget", "ProgramBudget", "StorageBudget", "ram_budget", "cycle_budget",
           "program_budget", "storage_budget", "EnduranceBudget", "MemoryWear", "endurance_budget",
           "LIFETIME_HOURS_PER_DAY", "LIFETIME_TARGET_YEARS", "WEAR_RUN_SAMPLES", "scratch_page_writes_per_s",
           "logging_cycles", "logging_cycles_per_sample", "JOURNAL_ENTRY_CYCLES_ESTIMATE", "algorithm_cycles_per_sample", "adc_acquisition_s",
           "adc_tad_s", "adc_channel_cycles", "adc_max_sampling_rate_hz", "typical_cycles_per_sample", "shortfalls",
           "MEAN_CYCLES", "estimated_cycles", "ADC_CALIBRATION", "logged_channel_cycles", "INTERRUPT_PARTS", "interrupt_cycles_estimate"]

#: General-purpose RAM of the PIC16F877 (DS30292: 368 x 8; the largest contiguous bank block is 96 bytes).
PIC_RAM_BYTES = 368
#: Program memory of the PIC16F877: 8K x 14-bit words (DS30292).
PIC_PROGRAM_WORDS = 8192
#: 24LC1025 page write time, maximum (DS21941: 5 ms max, 3 ms typical); the logger waits the maximum.
EEPROM_PAGE_WRITE_S = 5e-3
#: Serial dump rate: 115200 baud 8N1 with the 18.432 MHz crystal (gaitlog.firmware_sim.uart), XMODEM-1K blocks.
DUMP_BAUD = 115200
XMODEM_BLOCK_DATA, XMODEM_BLOCK_WIRE = 1024, 1029      # STX, block number, its complement, data, CRC-16


@dataclass(frozen=True)
class RamItem:
    """One block of RAM: name, bytes, where the figure comes from."""

    name: str
    bytes: int
    source: str


#: The firmware's own variables while logging.
FIRMWARE_RAM: tuple[RamItem, ...] = (
    RamItem("sample page buffer", 4 * WORDS_PER_PAGE,
            "implemented: gaitlog.firmware_sim.ring_buffer collects one 128-byte EEPROM page (32 P32 samples)"),
    RamItem("header counters", 4 + 2 + 1 + 4 + 2,
            "implemented: samples_written (u32), write_index (16 bits suffice for 65,536 slots), flags, "
            "steps_written (u32), step_write_index (u16); the rest of the header stays in the data EEPROM"),
    RamItem("UART receiver", 9,
            "estimate: hunt state, length (2), count (2), type, seq, CRC-16 register (2); payloads of the "
            "commands a logging device accepts are empty, the others are answered BUSY unbuffered"),
    RamItem("UART transmitter", 4, "estimate: field pointer, count, CRC-16 register (2); answers built on the fly"),
    RamItem("maths registers", 15, "implemented: the arithmetic kernels' ACC (4), ARG (2), REM (3), TMP (3), COUNT, "
            "SIGNS, FLAGS in common RAM 0x70-0x7E (firmware_sim/pic/registers.inc)"),
    RamItem("interrupt context", 4, "estimate: W, STATUS, PCLATH, FSR"),
    RamItem("I2C driver", 5, "estimate: state, 17-bit address (3), byte count"),
    RamItem("step record CRC", 2, "estimate: CRC-16 register while the record is streamed to the step EEPROM"),
    RamItem("sample timer and marker", 2, "estimate: sample flag, marker-button debounce"),
)

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
               online: OnlineParameters | None = None, online_estimator: bool = True,
               formats: object = None) -> RamBudget:
    """The RAM budget at ``sampling_rate_hz`` (the delay line grows with the rate); without the on-line
    estimator only the firmware's own variables. ``formats`` (a
    :class:`~gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`; default the shipped ones) sizes the
    algorithm's state variables in their words' whole bytes (:data:`~gaitlog.firmware_sim.algorithms.state.WORD_OF`;
    its temporaries keep their declared words)."""
    if not online_estimator:
        return RamBudget(float(sampling_rate_hz), (), FIRMWARE_RAM)
    c = SampleCounts.at(events or EventParameters(), online or OnlineParameters(), sampling_rate_hz)
    line, med = 2 * c.r3 + 1, c.median_steps
    persistent = [RamItem(f"algorithm: {v.name}", v.bytes, f"implemented: {v.note}")
                  for v in variables(line_length=line, median_steps=med, formats=formats)]
    temps = temporaries_bytes(median_steps=med)
    chain, f = [], "process"
    while CALLS[f]:
        f = max(CALLS[f], key=lambda g: temporaries_bytes(median_steps=med, entry=g))
        chain.append(f)
    algorithm = tuple(persistent) + (RamItem(
        "algorithm: temporaries", temps,
        "implemented: the largest chain of the kernel's declared frames, " + " > ".join(chain)),)
    assert sum(i.bytes for i in persistent) == persistent_bytes(line_length=line, median_steps=med, formats=formats)
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
    #: The logging interrupt's page commit per sample (:func:`logging_cycles`) and how it was obtained.
    page_commit: tuple[float, str] = (0.0, "")

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
            f"    of which page commit       {self.page_commit[0]:10,.1f}   ({self.page_commit[1]})",
            f"  algorithm, mean              {self.mean_algorithm:10,.0f}   (load {100 * self.mean_load:.0f} %)",
            f"  algorithm, worst sample      {self.worst_algorithm:10,d}   "
            f"({self.worst_algorithm / self.available:.2f} periods)",
            f"  worst backlog                {self.worst_backlog:10,d}   ({self.backlog_samples:.2f} samples behind; "
            f"{'fits' if self.fits else 'DOES NOT FIT'})",
        ]


def cycle_budget(stats, sampling_rate_hz: float, *, fosc_hz: float = DEFAULT_FOSC_HZ,
                 config: LoggerConfig | None = None, journal_entry_cycles: float | None = None) -> CycleBudget:
    """Cycle budget from a run's :class:`~gaitlog.firmware_sim.algorithms.online.CycleStats` (run with
    ``cycles_available =`` :func:`algorithm_cycles_per_sample`, as the firmware does); ``stats = None``: no
    on-line algorithm, the logging interrupt only. ``journal_entry_cycles``: as :func:`logging_cycles`."""
    logging = logging_cycles_per_sample(config, journal_entry_cycles=journal_entry_cycles)
    commit = logging_cycles(config, journal_entry_cycles=journal_entry_cycles)["page commit"]
    if stats is None:
        return CycleBudget(float(sampling_rate_hz), float(fosc_hz), 0.0, 0, 0, logging, commit)
    return CycleBudget(float(sampling_rate_hz), float(fosc_hz), stats.mean, int(stats.worst), int(stats.worst_backlog),
                       logging, commit)


#: Cycles per call of each primitive for the model's *mean* estimate: the kernels' mean measured in gpsim where
#: a kernel exists (``kernel_cycles.json``), :data:`CYCLES` otherwise. This is the calibration against the chip
#: (``gaitlog budget --measure``): priced at the worst-case :data:`CYCLES`, the model put steps 1-3 19 % above
#: gpsim's mean on a walk (13 % with a device calibration); at these means it is within 10 % (+5.6 % with the
#: nominal calibration, whose six zero cross-axis products run the multiply kernel faster than its mean; +0.5 %
#: with a device calibration). A per-primitive correction (e.g. the cited sat32, 20 cycles, against the 6-11 of
#: the assembly's sign test) fitted to one calibration moved the other away, so none is applied.
MEAN_CYCLES: dict[str, float] = {**{k: float(v) for k, v in CYCLES.items()},
                                 **{k: float(v) for k, v in MEASURED_CYCLES["cycles_mean"].items()}}


def typical_cycles_per_sample(calls: dict[str, int], n_samples: int) -> tuple[float, float]:
    """Cycles per sample from the algorithm's operation counts (``ArithmeticContext.calls``) times each
    primitive's cost: (with the worst-case costs of :data:`CYCLES` -- the chain's own counter must agree
    --, with the calibrated mean costs of :data:`MEAN_CYCLES`)."""
    n = max(1, int(n_samples))
    return (sum(CYCLES[k] * v for k, v in calls.items()) / n, sum(MEAN_CYCLES[k] * v for k, v in calls.items()) / n)


def estimated_cycles(calls_per_sample: np.ndarray) -> np.ndarray:
    """The model's mean estimate of each sample's cycles from its primitive calls (``(..., len(OPS))``, columns in
    :data:`~gaitlog.firmware_sim.fixedpoint.OPS` order) at :data:`MEAN_CYCLES`.

    >>> calls = np.zeros(len(OPS), np.int64); calls[OPS.index("sat32")] = 2
    >>> float(estimated_cycles(calls))
    40.0
    """
    return np.asarray(calls_per_sample) @ np.array([MEAN_CYCLES[k] for k in OPS])


#: The parts of :func:`logging_cycles` that the assembly's sampling interrupt does (the I2C page write and the
#: page commit are still the model's).
INTERRUPT_PARTS = ("ADC", "pack and store", "interrupt entry and exit")


def interrupt_cycles_estimate(config: LoggerConfig | None = None) -> float:
    """The model's estimate of the sampling interrupt's cycles per sample, the parts in assembly
    (:data:`INTERRUPT_PARTS`).

    >>> round(interrupt_cycles_estimate())
    1009
    """
    parts = logging_cycles(config)
    return float(sum(parts[k][0] for k in INTERRUPT_PARTS))


#: Program memory of the firmware besides the measured kernels: (name, words, source); estimates.
FIRMWARE_PROGRAM: tuple[tuple[str, int, str], ...] = (
    ("UART command handler, frames, CRC-16", 450, "estimate: hunt/length/CRC state machine, 12 commands, "
                                                   "table-driven CRC-16 in 256 words of RETLW counted apart"),
    ("CRC-16 table", 256, "estimate: one RETLW table of the CRC's high byte"),
    ("XMODEM-1K sender", 200, "estimate: block framing, ACK/NAK/CAN handling"),
    ("I2C EEPROM driver", 150, "estimate: start/stop, byte out/in, page write, acknowledge polling"),
    ("ADC, timer and sampling interrupt", 100, "estimate: context save, 3-6 conversions, P32 packing"),
    ("header and configuration in the data EEPROM", 150, "estimate: read/write of 256 bytes, counters"),
    ("start-up and main loop", 80, "estimate"),
)
#: Program words per primitive call site of the on-line algorithm: operand and result moves (2 words a byte,
#: 4-8 bytes) plus the CALL; the control flow around them counted as half as much again (estimate).
WORDS_PER_CALL_SITE = 18
_KERNEL_SOURCE = Path(__file__).resolve().parent / "algorithms" / "kernel.py"


def _primitive_call_sites() -> int:
    """Arithmetic call sites of the on-line algorithm's kernel source: its ``ar.*`` operations
    (``algorithms/arithmetic.py``) and scalar primitives (``s_*``, not the cycle bookkeeping ``s_cost``)."""
    tree = ast.parse(_KERNEL_SOURCE.read_text(encoding="utf-8"))
    calls = [n.func for n in ast.walk(tree) if isinstance(n, ast.Call)]
    ops = sum(1 for f in calls if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "ar")
    return ops + sum(1 for f in calls if isinstance(f, ast.Name) and f.id.startswith("s_") and f.id != "s_cost")


@dataclass(frozen=True)
class ProgramBudget:
    """Program memory (14-bit words) against the PIC16F877's 8K."""

    items: tuple[tuple[str, int, str], ...]

    @property
    def total_words(self) -> int:
        """Everything."""
        return sum(w for _, w, _ in self.items)

    @property
    def fits(self) -> bool:
        """Within 8K words."""
        return self.total_words <= PIC_PROGRAM_WORDS

    def lines(self) -> list[str]:
        """A printed table."""
        out = [f"program memory (PIC16F877: {PIC_PROGRAM_WORDS} words)"]
        out += [f"  {n:<44s} {w:5d}  {src}" for n, w, src in self.items]
        verdict = "fits" if self.fits else "DOES NOT FIT"
        spare = PIC_PROGRAM_WORDS - self.total_words
        out.append(f"  {'total':<44s} {self.total_words:5d}  {verdict} ({spare:+d} words)")
        return out


def program_budget(online_estimator: bool = True) -> ProgramBudget:
    """Program memory: the measured arithmetic kernels, the algorithm's call sites, the firmware (estimates)."""
    items = [("arithmetic kernels (firmware_sim/pic)", int(MEASURED_CYCLES["kernel_program_words"]),
              "measured: gpasm, kernels_end - kernels_begin")]
    if online_estimator:
        sites = _primitive_call_sites()
        items.append(("on-line step algorithm", sites * WORDS_PER_CALL_SITE,
                      f"estimate: {sites} primitive call sites in algorithms/kernel.py x {WORDS_PER_CALL_SITE} words"))
    return ProgramBudget(tuple(items) + FIRMWARE_PROGRAM)


@dataclass(frozen=True)
class StorageBudget:
    """Sample EEPROM write bandwidth and the serial dump."""

    config: LoggerConfig

    @property
    def write_bytes_per_s(self) -> float:
        """Sample bytes to store per second."""
        return self.config.bytes_per_sample * self.config.sampling_rate_hz

    @property
    def page_cycle_s(self) -> float:
        """One page: 131 bytes on the I2C bus (control, 2 address, 128 data) then the 5 ms write."""
        return (PAGE_BYTES + 3) * I2C_BYTE_CYCLES * 4.0 / self.config.fosc_hz + EEPROM_PAGE_WRITE_S

    @property
    def capacity_bytes_per_s(self) -> float:
        """The most the 24LC1025 accepts, page after page."""
        return PAGE_BYTES / self.page_cycle_s

    @property
    def fits(self) -> bool:
        """The pages are written faster than they fill."""
        return self.write_bytes_per_s <= self.capacity_bytes_per_s

    @property
    def recording_s(self) -> float:
        """How long the two 24LC1025 (256 KiB) last."""
        return MEMORY_BYTES / self.write_bytes_per_s

    @property
    def dump_s(self) -> float | None:
        """A full memory over XMODEM-1K at 115200 baud (None: the crystal cannot make that rate)."""
        try:
            t = UartTiming(baud=DUMP_BAUD, fosc_hz=self.config.fosc_hz).byte_time_s
        except Exception:   # noqa: BLE001 - the DeviceError of an unreachable rate
            return None
        return math.ceil((HEADER_SIZE + MEMORY_BYTES) / XMODEM_BLOCK_DATA) * XMODEM_BLOCK_WIRE * t

    def lines(self) -> list[str]:
        """A printed summary."""
        dump = f"{self.dump_s:.1f} s" if self.dump_s is not None else f"{DUMP_BAUD} baud not reachable"
        return [
            f"sample EEPROM (2 x 24LC1025, {2 * DEVICE_BYTES // 1024} KiB, {PAGE_BYTES}-byte pages)",
            f"  writes                       {self.write_bytes_per_s:10,.0f} B/s  "
            f"({self.config.bytes_per_sample} bytes "
            f"a sample; one page every {PAGE_BYTES / self.write_bytes_per_s * 1e3:,.1f} ms)",
            f"  page cycle                   {self.page_cycle_s * 1e3:10.2f} ms   (I2C transfer + 5 ms write, max)",
            f"  capacity                     {self.capacity_bytes_per_s:10,.0f} B/s  "
            f"({100 * self.write_bytes_per_s / self.capacity_bytes_per_s:.1f} % used; "
            f"{'fits' if self.fits else 'DOES NOT FIT'})",
            f"  memory full after            {self.recording_s:10,.1f} s",
            f"  dump, XMODEM-1K {DUMP_BAUD} 8N1 {dump}",
        ]


def storage_budget(config: LoggerConfig) -> StorageBudget:
    """EEPROM bandwidth and dump time of ``config``."""
    return StorageBudget(config)


assert "i2c_byte" in CYCLES


def shortfalls(config: LoggerConfig, ram: RamBudget, cycles: CycleBudget, program: ProgramBudget,
               storage: StorageBudget) -> list[str]:
    """What does not fit, and by how much (one line each; empty when everything fits)."""
    out = []
    period_s = 1.0 / config.sampling_rate_hz
    adc_s = config.adc_channels / adc_max_sampling_rate_hz(1, config.fosc_hz, config.source_impedance_ohm)
    if adc_s > period_s:
        out.append(f"ADC: {config.adc_channels} channels take {adc_s * 1e6:,.1f} us per sample (acquisition "
                   f"{adc_acquisition_s(config.source_impedance_ohm) * 1e6:.1f} us + 12 TAD of "
                   f"{adc_tad_s(config.fosc_hz) * 1e6:.2f} us each), the period is {period_s * 1e6:,.1f} us: at most "
                   f"{adc_max_sampling_rate_hz(config.adc_channels, config.fosc_hz, config.source_impedance_ohm):,.0f}"
                   f" Hz with nothing else to do ({adc_s / period_s:.1f}x too slow)")
    if cycles.logging > cycles.available:
        out.append(f"cycles: the logging interrupt alone needs {cycles.logging:,.0f} of {cycles.available:,.0f} per "
                   f"sample ({cycles.logging / cycles.available:.1f}x)")
    elif not cycles.fits:
        out.append(f"cycles: mean load {100 * cycles.mean_load:.0f} %, backlog {cycles.backlog_samples:.1f} samples "
                   f"(limit {WORDS_PER_PAGE})")
    if not ram.fits:
        out.append(f"RAM: {ram.total_bytes} of {PIC_RAM_BYTES} bytes ({ram.total_bytes - PIC_RAM_BYTES} over)")
    if not program.fits:
        out.append(f"program memory: {program.total_words} of {PIC_PROGRAM_WORDS} words "
                   f"({program.total_words - PIC_PROGRAM_WORDS} over)")
    if not storage.fits:
        out.append(f"EEPROM: {storage.write_bytes_per_s:,.0f} B/s to write, the 24LC1025 takes "
                   f"{storage.capacity_bytes_per_s:,.0f} B/s "
                   f"({storage.write_bytes_per_s / storage.capacity_bytes_per_s:.1f}x)")
    return out


def instrument_fit(config: LoggerConfig) -> tuple[list[str], float]:
    """An instrument on the logger (its channels sampled and stored, no on-line estimator: Morris's platform,
    Hall's rate sensors): what does not fit (:func:`shortfalls`, empty when it fits) and the fastest sampling
    rate at which these channels fit, Hz (bisection on the same rules, to 0.1 Hz).

    >>> instrument_fit(CONFIGURATIONS["morris-5"])[0]
    []
    >>> short, fastest = instrument_fit(CONFIGURATIONS["hall"])
    >>> short[0][:40], round(fastest)
    ('ADC: 6 channels take 233.5 us per sample', 1883)
    """
    def short(rate_hz: float) -> list[str]:
        c = replace(config, sampling_rate_hz=rate_hz, online_estimator=False)
        return shortfalls(c, ram_budget(rate_hz, online_estimator=False),
                          cycle_budget(None, rate_hz, fosc_hz=c.fosc_hz, config=c), program_budget(False),
                          storage_budget(c))

    lo, hi = 1.0, float(config.sampling_rate_hz)
    if not short(hi):
        return [], hi
    while hi - lo > 0.1:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if not short(mid) else (lo, mid)
    return short(config.sampling_rate_hz), lo


#: Hours of logging a day of the lifetime figures.
LIFETIME_HOURS_PER_DAY = (8.0, 24.0)
#: The 24LC1025s must last this many years of logging 8 hours a day.
LIFETIME_TARGET_YEARS = 10.0
#: Samples of the run whose write cycles the lifetime figures rest on: four whole laps of the scratch ring
#: (:data:`~gaitlog.firmware_sim.algorithms.kernel.SCRATCH_RING_BYTES` at 2 bytes a sample, 32,512 samples),
#: about two of the sample memory at 4 bytes a sample; the step ring's worst page (written as records come) is
#: taken over whatever part of a lap the run covers: an overestimate of its rate, never an underestimate.
WEAR_RUN_SAMPLES = 4 * SCRATCH_RING_BYTES // SCRATCH_SAMPLE_BYTES
_YEAR_S = 365.25 * 86400.0


def scratch_page_writes_per_s(sampling_rate_hz: float, flush_samples: int) -> float:
    """The design's write cycles per second of each scratch-ring page: a page write every ``flush_samples``
    samples, spread evenly over the ring's pages (aligned flush units that divide the page and the ring).

    >>> round(scratch_page_writes_per_s(50.0, 16), 6)
    0.006152
    """
    return sampling_rate_hz / flush_samples / SCRATCH_PAGES


@dataclass(frozen=True)
class MemoryWear:
    """Write cycles of one region of a non-volatile memory over a run: per unit (page or byte), the worst (a
    design's figures: the cycles of one second)."""

    name: str
    unit: str
    cycles: tuple[float, ...]
    first_unit: int
    endurance_cycles: int
    source: str

    @property
    def worst_unit(self) -> int:
        """The unit with the most write cycles (its number in the memory)."""
        return self.first_unit + int(max(range(len(self.cycles)), key=self.cycles.__getitem__))

    @property
    def worst_cycles(self) -> float:
        """Its write cycles over the run."""
        return max(self.cycles)


@dataclass(frozen=True)
class EnduranceBudget:
    """How long the memories last under continuous logging: each region's worst unit, its write cycles per
    second over the run (``duration_s`` of logging), against its endurance."""

    config: LoggerConfig
    duration_s: float
    regions: tuple[MemoryWear, ...]
    measured: bool
    #: Runs (START ... STOP) the measurement logged: the byte regions, written by header commits only (header
    #: version 3), are then also given in runs; 0: not stated.
    runs: int = 0
    #: Header version of the measured logger (3, the default device: the journal ring; 2: the data EEPROM's
    #: journal); 0: not stated (computed from the design).
    header_version: int = 0

    def rate_per_s(self, region: MemoryWear) -> float:
        """Write cycles per second of the region's worst unit."""
        return region.worst_cycles / self.duration_s

    def lifetime_years(self, region: MemoryWear, hours_per_day: float) -> float:
        """Years until the worst unit reaches its endurance, logging ``hours_per_day`` (inf: never written)."""
        rate = self.rate_per_s(region)
        return math.inf if rate == 0 else region.endurance_cycles / rate / (hours_per_day * 3600.0) * 86400.0 / _YEAR_S

    @property
    def limiting(self) -> MemoryWear:
        """The 24LC1025 region that wears out first (the memory's lifetime)."""
        pages = [r for r in self.regions if r.unit == "page"]
        return max(pages, key=lambda r: self.rate_per_s(r) / r.endurance_cycles)

    def years(self, hours_per_day: float) -> float:
        """The 24LC1025s' lifetime: their first page to wear out."""
        return self.lifetime_years(self.limiting, hours_per_day)

    def fits(self, years: float = LIFETIME_TARGET_YEARS) -> bool:
        """The 24LC1025s last ``years`` at 8 hours a day."""
        return self.years(LIFETIME_HOURS_PER_DAY[0]) >= years

    def lines(self) -> list[str]:
        """A printed table."""
        how = (f"measured by the model over {self.duration_s:,.0f} s of continuous logging" if self.measured
               else "computed from the design")
        h8, h24 = LIFETIME_HOURS_PER_DAY
        device = f"the logger, header version {self.header_version}; " if self.header_version else ""
        out = [f"memory endurance ({device}{how}; years of logging {h8:g} h / {h24:g} h a day)"]
        for r in self.regions:
            y8, y24 = self.lifetime_years(r, h8), self.lifetime_years(r, h24)
            where = f"worst {r.unit} {r.worst_unit:4d}, {r.worst_cycles:5,.0f} cycles" if self.measured else ""
            out.append(f"  {r.name:<16s} {where:<32s} {self.rate_per_s(r):9.6f}/s  {y8:10,.1f} y {y24:10,.1f} y"
                       f"   ({r.source})")
        out.append(f"  24LC1025 lifetime: {self.years(h8):,.1f} years at {h8:g} h a day, {self.years(h24):,.1f} at "
                   f"{h24:g} h (the {self.limiting.name}); {'fits' if self.fits() else 'DOES NOT FIT'} "
                   f"{LIFETIME_TARGET_YEARS:g} years")
        for r in self.regions:
            if r.unit != "page" and self.runs and r.worst_cycles:
                per_run = r.worst_cycles / self.runs
                out.append(f"  {r.name}: {per_run:g} cycles a run (a START and a STOP) on its worst byte, "
                           f"{r.endurance_cycles / per_run:,.0f} runs ({r.endurance_cycles / per_run / 3652.5:.1f} a "
                           "day for 10 years); the years above assume a run per measurement")
            if r.unit != "page" and self.lifetime_years(r, h8) < LIFETIME_TARGET_YEARS:
                out.append(f"  note: the {r.name}'s byte {r.worst_unit} ({r.source}) lasts "
                           f"{self.lifetime_years(r, h8):.2f} years at {h8:g} h a day ({r.endurance_cycles:,d} "
                           "cycles), short of the target; not in the 24LC1025 verdict")
        return out


def _step_rings(step: list[int], journal_ring: bool) -> tuple[MemoryWear, ...]:
    """The step EEPROM's block 0: the step ring, and with header version 3 the journal ring behind it."""
    first = SCRATCH_FIRST_BYTE // PAGE_BYTES
    if not journal_ring:
        return (MemoryWear("step ring", "page", tuple(step[:first]), 0, ENDURANCE_CYCLES,
                           "step EEPROM block 0: 20-byte records as they come"),)
    ring = RING_FIRST_BYTE // PAGE_BYTES
    return (MemoryWear("step ring", "page", tuple(step[:ring]), 0, ENDURANCE_CYCLES,
                       f"step EEPROM block 0: {STEP_CAPACITY_RECORDS_V3} 20-byte records as they come"),
            MemoryWear("journal ring", "page", tuple(step[ring:first]), ring, ENDURANCE_CYCLES,
                       f"step EEPROM end of block 0: an entry every {COMMIT_PAGES} page commits"))


def endurance_budget(config: LoggerConfig, *, duration_s: float | None = None, bank_wear=None, step_wear=None,
                     data_wear=None, flush_samples: int = 0, journal_ring: bool = False,
                     scratch_tail_writes: int = 0) -> EnduranceBudget:
    """The lifetime of the logger's memories: measured (the wear counters of a run of ``duration_s``: the
    sample bank's pages, the step EEPROM's, the data EEPROM's bytes; ``journal_ring``: the logger has header
    version 3, the default, whose journal is in the step EEPROM; False: version 2; ``scratch_tail_writes``:
    the scratch ring's tail writes among the step EEPROM's counts, for the label) or, without them, computed
    from the design (the sample pages written in turn; the scratch ring at ``flush_samples``, 0: no on-line
    algorithm: its flushes only)."""
    if bank_wear is not None:
        step = [int(x) for x in step_wear]
        first = SCRATCH_FIRST_BYTE // PAGE_BYTES
        regions = (
            MemoryWear("sample memory", "page", tuple(int(x) for x in bank_wear), 0, ENDURANCE_CYCLES,
                       "2 x 24LC1025, 128-byte pages written in turn"),
            *_step_rings(step, journal_ring),
            MemoryWear("scratch ring", "page", tuple(step[first:first + SCRATCH_PAGES]), first, ENDURANCE_CYCLES,
                       f"step EEPROM block 1: a_v, one page write every {flush_samples} samples and "
                       f"{scratch_tail_writes} tail writes"),
            MemoryWear("header slots", "page", tuple(step[first + SCRATCH_PAGES:]), first + SCRATCH_PAGES,
                       ENDURANCE_CYCLES, "step EEPROM, end of block 1: header commits"),
            MemoryWear("PIC data EEPROM", "byte", tuple(int(x) for x in data_wear), 0, DATA_EEPROM_ENDURANCE_CYCLES,
                       "header commits: START and STOP" if journal_ring else "header and page-commit journal"),
        )
        return EnduranceBudget(config, float(duration_s), regions, True, 1 if journal_ring else 0,
                               3 if journal_ring else 2)
    duration = 1.0
    pages = 2 * DEVICE_BYTES // PAGE_BYTES
    sample = config.bytes_per_sample * config.sampling_rate_hz / PAGE_BYTES / pages
    regions = [MemoryWear("sample memory", "page", (sample,), 0, ENDURANCE_CYCLES,
                          "2 x 24LC1025, 128-byte pages written in turn")]
    if flush_samples:
        regions.append(MemoryWear("scratch ring", "page", (scratch_page_writes_per_s(config.sampling_rate_hz,
                                                                                     flush_samples),),
                                  SCRATCH_FIRST_BYTE // PAGE_BYTES, ENDURANCE_CYCLES,
                                  f"a page write every {flush_samples} samples over {SCRATCH_PAGES} pages; "
                                  "its tail writes not counted"))
    return EnduranceBudget(config, duration, tuple(regions), False)
