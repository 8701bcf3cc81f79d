"""The PIC16F877's integer arithmetic: Q formats, words, multiply, divide, shifts, saturation, roots.

Every fixed-point algorithm of the firmware (``firmware_sim.algorithms``) computes with these functions and
nothing else, so the device's arithmetic is defined in one place. Values are held as numpy ``int64``
(vectorised; a scalar is a 0-d array) and every result is brought back into the word it would occupy on the
PIC (8, 16, 24 or 32 bits, two's complement or unsigned) by an explicit saturation or wrap.

Conventions
-----------
* ``Qm.n`` (:class:`QFormat`): ``m`` integer bits *not counting the sign*, ``n`` fraction bits, so a signed
  Qm.n value occupies ``m + n + 1`` bits (PROTOCOL.md's Q15.16 offset and Q1.30 matrix are 32-bit words).
  The raw integer ``r`` stands for ``r / 2**n``.
* Rounding of a right shift by ``s`` (dropping ``s`` fraction bits): ``"half_up"`` adds ``2**(s-1)`` then
  shifts arithmetically (``(r + 2**(s-1)) >> s``: ties go towards +inf, what ``ADDLW``/``RRF`` code does),
  ``"floor"`` is the bare arithmetic shift (two's complement truncation, towards -inf).
* Overflow: ``"saturate"`` clips to the word's range, ``"wrap"`` keeps the low bits (two's complement).
  Every saturation, wrap, and division by zero is counted in an :class:`ArithmeticContext` when one is
  passed, so a chain can assert that nothing saturated unreported.
* Division (:func:`div`) is the 32/16 signed divide of AN617 (sign-magnitude around the unsigned
  ``FXD3216U`` routine): the quotient is truncated towards zero and the remainder takes the dividend's sign
  (``n == q·d + r``, ``|r| < |d|``). Division by zero saturates the quotient (to the word's maximum for a
  non-negative dividend, minimum otherwise), sets the remainder to the dividend clipped to the word, and is
  counted.
* Square root (:func:`isqrt`) is the exact floor of the square root of a 32-bit unsigned input, what the
  bit-by-bit shift-subtract (restoring) algorithm returns; :func:`iroot4` is ``isqrt(isqrt(x))``, which is
  exactly ``floor(x ** (1/4))`` because ``floor(sqrt(floor(y))) == floor(sqrt(y))`` for ``y >= 0``.

Cycle costs
-----------
:data:`CYCLES` holds worst-case instruction cycles of each primitive on the PIC16 (one cycle = 4 clocks =
200 ns at 20 MHz). The multiply and divide figures are Microchip AN617's (``FXM1616S`` 269, ``FXM1616U``
256, ``FXD3216U`` 703; HARDWARE.md); the others are counted from hand-written mid-range instruction
sequences and are estimates (marked so in :data:`CYCLE_SOURCES`). An :class:`ArithmeticContext` adds
``CYCLES[op] * n_elements`` for every call, so the cycles per sample of a chain can be compared with the
100,000 cycles of one 20 ms sample period at 5 MIPS (:data:`CYCLES_PER_SAMPLE_50HZ`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = [
    "CYCLES",
    "CYCLE_SOURCES",
    "CYCLES_PER_SAMPLE_50HZ",
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
]

Rounding = Literal["half_up", "floor"]
Overflow = Literal["saturate", "wrap"]

#: Instruction cycles available per sample at 50 Hz and 5 MIPS (20 MHz clock / 4).
CYCLES_PER_SAMPLE_50HZ = 100_000

#: Worst-case PIC16 instruction cycles per element of each primitive (see :data:`CYCLE_SOURCES`).
CYCLES: dict[str, int] = {
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
    "load_eeprom_sample": 400,  # 4-byte I2C random read at 400 kHz: ~80 us = 400 cycles (estimate)
}

#: Where each :data:`CYCLES` figure comes from.
CYCLE_SOURCES: dict[str, str] = {
    "mul16x16s": "Microchip AN617, FXM1616S worst case",
    "mul16x16u": "Microchip AN617, FXM1616U worst case",
    "div32by16u": "Microchip AN617, FXD3216U worst case",
    **{k: "estimate: counted from a hand-written PIC16 instruction sequence"
       for k in ("add16", "add32", "sat16", "sat32", "shift32_per_bit", "round32", "compare16", "compare32",
                 "mul8x8u", "div32by16s", "isqrt32")},
    "load_eeprom_sample": "estimate: 24LC1025 random read, 4 data bytes + 3 address bytes at 400 kHz",
}


def word_limits(bits: int, signed: bool = True) -> tuple[int, int]:
    """Smallest and largest integer of a ``bits``-bit word.

    >>> word_limits(16), word_limits(8, signed=False)
    ((-32768, 32767), (0, 255))
    """
    if not 1 <= bits <= 62:
        raise ValueError(f"word width must be 1-62 bits, got {bits}")
    if signed:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


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
        saturate or wrap. NaN is an error (a firmware never sees one)."""
        v = np.asarray(x, dtype=np.float64) * 2.0 ** self.frac_bits
        if not np.all(np.isfinite(v)):
            raise ValueError(f"cannot quantise non-finite values to {self}")
        v = np.floor(v + 0.5) if rounding == "half_up" else np.floor(v)
        lim = float(2 ** 62)
        raw = np.clip(v, -lim, lim).astype(np.int64)
        return _overflow(raw, self.total_bits, self.signed, overflow, ctx, "from_float")


