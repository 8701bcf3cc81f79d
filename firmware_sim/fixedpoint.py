"""The PIC16F877's integer arithmetic: Q formats, words, multiply, divide, shifts, saturation, roots.

Every fixed-point computation of the firmware (``gaitlog.firmware_sim.algorithms``) uses these primitives and
nothing else, so the device's arithmetic is defined in one place.

Two faces, one definition
-------------------------
* **Scalar definitions** (``s_mul``, ``s_mul_q``, ``s_div``, ``s_div_round``, ``s_isqrt``, ``s_add``,
  ``s_shift_right`` ...): one PIC routine each, on Python / ``int64`` integers. They are plain Python
  functions registered with numba (``register_jitable``), so the on-line step algorithm's per-sample
  kernel inlines them when it is compiled and the same text runs uncompiled in Python. Each takes a counter
  array ``cnt`` (:func:`new_counters`) in which it adds its calls, cycles, saturations, wraps and divisions
  by zero.
* **Array API** (:func:`mul`, :func:`mul_q`, :func:`div`, :func:`div_round`, :func:`isqrt`, :func:`add` ...):
  the same scalar definitions applied element by element by compiled loops, for numpy arrays (broadcast,
  ``int64``), with the counts collected in an :class:`ArithmeticContext`. This is the face the bit-exact
  tests (apytypes) and the benchmarks use. Arrays of at most :data:`PYTHON_MAX_ELEMENTS` elements (the
  algorithm's configuration: a few dozen constants) run the loops' Python text on Python integers instead,
  which needs no numba (loading it costs ~0.4 s; :mod:`gaitlog.firmware_sim.compiled`); a test checks that both
  give the same bits.

Conventions
-----------
* ``Qm.n`` (:class:`QFormat`): ``m`` integer bits *not counting the sign*, ``n`` fraction bits, so a signed
  Qm.n value occupies ``m + n + 1`` bits (PROTOCOL.md's Q15.16 offset and Q1.30 matrix are 32-bit words).
  The raw integer ``r`` stands for ``r / 2**n``.
* Rounding of a right shift by ``s`` (dropping ``s`` fraction bits): ``"half_up"`` adds ``2**(s-1)`` then
  shifts arithmetically (``(r + 2**(s-1)) >> s``: ties go towards +inf, what ``ADDLW``/``RRF`` code does),
  ``"floor"`` is the bare arithmetic shift (two's complement truncation, towards -inf).
* Overflow: ``"saturate"`` clips to the word's range, ``"wrap"`` keeps the low bits (two's complement).
  Every saturation, wrap, and division by zero is counted, so a chain can assert that nothing saturated
  unreported; a saturation also sets the *sticky* flag (``cnt[C_STICKY]``), which the step algorithm reads
  and clears once per step (the firmware's status bit).
* Division (:func:`s_div`) is the 32/16 signed divide of AN617 (sign-magnitude around the unsigned
  ``FXD3216U`` routine): the quotient is truncated towards zero and the remainder takes the dividend's sign
  (``n == q·d + r``, ``|r| < |d|``). Division by zero saturates the quotient (to the word's maximum for a
  non-negative dividend, minimum otherwise), sets the remainder to the dividend clipped to 16 bits, and is
  counted (as a division by zero and as a saturation).
* Square root (:func:`s_isqrt`) is the exact floor of the square root of a 32-bit unsigned input, what the
  bit-by-bit shift-subtract (restoring) algorithm returns; ``nearest`` adds one when the remainder exceeds
  the root. :func:`iroot4` is ``isqrt(isqrt(x))``, exactly ``floor(x ** (1/4))`` because
  ``floor(sqrt(floor(y))) == floor(sqrt(y))`` for ``y >= 0``.

Cycle costs
-----------
:data:`CYCLES` holds worst-case instruction cycles of each primitive on the PIC16 (one cycle = 4 clocks).
Where ``firmware_sim/pic`` has an assembly kernel (multiplies, divides, shifts, saturation, square root), the
figure is measured: the kernel runs in gpsim's PIC16F877 model, bit-exact with this module on 10,000+
vectors, and ``gaitlog budget --measure-kernels`` writes its worst case to ``pic/kernel_cycles.json``, which
this module reads (:data:`MEASURED_CYCLES`). The other figures stay as cited (:data:`CITED_CYCLES`): the I2C
byte computed from the bus clock, the rest counted from hand-written instruction sequences and marked
*estimate* in :data:`CYCLE_SOURCES`. Every scalar call adds ``CYCLES[op]`` to the counters, so a kernel's
cycles per sample (mean and worst) can be compared with the cycles one sample period offers
(:func:`cycles_per_sample_available`).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from gaitlog.firmware_sim.compiled import njit, register_jitable

__all__ = [
    "CYCLES",
    "CYCLE_SOURCES",
    "CITED_CYCLES",
    "CITED_SOURCES",
    "MEASURED_CYCLES",
    "OPS",
    "CYCLE_TABLE",
    "I2C_BYTE_CYCLES",
    "I2C_SCL_CYCLES",
    "I2C_BYTE_INSTRUCTION_CYCLES",
    "DEFAULT_FOSC_HZ",
    "cycles_per_sample_available",
    "N_COUNTERS",
    "PYTHON_MAX_ELEMENTS",
    "C_SAT",
    "C_WRAP",
    "C_DIV0",
    "C_STICKY",
    "C_CYCLES",
    "new_counters",
    "ArithmeticContext",
    "Overflow",
    "QFormat",
    "Rounding",
    "add",
    "cumsum",
    "div",
    "div_round",
    "iroot4",
    "isqrt",
    "mul",
    "mul_q",
    "requantize",
    "saturate",
    "shift_left",
    "shift_right",
    "sub",
    "word_limits",
    "wrap",
    "s_add",
    "s_cost",
    "s_div",
    "s_div_round",
    "s_div_mode",
    "ROUND_TRUNCATE",
    "ROUND_HALF_UP",
    "ROUND_CONVERGENT",
    "ROUNDING_MODES",
    "s_from_float",
    "s_isqrt",
    "s_mul",
    "s_mul_q",
    "s_overflow",
    "s_requantize",
    "s_shift_left",
    "s_shift_right",
    "s_sub",
    "s_word_hi",
    "s_word_lo",
]

Rounding = Literal["half_up", "floor"]

#: Rounding modes of the scalar primitives' ``half_up`` argument and of :func:`s_div_mode` (a sweep dimension of
#: the fixed-point chain, per operation class: :mod:`gaitlog.firmware_sim.algorithms.format_kernel`).
ROUND_TRUNCATE, ROUND_HALF_UP, ROUND_CONVERGENT = 0, 1, 2
#: Their names.
ROUNDING_MODES: dict[str, int] = {"truncate": ROUND_TRUNCATE, "half-up": ROUND_HALF_UP,
                                  "convergent": ROUND_CONVERGENT}
Overflow = Literal["saturate", "wrap"]

#: The logger's crystal: 18.432 MHz, a baud-rate crystal (``gaitlog.firmware_sim.uart``); 4 clocks per cycle.
DEFAULT_FOSC_HZ = 18_432_000.0
#: I2C master at 400 kHz nominal: SSPADD = round(fosc / (4 · 400 kHz)) - 1 = 10 (logger.asm). The datasheet's
#: baud rate ``fosc / (4 (SSPADD + 1))`` makes one SCL period 11 instruction cycles (419 kHz); gpsim's MSSP takes
#: SSPADD + 2 = 12 (``gaitlog.firmware_sim.pic.chip_budget.i2c_event_cycles`` times each bus event: a byte sent
#: or received is 8 of these periods, an acknowledge 1), and the budget prices the bus as gpsim runs it.
I2C_SCL_CYCLES = 10 + 2
#: The instructions the scratch ring's reader (step_record.asm ``scr_next``) runs for each byte besides the bus:
#: ``I2C_CMD RCEN`` (3) and its wait (5: bank select, the polling loop's exit, ``BCF SSPIF``), ``MOVF``/``MOVWF``
#: (2), ``I2C_ACK`` (4) and its wait (5), and half of ``scr_next``'s ``CALL``, ``RETURN`` and bank select (5 for
#: its two bytes; 2.5, counted as 3).
I2C_BYTE_INSTRUCTION_CYCLES = 3 + 5 + 2 + 4 + 5 + 3
#: One byte received from the external EEPROM and acknowledged, as the assembly's reader takes it: 9 SCL periods
#: (8 data bits, the acknowledge) and its instructions, 130 cycles (gpsim: 106 + 21 a byte, 5 a pair; a byte
#: sent, ``MOVLW``/``CALL i2c_tx``, 121). The model's I2C reads and page writes count their bytes at this price,
#: and 5 (read: with the byte its close receives, not acknowledged) or 3 (write) bytes for the control and address
#: bytes, start, restart and stop (``kernel.I2C_READ_OVERHEAD``, ``I2C_WRITE_OVERHEAD``).
I2C_BYTE_CYCLES = 9 * I2C_SCL_CYCLES + I2C_BYTE_INSTRUCTION_CYCLES


def cycles_per_sample_available(sampling_rate_hz: float, fosc_hz: float = DEFAULT_FOSC_HZ) -> float:
    """Instruction cycles in one sample period: ``fosc / 4 / fs``.

    >>> cycles_per_sample_available(50.0), cycles_per_sample_available(50.0, 20e6)
    (92160.0, 100000.0)
    """
    return fosc_hz / 4.0 / sampling_rate_hz


#: The figures cited before the primitives ran on a PIC simulator (application notes, hand counts).
CITED_CYCLES: dict[str, int] = {
    "add16": 6,        # MOVF/ADDWF low, BTFSC C, INCF high, MOVF/ADDWF high
    "add32": 16,
    "sat16": 12,       # overflow test on the sign bits + load of the limit
    "sat32": 20,
    "shift32_per_bit": 5,  # RLF/RRF x4 bytes + carry set-up (arithmetic shift keeps the sign in C)
    "round32": 16,     # add 2**(s-1) to a 32-bit word
    "mul16x16s": 269,  # AN617 FXM1616S
    "mul16x16u": 256,  # AN617 FXM1616U
    "mul8x8u": 71,     # AN617 FXM0808U (estimate: 8 add-shift rounds)
    "div32by16u": 703,  # AN617 FXD3216U
    "div32by16s": 760,  # FXD3216U + sign handling of dividend, divisor and both results (estimate)
    "isqrt32": 560,    # restoring shift-subtract, 16 rounds of ~35 cycles on 32/16-bit words (estimate)
    "compare16": 8,
    "compare32": 16,
    "i2c_byte": I2C_BYTE_CYCLES,   # one byte on the I2C bus to/from an external EEPROM (computed above)
    "data_eeprom_byte": 8,  # read one byte of the PIC's data EEPROM: bank select, EEADR, RD, EEDATA (estimate)
    "ram_copy8": 4,     # move one byte between RAM locations through W (MOVF/MOVWF; estimate)
}

#: Where each :data:`CITED_CYCLES` figure comes from.
CITED_SOURCES: dict[str, str] = {
    "mul16x16s": "Microchip AN617, FXM1616S worst case",
    "mul16x16u": "Microchip AN617, FXM1616U worst case",
    "div32by16u": "Microchip AN617, FXD3216U worst case",
    "i2c_byte": "computed from the assembly: 9 SCL periods of 12 cycles as gpsim runs the MSSP at SSPADD = 10 "
                "(18.432 MHz) and the reader's 22 instruction cycles a byte",
    **{k: "estimate: counted from a hand-written PIC16 instruction sequence"
       for k in ("add16", "add32", "sat16", "sat32", "shift32_per_bit", "round32", "compare16", "compare32",
                 "mul8x8u", "div32by16s", "isqrt32", "data_eeprom_byte", "ram_copy8")},
}

#: The cycle table measured in gpsim on the assembly kernels of ``firmware_sim/pic`` (written by
#: ``gaitlog budget --measure-kernels``, :mod:`gaitlog.firmware_sim.pic.gpsim_bench`; ``kernels`` holds each
#: kernel's min, mean and max cycles per call).
MEASURED_CYCLES: dict = json.loads((Path(__file__).resolve().parent / "pic" / "kernel_cycles.json").read_text())

#: Worst-case PIC16 instruction cycles per element of each primitive: measured in gpsim where a kernel
#: exists, the cited figure otherwise (see :data:`CYCLE_SOURCES`).
CYCLES: dict[str, int] = {**CITED_CYCLES, **{k: int(v) for k, v in MEASURED_CYCLES["cycles"].items()}}

#: Where each :data:`CYCLES` figure comes from.
CYCLE_SOURCES: dict[str, str] = {**CITED_SOURCES, **MEASURED_CYCLES["sources"]}

#: The primitives in counter order (``cnt[i]`` counts calls of ``OPS[i]``).
OPS: tuple[str, ...] = tuple(CYCLES)
#: ``CYCLES`` as an array in :data:`OPS` order (compiled in as a constant).
CYCLE_TABLE = np.array([CYCLES[k] for k in OPS], dtype=np.int64)

OP_ADD16, OP_ADD32, OP_SAT16, OP_SAT32, OP_SHIFT, OP_ROUND, OP_MULS, OP_MULU, OP_MUL8, OP_DIVU, OP_DIVS, \
    OP_ISQRT, OP_CMP16, OP_CMP32, OP_I2C, OP_DEE, OP_COPY = range(len(OPS))

#: Counter slots after the per-primitive call counts.
C_SAT = len(OPS)          # elements saturated
C_WRAP = C_SAT + 1        # elements wrapped
C_DIV0 = C_SAT + 2        # divisions by zero (also counted as saturations)
C_STICKY = C_SAT + 3      # sticky saturation flag (1 after any saturation until cleared)
C_CYCLES = C_SAT + 4      # cycles counted since the slot was last cleared
N_COUNTERS = C_SAT + 5


def new_counters() -> np.ndarray:
    """A zeroed counter array for the scalar primitives."""
    return np.zeros(N_COUNTERS, dtype=np.int64)


def word_limits(bits: int, signed: bool = True) -> tuple[int, int]:
    """Smallest and largest integer of a ``bits``-bit word.

    >>> word_limits(16), word_limits(8, signed=False)
    ((-32768, 32767), (0, 255))
    """
    if not 1 <= bits <= 62:
        raise ValueError(f"word width must be 1-62 bits, got {bits}")
    return s_word_lo(bits, signed), s_word_hi(bits, signed)


# ---------------------------------------------------------------------------------------------------
# scalar definitions (numba inlines them; they also run as plain Python)


@register_jitable
def s_word_lo(bits, signed):
    """Smallest integer of a word."""
    return -(1 << (bits - 1)) if signed else 0


@register_jitable
def s_word_hi(bits, signed):
    """Largest integer of a word."""
    return (1 << (bits - 1)) - 1 if signed else (1 << bits) - 1


@register_jitable
def s_cost(cnt, op, n):
    """Count ``n`` executions of primitive ``op`` (an index into :data:`OPS`)."""
    cnt[op] += n
    cnt[C_CYCLES] += CYCLE_TABLE[op] * n


@register_jitable
def s_overflow(x, bits, signed, wrap, cnt):
    """``x`` brought into a ``bits``-bit word: clipped (counted, sticky flag) or wrapped (counted)."""
    lo = s_word_lo(bits, signed)
    hi = s_word_hi(bits, signed)
    if lo <= x <= hi:
        return x
    if wrap:
        y = x & ((1 << bits) - 1)
        if signed and y > hi:
            y -= 1 << bits
        cnt[C_WRAP] += 1
        return y
    cnt[C_SAT] += 1
    cnt[C_STICKY] = 1
    return lo if x < lo else hi


@register_jitable
def s_shift_right(x, s, half_up, cnt):
    """Drop ``s >= 0`` fraction bits: ``(x + 2**(s-1)) >> s`` (``half_up``) or ``x >> s``.

    ``half_up`` is also a rounding mode (:data:`ROUND_TRUNCATE` = False, :data:`ROUND_HALF_UP` = True,
    :data:`ROUND_CONVERGENT`: half up, an exact tie to the even neighbour; one comparison more).
    """
    if s == 0:
        return x
    s_cost(cnt, OP_SHIFT, s)
    if not half_up:
        return x >> s
    s_cost(cnt, OP_ROUND, 1)
    q = (x + (1 << (s - 1))) >> s
    if half_up == ROUND_CONVERGENT:
        s_cost(cnt, OP_CMP16, 1)
        if (x & ((1 << s) - 1)) == (1 << (s - 1)) and (q & 1):
            q -= 1
    return q


@register_jitable
def s_shift_left(x, s, bits, signed, wrap, cnt):
    """``x * 2**s`` brought into a ``bits``-bit word."""
    s_cost(cnt, OP_SHIFT, s)
    return s_overflow(x << s, bits, signed, wrap, cnt)


@register_jitable
def s_requantize(x, d, bits, signed, half_up, wrap, cnt):
    """Re-express ``x`` with ``d`` more fraction bits (``d < 0``: fewer, rounded), in a ``bits``-bit word."""
    if d >= 0:
        return s_shift_left(x, d, bits, signed, wrap, cnt)
    return s_overflow(s_shift_right(x, -d, half_up, cnt), bits, signed, wrap, cnt)


@register_jitable
def s_add(a, b, bits, signed, wrap, cnt):
    """``a + b`` in a ``bits``-bit word (operands in the same Q format)."""
    s_cost(cnt, OP_ADD16 if bits <= 16 else OP_ADD32, 1)
    if not wrap:
        s_cost(cnt, OP_SAT16 if bits <= 16 else OP_SAT32, 1)
    return s_overflow(a + b, bits, signed, wrap, cnt)


@register_jitable
def s_sub(a, b, bits, signed, wrap, cnt):
    """``a - b`` in a ``bits``-bit word."""
    return s_add(a, -b, bits, signed, wrap, cnt)


@register_jitable
def s_mul(a, b, signed, cnt):
    """Exact 16 x 16 -> 32-bit product (AN617 ``FXM1616S``/``FXM1616U``); operands must fit 16 bits."""
    lo = s_word_lo(16, signed)
    hi = s_word_hi(16, signed)
    if a < lo or a > hi or b < lo or b > hi:
        raise ValueError("mul operands must be 16-bit words")
    s_cost(cnt, OP_MULS if signed else OP_MULU, 1)
    return a * b


@register_jitable
def s_mul_q(a, b, shift, bits, signed, half_up, wrap, cnt):
    """Q multiply: the 32-bit product shifted right by ``shift`` (rounded), then into a ``bits``-bit word.

    A negative ``shift`` moves the product left (more fraction bits in the result than in the product).
    """
    p = s_mul(a, b, signed, cnt)
    r = s_shift_right(p, shift, half_up, cnt) if shift >= 0 else p << -shift
    if not wrap:
        s_cost(cnt, OP_SAT16 if bits <= 16 else OP_SAT32, 1)
    return s_overflow(r, bits, signed, wrap, cnt)


@register_jitable
def s_div(n, d, bits, signed, cnt):
    """32 / 16-bit division: quotient truncated towards zero (into a ``bits``-bit word), remainder with the
    dividend's sign; ``d == 0`` saturates (counted)."""
    if n < s_word_lo(32, signed) or n > s_word_hi(32, signed) or d < s_word_lo(16, signed) \
            or d > s_word_hi(16, signed):
        raise ValueError("div takes a 32-bit dividend and a 16-bit divisor")
    s_cost(cnt, OP_DIVS if signed else OP_DIVU, 1)
    if d == 0:
        cnt[C_DIV0] += 1
        cnt[C_SAT] += 1
        cnt[C_STICKY] = 1
        r = n
        if r > s_word_hi(16, signed):
            r = s_word_hi(16, signed)
        if r < s_word_lo(16, signed):
            r = s_word_lo(16, signed)
        return (s_word_hi(bits, signed) if n >= 0 else s_word_lo(bits, signed)), r
    q = abs(n) // abs(d)
    if (n < 0) != (d < 0):
        q = -q
    return s_overflow(q, bits, signed, False, cnt), n - q * d


