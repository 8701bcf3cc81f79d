"""The logger's per-sample firmware path in PIC16 assembly, run in gpsim on a recording's codes.

``logger.asm`` (RAM map ``logger_ram.inc``) is the sampling interrupt (CCP1 compare on Timer1 at the
sampling rate, three ADC channels with their acquisition time, P32 packing into the 128-byte page buffer,
the page handoff) and the main loop's steps 1-5 of the on-line algorithm (``kernel.py``: calibration,
gravity, a_v; ``steps.asm``: the delay line and the 3 Hz FIR y3, the foot-flat detector and its calls of
``finalise``). :class:`PicLogger` runs it in gpsim without stopping per sample:

* **The ADC is driven by gpsim's analog stimuli**: each code ``c`` is the voltage ``c · 5 V / 1023`` on
  AN0-AN2 (gpsim converts ``round(1023 V / VDD)``, so the voltage at the code's centre gives the code
  exactly), set half a period before the sample's conversion and held for one period; the marker button is
  a pulse on RB0/INT before the sample it marks. The firmware converts as on the chip: no code table, no
  injection, and a whole logging run (up to an S flag) is one gpsim run, from START, of any length.
  The configuration (calibration, FIR weights) is in the data EEPROM, as the host writes it
  (``config.inc``); the test build (``TEST_BUILD``) adds only a sample count after which the timer stops and
  the main loop ends at ``harness_done``. Logging runs (S flags) run in parallel.
* **Outputs** come from gpsim's register-write log (``log w``), stamped with its cycle counter: the 128
  page-buffer bytes (the packed words), the stage outputs and state (``FX..FZ``, ``G1``, ``G2``, ``AV``,
  ``Y3`` and the detector's bank-1 state, snapshot at the main loop's ``DECF PENDING`` that ends each
  sample), ``finalise``'s call record (taken at each write of ``CALL_FLAGS``), ``W_TEMP`` (the interrupt's
  entry and exit), ``ADCON0`` (channel select and GO: the acquisition time) and ``B0``, ``FZ_H``,
  ``AV_H``, ``M_L`` (where the stages begin and end). Nothing stops the simulation before ``harness_done``.
* **Cycles**: the interrupt from its vector to RETFIE is measured on the production build over
  :data:`ISR_PROBE_SAMPLES` samples at every page position; the stages per sample in the test build (the
  same code), less any interrupt that fell inside them.

:func:`verify` compares with the Python model: :func:`gaitlog.protocol.packing.pack_words` for the words,
the probes of :mod:`gaitlog.firmware_sim.algorithms.probe` for steps 1-3 and, through
:func:`~gaitlog.firmware_sim.algorithms.probe.detector_trace` (the kernel itself, one sample at a time), y3,
the detector's state after every sample and every call of ``finalise``.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.formats import ACC_Q, F_ACC
from gaitlog.firmware_sim.algorithms.parameters import FRACTION_SCALE, EventParameters, OnlineParameters, SampleCounts
from gaitlog.firmware_sim.algorithms.probe import (
    DETECTOR_FIELDS,
    CALL_FIELDS,
    calibrated_axes,
    detector_trace,
    gravity_states,
    step_records,
    online_config,
    vertical_acceleration,
)
from gaitlog.firmware_sim.algorithms.state import INDEX_MODULUS
from gaitlog.firmware_sim.budget import ADC_CONVERSION_TAD, PIC_RAM_BYTES, adc_acquisition_s, adc_tad_s
from gaitlog.firmware_sim.fixedpoint import DEFAULT_FOSC_HZ, cycles_per_sample_available
from gaitlog.firmware_sim.pic.gpsim_bench import PIC_DIR, copy_sources, gpsim_version, missing_tools
from gaitlog.firmware_sim.pic.ram_map import FIRMWARE_GROUPS, ram_map
from gaitlog.firmware_sim.pic.step_config import config_bytes
from gaitlog.protocol.packing import FLAG_MARK, FLAG_SESSION_START, pack_words, words_to_bytes
from gaitlog.protocol.steps import STEP_RECORD_DTYPE

__all__ = ["LOGGER_ASM", "TimerSetup", "timer_setup", "acquisition_loops", "LoggerRun",
           "PicLogger", "HeaderRun", "MemoryMap", "memory_map", "StageComparison", "PicVerification", "verify",
           "run_starts", "missing_tools", "LeanRun", "scratch_offset", "BENCH_RING_SAMPLES", "RecordsRun",
           "period_setup", "RecordsVerification", "verify_records", "bus_page_writes", "bus_reads", "BusRun"]

#: The firmware source.
LOGGER_ASM = PIC_DIR / "logger.asm"
#: The ADC's full scale (VDD, ADCON1 = 0x82: Vref = VDD/VSS) in gpsim, volts.
VDD_V = 5.0
#: gpsim's 10-bit conversion: ``round(ADC_STEPS · V / VDD)``.
ADC_STEPS = 1023
#: Cycles the marker button's pulse on RB0 stays high.
MARK_PULSE_CYCLES = 1000
#: Samples of the production build's run that measures the interrupt (two pages: every page position).
ISR_PROBE_SAMPLES = 64
#: Cycles of the interrupt after its exit stamp (the write of ``SWAPF W_TEMP, F``): that SWAPF, ``SWAPF
#: W_TEMP, W`` and RETFIE (2).
ISR_TAIL_CYCLES = 4
#: gpsim's ADCON0, the kernels' W_TEMP (common RAM) and the page buffer's two halves.
ADCON0_ADDR, W_TEMP_ADDR = 0x1F, 0x7F
#: Ring samples that gpsim's 24xx256 (32 KiB, the address's bit 15 ignored) keeps apart: ring samples ``p`` and
#: ``p + 16,384`` of the assembly's ring (:data:`~gaitlog.firmware_sim.algorithms.kernel.SCRATCH_RING_SAMPLES`,
#: 32,512) share a byte there, so the bench stands in for the 24LC1025's block while no sample a step reads is
#: 16,128 or more samples older than the newest written (a step reads a few hundred back).
BENCH_RING_SAMPLES = 0x4000
#: PCLATH: the interrupt writes it twice in bank 0 (cleared at entry, restored at exit)
PCLATH_ADDR = 0x0A
#: The interrupt as the test build's log shows it: its first bank-0 write (STATUS_TEMP) comes this many cycles
#: after the vector, its exit's PCLATH write this many before the exit's W_TEMP write. gpsim logs W_TEMP only
#: when it is written at 0x7F, i.e. when the interrupt came in bank 0, and the step record runs in banks 2-3.
ISR_ENTRY_CYCLES, ISR_EXIT_CYCLES = 3, 3
PAGE_ADDRS = tuple(range(0x110, 0x150)) + tuple(range(0x190, 0x1D0))
#: P32 words in the page buffer: the most samples the main loop may fall behind
PAGE_WORDS = len(PAGE_ADDRS) // 4
#: Timer1 prescaler settings (T1CKPS bits in T1CON, TMR1ON set).
_PRESCALERS = ((1, 0x01), (2, 0x11), (4, 0x21), (8, 0x31))

class PicError(RuntimeError):
    """gpasm or gpsim failed, or their output is not what the harness expects."""


@dataclass(frozen=True)
class TimerSetup:
    """Timer1 and CCP1 for one sampling rate: CCPR1 counts of ``prescale`` cycles per sample."""

    prescale: int
    ccpr1: int
    t1con: int

    @property
    def period_cycles(self) -> int:
        """Instruction cycles per sample period."""
        return self.prescale * self.ccpr1


def timer_setup(sampling_rate_hz: float, fosc_hz: float = DEFAULT_FOSC_HZ) -> TimerSetup:
    """The smallest Timer1 prescaler whose CCPR1 holds the period (an exact number of cycles).

    >>> timer_setup(50.0)
    TimerSetup(prescale=2, ccpr1=46080, t1con=17)
    """
    cycles = cycles_per_sample_available(sampling_rate_hz, fosc_hz)
    if abs(cycles - round(cycles)) > 1e-6:
        raise ValueError(f"{sampling_rate_hz:g} Hz is not a whole number of cycles at {fosc_hz / 1e6:g} MHz "
                         f"({cycles:.3f})")
    for prescale, bits in _PRESCALERS:
        if round(cycles) % prescale == 0 and round(cycles) // prescale <= 0xFFFF:
            return TimerSetup(prescale, round(cycles) // prescale, bits)
    raise ValueError(f"{sampling_rate_hz:g} Hz: {round(cycles)} cycles per sample do not fit Timer1 and CCPR1")


def acquisition_loops(fosc_hz: float = DEFAULT_FOSC_HZ, source_impedance_ohm: float = 32e3) -> int:
    """Loops of ``adc_convert``'s 3-cycle delay: the channel's acquisition time plus the 2 TAD the
    converter needs after the previous conversion, from ``MOVWF ADCON0`` to ``BSF ADCON0, GO`` (3 n + 1
    cycles).

    >>> acquisition_loops()
    67
    """
    need = (adc_acquisition_s(source_impedance_ohm) + 2 * adc_tad_s(fosc_hz)) * fosc_hz / 4.0
    return max(1, math.ceil((need - 1) / 3))


# ---------------------------------------------------------------------------------------------------
# building


def _symbols(lst: Path) -> dict[str, int]:
    """gpasm's symbol table (name -> value) from a listing."""
    return {m.group(1): int(m.group(2), 16)
            for m in re.finditer(r"^([A-Za-z_][A-Za-z_0-9]*)\s+([0-9A-Fa-f]{8})\s*$", lst.read_text(errors="replace"),
                                 re.M)}


def _hex(v: int) -> str:
    return f"0x{v:X}"                     # gpasm's default radix is hexadecimal: always say so


