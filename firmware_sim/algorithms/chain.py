"""The fixed-point step chain: 10-bit ADC codes -> per-step table (mirrors ``host.gait.pipeline``).

1. Calibration in fixed point (:class:`~firmware_sim.algorithms.calibration.CalibrationQ`).
2. Vertical acceleration from the moving-mean gravity (:func:`~.axes.vertical_acceleration_q`).
3. Events (:class:`~.events.FixedGaitEventDetector`).
4. One row per foot-flat, the step that ends there, windows and toe-off/heel-strike rules exactly as the
   float :class:`host.gait.pipeline.StepPipeline`; M1-M5 in integers (:mod:`.pendulum`,
   :mod:`.two_phase`, :mod:`.weinberg`, :mod:`.cadence`).

Every primitive call is counted in one :class:`~firmware_sim.fixedpoint.ArithmeticContext` (``ctx_``):
saturations, wraps, divisions by zero, and the estimated PIC cycles, from which ``cycles_per_sample_``
(compare with 100,000 at 50 Hz).

The result :class:`FixedStepTable` carries the integers (``*_q``) and their SI views with the same names
and meaning as the float ``StepTable`` fields (``table_fields()`` gives exactly the keyword arguments of
``host.gait.pipeline.StepTable``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np

from firmware_sim.algorithms.axes import vertical_acceleration_q
from firmware_sim.algorithms.cadence import CadenceM5Q, cadence_q
from firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from firmware_sim.algorithms.events import FixedGaitEventDetector
from firmware_sim.algorithms.formats import M5_Q, STEP_Q
from firmware_sim.algorithms.integration import step_samples_q, vertical_positions_q
from firmware_sim.algorithms.pendulum import PendulumDriftM2Q, PendulumM1Q, scale_by_k
from firmware_sim.algorithms.two_phase import TwoPhasePendulumM3Q
from firmware_sim.algorithms.weinberg import WeinbergM4Q
from firmware_sim.fixedpoint import ArithmeticContext

__all__ = ["FixedStepChain", "FixedStepTable", "nominal_calibration_q"]

ESTIMATORS = ("M1", "M2", "M3", "M4", "M5")


@dataclass(eq=False)
class FixedStepTable:
    """One row per detected step (ending at a foot-flat); indices are samples, ``-1`` = none.

    The float fields mirror ``host.gait.pipeline.StepTable``; ``length_q`` / ``raw_q`` / ``excursion_q``
    hold the integers (UQ2.14 m lengths, UQ0.16 m excursions, Q15.16 Hz cadence for raw M5, 0 where the
    float view is NaN).
    """

    sampling_rate_hz: float
    t0_s: float
    foot_flat: np.ndarray
    heel_strike: np.ndarray
    toe_off: np.ndarray
    start: np.ndarray
    bout: np.ndarray
    duration_s: np.ndarray
    n_missing: np.ndarray
    vertical_excursion_m: dict[str, np.ndarray] = field(default_factory=dict)
    acc_range_m_s2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    raw_m: dict[str, np.ndarray] = field(default_factory=dict)
    length_m: dict[str, np.ndarray] = field(default_factory=dict)
    excursion_q: dict[str, np.ndarray] = field(default_factory=dict)
    raw_q: dict[str, np.ndarray] = field(default_factory=dict)
    length_q: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of rows."""
        return int(self.foot_flat.size)

    def table_fields(self) -> dict[str, Any]:
        """Keyword arguments of ``host.gait.pipeline.StepTable`` (the float table type)."""
        return {k: getattr(self, k) for k in (
            "sampling_rate_hz", "t0_s", "foot_flat", "heel_strike", "toe_off", "start", "bout", "duration_s",
            "n_missing", "vertical_excursion_m", "acc_range_m_s2", "raw_m", "length_m")}