@register_jitable
def s_div_round(n, d, bits, signed, cnt):
    """32 / 16-bit division rounded to nearest, ties away from zero: ``sign·((|n| + |d| // 2) // |d|)``."""
    if n < s_word_lo(32, signed) or n > s_word_hi(32, signed) or d < s_word_lo(16, signed) \
            or d > s_word_hi(16, signed):
        raise ValueError("div takes a 32-bit dividend and a 16-bit divisor")
    s_cost(cnt, OP_DIVS if signed else OP_DIVU, 1)
    s_cost(cnt, OP_ADD32, 1)
    if d == 0:
        cnt[C_DIV0] += 1
        cnt[C_SAT] += 1
        cnt[C_STICKY] = 1
        return s_word_hi(bits, signed) if n >= 0 else s_word_lo(bits, signed)
    ad = abs(d)
    q = (abs(n) + (ad >> 1)) // ad
    if (n < 0) != (d < 0):
        q = -q
    return s_overflow(q, bits, signed, False, cnt)


@register_jitable
def s_div_mode(n, d, bits, signed, mode, cnt):
    """32 / 16-bit division in rounding ``mode``: :data:`ROUND_HALF_UP` rounds the magnitude's half up (ties away
    from zero, :func:`s_div_round`), :data:`ROUND_TRUNCATE` truncates towards zero (:func:`s_div`),
    :data:`ROUND_CONVERGENT` rounds to nearest with exact ties to the even quotient (one comparison more)."""
    if mode == ROUND_TRUNCATE:
        return s_div(n, d, bits, signed, cnt)[0]
    q = s_div_round(n, d, bits, signed, cnt)
    if mode == ROUND_CONVERGENT and d != 0:
        s_cost(cnt, OP_CMP16, 1)
        if 2 * (abs(n) % abs(d)) == abs(d) and (q & 1):
            q = q - 1 if q > 0 else q + 1
    return q


