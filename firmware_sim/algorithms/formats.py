"""The Q formats of the on-line step algorithm in the PIC's arithmetic.

Every number the algorithm keeps or computes has one of the formats below (``docs/FIXED_POINT.md`` gives
each one's range and why human walking cannot overflow it). The kernel
(:mod:`gaitlog.firmware_sim.algorithms.online`) uses their fraction bits (``F_*``) and words (``W_*``: width in bits,
negative for unsigned) as compile-time integers; in the float arithmetic they are ignored.
"""

from __future__ import annotations

from gaitlog.firmware_sim.fixedpoint import QFormat

__all__ = [
    "ACC_Q", "GRAVITY_Q", "ACC2_Q", "KERNEL_Q", "FIR_SUM_Q", "LOWPASS_Q", "VELOCITY_Q", "POSITION_Q",
    "POSITION2_Q", "EXCURSION_Q", "EXCURSION2_Q", "LENGTH_Q", "TWO_LENGTH_Q", "PENDULUM_ARG_Q", "PENDULUM_ARG2_Q",
    "STEP_Q", "K_Q", "K4_Q", "ROOT4_Q",
    "M5_Q", "MANTISSA_Q", "centred_q", "word",
]

#: Calibrated specific force and vertical acceleration a_v, g: Q2.13 (±4 g, 0.122 mg).
ACC_Q = QFormat(2, 13)
#: Gravity estimate (each exponential stage), g: Q2.29 in 32 bits (the shifted increments keep 16 bits).
GRAVITY_Q = QFormat(2, 29, word_bits=32)
#: Squares and dot products of accelerations, g^2: Q5.26 in 32 bits.
ACC2_Q = QFormat(5, 26, word_bits=32)
#: Gaussian FIR weights: Q1.14 (the full kernel sums to exactly 2^14).
KERNEL_Q = QFormat(1, 14)
#: FIR accumulator (sum of weight x pair of a_v), g: Q4.27 in 32 bits.
FIR_SUM_Q = QFormat(4, 27, word_bits=32)
#: FIR outputs (3 Hz, 10 Hz, 5 Hz and the impact band), g: Q2.16 in a 24-bit word.
LOWPASS_Q = QFormat(2, 16, word_bits=24)
#: Velocity accumulator ``V = sum(a_k + a_k-1)``: 32-bit, a_v's 13 fraction bits (unit 2 g T_s).
VELOCITY_Q = QFormat(18, 13, word_bits=32)
#: Position accumulator ``P = sum(V_k + V_k-1)``: 32-bit, 13 fraction bits (unit 4 g T_s^2).
POSITION_Q = QFormat(18, 13, word_bits=32)
#: M2's drift-corrected position and its constants c1, c2: 32-bit, 17 fraction bits (same unit).
POSITION2_Q = QFormat(14, 17, word_bits=32)
#: M1's vertical excursion h, m: unsigned Q0.16 (0 .. 1 m, 15 um): M1's integral is not drift-corrected and
#: reaches 0.95 m on long steps of the IPOL trials.
EXCURSION_Q = QFormat(0, 16, signed=False)
#: M2's and M3's (drift-corrected) excursions, m: unsigned Q-2.18 in 16 bits (0 .. 0.25 m, 3.8 um; a walking
#: trunk moves 2-10 cm, 9.5 cm at most on the IPOL trials; a larger h saturates, counted).
EXCURSION2_Q = QFormat(-2, 18, signed=False)
#: Leg and foot length, K of M1, M2, M4: unsigned Q1.15 (0 .. 2).
LENGTH_Q = QFormat(1, 15, signed=False)
#: Twice the leg length, and the foot length added to M3, m: unsigned Q2.14 (the UQ1.15 leg's bits read
#: with one fraction bit fewer are twice the leg: no shift).
TWO_LENGTH_Q = QFormat(2, 14, signed=False)
#: ``2 l h - h^2``, m^2: unsigned, ``14 + f_h`` fraction bits in 32 bits (2l in UQ2.14 times h): Q2.30 for
#: M1 (h < 1 m), Q0.32 for M2 and M3 (below 0.65 m^2 for a 1.3 m leg and h <= 0.25 m).
PENDULUM_ARG_Q = QFormat(2, 30, signed=False, word_bits=32)
PENDULUM_ARG2_Q = QFormat(0, 32, signed=False, word_bits=32)
#: Step length, m: unsigned Q2.14 (0 .. 4 m, 61 um): the record's five lengths.
STEP_Q = QFormat(2, 14, signed=False)
#: K of M1/M2 (and of M4, m / (m/s^2)^p, as the step configuration stores it): unsigned Q1.15.
K_Q = QFormat(1, 15, signed=False)
#: M4's device constant ``K g0^p`` (p the step configuration's M4 exponent, at most 1/2: g0^(1/2) = 3.13 without
#: K; the default 1/4: 1.77): unsigned Q2.14.
K4_Q = QFormat(2, 14, signed=False)
#: M4's square root, fourth and eighth roots of the range (g^(1/2), g^(1/4), g^(1/8)): unsigned Q1.15 (a
#: walking trunk's 3 Hz range is below 2 g; a range of 4 g saturates the square root's 32-bit argument, counted).
ROOT4_Q = QFormat(1, 15, signed=False)
#: M5 constants ``K1 fs`` (m · samples) and ``K2`` (m): Q15.16 in 32 bits.
M5_Q = QFormat(15, 16, word_bits=32)
#: Calibration matrix mantissas, a shared exponent beside them (block floating point): Q0.15.
MANTISSA_Q = QFormat(0, 15)


