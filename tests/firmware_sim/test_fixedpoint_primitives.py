"""The PIC arithmetic of ``gaitlog.firmware_sim.fixedpoint``, bit-exact against apytypes (and Python integers), through
the compiled element loops and through their Python text (small arrays)."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim import fixedpoint
from gaitlog.firmware_sim.fixedpoint import (
    CYCLES,
    ArithmeticContext,
    QFormat,
    add,
    cumsum,
    div,
    div_round,
    iroot4,
    isqrt,
    mul,
    mul_q,
    requantize,
    saturate,
    shift_right,
    sub,
    wrap,
)

apy = pytest.importorskip("apytypes")
A = apy.APyFixedArray
QM = apy.QuantizationMode
OM = apy.OverflowMode

RNG_SEED = 20061


@pytest.fixture(autouse=True, scope="module", params=["compiled", "python"])
def element_loops(request: pytest.FixtureRequest) -> Iterator[str]:
    """Every test runs twice: through the compiled element loops, and through their Python text (the path of
    arrays of at most ``PYTHON_MAX_ELEMENTS`` elements, which needs no numba)."""
    saved = fixedpoint.PYTHON_MAX_ELEMENTS
    fixedpoint.PYTHON_MAX_ELEMENTS = -1 if request.param == "compiled" else 1 << 40
    yield request.param
    fixedpoint.PYTHON_MAX_ELEMENTS = saved

ROUND = {"half_up": QM.RND, "floor": QM.TRN}
OVER = {"saturate": OM.SAT, "wrap": OM.WRAP}


def to_apy(raw: np.ndarray, q: QFormat) -> object:
    """Signed Q format -> apytypes array (apytypes counts the sign in ``int_bits``)."""
    return A(np.asarray(raw, np.int64), int_bits=q.int_bits + 1, frac_bits=q.frac_bits)


def from_apy(x: object) -> np.ndarray:
    """apytypes array -> raw integers at its own fraction bits (exact below 53 bits)."""
    v = np.asarray(x.to_numpy(), np.float64) * 2.0 ** x.frac_bits
    assert np.all(v == np.round(v))
    return v.astype(np.int64)


def cast_apy(x: object, q: QFormat, rounding: str, overflow: str) -> np.ndarray:
    return from_apy(x.cast(int_bits=q.int_bits + 1, frac_bits=q.frac_bits, quantization=ROUND[rounding],
                           overflow=OVER[overflow]))


def random_raw(rng: np.random.Generator, q: QFormat, n: int) -> np.ndarray:
    """Uniform raw values plus the word's edges."""
    edges = np.array([q.min_raw, q.min_raw + 1, -1, 0, 1, q.max_raw - 1, q.max_raw], np.int64)
    return np.concatenate([edges, rng.integers(q.min_raw, q.max_raw + 1, n - edges.size)])


MUL_CASES = [  # (a, b, out): the products the chain uses, and wide-range ones that overflow
    (QFormat(0, 15), QFormat(0, 15), QFormat(0, 15)),
    (QFormat(1, 14), QFormat(1, 14), QFormat(1, 14)),
    (QFormat(0, 15), QFormat(15, 0), QFormat(7, 8)),
    (QFormat(3, 12), QFormat(1, 14), QFormat(2, 13)),
    (QFormat(15, 0), QFormat(15, 0), QFormat(15, 16, word_bits=32)),
    (QFormat(7, 8), QFormat(7, 8), QFormat(4, 11)),
]


@pytest.mark.parametrize("qa,qb,qo", MUL_CASES, ids=lambda q: str(q))
@pytest.mark.parametrize("rounding", ["half_up", "floor"])
@pytest.mark.parametrize("overflow", ["saturate", "wrap"])
def test_mul_q_matches_apytypes(qa: QFormat, qb: QFormat, qo: QFormat, rounding: str, overflow: str) -> None:
    rng = np.random.default_rng(RNG_SEED)
    a = random_raw(rng, qa, 20_000)
    b = rng.permutation(random_raw(rng, qb, 20_000))
    shift = qa.frac_bits + qb.frac_bits - qo.frac_bits
    ctx = ArithmeticContext()
    ours = mul_q(a, b, shift, qo, rounding=rounding, overflow=overflow, ctx=ctx)
    ref = cast_apy(to_apy(a, qa) * to_apy(b, qb), qo, rounding, overflow)
    np.testing.assert_array_equal(ours, ref)
    # every element that left the range is counted, and nothing else
    exact = a * b
    if shift <= 0:
        scaled = exact << -shift
    else:
        scaled = (exact + (1 << (shift - 1)) if rounding == "half_up" else exact) >> shift
    n_out = int(np.count_nonzero((scaled < qo.min_raw) | (scaled > qo.max_raw)))
    assert (ctx.total_saturated if overflow == "saturate" else ctx.total_wrapped) == n_out
    assert ctx.calls["mul16x16s"] == a.size