@register_jitable
def s_isqrt(x, nearest, cnt):
    """``floor(sqrt(x))`` of an unsigned 32-bit integer (``nearest``: rounded to the nearest integer)."""
    if x < 0 or x > 4294967295:
        raise ValueError("isqrt takes unsigned 32-bit integers (0 .. 2**32 - 1)")
    s_cost(cnt, OP_ISQRT, 1)
    r = int(math.sqrt(float(x)))       # within one of the truth below 2**32; corrected exactly
    if r * r > x:
        r -= 1
    if (r + 1) * (r + 1) <= x:
        r += 1
    if nearest:
        s_cost(cnt, OP_CMP16, 1)
        if x - r * r > r:
            r += 1
    return r


@register_jitable
def s_from_float(v, frac, bits, signed, half_up, wrap, cnt):
    """Quantise a real value to a raw integer with ``frac`` fraction bits (``floor(v·2**frac + 1/2)``)."""
    y = v * 2.0 ** frac
    lim = 4611686018427387904.0       # 2**62: beyond any word, still exact in int64
    if y > lim:                       # clipped before the floor: compiled, the floor of a float beyond
        y = lim                       # int64's range is undefined (1e300 came out as the minimum)
    if y < -lim:
        y = -lim
    y = math.floor(y + 0.5) if half_up else math.floor(y)
    return s_overflow(int(y), bits, signed, wrap, cnt)