class FixedStepChain:
    """The firmware's step chain in fixed point: ADC codes -> :class:`FixedStepTable`.

    Parameters
    ----------
    leg_length_m, foot_length_m
        Anatomical inputs of M1-M3 (quantised to UQ1.15 m).
    calibration
        Per-subject constants with the attributes of ``host.estimators.calibration.KCalibration``
        (``k_m1``, ``k_m2``, ``k_m4``, ``k1_m5_m_s``, ``k2_m5_m``), or None: then M1/M2 use K = 1 and M4/M5
        are NaN, as in the float chain.
    detector
        Event detector (default parameters when None).
    gravity_window_s
        Window of the moving-mean gravity.

    Attributes
    ----------
    acc_q_, acc_v_q_, valid_
        Calibrated force (raw Q2.13 g, ``(n, 3)``), vertical acceleration (``(n,)``), validity.
    events_, steps_
        The fitted :class:`~.events.FixedGaitEventDetector` and the :class:`FixedStepTable`.
    ctx_
        The :class:`~firmware_sim.fixedpoint.ArithmeticContext` of the run.
    cycles_per_sample_
        Estimated PIC cycles per input sample.

    Examples
    --------
    >>> fs = 50.0; t = np.arange(int(20 * fs)) / fs
    >>> acc_g = np.zeros((t.size, 3))
    >>> acc_g[:, 2] = 1.0 - 0.02 * (2 * np.pi * 2.0) ** 2 * np.cos(2 * np.pi * 2.0 * t) / 9.80665
    >>> codes = np.clip(np.floor(acc_g * 256 + 512), 0, 1023).astype(int)
    >>> ch = FixedStepChain(leg_length_m=0.9, foot_length_m=0.26).run(codes, sampling_rate_hz=fs)
    >>> ch.steps_.n_steps in (38, 39, 40), ch.ctx_.report()
    (True, '')
    >>> round(float(np.nanmedian(ch.steps_.vertical_excursion_m["M2"])), 4)   # h = 4 cm, 10-bit codes
    0.0394
    """

    def __init__(
        self,
        *,
        leg_length_m: float,
        foot_length_m: float,
        calibration: Any | None = None,
        detector: FixedGaitEventDetector | None = None,
        gravity_window_s: float = 4.0,
    ) -> None:
        self.leg_length_m = leg_length_m
        self.foot_length_m = foot_length_m
        self.calibration = calibration
        self.detector = detector
        self.gravity_window_s = gravity_window_s

    def run(
        self,
        codes: np.ndarray,
        *,
        sampling_rate_hz: float,
        adc_calibration: CalibrationQ | None = None,
        valid: np.ndarray | None = None,
        t0_s: float = 0.0,
    ) -> Self:
        """Run the chain on ``(n, 3)`` ADC codes (0..1023; up to 4095 with a 12-bit calibration) sampled at
        ``sampling_rate_hz``.

        ``adc_calibration`` is the device's calibration (:class:`CalibrationQ`; the nominal 10-bit map
        when None, ``nominal_calibration_q(adc_bits=...)`` for other widths); ``valid`` marks the samples
        that were received (lost samples are never used).
        """
        c = np.asarray(codes)
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(f"codes must have shape (n, 3), got {c.shape}")
        fs = float(sampling_rate_hz)
        if not (np.isfinite(fs) and fs > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        n = c.shape[0]
        ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
        if ok.shape != (n,):
            raise ValueError(f"valid must have shape ({n},), got {ok.shape}")
        ctx = ArithmeticContext()
        cal = adc_calibration if adc_calibration is not None else nominal_calibration_q(adc_bits=10)
        self.acc_q_ = np.zeros((n, 3), np.int64)       # lost samples carry no code and are never used
        self.acc_q_[ok] = cal.apply(c[ok], ctx=ctx)
        av, _, ok2 = vertical_acceleration_q(self.acc_q_, sampling_rate_hz=fs, valid=ok,
                                             gravity_window_s=self.gravity_window_s, ctx=ctx)
        self.acc_v_q_, self.valid_ = av, ok2
        det = self.detector if self.detector is not None else FixedGaitEventDetector()
        det = FixedGaitEventDetector(**{k: getattr(det, k) for k in vars(det) if not k.endswith("_")})
        self.events_ = det.detect(av, sampling_rate_hz=fs, valid=ok2, ctx=ctx)
        self.steps_ = self._table(av, ok2, fs, t0_s, ctx)
        self.ctx_ = ctx
        self.cycles_per_sample_ = ctx.cycles_per_sample(n)
        return self

    def _table(self, av: np.ndarray, ok: np.ndarray, fs: float, t0_s: float,
               ctx: ArithmeticContext) -> FixedStepTable:
        ev = self.events_
        ff = ev.foot_flat_
        m = ff.size
        start = np.full(m, -1, np.int64)
        toe = np.full(m, -1, np.int64)
        if m > 1:
            linked = ev.bout_[1:] == ev.bout_[:-1]
            start[1:] = np.where(linked, ff[:-1], -1)
            toe[1:] = np.where(linked, ev.toe_off_[:-1], -1)
        hs = ev.heel_strike_
        toe = np.where((toe > start) & ((hs < 0) | (toe < hs)), toe, -1)
        w = np.flatnonzero(start >= 0)
        s_w, e_w = start[w], ff[w]
        leg, foot = self.leg_length_m, self.foot_length_m
        cal = self.calibration
        k1 = cal.k_m1 if cal is not None else 1.0
        k2 = cal.k_m2 if cal is not None else 1.0
        ss = step_samples_q(s_w, e_w, ok)
        ctx.cost("load_eeprom_sample", ss.index.size)   # M2's second pass reads a_v back from the EEPROM
        common = dict(step_start=s_w, step_end=e_w, valid=ok, ctx=ctx,
                      positions=(ss, vertical_positions_q(av, ss, ctx=ctx)))  # integrated once for M1-M3
        m1 = PendulumM1Q(k=1.0).estimate(av, sampling_rate_hz=fs, leg_length_m=leg, **common)
        m2 = PendulumDriftM2Q(k=1.0).estimate(av, sampling_rate_hz=fs, leg_length_m=leg, **common)
        m3 = TwoPhasePendulumM3Q().estimate(av, step_toe_off=toe[w], step_heel_strike=np.where(hs[w] > s_w, hs[w], -1),
                                            sampling_rate_hz=fs, leg_length_m=leg, foot_length_m=foot, **common)
        m4 = WeinbergM4Q(k=1.0).estimate(
            ev.first_harmonic_q_, step_start=s_w, step_end=e_w, defined=ev.first_harmonic_defined_, ctx=ctx)
        t_samples = e_w - s_w
        cad_q = cadence_q(t_samples, fs, ctx=ctx)

        def spread(x: np.ndarray, fill: float | int = np.nan) -> np.ndarray:
            out = np.full(m, fill, dtype=np.float64 if isinstance(fill, float) else np.int64)
            out[w] = x
            return out

        n_missing = np.zeros(m, np.int64)
        duration = np.full(m, np.nan)
        if w.size:
            duration[w] = t_samples / fs
            cm = np.concatenate([[0], np.cumsum(~ok)])
            n_missing[w] = cm[e_w + 1] - cm[s_w]
        # raw (K = 1) values: M1/M2/M3 lengths, M4 (g0 r)^(1/4) in m with K' = g0^(1/4), M5 cadence
        raw_q = {"M1": spread(m1.step_length_q_, 0), "M2": spread(m2.step_length_q_, 0),
                 "M3": spread(m3.step_length_q_, 0), "M4": spread(m4.step_length_q_, 0),
                 "M5": spread(cad_q, 0)}
        raw_m = {"M1": spread(m1.step_length_m_), "M2": spread(m2.step_length_m_), "M3": spread(m3.step_length_m_),
                 "M4": spread(m4.step_length_m_), "M5": spread(M5_Q.to_float(cad_q))}
        nan = np.full(m, np.nan)
        if cal is None:
            length_q = {"M1": raw_q["M1"].copy(), "M2": raw_q["M2"].copy(), "M3": raw_q["M3"].copy(),
                        "M4": np.zeros(m, np.int64), "M5": np.zeros(m, np.int64)}
            length_m = {"M1": raw_m["M1"].copy(), "M2": raw_m["M2"].copy(), "M3": raw_m["M3"].copy(),
                        "M4": nan.copy(), "M5": nan.copy()}
        else:
            l1 = scale_by_k(m1.step_length_q_, k1, ctx=ctx)
            l2 = scale_by_k(m2.step_length_q_, k2, ctx=ctx)
            l4 = WeinbergM4Q(k=cal.k_m4).estimate(ev.first_harmonic_q_, step_start=s_w, step_end=e_w,
                                                  defined=ev.first_harmonic_defined_, ctx=ctx)
            m5 = CadenceM5Q(k1_m_s=cal.k1_m5_m_s, k2_m=cal.k2_m5_m).estimate(step_samples=t_samples,
                                                                           sampling_rate_hz=fs, ctx=ctx)
            length_q = {"M1": spread(np.where(m1.impossible_, 0, l1), 0),
                        "M2": spread(np.where(m2.impossible_, 0, l2), 0),
                        "M3": raw_q["M3"].copy(), "M4": spread(l4.step_length_q_, 0),
                        "M5": spread(m5.step_length_q_, 0)}
            length_m = {"M1": spread(np.where(m1.impossible_, np.nan, STEP_Q.to_float(l1))),
                        "M2": spread(np.where(m2.impossible_, np.nan, STEP_Q.to_float(l2))),
                        "M3": raw_m["M3"].copy(), "M4": spread(l4.step_length_m_), "M5": spread(m5.step_length_m_)}
        return FixedStepTable(
            fs, float(t0_s), ff, hs.copy(), toe, start, ev.bout_.copy(), duration, n_missing,
            {"M1": spread(m1.vertical_excursion_m_), "M2": spread(m2.vertical_excursion_m_),
             "M3": spread(m3.single_support_excursion_m_)},
            spread(m4.acc_range_m_s2_), raw_m, length_m,
            {"M1": spread(m1.excursion_q_, 0), "M2": spread(m2.excursion_q_, 0), "M3": spread(m3.excursion_q_, 0)},
            raw_q, length_q,
        )