def centred_q(adc_bits: int) -> QFormat:
    """Format of calibration offsets and centred codes for ``adc_bits``-bit codes: ``Q{b}.{15-b}``.

    Codes of up to 10 bits live in the 10-bit fields of PROTOCOL.md (Q10.5); the 12-bit case is the sweep's
    hypothetical external converter (Q12.3: the same 1/32 of a 10-bit count).

    >>> str(centred_q(10)), str(centred_q(12))
    ('Q10.5/16', 'Q12.3/16')
    """
    if not 1 <= adc_bits <= 14:
        raise ValueError(f"code width must be 1 .. 14 bits, got {adc_bits}")
    b = max(10, int(adc_bits))
    return QFormat(b, 15 - b)


def word(q: QFormat) -> int:
    """The kernel's word argument of a format: its width in bits, negative when unsigned.

    >>> word(ACC_Q), word(STEP_Q), word(LOWPASS_Q)      # Q2.16 saturates at its 19 bits, stored in 24
    (16, -16, 19)
    """
    return q.total_bits if q.signed else -q.total_bits


# fraction bits and words as compile-time integers of the kernel
F_ACC = ACC_Q.frac_bits
F_GRAV = GRAVITY_Q.frac_bits
F_ACC2 = ACC2_Q.frac_bits
F_KERNEL = KERNEL_Q.frac_bits
F_FIR = FIR_SUM_Q.frac_bits
F_LP = LOWPASS_Q.frac_bits
F_POS = POSITION_Q.frac_bits
F_POS2 = POSITION2_Q.frac_bits
F_EXC = EXCURSION_Q.frac_bits
F_EXC2 = EXCURSION2_Q.frac_bits
F_TWO_LEN = TWO_LENGTH_Q.frac_bits
F_STEP = STEP_Q.frac_bits
F_K = K_Q.frac_bits
F_K4 = K4_Q.frac_bits
F_ROOT = ROOT4_Q.frac_bits
F_M5 = M5_Q.frac_bits
F_PARG = PENDULUM_ARG_Q.frac_bits
F_PARG2 = PENDULUM_ARG2_Q.frac_bits
#: Words of operands that are no format's value (a 32-bit product sum of the calibration, a multiplier's 16-bit
#: operand, twice a square root before it is rounded to a step length).
W16, W32 = 16, 32
U16, U32 = -16, -32
#: The FIR outputs' word: Q2.16 saturates at +-4 g (19 bits), kept in 24-bit RAM words.
W_LP = word(LOWPASS_Q)
#: Each format's word where its values saturate (a sweep narrows them:
#: :class:`gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`); the centred codes' is ``centred_q``'s.
W_CODE = word(centred_q(10))
W_ACC = word(ACC_Q)
W_GRAV = word(GRAVITY_Q)
W_ACC2 = word(ACC2_Q)
W_FIR = word(FIR_SUM_Q)
W_VEL = word(VELOCITY_Q)
W_POS = word(POSITION_Q)
W_POS2 = word(POSITION2_Q)
W_EXC = word(EXCURSION_Q)
W_EXC2 = word(EXCURSION2_Q)
W_PARG = word(PENDULUM_ARG_Q)
W_PARG2 = word(PENDULUM_ARG2_Q)
W_STEP = word(STEP_Q)
W_ROOT = word(ROOT4_Q)
W_M5 = word(M5_Q)