# ---------------------------------------------------------------------------------------------------
# compiled element loops of the array API (each applies one scalar definition)

#: Inputs of at most this many elements run the loops' Python text (:func:`_run`): bit for bit the compiled
#: loops' results on the primitives' domains, without loading numba for a handful of configuration constants.
PYTHON_MAX_ELEMENTS = 256


@njit(cache=True)
def _loop_overflow(x, bits, signed, wrap, out, cnt):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = s_overflow(x[i], bits, signed, wrap, cnt)


@njit(cache=True)
def _loop_shift_right(x, s, half_up, out, cnt):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = s_shift_right(x[i], s, half_up, cnt)


@njit(cache=True)
def _loop_requantize(x, d, bits, signed, half_up, wrap, out, cnt):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = s_requantize(x[i], d, bits, signed, half_up, wrap, cnt)


@njit(cache=True)
def _loop_add(a, b, bits, signed, wrap, out, cnt):  # pragma: no cover - compiled
    for i in range(a.size):
        out[i] = s_add(a[i], b[i], bits, signed, wrap, cnt)


@njit(cache=True)
def _loop_cumsum(a, bits, signed, wrap, out, cnt):  # pragma: no cover - compiled
    acc = 0
    for i in range(a.size):
        acc = s_add(acc, a[i], bits, signed, wrap, cnt)
        out[i] = acc