def _calibration_bytes(cal: CalibrationQ) -> list[int]:
    shift = cal.matrix_frac_bits + 5 - F_ACC
    if cal.adc_bits != 10:
        raise ValueError(f"the PIC's converter has 10 bits; this calibration is for {cal.adc_bits}-bit codes")
    if not 1 <= shift <= 31:
        raise ValueError(f"the calibration's rounding shift {shift} is outside the shr32r kernel's 1..31")
    words = [int(v) for v in cal.offset_raw] + [int(v) for v in np.asarray(cal.mantissa_raw).reshape(9)]
    out = []
    for w in words:
        out += [w & 0xFF, (w >> 8) & 0xFF]
    return out + [shift]


def _config_bytes(cal_bytes: list[int], weights: np.ndarray) -> list[int]:
    """The data EEPROM's configuration (logger_ram.inc's EE_CAL, EE_W3): the calibration, then the 3 Hz
    half-kernel (Q1.14 int16, little-endian)."""
    out = list(cal_bytes)
    for w in np.asarray(weights, np.int64).tolist():
        if not -32768 <= w <= 32767:
            raise ValueError(f"a FIR weight {w} does not fit its 16-bit word")
        out += [w & 0xFF, (w >> 8) & 0xFF]
    if len(out) > 256:
        raise ValueError(f"the configuration takes {len(out)} bytes, more than the 256 of the data EEPROM")
    return out


def _stimuli(codes: np.ndarray, flags: np.ndarray, period_cycles: int) -> str:
    """gpsim commands that drive AN0-AN2 with the codes and press the marker button (RB0) where ``flags`` has
    M: sample ``k``'s voltages hold from cycle ``(k + 1/2) P`` to ``(k + 3/2) P``, around its conversion
    near ``(k + 1) P`` (checked against the log by :func:`_check_conversions`). Each stimulus' points are on one
    line: gpsim parses points written one a line in a time quadratic in their number, on one line in a linear
    time (16,000 points: 3.4 s of CPU against 0.2 s, measured)."""
    at = ((np.arange(codes.shape[0]) + 0.5) * period_cycles).astype(np.int64)
    out = []
    for ch in range(3):
        pts = ", ".join(f"{t}, {c * VDD_V / ADC_STEPS:.12g}" for t, c in zip(at.tolist(), codes[:, ch].tolist()))
        out.append(f"stimulus asynchronous_stimulus\ninitial_state 0\nstart_cycle 0\nanalog\n{{ {pts} }}\n"
                   f"name an{ch}\nend\nnode n_an{ch}\nattach n_an{ch} an{ch} porta{ch}")
    marks = at[(np.asarray(flags) & FLAG_MARK) != 0]
    if marks.size:
        pts = ", ".join(f"{t}, 1, {t + MARK_PULSE_CYCLES}, 0" for t in marks.tolist())
        out.append(f"stimulus asynchronous_stimulus\ninitial_state 0\nstart_cycle 0\ndigital\n{{ {pts} }}\n"
                   f"name mark\nend\nnode n_mark\nattach n_mark mark portb0")
    return "\n".join(out) + "\n"


def _check_conversions(t_go: np.ndarray, n: int, period_cycles: int) -> None:
    """Each sample's three conversions (``GO``) fall inside the period its stimulus holds."""
    if t_go.size != 3 * n:
        raise PicError(f"gpsim converted {t_go.size} times for {n} samples (3 each)")
    k = np.repeat(np.arange(n), 3)
    bad = (t_go <= (k + 0.5) * period_cycles) | (t_go >= (k + 1.5) * period_cycles)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise PicError(f"sample {i // 3}'s conversion at cycle {int(t_go[i])} is outside its stimulus' period")


def _page_fsr(sample_number: int) -> int:
    w = sample_number % 32
    return 0x10 + 4 * w if w < 16 else 0x90 + 4 * (w - 16)


@dataclass(frozen=True)
class _Build:
    cod: Path
    symbols: dict[str, int]


def _assemble(build_dir: Path, defines: dict[str, int], *, test: bool) -> _Build:
    if test and not 0 < defines.get("N_SAMPLES", 1) < INDEX_MODULUS:
        raise ValueError(f"the test build stops on the 16-bit sample count: N_SAMPLES must be 1 .. {INDEX_MODULUS - 1}")
    build_dir.mkdir(parents=True, exist_ok=True)
    copy_sources(build_dir, LOGGER_ASM)
    args = ["gpasm", "-p", "p16f877", "-o", "logger.hex"]
    for k, v in defines.items():
        args += ["-D", f"{k}={_hex(v)}"]
    if test:
        args += ["-D", "TEST_BUILD"]
    proc = subprocess.run([*args, "logger.asm"], capture_output=True, text=True, timeout=120, cwd=build_dir)
    cod = build_dir / "logger.cod"
    if proc.returncode != 0 or not cod.exists():
        errors = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "Error" in ln] or [proc.stderr.strip()]
        raise PicError(f"gpasm failed on {LOGGER_ASM}: {errors[0][-300:]}")
    return _Build(cod, _symbols(build_dir / "logger.lst"))


# ---------------------------------------------------------------------------------------------------
# running


#: gpsim's ``log w`` lines: an instruction's line starts ``0x`` and its cycle counter in 16 hex digits; each of its
#: writes follows as ``  Wrote: 0xVVVV to NAME(0xAAAA) was 0xOOOO`` (value at a fixed column, address at a fixed
#: distance from the line's end). Source and ``Read:`` lines come between.
_CYCLE_DIGITS = 16
_WROTE = b"  Wrote: 0x"
_WROTE_TAIL = len("(0xAAAA) was 0xOOOO")
_HEX = np.full(256, -1, np.int64)
_HEX[np.frombuffer(b"0123456789abcdef", np.uint8)] = np.arange(16)
_HEX[np.frombuffer(b"ABCDEF", np.uint8)] = np.arange(10, 16)


def _hex_at(buf: np.ndarray, at: np.ndarray, digits: int) -> np.ndarray:
    """The ``digits`` hex digits of ``buf`` from each position in ``at``, as int64 (-1 where one is not hex)."""
    d = _HEX[buf[at[:, None] + np.arange(digits)]]
    v = np.zeros(at.size, np.int64)
    for j in range(digits):
        v = (v << 4) | d[:, j]
    return np.where((d < 0).any(axis=1), -1, v)