@settings(max_examples=300, deadline=None)
@given(a=st.integers(-32768, 32767), b=st.integers(-32768, 32767), shift=st.integers(0, 30),
       out_int=st.integers(0, 15), rounding=st.sampled_from(["half_up", "floor"]),
       overflow=st.sampled_from(["saturate", "wrap"]))
def test_mul_q_property_apytypes(a: int, b: int, shift: int, out_int: int, rounding: str, overflow: str) -> None:
    qo = QFormat(out_int, 15 - out_int)
    qa = QFormat(15, 0)
    # b carries all the fraction bits, so that a*b has `shift` more of them than qo
    fb = shift + qo.frac_bits
    ref_b = A([b], bits=16, frac_bits=fb)
    ref = cast_apy(to_apy(np.array([a]), qa) * ref_b, qo, rounding, overflow)
    ours = mul_q(np.array([a]), np.array([b]), shift, qo, rounding=rounding, overflow=overflow)
    assert ours.tolist() == ref.tolist()


@pytest.mark.parametrize("src,dst", [
    (QFormat(15, 16, word_bits=32), QFormat(7, 8)),
    (QFormat(1, 30, word_bits=32), QFormat(1, 14)),
    (QFormat(0, 15), QFormat(3, 4, word_bits=8)),
    (QFormat(7, 8), QFormat(3, 12)),                 # shift left: saturates / wraps
    (QFormat(23, 8, word_bits=32), QFormat(15, 0)),
])
@pytest.mark.parametrize("rounding", ["half_up", "floor"])
@pytest.mark.parametrize("overflow", ["saturate", "wrap"])
def test_requantize_matches_apytypes(src: QFormat, dst: QFormat, rounding: str, overflow: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 1)
    x = random_raw(rng, src, 20_000)
    ctx = ArithmeticContext()
    ours = requantize(x, src, dst, rounding=rounding, overflow=overflow, ctx=ctx)
    np.testing.assert_array_equal(ours, cast_apy(to_apy(x, src), dst, rounding, overflow))
    assert (ours >= dst.min_raw).all() and (ours <= dst.max_raw).all()


@pytest.mark.parametrize("q", [QFormat(7, 0, word_bits=8), QFormat(7, 8), QFormat(15, 16, word_bits=32)])
@pytest.mark.parametrize("overflow", ["saturate", "wrap"])
def test_add_sub_match_apytypes(q: QFormat, overflow: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 2)
    a = random_raw(rng, q, 10_000)
    b = rng.permutation(random_raw(rng, q, 10_000))
    ctx = ArithmeticContext()
    s = add(a, b, q, overflow=overflow, ctx=ctx)
    d = sub(a, b, q, overflow=overflow, ctx=ctx)
    np.testing.assert_array_equal(s, cast_apy(to_apy(a, q) + to_apy(b, q), q, "floor", overflow))
    np.testing.assert_array_equal(d, cast_apy(to_apy(a, q) - to_apy(b, q), q, "floor", overflow))
    n_out = int(np.count_nonzero(((a + b) < q.min_raw) | ((a + b) > q.max_raw))
                + np.count_nonzero(((a - b) < q.min_raw) | ((a - b) > q.max_raw)))
    assert (ctx.total_saturated if overflow == "saturate" else ctx.total_wrapped) == n_out > 0


@pytest.mark.parametrize("bits", [8, 16, 24, 32])
def test_saturate_and_wrap_edges_match_apytypes(bits: int) -> None:
    lim = 1 << (bits - 1)
    x = np.array([-3 * lim, -lim - 1, -lim, -lim + 1, -1, 0, 1, lim - 2, lim - 1, lim, lim + 1, 3 * lim + 5,
                  (1 << 45) + 7, -(1 << 45) - 7], np.int64)
    src = A(x, int_bits=48, frac_bits=0)
    q = QFormat(bits - 1, 0, word_bits=bits)
    np.testing.assert_array_equal(saturate(x, q), cast_apy(src, q, "floor", "saturate"))
    np.testing.assert_array_equal(wrap(x, q), cast_apy(src, q, "floor", "wrap"))
    np.testing.assert_array_equal(saturate(x, bits), saturate(x, q))


