"""The two arithmetics of the on-line step algorithm: float, and the PIC16F877's fixed point.

The algorithm (:mod:`gaitlog.firmware_sim.algorithms.online`) is written once, as the firmware computes it, with
every value in a declared Q format. It calls only the operations below; **the type of the values selects
the arithmetic**:

* ``float`` (numpy ``float64`` state): real values; formats, word widths and rounding are ignored
  (``mul`` is ``a * b``, ``requant`` is the identity, ``div`` is ``a / b``, ``sqrt`` is ``math.sqrt``);
* ``int`` (numpy ``int64`` state): raw integers of the declared Q formats, computed by the PIC primitives
  of :mod:`gaitlog.firmware_sim.fixedpoint` (``s_mul_q``, ``s_div_round``, ``s_isqrt`` ...): rounded, saturated and
  counted exactly as the PIC computes them.

A value's format is given as its number of fraction bits (``f``), a word as its width in bits (negative:
unsigned). "Value-preserving" operations (``requant``) change the representation only; "scaling"
operations (``scale2``) change the value. Comparisons (``<``, ``>``) and index arithmetic are plain Python
in both arithmetics (indices are integers in both).

Each operation is a plain Python function (it runs uncompiled, so the algorithm's ``py_func`` is a Python
reference of the compiled kernel) and a numba overload that picks the implementation from the argument
type at compile time, so the kernel compiles to two machine-code versions, one per arithmetic.

Examples
--------
>>> from gaitlog.firmware_sim.fixedpoint import new_counters
>>> cnt = new_counters()
>>> mul(0.5, 13, 0.25, 15, 14, 16, cnt), mul(4096, 13, 8192, 15, 14, 16, cnt)   # 0.125 in Q.14: 2048
(0.125, 2048)
>>> div(-7, 0, 2, 0, 0, 32, cnt), div(-7.0, 0, 2, 0, 0, 32, cnt)    # ties away from zero in fixed point
(-4, -3.5)
"""

from __future__ import annotations

import math

from gaitlog.firmware_sim.compiled import numba_types as types
from gaitlog.firmware_sim.compiled import overload
from gaitlog.firmware_sim.fixedpoint import (
    OP_MUL8,
    ROUND_HALF_UP,
    s_add,
    s_cost,
    s_div_mode,
    s_isqrt,
    s_mul_q,
    s_requantize,
    s_shift_left,
    s_shift_right,
)

__all__ = ["mul", "add", "sub", "neg", "requant", "scale2", "div", "sqrt", "mul_count", "FIXED", "ROUNDING_CLASSES"]

#: The rounding mode of each operation class (:data:`gaitlog.firmware_sim.fixedpoint.ROUNDING_MODES`): products
#: (``mul``), right shifts (``requant``, ``scale2``, the divisor's and the square root's alignment) and quotients
#: (``div``). The firmware's: half up everywhere (a quotient's magnitude: ties away from zero). A kernel compiled
#: for other modes (:mod:`gaitlog.firmware_sim.algorithms.format_kernel`) replaces these constants.
ROUND_MUL = ROUND_HALF_UP
ROUND_SHIFT = ROUND_HALF_UP
ROUND_DIV = ROUND_HALF_UP
#: The operation classes and their constants' names.
ROUNDING_CLASSES = {"mul": "ROUND_MUL", "shift": "ROUND_SHIFT", "div": "ROUND_DIV"}


def _fixed(x) -> bool:
    return not isinstance(x, float) and not (hasattr(x, "dtype") and x.dtype.kind == "f")


# ------------------------------------------------------------------------------------------------------
# fixed-point implementations (numba compiles them inline; plain Python runs them too)


def _mul_fixed(a, fa, b, fb, fo, bits, cnt):
    signed = bits > 0
    return s_mul_q(a, b, fa + fb - fo, abs(bits), signed, ROUND_MUL, False, cnt)


def _add_fixed(a, b, bits, cnt):
    return s_add(a, b, abs(bits), bits > 0, False, cnt)


def _sub_fixed(a, b, bits, cnt):
    return s_add(a, -b, abs(bits), bits > 0, False, cnt)


def _neg_fixed(a, bits, cnt):
    return s_add(0, -a, abs(bits), bits > 0, False, cnt)


def _requant_fixed(a, fa, fo, bits, cnt):
    return s_requantize(a, fo - fa, abs(bits), bits > 0, ROUND_SHIFT, False, cnt)


def _scale2_fixed(a, k, bits, cnt):
    if k >= 0:
        return s_shift_left(a, k, abs(bits), bits > 0, False, cnt)
    return s_shift_right(a, -k, ROUND_SHIFT, cnt)


def _div_fixed(a, fa, b, fb, fo, bits, cnt):
    s = fo - fa + fb          # the dividend's pre-shift: quotient frac = (fa + s) - fb = fo
    n = s_shift_left(a, s, 32, True, False, cnt) if s >= 0 else s_shift_right(a, -s, ROUND_SHIFT, cnt)
    return s_div_mode(n, b, abs(bits), bits > 0, ROUND_DIV, cnt)


def _sqrt_fixed(a, fa, fo, nearest, cnt):
    x = s_requantize(a, 2 * fo - fa, 32, False, ROUND_SHIFT, False, cnt)
    return s_isqrt(x, nearest, cnt)


