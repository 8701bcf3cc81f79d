"""The Q formats of the fixed-point step chain and the RAM its state takes on the PIC16F877.

Every number the chain keeps has one of the formats below (``docs/FIXED_POINT.md`` gives each one's range
and why human walking cannot overflow it). :data:`STATE_VARIABLES` lists what the chain must hold in RAM
between samples when it runs on-line, with its size; :func:`ram_bytes` sums it for comparison with the
PIC's 368 bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

from firmware_sim.fixedpoint import QFormat

#: Standard gravity, m/s^2 per g (the firmware folds it into its constants).
STANDARD_GRAVITY_M_S2 = 9.80665

#: Offset of the calibration in ADC counts: Q10.5 (+-1024 counts, 1/32 count) for the 10-bit ADC.
OFFSET_Q = QFormat(10, 5)
#: ADC code minus offset: Q10.5 in 16 bits (10-bit ADC; see :func:`centred_q` for other widths).
CENTRED_Q = QFormat(10, 5)


def centred_q(code_bits: int) -> QFormat:
    """Format of offsets and centred codes for ``code_bits``-bit codes: ``Q{b}.{15-b}`` in 16 bits.

    Codes of up to 10 bits live in the 10-bit fields of PROTOCOL.md (Q10.5); the 12-bit case is the
    sweep's hypothetical external converter (Q12.3: the same 1/32 of a 10-bit count).

    >>> str(centred_q(10)), str(centred_q(12))
    ('Q10.5/16', 'Q12.3/16')
    """
    if not 1 <= code_bits <= 14:
        raise ValueError(f"code width must be 1 .. 14 bits, got {code_bits}")
    b = max(10, int(code_bits))
    return QFormat(b, 15 - b)
#: Calibrated specific force and every acceleration of the chain, g: Q2.13 (+-4 g, 0.122 mg).
ACC_Q = QFormat(2, 13)
#: Squares and dot products of accelerations, g^2: Q5.26 in 32 bits (unsigned for |g|^2).
ACC2_Q = QFormat(5, 26, word_bits=32)
#: Window sums of the gravity estimate: Q18.13 in 32 bits (up to 400 samples of +-4 g... 2^18 g).
GRAVITY_SUM_Q = QFormat(18, 13, word_bits=32)
#: Low-pass kernel weights: Q1.14 (each < 1; the sum is 2^14 = 1).
KERNEL_Q = QFormat(1, 14)
#: Low-pass outputs (3 Hz and 10 Hz vertical acceleration), g: Q2.16 in a 24-bit word (3 bits finer than
#: the input, from a second 16/16 divide of the remainder; fewer exact ties between neighbouring samples).
LOWPASS_OUT_Q = QFormat(2, 16, word_bits=24)
#: Low-pass numerator (sum of weight x acceleration): Q4.27 in 32 bits.
LOWPASS_SUM_Q = QFormat(4, 27, word_bits=32)
#: Integrated velocity accumulator, units of 2 * ACC lsb * sample: signed 32-bit integer.
VELOCITY_Q = QFormat(31, 0, word_bits=32)
#: Integrated position accumulator, units of 4 * ACC lsb * sample^2: signed 32-bit integer.
POSITION_Q = QFormat(31, 0, word_bits=32)
#: Vertical excursion h, m: unsigned Q0.16 (0 .. 1 m, 15 um).
EXCURSION_Q = QFormat(0, 16, signed=False)
#: Leg and foot length, m: unsigned Q1.15 (0 .. 2 m, 31 um).
LENGTH_Q = QFormat(1, 15, signed=False)
#: ``2 l h - h^2``, m^2: unsigned Q2.30 in 32 bits.
PENDULUM_ARG_Q = QFormat(2, 30, signed=False, word_bits=32)
#: Step length, m: unsigned Q2.14 (0 .. 4 m, 61 um).
STEP_Q = QFormat(2, 14, signed=False)
#: Calibration constant K of M1/M2 and M4's K * g0^(1/4): unsigned Q1.15 (0 .. 2).
K_Q = QFormat(1, 15, signed=False)
#: Fourth root of M4's range in g: unsigned Q3.13.
ROOT4_Q = QFormat(3, 13, signed=False)
#: M5 constants and cadence: K1 * fs in m * samples and K2 in m, Q15.16 in 32 bits; cadence Hz Q15.16.
M5_Q = QFormat(15, 16, word_bits=32)


@dataclass(frozen=True)
class StateVariable:
    """One value the on-line chain keeps in RAM between samples."""

    name: str
    fmt: QFormat
    count: int
    stage: str
    note: str

    @property
    def bytes(self) -> int:
        """RAM taken."""
        return self.fmt.ram_bytes * self.count


U8 = QFormat(8, 0, signed=False, word_bits=8)
U16 = QFormat(16, 0, signed=False)


def state_variables(*, sampling_rate_hz: float = 50.0, gravity_window_s: float = 4.0,
                    lowpass_radius: int = 9, detail_radius: int = 3, hs_search: int = 10,
                    hs_after: int = 3) -> list[StateVariable]:
    """The RAM state of the on-line chain for the given parameters (50 Hz defaults).

    Window buffers of the centred filters hold *vertical accelerations* in RAM (the 5 Hz filter of the
    heel-strike impact band reads its taps from the 3 Hz delay line: same centre, shorter kernel); the
    gravity window (200 samples at 50 Hz) does not fit and is not held: the codes entering and leaving it
    are read back from the external EEPROM ring, where they are stored anyway (two 4-byte I2C reads per
    sample).
    """
    lp_taps = 2 * lowpass_radius + 1
    det_taps = 2 * detail_radius + 1
    return [
        StateVariable("calibration offset", OFFSET_Q, 3, "calibration", "copied from the data EEPROM header"),
        StateVariable("calibration matrix mantissas", QFormat(0, 15), 9, "calibration", "block exponent below"),
        StateVariable("calibration matrix exponent", U8, 1, "calibration", "shared shift of the 9 mantissas"),
        StateVariable("gravity window sums", GRAVITY_SUM_Q, 3, "axes", "running sums, add entering/subtract leaving"),
        StateVariable("gravity window count", U16, 1, "axes", "valid samples in the window"),
        StateVariable("3 Hz delay line (a_v)", ACC_Q, lp_taps, "low-pass", "centred Gaussian FIR"),
        StateVariable("3 Hz validity bits", U8, (lp_taps + 7) // 8, "low-pass", "one bit per tap"),
        StateVariable("10 Hz delay line (a_v)", ACC_Q, det_taps, "low-pass", "centred Gaussian FIR"),
        StateVariable("impact band history for HS", LOWPASS_OUT_Q, hs_search + hs_after + 1, "events",
                      "10 Hz - 5 Hz, peak search around FF"),
        StateVariable("10 Hz last two outputs for TO", LOWPASS_OUT_Q, 2, "events", "local-minimum test"),
        StateVariable("peak detector: candidate, trough, last FF", LOWPASS_OUT_Q, 3, "events", "values"),
        StateVariable("peak detector: indices", U16, 4, "events", "candidate, trough, last FF, last TO"),
        StateVariable("sample counter", QFormat(31, 0, word_bits=32), 1, "events", "time base"),
        StateVariable("a_v staging for the M2 pass", ACC_Q, 16, "integration",
                      "page-written to an EEPROM scratch area, read back for the second pass"),
        StateVariable("velocity accumulators M1, M2", VELOCITY_Q, 2, "integration", "reset at foot-flat"),
        StateVariable("position accumulators M1, M2", POSITION_Q, 2, "integration", "reset at foot-flat"),
        StateVariable("position max/min M1, M2, M3", POSITION_Q, 6, "integration", "running extremes"),
        StateVariable("drift constants c1, c2", QFormat(31, 0, word_bits=32), 2, "integration", "M2 second pass"),
        StateVariable("3 Hz max/min in the step", LOWPASS_OUT_Q, 2, "M4", "range of the first harmonic"),
        StateVariable("anatomy: leg, foot", LENGTH_Q, 2, "M1-M3", "constants"),
        StateVariable("K: M1, M2, M4; M5 K1, K2", K_Q, 3, "M1-M5", "constants (M5 pair below)"),
        StateVariable("M5 K1*fs, K2", M5_Q, 2, "M5", "constants"),
        StateVariable("step output: 5 lengths", STEP_Q, 5, "output", "until written to EEPROM"),
    ]


def ram_bytes(variables: list[StateVariable] | None = None) -> int:
    """Total RAM of the chain's state.

    >>> ram_bytes()
    277
    """
    return int(sum(v.bytes for v in (variables if variables is not None else state_variables())))
