"""The on-line step algorithm's per-sample program: causal, bounded state, one text for both arithmetics.

This is what the logger runs for every sample it takes (the sampling interrupt stores the sample; the main
loop runs :func:`process`), written as the firmware computes it: the state is the declared slots of
:mod:`gaitlog.firmware_sim.algorithms.state`, every value has its Q format (:mod:`gaitlog.firmware_sim.algorithms.formats`),
and the arithmetic is the vocabulary of :mod:`gaitlog.firmware_sim.algorithms.arithmetic`. Run with ``int64`` state it
is the PIC's fixed point (bit-exact, counted); with ``float64`` state it is the same algorithm in floating
point. numba compiles it once per arithmetic (``cache=True``); with ``NUMBA_DISABLE_JIT=1`` the same text
runs in CPython (a test checks that both give the same records, bit for bit). Compiled without numba's runtime
(``nrt=False``: no reference counting of the arrays passed from function to function, which took 40 % of the
kernel's time), except :func:`_median_twice`, which allocates. Its ring indices wrap by a comparison (the delay
line, a FIR's taps, the integrals' walk along the scratch ring; a ring of any size) or a mask (``CI_FLUSH``, a
power of two): the indices of Python's ``%``, without an integer division per tap or per integrated sample
(which took half of the kernel's time).

Per sample ``n`` (codes ``c``), after Alvarez et al. (2006):

1. **Calibration** ``f = M (c - o)`` (PROTOCOL.md 2.1; mantissas and shared exponent in fixed point).
2. **Gravity** ``g``: two cascaded exponential means of ``f`` (``g += (x - g) 2^-k``, ``k`` =
   ``gravity_shift``; during the first ``2^k`` samples ``k`` grows from 0, so the estimate starts as the
   running mean). Causal; the offline chain's centred 4 s window needs 2 s of future samples.
3. **Vertical acceleration** ``a_v = (f·g - |g|^2) / |g|`` (tilt correction; 0 when ``|g|`` is below
   ``min_gravity_g``).
4. ``a_v`` enters a delay line of ``2 r3 + 1`` samples; the **centred Gaussian FIR** low-pass at 3 Hz
   (``y3``) is evaluated at the line's centre ``m = n - r3`` (the offline chain's zero-phase filter, ``r3``
   samples late). Every ``CI_FLUSH`` samples (a power of two, at most the line's length and half a page) the
   line's newest a_v go to the scratch ring, the step EEPROM's second block, as one page write: no RAM
   buffer, and each 128-byte page is written ``128 / (2 CI_FLUSH)`` times per lap of the 32,768-sample ring
   (``docs/topics/eeprom-endurance.md``). The 10 Hz (``d10``) and 5 Hz FIR, the impact band ``d10 - d5``
   and ``y3`` again are evaluated on the scratch ring where a step needs them (step 6).
5. **Foot-flat** (peaks of ``y3``): a hysteresis detector confirms a peak when ``y3`` has risen by the
   prominence since the last trough and fallen by it since the peak; the prominence is a fraction of the
   recent step amplitude ``AMP`` (an exponential mean of the confirmed peaks' rises from the trough before
   them) clamped to a floor and a cap, the cap before the first confirmed peak (:func:`_prominence`; on-line
   algorithm version 3: floor 0.25, cap 0.5 m/s^2, for slow, short steps; versions 1-2: floor = cap). A
   confirmed peak becomes the
   *pending* foot-flat; a later confirmed peak closer than the minimum distance replaces it if higher and
   is dropped otherwise. The pending foot-flat is final once no peak within the distance can still come:
   ``m >= pending + distance`` and the peak being climbed (if any) lies beyond the distance or is lower —
   a look-ahead bounded by ``max_step``. The distance is ``max(min_step, fraction · median)`` of the last
   ``median_steps`` intervals between peaks ``min_step`` apart (the offline chain's first pass), so a missed
   foot-flat does not lengthen the distance that caused it; until three intervals are known (a run's first
   steps) the median is the prior typical step ``prior_step`` (0.55 s,
   :class:`~gaitlog.firmware_sim.algorithms.parameters.OnlineParameters`), where the offline chain has the whole
   recording's. *Double support* (on-line algorithm version 2): only a peak with ``y3 > 0`` is a foot-flat
   (:func:`_confirmed`): at foot-flat the centre of mass is at its lowest, its vertical velocity turning
   from down to up, so its vertical acceleration is upward; a peak at or below zero (the causal gravity
   estimate makes ``a_v``'s walking mean zero) is a ripple of the single support, where the body vaults
   over the stance leg and accelerates downward (the inverted pendulum of Alvarez et al.; Zijlstra & Hof,
   Gait Posture 18, 2003). No constant: a sign test, identical in both arithmetics.
   *Stop rule* (``stop_prominence``, 0: off): a
   peak that fell by ``stop_prominence`` only (:func:`_weak_peak` while looking for a trough, or after a full
   rise) ``DIST`` to ``3 DIST`` after a final full foot-flat, with nothing pending, becomes the pending
   foot-flat marked weak (:func:`_stop_candidate`); it is final ``max_step`` after it, and dropped at a
   full-prominence rise or foot-flat before (the walker did not stop). One weak step per bout end.
6. **Steps** (:func:`_finalise`, at each final foot-flat ``e``, with the previous one ``s``): read back from
   the scratch ring (the filters evaluated on it, :func:`_fir_scratch`): the heel-strike (impact = first
   maximum of the band in ``[e - hs_before, e + hs_after]``,
   minus ``hs_delay``), the toe-off (first local minimum of ``d10`` in ``(s, s + to_span]``), M4's range of
   ``y3`` in ``[s, e]``, and two passes over ``a_v[s..e]``: M1's double integral reset at ``s`` and its
   extremes; then, with ``c1 = -mean(a)`` and ``c2`` known in closed form (``P2(T) = 16 P(T) + 2 c1 T^2``),
   M2's corrected position ``p2`` and its extremes, and M3's single-support extremes (Alvarez eqs 1-3).
   Lengths: M1, M2 ``K 2 sqrt(2 l h - h^2)`` (``h > 2 l``: ``IMPOSSIBLE``, length 0), M3
   ``2 sqrt(2 l h1 - h1^2) + foot``, M4 ``K (a_max - a_min)^p`` (p from the step configuration, default
   ``parameters.M4_EXPONENT``, 1/4: square roots rounded to nearest),
   M5 ``K1 / T + K2`` (eqs 1, 4; the seeds' corrections). One record per foot-flat: a step
   whose previous foot-flat is more than ``max_step`` back (or none) starts a walking bout and has no
   window (``NO_WINDOW``, lengths 0).
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.algorithms import arithmetic as ar
from gaitlog.firmware_sim.algorithms.formats import (
    F_ACC,
    F_ACC2,
    F_EXC,
    F_EXC2,
    F_FIR,
    F_GRAV,
    F_K,
    F_K4,
    F_KERNEL,
    F_LP,
    F_M5,
    F_PARG,
    F_PARG2,
    F_POS,
    F_POS2,
    F_ROOT,
    F_STEP,
    F_TWO_LEN,
    U16,
    W32,
    W_ACC,
    W_ACC2,
    W_CODE,
    W_EXC,
    W_EXC2,
    W_FIR,
    W_GRAV,
    W_LP,
    W_M5,
    W_PARG,
    W_PARG2,
    W_POS,
    W_POS2,
    W_ROOT,
    W_STEP,
    W_VEL,
)
from gaitlog.firmware_sim.algorithms.parameters import minimum_distance
from gaitlog.firmware_sim.algorithms.state import (
    AMP,
    DIST,
    DUR_POS,
    F_AMP,
    F_LAST,
    F_LAST_WEAK,
    F_LOOK_MAX,
    F_OLD,
    F_PEND,
    F_PEND_WEAK,
    F_RAW,
    FLAGS,
    G1,
    G2,
    INDEX_HALF,
    INDEX_MASK,
    LAST,
    LINE_POS,
    MN,
    MX,
    MXPOS,
    N_DUR,
    PEND,
    PEND_Y,
    RAW,
    RAW_Y,
    N,
    since,
)
from gaitlog.firmware_sim.compiled import njit, register_jitable
from gaitlog.firmware_sim.fixedpoint import (
    C_CYCLES,
    C_STICKY,
    OP_CMP16,
    OP_CMP32,
    OP_COPY,
    OP_DEE,
    OP_I2C,
    s_cost,
)
from gaitlog.firmware_sim.eeprom import BLOCK_BYTES, PAGE_BYTES
from gaitlog.protocol.header_slots import SLOT_ADDRESSES
from gaitlog.protocol.steps import StepFlag

__all__ = ["process", "flush", "reset", "CI", "CV", "OUT_I", "OUT_V", "SCRATCH_SAMPLE_BYTES",
           "SCRATCH_FIRST_BYTE", "SCRATCH_RING_BYTES", "SCRATCH_PAGES", "SCRATCH_RING_SAMPLES",
           "scratch_start_page", "scratch_ring_sample", "scratch_reads_ahead", "scratch_tail_write"]

# ---------------------------------------------------------------------------------------------------------
# configuration layout (filled by gaitlog.firmware_sim.algorithms.online.OnlineConfig)

#: Integer configuration slots (the same in both arithmetics).
CI = dict(R3=0, R10=1, R5=2, MIN_STEP=3, MAX_STEP=4, HS_BEFORE=5, HS_AFTER=6, HS_DELAY=7, TO_SPAN=8,
          G_SHIFT=9, N_MED=10, FRACTION=11, CODE_FRAC=12, MANT_FRAC=13, EXC_SHIFT1=14, EXC_SHIFT2=15,
          UNIT_FRAC=16, SCRATCH=17, W10=18, W5=19, BUDGET=20, AMP_SHIFT=21, PRIOR_TWICE=22, FLUSH=23, M4_EIGHTHS=24)
N_CI = len(CI)
(CI_R3, CI_R10, CI_R5, CI_MIN_STEP, CI_MAX_STEP, CI_HS_BEFORE, CI_HS_AFTER, CI_HS_DELAY, CI_TO_SPAN,
 CI_G_SHIFT, CI_N_MED, CI_FRACTION, CI_CODE_FRAC, CI_MANT_FRAC, CI_EXC_SHIFT1, CI_EXC_SHIFT2, CI_UNIT_FRAC,
 CI_SCRATCH, CI_W10, CI_W5, CI_BUDGET, CI_AMP_SHIFT, CI_PRIOR_TWICE, CI_FLUSH, CI_M4_EIGHTHS) = range(N_CI)

#: Value configuration slots (raw fixed point or float); the FIR half-kernels follow at ``W3``.
CV = dict(DELTA=0, G_MIN=1, TWO_LEG=2, FOOT=3, K1=4, K2=5, K4=6, K1FS=7, K2M5=8, UNIT=9, OFF=10, M=13, FRAC=22,
          STOP=23, CAP=24, W3=25)
(CV_DELTA, CV_G_MIN, CV_TWO_LEG, CV_FOOT, CV_K1, CV_K2, CV_K4, CV_K1FS, CV_K2M5, CV_UNIT) = range(10)
CV_FRAC = CV["FRAC"]
CV_STOP = CV["STOP"]
CV_CAP = CV["CAP"]
CV_OFF, CV_M, CV_W3 = CV["OFF"], CV["M"], CV["W3"]

#: Columns of the integer record output: the end index (16 bits, as the PIC keeps it; the driver restores the
#: absolute index), the window duration, the toe-off after the window start (-1: none), the heel strike from the
#: end (signed; meaningless with ``NO_HEEL_STRIKE``), the flags: the record's own fields; then, not stored,
#: ``scratch_tail``: the kernel's ``N`` (16 bits) when the PIC wrote the scratch ring's tail before this record
#: (:func:`_scratch_tail`, one partial page write), 0 when it did not (a tail write has ``N mod FLUSH > 0``).
OUT_I = ("end", "duration", "toe_off", "heel_strike", "flags", "scratch_tail")
#: Columns of the value record output: the five lengths, the excursions h (M1, M2) and h1 (M3), M4's range.
OUT_V = ("length_m1", "length_m2", "length_m3", "length_m4", "length_m5", "h_m1", "h_m2", "h1_m3", "range_m4")
O_END, O_DUR, O_TO, O_HS, O_FLAGS, O_TAIL = range(6)
O_L, O_H1, O_H2, O_H3, O_RANGE = 0, 5, 6, 7, 8
#: The scratch ring holds a_v, 2 bytes a sample, in the step EEPROM's second block up to its header slots
#: (:data:`SCRATCH_RING_BYTES`, 508 pages: 32,512 samples), written ``CI_FLUSH`` samples at a time (one
#: aligned page write straight from the delay line: the run's k-th flush fills bytes ``2 CI_FLUSH k`` on, modulo
#: the ring) and read back by the step's passes; the filters a step needs besides (y3 for M4's range, d10 for
#: the toe-off, the impact band for the heel strike) are evaluated again on it. The emulator keeps its values
#: in ``scr`` (the newest are the delay line's) and counts the I2C bytes; the driver counts the page writes.
SCRATCH_SAMPLE_BYTES = 2
SCRATCH_FIRST_BYTE = BLOCK_BYTES
SCRATCH_RING_BYTES = SLOT_ADDRESSES[0] - SCRATCH_FIRST_BYTE
SCRATCH_PAGES = SCRATCH_RING_BYTES // PAGE_BYTES
SCRATCH_RING_SAMPLES = SCRATCH_RING_BYTES // SCRATCH_SAMPLE_BYTES


def scratch_start_page(run_start_sample: int) -> int:
    """The scratch ring's page where a run starts: the page its first sample's number points to (2 bytes a
    sample, modulo the ring's pages), so that short runs do not all wear the ring's first pages."""
    return SCRATCH_SAMPLE_BYTES * int(run_start_sample) // PAGE_BYTES % SCRATCH_PAGES


def scratch_ring_sample(run_start_sample: int, f: int) -> int:
    """The ring sample (from the ring's first byte, 2 bytes each) that holds the run's sample ``f`` (counted from
    START): ``(S + f) mod`` :data:`SCRATCH_RING_SAMPLES`, ``S`` the first sample of the run's start page.

    >>> scratch_ring_sample(0, 32511), scratch_ring_sample(0, 32512), scratch_ring_sample(64 * 507, 64)
    (32511, 0, 0)
    """
    first = scratch_start_page(run_start_sample) * PAGE_BYTES // SCRATCH_SAMPLE_BYTES
    return (first + int(f)) % SCRATCH_RING_SAMPLES


@register_jitable
def scratch_reads_ahead(cfg_i: np.ndarray) -> tuple[int, int]:
    """How far past a step's final foot-flat ``e``, and past its previous foot-flat ``s`` (with one), the step
    record (:func:`_finalise`) reads a_v on the scratch ring: M4's range, the 3 Hz FIR up to ``e`` (radius
    ``R3``), and the heel strike's band up to ``e + HS_AFTER`` (radius ``max(R10, R5)``); the toe-off's d10 up
    to ``s + TO_SPAN + 1`` (radius ``R10``). None reads past ``N - 1`` (each stops at ``m = N - 1 - R3``).
    The PIC writes the a_v newer than the last flush first when these reach them (step_join.asm's fin_join).

    >>> from gaitlog.firmware_sim.algorithms.probe import online_config
    >>> scratch_reads_ahead(online_config(50.0).cfg_i)
    (9, 19)
    """
    r3, r10, r5 = int(cfg_i[CI_R3]), int(cfg_i[CI_R10]), int(cfg_i[CI_R5])
    return max(r3, int(cfg_i[CI_HS_AFTER]) + max(r10, r5)), int(cfg_i[CI_TO_SPAN]) + 1 + r10


@register_jitable
def scratch_tail_write(e: int, s: int, n: int, cfg_i: np.ndarray) -> bool:
    """Whether the PIC writes the scratch ring's tail (the newest ``N mod FLUSH`` a_v, one partial page write)
    before the step record at final foot-flat ``e`` (``s``: the previous foot-flat, -1 without one), ``N``
    (``n``) samples into the run (16-bit indices): when the step record's reads (:func:`scratch_reads_ahead`)
    reach the first sample not yet flushed, ``N - N mod FLUSH``.

    >>> from gaitlog.firmware_sim.algorithms.probe import online_config
    >>> ci = online_config(50.0).cfg_i
    >>> scratch_tail_write(871, 850, 890, ci), scratch_tail_write(870, -1, 890, ci), scratch_tail_write(871, 850, 896, ci)
    (True, False, False)
    """
    tail = int(n) % int(cfg_i[CI_FLUSH])
    first = (int(n) - tail) & INDEX_MASK
    ahead_e, ahead_s = scratch_reads_ahead(cfg_i)
    return bool(tail) and (since(int(e) + ahead_e, first) >= 0 or (s >= 0 and since(int(s) + ahead_s, first) >= 0))


#: Byte moves of each FIR product besides its arithmetic (the loop's bookkeeping, :func:`_fir`).
FIR_TAP_COPIES = 8
#: I2C bytes around a transfer: a write sends control + 2 address bytes; a read adds a second control byte, and
#: its close receives one byte more, not acknowledged, before the stop (step_record.asm ``scr_close``: gpsim's
#: bus receives 2 r + 1 samples' bytes and one for each read of the step record).
I2C_WRITE_OVERHEAD = 3
I2C_READ_OVERHEAD = 5

# the shared rule, compiled into the kernel (parameters.py itself stays free of numba)
register_jitable(minimum_distance)
register_jitable(since)

_NO_WINDOW = int(StepFlag.NO_WINDOW)
_NO_TOE_OFF = int(StepFlag.NO_TOE_OFF)
_NO_HEEL_STRIKE = int(StepFlag.NO_HEEL_STRIKE)
_M3_UNDEFINED = int(StepFlag.M3_UNDEFINED)
_IMPOSSIBLE = int(StepFlag.IMPOSSIBLE)
_SATURATED = int(StepFlag.SATURATED)


# ---------------------------------------------------------------------------------------------------------
# helpers


@njit(cache=True, nrt=False)
def _fir(line, centre, length, cfg_v, w0, r, cnt):  # pragma: no cover - compiled
    """Centred symmetric FIR at ``centre`` of a ring of a_v (the delay line, or the scratch ring):
    ``w0 a + sum w_k (a_-k + a_+k)``, Q2.16; its ``r + 1`` weights read from the data EEPROM. Each of its ``r + 1``
    products also moves bytes into the multiplier's operands, as the assembly does it (steps.asm ``sf_tap``,
    step_record.asm ``fir_tap``): the a_v (2), the weight (2), the operand (2) and the running sum (2 of its 4
    loaded or stored), and tests the loop's end or its index's wrap (a 16-bit compare). ``0 <= centre < length``
    and ``r < length`` (a filter no wider than its ring): a tap's index wraps by one comparison."""
    s_cost(cnt, OP_DEE, 2 * (r + 1))
    s_cost(cnt, OP_COPY, FIR_TAP_COPIES * (r + 1))
    s_cost(cnt, OP_CMP16, r + 1)
    acc = ar.mul(cfg_v[w0], F_KERNEL, line[centre], F_ACC, F_FIR, W_FIR, cnt)
    for tap in range(1, r + 1):
        pair = ar.add(line[centre - tap + length if tap > centre else centre - tap],
                      line[centre + tap - length if centre + tap >= length else centre + tap], W_ACC, cnt)
        acc = ar.add(acc, ar.mul(cfg_v[w0 + tap], F_KERNEL, pair, F_ACC, F_FIR, W_FIR, cnt), W_FIR, cnt)
    return ar.requant(acc, F_FIR, F_LP, W_LP, cnt)


@njit(cache=True, nrt=False)
def _excursion(span, f_pos, shift, f_h, w_h, cfg_i, cfg_v, cnt):  # pragma: no cover - compiled
    """A position range (``f_pos`` fraction bits, unit 4 g T_s^2) in metres with ``f_h`` fraction bits in the
    word ``w_h`` (unsigned 16-bit as shipped)."""
    s16 = ar.requant(span, f_pos, f_pos - shift, U16, cnt)
    return ar.mul(s16, f_pos - shift, cfg_v[CV_UNIT], cfg_i[CI_UNIT_FRAC], f_h, w_h, cnt)


@njit(cache=True, nrt=False)
def _pendulum(h, f_h, f_arg, w_arg, cfg_v, cnt):  # pragma: no cover - compiled
    """``2 sqrt(2 l h - h^2)`` (UQ2.14 m) of an excursion with ``f_h`` fraction bits, and whether the step is
    impossible (``h > 2 l``; Alvarez eq 1). ``2 l`` is UQ2.14, so ``2 l h`` has ``14 + f_h`` fraction bits in 32
    bits (as shipped: ``f_arg`` of them in the unsigned word ``w_arg``) and its square root ``f_arg / 2``; the
    difference is kept one bit wider, signed (its borrow)."""
    lh2 = ar.mul(cfg_v[CV_TWO_LEG], F_TWO_LEN, h, f_h, f_arg, w_arg, cnt)
    hh = ar.mul(h, f_h, h, f_h, f_arg, w_arg, cnt)
    x = ar.sub(lh2, hh, abs(w_arg) + 1, cnt)
    if x < 0:
        return x * 0, True
    half = ar.sqrt(x, f_arg, f_arg // 2, False, cnt)
    return ar.requant(ar.scale2(half, 1, W32, cnt), f_arg // 2, F_STEP, W_STEP, cnt), False


@njit(cache=True, nrt=True)
def _median_twice(durs, n):  # pragma: no cover - compiled
    """Twice the median of the first ``n`` durations (an integer: the mean of the middle two when even).

    The sorted copy is an allocation: the one kernel function compiled with numba's runtime (module notes)."""
    d = np.sort(durs[:n].copy())
    if n % 2:
        return 2 * d[n // 2]
    return d[n // 2 - 1] + d[n // 2]


@njit(cache=True, nrt=False)
def _read_cost(cnt, records, record_bytes):  # pragma: no cover - compiled
    """One sequential I2C read of ``records`` scratch records of ``record_bytes``."""
    s_cost(cnt, OP_I2C, record_bytes * records + I2C_READ_OVERHEAD)


@njit(cache=True, nrt=False)
def _fir_scratch(scr, j, cfg_i, cfg_v, w0, r, cnt):  # pragma: no cover - compiled
    """The FIR of weights ``w0`` (radius ``r``) at sample ``j``, on a_v read back from the scratch ring (one
    sequential read of its ``2 r + 1`` samples; the newest are still in the delay line: counted as read too)."""
    _read_cost(cnt, 2 * r + 1, SCRATCH_SAMPLE_BYTES)
    return _fir(scr, j % cfg_i[CI_SCRATCH], cfg_i[CI_SCRATCH], cfg_v, w0, r, cnt)


@njit(cache=True, nrt=False)
def _band(scr, j, cfg_i, cfg_v, cnt):  # pragma: no cover - compiled
    """The impact band ``d10 - d5`` at sample ``j`` (Q2.16): both filters on one read of the ring, the window
    of the larger radius (as the step record reads it, step_record.asm)."""
    _read_cost(cnt, 2 * max(cfg_i[CI_R10], cfg_i[CI_R5]) + 1, SCRATCH_SAMPLE_BYTES)
    d10 = _fir(scr, j % cfg_i[CI_SCRATCH], cfg_i[CI_SCRATCH], cfg_v, cfg_i[CI_W10], cfg_i[CI_R10], cnt)
    return ar.sub(d10, _fir(scr, j % cfg_i[CI_SCRATCH], cfg_i[CI_SCRATCH], cfg_v, cfg_i[CI_W5], cfg_i[CI_R5],
                            cnt),
                  W_LP, cnt)


# ---------------------------------------------------------------------------------------------------------
# one step (at a final foot-flat): each part reads the scratch ring and keeps only its own accumulators


@njit(cache=True, nrt=False)
def _heel_strike(e, m, cfg_i, cfg_v, st_i, scr, cnt):  # pragma: no cover - compiled
    """Heel-strike before the foot-flat ``e``: the first maximum of the impact band in
    ``[e - hs_before, e + hs_after]`` (filter outputs up to ``m``; none before the run's first, ``r3``), minus
    ``hs_delay``; -1 if none. Indices are 16-bit (the loop runs on ``e``'s offsets, the ring wraps with them)."""
    young = not (st_i[FLAGS] & F_OLD)
    lo = e - cfg_i[CI_HS_BEFORE]
    if young and lo < cfg_i[CI_R3]:
        lo = cfg_i[CI_R3]
    hi = e + min(cfg_i[CI_HS_AFTER], since(m, e))
    best = -1
    peak = cfg_v[CV_DELTA] * 0
    for j in range(lo, hi + 1):
        band = _band(scr, j, cfg_i, cfg_v, cnt)
        s_cost(cnt, OP_CMP32, 1)
        if best < 0 or band > peak:
            peak = band
            best = j & INDEX_MASK
    if best < 0 or (young and best < cfg_i[CI_HS_DELAY]):
        return -1
    return (best - cfg_i[CI_HS_DELAY]) & INDEX_MASK


@njit(cache=True, nrt=False)
def _toe_off(s, m, cfg_i, cfg_v, scr, cnt):  # pragma: no cover - compiled
    """Toe-off after the foot-flat ``s``: the first local minimum of ``d10`` in ``(s, s + to_span]``; -1."""
    prev = _fir_scratch(scr, s, cfg_i, cfg_v, cfg_i[CI_W10], cfg_i[CI_R10], cnt)
    cur = _fir_scratch(scr, s + 1, cfg_i, cfg_v, cfg_i[CI_W10], cfg_i[CI_R10], cnt)
    for j in range(s + 1, s + min(cfg_i[CI_TO_SPAN], since(m, s) - 1) + 1):
        nxt = _fir_scratch(scr, j + 1, cfg_i, cfg_v, cfg_i[CI_W10], cfg_i[CI_R10], cnt)
        s_cost(cnt, OP_CMP32, 2)
        if cur < prev and cur <= nxt:
            return j & INDEX_MASK
        prev = cur
        cur = nxt
    return -1


@njit(cache=True, nrt=False)
def _range(s, e, cfg_i, cfg_v, scr, cnt):  # pragma: no cover - compiled
    """M4's ``a_max - a_min`` of the 3 Hz signal in ``[s, e]`` (Q2.16 g)."""
    y_max = _fir_scratch(scr, s, cfg_i, cfg_v, CV_W3, cfg_i[CI_R3], cnt)
    y_min = y_max
    for j in range(s + 1, s + since(e, s) + 1):
        y = _fir_scratch(scr, j, cfg_i, cfg_v, CV_W3, cfg_i[CI_R3], cnt)
        s_cost(cnt, OP_CMP32, 2)
        if y > y_max:
            y_max = y
        if y < y_min:
            y_min = y
    return ar.sub(y_max, y_min, W_LP, cnt)


@njit(cache=True, nrt=False)
def _pass1(s, e, cfg_i, scr, cnt):  # pragma: no cover - compiled
    """M1 (eq 1): the double integral reset at ``s``, ``V = sum(a_k + a_k-1)``, ``P = sum(V_k + V_k-1)``.

    Returns the position range, and M2's constants (eqs 2-3): ``c1 = -mean(a) = -V(T) / (2T)`` (Q.17) and
    ``c2 = P2(T) / T`` per sample with ``P2(T) = 16 P(T) + 2 c1 T^2`` exactly (the corrected integral of
    ``a + c1`` in closed form).
    """
    size = cfg_i[CI_SCRATCH]
    _read_cost(cnt, since(e, s) + 1, SCRATCH_SAMPLE_BYTES)
    vel = scr[0] * 0
    pos = vel
    p_max = vel
    p_min = vel
    prev = s % size                              # the ring's index of sample j - 1, wrapped by a comparison
    for j in range(s + 1, s + since(e, s) + 1):
        cur = prev + 1 if prev + 1 < size else 0
        v_new = ar.add(vel, ar.add(scr[cur], scr[prev], W_VEL, cnt), W_VEL, cnt)
        prev = cur
        pos = ar.add(pos, ar.add(v_new, vel, W_POS, cnt), W_POS, cnt)
        vel = v_new
        s_cost(cnt, OP_CMP32, 2)
        if pos > p_max:
            p_max = pos
        if pos < p_min:
            p_min = pos
    c1 = ar.div(ar.neg(vel, W_VEL, cnt), F_ACC, 2 * since(e, s), 0, F_POS2, W_POS2, cnt)
    c2 = ar.div(ar.add(ar.requant(pos, F_POS, F_POS2, W_POS2, cnt),
                       ar.scale2(ar.mul_count(c1, since(e, s) * since(e, s), W_POS2, cnt), 1, W_POS2, cnt), W_POS2,
                       cnt),
                F_POS2, since(e, s), 0, F_POS2, W_POS2, cnt)
    return ar.sub(p_max, p_min, W_POS, cnt), c1, c2


@njit(cache=True, nrt=False)
def _pass2(s, e, to, hs3, c1, c2, cfg_i, scr, cnt):  # pragma: no cover - compiled
    """M2's corrected position ``p2(tau) = P2(tau) - c2 tau`` by increments ``16 dP + 2 c1 (2 tau - 1) - c2``
    (additions only); returns its range over the step and over the single support ``[to, hs3]`` (M3;
    ``to < 0``: none)."""
    size = cfg_i[CI_SCRATCH]
    _read_cost(cnt, since(e, s) + 1, SCRATCH_SAMPLE_BYTES)
    vel = c1 * 0
    q = vel
    q_max = vel
    q_min = vel
    s_max = vel
    s_min = vel
    ramp = ar.scale2(c1, 1, W_POS2, cnt)
    ramp_step = ar.scale2(c1, 2, W_POS2, cnt)
    seen = False
    prev = s % size                              # the ring's index of sample j - 1, wrapped by a comparison
    for j in range(s + 1, s + since(e, s) + 1):
        cur = prev + 1 if prev + 1 < size else 0
        v_new = ar.add(vel, ar.add(scr[cur], scr[prev], W_VEL, cnt), W_VEL, cnt)
        prev = cur
        dp = ar.requant(ar.add(v_new, vel, W_POS, cnt), F_POS, F_POS2, W_POS2, cnt)
        vel = v_new
        q = ar.add(q, ar.add(ar.sub(dp, c2, W_POS2, cnt), ramp, W_POS2, cnt), W_POS2, cnt)
        ramp = ar.add(ramp, ramp_step, W_POS2, cnt)
        s_cost(cnt, OP_CMP32, 2)
        if q > q_max:
            q_max = q
        if q < q_min:
            q_min = q
        if to >= 0 and since(j, to) >= 0 and since(j, hs3) <= 0:
            s_cost(cnt, OP_CMP32, 2)
            if not seen or q > s_max:
                s_max = q
            if not seen or q < s_min:
                s_min = q
            seen = True
    return ar.sub(q_max, q_min, W_POS2, cnt), ar.sub(s_max, s_min, W_POS2, cnt)


@njit(cache=True, nrt=False)
def _scratch_tail(n, cfg_i, out_i, k, cnt):  # pragma: no cover - compiled
    """The PIC writes the scratch ring's tail before record ``k``: the delay line's newest ``N mod FLUSH`` a_v
    (``n`` = ``N``), one partial page write at the block the next flush rewrites (step_join.asm's
    ``scr_write_w``), where :func:`scratch_tail_write` holds and at STOP. Its bus bytes are counted, its ``N``
    goes to ``out_i[k, O_TAIL]`` (the driver counts the page's write cycle from it)."""
    s_cost(cnt, OP_I2C, SCRATCH_SAMPLE_BYTES * (n % cfg_i[CI_FLUSH]) + I2C_WRITE_OVERHEAD)
    out_i[k, O_TAIL] = n


@njit(cache=True, nrt=False)
def _finalise(e, m, cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt):  # pragma: no cover - compiled
    """The step ending at the final foot-flat ``e`` (newest filter output ``m``): record ``k``.

    The excursions and M4's range also go to the emulator's output (``out_v``, for analysis); the
    firmware consumes them as it computes them and stores the lengths only.
    """
    zero = cfg_v[CV_DELTA] * 0
    flags = 0
    s = st_i[LAST] if st_i[FLAGS] & F_LAST else -1
    if out_i[k, O_TAIL] == 0 and scratch_tail_write(e, s, st_i[N], cfg_i):
        _scratch_tail(st_i[N], cfg_i, out_i, k, cnt)
    hs = _heel_strike(e, m, cfg_i, cfg_v, st_i, scr, cnt)
    if hs < 0:
        flags |= _NO_HEEL_STRIKE
    to = -1
    l1 = zero
    l2 = zero
    l3 = zero
    l4 = zero
    l5 = zero
    for c in range(4):
        out_v[k, O_H1 + c] = zero
    if s < 0 or since(e, s) > cfg_i[CI_MAX_STEP]:
        flags |= _NO_WINDOW
        s = -1
    else:
        # events of the window (the offline chain's rules: toe-off between the start and the heel-strike)
        to = _toe_off(s, m, cfg_i, cfg_v, scr, cnt)
        if not (to >= 0 and (hs < 0 or since(to, hs) < 0)):
            to = -1
            flags |= _NO_TOE_OFF
        hs3 = hs if hs >= 0 and since(hs, s) > 0 else -1
        if not (to >= 0 and hs3 >= 0 and since(hs3, e) <= 0 and since(hs3, to) > 0):
            flags |= _M3_UNDEFINED
            hs3 = -1
        s_cost(cnt, OP_DEE, 24)                  # K, leg, foot and the M5 constants from the data EEPROM
        # M1 (eq 1)
        span, c1, c2 = _pass1(s, e, cfg_i, scr, cnt)
        out_v[k, O_H1] = _excursion(span, F_POS, cfg_i[CI_EXC_SHIFT1], F_EXC, W_EXC, cfg_i, cfg_v, cnt)
        length, bad = _pendulum(out_v[k, O_H1], F_EXC, F_PARG, W_PARG, cfg_v, cnt)
        if bad:
            flags |= _IMPOSSIBLE
        else:
            l1 = ar.mul(length, F_STEP, cfg_v[CV_K1], F_K, F_STEP, W_STEP, cnt)
        # M2 (eqs 2-3) and M3 (single support + foot length)
        span, span3 = _pass2(s, e, to if hs3 >= 0 else -1, hs3, c1, c2, cfg_i, scr, cnt)
        out_v[k, O_H2] = _excursion(span, F_POS2, cfg_i[CI_EXC_SHIFT2], F_EXC2, W_EXC2, cfg_i, cfg_v, cnt)
        length, bad = _pendulum(out_v[k, O_H2], F_EXC2, F_PARG2, W_PARG2, cfg_v, cnt)
        if bad:
            flags |= _IMPOSSIBLE
        else:
            l2 = ar.mul(length, F_STEP, cfg_v[CV_K2], F_K, F_STEP, W_STEP, cnt)
        if hs3 >= 0:
            out_v[k, O_H3] = _excursion(span3, F_POS2, cfg_i[CI_EXC_SHIFT2], F_EXC2, W_EXC2, cfg_i, cfg_v,
                                         cnt)
            length, bad = _pendulum(out_v[k, O_H3], F_EXC2, F_PARG2, W_PARG2, cfg_v, cnt)
            if bad:
                flags |= _IMPOSSIBLE
            else:
                l3 = ar.add(length, cfg_v[CV_FOOT], W_STEP, cnt)
        # M4 (eq 4): K (a_max - a_min)^p, p = the configuration's eighths / 8 (on-line algorithm version 4; the
        # step configuration's m4_exponent_eighths), the range in g and K g0^p the constant: the range's square
        # root, fourth and eighth roots (rounded to nearest, 15 fraction bits each; the first from the Q2.16
        # range), the constant (UQ2.14) multiplied by those the exponent's bits select
        out_v[k, O_RANGE] = _range(s, e, cfg_i, cfg_v, scr, cnt)
        # (a root is stored in ROOT4_Q's word: a no-op at the shipped 16 bits, which every root fits)
        length = ar.requant(ar.sqrt(out_v[k, O_RANGE], F_LP, F_ROOT, True, cnt), F_ROOT, F_ROOT, W_ROOT, cnt)
        if cfg_i[CI_M4_EIGHTHS] & 4:
            l4 = ar.mul(cfg_v[CV_K4], F_K4, length, F_ROOT, F_STEP, W_STEP, cnt)
        else:
            l4 = ar.requant(cfg_v[CV_K4], F_K4, F_STEP, W_STEP, cnt)
        if cfg_i[CI_M4_EIGHTHS] & 3:                                          # only the roots needed
            length = ar.requant(ar.sqrt(length, F_ROOT, F_ROOT, True, cnt), F_ROOT, F_ROOT, W_ROOT, cnt)  # ^(1/4)
            if cfg_i[CI_M4_EIGHTHS] & 2:
                l4 = ar.mul(l4, F_STEP, length, F_ROOT, F_STEP, W_STEP, cnt)
            if cfg_i[CI_M4_EIGHTHS] & 1:
                length = ar.requant(ar.sqrt(length, F_ROOT, F_ROOT, True, cnt), F_ROOT, F_ROOT, W_ROOT, cnt)  # ^(1/8)
                l4 = ar.mul(l4, F_STEP, length, F_ROOT, F_STEP, W_STEP, cnt)
        # M5: K1 / T + K2 with K1 fs in m samples
        l5 = ar.requant(ar.add(ar.div(cfg_v[CV_K1FS], F_M5, since(e, s), 0, F_M5, W_M5, cnt), cfg_v[CV_K2M5], W_M5,
                               cnt),
                        F_M5, F_STEP, W_STEP, cnt)
    if cnt[C_STICKY]:
        flags |= _SATURATED
        cnt[C_STICKY] = 0
    out_i[k, O_END] = e
    out_i[k, O_DUR] = since(e, s) if s >= 0 else 0
    out_i[k, O_TO] = since(to, s) if to >= 0 else -1
    out_i[k, O_HS] = since(hs, e) if hs >= 0 else 0
    out_i[k, O_FLAGS] = flags
    out_v[k, O_L + 0] = l1
    out_v[k, O_L + 1] = l2
    out_v[k, O_L + 2] = l3
    out_v[k, O_L + 3] = l4
    out_v[k, O_L + 4] = l5
    st_i[LAST] = e
    st_i[FLAGS] |= F_LAST
    if st_i[FLAGS] & F_PEND_WEAK:                 # a bout's weak last step (the stop rule): none may follow it
        st_i[FLAGS] |= F_LAST_WEAK
    else:
        st_i[FLAGS] &= ~F_LAST_WEAK
    st_i[FLAGS] &= ~F_PEND_WEAK
    return k + 1


@njit(cache=True, nrt=False)
def _confirmed(p, yp, m, cfg_i, cfg_v, st_i, st_v, durs, scr, out_i, out_v, k, cnt):  # pragma: no cover
    """A peak of ``y3`` at ``p`` confirmed by the hysteresis: the duration stream, then the foot-flat.

    Only a peak above zero is a foot-flat (module notes, step 5): one at or below zero is a ripple of the
    single support and enters neither the duration stream nor the foot-flat candidates.
    """
    s_cost(cnt, OP_CMP32, 1)
    if yp <= yp * 0:
        return k                                   # the CoM not accelerated upwards: no double support
    # the step-duration stream: peaks min_step apart (the offline chain's first pass)
    if (st_i[FLAGS] & F_RAW) and since(p, st_i[RAW]) < cfg_i[CI_MIN_STEP]:
        if yp > st_v[RAW_Y]:
            st_i[RAW] = p
            st_v[RAW_Y] = yp
    else:
        if (st_i[FLAGS] & F_RAW) and since(p, st_i[RAW]) <= cfg_i[CI_MAX_STEP]:
            durs[st_i[DUR_POS]] = since(p, st_i[RAW])
            st_i[DUR_POS] = (st_i[DUR_POS] + 1) % cfg_i[CI_N_MED]
            if st_i[N_DUR] < cfg_i[CI_N_MED]:
                st_i[N_DUR] += 1
            if st_i[N_DUR] >= 3:
                st_i[DIST] = minimum_distance(_median_twice(durs, st_i[N_DUR]), cfg_i[CI_MIN_STEP],
                                              cfg_i[CI_FRACTION])
                s_cost(cnt, OP_CMP16, st_i[N_DUR] * st_i[N_DUR])      # insertion sort of the ring
        st_i[RAW] = p
        st_v[RAW_Y] = yp
        st_i[FLAGS] |= F_RAW
    # foot-flat candidates
    if (st_i[FLAGS] & F_LAST) and since(p, st_i[LAST]) < st_i[DIST]:
        return k                                   # lower than a final foot-flat within the distance
    if not (st_i[FLAGS] & F_PEND):
        st_i[PEND] = p
        st_v[PEND_Y] = yp
        st_i[FLAGS] |= F_PEND
    elif since(p, st_i[PEND]) < st_i[DIST]:
        if yp > st_v[PEND_Y]:
            st_i[PEND] = p
            st_v[PEND_Y] = yp
    else:
        k = _finalise(st_i[PEND], m, cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt)
        st_i[PEND] = p
        st_v[PEND_Y] = yp
    return k


@njit(cache=True, nrt=False)
def _calibrated(cfg_v, row, c0, c1, c2, mf, cf, cnt):  # pragma: no cover - compiled
    """Row ``row`` of ``M (c - o)``: three products summed in 32 bits, rounded to Q2.13 g."""
    acc = ar.mul(cfg_v[CV_M + 3 * row], mf, c0, cf, mf + cf, W32, cnt)
    acc = ar.add(acc, ar.mul(cfg_v[CV_M + 3 * row + 1], mf, c1, cf, mf + cf, W32, cnt), W32, cnt)
    acc = ar.add(acc, ar.mul(cfg_v[CV_M + 3 * row + 2], mf, c2, cf, mf + cf, W32, cnt), W32, cnt)
    return ar.requant(acc, mf + cf, F_ACC, W_ACC, cnt)


@njit(cache=True, nrt=False)
def _front(cx, cy, cz, cfg_i, cfg_v, st_i, st_v, line, scr, cnt):  # pragma: no cover - compiled
    """Steps 1-4 for one sample: calibration, gravity, a_v into the delay line (and every ``CI_FLUSH`` samples
    from there to the scratch ring, one page write), the 3 Hz FIR output at the line's centre.

    Returns whether the filters have an output (the run is at least ``2 r3 + 1`` samples old) and the output.
    """
    r3 = cfg_i[CI_R3]
    n = st_i[N]
    if n & INDEX_HALF:                           # bit 15 of N: the run is old, N may wrap from now on
        st_i[FLAGS] |= F_OLD
    young = not (st_i[FLAGS] & F_OLD)
    # 1. calibration: f = M (codes - offset)
    c0 = ar.sub(ar.requant(cx, 0, cfg_i[CI_CODE_FRAC], W_CODE, cnt), cfg_v[CV_OFF + 0], W_CODE, cnt)
    c1 = ar.sub(ar.requant(cy, 0, cfg_i[CI_CODE_FRAC], W_CODE, cnt), cfg_v[CV_OFF + 1], W_CODE, cnt)
    c2 = ar.sub(ar.requant(cz, 0, cfg_i[CI_CODE_FRAC], W_CODE, cnt), cfg_v[CV_OFF + 2], W_CODE, cnt)
    fx = _calibrated(cfg_v, 0, c0, c1, c2, cfg_i[CI_MANT_FRAC], cfg_i[CI_CODE_FRAC], cnt)
    fy = _calibrated(cfg_v, 1, c0, c1, c2, cfg_i[CI_MANT_FRAC], cfg_i[CI_CODE_FRAC], cnt)
    fz = _calibrated(cfg_v, 2, c0, c1, c2, cfg_i[CI_MANT_FRAC], cfg_i[CI_CODE_FRAC], cnt)
    s_cost(cnt, OP_DEE, 25)                      # offsets, mantissas, exponent from the data EEPROM
    # 2. gravity: two exponential stages; the shift grows from 0 while the run is young (running mean)
    warm = 0
    while warm < cfg_i[CI_G_SHIFT] and (not young or (2 << warm) <= n + 1):
        warm += 1
    for axis in range(3):
        st_v[G1 + axis] = ar.add(st_v[G1 + axis], ar.scale2(ar.sub(ar.requant(
            fx if axis == 0 else (fy if axis == 1 else fz), F_ACC, F_GRAV, W_GRAV, cnt), st_v[G1 + axis], W_GRAV,
            cnt), -warm, W_GRAV, cnt), W_GRAV, cnt)
        st_v[G2 + axis] = ar.add(st_v[G2 + axis], ar.scale2(ar.sub(st_v[G1 + axis], st_v[G2 + axis], W_GRAV, cnt),
                                                            -warm, W_GRAV, cnt), W_GRAV, cnt)
    # 3. vertical acceleration a_v = (f.g - |g|^2) / |g|: the numerator exact, |g| rounded to nearest
    gx = ar.requant(st_v[G2 + 0], F_GRAV, F_ACC, W_ACC, cnt)
    gy = ar.requant(st_v[G2 + 1], F_GRAV, F_ACC, W_ACC, cnt)
    gz = ar.requant(st_v[G2 + 2], F_GRAV, F_ACC, W_ACC, cnt)
    norm2 = ar.add(ar.add(ar.mul(gx, F_ACC, gx, F_ACC, F_ACC2, W_ACC2, cnt),
                          ar.mul(gy, F_ACC, gy, F_ACC, F_ACC2, W_ACC2, cnt), W_ACC2, cnt),
                   ar.mul(gz, F_ACC, gz, F_ACC, F_ACC2, W_ACC2, cnt), W_ACC2, cnt)
    gn = ar.sqrt(norm2, F_ACC2, F_ACC, True, cnt)
    s_cost(cnt, OP_CMP16, 1)
    av = fx * 0
    if gn > cfg_v[CV_G_MIN]:
        av = ar.div(ar.sub(ar.add(ar.add(ar.mul(fx, F_ACC, gx, F_ACC, F_ACC2, W_ACC2, cnt),
                                         ar.mul(fy, F_ACC, gy, F_ACC, F_ACC2, W_ACC2, cnt), W_ACC2, cnt),
                                  ar.mul(fz, F_ACC, gz, F_ACC, F_ACC2, W_ACC2, cnt), W_ACC2, cnt), norm2, W_ACC2,
                           cnt), F_ACC2, gn, F_ACC, F_ACC, W_ACC, cnt)
    # 4. delay line; every CI_FLUSH samples its newest CI_FLUSH a_v go to the scratch ring as one page write
    line[st_i[LINE_POS]] = av
    st_i[LINE_POS] = st_i[LINE_POS] + 1 if st_i[LINE_POS] < 2 * r3 else 0
    scr[n % cfg_i[CI_SCRATCH]] = av
    if (n + 1) & (cfg_i[CI_FLUSH] - 1) == 0:
        s_cost(cnt, OP_I2C, SCRATCH_SAMPLE_BYTES * cfg_i[CI_FLUSH] + I2C_WRITE_OVERHEAD)
    st_i[N] = (n + 1) & INDEX_MASK
    if young and n < 2 * r3:
        return False, av * 0
    # the 3 Hz output at the line's centre m = n - r3 (the peak detector's input)
    centre = st_i[LINE_POS] - 1 - r3
    if centre < 0:
        centre += 2 * r3 + 1
    s_cost(cnt, OP_DEE, 3)                       # the prominence
    return True, _fir(line, centre, 2 * r3 + 1, cfg_v, CV_W3, r3, cnt)


@njit(cache=True, nrt=False)
def _prominence(cfg_i, cfg_v, st_i, st_v, cnt):  # pragma: no cover - compiled
    """The prominence in force: ``fraction · AMP`` (the recent step amplitude) clamped to the floor and the
    cap, the cap while no amplitude is known
    (:func:`~gaitlog.firmware_sim.algorithms.parameters.prominence_threshold`)."""
    s_cost(cnt, OP_DEE, 3)                       # the cap
    if not (st_i[FLAGS] & F_AMP):
        return cfg_v[CV_CAP]
    s_cost(cnt, OP_DEE, 2)                       # the floor
    s_cost(cnt, OP_CMP32, 1)
    if cfg_v[CV_CAP] <= cfg_v[CV_DELTA]:         # floor = cap (versions 1-2): a fixed threshold, no multiply
        return cfg_v[CV_DELTA]
    s_cost(cnt, OP_DEE, 2)                       # the fraction
    scaled = ar.mul(cfg_v[CV_FRAC], F_KERNEL, ar.requant(st_v[AMP], F_LP, F_ACC, W_ACC, cnt), F_ACC, F_LP, W_LP, cnt)
    s_cost(cnt, OP_CMP32, 2)
    if scaled > cfg_v[CV_CAP]:
        return cfg_v[CV_CAP]
    if scaled > cfg_v[CV_DELTA]:
        return scaled
    return cfg_v[CV_DELTA]


@njit(cache=True, nrt=False)
def _sample(cx, cy, cz, cfg_i, cfg_v, st_i, st_v, line, durs, scr, out_i, out_v, k, cnt):  # pragma: no cover
    """Everything the firmware does for one sample; returns the number of records written so far."""
    ready, y = _front(cx, cy, cz, cfg_i, cfg_v, st_i, st_v, line, scr, cnt)
    if not ready:
        return k
    # 5. foot-flat at the filter output m = n - r3: the pending foot-flat becomes final, then the hysteresis
    m = (st_i[N] - 1 - cfg_i[CI_R3]) & INDEX_MASK
    s_cost(cnt, OP_CMP32, 4)
    if (st_i[FLAGS] & F_PEND) and since(m, st_i[PEND]) >= (cfg_i[CI_MAX_STEP] if st_i[FLAGS] & F_PEND_WEAK
                                                           else st_i[DIST]):
        if not ((st_i[FLAGS] & F_LOOK_MAX) != 0 and since(st_i[MXPOS], st_i[PEND]) < st_i[DIST]
                and st_v[MX] > st_v[PEND_Y] and since(m, st_i[PEND]) <= cfg_i[CI_MAX_STEP]):
            k = _finalise(st_i[PEND], m, cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt)
            st_i[FLAGS] &= ~F_PEND
    if m == cfg_i[CI_R3] and not (st_i[FLAGS] & F_OLD):    # the run's first output
        st_v[MN] = y
    elif st_i[FLAGS] & F_LOOK_MAX:
        if y > st_v[MX]:
            st_v[MX] = y
            st_i[MXPOS] = m
        elif y < ar.sub(st_v[MX], _prominence(cfg_i, cfg_v, st_i, st_v, cnt), W_LP, cnt):
            if st_i[FLAGS] & F_PEND_WEAK:        # a full foot-flat follows the weak one: it was no stop step
                st_i[FLAGS] &= ~(F_PEND | F_PEND_WEAK)
            # the step amplitude: the confirmed peak's rise from the trough before it (exponential mean)
            if st_i[FLAGS] & F_AMP:
                st_v[AMP] = ar.add(st_v[AMP], ar.scale2(ar.sub(ar.sub(st_v[MX], st_v[MN], W_LP, cnt), st_v[AMP],
                                                                W_LP, cnt), -cfg_i[CI_AMP_SHIFT], W_LP, cnt),
                                   W_LP, cnt)
            else:
                st_v[AMP] = ar.sub(st_v[MX], st_v[MN], W_LP, cnt)
                st_i[FLAGS] |= F_AMP
            k = _confirmed(st_i[MXPOS], st_v[MX], m, cfg_i, cfg_v, st_i, st_v, durs, scr, out_i, out_v, k, cnt)
            st_i[FLAGS] &= ~F_LOOK_MAX
            st_v[MN] = y
            st_v[MX] = y                         # looking for a trough: MX follows the weak peaks (below)
            st_i[MXPOS] = m
        elif cfg_v[CV_STOP] > 0 and y < ar.sub(st_v[MX], cfg_v[CV_STOP], W_LP, cnt):
            _stop_candidate(cfg_i, st_i, st_v, cnt)  # a peak that rose fully and fell only a little
    elif y < st_v[MN]:
        st_v[MN] = y
        st_v[MX] = y
        st_i[MXPOS] = m
    elif y > ar.add(st_v[MN], _prominence(cfg_i, cfg_v, st_i, st_v, cnt), W_LP, cnt):
        st_i[FLAGS] |= F_LOOK_MAX
        if st_i[FLAGS] & F_PEND_WEAK:            # not quiet after a weak peak: it was no stop step
            st_i[FLAGS] &= ~(F_PEND | F_PEND_WEAK)
        st_v[MX] = y
        st_i[MXPOS] = m
    elif cfg_v[CV_STOP] > 0:
        _weak_peak(y, m, cfg_i, cfg_v, st_i, st_v, cnt)
    return k


@njit(cache=True, nrt=False)
def _weak_peak(y, m, cfg_i, cfg_v, st_i, st_v, cnt):  # pragma: no cover - compiled
    """The stop rule, while looking for a trough: ``MX`` follows the highest ``y3`` since the trough ``MN``
    (or since the last weak peak); a bump that rose and fell by ``stop_prominence`` is a weak peak. The
    first weak peak ``DIST`` to ``MAX_STEP`` after a final full foot-flat becomes the pending foot-flat,
    marked weak: final once ``MAX_STEP`` passes without a full-prominence rise (the walker stopped), dropped
    at such a rise."""
    s_cost(cnt, OP_CMP32, 1)
    if y > st_v[MX]:
        st_v[MX] = y
        st_i[MXPOS] = m
        return
    s_cost(cnt, OP_DEE, 3)
    s_cost(cnt, OP_CMP32, 2)
    if (y < ar.sub(st_v[MX], cfg_v[CV_STOP], W_LP, cnt)
            and st_v[MX] > ar.add(st_v[MN], cfg_v[CV_STOP], W_LP, cnt)):
        _stop_candidate(cfg_i, st_i, st_v, cnt)
        st_v[MX] = y
        st_i[MXPOS] = m


@njit(cache=True, nrt=False)
def _stop_candidate(cfg_i, st_i, st_v, cnt):  # pragma: no cover - compiled
    """The weak peak at ``MXPOS`` is the pending foot-flat, marked weak, when it is the first one ``DIST`` to
    ``min(3 DIST, MAX_STEP)`` after a final full foot-flat (within about two typical steps; nothing pending,
    the last step not itself a weak one)."""
    s_cost(cnt, OP_CMP16, 3)
    if ((st_i[FLAGS] & (F_LAST | F_LAST_WEAK | F_PEND)) == F_LAST
            and st_i[DIST] <= since(st_i[MXPOS], st_i[LAST]) <= min(3 * st_i[DIST], cfg_i[CI_MAX_STEP])):
        st_i[PEND] = st_i[MXPOS]
        st_v[PEND_Y] = st_v[MX]
        st_i[FLAGS] |= F_PEND | F_PEND_WEAK


# ---------------------------------------------------------------------------------------------------------
# entry points


@njit(cache=True, nrt=False, nogil=True)
def process(codes, cfg_i, cfg_v, st_i, st_v, line, durs, scr, out_i, out_v, k, cnt, cyc):  # pragma: no cover
    """Run the algorithm over a block of ``(n, 3)`` codes (value dtype); return the records written.

    ``cyc`` collects the cycles: ``[total, worst sample, samples, index of the worst sample, backlog, worst
    backlog]``. The backlog is the work the main loop still owes when the next sample arrives, with
    ``cfg_i[CI_BUDGET]`` cycles per sample period left to the algorithm (the sampling interrupt keeps
    storing samples meanwhile; the algorithm reads them back).
    """
    for row in range(codes.shape[0]):
        cnt[C_CYCLES] = 0
        k = _sample(codes[row, 0], codes[row, 1], codes[row, 2], cfg_i, cfg_v, st_i, st_v, line, durs, scr,
                    out_i, out_v, k, cnt)
        if cnt[C_CYCLES] > cyc[1]:
            cyc[1] = cnt[C_CYCLES]
            cyc[3] = cyc[2]
        cyc[0] += cnt[C_CYCLES]
        cyc[2] += 1
        cyc[4] = max(0, cyc[4] + cnt[C_CYCLES] - cfg_i[CI_BUDGET])
        if cyc[4] > cyc[5]:
            cyc[5] = cyc[4]
    return k


@njit(cache=True, nrt=False, nogil=True)
def flush(cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt):  # pragma: no cover - compiled
    """End of a run (STOP): the pending foot-flat becomes final with the samples there are."""
    if st_i[FLAGS] & F_PEND and (st_i[FLAGS] & F_OLD or st_i[N] > 2 * cfg_i[CI_R3]):
        if st_i[N] % cfg_i[CI_FLUSH]:            # the newest a_v go to the ring first, whatever the step reads
            _scratch_tail(st_i[N], cfg_i, out_i, k, cnt)
        k = _finalise(st_i[PEND], (st_i[N] - 1 - cfg_i[CI_R3]) & INDEX_MASK, cfg_i, cfg_v, st_i, st_v, scr, out_i,
                      out_v, k, cnt)
        st_i[FLAGS] &= ~F_PEND
    return k


@njit(cache=True, nrt=False, nogil=True)
def reset(cfg_i, st_i, st_v, line, durs):  # pragma: no cover - compiled
    """START: a fresh state; the minimum distance from the prior typical step until the median is known."""
    st_i[:] = 0
    st_v[:] = 0
    line[:] = 0
    durs[:] = 0
    st_i[DIST] = minimum_distance(cfg_i[CI_PRIOR_TWICE], cfg_i[CI_MIN_STEP], cfg_i[CI_FRACTION])