def _mul_count_fixed(a, n, bits, cnt):
    # value times a small non-negative integer (a sample count): a 32 x 8 multiply, four 8 x 8 products
    s_cost(cnt, OP_MUL8, 4)
    return s_add(0, a * n, abs(bits), bits > 0, False, cnt)


#: The fixed-point implementation of each operation (a kernel compiled for other rounding modes compiles these).
FIXED = {"mul": _mul_fixed, "add": _add_fixed, "sub": _sub_fixed, "neg": _neg_fixed, "requant": _requant_fixed,
         "scale2": _scale2_fixed, "div": _div_fixed, "sqrt": _sqrt_fixed, "mul_count": _mul_count_fixed}


# ------------------------------------------------------------------------------------------------------
# float implementations


def _mul_float(a, fa, b, fb, fo, bits, cnt):
    return a * b


def _add_float(a, b, bits, cnt):
    return a + b


def _sub_float(a, b, bits, cnt):
    return a - b


def _neg_float(a, bits, cnt):
    return -a


def _requant_float(a, fa, fo, bits, cnt):
    return a


def _scale2_float(a, k, bits, cnt):
    return a * 2.0 ** k


def _div_float(a, fa, b, fb, fo, bits, cnt):
    return a / b


def _sqrt_float(a, fa, fo, nearest, cnt):
    return math.sqrt(a)


def _mul_count_float(a, n, bits, cnt):
    return a * n


# ------------------------------------------------------------------------------------------------------
# the vocabulary: Python dispatch + numba overloads (compile-time dispatch on the value type)


def mul(a, fa, b, fb, fo, bits, cnt):
    """``a · b`` in ``fo`` fraction bits and a ``bits`` word (rounded half up, saturated)."""
    return (_mul_fixed if _fixed(a) else _mul_float)(a, fa, b, fb, fo, bits, cnt)


def add(a, b, bits, cnt):
    """``a + b`` (same format), saturated into a ``bits`` word."""
    return (_add_fixed if _fixed(a) else _add_float)(a, b, bits, cnt)


def sub(a, b, bits, cnt):
    """``a - b`` (same format), saturated into a ``bits`` word."""
    return (_sub_fixed if _fixed(a) else _sub_float)(a, b, bits, cnt)


def neg(a, bits, cnt):
    """``-a``, saturated into a ``bits`` word."""
    return (_neg_fixed if _fixed(a) else _neg_float)(a, bits, cnt)


def requant(a, fa, fo, bits, cnt):
    """The same value with ``fo`` instead of ``fa`` fraction bits (rounded half up, saturated)."""
    return (_requant_fixed if _fixed(a) else _requant_float)(a, fa, fo, bits, cnt)


def scale2(a, k, bits, cnt):
    """``a · 2**k`` (same format; ``k < 0`` rounds half up)."""
    return (_scale2_fixed if _fixed(a) else _scale2_float)(a, k, bits, cnt)


def div(a, fa, b, fb, fo, bits, cnt):
    """``a / b`` in ``fo`` fraction bits (rounded to nearest, ties away from zero; ``b`` a 16-bit word)."""
    return (_div_fixed if _fixed(a) else _div_float)(a, fa, b, fb, fo, bits, cnt)


def sqrt(a, fa, fo, nearest, cnt):
    """``sqrt(a)`` in ``fo`` fraction bits (floor, or ``nearest``; the argument an unsigned 32-bit word)."""
    return (_sqrt_fixed if _fixed(a) else _sqrt_float)(a, fa, fo, nearest, cnt)


def mul_count(a, n, bits, cnt):
    """``a · n`` for a small non-negative integer ``n`` (a number of samples), saturated."""
    return (_mul_count_fixed if _fixed(a) else _mul_count_float)(a, n, bits, cnt)


def _pick(a, fixed_impl, float_impl):
    return float_impl if isinstance(a, types.Float) else fixed_impl


# numba checks that an overload's signature matches the function's: one declaration each
@overload(mul, jit_options={"cache": True})
def _ol_mul(a, fa, b, fb, fo, bits, cnt):
    return _pick(a, _mul_fixed, _mul_float)


@overload(add, jit_options={"cache": True})
def _ol_add(a, b, bits, cnt):
    return _pick(a, _add_fixed, _add_float)


@overload(sub, jit_options={"cache": True})
def _ol_sub(a, b, bits, cnt):
    return _pick(a, _sub_fixed, _sub_float)


@overload(neg, jit_options={"cache": True})
def _ol_neg(a, bits, cnt):
    return _pick(a, _neg_fixed, _neg_float)


@overload(requant, jit_options={"cache": True})
def _ol_requant(a, fa, fo, bits, cnt):
    return _pick(a, _requant_fixed, _requant_float)


@overload(scale2, jit_options={"cache": True})
def _ol_scale2(a, k, bits, cnt):
    return _pick(a, _scale2_fixed, _scale2_float)


@overload(div, jit_options={"cache": True})
def _ol_div(a, fa, b, fb, fo, bits, cnt):
    return _pick(a, _div_fixed, _div_float)


@overload(sqrt, jit_options={"cache": True})
def _ol_sqrt(a, fa, fo, nearest, cnt):
    return _pick(a, _sqrt_fixed, _sqrt_float)


@overload(mul_count, jit_options={"cache": True})
def _ol_mul_count(a, n, bits, cnt):
    return _pick(a, _mul_count_fixed, _mul_count_float)