@njit(cache=True)
def _loop_mul_q(a, b, shift, bits, signed, half_up, wrap, out, cnt):  # pragma: no cover - compiled
    for i in range(a.size):
        out[i] = s_mul_q(a[i], b[i], shift, bits, signed, half_up, wrap, cnt)


@njit(cache=True)
def _loop_mul(a, b, signed, out, cnt):  # pragma: no cover - compiled
    for i in range(a.size):
        out[i] = s_mul(a[i], b[i], signed, cnt)


@njit(cache=True)
def _loop_div(n, d, bits, signed, q, r, cnt):  # pragma: no cover - compiled
    for i in range(n.size):
        q[i], r[i] = s_div(n[i], d[i], bits, signed, cnt)


@njit(cache=True)
def _loop_div_round(n, d, bits, signed, out, cnt):  # pragma: no cover - compiled
    for i in range(n.size):
        out[i] = s_div_round(n[i], d[i], bits, signed, cnt)


@njit(cache=True)
def _loop_isqrt(x, nearest, out, cnt):  # pragma: no cover - compiled
    for i in range(x.size):
        out[i] = s_isqrt(x[i], nearest, cnt)


@njit(cache=True)
def _loop_from_float(v, frac, bits, signed, half_up, wrap, out, cnt):  # pragma: no cover - compiled
    for i in range(v.size):
        out[i] = s_from_float(v[i], frac, bits, signed, half_up, wrap, cnt)


# ---------------------------------------------------------------------------------------------------
# formats


@dataclass(frozen=True)
class QFormat:
    """A fixed-point format ``Qm.n`` held in a ``word_bits``-bit word.

    Parameters
    ----------
    int_bits
        ``m``: integer bits, not counting the sign bit.
    frac_bits
        ``n``: fraction bits (may be negative: a coarser unit than 1).
    signed
        Two's complement (one extra sign bit) or unsigned.
    word_bits
        Width of the RAM word that stores it (8, 16, 24 or 32; at least ``m + n + signed``).

    Examples
    --------
    >>> q = QFormat(1, 14)                     # Q1.14 in a 16-bit word: [-2, 2) g in steps of 2**-14 g
    >>> q.total_bits, q.min_raw, q.max_raw, q.ram_bytes
    (16, -32768, 32767, 2)
    >>> q.from_float(np.array([0.5, -2.5, 1.99999])).tolist()
    [8192, -32768, 32767]
    >>> float(q.to_float(8192))
    0.5
    """

    int_bits: int
    frac_bits: int
    signed: bool = True
    word_bits: int = 16

    def __post_init__(self) -> None:
        if self.word_bits not in (8, 16, 24, 32):
            raise ValueError(f"word_bits must be 8, 16, 24 or 32 (PIC byte multiples), got {self.word_bits}")
        if self.int_bits + self.frac_bits < 1:
            raise ValueError(f"Q{self.int_bits}.{self.frac_bits} has no value bits")
        if self.total_bits > self.word_bits:
            raise ValueError(f"Q{self.int_bits}.{self.frac_bits} ({'signed' if self.signed else 'unsigned'}) "
                             f"needs {self.total_bits} bits, more than its {self.word_bits}-bit word")

    @property
    def total_bits(self) -> int:
        """Bits of the value: ``m + n`` plus the sign bit."""
        return self.int_bits + self.frac_bits + int(self.signed)

    @property
    def min_raw(self) -> int:
        """Smallest raw integer."""
        return word_limits(self.total_bits, self.signed)[0]

    @property
    def max_raw(self) -> int:
        """Largest raw integer."""
        return word_limits(self.total_bits, self.signed)[1]

    @property
    def lsb(self) -> float:
        """Value of one raw unit, ``2**-n``."""
        return 2.0 ** -self.frac_bits

    @property
    def min_value(self) -> float:
        """Smallest representable value."""
        return self.min_raw * self.lsb

    @property
    def max_value(self) -> float:
        """Largest representable value."""
        return self.max_raw * self.lsb

    @property
    def ram_bytes(self) -> int:
        """RAM taken by one value (its word)."""
        return self.word_bits // 8

    def __str__(self) -> str:
        return f"{'' if self.signed else 'U'}Q{self.int_bits}.{self.frac_bits}/{self.word_bits}"

    def to_float(self, raw: np.ndarray | int) -> np.ndarray:
        """Real value of raw integers (float64; exact for words up to 53 bits)."""
        return np.asarray(raw, dtype=np.int64).astype(np.float64) * self.lsb

    def from_float(
        self,
        x: np.ndarray | float,
        *,
        rounding: Rounding = "half_up",
        overflow: Overflow = "saturate",
        ctx: ArithmeticContext | None = None,
    ) -> np.ndarray:
        """Quantise real values to raw integers (``half_up``: ``floor(x·2**n + 1/2)``; ``floor``), then
        saturate or wrap (:func:`s_from_float`). NaN is an error (a firmware never sees one)."""
        v = np.asarray(x, dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"cannot quantise non-finite values to {self}")
        return _apply(_loop_from_float, ctx, "from_float", v, self.frac_bits, self.total_bits, self.signed,
                      _half_up(rounding), _wraps(overflow))


# ---------------------------------------------------------------------------------------------------
# counters