def test_unsigned_words_against_python_ints() -> None:
    rng = np.random.default_rng(RNG_SEED + 3)
    x = rng.integers(-(1 << 20), 1 << 20, 5000)
    assert wrap(x, 16, signed=False).tolist() == [v % 65536 for v in x.tolist()]
    assert saturate(x, 16, signed=False).tolist() == [min(max(v, 0), 65535) for v in x.tolist()]
    a = rng.integers(0, 65536, 5000)
    b = rng.integers(0, 65536, 5000)
    assert mul(a, b, signed=False).tolist() == [p * q for p, q in zip(a.tolist(), b.tolist())]


@pytest.mark.parametrize("s", [1, 2, 7, 15, 16, 30])
def test_shift_right_rounding(s: int) -> None:
    rng = np.random.default_rng(RNG_SEED + s)
    q = QFormat(31, 0, word_bits=32)
    x = random_raw(rng, q, 20_000)
    for rounding in ("half_up", "floor"):
        # half up of the largest words rounds to (max >> s) + 1: still inside the 32-bit word
        ref = cast_apy(A(x, int_bits=32 - s, frac_bits=s), q, rounding, "wrap")
        np.testing.assert_array_equal(shift_right(x, s, rounding=rounding), ref)
    # half up: ties towards +inf, against exact rational rounding
    ties = (np.arange(-50, 50) * 2 + 1) << (s - 1)
    assert shift_right(ties, s).tolist() == [math.floor(v / 2 ** s + 0.5) for v in ties.tolist()]


@pytest.mark.parametrize("q", [QFormat(0, 15), QFormat(15, 16, word_bits=32), QFormat(1, 30, word_bits=32)])
def test_from_float_matches_apytypes(q: QFormat) -> None:
    rng = np.random.default_rng(RNG_SEED + 4)
    # dyadic rationals with more fraction bits than q, some outside its range, ties included
    shift = q.frac_bits + 3
    span = 1 << (q.int_bits + shift + 1)                 # values up to twice the range
    x = rng.integers(-span, span, 20_000).astype(np.float64) / 2.0 ** shift
    x = np.concatenate([x, np.array([0.5, -0.5, 1.5, -1.5]) * q.lsb, [q.max_value + q.lsb, q.min_value - q.lsb]])
    wide = A.from_float(x, int_bits=q.int_bits + 8, frac_bits=q.frac_bits + 20)
    assert np.array_equal(wide.to_numpy(), x)          # the oracle's input is exact
    for rounding in ("half_up", "floor"):
        for overflow in ("saturate", "wrap"):
            np.testing.assert_array_equal(q.from_float(x, rounding=rounding, overflow=overflow),
                                          cast_apy(wide, q, rounding, overflow))


