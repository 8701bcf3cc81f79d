"""The on-line step algorithm as an object: configure, feed samples, get one record per foot-flat.

:class:`OnlineStepAlgorithm` wraps the compiled per-sample kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`)
with its configuration and state. The same object runs

* inside the emulated logger (:class:`gaitlog.firmware_sim.device.Logger`): the sampling interrupt's samples are
  fed as they are logged (``arithmetic="fixed"``, the PIC's), and each record is stored in the step memory;
* on the host, to replay a dump (the same codes, the same configuration from the header: the same records
  bit for bit) or to compare arithmetics (``arithmetic="float"``: the same algorithm in floating point).

Configuration (:class:`OnlineConfig`): the device calibration (PROTOCOL.md 2.1), the step configuration
(:class:`gaitlog.protocol.steps.StepConfig`: leg and foot length, K of M1, M2, M4, the M5 line, and whether K is
calibrated), the rules (:class:`~gaitlog.firmware_sim.algorithms.parameters.EventParameters`,
:class:`~gaitlog.firmware_sim.algorithms.parameters.OnlineParameters`) and the sampling rate. In fixed point every
constant is quantised as the PIC keeps it; in float the configuration's values are used as they are stored
in the header (the same numbers): the arithmetic is the only difference. Without a calibrated K, the
lengths are the raw values a K calibration needs (K = 1; M4 in (m/s^2)^p, p the step configuration's M4 exponent (default ``parameters.M4_EXPONENT``), M5 = 1/T in Hz: K1 = 1 m·s,
K2 = 0), flagged ``UNCALIBRATED``.

Examples
--------
A sinusoidal centre of mass (h = 4 cm, 2 steps/s) on the z axis, 10-bit codes, leg 0.9 m:

>>> sampling_rate_hz = 50.0; t = np.arange(int(20 * sampling_rate_hz)) / sampling_rate_hz
>>> acc = np.zeros((t.size, 3)); acc[:, 2] = 1 - 0.02 * (4 * np.pi) ** 2 * np.cos(4 * np.pi * t) / 9.80665
>>> codes = np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)
>>> cfg = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
>>> steps = OnlineStepAlgorithm(sampling_rate_hz=sampling_rate_hz, step_config=cfg).run(codes)
>>> steps.n_steps in (37, 38, 39), round(float(np.median(steps.excursion_m()[1:, 1])), 3)
(True, 0.04)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gaitlog.firmware_sim.algorithms import aot_kernel, format_kernel, kernel
from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.formats import (
    EXCURSION2_Q,
    EXCURSION_Q,
    K_Q,
    KERNEL_Q,
    LENGTH_Q,
    M5_Q,
    STEP_Q,
    TWO_LENGTH_Q,
    centred_q,
)
from gaitlog.firmware_sim.algorithms.parameters import (
    M4_EXPONENT,
    SIGMA_S_AT_1HZ,
    EventParameters,
    OnlineParameters,
    SampleCounts,
    m4_exponent_eighths,
)
from gaitlog.firmware_sim.algorithms.state import (
    INDEX_HALF,
    INDEX_MASK,
    INDEX_MODULUS,
    N_INDICES,
    N_VALUES,
    ram_bytes,
    variables,
)
from gaitlog.firmware_sim.algorithms.state import LINE_POS as LINE_POS_SLOT
from gaitlog.firmware_sim.algorithms.state import N as _N_SLOT
from gaitlog.firmware_sim.eeprom import PAGE_BYTES
from gaitlog.firmware_sim.logging_cycles import algorithm_cycles_per_sample
from gaitlog.firmware_sim.fixedpoint import (
    C_CYCLES,
    C_DIV0,
    C_SAT,
    C_WRAP,
    DEFAULT_FOSC_HZ,
    ArithmeticContext,
    QFormat,
    cycles_per_sample_available,
    mul_q,
    new_counters,
    requantize,
)
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.steps import (
    HEEL_STRIKE_NOT_FOUND,
    STEP_LENGTH_FIELDS,
    StepConfig,
    StepFlag,
    empty_step_records,
)
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["ARITHMETICS", "OnlineConfig", "OnlineSteps", "OnlineStepAlgorithm", "CycleStats", "load_kernels",
           "step_algorithm_for"]

#: The two arithmetics of the algorithm.
ARITHMETICS = ("fixed", "float")
#: :meth:`OnlineStepAlgorithm.feed` runs the kernel on blocks of at most this many samples (memory stays
#: bounded; the kernel's 16-bit end indices of a block's records are then less than 2^16 samples behind its
#: last sample, so the driver restores their absolute values).
BLOCK_SAMPLES = INDEX_HALF


def _gaussian_half(cutoff_hz: float, sampling_rate_hz: float, radius: int) -> np.ndarray:
    """The normalised Gaussian (-3 dB at ``cutoff_hz``) of ``radius``, centre first (half kernel)."""
    sigma = SIGMA_S_AT_1HZ / cutoff_hz * sampling_rate_hz
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    phi = np.exp(-0.5 * (x / sigma) ** 2)
    phi /= phi.sum()
    return phi[radius:]


def _kernel_q(half: np.ndarray, fmt: QFormat = KERNEL_Q) -> np.ndarray:
    """Q1.14 half kernel (or ``fmt``'s) whose full kernel sums to exactly 2^14 (the rounding residue in the centre
    tap)."""
    one = 1 << fmt.frac_bits
    q = np.asarray(fmt.from_float(half), np.int64)
    q[0] += one - (q[0] + 2 * int(q[1:].sum()))
    return q


def _leg_and_foot(fq: KernelFormats, raw: dict) -> tuple[int, int]:
    """The kernel's ``2 l`` (``TWO_LENGTH_Q``: the UQ1.15 leg's bits read with one fraction bit fewer are twice the
    leg, no shift) and foot length (added to M3's pendulum length: in the step format, UQ2.14 as ``TWO_LENGTH_Q``)
    from the step configuration's UQ1.15 fields, each first stored in ``fq``'s ``LENGTH_Q``."""
    leg_q = fq.q("leg_frac_bits")
    leg = requantize(np.int64(raw["leg_length_q15"]), LENGTH_Q, leg_q)
    twice = QFormat(leg_q.int_bits + 1, leg_q.frac_bits - 1, signed=False, word_bits=leg_q.word_bits)
    foot = requantize(np.int64(raw["foot_length_q15"]), LENGTH_Q, leg_q)
    return (int(requantize(leg, twice, fq.q("two_leg_frac_bits"))),
            int(requantize(foot, leg_q, fq.q("step_frac_bits"))))


def _scratch_size(c: SampleCounts) -> int:
    """The emulator's scratch ring (values): a power of two covering the oldest a_v a step can read, its
    filters' reach included (see ``kernel``). The EEPROM's ring holds more (32,512 samples), the same values."""
    need = 2 * c.r3 + 2 * c.max_step + c.hs_before + c.to_span + 4
    size = 1 << max(6, math.ceil(math.log2(need)))
    if size > INDEX_MODULUS:          # the ring follows the 16-bit indices across their wrap: it divides 2^16
        raise ValueError(f"the scratch ring needs {need} samples, more than the 16-bit indices reach")
    return size


def _flush_samples(c: SampleCounts) -> int:
    """a_v written to the scratch ring at a time: the largest power of two within the delay line (where they
    wait, no RAM of their own) and half a 128-byte page (two bytes each; a power of two: the page writes are
    aligned, and 2^16 is a multiple, so the 16-bit sample index wraps with them)."""
    return 1 << int(math.floor(math.log2(min(2 * c.r3 + 1, PAGE_BYTES // kernel.SCRATCH_SAMPLE_BYTES))))


@dataclass(frozen=True, eq=False)
class OnlineConfig:
    """The kernel's configuration arrays for one arithmetic (built by :meth:`build`).

    Attributes
    ----------
    arithmetic
        ``"fixed"`` or ``"float"``.
    counts
        The parameters in samples at the sampling rate.
    step_config
        The step configuration as stored (quantised).
    cfg_i, cfg_v
        Integer and value configuration (``kernel.CI``, ``kernel.CV``).
    formats
        The fixed-point kernel's Q formats (the shipped ones unless a sweep asks for others).
    """

    arithmetic: str
    counts: SampleCounts
    step_config: StepConfig
    adc_bits: int
    cfg_i: np.ndarray
    cfg_v: np.ndarray
    formats: KernelFormats = KernelFormats()

    @property
    def value_dtype(self) -> type:
        """``np.int64`` (fixed point) or ``np.float64``."""
        return np.int64 if self.arithmetic == "fixed" else np.float64

    @classmethod
    def build(cls, *, sampling_rate_hz: float, step_config: StepConfig, calibration: object | None = None,
              arithmetic: str = "fixed", adc_bits: int = 10, events: EventParameters | None = None,
              online: OnlineParameters | None = None, cycles_available: float | None = None,
              formats: KernelFormats | None = None) -> OnlineConfig:
        """The configuration of the algorithm.

        Parameters
        ----------
        calibration
            The device calibration (``offset_counts``, ``matrix_g_per_count``: a
            :class:`gaitlog.protocol.header.CalibrationSlot`) or None for the nominal map of ``adc_bits`` (±2 g).
        step_config
            Leg, foot, K constants (:class:`gaitlog.protocol.steps.StepConfig`); used as stored (quantised).
        adc_bits
            Width of the ADC codes (10 on the device; 8-12 for the sweep's hypothetical converters).
        cycles_available
            PIC cycles per sample period left to the algorithm (for the backlog figure only; default: the
            whole period at the 18.432 MHz crystal, ``gaitlog.firmware_sim.logging_cycles`` subtracts the
            logging's share).
        formats
            The fixed-point Q formats (:class:`~gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`; default the
            shipped ones); ignored in float.
        """
        fq = formats if formats is not None else KernelFormats()
        if arithmetic not in ARITHMETICS:
            raise ValueError(f"arithmetic must be one of {ARITHMETICS}, got {arithmetic!r}")
        ev = events if events is not None else EventParameters()
        on = online if online is not None else OnlineParameters()
        c = SampleCounts.at(ev, on, sampling_rate_hz)
        sampling_rate_hz = c.sampling_rate_hz
        sc = step_config.quantised()
        if not sc.leg_length_m > 0:
            raise ValueError("the step configuration needs a leg length > 0")
        cal_q = (CalibrationQ.from_protocol(calibration, adc_bits=adc_bits) if calibration is not None
                 else nominal_calibration_q(adc_bits=adc_bits)).with_mantissa_bits(fq.mantissa_frac_bits)
        halves = [_gaussian_half(ev.ff_cutoff_hz, sampling_rate_hz, c.r3), _gaussian_half(ev.detail_cutoff_hz, sampling_rate_hz, c.r10),
                  _gaussian_half(ev.impact_cutoff_hz, sampling_rate_hz, c.r5)]
        w10 = kernel.CV_W3 + c.r3 + 1
        w5 = w10 + c.r10 + 1
        # metres per position unit (4 g T_s^2), its fraction bits, and the pre-shifts that fit 1 m in 16 bits
        unit = STANDARD_GRAVITY_M_S2 / (4.0 * sampling_rate_hz * sampling_rate_hz)
        unit_frac = int(math.floor(math.log2(65535.0 / unit)))
        # pre-shifts of the position ranges (M1: 13 fraction bits, M2/M3: 17) that fit the largest h of their
        # excursion formats (1 m, 0.25 m) in 16 bits
        shifts = [max(0, math.ceil(math.log2(2.0 ** q.frac_bits * e.max_value / unit / 65535.0)))
                  for q, e in ((fq.position_q, EXCURSION_Q), (fq.position2_q, EXCURSION2_Q))]
        cal = sc.calibrated
        # M4's exponent: the configuration's, else the default (what the firmware stores at START); its constant
        # is K g0^p (the range is in g on the device, in m/s^2 in K's unit)
        m4_eighths = m4_exponent_eighths(sc.m4_exponent if sc.m4_exponent > 0 else M4_EXPONENT)
        g0_power_m4 = STANDARD_GRAVITY_M_S2 ** (m4_eighths / 8)
        k1, k2, k4 = (sc.k_m1, sc.k_m2, sc.k_m4) if cal else (1.0, 1.0, 1.0)
        k1_m5, k2_m5 = (sc.k1_m5_m_s, sc.k2_m5_m) if cal else (1.0, 0.0)
        cfg_i = np.zeros(kernel.N_CI, np.int64)
        ci = kernel.CI
        for name, value in dict(R3=c.r3, R10=c.r10, R5=c.r5, MIN_STEP=c.min_step, MAX_STEP=c.max_step,
                                HS_BEFORE=c.hs_before, HS_AFTER=c.hs_after, HS_DELAY=c.hs_delay, TO_SPAN=c.to_span,
                                G_SHIFT=c.gravity_shift, N_MED=c.median_steps, FRACTION=c.fraction_scaled,
                                CODE_FRAC=centred_q(adc_bits).frac_bits, MANT_FRAC=cal_q.matrix_frac_bits,
                                EXC_SHIFT1=shifts[0], EXC_SHIFT2=shifts[1], UNIT_FRAC=unit_frac,
                                SCRATCH=_scratch_size(c), W10=w10, W5=w5, AMP_SHIFT=ev.amplitude_shift,
                                PRIOR_TWICE=c.prior_step_twice, FLUSH=_flush_samples(c), M4_EIGHTHS=m4_eighths,
                                BUDGET=int(cycles_available if cycles_available is not None
                                           else cycles_per_sample_available(sampling_rate_hz))).items():
            cfg_i[ci[name]] = value
        n_v = w5 + c.r5 + 1
        if arithmetic == "fixed":
            cfg_v = np.zeros(n_v, np.int64)
            raw = sc.raw if cal else dict(sc.raw, k_m1_q15=1 << 15, k_m2_q15=1 << 15, k_m4_q15=1 << 15,
                                          k1_m5_q16=1 << 16, k2_m5_q16=0)
            # K' = K g0^p: one UQ1.15 multiply at START
            k_q, k4_q, m5_q = fq.q("k_frac_bits"), fq.q("k4_frac_bits"), fq.q("m5_frac_bits")
            k4p = int(mul_q(np.int64(raw["k_m4_q15"]), k4_q.from_float(g0_power_m4), K_Q.frac_bits, k4_q, signed=False))
            k1fs = raw["k1_m5_q16"] * sampling_rate_hz
            leg, foot = _leg_and_foot(fq, raw)
            values = dict(
                DELTA=int(fq.lowpass_q.from_float(ev.min_prominence_m_s2 / STANDARD_GRAVITY_M_S2)),
                CAP=int(fq.lowpass_q.from_float(ev.max_prominence_m_s2 / STANDARD_GRAVITY_M_S2)),
                FRAC=int(fq.q("kernel_frac_bits").from_float(ev.prominence_fraction)),
                STOP=int(fq.lowpass_q.from_float(ev.stop_prominence_m_s2 / STANDARD_GRAVITY_M_S2)),
                G_MIN=int(fq.acc_q.from_float(on.min_gravity_g)),
                TWO_LEG=leg, FOOT=foot,
                K1=int(requantize(np.int64(raw["k_m1_q15"]), K_Q, k_q)),
                K2=int(requantize(np.int64(raw["k_m2_q15"]), K_Q, k_q)), K4=k4p,
                K1FS=int(m5_q.from_float(k1fs / 2 ** 16)),
                K2M5=int(requantize(np.int64(raw["k2_m5_q16"]), M5_Q, m5_q)),
                UNIT=int(math.floor(unit * 2 ** unit_frac + 0.5)),
            )
            cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3] = requantize(cal_q.offset_raw, centred_q(adc_bits),
                                                                fq.code_q(adc_bits))
            cfg_v[kernel.CV_M:kernel.CV_M + 9] = cal_q.mantissa_raw.reshape(9)
            weights = [_kernel_q(h, fq.q("kernel_frac_bits")) for h in halves]
        else:
            cfg_v = np.zeros(n_v, np.float64)
            values = dict(
                DELTA=ev.min_prominence_m_s2 / STANDARD_GRAVITY_M_S2, FRAC=ev.prominence_fraction,
                CAP=ev.max_prominence_m_s2 / STANDARD_GRAVITY_M_S2,
                STOP=ev.stop_prominence_m_s2 / STANDARD_GRAVITY_M_S2,
                G_MIN=on.min_gravity_g,
                TWO_LEG=2.0 * sc.leg_length_m, FOOT=sc.foot_length_m, K1=k1, K2=k2, K4=k4 * g0_power_m4,
                K1FS=k1_m5 * sampling_rate_hz, K2M5=k2_m5, UNIT=unit,
            )
            slot = calibration.quantised() if calibration is not None else None
            off = slot.offset_counts if slot is not None else np.full(3, 2.0 ** (adc_bits - 1))
            mat = slot.matrix_g_per_count if slot is not None else np.eye(3) * 4.0 / 2 ** adc_bits
            cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3] = off
            cfg_v[kernel.CV_M:kernel.CV_M + 9] = np.asarray(mat, np.float64).reshape(9)
            weights = halves
        for name, value in values.items():
            cfg_v[kernel.CV[name]] = value
        cfg_v[kernel.CV_W3:w10] = weights[0]
        cfg_v[w10:w5] = weights[1]
        cfg_v[w5:n_v] = weights[2]
        if arithmetic == "fixed":
            for name in ("TWO_LEG", "FOOT", "K1", "K2", "K4"):
                if not 0 <= cfg_v[kernel.CV[name]] <= 0xFFFF:
                    raise ValueError(f"step configuration: {name} does not fit its 16-bit word")
        return cls(arithmetic, c, sc, int(adc_bits), cfg_i, cfg_v, fq)


@dataclass(eq=False)
class OnlineSteps:
    """Records of the on-line algorithm: one per final foot-flat, in one arithmetic.

    Indices are sample indices of the input (``-1`` = not found); values are raw fixed point (lengths UQ2.14
    m, excursions UQ0.16 m, M4's range Q2.16 g) or floats (m, m, g).

    Attributes
    ----------
    end, duration, toe_off, heel_strike, flags
        ``(n,)`` int64: the foot-flat ending the step, its window in samples (0 = no window), the toe-off
        after the window start, the heel-strike before the end, the ``gaitlog.protocol.steps.StepFlag`` bits.
    lengths
        ``(n, 5)`` M1-M5.
    extras
        ``(n, 4)`` h (M1), h (M2), h1 (M3), M4's range.
    """

    arithmetic: str
    sampling_rate_hz: float
    calibrated: bool
    end: np.ndarray
    duration: np.ndarray
    toe_off: np.ndarray
    heel_strike: np.ndarray
    flags: np.ndarray
    lengths: np.ndarray
    extras: np.ndarray
    formats: KernelFormats = KernelFormats()

    @classmethod
    def empty(cls, arithmetic: str, sampling_rate_hz: float, calibrated: bool) -> OnlineSteps:
        """No record."""
        z = np.zeros(0, np.int64)
        dt = np.int64 if arithmetic == "fixed" else np.float64
        return cls(arithmetic, float(sampling_rate_hz), bool(calibrated), z, z.copy(), z.copy(), z.copy(), z.copy(),
                   np.zeros((0, 5), dt), np.zeros((0, 4), dt))

    @property
    def n_steps(self) -> int:
        """Number of records."""
        return int(self.end.size)

    def __len__(self) -> int:
        return self.n_steps

    def __repr__(self) -> str:
        lengths = "calibrated" if self.calibrated else "raw"
        return (f"OnlineSteps({self.n_steps} records, {self.arithmetic} arithmetic at {self.sampling_rate_hz:g} Hz, "
                f"{lengths} lengths)")

    def shifted(self, offset: int) -> OnlineSteps:
        """The same records with every index moved by ``offset`` samples (``-1`` stays ``-1``)."""
        mv = lambda x: np.where(x >= 0, x + offset, -1)  # noqa: E731
        return replace(self, end=self.end + offset, toe_off=mv(self.toe_off), heel_strike=mv(self.heel_strike))

    @staticmethod
    def concatenate(parts: list[OnlineSteps]) -> OnlineSteps:
        """Records of several blocks or runs, in order (same arithmetic)."""
        if not parts:
            raise ValueError("nothing to concatenate")
        first = parts[0]
        return replace(first, **{k: np.concatenate([getattr(p, k) for p in parts])
                                 for k in ("end", "duration", "toe_off", "heel_strike", "flags", "lengths", "extras")})

    def length_m(self) -> np.ndarray:
        """``(n, 5)`` lengths in metres (fixed point converted; 0 stays 0)."""
        return (self.formats.q("step_frac_bits").to_float(self.lengths) if self.arithmetic == "fixed"
                else np.asarray(self.lengths, float))

    def excursion_m(self) -> np.ndarray:
        """``(n, 3)`` vertical excursions h (M1), h (M2), h1 (M3) in metres."""
        x = self.extras[:, :3]
        if self.arithmetic != "fixed":
            return np.asarray(x, float)
        return np.column_stack([self.formats.q("excursion_frac_bits").to_float(x[:, 0]),
                                self.formats.q("excursion2_frac_bits").to_float(x[:, 1:])])

    def range_g(self) -> np.ndarray:
        """``(n,)`` M4's range of the 3 Hz vertical acceleration, g."""
        x = self.extras[:, 3]
        return self.formats.lowpass_q.to_float(x) if self.arithmetic == "fixed" else np.asarray(x, float)

    def has_flag(self, flag: StepFlag) -> np.ndarray:
        """``(n,)`` bool: records with ``flag`` set."""
        return (self.flags & int(flag)) != 0

    def to_records(self, first_sample_number: int) -> np.ndarray:
        """The records as the device stores them (:data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`; CRC not yet set).

        ``first_sample_number`` is the absolute sample number (PROTOCOL.md section 2) of input index 0.
        Fixed point only: the device's lengths are the raw UQ2.14 integers.
        """
        if self.arithmetic != "fixed":
            raise ValueError("only fixed-point records are the device's (the float arithmetic has no record format)")
        rec = empty_step_records(self.n_steps)
        window = self.duration > 0
        start = self.end - self.duration
        rec["end_sample"] = first_sample_number + self.end
        rec["duration_samples"] = self.duration
        rec["toe_off_samples"] = np.where(window & (self.toe_off >= 0), self.toe_off - start, 0)
        rec["heel_strike_samples"] = np.where(self.heel_strike >= 0, self.heel_strike - self.end,
                                              HEEL_STRIKE_NOT_FOUND)
        rec["flags"] = self.flags
        for i, name in enumerate(STEP_LENGTH_FIELDS):
            rec[name] = self.lengths[:, i]
        return rec

    @classmethod
    def from_records(cls, records: np.ndarray, *, first_sample_number: int, sampling_rate_hz: float) -> OnlineSteps:
        """Device records (:data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`) as fixed-point :class:`OnlineSteps`,
        indices counted from absolute sample ``first_sample_number`` (excursions and ranges are not stored:
        zero)."""
        r = np.asarray(records)
        end = r["end_sample"].astype(np.int64) - int(first_sample_number)
        dur = r["duration_samples"].astype(np.int64)
        flags = r["flags"].astype(np.int64)
        to_rel = r["toe_off_samples"].astype(np.int64)
        hs_rel = r["heel_strike_samples"].astype(np.int64)
        toe_off = np.where((dur > 0) & (to_rel > 0), end - dur + to_rel, -1)
        heel_strike = np.where(hs_rel != HEEL_STRIKE_NOT_FOUND, end + hs_rel, -1)
        lengths = np.column_stack([r[name].astype(np.int64) for name in STEP_LENGTH_FIELDS]) if r.size else \
            np.zeros((0, 5), np.int64)
        calibrated = not bool(np.all(flags & int(StepFlag.UNCALIBRATED))) if r.size else True
        return cls("fixed", float(sampling_rate_hz), calibrated, end, dur, toe_off, heel_strike, flags, lengths,
                   np.zeros((r.size, 4), np.int64))


@dataclass
class CycleStats:
    """PIC cycles the kernel counted (fixed point): per sample, mean and worst, and the main loop's backlog.

    ``worst_backlog`` is the most work (cycles) the algorithm still owed when a sample arrived, with the
    configured cycles per sample period; divided by that budget it is how many samples it lagged behind
    the sampling interrupt at worst.
    """

    total: int = 0
    worst: int = 0
    samples: int = 0
    worst_sample: int = -1
    worst_backlog: int = 0

    @property
    def mean(self) -> float:
        """Mean cycles per sample."""
        return self.total / max(1, self.samples)


class OnlineStepAlgorithm:
    """The firmware's on-line step algorithm (one run at a time; :meth:`reset` is START).

    Parameters
    ----------
    sampling_rate_hz
        The logger's sampling rate.
    step_config
        Leg and foot length, K constants (:class:`gaitlog.protocol.steps.StepConfig`).
    calibration
        Device calibration (a :class:`gaitlog.protocol.header.CalibrationSlot`) or None for the nominal map.
    arithmetic
        ``"fixed"`` (the PIC's, as the logger computes it) or ``"float"``.
    adc_bits, events, online, cycles_available, formats
        See :meth:`OnlineConfig.build`.

    Attributes
    ----------
    config
        The :class:`OnlineConfig`.
    cycles
        :class:`CycleStats` of everything fed so far (fixed point; not meaningful in float).
    compiled_by
        ``"aot"`` (the kernel compiled ahead of time, :mod:`gaitlog.firmware_sim.algorithms.aot_kernel`), ``"jit"``, or
        ``"variant"`` (other formats or rounding: :mod:`gaitlog.firmware_sim.algorithms.format_kernel`'s module in the
        compile cache, or its JIT).
    """

    def __init__(self, *, sampling_rate_hz: float, step_config: StepConfig, calibration: object | None = None,
                 arithmetic: str = "fixed", adc_bits: int = 10, events: EventParameters | None = None,
                 online: OnlineParameters | None = None, cycles_available: float | None = None,
                 formats: KernelFormats | None = None) -> None:
        self.config = OnlineConfig.build(sampling_rate_hz=sampling_rate_hz, step_config=step_config,
                                         calibration=calibration, arithmetic=arithmetic, adc_bits=adc_bits,
                                         events=events, online=online, cycles_available=cycles_available,
                                         formats=formats)
        c = self.config.counts
        dt = self.config.value_dtype
        self._st_i = np.zeros(N_INDICES, np.int64)
        self._st_v = np.zeros(N_VALUES, dt)
        self._line = np.zeros(2 * c.r3 + 1, dt)
        self._durs = np.zeros(c.median_steps, np.int64)
        self._scr = np.zeros(int(self.config.cfg_i[kernel.CI_SCRATCH]), dt)
        self._wear = np.zeros(kernel.SCRATCH_PAGES, np.int64)
        self._tails: list[np.ndarray] = []
        self._cnt = new_counters()
        self._cyc = np.zeros(6, np.int64)
        self._fed = 0                # samples fed since the last reset (the driver's count; the kernel's N is 16-bit)
        if self.arithmetic == "fixed" and not self.config.formats.compiled_shipped:
            (self._process, self._flush, self._reset), self.compiled_by = (
                format_kernel.entry_points(self.config.formats), "variant")
        else:
            (self._process, self._flush, self._reset), self.compiled_by = aot_kernel.entry_points(self.arithmetic)
        self.reset()

    @property
    def arithmetic(self) -> str:
        """``"fixed"`` or ``"float"``."""
        return self.config.arithmetic

    @property
    def sampling_rate_hz(self) -> float:
        """The sampling rate."""
        return self.config.counts.sampling_rate_hz

    @property
    def samples_seen(self) -> int:
        """Samples fed since the last :meth:`reset`."""
        return self._fed

    @property
    def cycles(self) -> CycleStats:
        """Cycles counted by the fixed-point primitives and the kernel's I/O, since construction."""
        return CycleStats(int(self._cyc[0]), int(self._cyc[1]), int(self._cyc[2]), int(self._cyc[3]),
                          int(self._cyc[5]))

    @property
    def scratch_page_writes(self) -> np.ndarray:
        """Page writes to each 128-byte page of the scratch ring (:data:`~gaitlog.firmware_sim.algorithms.kernel.
        SCRATCH_PAGES` pages from the step EEPROM's second block) since construction: what the pages' write-cycle
        counters (the 24LC1025's endurance) count."""
        return self._wear.copy()

    @property
    def scratch_tail_samples(self) -> np.ndarray:
        """The scratch ring's tail writes since construction (the PIC's partial page writes of the newest
        ``N mod FLUSH`` a_v before a step record that reads them, and at STOP; ``kernel._scratch_tail``), each
        as the samples its run had then: also in :attr:`scratch_page_writes`, on the page the next flush
        rewrites."""
        return np.concatenate([np.zeros(0, np.int64), *self._tails])

    def _count_page_writes(self, blocks: np.ndarray) -> None:
        """One write cycle on the page of each flush block ``k`` of the run (``2 CI_FLUSH`` bytes from byte
        ``2 CI_FLUSH k`` of the ring, modulo its length): a flush writes the whole block, a tail write its
        start."""
        unit = kernel.SCRATCH_SAMPLE_BYTES * int(self.config.cfg_i[kernel.CI_FLUSH])
        np.add.at(self._wear, unit * np.asarray(blocks, np.int64) % kernel.SCRATCH_RING_BYTES // PAGE_BYTES, 1)

    def _count_flushes(self, fed_before: int, fed_after: int) -> None:
        """The kernel's scratch flushes while the run went from ``fed_before`` to ``fed_after`` samples (one
        after every ``CI_FLUSH`` samples of the run)."""
        flush = int(self.config.cfg_i[kernel.CI_FLUSH])
        self._count_page_writes(np.arange(fed_before // flush, fed_after // flush))

    def _count_tails(self, out_i: np.ndarray, k: int, fed_before: int) -> None:
        """The tail writes before the kernel's records ``out_i[:k]``, made while the run went on from
        ``fed_before`` samples (by at most :data:`BLOCK_SAMPLES`): their 16-bit ``N`` made the run's count."""
        n16 = out_i[:k, kernel.O_TAIL]
        n16 = n16[n16 > 0]
        n = fed_before + ((n16 - fed_before) & INDEX_MASK)
        self._tails.append(n)
        self._count_page_writes(n // int(self.config.cfg_i[kernel.CI_FLUSH]))

    def arithmetic_context(self) -> ArithmeticContext:
        """Calls, cycles, saturations, wraps and divisions by zero since construction."""
        ctx = ArithmeticContext()
        cnt = self._cnt.copy()
        cnt[C_CYCLES] = 0
        ctx.absorb(cnt, "online")
        return ctx

    @property
    def saturations(self) -> int:
        """Elements saturated since construction (plus divisions by zero)."""
        return int(self._cnt[C_SAT])

    @property
    def wraps(self) -> int:
        """Elements wrapped since construction."""
        return int(self._cnt[C_WRAP])

    @property
    def divisions_by_zero(self) -> int:
        """Divisions by zero since construction."""
        return int(self._cnt[C_DIV0])

    def ram_bytes(self) -> int:
        """The algorithm's RAM on the PIC for this configuration (:func:`gaitlog.firmware_sim.algorithms.state.ram_bytes`)."""
        c = self.config.counts
        return ram_bytes(line_length=2 * c.r3 + 1, median_steps=c.median_steps)

    def variables(self):
        """The declared state variables for this configuration."""
        c = self.config.counts
        return variables(line_length=2 * c.r3 + 1, median_steps=c.median_steps, formats=self.config.formats)

    def state_values(self) -> np.ndarray:
        """A copy of the kernel's value state (slots of :data:`gaitlog.firmware_sim.algorithms.state.VALUE_SLOTS`:
        raw fixed point or floats), as it is between two samples (an observer's view; the run is not touched)."""
        return self._st_v.copy()

    def newest_vertical_acceleration(self) -> int | float:
        """The a_v of the last sample fed (the delay line's newest entry; 0 before the first)."""
        pos = int(self._st_i[LINE_POS_SLOT])
        return self._line[(pos - 1) % self._line.size].item()

    def reset(self) -> None:
        """START: forget the previous run."""
        self._reset(self.config.cfg_i, self._st_i, self._st_v, self._line, self._durs)
        self._scr[:] = 0
        self._fed = 0

    def _steps(self, out_i: np.ndarray, out_v: np.ndarray, k: int, offset: int) -> OnlineSteps:
        """The kernel's records as :class:`OnlineSteps`: its 16-bit end index made absolute from the samples fed
        (as the firmware makes the record's 32-bit ``end_sample`` from its sample counter), the toe-off and heel
        strike from their offsets."""
        sc = self.config.step_config
        end = self._fed - 1 - ((self._st_i[_N_SLOT] - 1 - out_i[:k, 0]) & INDEX_MASK)
        duration, to_rel, hs_rel, flags = (out_i[:k, c].copy() for c in range(1, 5))
        toe_off = np.where(to_rel >= 0, end - duration + to_rel, -1)
        heel_strike = np.where(flags & int(StepFlag.NO_HEEL_STRIKE), -1, end + hs_rel)
        s = OnlineSteps(self.arithmetic, self.sampling_rate_hz, bool(sc.calibrated), end, duration, toe_off,
                        heel_strike, flags, out_v[:k, :5].copy(), out_v[:k, 5:].copy(), self.config.formats)
        if not sc.calibrated:
            s.flags |= int(StepFlag.UNCALIBRATED)
        return s.shifted(offset) if offset else s

    def _outputs(self, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        rows = n_samples // max(1, self.config.counts.min_step) + 4
        return np.zeros((rows, len(kernel.OUT_I)), np.int64), np.zeros((rows, len(kernel.OUT_V)), self._st_v.dtype)

    def feed(self, codes: np.ndarray, *, offset: int = 0) -> OnlineSteps:
        """Process a block of ``(n, 3)`` ADC codes of the current run; return the records it finished.

        Indices of the records count from the run's first sample, plus ``offset``.
        """
        c = np.asarray(codes)
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(f"codes must have shape (n, 3), got {c.shape}")
        top = (1 << max(10, self.config.adc_bits)) - 1
        if c.size and (c.min() < 0 or c.max() > top):
            raise ValueError(f"ADC codes must be 0 .. {top}")
        parts = []
        for a in range(0, c.shape[0], BLOCK_SAMPLES):
            block = c[a:a + BLOCK_SAMPLES]
            out_i, out_v = self._outputs(block.shape[0])
            k = self._process(np.ascontiguousarray(block, dtype=self._st_v.dtype), self.config.cfg_i,
                              self.config.cfg_v, self._st_i, self._st_v, self._line, self._durs, self._scr, out_i,
                              out_v, 0, self._cnt, self._cyc)
            self._count_flushes(self._fed, self._fed + block.shape[0])
            self._count_tails(out_i, k, self._fed)
            self._fed += block.shape[0]
            parts.append(self._steps(out_i, out_v, k, offset))
        if len(parts) == 1:
            return parts[0]
        return OnlineSteps.concatenate(parts) if parts else self._steps(*self._outputs(0), 0, offset)

    def flush(self, *, offset: int = 0) -> OnlineSteps:
        """STOP: the pending foot-flat becomes final; return its record (if any)."""
        out_i, out_v = self._outputs(0)
        k = self._flush(self.config.cfg_i, self.config.cfg_v, self._st_i, self._st_v, self._scr, out_i, out_v, 0,
                        self._cnt)
        self._count_tails(out_i, k, self._fed)
        return self._steps(out_i, out_v, k, offset)

    def run(self, codes: np.ndarray, *, run_starts: np.ndarray | None = None) -> OnlineSteps:
        """A whole recording: each run (from each index of ``run_starts``, default ``[0]``) starts with
        :meth:`reset` and ends with :meth:`flush`, as on the logger. Indices count from the first sample.

        The records do not depend on how the samples are split into blocks.
        """
        c = np.asarray(codes)
        starts = np.unique(np.concatenate([[0], np.asarray(run_starts if run_starts is not None else [], np.int64)]))
        starts = starts[(starts >= 0) & (starts < max(c.shape[0], 1))]
        bounds = np.append(starts, c.shape[0])
        parts = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            self.reset()
            parts.append(self.feed(c[int(a):int(b)], offset=int(a)))
            parts.append(self.flush(offset=int(a)))
        if not parts:
            return OnlineSteps.empty(self.arithmetic, self.sampling_rate_hz, self.config.step_config.calibrated)
        return OnlineSteps.concatenate(parts)


def step_algorithm_for(header: DeviceHeader, *, fosc_hz: float = DEFAULT_FOSC_HZ) -> OnlineStepAlgorithm | None:
    """The on-line step algorithm as the firmware sets it up at START from its header (sampling rate, ADC
    width, calibration slot, step configuration; fixed point), or None when the header turns it off. The
    host's replay (:mod:`gaitlog.host.files.replay`) uses the same, so device and replay cannot be set up
    differently (:class:`gaitlog.firmware_sim.firmware.Firmware` takes it from here)."""
    if not header.step_config.enabled:
        return None
    sampling_rate_hz = header.sampling_rate_hz
    return OnlineStepAlgorithm(sampling_rate_hz=sampling_rate_hz, step_config=header.step_config,
                               calibration=header.calibration, arithmetic="fixed", adc_bits=header.adc_bits,
                               cycles_available=algorithm_cycles_per_sample(sampling_rate_hz, fosc_hz))


def load_kernels(arithmetics: tuple[str, ...] = ("fixed",)) -> None:
    """Load the compiled kernels now (building them if the cache is cold: seconds, once per version of the
    sources), so that a device served in real time answers START without that delay."""
    cfg = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
    for arithmetic in arithmetics:
        OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg, arithmetic=arithmetic).run(
            np.full((8, 3), 512, np.int64))