# ---------------------------------------------------------------------------------------------------
# counters


@dataclass
class ArithmeticContext:
    """Counts what the arithmetic did: saturations and wraps per operation, divisions by zero, cycles.

    Pass one to every primitive of a chain (keyword ``ctx``); read it afterwards.

    Attributes
    ----------
    saturated
        ``Counter`` of elements clipped, keyed by operation name.
    wrapped
        ``Counter`` of elements whose value wrapped around, keyed by operation name.
    div_by_zero
        Number of divisions by zero (each also counted in ``saturated["div"]``).
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
        """Mean estimated cycles per input sample (compare with :data:`CYCLES_PER_SAMPLE_50HZ`)."""
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
# word handling


def _limits_of(fmt: QFormat | int, signed: bool) -> tuple[int, int, int, bool]:
    if isinstance(fmt, QFormat):
        return (*word_limits(fmt.total_bits, fmt.signed), fmt.total_bits, fmt.signed)
    lo, hi = word_limits(int(fmt), signed)
    return lo, hi, int(fmt), signed


def _overflow(x: np.ndarray, bits: int, signed: bool, mode: Overflow, ctx: ArithmeticContext | None,
              op: str) -> np.ndarray:
    lo, hi = word_limits(bits, signed)
    if mode in ("saturate", "wrap") and _within(x, lo, hi):
        return x                     # nothing to do (the common case: two fast reductions)
    if mode == "saturate":
        out = np.minimum(np.maximum(x, lo), hi)
        if ctx is not None:
            n = int(np.count_nonzero((x < lo) | (x > hi)))
            if n:
                ctx.saturated[op] += n
        return out
    if mode == "wrap":
        mask = (1 << bits) - 1
        out = x & mask
        if signed:
            out = np.where(out > hi, out - (1 << bits), out)
        if ctx is not None:
            n = int(np.count_nonzero(out != x))
            if n:
                ctx.wrapped[op] += n
        return out
    raise ValueError(f"overflow must be 'saturate' or 'wrap', got {mode!r}")


def _within(x: np.ndarray, lo: int, hi: int) -> bool:
    """All of ``x`` inside ``[lo, hi]`` (two reductions)."""
    return x.size == 0 or (int(x.min()) >= lo and int(x.max()) <= hi)


def _as_int(x: np.ndarray | int) -> np.ndarray:
    a = np.asarray(x)
    if a.dtype.kind not in "iub":
        raise TypeError(f"fixed-point primitives take integer arrays, got dtype {a.dtype}")
    return a.astype(np.int64, copy=False)


def saturate(x: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
             ctx: ArithmeticContext | None = None, op: str = "saturate") -> np.ndarray:
    """Clip raw integers to the range of ``fmt`` (a :class:`QFormat` or a word width in bits).

    Like every primitive here, it may return its (int64) input itself when nothing changes: do not modify
    a result in place if its input must stay intact.

    >>> saturate(np.array([-200, 100, 200]), 8).tolist()
    [-128, 100, 127]
    """
    _, _, bits, sgn = _limits_of(fmt, signed)
    return _overflow(_as_int(x), bits, sgn, "saturate", ctx, op)


def wrap(x: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
         ctx: ArithmeticContext | None = None, op: str = "wrap") -> np.ndarray:
    """Keep the low bits of raw integers (two's complement wrap-around into ``fmt``).

    >>> wrap(np.array([128, -129, 300]), 8).tolist(), wrap(np.array([-1, 256]), 8, signed=False).tolist()
    ([-128, 127, 44], [255, 0])
    """
    _, _, bits, sgn = _limits_of(fmt, signed)
    return _overflow(_as_int(x), bits, sgn, "wrap", ctx, op)


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
    a = _as_int(x)
    if s < 0:
        raise ValueError(f"shift must be >= 0, got {s}")
    if ctx is not None:
        ctx.cost("shift32_per_bit", a.size * s)
        if rounding == "half_up" and s:
            ctx.cost("round32", a.size)
    if s == 0:
        return a.copy()
    if rounding == "half_up":
        return (a + (1 << (s - 1))) >> s
    if rounding == "floor":
        return a >> s
    raise ValueError(f"rounding must be 'half_up' or 'floor', got {rounding!r}")


def shift_left(x: np.ndarray | int, s: int, fmt: QFormat | int, *, signed: bool = True,
               overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``x * 2**s`` brought into ``fmt`` (saturated or wrapped, counted as ``"shift_left"``).

    >>> shift_left(np.array([1, 20000]), 1, 16).tolist()
    [2, 32767]
    """
    a = _as_int(x)
    if s < 0:
        raise ValueError(f"shift must be >= 0, got {s}")
    _, _, bits, sgn = _limits_of(fmt, signed)
    if ctx is not None:
        ctx.cost("shift32_per_bit", a.size * s)
    return _overflow(a << s, bits, sgn, overflow, ctx, "shift_left")


def requantize(x: np.ndarray | int, src: QFormat, dst: QFormat, *, rounding: Rounding = "half_up",
               overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None) -> np.ndarray:
    """Raw integers of format ``src`` re-expressed in ``dst`` (shift with rounding, then saturate/wrap).

    >>> requantize(np.array([12345, -12345]), QFormat(15, 16, word_bits=32), QFormat(7, 8)).tolist()
    [48, -48]
    """
    a = _as_int(x)
    d = dst.frac_bits - src.frac_bits
    if d >= 0:
        return shift_left(a, d, dst, overflow=overflow, ctx=ctx)
    return _overflow(shift_right(a, -d, rounding=rounding, ctx=ctx), dst.total_bits, dst.signed, overflow,
                     ctx, "requantize")


def add(a: np.ndarray | int, b: np.ndarray | int, fmt: QFormat | int, *, signed: bool = True,
        overflow: Overflow = "saturate", ctx: ArithmeticContext | None = None, op: str = "add") -> np.ndarray:
    """``a + b`` in the word of ``fmt`` (operands already in the same Q format).

    >>> add(np.array([30000, -30000]), np.array([30000, -30000]), 16).tolist()
    [32767, -32768]
    >>> add(np.array([30000]), np.array([30000]), 16, overflow="wrap").tolist()
    [-5536]
    """
    x, y = _as_int(a), _as_int(b)
    _, _, bits, sgn = _limits_of(fmt, signed)
    if ctx is not None:
        n = np.broadcast(x, y).size
        ctx.cost("add16" if bits <= 16 else "add32", n)
        ctx.cost("sat16" if bits <= 16 else "sat32", n) if overflow == "saturate" else None
    return _overflow(x + y, bits, sgn, overflow, ctx, op)


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

    Wrap is a ring homomorphism, so the wrapped running sum is the wrapped exact running sum (one
    vectorised pass). A saturating accumulator is recursive: the exact running sum is used up to the first
    sample that leaves the range, and a per-sample loop (the firmware's) continues from there.

    >>> cumsum(np.array([100, 100, -50, 100]), 8).tolist()
    [100, 127, 77, 127]
    >>> cumsum(np.array([100, 100, -50]), 8, overflow="wrap").tolist()
    [100, -56, -106]
    """
    a = _as_int(x)
    if a.ndim != 1:
        raise ValueError(f"cumsum takes a 1-D array, got shape {a.shape}")
    lo, hi, bits, sgn = _limits_of(fmt, signed)
    if ctx is not None:
        ctx.cost("add16" if bits <= 16 else "add32", a.size)
    exact = np.cumsum(a)
    if overflow == "wrap":
        return _overflow(exact, bits, sgn, "wrap", ctx, op)
    if overflow != "saturate":
        raise ValueError(f"overflow must be 'saturate' or 'wrap', got {overflow!r}")
    if ctx is not None:
        ctx.cost("sat16" if bits <= 16 else "sat32", a.size)
    bad = np.flatnonzero((exact < lo) | (exact > hi))
    if bad.size == 0:
        return exact
    out = exact.copy()
    k0 = int(bad[0])
    acc = int(exact[k0 - 1]) if k0 else 0
    n_sat = 0
    vals = a.tolist()
    for k in range(k0, a.size):  # recursive: the clipped state feeds the next sample
        acc += vals[k]
        if acc > hi:
            acc, n_sat = hi, n_sat + 1
        elif acc < lo:
            acc, n_sat = lo, n_sat + 1
        out[k] = acc
    if ctx is not None and n_sat:
        ctx.saturated[op] += n_sat
    return out


# ---------------------------------------------------------------------------------------------------
# multiply, divide


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
    if ctx is not None:
        ctx.cost("mul16x16s" if signed else "mul16x16u", np.broadcast(x, y).size)
    return x * y


def mul_q(a: np.ndarray | int, b: np.ndarray | int, shift: int, out: QFormat | int, *,
          rounding: Rounding = "half_up", overflow: Overflow = "saturate", signed: bool = True,
          ctx: ArithmeticContext | None = None, op: str = "mul_q") -> np.ndarray:
    """Q multiply: the 32-bit product shifted right by ``shift`` with rounding, then saturated or wrapped.

    ``shift = frac(a) + frac(b) - frac(out)``; Q0.15 x Q0.15 -> Q0.15: ``shift = 15``. A negative
    ``shift`` moves the product left (more fraction bits in ``out`` than in the product).

    >>> q15 = QFormat(0, 15)
    >>> mul_q(np.array([16384, -32768]), np.array([16384, -32768]), 15, q15).tolist()   # 0.25, +1 saturates
    [8192, 32767]
    """
    p = mul(a, b, signed=signed, ctx=ctx)
    r = shift_right(p, shift, rounding=rounding, ctx=ctx) if shift >= 0 else p << -shift
    _, _, bits, sgn = _limits_of(out, signed)
    if ctx is not None and overflow == "saturate":
        ctx.cost("sat16" if bits <= 16 else "sat32", r.size)
    return _overflow(r, bits, sgn, overflow, ctx, op)


def _div_operands(n: np.ndarray | int, d: np.ndarray | int, out: QFormat | int, signed: bool,
                  ctx: ArithmeticContext | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, tuple]:
    """Checked 32-bit dividend and 16-bit divisor of :func:`div` / :func:`div_round`, broadcast; the divisor with
    zeros replaced by 1 (``safe``), the zero mask and count, the output limits; the divide's cycles counted."""
    x, y = _as_int(n), _as_int(d)
    xl, xh = word_limits(32, signed)
    yl, yh = word_limits(16, signed)
    if not (_within(x, xl, xh) and _within(y, yl, yh)):
        raise ValueError(f"div takes a {'signed' if signed else 'unsigned'} 32-bit dividend and 16-bit divisor")
    if x.shape != y.shape:
        x, y = np.broadcast_arrays(x, y)
    if ctx is not None:
        ctx.cost("div32by16s" if signed else "div32by16u", x.size)
    zero = y == 0
    nz = int(np.count_nonzero(zero))
    safe = np.where(zero, 1, y) if nz else y
    return x, y, safe, zero, nz, _limits_of(out, signed)


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
    x, y, safe, zero, nz, (lo, hi, bits, sgn) = _div_operands(n, d, out, signed, ctx)
    # magnitudes: truncation towards zero. The float64 quotient of |n| < 2**31 by |d| < 2**16 is never
    # rounded up to the next integer (the gap 1/|d| >= 2**-16 exceeds the rounding error q * 2**-53), so
    # its floor is the exact integer quotient (and much faster than numpy's integer division).
    q = np.floor(np.abs(x) / np.abs(safe)).astype(np.int64)
    np.negative(q, out=q, where=(x ^ safe) < 0)
    r = x - q * safe
    if nz:
        q = np.where(zero, np.where(x >= 0, hi, lo), q)
        r = np.where(zero, np.clip(x, *word_limits(16, signed)), r)
        if ctx is not None:
            ctx.div_by_zero += nz
            ctx.saturated[op] += nz
    return _overflow(q, bits, sgn, "saturate", ctx, op), r


def div_round(n: np.ndarray | int, d: np.ndarray | int, out: QFormat | int = 32, *, signed: bool = True,
              ctx: ArithmeticContext | None = None, op: str = "div_round") -> np.ndarray:
    """32 / 16-bit division rounded to nearest, ties away from zero: ``sign·((|n| + |d| // 2) // |d|)``.

    The firmware idiom: add half the divisor's magnitude to the dividend's magnitude, then the truncating
    :func:`div` on magnitudes (the 33-bit intermediate is held in the routine's carry). Division by zero
    saturates and is counted as in :func:`div`.

    >>> div_round(np.array([7, -7, 5, -5, 4, 1]), np.array([2, 2, 2, 2, 3, 0])).tolist()
    [4, -4, 3, -3, 1, 2147483647]
    """
    x, y, safe, zero, nz, (lo, hi, bits, sgn) = _div_operands(n, d, out, signed, ctx)
    if ctx is not None:
        ctx.cost("add32", x.size)
    ay = np.abs(safe)
    res = np.floor((np.abs(x) + (ay >> 1)) / ay).astype(np.int64)   # exact, as in div()
    np.negative(res, out=res, where=(x ^ safe) < 0)
    if nz:
        res = np.where(zero, np.where(x >= 0, hi, lo), res)
        if ctx is not None:
            ctx.div_by_zero += nz
            ctx.saturated[op] += nz
    return _overflow(res, bits, sgn, "saturate", ctx, op)


# ---------------------------------------------------------------------------------------------------
# roots

_U32_MAX = (1 << 32) - 1


def isqrt(x: np.ndarray | int, *, rounding: Literal["floor", "nearest"] = "floor",
          ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``floor(sqrt(x))`` of unsigned 32-bit integers, exactly (as the shift-subtract algorithm gives).

    ``rounding="nearest"`` rounds to the nearest integer instead: ``r + 1`` when the remainder
    ``x - r**2`` exceeds ``r`` (``x >= (r + 1/2)**2`` exactly; the restoring algorithm leaves the remainder
    in its register, so this costs one 16-bit compare).

    Vectorised: the float64 square root of an integer below ``2**32`` is within one of the truth, and one
    integer correction step each way makes it exact (checked against :func:`math.isqrt`).

    >>> isqrt(np.array([0, 1, 3, 4, 15, 16, 2**32 - 1])).tolist()
    [0, 1, 1, 2, 3, 4, 65535]
    >>> isqrt(np.array([2, 3, 6, 7, 2**32 - 1]), rounding="nearest").tolist()
    [1, 2, 2, 3, 65536]
    """
    a = _as_int(x)
    if np.any((a < 0) | (a > _U32_MAX)):
        raise ValueError("isqrt takes unsigned 32-bit integers (0 .. 2**32 - 1)")
    if ctx is not None:
        ctx.cost("isqrt32", a.size)
    r = np.floor(np.sqrt(a.astype(np.float64))).astype(np.int64)
    r = np.where(r * r > a, r - 1, r)
    r = np.where((r + 1) * (r + 1) <= a, r + 1, r)
    if rounding == "nearest":
        if ctx is not None:
            ctx.cost("compare16", a.size)
        return np.where(a - r * r > r, r + 1, r)
    if rounding != "floor":
        raise ValueError(f"rounding must be 'floor' or 'nearest', got {rounding!r}")
    return r


def iroot4(x: np.ndarray | int, *, ctx: ArithmeticContext | None = None) -> np.ndarray:
    """``floor(x ** (1/4))`` of unsigned 32-bit integers, as ``isqrt(isqrt(x))`` (exact: nested floors of
    the square root compose, ``floor(sqrt(floor(sqrt(x)))) == floor(x ** 0.25)``).

    To keep ``f`` fraction bits in the root of a value with ``n`` fraction bits, pass ``x << (4f - n)``.

    >>> iroot4(np.array([0, 15, 16, 80, 81, 2**32 - 1])).tolist()
    [0, 1, 2, 2, 3, 255]
    """
    return isqrt(isqrt(x, ctx=ctx), ctx=ctx)