def test_div_matches_apytypes_truncation_towards_zero() -> None:
    rng = np.random.default_rng(RNG_SEED + 5)
    n = np.concatenate([rng.integers(-(1 << 31), 1 << 31, 20_000), [-(1 << 31), (1 << 31) - 1, 0, -1, 1, 7, -7]])
    d = np.concatenate([rng.integers(-(1 << 15), 1 << 15, 20_000), [-1, -1, 5, 2, -2, 2, 2]])
    d = np.where(d == 0, 3, d)
    q, r = div(n, d)
    quot = A(n, int_bits=32, frac_bits=0) / A(d, int_bits=16, frac_bits=0)
    ref = from_apy(quot.cast(int_bits=34, frac_bits=0, quantization=QM.TRN_ZERO, overflow=OM.WRAP))
    ref = np.clip(ref, -(1 << 31), (1 << 31) - 1)          # -2**31 / -1 saturates in a 32-bit quotient
    np.testing.assert_array_equal(q, ref)
    ok = ~((n == -(1 << 31)) & (d == -1))
    np.testing.assert_array_equal(n[ok], q[ok] * d[ok] + r[ok])
    assert np.all(np.abs(r) < np.abs(d)) and np.all((r == 0) | (np.sign(r) == np.sign(n)))
    # python reference of truncation toward zero
    assert q[:200].tolist() == [int(abs(a) // abs(b)) * (1 if (a < 0) == (b < 0) else -1)
                                for a, b in zip(n[:200].tolist(), d[:200].tolist())]


def test_div_saturation_and_divide_by_zero_are_counted() -> None:
    ctx = ArithmeticContext()
    q, r = div(np.array([100, -100, 0, 70000, -(1 << 31)]), np.array([0, 0, 0, 2, -1]), out=16, ctx=ctx)
    assert q.tolist() == [32767, -32768, 32767, 32767, 32767]
    assert r.tolist()[:3] == [100, -100, 0]
    assert ctx.div_by_zero == 3
    assert ctx.saturated["div"] == 5
    assert "division by zero: 3" in ctx.report()


@pytest.mark.parametrize("overflow", ["saturate", "wrap"])
def test_cumsum_against_apytypes_and_loop(overflow: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 6)
    q = QFormat(15, 16, word_bits=32)
    steps = rng.integers(-(1 << 27), (1 << 27) + (1 << 24), 30_000)   # drifts upward: overflows
    ctx = ArithmeticContext()
    ours = cumsum(steps, q, overflow=overflow, ctx=ctx)
    if overflow == "wrap":
        ref = cast_apy(A(steps, int_bits=32, frac_bits=16).cumsum(), q, "floor", "wrap")
        np.testing.assert_array_equal(ours, ref)
        assert ctx.total_wrapped > 0
    else:
        acc, ref, n_sat = 0, [], 0
        for v in steps.tolist():
            acc += v
            if acc > q.max_raw or acc < q.min_raw:
                acc, n_sat = min(max(acc, q.min_raw), q.max_raw), n_sat + 1
            ref.append(acc)
        assert ours.tolist() == ref
        assert ctx.saturated["cumsum"] == n_sat > 0


def test_isqrt_exhaustive_on_square_boundaries() -> None:
    k = np.arange(0, 65536, dtype=np.int64)
    x = np.concatenate([k * k, k * k - 1, k * k + 1, [(1 << 32) - 1, (1 << 32) - 2]])
    x = x[(x >= 0) & (x < (1 << 32))]
    np.testing.assert_array_equal(isqrt(x), [math.isqrt(v) for v in x.tolist()])


def test_isqrt_nearest_against_exact_rationals() -> None:
    rng = np.random.default_rng(RNG_SEED + 9)
    k = np.arange(0, 65536, dtype=np.int64)
    x = np.concatenate([k * k + k, k * k + k + 1, rng.integers(0, 1 << 32, 50_000)])   # (k+1/2)^2 = k^2+k+1/4
    x = x[x < (1 << 32)]
    r = isqrt(x, rounding="nearest")
    # nearest: |r - sqrt(x)| <= 1/2  <=>  (2r - 1)^2 <= 4x <= (2r + 1)^2 (no exact ties for integers)
    assert np.all((r == 0) | ((2 * r - 1) ** 2 <= 4 * x)) and np.all(4 * x <= (2 * r + 1) ** 2)
    assert isqrt(np.array([12]), rounding="nearest").tolist() == [round(math.sqrt(12))]


def test_isqrt_random_and_bad_input() -> None:
    rng = np.random.default_rng(RNG_SEED + 7)
    x = rng.integers(0, 1 << 32, 100_000)
    np.testing.assert_array_equal(isqrt(x), [math.isqrt(v) for v in x.tolist()])
    with pytest.raises(ValueError, match="unsigned 32-bit"):
        isqrt(np.array([-1]))
    with pytest.raises(ValueError, match="unsigned 32-bit"):
        isqrt(np.array([1 << 32]))
    with pytest.raises(TypeError, match="integer arrays"):
        isqrt(np.array([2.0]))


@settings(max_examples=500, deadline=None)
@given(st.integers(0, (1 << 32) - 1))
def test_isqrt_iroot4_property(v: int) -> None:
    assert int(isqrt(v)) == math.isqrt(v)
    r = int(iroot4(v))
    assert r ** 4 <= v < (r + 1) ** 4


def test_iroot4_boundaries() -> None:
    k = np.arange(0, 256, dtype=np.int64)
    x = np.concatenate([k ** 4, k ** 4 - 1, k ** 4 + 1])
    x = x[(x >= 0) & (x < (1 << 32))]
    r = iroot4(x)
    assert np.all(r ** 4 <= x) and np.all((r + 1) ** 4 > x)


def test_qformat_validation() -> None:
    with pytest.raises(ValueError, match="needs 17 bits"):
        QFormat(1, 15)
    with pytest.raises(ValueError, match="word_bits"):
        QFormat(1, 10, word_bits=12)
    assert str(QFormat(15, 16, word_bits=32)) == "Q15.16/32"
    assert QFormat(10, 0, signed=False).max_raw == 1023
    with pytest.raises(ValueError, match="non-finite"):
        QFormat(0, 15).from_float(np.array([np.nan]))


def test_mul_rejects_wide_operands() -> None:
    with pytest.raises(ValueError, match="16-bit"):
        mul(np.array([40000]), np.array([1]))


def test_context_cycles() -> None:
    ctx = ArithmeticContext()
    mul_q(np.arange(10), np.arange(10), 4, 16, ctx=ctx)
    div(np.arange(10), np.full(10, 3), ctx=ctx)
    assert ctx.cycles["mul16x16s"] == 10 * CYCLES["mul16x16s"]      # measured in gpsim (firmware_sim/pic)
    assert ctx.cycles["div32by16s"] == 10 * CYCLES["div32by16s"]
    assert ctx.cycles_per_sample(10) == ctx.total_cycles / 10
    with pytest.raises(KeyError):
        ctx.cost("fft")


def test_div_round_matches_apytypes_and_fractions() -> None:
    from fractions import Fraction

    rng = np.random.default_rng(RNG_SEED + 8)
    n = np.concatenate([rng.integers(-(1 << 31), 1 << 31, 20_000), np.arange(-20, 21)])
    d = np.concatenate([rng.integers(-(1 << 15), 1 << 15, 20_000), np.full(41, 4)])
    d = np.where(d == 0, 7, d)
    ctx = ArithmeticContext()
    ours = div_round(n, d, ctx=ctx)
    quot = A(n, int_bits=32, frac_bits=0) / A(d, int_bits=16, frac_bits=0)
    ref = from_apy(quot.cast(int_bits=34, frac_bits=0, quantization=QM.RND_INF, overflow=OM.WRAP))
    np.testing.assert_array_equal(ours, np.clip(ref, -(1 << 31), (1 << 31) - 1))
    for a, b, q in zip(n[-41:].tolist(), d[-41:].tolist(), ours[-41:].tolist()):
        f = Fraction(a, b)
        assert q == (int(abs(f) + Fraction(1, 2)) * (1 if f >= 0 else -1))
    assert ctx.total_saturated == 0


def to_apy_unsigned(raw: np.ndarray, q: QFormat) -> object:
    """Unsigned Q format -> apytypes array (a signed array one integer bit wider holds it exactly)."""
    return A(np.asarray(raw, np.int64), int_bits=q.int_bits + 1, frac_bits=q.frac_bits)


UNSIGNED_MUL_CASES = [  # the unsigned products of the on-line algorithm (random operands overflow two)
    (QFormat(2, 14, signed=False), QFormat(1, 15, signed=False), QFormat(2, 14, signed=False)),   # length x K
    (QFormat(1, 15, signed=False), QFormat(0, 16, signed=False), QFormat(1, 31, signed=False, word_bits=32)),
    (QFormat(0, 16, signed=False), QFormat(0, 16, signed=False), QFormat(2, 30, signed=False, word_bits=32)),
    (QFormat(3, 13, signed=False), QFormat(1, 15, signed=False), QFormat(0, 16, signed=False)),   # overflows
]


@pytest.mark.parametrize("qa,qb,qo", UNSIGNED_MUL_CASES, ids=lambda q: str(q))
@pytest.mark.parametrize("rounding", ["half_up", "floor"])
def test_unsigned_mul_q_matches_apytypes(qa: QFormat, qb: QFormat, qo: QFormat, rounding: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 11)
    a = np.concatenate([[0, 1, qa.max_raw - 1, qa.max_raw], rng.integers(0, qa.max_raw + 1, 20_000)])
    b = np.concatenate([[qb.max_raw, 0, 1, qb.max_raw], rng.integers(0, qb.max_raw + 1, 20_000)])
    shift = qa.frac_bits + qb.frac_bits - qo.frac_bits
    ctx = ArithmeticContext()
    ours = mul_q(a, b, shift, qo, rounding=rounding, signed=False, ctx=ctx)
    prod = to_apy_unsigned(a, qa) * to_apy_unsigned(b, qb)
    wide = prod.cast(int_bits=qa.int_bits + qb.int_bits + 3, frac_bits=qo.frac_bits, quantization=ROUND[rounding],
                     overflow=OM.WRAP)
    ref = from_apy(wide)
    n_over = int(np.count_nonzero(ref > qo.max_raw))
    np.testing.assert_array_equal(ours, np.minimum(ref, qo.max_raw))      # saturates at the top, never below 0
    assert ctx.calls["mul16x16u"] == a.size and ctx.total_saturated == n_over
    assert (n_over > 0) == (qa.max_value * qb.max_value > qo.max_value)


@pytest.mark.parametrize("rounded", [False, True])
def test_unsigned_div_matches_apytypes(rounded: bool) -> None:
    rng = np.random.default_rng(RNG_SEED + 12)
    n = np.concatenate([rng.integers(0, 1 << 32, 20_000), [(1 << 32) - 1, 0, 1, 7, 65535 * 65536]])
    d = np.concatenate([rng.integers(1, 1 << 16, 20_000), [1, 7, 2, 2, 65535]])
    ctx = ArithmeticContext()
    quot = A(n, int_bits=33, frac_bits=0) / A(d, int_bits=17, frac_bits=0)
    if rounded:
        ours = div_round(n, d, signed=False, ctx=ctx)
        mode = QM.RND_INF
    else:
        ours, rem = div(n, d, signed=False, ctx=ctx)
        mode = QM.TRN_ZERO
        np.testing.assert_array_equal(n, ours * d + rem)
        assert np.all((rem >= 0) & (rem < d))
    ref = from_apy(quot.cast(int_bits=34, frac_bits=0, quantization=mode, overflow=OM.WRAP))
    np.testing.assert_array_equal(ours, np.minimum(ref, (1 << 32) - 1))
    assert ctx.calls["div32by16u"] == n.size
    with pytest.raises(ValueError, match="unsigned 32-bit dividend"):
        div(np.array([-1]), np.array([3]), signed=False)


# ---------------------------------------------------------------------------------------------------------
# rounding modes (the sweep's per-class rounding): against exact rational arithmetic


def _exact_round(num: int, den: int, mode: str) -> int:
    """``num / den`` rounded by ``mode`` with Python's exact fractions (the independent truth)."""
    from fractions import Fraction
    import math as _m

    x = Fraction(num, den)
    if mode == "floor":
        return _m.floor(x)
    if mode == "half-up":
        return _m.floor(x + Fraction(1, 2))
    if mode == "convergent":
        return round(x)                           # Fraction.__round__: ties to even
    if mode == "toward-zero":
        return int(x)
    if mode == "half-away":
        return _m.floor(abs(x) + Fraction(1, 2)) * (1 if x >= 0 else -1)
    raise ValueError(mode)


def test_shift_right_rounding_modes_match_exact_fractions() -> None:
    from gaitlog.firmware_sim.fixedpoint import ROUND_CONVERGENT, ROUND_HALF_UP, ROUND_TRUNCATE, new_counters, s_shift_right

    cnt = new_counters()
    for x in range(-70, 71):
        for s in (1, 2, 3):
            assert s_shift_right(x, s, ROUND_TRUNCATE, cnt) == _exact_round(x, 1 << s, "floor")
            assert s_shift_right(x, s, ROUND_HALF_UP, cnt) == _exact_round(x, 1 << s, "half-up")
            assert s_shift_right(x, s, True, cnt) == _exact_round(x, 1 << s, "half-up")
            assert s_shift_right(x, s, ROUND_CONVERGENT, cnt) == _exact_round(x, 1 << s, "convergent"), (x, s)


def test_division_rounding_modes_match_exact_fractions() -> None:
    from gaitlog.firmware_sim.fixedpoint import ROUND_CONVERGENT, ROUND_HALF_UP, ROUND_TRUNCATE, new_counters, s_div_mode

    cnt = new_counters()
    for n in range(-60, 61):
        for d in (-8, -6, -4, -3, -2, 2, 3, 4, 6, 8):
            assert s_div_mode(n, d, 32, True, ROUND_TRUNCATE, cnt) == _exact_round(n, d, "toward-zero")
            assert s_div_mode(n, d, 32, True, ROUND_HALF_UP, cnt) == _exact_round(n, d, "half-away")
            assert s_div_mode(n, d, 32, True, ROUND_CONVERGENT, cnt) == _exact_round(n, d, "convergent"), (n, d)


def test_rounding_costs_truncate_least_convergent_most() -> None:
    """Truncation drops the rounding addition; convergent rounding adds a tie test (cycle model)."""
    from gaitlog.firmware_sim.fixedpoint import C_CYCLES, ROUNDING_MODES, new_counters, s_shift_right

    cycles = {}
    for name, mode in ROUNDING_MODES.items():
        cnt = new_counters()
        s_shift_right(12345, 4, mode, cnt)
        cycles[name] = cnt[C_CYCLES]
    assert cycles["truncate"] < cycles["half-up"] < cycles["convergent"]