def _writes(log_text: str | bytes, wanted: set[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cycle, address, value) of every logged write to an address in ``wanted``, parsed in numpy (a recording's
    log has millions of lines)."""
    raw = log_text.encode() if isinstance(log_text, str) else log_text
    buf = np.frombuffer(raw + b"\n" + b" " * 32, np.uint8)        # padding: fixed-column reads stay inside
    ends = np.flatnonzero(buf[:len(raw) + 1] == ord("\n"))
    starts = np.concatenate([[0], ends[:-1] + 1])
    length = ends - starts
    is_cycle = (length > 2 + _CYCLE_DIGITS) & (buf[starts] == ord("0")) & (buf[starts + 1] == ord("x"))
    is_cycle &= buf[starts + 2 + _CYCLE_DIGITS] == ord(" ")
    is_write = length > len(_WROTE) + _WROTE_TAIL
    for j, ch in enumerate(_WROTE):
        is_write &= buf[starts + j] == ch
    is_write &= buf[np.maximum(ends - _WROTE_TAIL, 0)] == ord("(")
    cycle_of_line = np.concatenate([[0], _hex_at(buf, starts[is_cycle] + 2, _CYCLE_DIGITS)])[np.cumsum(is_cycle)]
    w = np.flatnonzero(is_write)
    addr = _hex_at(buf, ends[w] - _WROTE_TAIL + 3, 4)
    val = _hex_at(buf, starts[w] + len(_WROTE), 4)
    cyc = cycle_of_line[w]
    if (addr < 0).any() or (val < 0).any() or (cyc < 0).any():
        raise PicError("gpsim's write log has a line the harness cannot read")
    keep = np.isin(addr, np.fromiter(wanted, np.int64, len(wanted)))
    cyc, addr, val = cyc[keep], addr[keep], val[keep]
    repeat = np.zeros(cyc.size, bool)                # BSF ADCON0, GO is logged twice
    repeat[1:] = (cyc[1:] == cyc[:-1]) & (addr[1:] == addr[:-1])
    return cyc[~repeat], addr[~repeat], val[~repeat]


def _gpsim(build: _Build, addrs: list[int], stop: str, timeout_s: float, stimuli: str = "",
           bus: tuple[str, ...] | None = None) -> bytes:
    """Run ``build`` in gpsim (``stimuli``: commands that attach stimuli), logging writes to ``addrs``, until
    ``stop`` (``e LABEL`` or ``c CYCLES``). The scratch ring's EEPROM is on the I2C bus in every run (the
    firmware's page writes wait for its acknowledge; ``bus``: other gpsim commands that set up the bus)."""
    with tempfile.TemporaryDirectory(prefix="gpsim-logger-") as tmp:
        log = Path(tmp) / "writes.log"
        lines = [*(I2C_SETUP if bus is None else bus), *([stimuli] if stimuli else []), *([f"log on {log}"] if addrs else []), *(f"log w {a}" for a in addrs), f"break {stop}", "run",
                 "quit"]
        (Path(tmp) / "run.stc").write_text("\n".join(lines) + "\n")
        proc = subprocess.run(["gpsim", "-i", "-s", str(build.cod), "-c", str(Path(tmp) / "run.stc")],
                              capture_output=True, text=True, timeout=timeout_s, cwd=tmp)
        bad = ("***ERROR", "cannot be set", "stack overflow", "stack underflow")
        if proc.returncode != 0 or any(b in proc.stdout.lower() or b in proc.stdout for b in bad):
            err = next((ln for ln in proc.stdout.splitlines() if any(b in ln.lower() or b in ln for b in bad)),
                       proc.stderr.strip()[-300:])
            raise PicError(f"gpsim failed on {build.cod.name} (exit {proc.returncode}): {err}")
        if "Hit a Breakpoint" not in proc.stdout and "cycle break" not in proc.stdout:
            raise PicError(f"gpsim stopped before {stop!r}: {proc.stdout.strip()[-300:]}")
        return log.read_bytes() if log.exists() else b""


def scratch_offset(run_start_sample: int, f: int) -> int:
    """The assembly's ring offset ``SCR_K`` (logger_ram.inc) once the run's sample ``f`` (counted from START) is
    written: the 16-bit index ``j`` of a sample is at ring sample ``K + j``, plus the ring's length when that
    is negative (:func:`~gaitlog.firmware_sim.algorithms.kernel.scratch_ring_sample`, the model's placement).

    >>> scratch_offset(0, 0), scratch_offset(64 * 507, 0), scratch_offset(64 * 507, 64), scratch_offset(0, 65536)
    (0, 32448, 65472, 512)
    """
    return (kernel.scratch_ring_sample(run_start_sample, f) - int(f)) & 0xFFFF


def _lean_log(addr: np.ndarray, val: np.ndarray, n: int, sym: dict[str, int]
              ) -> tuple[np.ndarray, np.ndarray, dict[int, int], int]:
    """One pass over a lean write log (``PENDING``, the call record, ``REC``, ``LAST``'s high byte and whatever
    else was logged): the calls (as :attr:`LoggerRun.calls`), the step records (taken when the step record
    writes ``LAST``'s high byte after a call), the logged RAM at the end (address -> byte) and the largest
    backlog (``PENDING``). A sample ends where the main loop decrements ``PENDING``; the interrupt's first
    increment starts the run (START's clearing of the call record is not a call). STOP's call, after the last
    sample, has the run's end as its sample (``n``), as :func:`_replay_log` counts it."""
    rec, step_rec, last_h = [(sym[k], b) for k, b in _RECORD], sym["REC"], sym["LAST"] + 1
    ram: dict[int, int] = {}
    pending = done = backlog = 0
    started = due = False
    calls, records = [], []
    for a, v in zip(addr.tolist(), val.tolist()):
        if a == sym["PENDING"]:
            started |= v == (pending + 1) & 0xFF
            done += v == (pending - 1) & 0xFF
            pending, backlog = v, max(backlog, v)
            continue
        ram[a] = v
        if a == sym["CALL_FLAGS"] and started:
            calls.append([done] + [sum(ram.get(s + i, 0) << (8 * i) for i in range(b)) for s, b in rec])
            due = True
        elif a == last_h and due:                # the step record's end: LAST = e
            records.append([ram.get(step_rec + i, 0) for i in range(STEP_RECORD_BYTES)])
            due = False
    if done != n:
        raise PicError(f"gpsim's main loop finished {done} samples of {n}")
    return (np.asarray(calls, np.int64).reshape(-1, 1 + len(_RECORD)),
            np.asarray(records, np.uint8).reshape(-1, STEP_RECORD_BYTES), ram, backlog)


class HeaderRun(NamedTuple):
    """:meth:`PicLogger.run_header`: the samples the main loop processed and the header counters after the run
    (logger_ram.inc): ``samples_written`` (2^32 - 1 once saturated), ``write_index`` (its low 16 bits),
    ``steps_written`` and the run's mode (``overwrite``); a run stopped when full processed fewer samples."""

    samples_processed: int
    samples_written: int
    write_index: int
    steps_written: int
    overwrite: bool


class LeanRun(NamedTuple):
    """:meth:`PicLogger.run_calls`: ``finalise``'s calls, the detector's state after the last sample, and the
    step records (``(k, 20)`` bytes)."""

    calls: np.ndarray
    state: np.ndarray
    records: np.ndarray


#: The data-EEPROM address of the step configuration (logger_ram.inc STEP_CFG_EE).
STEP_CFG_EE = 0x30
#: gpsim's I2C bus: the scratch ring's EEPROM (e24xx256) on RC3 (SCL) and RC4 (SDA), 10 kOhm pull-ups, as the
#: step record's bench has it (gpsim_steps). Its A2 pin is pulled high, so that it answers the control byte
#: 0xA8 (1010 A2 A1 A0 R/W), the logger's 24LC1025 second block (1010 B0 A1 A0 R/W, step_record.asm SCR_CONTROL).
I2C_SETUP = ("module library libgpsim_modules.so", "module load e24xx256 ee", "module load pullup Rscl",
             "module load pullup Rsda", "Rscl.resistance = 10000.", "Rsda.resistance = 10000.", "node scl",
             "node sda", "attach scl portc3 ee.SCL Rscl.pin", "attach sda portc4 ee.SDA Rsda.pin",
             "module load pullup Ra2", "Ra2.resistance = 10000.", "node a2", "attach a2 ee.A2 Ra2.pin")

#: RAM the harness snapshots after each sample (bank-0 symbols, bytes): stage outputs and state.
_SNAPSHOT = (("FX_L", 2), ("FY_L", 2), ("FZ_L", 2), *((f"G{s}{a}", 4) for s in "12" for a in "XYZ"), ("AV_L", 2),
             ("Y3_0", 3))
#: The detector's state (bank 1), in :data:`~gaitlog.firmware_sim.algorithms.probe.DETECTOR_FIELDS` order:
#: (symbol, bytes, signed); the durations ring follows.
_DETECTOR = (("MN", 3, True), ("MX", 3, True), ("MXPOS", 2, False), ("PEND", 2, False), ("PEND_Y", 3, True),
             ("LAST", 2, False), ("RAW", 2, False), ("RAW_Y", 3, True), ("AMP", 3, True), ("DIST", 1, False),
             ("N_DUR", 1, False), ("DUR_POS", 1, False), ("AFLAGS", 1, False), ("N_L", 2, False),
             ("LINE_POS", 1, False))
#: finalise's call record: (symbol, bytes), after the sample index.
_RECORD = (("CALL_E", 2), ("CALL_S", 2), ("CALL_M", 2), ("CALL_FLAGS", 1))
#: Bytes of the step record (step_record.asm ``REC``), taken when finalise has written ``LAST``'s high byte.
STEP_RECORD_BYTES = 20
#: Stages timed per sample, and the write that ends each (``M_L``: written only once the filter has an output).
STAGES = ("step 1 (calibration)", "steps 2-3 (gravity, a_v)", "step 4 (delay line, 3 Hz FIR)",
          "step 5 (foot-flat detector)")


@dataclass(frozen=True)
class LoggerRun:
    """The assembly on ``n`` samples in gpsim (the test build), and the interrupt measured on the production build.

    Attributes
    ----------
    packed
        ``(n, 4)`` uint8: the bytes the interrupt wrote into the page buffer per sample (a P32 word, LE).
    calibrated
        ``(n, 3)`` int64: stage 1's calibrated axes, raw Q2.13 g (``FX``, ``FY``, ``FZ``).
    gravity
        ``(n, 6)`` int64: stage 2's state after the sample, raw Q2.29 (``G1X..G1Z``, ``G2X..G2Z``).
    a_v
        ``(n,)`` int64: stage 3's vertical acceleration, raw Q2.13 g (``AV``).
    y3, ready
        ``(n,)`` int64 step 4's 3 Hz FIR output (raw Q2.16, ``Y3``) and bool: whether the sample had one.
    detector
        ``(n, len(DETECTOR_FIELDS))`` int64: step 5's state after the sample (indices unsigned 16-bit).
    calls
        ``(k, len(CALL_FIELDS))`` int64: each call of ``finalise``: the sample, e, s, m, flags.
    isr_cycles
        ``(n,)`` the interrupt, vector to RETFIE, as the production build takes it at this sample's page position.
    stage_cycles
        ``(n, 4)`` the :data:`STAGES`, less any interrupt inside them.
    acquisition_cycles_min
        The shortest channel select to GO seen (the acquisition time the ADC got).
    period_cycles
        Measured cycles between two interrupts (the production build; all equal).
    simulated_cycles, gpsim_s, wall_s
        Cycles gpsim simulated, the wall time of the gpsim runs (sum over runs), the whole run's wall time.
    """

    packed: np.ndarray
    calibrated: np.ndarray
    gravity: np.ndarray
    a_v: np.ndarray
    y3: np.ndarray
    ready: np.ndarray
    detector: np.ndarray
    calls: np.ndarray
    isr_cycles: np.ndarray
    stage_cycles: np.ndarray
    acquisition_cycles_min: int
    period_cycles: int
    simulated_cycles: int
    gpsim_s: float
    wall_s: float
    records: np.ndarray = field(default_factory=lambda: np.zeros((0, STEP_RECORD_BYTES), np.uint8))
    backlog_max: int = 0
    #: per run whose STOP finalised a step: cycles from its last sample's end (``DECF PENDING``) to the STOP
    #: record's end (``LAST`` written), the scratch ring's partial block included
    stop_cycles: tuple[int, ...] = ()


@dataclass(frozen=True)
class _RunOut:
    packed: np.ndarray
    ram: dict              # name -> (n,) int64 snapshot values
    ready: np.ndarray
    calls: np.ndarray
    stage_cycles: np.ndarray
    acquisition_cycles_min: int
    simulated_cycles: int
    gpsim_s: float
    records: np.ndarray
    backlog_max: int
    stop_cycles: int = 0          # 0: STOP finalised nothing


def _int(b: np.ndarray, signed: bool = True) -> np.ndarray:
    v = np.zeros(b.shape[0], np.int64)
    for i in range(b.shape[1]):
        v |= b[:, i].astype(np.int64) << (8 * i)
    bits = 8 * b.shape[1]
    return np.where(v >= 1 << (bits - 1), v - (1 << bits), v) if signed else v


def _packed(addr: np.ndarray, val: np.ndarray, n: int, first_sample: int) -> np.ndarray:
    page = np.isin(addr, PAGE_ADDRS)
    if page.sum() != 4 * n:
        raise PicError(f"gpsim wrote {int(page.sum())} page-buffer bytes for {n} samples")
    expect = np.asarray([_page_fsr(first_sample + i) for i in range(n)]) + 0x100
    if not np.array_equal(addr[page][0::4], expect):
        raise PicError("the page buffer was written out of order")
    return val[page].reshape(-1, 4).astype(np.uint8)


@dataclass
class _Replay:
    """The state of one pass over the log (see :func:`_replay_log`)."""

    ram: dict
    in_isr: bool = False
    isr_t: int = 0
    isr_sum: int = 0
    marks: list = field(default_factory=list)


def _replay_log(cyc, addr, val, n, sym, ram0):
    """One pass over the log: the RAM bytes after each sample (snapshots at the main loop's ``DECF PENDING``,
    outside the interrupt), whether the sample reached step 5, each call record, each sample's stage cycles."""
    r = _Replay(dict(ram0))
    snap_addrs = sorted(r.ram)
    bounds = [sym["B0"], sym["FZ_H"], sym["AV_H"], sym["M_L"]]
    snaps, stages, ready, calls = [], [], [], []
    rec_flags, rec = sym["CALL_FLAGS"], [(sym[k], b) for k, b in _RECORD]
    step_rec, last_h, due, records = sym["REC"], sym["LAST"] + 1, False, []
    t_end = stop_cycles = 0                      # the last sample's DECF PENDING; STOP's record after it
    status_temp, pclath_seen = sym["STATUS_TEMP"], 0
    for t, a, v in zip(cyc.tolist(), addr.tolist(), val.tolist()):
        if a == status_temp:
            r.in_isr, r.isr_t, pclath_seen = True, t - ISR_ENTRY_CYCLES, 0
            continue
        if a == PCLATH_ADDR:
            pclath_seen += r.in_isr
            if r.in_isr and pclath_seen == 2:
                r.in_isr = False
                r.isr_sum += t + ISR_EXIT_CYCLES + ISR_TAIL_CYCLES - r.isr_t
            continue
        if r.in_isr:
            continue
        if a in r.ram:
            r.ram[a] = v
        if len(r.marks) < len(bounds) and a == bounds[len(r.marks)]:     # the stages' ends, in their order
            r.marks.append((t, r.isr_sum))
        if a == rec_flags and (r.marks or snaps):    # a sample's call or STOP's (not START's clearing)
            calls.append([len(snaps)] + [sum(r.ram[s + i] << (8 * i) for i in range(b)) for s, b in rec])
            due = True
        if a == last_h and due:                  # the step record's end: LAST = e
            records.append([r.ram[step_rec + i] for i in range(STEP_RECORD_BYTES)])
            due = False
            stop_cycles = t - t_end if len(snaps) == n else 0
        if a == sym["PENDING"] and r.marks:       # the sample's DECF (not the set-up's CLRF)
            snaps.append([r.ram[x] for x in snap_addrs])
            ready.append(len(r.marks) == len(bounds))
            ts = r.marks + [(t, r.isr_sum)]
            times = [((ts[i + 1][0] - ts[i][0]) - (ts[i + 1][1] - ts[i][1])) for i in range(len(ts) - 1)]
            stages.append(times + [0] * (len(STAGES) - len(times)))
            r.marks, t_end = [], t
    if len(snaps) != n:
        raise PicError(f"gpsim's main loop finished {len(snaps)} samples of {n}")
    return (np.asarray(snaps, np.int64), snap_addrs, np.asarray(ready, bool),
            np.asarray(calls, np.int64).reshape(-1, 1 + len(_RECORD)), np.asarray(stages, np.int64),
            np.asarray(records, np.uint8).reshape(-1, STEP_RECORD_BYTES), stop_cycles)


@dataclass(frozen=True)
class RecordsRun:
    """One logging run in gpsim's lean records mode (:meth:`PicLogger.run_records`).

    ``calls``: ``(k, len(CALL_FIELDS))`` as :attr:`LoggerRun.calls` (the sample from the run's first);
    ``records``: ``(k, 20)`` uint8, each record's bytes when ``finalise`` wrote ``LAST``; ``backlog_max``: the
    most samples waiting (``PENDING``); ``period_cycles``: the sampling period the run had; ``gpsim_s``: the
    gpsim process's wall time.
    """

    calls: np.ndarray
    records: np.ndarray
    backlog_max: int
    period_cycles: int
    simulated_cycles: int
    gpsim_s: float


#: The MSSP's SSPBUF (bank 0) and SSPCON2 (bank 1), and SSPCON2's start and repeated-start bits.
SSPBUF_ADDR, SSPCON2_ADDR, SSPCON2_SEN, SSPCON2_RSEN = 0x13, 0x91, 0x01, 0x02
#: The control byte of a write to the scratch ring's block (step_record.asm SCR_CONTROL, the 24LC1025's second).
SCR_CONTROL_WRITE = 0xA8


def bus_page_writes(addr: np.ndarray, val: np.ndarray) -> np.ndarray:
    """The page writes on the I2C bus in a write log of ``PENDING`` (any address but the MSSP's), ``SSPBUF`` and
    ``SSPCON2``: ``(k, 3)`` int64 rows of (samples the main loop had finished, the first byte's address, data
    bytes). A transfer runs from one start condition (``SEN`` set) to the next; a page write is one that sends
    the write control byte, two address bytes and data, with no repeated start (a read has one; the
    acknowledge polling sends the control byte alone)."""
    rows: list[list[int]] = []
    done, pending, sent, restart = 0, 0, [], False

    def close() -> None:
        if not restart and len(sent) > 3 and sent[0] == SCR_CONTROL_WRITE:
            rows.append([sent_at, (sent[1] << 8) | sent[2], len(sent) - 3])

    sent_at = 0
    for a, v in zip(addr.tolist(), val.tolist()):
        if a == SSPBUF_ADDR:
            sent.append(v)
        elif a == SSPCON2_ADDR:
            if v & SSPCON2_SEN:
                close()
                sent, restart, sent_at = [], False, done
            restart |= bool(v & SSPCON2_RSEN)
        else:
            done += v == (pending - 1) & 0xFF
            pending = v
    close()
    return np.asarray(rows, np.int64).reshape(-1, 3)


#: SSPCON2's receive-enable bit: one byte received.
SSPCON2_RCEN = 0x08


def bus_reads(addr: np.ndarray, val: np.ndarray) -> np.ndarray:
    """The random reads in the same write log as :func:`bus_page_writes`: ``(k, 3)`` int64 rows of (samples the
    main loop had finished, reads begun, i.e. repeated starts, bytes received), one row per sample with a read."""
    rows: dict[int, list[int]] = {}
    done = pending = 0
    for a, v in zip(addr.tolist(), val.tolist()):
        if a == SSPCON2_ADDR and v & (SSPCON2_RSEN | SSPCON2_RCEN):
            row = rows.setdefault(done, [done, 0, 0])
            row[1] += bool(v & SSPCON2_RSEN)
            row[2] += bool(v & SSPCON2_RCEN)
        elif a not in (SSPBUF_ADDR, SSPCON2_ADDR):
            done += v == (pending - 1) & 0xFF
            pending = v
    return np.asarray([rows[k] for k in sorted(rows)], np.int64).reshape(-1, 3)


class BusRun(NamedTuple):
    """:meth:`PicLogger.run_bus`: the page writes (:func:`bus_page_writes`) and the reads (:func:`bus_reads`)."""

    page_writes: np.ndarray
    reads: np.ndarray


def period_setup(period_cycles: int) -> TimerSetup:
    """Timer1 and CCP1 for a sampling period of ``period_cycles`` instruction cycles (the smallest prescaler
    whose CCPR1 holds it exactly).

    >>> period_setup(46_080)
    TimerSetup(prescale=1, ccpr1=46080, t1con=1)
    """
    for prescale, bits in _PRESCALERS:
        if period_cycles % prescale == 0 and period_cycles // prescale <= 0xFFFF:
            return TimerSetup(prescale, period_cycles // prescale, bits)
    raise ValueError(f"{period_cycles} cycles per sample do not fit Timer1 and CCPR1")


class PicLogger:
    """Runs ``logger.asm`` in gpsim on a recording's codes (see the module notes).

    Parameters
    ----------
    sampling_rate_hz, fosc_hz
        The timer's rate and the crystal.
    gravity_shift
        The gravity means' final shift (the kernel's ``G_SHIFT``); default: the on-line algorithm's at
        ``sampling_rate_hz`` with the default parameters (6 at 50 Hz).
    source_impedance_ohm
        The ADC source (the ADXL202's 32 kOhm output): sets the acquisition delay.
    workers
        gpsim processes at a time (one per logging run).
    overwrite, steps_written
        The header at START (logger_ram.inc's header counters): ring mode (else stop when full) and
        ``steps_written``; ``samples_written`` at START is each run's first sample number.
    """

    def __init__(self, *, sampling_rate_hz: float = 50.0, fosc_hz: float = DEFAULT_FOSC_HZ,
                 gravity_shift: int | None = None,
                 source_impedance_ohm: float = 32e3, workers: int = 2, timeout_s: float = 600.0,
                 overwrite: bool = True, steps_written: int = 0) -> None:
        self.sampling_rate_hz = sampling_rate_hz
        self.fosc_hz = fosc_hz
        self.gravity_shift = gravity_shift if gravity_shift is not None else SampleCounts.at(
            EventParameters(), OnlineParameters(), sampling_rate_hz).gravity_shift
        #: the kernel's G_MIN: the smallest ``|g|`` that gives an a_v, raw Q2.13
        self.min_gravity_raw = int(ACC_Q.from_float(OnlineParameters().min_gravity_g))
        #: the on-line algorithm's configuration at this rate (steps 4-5's constants and weights)
        self.config = online_config(sampling_rate_hz)
        self.source_impedance_ohm = source_impedance_ohm
        self.workers = workers
        self.timeout_s = timeout_s
        self.overwrite = overwrite
        self.steps_written = steps_written

    def _write_config(self, build_dir: Path, cal_bytes: list[int]) -> None:
        """The data EEPROM's configuration (the calibration's bytes, FIR weights, step configuration) as
        ``config.inc`` in ``build_dir``."""
        (build_dir / "config.inc").write_text("".join(f"        de      0x{b:02X}\n" for b in self._eeprom(cal_bytes)))

    def _defines(self, first_sample: int) -> dict[str, int]:
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        ci, cv = self.config.cfg_i, self.config.cfg_v
        steps = {k: int(ci[kernel.CI[k]]) for k in ("R3", "N_MED", "MIN_STEP", "MAX_STEP", "FRACTION", "AMP_SHIFT",
                                                     "PRIOR_TWICE", "FLUSH")}
        steps.update({k: int(cv[kernel.CV[k]]) for k in ("DELTA", "CAP", "FRAC", "STOP")})
        steps["SCR_AHEAD_E"], steps["SCR_AHEAD_S"] = kernel.scratch_reads_ahead(ci)
        if not (steps["MAX_STEP"] < 256 and steps["FRACTION"] <= FRACTION_SCALE and steps["FLUSH"] <= 128
                and min(steps["DELTA"], steps["CAP"], steps["STOP"], steps["FRAC"]) >= 0):
            raise ValueError(f"the assembly's steps 4-5 need MAX_STEP < 256, FRACTION <= {FRACTION_SCALE}, "
                             f"FLUSH <= 128 and non-negative thresholds: {steps}")
        return dict(CCP_PERIOD=t.ccpr1, T1_SETUP=t.t1con,
                    ACQ_LOOPS=acquisition_loops(self.fosc_hz, self.source_impedance_ohm),
                    FIRST_SAMPLE_L=first_sample & 0xFF, FIRST_SAMPLE_H=(first_sample >> 8) & 0xFF,
                    FIRST_SAMPLE_U=(first_sample >> 16) & 0xFF, FIRST_SAMPLE_T=(first_sample >> 24) & 0xFF,
                    OVERWRITE=int(self.overwrite), STEPS_WRITTEN=self.steps_written,
                    PAGE_START=_page_fsr(first_sample), G_SHIFT=self.gravity_shift,
                    SCR_SAMPLES=kernel.SCRATCH_RING_SAMPLES, SCR_K0=scratch_offset(first_sample, 0),
                    G_MIN=self.min_gravity_raw, **steps)

    def _eeprom(self, cal_bytes: list[int]) -> list[int]:
        """The data EEPROM: the calibration and the 3 Hz half-kernel (logger_ram.inc EE_*), then the step
        configuration at STEP_CFG_EE (step_record_ram.inc CFG_*, :func:`gpsim_steps.config_bytes`)."""
        head = _config_bytes(cal_bytes, self._weights())
        if len(head) > STEP_CFG_EE:
            raise ValueError(f"the configuration's {len(head)} bytes overlap the step configuration at {STEP_CFG_EE}")
        step = config_bytes(self.config.cfg_i, self.config.cfg_v,
                            calibrated=bool(self.config.step_config.calibrated))
        return head + [0xFF] * (STEP_CFG_EE - len(head)) + step

    def _n_med(self) -> int:
        return int(self.config.cfg_i[kernel.CI_N_MED])

    def _weights(self) -> np.ndarray:
        r3 = int(self.config.cfg_i[kernel.CI_R3])
        return self.config.cfg_v[kernel.CV_W3:kernel.CV_W3 + r3 + 1]

    def _run_one(self, codes, flags, cal_bytes, first_sample) -> _RunOut:
        """One logging run (a START) in one gpsim run."""
        period = timer_setup(self.sampling_rate_hz, self.fosc_hz).period_cycles
        n = codes.shape[0]
        with tempfile.TemporaryDirectory(prefix="pic-logger-") as tmp:
            d = Path(tmp)
            self._write_config(d, cal_bytes)
            build = _assemble(d, dict(self._defines(first_sample), N_SAMPLES=n, START_N=0), test=True)
            sym = build.symbols
            tracked = {sym[k] + i for k, b in _SNAPSHOT for i in range(b)}
            tracked |= {sym[k] + i for k, b, _ in _DETECTOR for i in range(b)}
            tracked |= {sym["DURS"] + i for i in range(self._n_med())}
            tracked |= {sym[k] + i for k, b in _RECORD for i in range(b)}
            tracked |= {sym["REC"] + i for i in range(STEP_RECORD_BYTES)}
            logged = sorted(tracked | {sym["B0"], sym["FZ_H"], sym["AV_H"], sym["M_L"], sym["PENDING"], sym["STATUS_TEMP"], PCLATH_ADDR,
                                       ADCON0_ADDR, *PAGE_ADDRS})
            t0 = time.perf_counter()
            text = _gpsim(build, logged, "e harness_done", self.timeout_s, _stimuli(codes, flags, period))
            dt = time.perf_counter() - t0
        cyc, addr, val = _writes(text, set(logged))
        start = {a: 0 for a in tracked}
        snaps, order, ready, calls, stages, records, stop_cycles = _replay_log(cyc, addr, val, n, sym, start)
        col = {a: i for i, a in enumerate(order)}
        ram = {}
        for k, b in _SNAPSHOT:
            ram[k] = snaps[:, [col[sym[k] + i] for i in range(b)]]
        for k, b, _ in _DETECTOR:
            ram[k] = snaps[:, [col[sym[k] + i] for i in range(b)]]
        ram["DURS"] = snaps[:, [col[sym["DURS"] + i] for i in range(self._n_med())]]
        adc = cyc[addr == ADCON0_ADDR][1:]                  # the first is the set-up's
        _check_conversions(adc[1::2], n, period)
        acq = int(np.min(adc[1::2] - adc[0::2])) if adc.size >= 2 else 0
        return _RunOut(_packed(addr, val, n, first_sample), ram, ready, calls, stages, acq,
                       int(cyc.max()) if cyc.size else 0, dt, records,
                       int(val[addr == sym["PENDING"]].max(initial=0)), stop_cycles)

    def _logged_run(self, codes: np.ndarray, calibration: CalibrationQ, defines: dict[str, int],
                    logged: Callable[[dict[str, int]], set[int]], prefix: str
                    ) -> tuple[dict[str, int], np.ndarray, np.ndarray, np.ndarray]:
        """One test-build run of ``codes`` (a START to the harness's end, at the rate's period, no marker flags)
        with only the addresses ``logged(symbols)`` in gpsim's write log: the build's symbols and the writes
        (cycles, addresses, values)."""
        period = timer_setup(self.sampling_rate_hz, self.fosc_hz).period_cycles
        c = np.asarray(codes, np.int64).reshape(-1, 3)
        n = c.shape[0]
        with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
            d = Path(tmp)
            self._write_config(d, _calibration_bytes(calibration))
            build = _assemble(d, dict(defines, N_SAMPLES=n), test=True)
            wanted = logged(build.symbols)
            text = _gpsim(build, sorted(wanted), "e harness_done", self.timeout_s,
                          _stimuli(c, np.zeros(n, np.int64), period))
        return (build.symbols, *_writes(text, wanted))

    def run_calls(self, codes: np.ndarray, calibration: CalibrationQ, *, start_n: int = 0,
                  run_start_sample: int = 0) -> LeanRun:
        """One run from START with a lean write log: ``finalise``'s calls (as :attr:`LoggerRun.calls`), the step
        records (as :attr:`LoggerRun.records`) and the detector's state after the last sample (as a row of
        :attr:`LoggerRun.detector`). Only the call record, the step record, the detector's state and ``PENDING``
        are logged; a sample ends where ``PENDING`` is decremented.

        ``start_n``: the kernel's ``N`` at START (the test build's ``START_N``: a run that old, its gravity
        warm-up over), so that a run crosses 2^15 (``F_OLD``) or the 16-bit index wrap after a few thousand
        samples instead of the 65,536 (6 x 10^9 cycles) a run from 0 would take;
        :func:`~gaitlog.firmware_sim.algorithms.probe.detector_trace` starts the kernel at the same ``N``.
        ``run_start_sample``: the run's first sample number, which places the scratch ring's start (``SCR_K0``:
        the run's sample ``start_n`` at ring sample ``(S + start_n) mod 32,512``, ``S`` the first sample of its
        start page)."""
        if start_n and not (2 << self.gravity_shift) <= start_n < INDEX_MODULUS:
            raise ValueError(f"start_n must be 0 or {2 << self.gravity_shift} .. {INDEX_MODULUS - 1}")
        n = np.asarray(codes).reshape(-1, 3).shape[0]

        def tracked(sym: dict[str, int]) -> set[int]:
            out = {sym[k] + i for k, b, _ in _DETECTOR for i in range(b)}
            out |= {sym["DURS"] + i for i in range(self._n_med())}
            out |= {sym[k] + i for k, b in _RECORD for i in range(b)}
            return out | {sym["REC"] + i for i in range(STEP_RECORD_BYTES)} | {sym["PENDING"]}

        sym, _, addr, val = self._logged_run(codes, calibration, dict(self._defines(0), START_N=start_n,
                                             SCR_K0=scratch_offset(run_start_sample, start_n)), tracked,
                                             "pic-logger-lean-")
        state = [(sym[k], b, signed) for k, b, signed in _DETECTOR] + [(sym["DURS"] + i, 1, False)
                                                                         for i in range(self._n_med())]
        calls, records, ram, _ = _lean_log(addr, val, n, sym)

        def value(a, b, signed):
            v = sum(ram.get(a + i, 0) << (8 * i) for i in range(b))
            return v - (1 << (8 * b)) if signed and v >= 1 << (8 * b - 1) else v

        return LeanRun(calls, np.asarray([value(a, b, sg) for a, b, sg in state], np.int64), records)

    def run_page_writes(self, codes: np.ndarray, calibration: CalibrationQ, *, run_start_sample: int = 0
                        ) -> np.ndarray:
        """The page writes the firmware put on the I2C bus in one run (:meth:`run_bus`)."""
        return self.run_bus(codes, calibration, run_start_sample=run_start_sample).page_writes

    def run_bus(self, codes: np.ndarray, calibration: CalibrationQ, *, run_start_sample: int = 0) -> BusRun:
        """One run from START to STOP (``step_flush``) with only ``PENDING`` and the MSSP's ``SSPBUF`` and
        ``SSPCON2`` logged: the page writes the firmware put on the I2C bus (:func:`bus_page_writes`; the
        scratch ring's flushes and its tail writes) and its reads (:func:`bus_reads`). ``run_start_sample``
        places the ring's start as in :meth:`run_calls`."""
        _, _, addr, val = self._logged_run(
            codes, calibration, dict(self._defines(0), START_N=0, SCR_K0=scratch_offset(run_start_sample, 0)),
            lambda sym: {sym["PENDING"], SSPBUF_ADDR, SSPCON2_ADDR}, "pic-logger-bus-")
        return BusRun(bus_page_writes(addr, val), bus_reads(addr, val))

    def run_header(self, codes: np.ndarray, calibration: CalibrationQ, *, first_sample_number: int = 0) -> HeaderRun:
        """One run from START with the header at ``first_sample_number`` samples written (``overwrite`` and
        ``steps_written`` from the harness): the header counters (logger_ram.inc) after the run, from a lean
        write log. In stop-when-full mode the run ends where the memory fills (the interrupt's STOP)."""
        sample_bytes = ("SAMPLE_L", "SAMPLE_H", "SAMPLE_U", "SAMPLE_T")
        sym, _, addr, val = self._logged_run(
            codes, calibration, dict(self._defines(first_sample_number), START_N=0),
            lambda sym: ({sym[k] for k in (*sample_bytes, "FW_FLAGS", "PENDING")}
                         | {sym["STEPS_W"] + i for i in range(4)}),
            "pic-logger-header-")
        counted = [sym[k] for k in sample_bytes]
        steps_at = [sym["STEPS_W"] + i for i in range(4)]
        last = {a: v for a, v in zip(addr.tolist(), val.tolist())}
        sw, steps = (sum(last.get(a, 0) << (8 * i) for i, a in enumerate(at)) for at in (counted, steps_at))
        flags = last.get(sym["FW_FLAGS"], 0)
        done = int(np.sum(np.diff(val[addr == sym["PENDING"]]) == -1))         # the main loop's DECF PENDING
        return HeaderRun(done, 0xFFFFFFFF if flags >> sym["FWF_SW_SAT"] & 1 else sw, sw & 0xFFFF, steps,
                         bool(flags >> sym["FWF_OVERWRITE"] & 1))

    def measure_isr(self) -> tuple[np.ndarray, int]:
        """The production build's interrupt: cycles (vector to RETFIE) at each of the 32 page positions of a
        run started at sample 0, and the period between interrupts."""
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        with tempfile.TemporaryDirectory(prefix="pic-logger-isr-") as tmp:
            build = _assemble(Path(tmp), self._defines(0), test=False)
            stop = f"c {t.period_cycles * (ISR_PROBE_SAMPLES + 1)}"
            text = _gpsim(build, [W_TEMP_ADDR], stop, self.timeout_s)
        cyc, _, _ = _writes(text, {W_TEMP_ADDR})
        start, end = cyc[0::2], cyc[1::2] + ISR_TAIL_CYCLES
        if end.size < ISR_PROBE_SAMPLES:
            raise PicError(f"the production build took {end.size} samples in {ISR_PROBE_SAMPLES + 1} periods")
        isr = (end - start[:end.size])[:ISR_PROBE_SAMPLES]
        periods = np.unique(np.diff(start))
        if periods.size != 1:
            raise PicError(f"the sampling interrupt's period varies: {periods.tolist()} cycles")
        return isr[:32], int(periods[0])

    def raw_speed(self, n_samples: int, *, codes: np.ndarray | None = None,
                  calibration: CalibrationQ | None = None) -> tuple[int, float]:
        """gpsim's own speed on this firmware: the production build, nothing logged, for ``n_samples`` sample
        periods; returns (cycles simulated, wall seconds of the gpsim process). With ``codes`` and
        ``calibration``: the test build on the first ``n_samples`` codes' stimuli instead, nothing logged, to
        ``harness_done`` (the same work as a harness run, with no log to write or read)."""
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        with tempfile.TemporaryDirectory(prefix="pic-logger-raw-") as tmp:
            if codes is None or calibration is None:
                build = _assemble(Path(tmp), self._defines(0), test=False)
                stop, stimuli = f"c {t.period_cycles * n_samples}", ""
            else:
                c = np.asarray(codes, np.int64).reshape(-1, 3)[:n_samples]
                self._write_config(Path(tmp), _calibration_bytes(calibration))
                build = _assemble(Path(tmp), dict(self._defines(0), N_SAMPLES=c.shape[0], START_N=0), test=True)
                stop, stimuli = "e harness_done", _stimuli(c, np.zeros(c.shape[0], np.int64), t.period_cycles)
            t0 = time.perf_counter()
            _gpsim(build, [], stop, self.timeout_s, stimuli)
            return t.period_cycles * n_samples, time.perf_counter() - t0

    def run_records(self, codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *,
                    first_sample_number: int = 0, period_cycles: int | None = None) -> RecordsRun:
        """One logging run (``codes`` from a START to the next) in the records-only lean mode: the same test
        build, the codes as analog stimuli, but only ``PENDING``, ``ADCON0``, ``finalise``'s call record, the
        step record (``REC``) and ``LAST``'s high byte are logged, so that gpsim's log stays small and its
        parsing costs little next to gpsim. The conversions are checked against their stimuli as in
        :meth:`run`.

        ``period_cycles``: the sampling period (default: the rate's). A shorter one runs the same code with
        fewer idle cycles per sample; the step records do not depend on it as long as the main loop keeps up
        (``backlog_max`` below :data:`PAGE_WORDS`, which :func:`verify_records` requires)."""
        t = period_setup(period_cycles) if period_cycles else timer_setup(self.sampling_rate_hz, self.fosc_hz)
        c = np.asarray(codes, np.int64).reshape(-1, 3)
        n = c.shape[0]
        with tempfile.TemporaryDirectory(prefix="pic-logger-records-") as tmp:
            d = Path(tmp)
            self._write_config(d, _calibration_bytes(calibration))
            defines = dict(self._defines(first_sample_number), CCP_PERIOD=t.ccpr1, T1_SETUP=t.t1con)
            build = _assemble(d, dict(defines, N_SAMPLES=n, START_N=0), test=True)
            sym = build.symbols
            logged = {sym[k] + i for k, b in _RECORD for i in range(b)} | {sym["PENDING"], sym["LAST"] + 1,
                                                                            ADCON0_ADDR}
            logged |= {sym["REC"] + i for i in range(STEP_RECORD_BYTES)}
            t0 = time.perf_counter()
            text = _gpsim(build, sorted(logged), "e harness_done", self.timeout_s,
                          _stimuli(c, np.asarray(flags, np.int64).reshape(-1), t.period_cycles))
            dt = time.perf_counter() - t0
        cyc, addr, val = _writes(text, logged)
        adc = cyc[addr == ADCON0_ADDR][1:]                  # the first is the set-up's
        _check_conversions(adc[1::2], n, t.period_cycles)
        other = addr != ADCON0_ADDR
        calls, records, _, backlog = _lean_log(addr[other], val[other], n, sym)
        return RecordsRun(calls, records, backlog, t.period_cycles, int(cyc.max(initial=0)), dt)

    def run(self, codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *,
            first_sample_number: int = 0) -> LoggerRun:
        """Run the assembly on ``codes`` (``(n, 3)``) with ``flags`` (S starts a run, M presses the button).

        The first sample starts a run whether or not it has S (the firmware's START)."""
        t0 = time.perf_counter()
        c = np.asarray(codes, np.int64).reshape(-1, 3)
        f = np.asarray(flags, np.int64).reshape(-1)
        cal_bytes = _calibration_bytes(calibration)
        starts = run_starts(f)
        runs = [(a, b) for a, b in zip(starts, starts[1:] + [c.shape[0]]) if b > a]
        if not runs:
            raise ValueError("no samples to run")
        with ThreadPoolExecutor(max_workers=max(1, self.workers)) as pool:
            isr = pool.submit(self.measure_isr)                 # the production build, beside the first run
            parts = list(pool.map(lambda ab: self._run_one(c[ab[0]:ab[1]], f[ab[0]:ab[1]], cal_bytes,
                                                           first_sample_number + ab[0]), runs))
            isr_by_pos, period = isr.result()

        def cat(key, signed=True):
            return np.concatenate([_int(p.ram[key], signed) for p in parts])

        calls = [p.calls + np.array([a] + [0] * len(_RECORD)) for p, (a, _) in zip(parts, runs)]
        detector = np.stack([cat(k, s) for k, _, s in _DETECTOR], axis=1)
        durs = np.concatenate([p.ram["DURS"] for p in parts]).astype(np.int64)
        positions = (first_sample_number + np.arange(c.shape[0])) % 32
        return LoggerRun(
            packed=np.concatenate([p.packed for p in parts]),
            calibrated=np.stack([cat(k) for k in ("FX_L", "FY_L", "FZ_L")], axis=1),
            gravity=np.stack([cat(f"G{s}{a}") for s in "12" for a in "XYZ"], axis=1), a_v=cat("AV_L"),
            y3=cat("Y3_0"), ready=np.concatenate([p.ready for p in parts]),
            detector=np.concatenate([detector, durs], axis=1), calls=np.concatenate(calls),
            isr_cycles=isr_by_pos[positions], stage_cycles=np.concatenate([p.stage_cycles for p in parts]),
            acquisition_cycles_min=min(p.acquisition_cycles_min for p in parts), period_cycles=period,
            simulated_cycles=sum(p.simulated_cycles for p in parts), gpsim_s=sum(p.gpsim_s for p in parts),
            wall_s=time.perf_counter() - t0, records=np.concatenate([p.records for p in parts]),
            backlog_max=max(p.backlog_max for p in parts), stop_cycles=tuple(p.stop_cycles for p in parts
                                                                           if p.stop_cycles))


def run_starts(flags: np.ndarray) -> list[int]:
    """Where the logging runs start: sample 0 and every sample with the S flag."""
    return sorted({0, *np.flatnonzero(np.asarray(flags) & FLAG_SESSION_START).tolist()})


# ---------------------------------------------------------------------------------------------------
# memory


@dataclass(frozen=True)
class MemoryMap:
    """RAM and program memory of the production build, from gpasm's listing (measured).

    ``ram_bytes`` per block (bank 0-3 and common RAM) and ``ram_groups``, the firmware's own variable groups
    (:data:`~.ram_map.FIRMWARE_GROUPS`: the header counters, and the UART handler's and the page writer's, reserved
    at the model's sizes), both from one :class:`~.ram_map.RamMap`; ``ram_problems``: what
    :meth:`~.ram_map.RamMap.problems` finds (empty when it fits). ``program_words``: words from 0 to ``code_end``
    (page 0) plus page 1's routines and page 2; ``kernel_words``: the arithmetic kernels (page 0's and page 2's
    copy); ``steps_words``: steps 4-5 (both pages); ``step_record_words``: the step record (page 2, without its
    kernels) and its joins (page 1); ``pages``: words used per program-memory page.
    """

    ram_bytes: dict[str, int]
    program_words: int
    kernel_words: int
    steps_words: int = 0
    step_record_words: int = 0
    pages: dict[str, int] = field(default_factory=dict)
    ram_groups: dict[str, int] = field(default_factory=dict)
    ram_problems: tuple[str, ...] = ()

    @property
    def ram_total_bytes(self) -> int:
        return sum(self.ram_bytes.values())

    def ram_line(self) -> str:
        """The RAM figure, per bank and with the firmware's groups named."""
        groups = ", ".join(f"{k} {v}" + (" (reserved: the model's part, its estimate)"
                                         if FIRMWARE_GROUPS[k][2] else "") for k, v in self.ram_groups.items())
        return (f"{self.ram_total_bytes} of {PIC_RAM_BYTES} bytes ("
                + ", ".join(f"{k} {v}" for k, v in self.ram_bytes.items()) + f"); of them the firmware's {groups}"
                + ("" if not self.ram_problems else "; PROBLEMS: " + "; ".join(self.ram_problems)))


_RAM_BLOCKS = ("bank 0", "bank 1 (steps 4-5, header counters)", "bank 2 (page buffer, step record)",
               "bank 3 (page buffer, step record)", "common (kernels, W_TEMP)")


def memory_map(*, sampling_rate_hz: float = 50.0, fosc_hz: float = DEFAULT_FOSC_HZ) -> MemoryMap:
    """Assemble the production build and read its RAM map (:func:`~.ram_map.ram_map`) and program size from the
    listing."""
    with tempfile.TemporaryDirectory(prefix="pic-logger-map-") as tmp:
        b = _assemble(Path(tmp), PicLogger(sampling_rate_hz=sampling_rate_hz, fosc_hz=fosc_hz)._defines(0),
                      test=False)
        ram = ram_map((Path(tmp) / "logger.lst").read_text(errors="replace"), b.symbols)
    s = b.symbols
    page1 = s["page1_end"] - s["page1_begin"]
    joins = s["join_end"] - s["join_begin"]
    page2 = s["page2_end"] - s["page2_begin"]
    kernels = s["kernels_end"] - s["kernels_begin"]
    pages = {"page 0": s["code_end"], "page 1": page1 + joins, "page 2": page2}
    return MemoryMap(dict(zip(_RAM_BLOCKS, ram.bank_bytes().values())), sum(pages.values()), 2 * kernels,
                     s["steps_end"] - s["steps_begin"] + page1, page2 - kernels + joins, pages, ram.groups(),
                     tuple(ram.problems()))


# ---------------------------------------------------------------------------------------------------
# verification


@dataclass(frozen=True)
class StageComparison:
    """One compared stage: how many samples are identical, and the first that is not."""

    name: str
    n_compared: int
    n_identical: int
    first_difference: dict | None = None

    @property
    def identical(self) -> bool:
        return self.n_identical == self.n_compared


def _compare(name: str, fields: tuple[str, ...], pic: np.ndarray, model: np.ndarray) -> StageComparison:
    same = np.all(pic == model, axis=1)
    first = None
    if not same.all():
        i = int(np.flatnonzero(~same)[0])
        j = int(np.flatnonzero(pic[i] != model[i])[0])
        first = {"sample": i, "field": fields[j], "gpsim": int(pic[i, j]), "model": int(model[i, j])}
    return StageComparison(name, int(same.size), int(same.sum()), first)


def _stats(x: np.ndarray) -> dict:
    if x.size == 0:
        return {"mean": 0.0, "p99": 0.0, "worst": 0}
    return {"mean": round(float(x.mean()), 1), "p99": float(np.percentile(x, 99)), "worst": int(x.max())}


@dataclass(frozen=True)
class PicVerification:
    """:func:`verify`'s result: the compared stages, the measured cycles and memory, the harness speed."""

    source: str
    n_samples: int
    sampling_rate_hz: float
    stages: list[StageComparison]
    cycles: dict[str, dict]
    acquisition_cycles_min: int
    acquisition_cycles_needed: float
    period_cycles: int
    memory: MemoryMap
    gpsim_s: float
    wall_s: float
    gpsim: str = ""
    notes: list[str] = field(default_factory=list)
    #: the most samples taken and not yet processed (PENDING, measured): the page buffer holds 32
    backlog_max: int = 0
    #: :attr:`LoggerRun.stop_cycles`: STOP's last step record, per run that had one (measured)
    stop_cycles: tuple[int, ...] = ()

    @property
    def identical(self) -> bool:
        return all(s.identical for s in self.stages)

    @property
    def realtime_factor(self) -> float:
        """Recording seconds per wall second of the whole verification (gpasm, gpsim, parsing)."""
        return self.n_samples / self.sampling_rate_hz / self.wall_s if self.wall_s > 0 else float("inf")

    def format_table(self) -> str:
        lines = [f"{self.source}: {self.n_samples:,} samples at {self.sampling_rate_hz:g} Hz, PIC assembly in gpsim "
                 f"{self.gpsim} vs the Python model"]
        for s in self.stages:
            unit = {"finalise calls": "calls", "step records": "records"}.get(s.name, "samples")
            line = f"  {s.name:<18} {s.n_identical:,} of {s.n_compared:,} {unit} identical"
            if s.first_difference:
                d = s.first_difference
                where = (f"record {d['record']} (end sample {d['sample']})" if "record" in d
                         else f"sample {d['sample']}")
                line += f"; first difference: {where}, {d['field']}: gpsim {d['gpsim']}, model {d['model']}"
            lines.append(line)
        lines.append(f"cycles per sample (measured in gpsim; {self.period_cycles:,} available):")
        for k, v in self.cycles.items():
            lines.append(f"  {k:<30} mean {v['mean']:>8,.1f}   p99 {v['p99']:>8,.1f}   worst {v['worst']:>7,}")
        if self.stop_cycles:
            lines.append(f"STOP (measured): a pending step finalised at the end of {len(self.stop_cycles)} run(s), "
                         f"its record done {max(self.stop_cycles):,} cycles after the run's last sample (worst)")
        lines.append(f"backlog (measured): at most {self.backlog_max} samples waiting for the main loop, of the "
                     f"{PAGE_WORDS}-sample page buffer")
        lines.append(f"ADC acquisition: {self.acquisition_cycles_min} cycles from channel select to GO (measured; "
                     f"needed {self.acquisition_cycles_needed:.1f})")
        m = self.memory
        lines.append(f"RAM (measured, gpasm listing): {m.ram_line()}")
        lines.append(f"program memory (measured): {m.program_words:,} of 8,192 words ({m.kernel_words} kernels in two "
                     f"copies, {m.step_record_words:,} step record); "
                     + ", ".join(f"{k} {v:,} of 2,048" for k, v in m.pages.items()))
        lines.append(f"harness: {self.wall_s:.1f} s ({self.realtime_factor:.1f}x real time; "
                     f"gpsim {self.gpsim_s:.1f} s)")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def to_json(self) -> str:
        doc = {"source": self.source, "n_samples": self.n_samples, "sampling_rate_hz": self.sampling_rate_hz,
               "identical": self.identical, "gpsim": self.gpsim,
               "stages": [{"name": s.name, "n_compared": s.n_compared, "n_identical": s.n_identical,
                           "first_difference": s.first_difference} for s in self.stages],
               "cycles_measured": self.cycles, "period_cycles": self.period_cycles,
               "acquisition_cycles_min": self.acquisition_cycles_min, "backlog_max_samples": self.backlog_max,
               "stop_cycles_measured": list(self.stop_cycles),
               "acquisition_cycles_needed": round(self.acquisition_cycles_needed, 1),
               "ram_bytes_measured": self.memory.ram_bytes, "ram_total_bytes": self.memory.ram_total_bytes,
               "ram_groups_measured": self.memory.ram_groups, "ram_problems": list(self.memory.ram_problems),
               "program_words_measured": self.memory.program_words, "kernel_words": self.memory.kernel_words,
               "wall_s": round(self.wall_s, 3), "gpsim_s": round(self.gpsim_s, 3),
               "realtime_factor": round(self.realtime_factor, 2), "notes": self.notes}
        return json.dumps(doc, indent=2)


def _compare_calls(pic: np.ndarray, model: np.ndarray) -> StageComparison:
    """finalise's calls, in order: identical when the lists are; else the first call that differs (or is
    missing on one side)."""
    k = max(pic.shape[0], model.shape[0])
    same = [i < pic.shape[0] and i < model.shape[0] and np.array_equal(pic[i], model[i]) for i in range(k)]
    first = None
    if not all(same):
        i = same.index(False)
        if i >= pic.shape[0] or i >= model.shape[0]:
            first = {"call": i, "sample": int((model if i < model.shape[0] else pic)[i, 0]), "field": "call",
                     "gpsim": "none" if i >= pic.shape[0] else "a call", "model": "none" if i >= model.shape[0]
                     else "a call"}
        else:
            j = int(np.flatnonzero(pic[i] != model[i])[0])
            first = {"call": i, "sample": int(min(pic[i, 0], model[i, 0])), "field": CALL_FIELDS[j],
                     "gpsim": int(pic[i, j]), "model": int(model[i, j])}
    return StageComparison("finalise calls", k, int(sum(same)), first)


def _compare_records(pic: np.ndarray, model: np.ndarray) -> StageComparison:
    """The step records (``(k, 20)`` bytes each side), in order: identical when every byte is; else the first
    record that differs, its end sample and its first differing field (or the record missing on one side)."""
    k = max(pic.shape[0], model.shape[0])
    same = [i < pic.shape[0] and i < model.shape[0] and np.array_equal(pic[i], model[i]) for i in range(k)]
    first = None
    if not all(same):
        i = same.index(False)
        side = model if i < model.shape[0] else pic
        end = int(np.frombuffer(side[i].tobytes(), STEP_RECORD_DTYPE)["end_sample"][0])
        if i >= pic.shape[0] or i >= model.shape[0]:
            first = {"record": i, "sample": end, "field": "record",
                     "gpsim": "none" if i >= pic.shape[0] else "a record",
                     "model": "none" if i >= model.shape[0] else "a record"}
        else:
            a, b = (np.frombuffer(x[i].tobytes(), STEP_RECORD_DTYPE)[0] for x in (pic, model))
            name = next(n for n in STEP_RECORD_DTYPE.names if a[n] != b[n])
            first = {"record": i, "sample": end, "field": name, "gpsim": int(a[name]), "model": int(b[name])}
    return StageComparison("step records", k, int(sum(same)), first)


def _verification_inputs(codes: np.ndarray, flags: np.ndarray, sampling_rate_hz: float,
                         harness: PicLogger | None) -> tuple[np.ndarray, np.ndarray, PicLogger, list[int]]:
    """What :func:`verify` and :func:`verify_records` start from: the codes ``(n, 3)``, the flags, the harness and
    the runs' first samples; :class:`PicError` when gpasm/gpsim are absent."""
    why = missing_tools()
    if why:
        raise PicError(why)
    f = np.asarray(flags, np.int64).reshape(-1)
    return (np.asarray(codes, np.int64).reshape(-1, 3), f,
            harness or PicLogger(sampling_rate_hz=sampling_rate_hz), run_starts(f))


def verify(codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *, sampling_rate_hz: float = 50.0,
           source: str = "codes", first_sample_number: int = 0, harness: PicLogger | None = None,
           a_v: bool = True) -> PicVerification:
    """Run the assembly in gpsim on ``codes`` and compare it with the model, stage by stage.

    Stages: *packed words* (the page buffer's bytes vs :func:`~gaitlog.protocol.packing.pack_words`),
    *calibrated axes* (``FX..FZ`` vs :func:`~gaitlog.firmware_sim.algorithms.probe.calibrated_axes`) and
    *gravity* (``G1``, ``G2`` after each sample vs :func:`~gaitlog.firmware_sim.algorithms.probe.gravity_states`,
    restarted at each run's first sample) and *a_v* (``AV`` vs
    :func:`~gaitlog.firmware_sim.algorithms.probe.vertical_acceleration`), then through
    :func:`~gaitlog.firmware_sim.algorithms.probe.detector_trace`: *y3* (whether the sample has a filter
    output, and ``Y3``), *detector* (the bank-1 state after each sample), *finalise calls* (each call's
    sample, e, s, m, flags) and *step records* (20 bytes each), STOP's call and record at each run's end
    included. ``a_v=False`` leaves out a_v and steps 4-5, for a calibration whose ``|g|``
    exceeds the model's 16-bit divisor, where the model raises.
    Raises :class:`PicError` when gpasm/gpsim are absent or fail.
    """
    t0 = time.perf_counter()
    c, f, h, starts = _verification_inputs(codes, flags, sampling_rate_hz, harness)
    with ThreadPoolExecutor(max_workers=1) as pool:        # gpsim runs while the model computes
        pending = pool.submit(h.run, c, f, calibration, first_sample_number=first_sample_number)
        model_f = calibrated_axes(c, calibration)
        model_g = np.concatenate([gravity_states(model_f[a:b], h.gravity_shift)
                                  for a, b in zip(starts, starts[1:] + [c.shape[0]])])
        model_av = vertical_acceleration(model_f, model_g[:, 3:], h.min_gravity_raw) if a_v else None
        trace = (detector_trace(c, calibration, h.sampling_rate_hz, starts)
                 if a_v else None)
        run = pending.result()
    expect_packed = np.frombuffer(words_to_bytes(pack_words(c, f)), np.uint8).reshape(-1, 4)
    stages = [_compare("packed words", ("byte 0", "byte 1", "byte 2", "byte 3"), run.packed.astype(np.int64),
                       expect_packed.astype(np.int64)),
              _compare("calibrated axes", ("fx", "fy", "fz"), run.calibrated, model_f),
              _compare("gravity", ("g1x", "g1y", "g1z", "g2x", "g2y", "g2z"), run.gravity, model_g)]
    if a_v:
        stages.append(_compare("a_v", ("a_v",), run.a_v.reshape(-1, 1), model_av.reshape(-1, 1)))
        stages.append(_compare("y3", ("ready", "y3"), np.stack([run.ready, np.where(run.ready, run.y3, 0)], axis=1),
                               np.stack([trace.ready, np.where(trace.ready, trace.y3, 0)], axis=1)))
        n_med = trace.state.shape[1] - len(DETECTOR_FIELDS)
        stages.append(_compare("detector", DETECTOR_FIELDS + tuple(f"durations[{i}]" for i in range(n_med)),
                               run.detector, trace.state))
        stages.append(_compare_calls(run.calls, trace.calls))
        stages.append(_compare_records(run.records, trace.records))
    total = run.isr_cycles + run.stage_cycles.sum(axis=1)
    cycles = {"sampling interrupt": _stats(run.isr_cycles)}
    cycles.update({name: _stats(run.stage_cycles[:, i]) for i, name in enumerate(STAGES)})
    cycles["total in assembly"] = _stats(total)
    need = (adc_acquisition_s(h.source_impedance_ohm) + 2 * adc_tad_s(h.fosc_hz)) * h.fosc_hz / 4.0
    notes = ["the sample pages' I2C write and the UART command handler are not yet in assembly (STOP comes after "
             "the run's last sample); the step records' end sample counts from the run's START",
             f"the assembly's scratch ring is the model's ({kernel.SCRATCH_RING_SAMPLES:,} samples from the run's start "
             "page); gpsim's 24xx256 keeps ring samples 16,384 apart on one byte",
             f"ADC conversion: {ADC_CONVERSION_TAD} TAD as gpsim times it"]
    return PicVerification(source, int(c.shape[0]), h.sampling_rate_hz, stages, cycles, run.acquisition_cycles_min,
                           need, run.period_cycles, memory_map(sampling_rate_hz=h.sampling_rate_hz, fosc_hz=h.fosc_hz),
                           run.gpsim_s, time.perf_counter() - t0, gpsim_version(), notes, run.backlog_max,
                           run.stop_cycles)



@dataclass(frozen=True)
class RecordsVerification:
    """:func:`verify_records`' result: the step records compared, the backlog, the harness's speed."""

    source: str
    n_samples: int
    sampling_rate_hz: float
    records: StageComparison
    backlog_max: int
    period_cycles: int
    simulated_cycles: int
    gpsim_s: float
    wall_s: float

    @property
    def identical(self) -> bool:
        """Every record identical, and the main loop kept up (no sample lost to a full page buffer)."""
        return self.records.identical and self.backlog_max < PAGE_WORDS

    @property
    def realtime_factor(self) -> float:
        """Recording seconds per wall second (gpasm, gpsim, parsing, the model)."""
        return self.n_samples / self.sampling_rate_hz / self.wall_s if self.wall_s > 0 else float("inf")


def verify_records(codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *, sampling_rate_hz: float = 50.0,
                   source: str = "codes", first_sample_number: int = 0, harness: PicLogger | None = None,
                   period_cycles: int | None = None) -> RecordsVerification:
    """The step records only: every logging run through gpsim in the lean records mode
    (:meth:`PicLogger.run_records`) and the model's records from the kernel fed each run whole
    (:func:`~gaitlog.firmware_sim.algorithms.probe.step_records`, STOP's included, the model's own scratch
    ring), compared byte for byte. :func:`verify` compares the same records and every stage besides.
    Raises :class:`PicError` when gpasm/gpsim are absent or fail."""
    t0 = time.perf_counter()
    c, f, h, starts = _verification_inputs(codes, flags, sampling_rate_hz, harness)
    runs = [(a, b) for a, b in zip(starts, starts[1:] + [c.shape[0]]) if b > a]
    if not runs:
        raise ValueError("no samples to run")
    with ThreadPoolExecutor(max_workers=max(1, h.workers)) as pool:
        parts = list(pool.map(lambda ab: h.run_records(c[ab[0]:ab[1]], f[ab[0]:ab[1]], calibration,
                                                       first_sample_number=first_sample_number + ab[0],
                                                       period_cycles=period_cycles), runs))
    model = step_records(c, calibration, h.sampling_rate_hz, starts)
    pic = np.concatenate([p.records for p in parts])
    return RecordsVerification(source, int(c.shape[0]), h.sampling_rate_hz, _compare_records(pic, model),
                               max(p.backlog_max for p in parts), parts[0].period_cycles,
                               sum(p.simulated_cycles for p in parts), sum(p.gpsim_s for p in parts),
                               time.perf_counter() - t0)
