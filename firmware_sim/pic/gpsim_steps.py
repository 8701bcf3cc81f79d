"""The step record (step 6 of the on-line algorithm, ``step_record.asm``) in gpsim, against the model.

``step_record.asm`` is kernel.py's ``_finalise`` in PIC16 assembly: the heel strike, the window, the toe-off,
M4's range, the two passes over a_v[s..e], M1-M5, the flags and the 20-byte record with its CRC. This module
runs it in gpsim on every step of a run and compares the record bytes with the model's:

* the model's inputs of each ``_finalise`` call (e, m, ``LAST``, ``FLAGS``, the sticky saturation flag, the
  absolute sample number of m) and its records come from
  :func:`gaitlog.firmware_sim.algorithms.probe.finalise_calls`;
* the bench (``step_bench.asm``) holds them as a table in program memory and the step configuration
  (:func:`config_bytes`) in the data EEPROM; ``finalise`` reads the run's a_v from the scratch ring on the I2C
  bus, a 24xx256 that gpsim's ``e24xx256`` module models and the gpsim script fills (:data:`RING_256K_SAMPLES`
  samples; the model's emulated ring is set to as many, :func:`with_scratch_ring`), or, in the test build,
  from a table in program memory (``reader="table"``);
* up to :data:`STEPS_PER_RUN` steps whose reads all fall within :data:`TABLE_SAMPLES` samples are one gpasm
  and one gpsim run, and nothing stops the simulation before its end;
* gpsim's register-write log gives each step's record bytes (``OUTB``), the state after it and two cycle
  stamps around the call (``MARK``); :func:`stack_levels` bounds the stack over every path of the program.

A difference names the step and the record field (:data:`gaitlog.protocol.steps.STEP_RECORD_OFFSETS`).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.probe import FinaliseTrace, finalise_calls
from gaitlog.firmware_sim.pic.gpsim_bench import PIC_DIR, copy_sources, missing_tools
from gaitlog.firmware_sim.pic.step_config import CFG_W3, MAX_R3, MAX_R_EVENTS, s32_le_bytes, config_bytes  # noqa: F401 -- re-exported
from gaitlog.firmware_sim.pic.gpsim_logger import BENCH_RING_SAMPLES, I2C_SETUP, PicError, _symbols, _writes, scratch_offset
from gaitlog.protocol.steps import STEP_RECORD_OFFSETS, STEP_RECORD_SIZE

__all__ = ["STEP_BENCH_ASM", "STEPS_PER_RUN", "TABLE_SAMPLES", "CALL_STAMP_CYCLES", "config_bytes",
           "StepBenchRun", "program_words", "stack_levels", "finalise_stack_levels", "run_bench", "RecordDifference", "StepVerification", "verify_steps", "compare", "RING_256K_SAMPLES", "with_scratch_ring",
           "missing_tools"]

#: The bench's source.
STEP_BENCH_ASM = PIC_DIR / "step_bench.asm"
#: Steps per gpsim run: the step table at 0x0A00-0x0FFF, 12 words a step.
STEPS_PER_RUN = (0x1000 - 0x0A00) // 12
#: Samples a gpsim run may read: the test build's table at 0x1000-0x1FFF holds as many (two words a sample).
TABLE_SAMPLES = 0x1000 // 2
#: Cycles between the two ``MARK`` stamps that are not finalise's CALL, body and RETURN (the second MOVWF).
CALL_STAMP_CYCLES = 1
#: Bytes the bench writes to ``OUTB`` per step: the record, ALG_FLAGS, ALG_LAST (LE), the kernels' FLAGS.
OUT_BYTES = STEP_RECORD_SIZE + 4


#: Samples a 24xx256 holds (32 KiB, two bytes a sample): the bench's EEPROM.
RING_256K_SAMPLES = BENCH_RING_SAMPLES


def with_scratch_ring(algorithm, samples: int = RING_256K_SAMPLES):
    """``algorithm`` (an :class:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`) with its emulated
    scratch ring enlarged to ``samples`` (a power of two dividing 2^16), as an EEPROM ring holds them.

    The emulator's ring is the smallest power of two that ``online._scratch_size`` finds sufficient (256 at
    50 Hz), but a weak stop step (the stop rule) can be finalised more than that after its foot-flat: the
    emulator then reads samples its ring has overwritten, where the EEPROM ring still holds them.
    """
    if samples & (samples - 1) or not 0 < samples <= 1 << 16:
        raise ValueError(f"the ring's {samples} samples must be a power of two up to 65,536")
    algorithm.config.cfg_i[kernel.CI_SCRATCH] = samples
    algorithm._scr = np.zeros(samples, algorithm._scr.dtype)
    return algorithm


# ---------------------------------------------------------------------------------------------------------
# the stack: a static bound over every path of the assembled program


def program_words(hex_path: Path) -> dict[int, int]:
    """Program memory (word address -> 14-bit word) of an Intel HEX file as gpasm writes it (INHX8M/32)."""
    mem: dict[int, int] = {}
    base = 0
    for line in hex_path.read_text().split():
        b = bytes.fromhex(line[1:])
        n, addr, kind, data = b[0], b[1] << 8 | b[2], b[3], b[4:4 + b[0]]
        if kind == 4:
            base = (data[0] << 8 | data[1]) << 16
        elif kind == 0:
            for i in range(0, n, 2):
                mem[(base + addr + i) // 2] = data[i] | data[i + 1] << 8
    return mem


def stack_levels(mem: dict[int, int], entry: int) -> int:
    """The most return addresses a call of ``entry`` puts on the stack, its own included, over every path
    (CALL k: one more level at k; GOTO k: the same level; a skip: both next instructions; RETURN, RETLW: back).
    Computed jumps (writes to PCL) are refused: their targets are not in the code."""
    memo: dict[int, int] = {}
    active: set[int] = set()

    def below(pc: int) -> int:
        if pc in memo:
            return memo[pc]
        if pc in active:                           # a loop: no deeper than the path that entered it
            return 0
        w = mem.get(pc)
        if w is None:
            raise ValueError(f"the path from 0x{entry:04X} runs into unprogrammed word 0x{pc:04X}")
        active.add(pc)
        if w in (0x0008, 0x0009) or w & 0x3C00 == 0x3400:              # RETURN, RETFIE, RETLW
            d = 0
        elif w & 0x3800 == 0x2000:                                      # CALL
            d = max(1 + below(w & 0x7FF), below(pc + 1))
        elif w & 0x3800 == 0x2800:                                      # GOTO
            d = below(w & 0x7FF)
        elif w & 0x3C00 in (0x1800, 0x1C00) or w & 0x3F00 in (0x0B00, 0x0F00):   # BTFSC/BTFSS, DECFSZ/INCFSZ
            d = max(below(pc + 1), below(pc + 2))
        else:
            if w & 0x3000 == 0 and w & 0x80 and w & 0x7F == 0x02:       # a byte operation that writes PCL
                raise ValueError(f"a computed jump at 0x{pc:04X}")
            d = below(pc + 1)
        active.discard(pc)
        memo[pc] = d
        return d

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 20000))
    try:
        return 1 + below(entry)
    finally:
        sys.setrecursionlimit(limit)


# ---------------------------------------------------------------------------------------------------------
# the bench


@dataclass(frozen=True)
class StepBenchRun:
    """The assembly's outputs for every traced call.

    Attributes
    ----------
    records
        ``(k, 20)`` uint8: the record bytes.
    state
        ``(k, 4)`` int64: after the call, the algorithm's FLAGS, LAST, the kernels' FLAGS register.
    cycles
        ``(k,)`` int64: the call, CALL and RETURN included (gpsim's cycle counter).
    program_words, kernel_words, ram_bytes
        finalise and its helpers (without the kernels) and the kernels: words from the listing; RAM of its map
        (banks 2 and 3 tails, the bank-0 alias).
    stack_levels
        :func:`stack_levels` of ``finalise`` in the assembled bench (every path, the kernels included).
    gpsim_runs, simulated_cycles, gpsim_s
        gpsim runs, the cycles they simulated, their wall time.
    """

    records: np.ndarray
    state: np.ndarray
    cycles: np.ndarray
    program_words: int
    kernel_words: int
    ram_bytes: dict
    stack_levels: int
    gpsim_runs: int
    simulated_cycles: int
    gpsim_s: float


def _reach(trace: FinaliseTrace, i: int, ci: dict) -> tuple[int, int]:
    """The absolute samples call ``i`` may read (its heel strike, window, toe-off, range, passes)."""
    r = max(ci["R3"], ci["R10"], ci["R5"])
    m = int(trace.m_abs[i])
    e = m - ((int(trace.m[i]) - int(trace.e[i])) & 0xFFFF)
    lo = e - ci["HS_BEFORE"] - r
    if trace.flags[i] & 4:                                       # F_LAST: a window may be read
        back = (int(trace.e[i]) - int(trace.last[i])) & 0xFFFF
        if back <= ci["MAX_STEP"]:
            lo = min(lo, e - back - r)
    return lo, m + r


def _segments(trace: FinaliseTrace, ci: dict) -> list[tuple[int, int, int, int]]:
    """Greedy runs of consecutive calls: ``(first call, end call, first and last sample read)``."""
    out, a = [], 0
    n = len(trace.e)
    while a < n:
        lo, hi = _reach(trace, a, ci)
        b = a + 1
        while b < n and b - a < STEPS_PER_RUN:
            lo2, hi2 = _reach(trace, b, ci)
            if max(hi, hi2) - min(lo, lo2) + 1 > TABLE_SAMPLES:
                break
            lo, hi = min(lo, lo2), max(hi, hi2)
            b += 1
        if hi - lo + 1 > TABLE_SAMPLES:
            raise ValueError(f"step {a} reads {hi - lo + 1} samples, more than the table's {TABLE_SAMPLES}")
        out.append((a, b, lo, hi))
        a = b
    return out


#: gpsim's I2C bus: the logger harness's (the 24xx256 on RC3 SCL, RC4 SDA, 10 kOhm pull-ups).
_I2C_SETUP = I2C_SETUP


def _run_start(trace: FinaliseTrace) -> int:
    """The run's first sample number (``m_abs`` of a call less its run index ``m``; the first call comes before
    the 16-bit index wraps)."""
    return int(trace.m_abs[0]) - int(trace.m[0]) if len(trace.m) else 0


def _eeprom_lines(trace: FinaliseTrace, first: int, last: int) -> list[str]:
    """gpsim commands that fill the 24xx256 with the segment's a_v where the logger's scr_write puts them: the
    run's sample ``f`` at ring sample ``(S + f) mod 32,512`` (``kernel.scratch_ring_sample``), byte twice that,
    its bit 15 dropped as the 24xx256 drops it."""
    out, start = [], _run_start(trace)
    for j in range(max(first, 0), min(last + 1, trace.a_v.size)):
        v = int(trace.a_v[j]) & 0xFFFF
        addr = 2 * kernel.scratch_ring_sample(start, j) % (2 * RING_256K_SAMPLES)
        out += [f"ee.eeData[0x{addr:X}] = 0x{v & 0xFF:X}", f"ee.eeData[0x{addr + 1:X}] = 0x{v >> 8:X}"]
    return out


def _write_tables(folder: Path, trace: FinaliseTrace, a: int, b: int, first: int, cfg: list[int]) -> None:
    words = []
    for i in range(a, b):
        row = [int(trace.e[i]), int(trace.m[i]), int(trace.last[i])]
        words += [x for v in row for x in (v & 0xFF, v >> 8)]
        words += [int(trace.flags[i]) & 0xFF, int(trace.sticky[i]) & 1] + s32_le_bytes(int(trace.m_abs[i]))
    (folder / "steps.inc").write_text("".join(f"        dw      0x{w:02X}\n" for w in words))
    idx = np.arange(first, first + TABLE_SAMPLES)
    ok = (idx >= 0) & (idx < trace.a_v.size)
    av = np.where(ok, trace.a_v[np.clip(idx, 0, max(trace.a_v.size - 1, 0))], 0) & 0xFFFF
    last = int(np.flatnonzero(ok)[-1]) + 1 if ok.any() else 0
    (folder / "scratch.inc").write_text("".join(f"        dw      0x{v & 0xFF:02X}, 0x{v >> 8:02X}\n"
                                                for v in av[:last].tolist()))
    (folder / "config.inc").write_text("        org     0x2100\n" + "".join(
        f"        de      0x{v:02X}\n" for v in cfg))


def _assemble(folder: Path, source: Path, n_steps: int, j0: int, table: bool = False, k0: int = 0) -> dict[str, int]:
    proc = subprocess.run(["gpasm", "-p", "p16f877", "-q", "-w2", "-D", f"N_STEPS=0x{n_steps:X}",
                           "-D", f"SCR_J0=0x{j0 & 0xFFFF:X}", "-D", f"SCR_SAMPLES=0x{kernel.SCRATCH_RING_SAMPLES:X}",
                           "-D", f"SCR_K0=0x{k0:X}", *(["-D", "TABLE_READER"] if table else []),
                           source.name], capture_output=True, text=True, timeout=120, cwd=folder)
    cod = folder / (source.stem + ".cod")
    if proc.returncode != 0 or not cod.exists():
        errors = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "rror" in ln] or [proc.stderr.strip()]
        raise PicError(f"gpasm failed on {source.name}: {errors[0][-300:]}")
    return _symbols(folder / (source.stem + ".lst"))


#: gpsim stops a bench run after this many cycles a step (a step takes a few hundred thousand).
MAX_CYCLES_PER_STEP = 5_000_000


def _gpsim(folder: Path, cod: Path, addrs: list[int], n_steps: int, timeout_s: float,
           setup: list[str]) -> tuple[str, str]:
    log = folder / "writes.log"
    lines = [*setup, f"log on {log}", *(f"log w 0x{a:X}" for a in addrs),
             f"break c {MAX_CYCLES_PER_STEP * (n_steps + 1)}", "break e bench_done", "run", "cycles", "quit"]
    (folder / "run.stc").write_text("\n".join(lines) + "\n")
    proc = subprocess.run(["gpsim", "-i", "-s", cod.name, "-c", "run.stc"], capture_output=True, text=True,
                          timeout=timeout_s, cwd=folder)
    bad = ("***ERROR", "stack overflow", "stack underflow", "Stack overflow")
    if proc.returncode != 0 or any(b in proc.stdout for b in bad):
        err = next((ln for ln in proc.stdout.splitlines() if any(b in ln for b in bad)), proc.stderr.strip()[-300:])
        raise PicError(f"gpsim failed on {cod.name} (exit {proc.returncode}): {err}")
    tail = proc.stdout.strip()[-400:]
    if "Hit a Breakpoint" not in proc.stdout or "cycle break" in proc.stdout.lower():
        raise PicError(f"gpsim stopped before bench_done: {tail[-300:]}")
    return (log.read_text(errors="replace") if log.exists() else ""), proc.stdout


def finalise_stack_levels(*, overrides: dict[str, str] | None = None) -> int:
    """:func:`stack_levels` of ``finalise`` in the bench assembled without tables (``overrides``: as
    :func:`run_bench`)."""
    with tempfile.TemporaryDirectory(prefix="gpsim-steps-") as tmp:
        folder = Path(tmp)
        copy_sources(folder, STEP_BENCH_ASM)
        for name, text in (overrides or {}).items():
            (folder / name).write_text(text)
        for name in ("steps.inc", "scratch.inc"):
            (folder / name).write_text("")
        (folder / "config.inc").write_text("        org     0x2100\n")
        sym = _assemble(folder, STEP_BENCH_ASM, 1, 0)
        return stack_levels(program_words(folder / (STEP_BENCH_ASM.stem + ".hex")), sym["finalise"])


def run_bench(trace: FinaliseTrace, cfg_i: np.ndarray, cfg_v: np.ndarray, *, calibrated: bool = True,
              m4_eighths: int | None = None, overrides: dict[str, str] | None = None,
              reader: str = "i2c", timeout_s: float = 600.0) -> StepBenchRun:
    """Run ``step_bench.asm`` on every call of ``trace``; ``overrides`` replaces source files by name (a test's
    broken variant). ``reader``: the scratch ring on the I2C bus (``"i2c"``, the firmware's reader, a 24xx256
    in gpsim filled by its script) or the test build's table in program memory (``"table"``)."""
    if reader not in ("i2c", "table"):
        raise ValueError(f"reader must be 'i2c' or 'table', got {reader!r}")
    why = missing_tools()
    if why:
        raise PicError(f"the step bench needs gputils and gpsim: {why}")
    src = STEP_BENCH_ASM
    ci = {k: int(cfg_i[v]) for k, v in kernel.CI.items()}
    cfg = config_bytes(cfg_i, cfg_v, calibrated=calibrated, m4_eighths=m4_eighths)
    recs, state, cycles = [], [], []
    sym: dict[str, int] = {}
    sim_cycles, t_gpsim, runs, levels = 0, 0.0, 0, 0
    for a, b, first, last in _segments(trace, ci):
        with tempfile.TemporaryDirectory(prefix="gpsim-steps-") as tmp:
            folder = Path(tmp)
            copy_sources(folder, src)
            for name, text in (overrides or {}).items():
                (folder / name).write_text(text)
            _write_tables(folder, trace, a, b, first, cfg)
            newest = min(last, trace.a_v.size - 1)          # the ring's offset once the segment's last is written
            sym = _assemble(folder, src, b - a, first, table=reader == "table",
                            k0=scratch_offset(_run_start(trace), newest))
            levels = max(levels, stack_levels(program_words(folder / (src.stem + ".hex")), sym["finalise"]))
            t0 = time.perf_counter()
            setup = [] if reader == "table" else [*_I2C_SETUP, *_eeprom_lines(trace, first, last)]
            log, out = _gpsim(folder, folder / (src.stem + ".cod"), [sym["OUTB"], sym["MARK"]], b - a, timeout_s,
                              setup)
            t_gpsim += time.perf_counter() - t0
            runs += 1
        cyc, addr, val = _writes(log, {sym["OUTB"], sym["MARK"]})
        marks = cyc[addr == sym["MARK"]]
        outs = val[addr == sym["OUTB"]]
        n = b - a
        if marks.size != 2 * n or outs.size != OUT_BYTES * n:
            raise PicError(f"gpsim wrote {marks.size} stamps and {outs.size} output bytes for {n} steps")
        cycles.append(marks[1::2] - marks[0::2] - CALL_STAMP_CYCLES)
        o = outs.reshape(n, OUT_BYTES)
        recs.append(o[:, :STEP_RECORD_SIZE])
        state.append(np.column_stack([o[:, 20], o[:, 21] | (o[:, 22] << 8), o[:, 23]]))
        sim_cycles += int(cyc.max()) if cyc.size else 0
    k = len(trace.e)
    ram = {"bank 2": sym.get("RAM2_STEP_END", 0x170) - 0x150, "bank 3": sym.get("RAM3_STEP_END", 0x1F0) - 0x1D0,
           "bank 0 alias": 6}
    return StepBenchRun(np.concatenate(recs).astype(np.uint8) if recs else np.zeros((0, 20), np.uint8),
                        np.concatenate(state) if state else np.zeros((0, 3), np.int64),
                        np.concatenate(cycles) if cycles else np.zeros(0, np.int64),
                        sym.get("step_code_end", 0) - sym.get("step_code_begin", 0),
                        sym.get("kernels_end", 0) - sym.get("kernels_begin", 0), ram, levels, runs, sim_cycles,
                        t_gpsim) \
        if k else StepBenchRun(np.zeros((0, 20), np.uint8), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), 0, 0,
                               {}, 0, 0, 0, 0.0)


# ---------------------------------------------------------------------------------------------------------
# the comparison


@dataclass(frozen=True)
class RecordDifference:
    """The first differing byte of a step: its index, the record field, both values."""

    step: int
    end_sample: int
    field: str
    pic: int
    model: int

    def __str__(self) -> str:
        return (f"step {self.step} (end_sample {self.end_sample}): {self.field} is {self.pic} on the PIC, "
                f"{self.model} in the model")


def _field_value(raw: bytes, name: str) -> int:
    off, size = STEP_RECORD_OFFSETS[name]
    order = "big" if name == "record_crc" else "little"
    signed = name == "heel_strike_samples"
    return int.from_bytes(raw[off:off + size], order, signed=signed)


def _first_difference(step: int, pic: bytes, model: bytes) -> RecordDifference:
    for name, (off, size) in STEP_RECORD_OFFSETS.items():
        if pic[off:off + size] != model[off:off + size]:
            return RecordDifference(step, _field_value(model, "end_sample"), name, _field_value(pic, name),
                                    _field_value(model, name))
    raise ValueError("the records are identical")


@dataclass(frozen=True)
class StepVerification:
    """gpsim's step records against the model's, for one run."""

    n_steps: int
    n_identical: int
    differences: list[RecordDifference]
    state_identical: bool
    pic_cycles: np.ndarray
    model_cycles: np.ndarray
    bench: StepBenchRun = field(repr=False)

    @property
    def identical(self) -> bool:
        return self.n_identical == self.n_steps and self.state_identical

    def summary(self) -> str:
        """One line, or the first difference."""
        head = f"step records       {self.n_identical} of {self.n_steps} identical"
        return head if not self.differences else f"{head}; first difference: {self.differences[0]}"


def verify_steps(algorithm, codes: np.ndarray, *, first_sample_number: int = 0,
                 overrides: dict[str, str] | None = None) -> StepVerification:
    """Run one run of ``codes`` through the model (``algorithm``, a fixed-point
    :class:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`) and the assembly; compare every record
    byte for byte, and the state each call leaves (``LAST``, ``FLAGS``, the sticky flag cleared)."""
    trace = finalise_calls(algorithm, codes, first_sample_number=first_sample_number)
    return compare(trace, algorithm.config, overrides=overrides)


def compare(trace: FinaliseTrace, config, *, overrides: dict[str, str] | None = None) -> StepVerification:
    """The bench on the calls of ``trace`` (of an algorithm with ``config``, its ``OnlineConfig``) against the
    records and state the model's calls left."""
    bench = run_bench(trace, config.cfg_i, config.cfg_v, calibrated=bool(config.step_config.calibrated),
                      overrides=overrides)
    model = trace.records.view(np.uint8).reshape(-1, STEP_RECORD_SIZE)
    diffs = [_first_difference(i, bench.records[i].tobytes(), model[i].tobytes())
             for i in range(model.shape[0]) if not np.array_equal(bench.records[i], model[i])]
    # the state after each call: LAST = e, F_LAST set, F_LAST_WEAK = F_PEND_WEAK, F_PEND_WEAK cleared
    f = trace.flags
    want_flags = ((f | 4) & ~(32 | 64)) | np.where(f & 32, 64, 0)
    state_ok = bool(np.array_equal(bench.state[:, 0], want_flags & 0xFF) and np.array_equal(bench.state[:, 1], trace.e)
                    and not np.any(bench.state[:, 2] & 1))
    return StepVerification(model.shape[0], model.shape[0] - len(diffs), diffs, state_ok, bench.cycles,
                            trace.cycles, bench)
