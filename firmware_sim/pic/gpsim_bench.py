"""The PIC16 arithmetic kernels run in gpsim, checked bit for bit against :mod:`gaitlog.firmware_sim.fixedpoint`.

The kernels (``firmware_sim/pic/*.asm``, calling convention in ``CONVENTION.md``) are assembled with
gputils' ``gpasm`` into one test program (``harness.asm``) and executed by ``gpsim``'s PIC16F877 model,
headless. One gpsim process runs one kernel over all its vectors: the command script stops the PIC at the
kernel's loop label before every call, writes the operands into the maths registers by symbol, runs the
call, and reads the results, the sticky flags and gpsim's cycle counter at the next stop. The difference of
two counter readings, minus the loop's ``GOTO`` (2 cycles), is the cost of one call including its ``CALL``
and ``RETURN``.

Each result is compared with the scalar definition of the same primitive in ``fixedpoint`` (``s_mul``,
``s_div``, ``s_div_round``, ``s_shift_right``, ``s_overflow``, ``s_isqrt``) on edge cases (word limits,
-2^31 / -1, negative rounding ties, division by zero, saturation) and random vectors (uniform words, random
bit lengths, near squares and exact ties). The measured cycles per call (min, mean, max) become the cycle
table that ``fixedpoint.CYCLES`` reads (``kernel_cycles.json``, written by
``gaitlog budget --measure-kernels``).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.fixedpoint import (
    CITED_CYCLES,
    CITED_SOURCES,
    C_DIV0,
    C_SAT,
    new_counters,
    s_div,
    s_div_round,
    s_isqrt,
    s_mul,
    s_overflow,
    s_shift_right,
)

__all__ = ["PIC_DIR", "CYCLE_TABLE_PATH", "KERNELS", "Kernel", "KernelRun", "missing_tools", "assemble",
           "vectors", "run_kernel", "measure", "cycle_table", "gpsim_version", "program_words", "write_cycle_table", "markdown_table"]

#: The assembly sources.
PIC_DIR = Path(__file__).resolve().parent
#: The measured cycle table that ``fixedpoint`` reads.
CYCLE_TABLE_PATH = PIC_DIR / "kernel_cycles.json"
#: Cycles of the harness loop's ``GOTO`` between two calls (not part of the kernel).
LOOP_GOTO_CYCLES = 2
#: Random vectors per kernel (besides the edge cases).
DEFAULT_RANDOM = 10_000

FLAG_SAT, FLAG_DIV0 = 1, 2


def _u(x: int, nbytes: int) -> list[int]:
    """Little-endian bytes of ``x`` (two's complement)."""
    x &= (1 << (8 * nbytes)) - 1
    return [(x >> (8 * i)) & 0xFF for i in range(nbytes)]


def _s(v: int, bits: int) -> int:
    """Signed value of a ``bits``-bit pattern."""
    return v - (1 << bits) if v >> (bits - 1) & 1 else v


def _names(prefix: str, nbytes: int) -> list[str]:
    """Register symbols of a word: ``ACC0``, ``ACC1``, ...; single registers (``FLAGS``) by their name."""
    return [prefix] if prefix == "FLAGS" else [f"{prefix}{i}" for i in range(nbytes)]


def _flags(cnt: np.ndarray) -> int:
    return (FLAG_SAT if cnt[C_SAT] else 0) | (FLAG_DIV0 if cnt[C_DIV0] else 0)


@dataclass(frozen=True)
class Kernel:
    """One assembly kernel: its registers and its definition in ``fixedpoint``.

    ``inputs`` are (register prefix, bytes) written before the call, ``outputs`` (prefix, bytes, signed)
    read after it; ``reference(*operands)`` gives the expected outputs and flags.
    """

    name: str
    select: int
    inputs: tuple[tuple[str, int], ...]
    outputs: tuple[tuple[str, int, bool], ...]
    reference: Callable[..., tuple[tuple[int, ...], int]]
    doc: str


def _ref_mul(signed: bool):
    def f(a: int, b: int):
        cnt = new_counters()
        return (s_mul(a, b, signed, cnt),), _flags(cnt)
    return f


def _ref_div(signed: bool):
    def f(n: int, d: int):
        cnt = new_counters()
        q, r = s_div(n, d, 32, signed, cnt)
        return (q, r), _flags(cnt)
    return f


def _ref_div_round(signed: bool):
    def f(n: int, d: int):
        cnt = new_counters()
        return (s_div_round(n, d, 32, signed, cnt),), _flags(cnt)
    return f


def _ref_shift(half_up: bool):
    def f(x: int, s: int):
        cnt = new_counters()
        return (s_shift_right(x, s, half_up, cnt),), _flags(cnt)
    return f


def _ref_sat16(x: int):
    cnt = new_counters()
    return (s_overflow(x, 16, True, False, cnt),), _flags(cnt)


def _ref_isqrt(nearest: bool):
    def f(x: int):
        cnt = new_counters()
        return (s_isqrt(x, nearest, cnt),), _flags(cnt)
    return f


def _ref_iroot4(x: int):
    cnt = new_counters()
    return (s_isqrt(s_isqrt(x, False, cnt), False, cnt),), _flags(cnt)


_A16, _A32, _B16, _S = ("ACC", 2), ("ACC", 4), ("ARG", 2), ("ARG", 1)
_FL = ("FLAGS", 1, False)

#: The kernels in ``harness.asm``'s dispatch order.
KERNELS: dict[str, Kernel] = {k.name: k for k in (
    Kernel("mul16u", 0, (_A16, _B16), (("ACC", 4, False), _FL), _ref_mul(False), "16 x 16 -> 32 unsigned (s_mul)"),
    Kernel("mul16s", 1, (_A16, _B16), (("ACC", 4, True), _FL), _ref_mul(True), "16 x 16 -> 32 signed (s_mul)"),
    Kernel("div32u", 2, (_A32, _B16), (("ACC", 4, False), ("REM", 2, False), _FL), _ref_div(False),
           "32 / 16 unsigned, truncating, with remainder (s_div)"),
    Kernel("div32s", 3, (_A32, _B16), (("ACC", 4, True), ("REM", 2, True), _FL), _ref_div(True),
           "32 / 16 signed, truncating, with remainder (s_div)"),
    Kernel("divr32u", 4, (_A32, _B16), (("ACC", 4, False), _FL), _ref_div_round(False),
           "32 / 16 unsigned, rounded to nearest (s_div_round)"),
    Kernel("divr32s", 5, (_A32, _B16), (("ACC", 4, True), _FL), _ref_div_round(True),
           "32 / 16 signed, rounded to nearest, ties away from zero (s_div_round)"),
    Kernel("shr32", 6, (_A32, _S), (("ACC", 4, True), _FL), _ref_shift(False),
           "arithmetic right shift of a 32-bit word, floor (s_shift_right)"),
    Kernel("shr32r", 7, (_A32, _S), (("ACC", 4, True), _FL), _ref_shift(True),
           "right shift rounding half up (s_shift_right)"),
    Kernel("sat16", 8, (_A32,), (("ACC", 2, True), _FL), _ref_sat16, "32-bit word saturated to 16 bits (s_overflow)"),
    Kernel("isqrt32", 9, (_A32,), (("ACC", 4, False), _FL), _ref_isqrt(False), "floor(sqrt(x)), 32-bit x (s_isqrt)"),
    Kernel("isqrt32n", 10, (_A32,), (("ACC", 3, False), _FL), _ref_isqrt(True),
           "sqrt rounded to nearest (s_isqrt nearest)"),
    Kernel("iroot4", 11, (_A32,), (("ACC", 4, False), _FL), _ref_iroot4, "floor(x^(1/4)) = isqrt(isqrt(x)) (iroot4)"),
)}


def missing_tools() -> str | None:
    """Why the kernels cannot run here (``None`` when ``gpasm`` and ``gpsim`` are on the PATH)."""
    absent = [t for t in ("gpasm", "gpsim") if shutil.which(t) is None]
    if absent:
        return f"{' and '.join(absent)} not installed (Debian packages gputils, gpsim; .ci/run installs them)"
    return None


def copy_sources(build_dir: Path, main_asm: Path) -> None:
    """The assembly sources copied into ``build_dir`` and assembled there under their bare names: a ``.cod`` file
    holds each source's name in 63 bytes, and gpsim crashes (SIGSEGV) reading one with a longer path, as a
    checkout's or a test's folder easily gives."""
    for src in [*PIC_DIR.glob("*.asm"), *PIC_DIR.glob("*.inc")]:
        if src.name != main_asm.name:
            shutil.copyfile(src, build_dir / src.name)
    shutil.copyfile(main_asm, build_dir / main_asm.name)


def assemble(build_dir: Path) -> Path:
    """Assemble ``harness.asm`` with its kernels into ``build_dir``; returns the ``.cod`` for gpsim."""
    build_dir.mkdir(parents=True, exist_ok=True)
    copy_sources(build_dir, PIC_DIR / "harness.asm")
    proc = subprocess.run(["gpasm", "-q", "-p", "p16f877", "-o", "harness.hex", "harness.asm"],
                          capture_output=True, text=True, timeout=60, cwd=build_dir)
    cod = build_dir / "harness.cod"
    if proc.returncode != 0 or not cod.exists():
        raise RuntimeError(f"gpasm failed on {PIC_DIR / 'harness.asm'}: {(proc.stdout + proc.stderr).strip()}")
    return cod


# ---------------------------------------------------------------------------------------------------
# vectors


def _bitlen_ints(rng: np.random.Generator, n: int, bits: int, signed: bool) -> list[int]:
    """Magnitudes of random bit length (0..bits), random sign when ``signed``, clipped to the word."""
    lengths = rng.integers(0, bits + 1, n)
    mags = [int(rng.integers(0, 1 << int(k))) if k else 0 for k in lengths]
    if not signed:
        return [min(m, (1 << bits) - 1) for m in mags]
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return [max(lo, min(hi, -m if s else m)) for m, s in zip(mags, rng.integers(0, 2, n))]


def _uniform(rng: np.random.Generator, n: int, bits: int, signed: bool) -> list[int]:
    lo = -(1 << (bits - 1)) if signed else 0
    return [int(v) + lo for v in rng.integers(0, 1 << bits, n, dtype=np.uint64)]


def _mix(rng: np.random.Generator, n: int, bits: int, signed: bool) -> list[int]:
    """Half uniform over the word, half of random bit length (small values as often as large ones)."""
    out = _uniform(rng, n - n // 2, bits, signed) + _bitlen_ints(rng, n // 2, bits, signed)
    return [out[i] for i in rng.permutation(n)]


def _word_edges(bits: int, signed: bool) -> list[int]:
    if signed:
        lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        return [lo, lo + 1, lo + 2, -256, -255, -129, -128, -2, -1, 0, 1, 2, 127, 128, 255, 256, hi - 1, hi]
    hi = (1 << bits) - 1
    return [0, 1, 2, 127, 128, 255, 256, 1 << (bits - 1), (1 << (bits - 1)) - 1, hi - 1, hi]


def vectors(name: str, n_random: int = DEFAULT_RANDOM, seed: int = 0) -> list[tuple[int, ...]]:
    """Operand tuples for kernel ``name``: its edge cases, then ``n_random`` random vectors."""
    rng = np.random.default_rng([seed, KERNELS[name].select])
    signed = name in ("mul16s", "div32s", "divr32s", "shr32", "shr32r", "sat16")
    if name.startswith("mul"):
        e = _word_edges(16, signed)
        edge = [(a, b) for a in e for b in e]
        rnd = list(zip(_mix(rng, n_random, 16, signed), _mix(rng, n_random, 16, signed)))
    elif name.startswith("div"):
        en, ed = _word_edges(32, signed), _word_edges(16, signed) + [3, 7, 10]
        edge = [(a, b) for a in en for b in ed]
        # ties of the rounding divide: n = k d + d/2 with even d, both signs of n and d
        for d in (2, 4, 6, 100, 32766):
            for k in (0, 1, 2, 7, 1000):
                for sn in (1, -1) if signed else (1,):
                    for sd in (1, -1) if signed else (1,):
                        edge.append((sn * (k * d + d // 2), sd * d))
        nn = _mix(rng, n_random, 32, signed)
        dd = _mix(rng, n_random, 16, signed)
        rnd = list(zip(nn, dd))
    elif name.startswith("shr"):
        edge = [(x, s) for x in _word_edges(32, True) for s in (0, 1, 2, 7, 8, 15, 16, 17, 30, 31)]
        for s in range(1, 32):                 # exact ties: x = m 2^s + 2^(s-1), both signs
            for m in (0, 1, 2, -1, -2, -3, (1 << (31 - s)) - 1, -(1 << (31 - s))):
                x = m * (1 << s) + (1 << (s - 1))
                if -(1 << 31) <= x < (1 << 31):
                    edge.append((x, s))
        rnd = list(zip(_mix(rng, n_random, 32, True), [int(s) for s in rng.integers(0, 32, n_random)]))
    elif name == "sat16":
        edge = [(x,) for x in _word_edges(32, True) + [-32769, -32768, -32767, 32766, 32767, 32768, 65535,
                                                       65536, -65536, -65537, 0x7FFF8000, -0x7FFF8000]]
        rnd = [(x,) for x in _mix(rng, n_random, 32, True)]
    else:                                       # square roots
        e = _word_edges(32, False)
        for r in (1, 2, 3, 255, 256, 4095, 46340, 65534, 65535):
            e += [r * r - 1, r * r, r * r + r, r * r + r + 1]
        edge = [(x,) for x in e if 0 <= x < (1 << 32)]
        r = rng.integers(0, 1 << 16, n_random // 2)
        near = [int(v * v + off) for v, off in zip(r, rng.integers(-2, 3, r.size)) if 0 <= v * v + off < 1 << 32]
        near += [int(v * v + v + off) for v, off in zip(r, rng.integers(0, 2, r.size))
                 if v * v + v + off < 1 << 32]
        rnd = [(x,) for x in _mix(rng, n_random - n_random // 2, 32, False) + near[: n_random // 2]]
    return edge + rnd


# ---------------------------------------------------------------------------------------------------
# gpsim


@dataclass(frozen=True)
class KernelRun:
    """One kernel run in gpsim over its vectors."""

    name: str
    operands: list[tuple[int, ...]]
    outputs: list[tuple[int, ...]]      # results (signedness per the kernel) then the flags
    expected: list[tuple[int, ...]]
    cycles: np.ndarray                   # per call, including CALL and RETURN

    @property
    def mismatches(self) -> list[tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]]:
        """(operands, gpsim, fixedpoint) of every vector that differs."""
        return [(v, o, e) for v, o, e in zip(self.operands, self.outputs, self.expected) if o != e]

    def summary(self) -> dict:
        """The run as plain numbers."""
        return {"kernel": self.name, "doc": KERNELS[self.name].doc, "vectors": len(self.operands),
                "mismatches": len(self.mismatches), "cycles_min": int(self.cycles.min()),
                "cycles_mean": round(float(self.cycles.mean()), 1), "cycles_max": int(self.cycles.max())}


_READ = re.compile(r"^(?:\*\*gpsim> )*([A-Za-z_0-9]+) = 0x([0-9A-Fa-f]+)\s*$")


#: Vectors per gpsim start: gpsim's time per command grows with the length of its script (4,000 vectors
#: take 9x the time of 1,000), so long runs are cut into chunks of this many.
CHUNK = 1000


def _run_chunk(k: Kernel, operands: list[tuple[int, ...]], cod: Path,
               timeout_s: float) -> tuple[list[tuple[int, ...]], list[int]]:
    """One gpsim process: kernel ``k`` on ``operands``; its outputs and cycles per call."""
    lines = ["STARTS = 0", f"KERNEL_SELECT = {k.select}", f"break e at_{k.name}", "run", "cycles"]
    reads = [r for p, nb, _ in k.outputs for r in _names(p, nb)]
    for ops in operands:
        for (prefix, nb), v in zip(k.inputs, ops):
            lines += [f"{r} = {b}" for r, b in zip(_names(prefix, nb), _u(v, nb))]
        lines += ["FLAGS = 0", "run", *reads, "cycles"]
    lines += ["STARTS", "quit"]
    with tempfile.TemporaryDirectory(prefix=f"gpsim-{k.name}-") as tmp:
        script = Path(tmp) / f"{k.name}.stc"
        script.write_text("\n".join(lines) + "\n")
        proc = subprocess.run(["gpsim", "-i", "-s", str(cod), "-c", str(script)], capture_output=True,
                              text=True, timeout=timeout_s, cwd=tmp)
    if "***ERROR" in proc.stdout or proc.returncode != 0:
        err = next((ln for ln in proc.stdout.splitlines() if "ERROR" in ln), proc.stderr.strip()[-300:])
        raise RuntimeError(f"gpsim ({k.name}) failed (exit {proc.returncode}): {err}")
    values = [(m.group(1), int(m.group(2), 16)) for m in map(_READ.match, proc.stdout.splitlines()) if m]
    per = len(reads) + 1
    if len(values) != 2 + per * len(operands) or values[-1][0] != "STARTS":
        raise RuntimeError(f"gpsim ({k.name}): expected {2 + per * len(operands)} register reads, got "
                           f"{len(values)}; stderr: {proc.stderr.strip()[-300:]}")
    if values[-1][1] != 1:
        raise RuntimeError(f"gpsim ({k.name}): the PIC restarted {values[-1][1] - 1} times during the run")
    counter = [values[0][1]] + [values[per * (i + 1)][1] for i in range(len(operands))]
    outputs = []
    for i in range(len(operands)):
        got = values[1 + per * i: per * (i + 1)]
        if [g[0] for g in got] != reads:
            raise RuntimeError(f"gpsim ({k.name}): reads out of order: {got}")
        out, j = [], 0
        for _, nb, signed in k.outputs:
            v = sum(got[j + b][1] << (8 * b) for b in range(nb))
            out.append(_s(v, 8 * nb) if signed else v)
            j += nb
        outputs.append(tuple(out))
    return outputs, (np.diff(np.asarray(counter, np.int64)) - LOOP_GOTO_CYCLES).tolist()


def _expected(k: Kernel, operands: list[tuple[int, ...]]) -> list[tuple[int, ...]]:
    out = []
    for ops in operands:
        res, flags = k.reference(*ops)
        out.append(tuple(res) + (flags,))
    return out


def run_kernel(kernel: str | Kernel, operands: list[tuple[int, ...]], cod: Path, *, workers: int = 1,
               timeout_s: float = 600.0) -> KernelRun:
    """Run a kernel on every operand tuple (``CHUNK`` per gpsim start); compare with ``fixedpoint``.

    ``kernel`` is a name of :data:`KERNELS` or a :class:`Kernel` (a test can pair one kernel's code with
    another's reference to see the comparison fail).
    """
    k = KERNELS[kernel] if isinstance(kernel, str) else kernel
    chunks = [operands[i:i + CHUNK] for i in range(0, len(operands), CHUNK)]
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        parts = list(pool.map(lambda c: _run_chunk(k, c, cod, timeout_s), chunks))
    outputs = [o for p in parts for o in p[0]]
    cycles = np.asarray([c for p in parts for c in p[1]], np.int64)
    return KernelRun(k.name, list(operands), outputs, _expected(k, operands), cycles)


def measure(n_random: int = DEFAULT_RANDOM, *, seed: int = 0, kernels: tuple[str, ...] | None = None,
            workers: int = 2) -> tuple[dict[str, KernelRun], int]:
    """Assemble, then run every kernel on its edge cases and ``n_random`` random vectors (gpsim processes
    ``workers`` at a time). Returns the runs and the kernels' program words."""
    names = tuple(kernels or KERNELS)
    with tempfile.TemporaryDirectory(prefix="gpsim-build-") as tmp:
        cod = assemble(Path(tmp))
        words = program_words(Path(tmp))
        tasks = [(n, c) for n in names for c in
                 (lambda v: [v[i:i + CHUNK] for i in range(0, len(v), CHUNK)])(vectors(n, n_random, seed))]
        with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
            parts = list(pool.map(lambda t: _run_chunk(KERNELS[t[0]], t[1], cod, 600.0), tasks))
    runs = {}
    for n in names:
        ops = [v for (m, c) in tasks if m == n for v in c]
        outs = [o for (m, _), p in zip(tasks, parts) if m == n for o in p[0]]
        cyc = np.asarray([x for (m, _), p in zip(tasks, parts) if m == n for x in p[1]], np.int64)
        runs[n] = KernelRun(n, ops, outs, _expected(KERNELS[n], ops), cyc)
    return runs, words


# ---------------------------------------------------------------------------------------------------
# the cycle table

#: How each ``fixedpoint.CYCLES`` key is measured: (kernel, rule). "call" = the kernel's worst case
#: including CALL and RETURN (a subroutine, as AN617's figures); "inline" = minus CALL and RETURN (4
#: cycles: the firmware writes it in line); "per_bit" / "round" = derived from the shift kernels.
TABLE_RULES: dict[str, tuple[str, str]] = {
    "mul16x16s": ("mul16s", "call"),
    "mul16x16u": ("mul16u", "call"),
    "div32by16u": ("div32u", "call"),
    "div32by16s": ("div32s", "call"),
    "isqrt32": ("isqrt32", "call"),
    "sat16": ("sat16", "inline"),
    "shift32_per_bit": ("shr32", "per_bit"),
    "round32": ("shr32r", "round"),
}
CALL_RETURN_CYCLES = 4


def _cycles_by_shift(run: KernelRun) -> dict[int, int]:
    out: dict[int, int] = {}
    for ops, c in zip(run.operands, run.cycles.tolist()):
        out[ops[1]] = max(out.get(ops[1], 0), int(c))
    return out


def program_words(build_dir: Path) -> int:
    """Program memory words of the kernels (``kernels_end - kernels_begin`` in gpasm's listing of
    ``harness.asm``; :func:`assemble` must have run in ``build_dir``)."""
    text = (build_dir / "harness.lst").read_text(errors="replace")
    addr = {m.group(1): int(m.group(2), 16)
            for m in re.finditer(r"^(kernels_begin|kernels_end)\s+([0-9A-Fa-f]+)\s*$", text, re.M)}
    if len(addr) != 2:
        raise RuntimeError(f"gpasm listing {build_dir / 'harness.lst'} has no kernels_begin/kernels_end symbols")
    return addr["kernels_end"] - addr["kernels_begin"]


def cycle_table(runs: dict[str, KernelRun], version: str, kernel_words: int) -> dict:
    """The measured table (the content of ``kernel_cycles.json``) from bit-exact runs."""
    bad = {n: len(r.mismatches) for n, r in runs.items() if r.mismatches}
    if bad:
        raise RuntimeError(f"kernels differ from fixedpoint.py, no table written: {bad}")
    missing = {k for k, _ in TABLE_RULES.values()} - set(runs)
    if missing:
        raise RuntimeError(f"the cycle table needs the kernels {sorted(missing)}")
    kernels = {n: r.summary() for n, r in runs.items()}
    cycles, means, sources = {}, {}, {}
    for key, (kname, rule) in TABLE_RULES.items():
        s = kernels[kname]
        how = f"gpsim {version}, firmware_sim/pic kernel {kname}, {s['vectors']:,} vectors"
        means[key] = s["cycles_mean"] - (CALL_RETURN_CYCLES if rule == "inline" else 0)
        if rule == "call":
            cycles[key] = s["cycles_max"]
            sources[key] = (f"measured: worst case including CALL/RETURN ({how}; min {s['cycles_min']}, "
                            f"mean {s['cycles_mean']:g})")
        elif rule == "inline":
            cycles[key] = s["cycles_max"] - CALL_RETURN_CYCLES
            sources[key] = f"measured: worst case less CALL/RETURN, as written in line ({how})"
        elif rule == "per_bit":
            by = _cycles_by_shift(runs[kname])
            cycles[key] = means[key] = max(by[s_] - by[s_ - 1] for s_ in range(2, 32))
            sources[key] = f"measured: cycles per extra bit of shift, s = 1..31 ({how})"
        else:
            fl, rd = _cycles_by_shift(runs["shr32"]), _cycles_by_shift(runs[kname])
            cycles[key] = means[key] = max(rd[s_] - fl[s_] for s_ in range(1, 32))
            sources[key] = f"measured: half-up minus floor shift at the same s, worst over s = 1..31 ({how})"
    return {"generated_by": "gaitlog budget --measure-kernels", "gpsim": version, "device": "p16f877",
            "cycles": cycles, "cycles_mean": {k: round(v, 1) for k, v in means.items()}, "sources": sources,
            "kernel_program_words": int(kernel_words), "kernels": kernels}


#: How ``fixedpoint`` charges each kernel's work: (primitive, multiplier) terms; ``s`` = per bit of shift.
KERNEL_MODEL: dict[str, tuple[tuple[str, str], ...]] = {
    "mul16u": (("mul16x16u", ""),), "mul16s": (("mul16x16s", ""),),
    "div32u": (("div32by16u", ""),), "div32s": (("div32by16s", ""),),
    "divr32u": (("div32by16u", ""), ("add32", "")), "divr32s": (("div32by16s", ""), ("add32", "")),
    "shr32": (("shift32_per_bit", "s"),), "shr32r": (("round32", ""), ("shift32_per_bit", "s")),
    "sat16": (("sat16", ""),), "isqrt32": (("isqrt32", ""),), "isqrt32n": (("isqrt32", ""), ("compare16", "")),
    "iroot4": (("isqrt32", "2"),),
}


def _model(kernel: str, cycles: dict[str, int]) -> str:
    terms = KERNEL_MODEL[kernel]
    text = " + ".join(f"{m} x {cycles[k]}" if m == "2" else f"{cycles[k]} {m}".strip() for k, m in terms)
    if all(m != "s" for _, m in terms) and (len(terms) > 1 or terms[0][1]):
        total = sum(cycles[k] * (2 if m == "2" else 1) for k, m in terms)
        text += f" = {total}"
    return text


def markdown_table(table: dict) -> str:
    """The measured cycles beside the figures cited before (the table of ``docs/FIXED_POINT.md``)."""
    now = {**CITED_CYCLES, **table["cycles"]}
    rows = ["| kernel | what | vectors | gpsim cycles min / mean / max | `CYCLES` charges now | cited before |",
            "|---|---|---|---|---|---|"]
    for name, s in table["kernels"].items():
        keys = sorted({k for k, _ in KERNEL_MODEL[name]})
        cited = ", ".join(dict.fromkeys(CITED_SOURCES.get(k, "").split(":")[0].replace("Microchip ", "")
                                        for k in keys if k in table["cycles"]))
        rows.append(f"| `{name}` | {s['doc']} | {s['vectors']:,} | {s['cycles_min']} / {s['cycles_mean']:g} / "
                    f"{s['cycles_max']} | {_model(name, now)} | {_model(name, CITED_CYCLES)} ({cited}) |")
    return "\n".join(rows)


def gpsim_version() -> str:
    """``gpsim --version``'s release (e.g. ``0.31.0``)."""
    proc = subprocess.run(["gpsim", "--version"], capture_output=True, text=True, timeout=30)
    out = proc.stdout + proc.stderr
    m = re.search(r"gpsim-([0-9.]+)", out)
    return m.group(1) if m else out.strip()


def write_cycle_table(table: dict, path: Path = CYCLE_TABLE_PATH) -> None:
    """Write the table as JSON (stable key order, one trailing newline)."""
    path.write_text(json.dumps(table, indent=2) + "\n")