@dataclass
class ArithmeticContext:
    """Counts what the arithmetic did: saturations and wraps per operation, divisions by zero, cycles.

    Pass one to every primitive of the array API (keyword ``ctx``); read it afterwards. A counter array of
    the scalar primitives (:func:`new_counters`) is added with :meth:`absorb`.

    Attributes
    ----------
    saturated
        ``Counter`` of elements clipped, keyed by operation name.
    wrapped
        ``Counter`` of elements whose value wrapped around, keyed by operation name.
    div_by_zero
        Number of divisions by zero (each also counted in ``saturated``).
    cycles
        ``Counter`` of estimated PIC cycles per :data:`CYCLES` key.
    calls
        ``Counter`` of elements processed per :data:`CYCLES` key.

    Examples
    --------
    >>> ctx = ArithmeticContext()
    >>> saturate(np.array([40000, 5]), QFormat(15, 0), ctx=ctx).tolist()
    [32767, 5]
    >>> ctx.total_saturated, ctx.report()
    (1, 'saturated: saturate=1')
    """

    saturated: Counter = field(default_factory=Counter)
    wrapped: Counter = field(default_factory=Counter)
    div_by_zero: int = 0
    cycles: Counter = field(default_factory=Counter)
    calls: Counter = field(default_factory=Counter)

    def cost(self, op: str, n: int = 1) -> None:
        """Add the cycles of ``n`` executions of primitive ``op`` (a :data:`CYCLES` key)."""
        if op not in CYCLES:
            raise KeyError(f"unknown primitive {op!r}; expected one of {sorted(CYCLES)}")
        self.calls[op] += int(n)
        self.cycles[op] += CYCLES[op] * int(n)

    def absorb(self, cnt: np.ndarray, op: str) -> None:
        """Add a counter array of the scalar primitives; its saturations and wraps are attributed to ``op``."""
        for i, name in enumerate(OPS):
            if cnt[i]:
                self.cost(name, int(cnt[i]))
        if cnt[C_SAT]:
            self.saturated[op] += int(cnt[C_SAT])
        if cnt[C_WRAP]:
            self.wrapped[op] += int(cnt[C_WRAP])
        self.div_by_zero += int(cnt[C_DIV0])

    @property
    def total_saturated(self) -> int:
        """Elements clipped by any operation."""
        return int(sum(self.saturated.values()))

    @property
    def total_wrapped(self) -> int:
        """Elements wrapped by any operation."""
        return int(sum(self.wrapped.values()))

    @property
    def total_cycles(self) -> int:
        """Estimated cycles of everything counted."""
        return int(sum(self.cycles.values()))

    def cycles_per_sample(self, n_samples: int) -> float:
        """Mean estimated cycles per input sample (compare with :func:`cycles_per_sample_available`)."""
        return self.total_cycles / max(1, int(n_samples))

    def report(self) -> str:
        """One line per kind of event, empty string when nothing saturated, wrapped or divided by zero."""
        parts = []
        if self.saturated:
            parts.append("saturated: " + ", ".join(f"{k}={v}" for k, v in sorted(self.saturated.items())))
        if self.wrapped:
            parts.append("wrapped: " + ", ".join(f"{k}={v}" for k, v in sorted(self.wrapped.items())))
        if self.div_by_zero:
            parts.append(f"division by zero: {self.div_by_zero}")
        return "; ".join(parts)


# ---------------------------------------------------------------------------------------------------
# array API


def _bits_of(fmt: QFormat | int, signed: bool) -> tuple[int, bool]:
    if isinstance(fmt, QFormat):
        return fmt.total_bits, fmt.signed
    bits = int(fmt)
    word_limits(bits, signed)          # validates the width
    return bits, signed


def _as_int(x: np.ndarray | int) -> np.ndarray:
    a = np.asarray(x)
    if a.dtype.kind not in "iub":
        raise TypeError(f"fixed-point primitives take integer arrays, got dtype {a.dtype}")
    return a.astype(np.int64, copy=False)


def _half_up(rounding: str) -> bool:
    if rounding not in ("half_up", "floor"):
        raise ValueError(f"rounding must be 'half_up' or 'floor', got {rounding!r}")
    return rounding == "half_up"


def _wraps(overflow: str) -> bool:
    if overflow not in ("saturate", "wrap"):
        raise ValueError(f"overflow must be 'saturate' or 'wrap', got {overflow!r}")
    return overflow == "wrap"


def _within(x: np.ndarray, lo: int, hi: int) -> bool:
    """All of ``x`` inside ``[lo, hi]`` (two reductions)."""
    return x.size == 0 or (int(x.min()) >= lo and int(x.max()) <= hi)


def _run(loop, inputs: list[np.ndarray], *rest) -> None:
    """Call an element loop: compiled, or its Python text on Python numbers for small inputs (same bits)."""
    if inputs[0].size <= PYTHON_MAX_ELEMENTS:
        getattr(loop, "py_func", loop)(*[a.astype(object) for a in inputs], *rest)
    else:
        loop(*inputs, *rest)


def _apply(loop, ctx: ArithmeticContext | None, op: str, *args):
    """Run an element loop over the broadcast array arguments (the leading ndarrays of ``args``)."""
    n_arr = 0
    while n_arr < len(args) and isinstance(args[n_arr], np.ndarray):
        n_arr += 1
    arrays = np.broadcast_arrays(*args[:n_arr]) if n_arr > 1 else [args[0]]
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a).reshape(-1) for a in arrays]
    out = np.empty(shape, np.int64)
    cnt = new_counters()
    _run(loop, flat, *args[n_arr:], out.reshape(-1), cnt)
    if ctx is not None:
        ctx.absorb(cnt, op)
    return out


def saturate(x: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
             ctx: ArithmeticContext | None = None, op: str = "saturate") -> np.ndarray:
    """Clip raw integers to the range of ``fmt`` (a :class:`QFormat` or a word width in bits).

    >>> saturate(np.array([-200, 100, 200]), 8).tolist()
    [-128, 100, 127]
    """
    bits, sgn = _bits_of(fmt, signed)
    return _apply(_loop_overflow, ctx, op, _as_int(x), bits, sgn, False)


