"""The logger's per-sample firmware path in PIC16 assembly, run in gpsim on a recording's codes.

``logger.asm`` (RAM map ``logger_ram.inc``) is the sampling interrupt (CCP1 compare on Timer1 at the
sampling rate, three ADC channels with their acquisition time, P32 packing into the 128-byte page buffer,
the page handoff) and the main loop's first three steps of the on-line algorithm (``kernel.py`` steps 1-3:
calibration, gravity, a_v). :class:`PicLogger` runs it in gpsim without stopping per sample:

* **Test build** (``TEST_BUILD``): after each conversion the interrupt overwrites ADRESH:ADRESL with the
  next code of a table assembled into program memory (words 0x0800-0x1FFF, one 14-bit word per code, bit
  10 of an x word = the marker button), so up to :data:`CHUNK_SAMPLES` samples are one gpasm and one gpsim
  run. Longer runs are cut into chunks that run one after the other, each starting from the stage-2 state
  the previous one's log ended with (``state.inc``); logging runs (S flags) run in parallel. The timer runs
  at the real rate: gpsim simulates every cycle of every sample period.
* **Outputs** come from gpsim's register-write log (``log w``), stamped with its cycle counter: the 128
  page-buffer bytes (the packed words), the stage outputs and state (``FX..FZ``, ``G1``, ``G2``, ``AV``,
  snapshot at the main loop's ``DECF PENDING`` that ends each sample), ``W_TEMP`` (the interrupt's entry
  and exit), ``ADCON0`` (channel select and GO: the acquisition time) and ``B0`` (the main loop's start).
  Nothing stops the simulation before the table's end (``harness_done``).
* **Cycles**: the interrupt from its vector to RETFIE is measured on the production build (no table, no
  injection) over :data:`ISR_PROBE_SAMPLES` samples at every page position; the stages from reading the
  sample's word back from the page to ``DECF PENDING`` are measured per sample in the test build (the same
  code), less any interrupt that fell inside them.

:func:`verify` compares with the Python model: :func:`gaitlog.protocol.packing.pack_words` for the words,
the probes of :mod:`gaitlog.firmware_sim.algorithms.probe` for steps 1-3.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.formats import ACC_Q, F_ACC
from gaitlog.firmware_sim.algorithms.parameters import EventParameters, OnlineParameters, SampleCounts
from gaitlog.firmware_sim.algorithms.probe import calibrated_axes, gravity_states, vertical_acceleration
from gaitlog.firmware_sim.budget import ADC_CONVERSION_TAD, adc_acquisition_s, adc_tad_s
from gaitlog.firmware_sim.fixedpoint import DEFAULT_FOSC_HZ, cycles_per_sample_available
from gaitlog.firmware_sim.pic.gpsim_bench import PIC_DIR, copy_sources, gpsim_version, missing_tools
from gaitlog.protocol.packing import FLAG_MARK, FLAG_SESSION_START, pack_words, words_to_bytes

__all__ = ["LOGGER_ASM", "CHUNK_SAMPLES", "TimerSetup", "timer_setup", "acquisition_loops", "LoggerRun",
           "PicLogger", "MemoryMap", "memory_map", "StageComparison", "PicVerification", "verify", "run_starts",
           "missing_tools"]

#: The firmware source.
LOGGER_ASM = PIC_DIR / "logger.asm"
#: Samples per gpsim run: the code table fills program memory 0x0800-0x1FFF (6,144 words, 3 per sample).
CHUNK_SAMPLES = 2048
#: Program memory of the code table (logger.asm's CODE_TABLE).
CODE_TABLE = 0x0800
#: Samples of the production build's run that measures the interrupt (two pages: every page position).
ISR_PROBE_SAMPLES = 64
#: Cycles of the interrupt after its exit stamp (the write of ``SWAPF W_TEMP, F``): that SWAPF, ``SWAPF
#: W_TEMP, W`` and RETFIE (2).
ISR_TAIL_CYCLES = 4
#: Bit of a table word (x code) that presses the marker button.
TABLE_MARK_BIT = 10
#: gpsim's ADCON0, the kernels' W_TEMP (common RAM) and the page buffer's two halves.
ADCON0_ADDR, W_TEMP_ADDR = 0x1F, 0x7F
PAGE_ADDRS = tuple(range(0x110, 0x150)) + tuple(range(0x190, 0x1D0))
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


def _table_words(codes: np.ndarray, flags: np.ndarray) -> np.ndarray:
    words = np.asarray(codes, np.int64).reshape(-1, 3).copy()
    words[:, 0] |= ((np.asarray(flags) & FLAG_MARK) != 0).astype(np.int64) << TABLE_MARK_BIT
    return words.reshape(-1)


def _page_fsr(sample_number: int) -> int:
    w = sample_number % 32
    return 0x10 + 4 * w if w < 16 else 0x90 + 4 * (w - 16)


@dataclass(frozen=True)
class _Build:
    cod: Path
    symbols: dict[str, int]


def _assemble(build_dir: Path, defines: dict[str, int], *, test: bool) -> _Build:
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


_WRITE = re.compile(r"^0x([0-9A-Fa-f]+) p16f877|^\s+Wrote: 0x([0-9A-Fa-f]+) to \S+\(0x([0-9A-Fa-f]+)\)", re.M)


def _writes(log_text: str, wanted: set[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cycle, address, value) of every logged write to an address in ``wanted``."""
    cyc, addr, val = [], [], []
    now = 0
    for m in _WRITE.finditer(log_text):
        if m.group(1) is not None:
            now = int(m.group(1), 16)
            continue
        a = int(m.group(3), 16)
        if a in wanted and not (cyc and cyc[-1] == now and addr[-1] == a):   # BSF ADCON0, GO is logged twice
            cyc.append(now)
            addr.append(a)
            val.append(int(m.group(2), 16))
    return np.asarray(cyc, np.int64), np.asarray(addr, np.int64), np.asarray(val, np.int64)


