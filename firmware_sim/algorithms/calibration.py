"""Calibration of 10-bit ADC codes in fixed point: ``a_g = M · (codes − offset)`` (PROTOCOL.md 2.1).

The header's calibration slot stores the offset in Q15.16 counts and the matrix in Q1.30 g per count
(32-bit words). The PIC keeps less, in 16-bit words:

* offset in :data:`~gaitlog.firmware_sim.algorithms.formats.OFFSET_Q` (Q10.5 counts, rounded half up; codes of
  12 bits, for the ADC sweep, use Q12.3: :func:`~gaitlog.firmware_sim.algorithms.formats.centred_q`);
* the nine matrix entries as Q0.15 mantissas with one shared exponent (block floating point): entry
  ``M_ij ≈ m_ij · 2**-(15 + e)``, ``e`` the largest shift that keeps the largest ``|M_ij|`` below 1 in
  Q0.15. For the nominal ±2 g over 10 bits (1/256 g per count) ``e = 7``: 22 fraction bits, a relative
  resolution of 2⁻¹⁴ on the diagonal.

The on-line algorithm applies it per sample (:mod:`gaitlog.firmware_sim.algorithms.kernel`, step 1): per axis one
16-bit subtraction (Q10.5), three 16×16→32 multiplies, a saturating 32-bit sum and a rounding shift to
:data:`~gaitlog.firmware_sim.algorithms.formats.ACC_Q` (Q2.13 g).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gaitlog.firmware_sim.algorithms.formats import MANTISSA_Q, centred_q
from gaitlog.firmware_sim.fixedpoint import QFormat, requantize
from gaitlog.protocol.adc_bits import MAX_SIMULATED_ADC_BITS, check_adc_bits

SLOT_OFFSET_Q = QFormat(15, 16, word_bits=32)
SLOT_MATRIX_Q = QFormat(1, 30, word_bits=32)


@dataclass(frozen=True, eq=False)
class CalibrationQ:
    """The calibration as the PIC keeps it.

    Attributes
    ----------
    offset_raw
        ``(3,)`` offsets, raw ``centred_q(adc_bits)`` (Q10.5 for 10-bit codes).
    mantissa_raw
        ``(3, 3)`` matrix mantissas, raw Q0.15.
    matrix_frac_bits
        Fraction bits of the matrix entries (``15 + e``).
    adc_bits
        Width of the codes (10: the PIC's converter and PROTOCOL.md's fields; up to 12 for the sweep).
    """

    offset_raw: np.ndarray
    mantissa_raw: np.ndarray
    matrix_frac_bits: int
    adc_bits: int = 10

    @classmethod
    def from_slot(cls, offset_q16: np.ndarray, matrix_q30: np.ndarray, *, adc_bits: int = 10) -> CalibrationQ:
        """From the header slot's integers (``offset_q16`` (3,), ``matrix_q30`` (3, 3) or (9,))."""
        off = np.asarray(offset_q16, np.int64).reshape(3)
        m = np.asarray(matrix_q30, np.int64).reshape(3, 3)
        offset_raw = requantize(off, SLOT_OFFSET_Q, centred_q(adc_bits))
        big = int(np.max(np.abs(m)))
        if big == 0:
            raise ValueError("calibration matrix is all zeros")
        # drop just enough of the 30 fraction bits that the largest entry (rounded) fits a Q0.15 mantissa
        drop = 0
        while drop < 30 and (big + ((1 << drop) >> 1)) >> drop > MANTISSA_Q.max_raw:
            drop += 1
        frac = SLOT_MATRIX_Q.frac_bits - drop
        mant = requantize(m, SLOT_MATRIX_Q, QFormat(15 - frac, frac))
        return cls(offset_raw, mant, frac, int(adc_bits))

    @classmethod
    def from_float(cls, offset_counts: np.ndarray, matrix_g_per_count: np.ndarray, *,
                   adc_bits: int = 10) -> CalibrationQ:
        """From float parameters, through the slot's Q15.16 / Q1.30 words (as the device receives them)."""
        off = SLOT_OFFSET_Q.from_float(np.asarray(offset_counts, np.float64).reshape(3))
        m = SLOT_MATRIX_Q.from_float(np.asarray(matrix_g_per_count, np.float64).reshape(3, 3))
        return cls.from_slot(off, m, adc_bits=adc_bits)

    @classmethod
    def from_protocol(cls, calibration: object, *, adc_bits: int = 10) -> CalibrationQ:
        """From a :class:`gaitlog.protocol.header.CalibrationSlot` (its ``offset_counts`` and ``matrix_g_per_count``)."""
        return cls.from_float(calibration.offset_counts, calibration.matrix_g_per_count, adc_bits=adc_bits)

    def with_mantissa_bits(self, bits: int) -> CalibrationQ:
        """The same calibration with mantissas of ``bits`` fraction bits instead of Q0.15's (rounded half up; a
        sweep's question, the shipped ``bits`` give ``self``)."""
        drop = MANTISSA_Q.frac_bits - int(bits)
        if drop < 0:
            raise ValueError(f"mantissa bits must be at most {MANTISSA_Q.frac_bits}, got {bits}")
        if drop == 0:
            return self
        mant = (self.mantissa_raw + (1 << (drop - 1))) >> drop
        return replace(self, mantissa_raw=mant, matrix_frac_bits=self.matrix_frac_bits - drop)

    @property
    def offset_counts(self) -> np.ndarray:
        """The offsets the PIC uses, counts (float)."""
        return centred_q(self.adc_bits).to_float(self.offset_raw)

    @property
    def matrix_g_per_count(self) -> np.ndarray:
        """The matrix the PIC uses, g per count (float)."""
        return self.mantissa_raw.astype(np.float64) * 2.0 ** -self.matrix_frac_bits


def nominal_calibration_q(*, adc_bits: int = 10) -> CalibrationQ:
    """The nominal map of PROTOCOL.md 2.1 (``cal_format = 0``): offset ``2**(bits-1)`` and
    ``M = diag(4 g / 2**bits)``, for codes right-justified in 10-bit fields (up to 12 bits for the sweep).

    >>> cal = nominal_calibration_q()
    >>> cal.offset_counts.tolist(), cal.matrix_frac_bits, cal.mantissa_raw[0, 0]
    ([512.0, 512.0, 512.0], 22, np.int64(16384))
    >>> nominal_calibration_q(adc_bits=12).offset_raw.tolist()
    [16384, 16384, 16384]
    """
    check_adc_bits(adc_bits, max_bits=MAX_SIMULATED_ADC_BITS, error=ValueError)
    return CalibrationQ.from_float(np.full(3, 2.0 ** (adc_bits - 1)), np.eye(3) * 4.0 / 2.0 ** adc_bits,
                                   adc_bits=adc_bits)