def wrap(x: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
         ctx: ArithmeticContext | None = None, op: str = "wrap") -> np.ndarray:
    """Keep the low bits of raw integers (two's complement wrap-around into ``fmt``).

    >>> wrap(np.array([128, -129, 300]), 8).tolist(), wrap(np.array([-1, 256]), 8, signed=False).tolist()
    ([-128, 127, 44], [255, 0])
    """
    bits, sgn = _bits_of(fmt, signed)
    return _apply(_loop_overflow, ctx, op, _as_int(x), bits, sgn, True)


def shift_right(x: np.ndarray | int, s: int, *, rounding: Rounding = "half_up",
                ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Drop ``s >= 0`` fraction bits: ``(x + 2**(s-1)) >> s`` (``half_up``) or ``x >> s`` (``floor``).

    Exact for ``|x| < 2**62``. The result needs no saturation: it is never larger in magnitude than ``x``
    (except ``half_up`` of the word's maximum, which can reach ``max >> s`` + 1, still inside the word).

    >>> shift_right(np.array([3, 2, -2, -3, 5]), 1).tolist()        # 1.5, 1, -1, -1.5, 2.5
    [2, 1, -1, -1, 3]
    >>> shift_right(np.array([3, -3]), 1, rounding="floor").tolist()
    [1, -2]
    """
    if s < 0:
        raise ValueError(f"shift must be >= 0, got {s}")
    return _apply(_loop_shift_right, ctx, "shift_right", _as_int(x), int(s), _half_up(rounding))


def shift_left(x: np.ndarray | int, s: int, fmt: QFormat | int, *, signed: bool = True,
               overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``x * 2**s`` brought into ``fmt`` (saturated or wrapped, counted as ``"shift_left"``).

    >>> shift_left(np.array([1, 20000]), 1, 16).tolist()
    [2, 32767]
    """
    if s < 0:
        raise ValueError(f"shift must be >= 0, got {s}")
    bits, sgn = _bits_of(fmt, signed)
    return _apply(_loop_requantize, ctx, "shift_left", _as_int(x), int(s), bits, sgn, True, _wraps(overflow))


def requantize(x: np.ndarray | int, src: QFormat, dst: QFormat, *, rounding: Rounding = "half_up",
               overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Raw integers of format ``src`` re-expressed in ``dst`` (shift with rounding, then saturate/wrap).

    >>> requantize(np.array([12345, -12345]), QFormat(15, 16, word_bits=32), QFormat(7, 8)).tolist()
    [48, -48]
    """
    d = dst.frac_bits - src.frac_bits
    return _apply(_loop_requantize, ctx, "shift_left" if d >= 0 else "requantize", _as_int(x), d,
                  dst.total_bits, dst.signed, _half_up(rounding), _wraps(overflow))


def add(a: np.ndarray | int, b: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
        overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None, op: str = "add") -> np.ndarray:
    """``a + b`` in the word of ``fmt`` (operands already in the same Q format).

    >>> add(np.array([30000, -30000]), np.array([30000, -30000]), 16).tolist()
    [32767, -32768]
    >>> add(np.array([30000]), np.array([30000]), 16, overflow="wrap").tolist()
    [-5536]
    """
    bits, sgn = _bits_of(fmt, signed)
    return _apply(_loop_add, ctx, op, _as_int(a), _as_int(b), bits, sgn, _wraps(overflow))


def sub(a: np.ndarray | int, b: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
        overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None, op: str = "sub") -> np.ndarray:
    """``a - b`` in the word of ``fmt``.

    >>> sub(np.array([-30000]), np.array([30000]), 16).tolist()
    [-32768]
    """
    return add(a, -_as_int(b), fmt, signed=signed, overflow=overflow, ctx=ctx, op=op)


def cumsum(x: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True, overflow: Overflow = "saturate",
           ctx: ArithmeticContext | None = None, op: str = "cumsum") -> np.ndarray:
    """Running sum of a 1-D array in an accumulator word, saturating at each step or wrapping.

    >>> cumsum(np.array([100, 100, -50, 100]), 8).tolist()
    [100, 127, 77, 127]
    >>> cumsum(np.array([100, 100, -50]), 8, overflow="wrap").tolist()
    [100, -56, -106]
    """
    a = _as_int(x)
    if a.ndim != 1:
        raise ValueError(f"cumsum takes a 1-D array, got shape {a.shape}")
    bits, sgn = _bits_of(fmt, signed)
    return _apply(_loop_cumsum, ctx, op, a, bits, sgn, _wraps(overflow))


def mul(a: np.ndarray | int, b: np.ndarray | int, *, signed: bool = True,
        ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Exact 16 x 16 -> 32-bit product (AN617 ``FXM1616S``/``FXM1616U``); operands must fit 16 bits.

    >>> mul(np.array([-32768, 32767]), np.array([-32768, 32767])).tolist()
    [1073741824, 1073676289]
    """
    x, y = _as_int(a), _as_int(b)
    lo, hi = word_limits(16, signed)
    if not (_within(x, lo, hi) and _within(y, lo, hi)):
        raise ValueError(f"mul operands must be {'signed' if signed else 'unsigned'} 16-bit ({lo}..{hi})")
    return _apply(_loop_mul, ctx, "mul", x, y, bool(signed))


def mul_q(a: np.ndarray | int, b: np.ndarray | int, shift: int, out: QFormat | int, *,
          rounding: Rounding = "half_up", overflow: Overflow = "saturate", signed: bool = True,
          ctx: ArithmeticContext | None = None, op: str = "mul_q") -> np.ndarray:
    """Q multiply: the 32-bit product shifted right by ``shift`` with rounding, then saturated or wrapped.

    ``shift = frac(a) + frac(b) - frac(out)``; Q0.15 x Q0.15 -> Q0.15: ``shift = 15``. A negative
    ``shift`` moves the product left (more fraction bits in ``out`` than in the product). The operands are
    ``signed`` (or unsigned) 16-bit words; the result takes the signedness of ``out`` when it is a
    :class:`QFormat`, of ``signed`` otherwise.

    >>> q15 = QFormat(0, 15)
    >>> mul_q(np.array([16384, -32768]), np.array([16384, -32768]), 15, q15).tolist()   # 0.25, +1 saturates
    [8192, 32767]
    """
    x, y = _as_int(a), _as_int(b)
    lo, hi = word_limits(16, signed)
    if not (_within(x, lo, hi) and _within(y, lo, hi)):
        raise ValueError(f"mul operands must be {'signed' if signed else 'unsigned'} 16-bit ({lo}..{hi})")
    bits, sgn = _bits_of(out, signed)
    if sgn != signed:      # the routine's word follows the operands; the result is then brought into `out`
        r = _apply(_loop_mul_q, ctx, op, x, y, int(shift), 62, bool(signed), _half_up(rounding), False)
        return _apply(_loop_overflow, ctx, op, r, bits, sgn, _wraps(overflow))
    return _apply(_loop_mul_q, ctx, op, x, y, int(shift), bits, sgn, _half_up(rounding), _wraps(overflow))


def _div_check(n: np.ndarray, d: np.ndarray, signed: bool) -> None:
    xl, xh = word_limits(32, signed)
    yl, yh = word_limits(16, signed)
    if not (_within(n, xl, xh) and _within(d, yl, yh)):
        raise ValueError(f"div takes a {'signed' if signed else 'unsigned'} 32-bit dividend and 16-bit divisor")


def div(n: np.ndarray | int, d: np.ndarray | int, out: QFormat | int = 32, *, signed: bool = True,
        ctx: ArithmeticContext | None = None, op: str = "div") -> tuple[np.ndarray, np.ndarray]:
    """32 / 16-bit division: quotient truncated towards zero, remainder with the dividend's sign.

    Parameters
    ----------
    n
        Dividend, a 32-bit word (signed or unsigned per ``signed``).
    d
        Divisor, a 16-bit word.
    out
        Word of the quotient (default 32 bits, AN617's); a quotient outside it saturates (counted).

    Returns
    -------
    quotient, remainder
        ``n == q·d + r`` with ``|r| < |d|`` (when nothing saturated). ``d == 0`` gives the quotient's
        saturation value (max for ``n >= 0``, min otherwise), ``r = n`` clipped to 16 bits, and is counted
        in ``ctx.div_by_zero``.

    Examples
    --------
    >>> q, r = div(np.array([7, -7, 7, -7, 5]), np.array([2, 2, -2, -2, 0]))
    >>> q.tolist(), r.tolist()
    ([3, -3, -3, 3, 2147483647], [1, -1, 1, -1, 5])
    """
    x, y = _as_int(n), _as_int(d)
    _div_check(x, y, signed)
    bits, sgn = _bits_of(out, signed)
    xb, yb = np.broadcast_arrays(x, y)
    q = np.empty(xb.shape, np.int64)
    r = np.empty(xb.shape, np.int64)
    cnt = new_counters()
    _run(_loop_div, [np.ascontiguousarray(xb).reshape(-1), np.ascontiguousarray(yb).reshape(-1)], bits,
         bool(signed), q.reshape(-1), r.reshape(-1), cnt)
    if ctx is not None:
        ctx.absorb(cnt, op)
    return q, r


def div_round(n: np.ndarray | int, d: np.ndarray | int, out: QFormat | int = 32, *, signed: bool = True,
              ctx: ArithmeticContext | None = None, op: str = "div_round") -> np.ndarray:
    """32 / 16-bit division rounded to nearest, ties away from zero: ``sign·((|n| + |d| // 2) // |d|)``.

    The firmware idiom: add half the divisor's magnitude to the dividend's magnitude, then the truncating
    :func:`div` on magnitudes (the 33-bit intermediate is held in the routine's carry). Division by zero
    saturates and is counted as in :func:`div`.

    >>> div_round(np.array([7, -7, 5, -5, 4, 1]), np.array([2, 2, 2, 2, 3, 0])).tolist()
    [4, -4, 3, -3, 1, 2147483647]
    """
    x, y = _as_int(n), _as_int(d)
    _div_check(x, y, signed)
    bits, _ = _bits_of(out, signed)
    return _apply(_loop_div_round, ctx, op, x, y, bits, bool(signed))


def isqrt(x: np.ndarray | int, *, rounding: Literal["floor", "nearest"] = "floor",
          ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``floor(sqrt(x))`` of unsigned 32-bit integers, exactly (as the shift-subtract algorithm gives).

    ``rounding="nearest"`` rounds to the nearest integer instead: ``r + 1`` when the remainder
    ``x - r**2`` exceeds ``r`` (``x >= (r + 1/2)**2`` exactly; the restoring algorithm leaves the remainder
    in its register, so this costs one 16-bit compare).

    >>> isqrt(np.array([0, 1, 3, 4, 15, 16, 2**32 - 1])).tolist()
    [0, 1, 1, 2, 3, 4, 65535]
    >>> isqrt(np.array([2, 3, 6, 7, 2**32 - 1]), rounding="nearest").tolist()
    [1, 2, 2, 3, 65536]
    """
    a = _as_int(x)
    if not _within(a, 0, (1 << 32) - 1):
        raise ValueError("isqrt takes unsigned 32-bit integers (0 .. 2**32 - 1)")
    if rounding not in ("floor", "nearest"):
        raise ValueError(f"rounding must be 'floor' or 'nearest', got {rounding!r}")
    return _apply(_loop_isqrt, ctx, "isqrt", a, rounding == "nearest")


def iroot4(x: np.ndarray | int, *, ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``floor(x ** (1/4))`` of unsigned 32-bit integers, as ``isqrt(isqrt(x))`` (exact: nested floors of
    the square root compose, ``floor(sqrt(floor(sqrt(x)))) == floor(x ** 0.25)``).

    To keep ``f`` fraction bits in the root of a value with ``n`` fraction bits, pass ``x << (4f - n)``.

    >>> iroot4(np.array([0, 15, 16, 80, 81, 2**32 - 1])).tolist()
    [0, 1, 2, 2, 3, 255]
    """
    return isqrt(isqrt(x, ctx=ctx), ctx=ctx)