def _gpsim(build: _Build, addrs: list[int], stop: str, timeout_s: float) -> str:
    """Run ``build`` in gpsim, logging writes to ``addrs``, until ``stop`` (``e LABEL`` or ``c CYCLES``)."""
    with tempfile.TemporaryDirectory(prefix="gpsim-logger-") as tmp:
        log = Path(tmp) / "writes.log"
        lines = [*([f"log on {log}"] if addrs else []), *(f"log w {a}" for a in addrs), f"break {stop}", "run",
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
        return log.read_text(errors="replace") if log.exists() else ""


#: Stage 2's state in RAM, in logger_ram.inc's order (G1X .. THR_H, 29 bytes): what a chunk hands the next.
STATE_BYTES = 29
#: RAM the harness snapshots after each sample (bank-0 symbols): stage outputs and state.
_SNAPSHOT = ("FX_L", "FX_H", "FY_L", "FY_H", "FZ_L", "FZ_H", *(f"G{s}{a}" for s in "12" for a in "XYZ"), "AV_L", "AV_H")


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
    isr_cycles
        ``(n,)`` the interrupt, vector to RETFIE, as the production build takes it at this sample's page position.
    stage_cycles
        ``(n, 2)`` stage 1 (the word's read-back to the store of ``FZ``) and stages 2 and 3 (to the main
        loop's ``DECF PENDING``), less any interrupt inside them.
    acquisition_cycles_min
        The shortest channel select to GO seen (the acquisition time the ADC got).
    period_cycles
        Measured cycles between two interrupts (the production build; all equal).
    simulated_cycles, gpsim_s, wall_s
        Cycles gpsim simulated, the wall time of the gpsim runs (sum over chunks), the whole run's wall time.
    """

    packed: np.ndarray
    calibrated: np.ndarray
    gravity: np.ndarray
    a_v: np.ndarray
    isr_cycles: np.ndarray
    stage_cycles: np.ndarray
    acquisition_cycles_min: int
    period_cycles: int
    simulated_cycles: int
    gpsim_s: float
    wall_s: float


@dataclass(frozen=True)
class _ChunkOut:
    packed: np.ndarray
    ram: np.ndarray            # (n, len(_SNAPSHOT) * bytes) snapshot bytes, see _snapshot_values
    stage_cycles: np.ndarray
    acquisition_cycles_min: int
    final_state: list[int]     # STATE_BYTES bytes, the next chunk's start
    simulated_cycles: int
    gpsim_s: float


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


def _replay_log(cyc, addr, val, n, sym, state0):
    """One pass over the log: the RAM bytes ``sym`` names after each sample (snapshots at the main loop's
    ``DECF PENDING``, outside the interrupt) and each sample's stage cycles."""
    ram = dict(state0)
    snap_addrs = sorted(a for a in ram)
    snaps, stages = [], []
    in_isr, isr_t, isr_sum = False, 0, 0
    t_b0 = t_fz = None
    isr_at_b0 = isr_at_fz = 0
    for t, a, v in zip(cyc.tolist(), addr.tolist(), val.tolist()):
        if a == W_TEMP_ADDR:
            in_isr = not in_isr
            if in_isr:
                isr_t = t
            else:
                isr_sum += t + ISR_TAIL_CYCLES - isr_t
            continue
        if in_isr:
            continue
        if a in ram:
            ram[a] = v
        if a == sym["B0"]:
            t_b0, isr_at_b0 = t, isr_sum
        elif a == sym["FZ_H"]:
            t_fz, isr_at_fz = t, isr_sum
        elif a == sym["PENDING"] and t_b0 is not None:          # the sample's DECF (not the set-up's CLRF)
            snaps.append([ram[x] for x in snap_addrs])
            stages.append((t_fz - t_b0 - (isr_at_fz - isr_at_b0), t - t_fz - (isr_sum - isr_at_fz)))
            t_b0 = None
    if len(snaps) != n:
        raise PicError(f"gpsim's main loop finished {len(snaps)} samples of {n}")
    return np.asarray(snaps, np.int64), np.asarray(stages, np.int64), ram


def _state_bytes(sym: dict[str, int], ram: dict[int, int]) -> list[int]:
    g = sym["G1X"]
    return [ram[g + i] for i in range(STATE_BYTES)]


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
    chunk_samples
        Samples per gpsim run (at most :data:`CHUNK_SAMPLES`).
    workers
        gpsim processes at a time (runs in parallel; the chunks of one run one after the other).
    """

    def __init__(self, *, sampling_rate_hz: float = 50.0, fosc_hz: float = DEFAULT_FOSC_HZ,
                 gravity_shift: int | None = None,
                 source_impedance_ohm: float = 32e3, chunk_samples: int = CHUNK_SAMPLES, workers: int = 2,
                 timeout_s: float = 600.0) -> None:
        self.sampling_rate_hz = sampling_rate_hz
        self.fosc_hz = fosc_hz
        self.gravity_shift = gravity_shift if gravity_shift is not None else SampleCounts.at(
            EventParameters(), OnlineParameters(), sampling_rate_hz).gravity_shift
        #: the kernel's G_MIN: the smallest ``|g|`` that gives an a_v, raw Q2.13
        self.min_gravity_raw = int(ACC_Q.from_float(OnlineParameters().min_gravity_g))
        self.source_impedance_ohm = source_impedance_ohm
        self.chunk_samples = chunk_samples
        self.workers = workers
        self.timeout_s = timeout_s

    def _defines(self, first_sample: int, session: bool) -> dict[str, int]:
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        return dict(CCP_PERIOD=t.ccpr1, T1_SETUP=t.t1con,
                    ACQ_LOOPS=acquisition_loops(self.fosc_hz, self.source_impedance_ohm),
                    FIRST_SAMPLE_L=first_sample & 0xFF, FIRST_SAMPLE_H=(first_sample >> 8) & 0xFF,
                    PAGE_START=_page_fsr(first_sample), SESSION_START=int(session), G_SHIFT=self.gravity_shift,
                    G_MIN=self.min_gravity_raw)

    def _chunk(self, codes, flags, cal_bytes, first_sample, state) -> _ChunkOut:
        """One gpsim run; ``state``: stage 2's bytes to start from (None: a START)."""
        with tempfile.TemporaryDirectory(prefix="pic-logger-") as tmp:
            d = Path(tmp)
            (d / "calibration.inc").write_text("".join(f"        retlw   0x{b:02X}\n" for b in cal_bytes))
            (d / "state.inc").write_text("".join(f"        retlw   0x{b:02X}\n" for b in (state or [0] * STATE_BYTES)))
            words = _table_words(codes, flags)
            (d / "codes.inc").write_text("".join(f"        dw      0x{w:03X}\n" for w in words))
            build = _assemble(d, dict(self._defines(first_sample, state is None), N_SAMPLES=codes.shape[0]),
                              test=True)
            sym = build.symbols
            tracked = {sym[k] + i for k in _SNAPSHOT for i in range(4 if k.startswith("G") else 1)}
            tracked |= {sym["G1X"] + i for i in range(STATE_BYTES)}
            logged = sorted(tracked | {sym["B0"], sym["PENDING"], W_TEMP_ADDR, ADCON0_ADDR, *PAGE_ADDRS})
            t0 = time.perf_counter()
            text = _gpsim(build, logged, "e harness_done", self.timeout_s)
            dt = time.perf_counter() - t0
        cyc, addr, val = _writes(text, set(logged))
        n = codes.shape[0]
        g0 = sym["G1X"]
        start = {a: 0 for a in tracked}
        start.update({g0 + i: b for i, b in enumerate(state or [0] * STATE_BYTES)})
        if state is None:
            start[sym["THR_L"]] = 2
        snaps, stages, ram = _replay_log(cyc, addr, val, n, sym, start)
        order = sorted(tracked)
        cols = {a: i for i, a in enumerate(order)}
        pick = [cols[sym[k] + i] for k in _SNAPSHOT for i in range(4 if k.startswith("G") else 1)]
        adc = cyc[addr == ADCON0_ADDR][1:]                  # the first is the set-up's
        acq = int(np.min(adc[1::2] - adc[0::2])) if adc.size >= 2 else 0
        return _ChunkOut(_packed(addr, val, n, first_sample), snaps[:, pick], stages, acq,
                         _state_bytes(sym, ram), int(cyc.max()) if cyc.size else 0, dt)

    def _run_chunks(self, c, f, cal_bytes, first_sample_number, a, b) -> list[_ChunkOut]:
        """The chunks of one logging run ``[a, b)``, one after the other, each starting where the last ended."""
        out, state = [], None
        for i in range(a, b, self.chunk_samples):
            j = min(i + self.chunk_samples, b)
            part = self._chunk(c[i:j], f[i:j], cal_bytes, first_sample_number + i, state)
            out.append(part)
            state = part.final_state
        return out

    def measure_isr(self) -> tuple[np.ndarray, int]:
        """The production build's interrupt: cycles (vector to RETFIE) at each of the 32 page positions of a
        run started at sample 0, and the period between interrupts."""
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        with tempfile.TemporaryDirectory(prefix="pic-logger-isr-") as tmp:
            build = _assemble(Path(tmp), self._defines(0, True), test=False)
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

    def raw_speed(self, n_samples: int) -> tuple[int, float]:
        """gpsim's own speed on this firmware: the production build, nothing logged, for ``n_samples`` sample
        periods; returns (cycles simulated, wall seconds of the gpsim process)."""
        t = timer_setup(self.sampling_rate_hz, self.fosc_hz)
        with tempfile.TemporaryDirectory(prefix="pic-logger-raw-") as tmp:
            build = _assemble(Path(tmp), self._defines(0, True), test=False)
            t0 = time.perf_counter()
            _gpsim(build, [], f"c {t.period_cycles * n_samples}", self.timeout_s)
            return t.period_cycles * n_samples, time.perf_counter() - t0

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
        with ThreadPoolExecutor(max_workers=max(1, self.workers)) as pool:
            per_run = list(pool.map(lambda ab: self._run_chunks(c, f, cal_bytes, first_sample_number, *ab), runs))
            isr_by_pos, period = self.measure_isr()
        parts = [p for r in per_run for p in r]
        if not parts:
            raise ValueError("no samples to run")
        ram = np.concatenate([p.ram for p in parts])
        calibrated = np.stack([_int(ram[:, 2 * k:2 * k + 2]) for k in range(3)], axis=1)
        gravity = np.stack([_int(ram[:, 6 + 4 * k:10 + 4 * k]) for k in range(6)], axis=1)
        a_v = _int(ram[:, 30:32])
        positions = (first_sample_number + np.arange(c.shape[0])) % 32
        return LoggerRun(
            packed=np.concatenate([p.packed for p in parts]), calibrated=calibrated, gravity=gravity, a_v=a_v,
            isr_cycles=isr_by_pos[positions], stage_cycles=np.concatenate([p.stage_cycles for p in parts]),
            acquisition_cycles_min=min(p.acquisition_cycles_min for p in parts), period_cycles=period,
            simulated_cycles=sum(p.simulated_cycles for p in parts), gpsim_s=sum(p.gpsim_s for p in parts),
            wall_s=time.perf_counter() - t0)


def run_starts(flags: np.ndarray) -> list[int]:
    """Where the logging runs start: sample 0 and every sample with the S flag."""
    return sorted({0, *np.flatnonzero(np.asarray(flags) & FLAG_SESSION_START).tolist()})


# ---------------------------------------------------------------------------------------------------
# memory


@dataclass(frozen=True)
class MemoryMap:
    """RAM and program memory of the production build, from gpasm's listing (measured).

    ``ram_bytes`` per block (bank 0-3 and common RAM), ``program_words``: words from 0 to ``code_end``.
    """

    ram_bytes: dict[str, int]
    program_words: int
    kernel_words: int

    @property
    def ram_total_bytes(self) -> int:
        return sum(self.ram_bytes.values())


def memory_map(*, sampling_rate_hz: float = 50.0, fosc_hz: float = DEFAULT_FOSC_HZ) -> MemoryMap:
    """Assemble the production build and read its RAM blocks' ends and program size from the listing."""
    with tempfile.TemporaryDirectory(prefix="pic-logger-map-") as tmp:
        b = _assemble(Path(tmp), PicLogger(sampling_rate_hz=sampling_rate_hz, fosc_hz=fosc_hz)._defines(0, True),
                      test=False)
    s = b.symbols
    ram = {"bank 0": s["RAM0_END"] - 0x20, "bank 1": s["RAM1_END"] - 0xA0,
           "bank 2 (page buffer)": s["RAM2_END"] - 0x110,
           "bank 3 (page buffer)": s["RAM3_END"] - 0x190, "common (kernels, W_TEMP)": 16}
    return MemoryMap(ram, s["code_end"], s["kernels_end"] - s["kernels_begin"])


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
            line = f"  {s.name:<18} {s.n_identical:,} of {s.n_compared:,} samples identical"
            if s.first_difference:
                d = s.first_difference
                line += (f"; first difference: sample {d['sample']}, {d['field']}: gpsim {d['gpsim']}, "
                         f"model {d['model']}")
            lines.append(line)
        lines.append(f"cycles per sample (measured in gpsim; {self.period_cycles:,} available):")
        for k, v in self.cycles.items():
            lines.append(f"  {k:<28} mean {v['mean']:>8,.1f}   p99 {v['p99']:>8,.1f}   worst {v['worst']:>7,}")
        lines.append(f"ADC acquisition: {self.acquisition_cycles_min} cycles from channel select to GO (measured; "
                     f"needed {self.acquisition_cycles_needed:.1f})")
        m = self.memory
        lines.append(f"RAM (measured, gpasm listing): {m.ram_total_bytes} of 368 bytes: "
                     + ", ".join(f"{k} {v}" for k, v in m.ram_bytes.items()))
        lines.append(f"program memory (measured): {m.program_words} of 8192 words ({m.kernel_words} kernels)")
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
               "acquisition_cycles_min": self.acquisition_cycles_min,
               "acquisition_cycles_needed": round(self.acquisition_cycles_needed, 1),
               "ram_bytes_measured": self.memory.ram_bytes, "ram_total_bytes": self.memory.ram_total_bytes,
               "program_words_measured": self.memory.program_words, "kernel_words": self.memory.kernel_words,
               "wall_s": round(self.wall_s, 3), "gpsim_s": round(self.gpsim_s, 3),
               "realtime_factor": round(self.realtime_factor, 2), "notes": self.notes}
        return json.dumps(doc, indent=2)


def verify(codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *, sampling_rate_hz: float = 50.0,
           source: str = "codes", first_sample_number: int = 0, harness: PicLogger | None = None,
           a_v: bool = True) -> PicVerification:
    """Run the assembly in gpsim on ``codes`` and compare it with the model, stage by stage.

    Stages: *packed words* (the page buffer's bytes vs :func:`~gaitlog.protocol.packing.pack_words`),
    *calibrated axes* (``FX..FZ`` vs :func:`~gaitlog.firmware_sim.algorithms.probe.calibrated_axes`) and
    *gravity* (``G1``, ``G2`` after each sample vs :func:`~gaitlog.firmware_sim.algorithms.probe.gravity_states`,
    restarted at each run's first sample) and *a_v* (``AV`` vs
    :func:`~gaitlog.firmware_sim.algorithms.probe.vertical_acceleration`; ``a_v=False`` leaves it out, for a
    calibration whose ``|g|`` exceeds the model's 16-bit divisor, where the model raises).
    Raises :class:`PicError` when gpasm/gpsim are absent or fail.
    """
    why = missing_tools()
    if why:
        raise PicError(why)
    t0 = time.perf_counter()
    c = np.asarray(codes, np.int64).reshape(-1, 3)
    f = np.asarray(flags, np.int64).reshape(-1)
    h = harness or PicLogger(sampling_rate_hz=sampling_rate_hz)
    run = h.run(c, f, calibration, first_sample_number=first_sample_number)
    expect_packed = np.frombuffer(words_to_bytes(pack_words(c, f)), np.uint8).reshape(-1, 4)
    model_f = calibrated_axes(c, calibration)
    starts = run_starts(f)
    model_g = np.concatenate([gravity_states(model_f[a:b], h.gravity_shift)
                              for a, b in zip(starts, starts[1:] + [c.shape[0]])])
    stages = [_compare("packed words", ("byte 0", "byte 1", "byte 2", "byte 3"), run.packed.astype(np.int64),
                       expect_packed.astype(np.int64)),
              _compare("calibrated axes", ("fx", "fy", "fz"), run.calibrated, model_f),
              _compare("gravity", ("g1x", "g1y", "g1z", "g2x", "g2y", "g2z"), run.gravity, model_g)]
    if a_v:
        model_av = vertical_acceleration(model_f, model_g[:, 3:], h.min_gravity_raw)
        stages.append(_compare("a_v", ("a_v",), run.a_v.reshape(-1, 1), model_av.reshape(-1, 1)))
    total = run.isr_cycles + run.stage_cycles.sum(axis=1)
    cycles = {"sampling interrupt": _stats(run.isr_cycles), "stage 1 (calibration)": _stats(run.stage_cycles[:, 0]),
              "stages 2-3 (gravity, a_v)": _stats(run.stage_cycles[:, 1]), "total in assembly": _stats(total)}
    need = (adc_acquisition_s(h.source_impedance_ohm) + 2 * adc_tad_s(h.fosc_hz)) * h.fosc_hz / 4.0
    notes = ["the I2C page write, the UART command handler and the algorithm after step 3 are not yet in assembly",
             f"ADC conversion: {ADC_CONVERSION_TAD} TAD as gpsim times it"]
    return PicVerification(source, int(c.shape[0]), h.sampling_rate_hz, stages, cycles, run.acquisition_cycles_min,
                           need, run.period_cycles, memory_map(sampling_rate_hz=h.sampling_rate_hz, fosc_hz=h.fosc_hz),
                           run.gpsim_s, time.perf_counter() - t0, gpsim_version(), notes)
