"""A parameter grid over the simulated logger (``gaitlog sweep``): ADC bits x sampling rate x sensor noise x
Q formats of the fixed-point chain x mounting misalignment x simulated population x subjects x seeds, as
independent tasks, each deterministic from its seed.

**Tasks.** One task is one subject of one seed and population (``random_subjects(n_subjects, seed=seed,
population=population)[i]``, walking with seed ``seed * 1000 + i`` the protocol with the population's walk
habits, as :class:`gaitlog.host.studies.evaluation.SimulatedEvaluation`), its logger tilted by
``misalignment_deg`` more than the subject's own mounting (a pitch about the trunk's medio-lateral axis,
composed with the subject's rotation), sampled at one rate with one noise density, quantised at one ADC width,
and its fixed-point chain compiled with one set of Q formats
(:class:`gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`, by label: ``shipped``,
``acc10-lp12``...). Its work is the comparison of :func:`gaitlog.host.studies.compare.compare_walk` (ideal,
offline, on-line float and on-line fixed-point chains, one K per calibration mode fitted on the offline chain,
used by all four), as ``gaitlog compare --simulate`` runs it for one configuration. A task depends on nothing
but its own fields, so it gives the same rows in any process, in any order, on any machine: 1 worker, N
workers, a remote cluster or a resumed run agree exactly (the tests check it).

The expensive part, rendering the walk and the sensor's analog response, depends on the subject and seed only;
a process keeps the last :data:`WALK_MEMO_SIZE` rendered walks (:func:`analog_walk`), so the tasks of one
subject run by one worker render its walk once. The memo changes no result, only the time.

**Rows.** :func:`run_task` returns plain JSON-able rows: ``sections`` (one per configuration x subject x
evaluated 20 m section x calibration mode x estimator: the section ratio estimated / real of every chain) and
``splits`` (one per configuration x subject x share x estimator: the per-step error split ADC = offline -
ideal, algorithm = online-float - offline, arithmetic = online-fixed - online-float, mm), and ``task``, the
per-task scalars (step-timing error, fixed-point saturation).

**Q formats.** The fixed-point chain's formats are compile-time constants of the numba kernel; a set other
than the shipped one is the same kernel text JIT-compiled with other fraction bits
(:mod:`gaitlog.firmware_sim.algorithms.format_kernel`, ~10 s once per worker process and set), the shipped set runs the
kernel built ahead of time. Only the on-line fixed-point chain depends on them: the arithmetic share (online-fixed
- online-float) is the error they cause. :func:`smallest_q_formats` answers, per variable swept alone, the
coarsest fraction bits keeping every estimator within 1 mm per step and 1 % per 20 m section of float.

**Rounding** (``rounding``: ``shipped``, a mode for every operation class, or e.g. ``mul:truncate+div:convergent``)
is compiled into the fixed-point kernel with the Q formats (:class:`KernelFormats`); like them it changes only the
on-line fixed-point chain. A task at the shipped rounding keeps the name it had before rounding was a dimension.

**Theory and cost.** Each task also predicts its ADC and arithmetic shares from ``q^2/12`` carried through the
estimators (:func:`predicted_step_errors_mm`, :mod:`gaitlog.host.studies.quantisation_theory`), and the summary puts
each configuration's cost in ``gaitlog budget``'s model beside its accuracy (:func:`configuration_cost`).
:func:`smallest_formats` answers, per converter setting, Q-format set and rounding, the smallest ADC width holding
both shares, measured and as the theory predicts it.

**M5 and the rate** (Alvarez et al. left open whether M5's spread comes from timing steps at 50 Hz; M5 is
``K1 / T + K2`` with ``T`` counted in samples, so timing enters M5 alone). :func:`m5_rate_answer`, the project's
one answer to it: the part of M5's section-ratio spread that the sampled step timing
adds (``sqrt(var(sampled T) - var(exact T))``, the same K) per rate, and the lowest rate from which it stays
within 1 %.

**The converter and the sensor** (:data:`EFFECT_DIMENSIONS`, each 0 = off by default): INL, DNL, offset and
gain error of the converter (LSB of the swept width), its acquisition time (sequential sampling: the channel
skew; µs) and the source impedance it charges through (the settling error; with an acquisition time only), the
sensor's 1/f corner and a temperature swing (a linear ramp from 25 °C to 25 °C + swing over the walk, the
ADXL202E's typical temperature coefficients with signs seeded by the subject's sensor). Each subject wears its
own device: the INL/DNL curve and the coefficients' signs are seeded with its sensor's seed. The ideal chain
keeps the simultaneous, unquantised input: the converter's effects land in the ADC share (offline - ideal); the
sensor's in every chain (and in the section ratios against the real distance). The device calibration takes the
converter's offset and gain error in, as a pose calibration would (:meth:`gaitlog.host.studies.compare.SampledWalk.
calibration`); the drift and the nonlinearity are left. :func:`dimensions` lists every dimension, sweepable or
not yet (``gaitlog sweep --list-dimensions``).

**M4's exponent** (``m4_exponent``, p in ``S = K (a_max - a_min)^p``: whole eighths up to 1/2, what the step
configuration stores, :data:`M4_EXPONENTS`; default 1/4, Weinberg's) is M4's estimator throughout the task: the
offline chains' raw M4, the one K per mode fitted on them, and the on-line algorithm's step configuration (byte 20,
in eighths; the task's ``step_config`` is that block as the fixed-point run used it, hex). The other estimators
do not depend on it.

**Spec files.** :meth:`SweepGrid.from_spec` reads a JSON or TOML mapping with the keys of :data:`SPEC_KEYS`
(lists or single values); anything else is an error naming the key.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import itertools
import json
import math
import threading
import tomllib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.firmware_sim.algorithms import formats
from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.firmware_sim.budget import LoggerConfig, logging_cycles_per_sample, ram_budget
from gaitlog.firmware_sim.fixedpoint import QFormat, cycles_per_sample_available
from gaitlog.firmware_sim.adc import (
    ADXL202_OUTPUT_RESISTANCE_OHM,
    DEFAULT_SAMPLING_RATE_HZ,
    DATASHEET_SOURCE_IMPEDANCE_OHM,
    pic_acquisition_time_s,
)
from gaitlog.firmware_sim.sensor import (
    ADXL202_OFFSET_TEMPCO_G_PER_C,
    ADXL202_SENSITIVITY_TEMPCO_PER_C,
    REFERENCE_TEMPERATURE_C,
    SensorModel,
    TemperatureProfile,
    datasheet_tempcos,
)
from gaitlog.firmware_sim.world.walk_plan import POPULATION_PLANS, WalkPlan
from gaitlog.host.errors import HostError
from gaitlog.host.gait.sections import MODES
from gaitlog.host.studies.compare import CHAINS, SHARES, column_key, compare_walk, pair_label
from gaitlog.host.studies.quantisation_theory import (
    adc_sigma_m,
    adc_vertical_variance_m2_s4,
    arithmetic_sigma_m,
    median_abs_of_mixture,
)
from gaitlog.host.studies.simulation import AnalogWalk, simulated_population
from gaitlog.protocol.adc_bits import MAX_SIMULATED_ADC_BITS, check_adc_bits
from gaitlog.protocol.steps import M4_EXPONENT_EIGHTHS_MAX

#: The default grid's ADC widths, bits, and logger rates, Hz (half, once and twice the logger's 50 Hz).
ADC_BITS = (8, 10, 12)
RATES_HZ = (DEFAULT_SAMPLING_RATE_HZ / 2, DEFAULT_SAMPLING_RATE_HZ, DEFAULT_SAMPLING_RATE_HZ * 2)
#: The sensor's own white-noise density (ADXL202E typical), g/√Hz.
SENSOR_NOISE_G_RTHZ: float = next(f.default for f in fields(SensorModel) if f.name == "noise_density_g_rthz")
#: Walking protocols: the paper's (10 min, 12 laps of 20 m at four speeds) and a short one for quick looks and
#: tests (four 40 m corridors with short rests).
PROTOCOLS: dict[str, WalkPlan | None] = {
    "paper": None,
    "short": WalkPlan(corridor_length_m=40.0, rest_s=8.0, lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 80.0)),
}
#: The simulated population when the grid names none (that of :func:`gaitlog.host.studies.simulation.simulated_population`).
DEFAULT_POPULATION: str = inspect.signature(simulated_population).parameters["population"].default
#: Largest extra mounting tilt, degrees.
MAX_MISALIGNMENT_DEG = 45.0
#: M4's exponents a step configuration stores (whole eighths up to 1/2).
M4_EXPONENTS = tuple(e / 8 for e in range(1, M4_EXPONENT_EIGHTHS_MAX + 1))
#: Largest spec file read, bytes.
MAX_SPEC_BYTES = 1 << 20
#: Rendered walks kept per process (:func:`analog_walk`).
WALK_MEMO_SIZE = 2
#: The converter's and the sensor's effects (module notes): grid field -> (meaning, unit, largest magnitude).
EFFECT_DIMENSIONS: dict[str, tuple[str, str, float]] = {
    "inl_lsb": ("converter INL, peak of the seeded bow (PIC16F877: < 1)", "LSB", 8.0),
    "dnl_lsb": ("converter DNL, seeded code-width jitter (PIC16F877: < 1)", "LSB", 1.0),
    "adc_offset_lsb": ("converter offset error (PIC16F877: < ±2)", "LSB", 16.0),
    "adc_gain_error_lsb": ("converter gain error (PIC16F877: < ±1)", "LSB", 16.0),
    "acquisition_time_us": ("acquisition time before each channel's conversion: sequential sampling, the channel "
                            "skew (0: simultaneous; data sheet example "
                            f"{pic_acquisition_time_s(DATASHEET_SOURCE_IMPEDANCE_OHM) * 1e6:.2f})", "µs", 1000.0),
    "source_impedance_ohm": ("source impedance the hold capacitor charges through: the settling error (with an "
                             f"acquisition time; ADXL202 unbuffered: {ADXL202_OUTPUT_RESISTANCE_OHM:g})", "Ω", 1e6),
    "source_capacitance_nf": ("capacitance at the pin behind the source impedance (0: none; ADXL202 unbuffered: its "
                              "filter capacitor, 250 for 20 Hz)", "nF", 1e4),
    "flicker_corner_hz": ("sensor 1/f noise corner (0: white noise only)", "Hz", 100.0),
    "temperature_swing_c": (f"temperature ramp over the walk from {REFERENCE_TEMPERATURE_C:g} °C, ADXL202E typical "
                            f"drift ({ADXL202_OFFSET_TEMPCO_G_PER_C * 1e3:g} mg/°C, "
                            f"{ADXL202_SENSITIVITY_TEMPCO_PER_C * 100:.3f} %/°C)", "°C", 100.0),
}
#: Keys of a spec file and their meaning.
SPEC_KEYS = {
    "adc_bits": "ADC widths, bits",
    "sampling_rate_hz": "logger sampling rates, Hz",
    "noise_density_g_rthz": "sensor white-noise densities, g/√Hz",
    "q_formats": "Q-format sets of the fixed-point chain (shipped, or e.g. acc10-lp12-wstep15: fraction bits of "
                 "acc, grav, lp, m2pos, sq, fir, kern, exc, excc, root, step, k, kw, cad, mant, leg, twoleg, parg, "
                 "pargc; w+name: a format's word (wacc12, wgrav24, wvel, wpos, wcode ...); lpint: the lowpass's "
                 "integer bits; --list-dimensions)",
    "rounding": "rounding of the fixed-point chain per operation class (mul, shift, div): shipped, truncate, "
                "half-up, convergent, or per class, e.g. mul:truncate+div:convergent; shipped: half-up (a quotient's "
                "magnitude: ties away from zero)",
    "misalignment_deg": "extra mounting tilts of the logger (pitch), degrees",
    "m4_exponent": f"M4's exponents p in S = K (a_max - a_min)^p, as the step configuration stores them "
                   f"({', '.join(f'{e:g}' for e in M4_EXPONENTS)}; Weinberg's {M4_EXPONENT:g})",
    "population": f"simulated populations ({', '.join(POPULATION_PLANS)})",
    **{k: f"{v[0]}, {v[1]}" for k, v in EFFECT_DIMENSIONS.items()},
    "subjects": "simulated subjects per seed",
    "seeds": "seeds of the subject draws",
    "estimators": f"estimators kept in the rows ({', '.join(ESTIMATORS)})",
    "protocol": f"walking protocol ({', '.join(PROTOCOLS)})",
}
#: Section-ratio columns of a ``sections`` row (the chains and the exact-timing offline chain).
RATIO_KINDS = tuple(column_key(c) for c in CHAINS) + ("exact_timing",)
#: Configuration columns, first in every row.
CONFIG_COLUMNS = ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "q_formats", "misalignment_deg",
                  "population", "protocol", "seed", *EFFECT_DIMENSIONS, "rounding", "m4_exponent")
#: The configuration columns a summary row is grouped by (the others are pooled).
SUMMARY_KEYS = ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "q_formats", "misalignment_deg",
                "population", *EFFECT_DIMENSIONS, "rounding", "m4_exponent")
SECTION_COLUMNS = CONFIG_COLUMNS + ("subject", "excursion", "speed_label", "section", "real_m", "mode", "estimator") \
    + tuple(f"ratio_{k}" for k in RATIO_KINDS)
SPLIT_COLUMNS = CONFIG_COLUMNS + ("subject", "share", "pair", "estimator", "n", "median_abs_mm", "p95_abs_mm",
                                  "max_abs_mm", "bias_mm", "max_rel", "n_different_events", "theory_median_abs_mm")
SUMMARY_COLUMNS = (SUMMARY_KEYS + ("mode", "estimator", "n_subjects", "n_sections")
                   + tuple(f"{q}_{k}" for k in RATIO_KINDS[:-1] for q in ("median", "iqr"))
                   + ("subject_median_offline_lo", "subject_median_offline_hi", "adc_ratio_abs_max",
                      "adc_step_mm", "arith_ratio_abs_max", "arith_step_mm", "arith_step_mm_lo", "arith_step_mm_hi",
                      "adc_step_mm_lo", "adc_step_mm_hi", "adc_step_mm_theory", "arith_step_mm_theory",
                      "ram_bytes", "cycles_per_sample", "cpu_load"))
#: The quantisation question's tolerances: per-step ``|offline - ideal|`` median and section-ratio difference.
STEP_TOLERANCE_MM = 1.0
RATIO_TOLERANCE = 0.01


@dataclass(frozen=True)
class SweepTask:
    """One subject x one configuration (module notes); everything the task's result depends on."""

    seed: int
    subject_index: int
    n_subjects: int
    adc_bits: int
    sampling_rate_hz: float
    noise_density_g_rthz: float
    protocol: str
    estimators: tuple[str, ...]
    calibration_sections: int = 2
    q_formats: str = "shipped"
    misalignment_deg: float = 0.0
    population: str = DEFAULT_POPULATION
    inl_lsb: float = 0.0
    dnl_lsb: float = 0.0
    adc_offset_lsb: float = 0.0
    adc_gain_error_lsb: float = 0.0
    acquisition_time_us: float = 0.0
    source_impedance_ohm: float = 0.0
    source_capacitance_nf: float = 0.0
    flicker_corner_hz: float = 0.0
    temperature_swing_c: float = 0.0
    rounding: str = "shipped"
    m4_exponent: float = M4_EXPONENT

    @property
    def group(self) -> tuple:
        """The walk this task samples: tasks of one group share its rendering (:func:`analog_walk`)."""
        return (self.seed, self.subject_index, self.n_subjects, self.protocol, self.population, self.misalignment_deg)

    @property
    def key(self) -> str:
        """A file-name-safe name, unique for the task's fields (readable part + hash of all fields; the effects
        of :data:`EFFECT_DIMENSIONS` only when on, so the tasks of an earlier grid keep their names)."""
        text = json.dumps({k: v for k, v in asdict(self).items() if k not in _DEFAULTS or v != _DEFAULTS[k]},
                          sort_keys=True)
        digest = hashlib.sha256(text.encode()).hexdigest()[:12]
        rounding = "" if self.rounding == "shipped" else f"{self.rounding.replace(':', '.')}-"
        m4 = "" if self.m4_exponent == M4_EXPONENT else f"p{round(8 * self.m4_exponent)}of8-"
        return (f"seed{self.seed}-s{self.subject_index}-{self.adc_bits}b-{self.sampling_rate_hz:g}Hz-"
                f"n{self.noise_density_g_rthz:g}-{self.q_formats}-{rounding}{m4}"
                f"{effects_label(asdict(self), sep='-')}{digest}")

    def effects(self) -> dict[str, float]:
        """The values of :data:`EFFECT_DIMENSIONS`."""
        return {k: getattr(self, k) for k in EFFECT_DIMENSIONS}


@dataclass(frozen=True)
class SweepGrid:
    """The grid (module notes); :meth:`tasks` lists its tasks in a fixed order."""

    adc_bits: tuple[int, ...] = ADC_BITS
    sampling_rate_hz: tuple[float, ...] = RATES_HZ
    noise_density_g_rthz: tuple[float, ...] = (SENSOR_NOISE_G_RTHZ,)
    q_formats: tuple[str, ...] = ("shipped",)
    misalignment_deg: tuple[float, ...] = (0.0,)
    population: tuple[str, ...] = (DEFAULT_POPULATION,)
    inl_lsb: tuple[float, ...] = (0.0,)
    dnl_lsb: tuple[float, ...] = (0.0,)
    adc_offset_lsb: tuple[float, ...] = (0.0,)
    adc_gain_error_lsb: tuple[float, ...] = (0.0,)
    acquisition_time_us: tuple[float, ...] = (0.0,)
    source_impedance_ohm: tuple[float, ...] = (0.0,)
    source_capacitance_nf: tuple[float, ...] = (0.0,)
    flicker_corner_hz: tuple[float, ...] = (0.0,)
    temperature_swing_c: tuple[float, ...] = (0.0,)
    rounding: tuple[str, ...] = ("shipped",)
    m4_exponent: tuple[float, ...] = (M4_EXPONENT,)
    subjects: int = 4
    seeds: tuple[int, ...] = (0,)
    estimators: tuple[str, ...] = ESTIMATORS
    protocol: str = "paper"
    calibration_sections: int = field(default=2, repr=False)

    def __post_init__(self) -> None:
        for b in self.adc_bits:
            check_adc_bits(b, max_bits=MAX_SIMULATED_ADC_BITS, what="ADC bits", error=HostError)
        for name in ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "q_formats", "misalignment_deg",
                     "population", "seeds", "estimators", "rounding", "m4_exponent", *EFFECT_DIMENSIONS):
            if not getattr(self, name):
                raise HostError(f"sweep grid: {name} is empty")
        self._canonical_fixed_point()
        for m in self.misalignment_deg:
            if not (math.isfinite(m) and abs(m) <= MAX_MISALIGNMENT_DEG):
                raise HostError(f"sweep grid: misalignment {m:g} degrees outside ±{MAX_MISALIGNMENT_DEG:g}")
        unknown_pop = [p for p in self.population if p not in POPULATION_PLANS]
        if unknown_pop:
            raise HostError(f"sweep grid: unknown population(s) {', '.join(unknown_pop)}; known: "
                            f"{', '.join(POPULATION_PLANS)}")
        for name in ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "q_formats", "misalignment_deg",
                     "population", "seeds", "rounding", "m4_exponent", *EFFECT_DIMENSIONS):
            values = getattr(self, name)
            if len(set(values)) != len(values):
                raise HostError(f"sweep grid: {name} lists a value twice")
        self._check_m4_exponents()
        for r in self.sampling_rate_hz:
            if not (math.isfinite(r) and 10.0 <= r <= 1000.0):
                raise HostError(f"sweep grid: sampling rate {r:g} Hz outside 10-1000 Hz")
        for n in self.noise_density_g_rthz:
            if not (math.isfinite(n) and 0.0 <= n <= 0.01):
                raise HostError(f"sweep grid: noise density {n:g} g/√Hz outside 0-0.01")
        self._check_effects()
        if not 1 <= self.subjects <= 1000:
            raise HostError(f"sweep grid: subjects must be 1..1000, got {self.subjects}")
        unknown = [e for e in self.estimators if e not in ESTIMATORS]
        if unknown:
            raise HostError(f"sweep grid: unknown estimator(s) {', '.join(unknown)}; known: {', '.join(ESTIMATORS)}")
        if self.protocol not in PROTOCOLS:
            raise HostError(f"sweep grid: unknown protocol {self.protocol!r}; known: {', '.join(PROTOCOLS)}")

    def _canonical_fixed_point(self) -> None:
        """The Q-format sets and roundings by their canonical labels (a bad one: :class:`HostError`)."""
        try:
            labels = [KernelFormats.parse(q).label() for q in self.q_formats]
            roundings = [KernelFormats.parse("shipped", r).rounding_label() for r in self.rounding]
        except ValueError as err:
            raise HostError(f"sweep grid: {err}") from None
        object.__setattr__(self, "q_formats", tuple(labels))
        object.__setattr__(self, "rounding", tuple(roundings))

    def _check_m4_exponents(self) -> None:
        """M4's exponents among :data:`M4_EXPONENTS` (else :class:`HostError` naming them)."""
        for p in self.m4_exponent:
            if p not in M4_EXPONENTS:
                raise HostError(f"sweep grid: M4 exponent {p:g} is not one the step configuration stores "
                                f"({', '.join(f'{e:g}' for e in M4_EXPONENTS)})")

    def _check_effects(self) -> None:
        """:data:`EFFECT_DIMENSIONS` within their ranges (and those whose sign has no meaning not negative)."""
        for name, (_, unit, top) in EFFECT_DIMENSIONS.items():
            values = tuple(float(v) for v in getattr(self, name))
            object.__setattr__(self, name, values)
            signed = name in ("adc_offset_lsb", "adc_gain_error_lsb", "temperature_swing_c")
            for v in values:
                if not (math.isfinite(v) and (signed or v >= 0) and abs(v) <= top):
                    raise HostError(f"sweep grid: {name} {v:g} {unit} outside {'±' if signed else '0 .. '}{top:g}")

    @classmethod
    def from_spec(cls, spec: dict, *, source: str = "spec") -> SweepGrid:
        """A grid from a mapping with the keys of :data:`SPEC_KEYS` (scalars or lists; missing keys: defaults)."""
        unknown = sorted(set(spec) - set(SPEC_KEYS))
        if unknown:
            raise HostError(f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(SPEC_KEYS)}")
        kinds = {"adc_bits": int, "sampling_rate_hz": float, "noise_density_g_rthz": float, "seeds": int,
                 "estimators": str, "q_formats": str, "misalignment_deg": float, "population": str, "rounding": str,
                 "m4_exponent": float, **dict.fromkeys(EFFECT_DIMENSIONS, float)}
        kw: dict[str, Any] = {}
        for key, value in spec.items():
            try:
                if key in kinds:
                    values = value if isinstance(value, list) else [value]
                    if any(isinstance(v, bool) or isinstance(v, str) != (kinds[key] is str) for v in values):
                        raise ValueError(key)
                    kw[key] = tuple(kinds[key](v) for v in values)
                elif key == "subjects":
                    if isinstance(value, bool) or not isinstance(value, int):
                        raise ValueError(key)
                    kw[key] = value
                else:
                    kw[key] = str(value)
            except (TypeError, ValueError):
                raise HostError(f"{source}: {key} = {value!r} is not {SPEC_KEYS[key]}") from None
        try:
            return cls(**kw)
        except HostError as err:
            raise HostError(f"{source}: {err}") from None

    @classmethod
    def load(cls, path: str | Path) -> SweepGrid:
        """A grid from a ``.json`` or ``.toml`` spec file."""
        p = Path(path)
        try:
            if p.stat().st_size > MAX_SPEC_BYTES:
                raise HostError(f"{p}: {p.stat().st_size} bytes is too large for a sweep spec")
            text = p.read_text(encoding="utf-8")
        except OSError as err:
            raise HostError(f"{p}: cannot read: {err.strerror or err}") from None
        except UnicodeDecodeError:
            raise HostError(f"{p}: not a text file (a JSON or TOML spec is UTF-8 text)") from None
        try:
            spec = tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
        except (tomllib.TOMLDecodeError, json.JSONDecodeError, RecursionError) as err:
            raise HostError(f"{p}: not a valid {'TOML' if p.suffix.lower() == '.toml' else 'JSON'} spec: {err}") from None
        if not isinstance(spec, dict):
            raise HostError(f"{p}: a spec is a mapping of {', '.join(SPEC_KEYS)}")
        return cls.from_spec(spec, source=str(p))

    def to_spec(self) -> dict:
        """The spec mapping of this grid (:meth:`from_spec` of it gives it back)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items() if k in SPEC_KEYS}

    def tasks(self) -> list[SweepTask]:
        """Every task, seed by seed, population, misalignment and subject (the walk's order), then rate, noise,
        the converter's and sensor's effects, M4's exponent, rounding, Q formats and width."""
        return [SweepTask(seed, i, self.subjects, b, float(r), float(n), self.protocol, tuple(self.estimators),
                          self.calibration_sections, q, float(m), pop, **effects, rounding=rd, m4_exponent=float(p))
                for seed in self.seeds for pop in self.population for m in self.misalignment_deg
                for i in range(self.subjects) for r in self.sampling_rate_hz
                for n in self.noise_density_g_rthz for effects in self.effect_sets() for p in self.m4_exponent
                for rd in self.rounding for q in self.q_formats for b in self.adc_bits]

    def effect_sets(self) -> list[dict[str, float]]:
        """Every combination of the :data:`EFFECT_DIMENSIONS` values, in the grid's order."""
        return [dict(zip(EFFECT_DIMENSIONS, combo, strict=True))
                for combo in itertools.product(*(getattr(self, k) for k in EFFECT_DIMENSIONS))]


_WALKS: OrderedDict[tuple, AnalogWalk] = OrderedDict()
_WALKS_LOCK = threading.Lock()          # a threaded worker runs several tasks in one process


def walk_plan(protocol: str, population: str) -> WalkPlan | None:
    """The protocol walked with the population's habits (:data:`POPULATION_PLANS`; None: the paper's, ``v1``)."""
    plan, habits = PROTOCOLS[protocol], POPULATION_PLANS[population]
    if plan is None:
        return WalkPlan(**habits) if habits else None
    return replace(plan, **habits)


def misaligned(subject: Any, misalignment_deg: float) -> Any:
    """``subject`` with the logger tilted ``misalignment_deg`` more (a pitch about the trunk's medio-lateral
    axis, device ``y``, after the subject's own mounting rotation); the subject itself at 0."""
    if misalignment_deg == 0.0:
        return subject
    r = Rotation.from_rotvec([0.0, misalignment_deg, 0.0], degrees=True) * Rotation.from_rotvec(
        subject.mounting_rotation_deg, degrees=True)
    return replace(subject, mounting_rotation_deg=tuple(float(a) for a in r.as_rotvec(degrees=True)))


def analog_walk(seed: int, subject_index: int, n_subjects: int, protocol: str, population: str = DEFAULT_POPULATION,
                misalignment_deg: float = 0.0) -> tuple[Any, AnalogWalk]:
    """The subject and its rendered walk (module notes: a per-process memo of :data:`WALK_MEMO_SIZE` walks)."""
    key = (seed, subject_index, n_subjects, protocol, population, misalignment_deg)          # SweepTask.group
    with _WALKS_LOCK:
        walk = _WALKS.get(key)
        if walk is not None:
            _WALKS.move_to_end(key)
            return walk.subject, walk
    subjects, plan = simulated_population(n_subjects, seed=seed, population=population,
                                          walk_plan=walk_plan(protocol, population))
    subject = misaligned(subjects[subject_index], misalignment_deg)
    walk = AnalogWalk(subject=subject, seed=seed * 1000 + subject_index, walk_plan=plan).run()
    with _WALKS_LOCK:
        _WALKS[key] = walk
        while len(_WALKS) > WALK_MEMO_SIZE:
            _WALKS.popitem(last=False)
    return subject, walk


def _plain(v: Any) -> Any:
    """A JSON-able Python scalar of a numpy one."""
    if isinstance(v, np.generic):
        return v.item()
    return v


def run_task(task: SweepTask) -> dict:
    """The rows of one task (module notes): ``{"sections": [...], "splits": [...], "task": {...}}``."""
    subject, walk = analog_walk(task.seed, task.subject_index, task.n_subjects, task.protocol, task.population,
                                task.misalignment_deg)
    sensor_changes, converter = effects_of(task.effects(), walk)
    sw = walk.sample(task.sampling_rate_hz, noise_density_g_rthz=task.noise_density_g_rthz,
                     sensor_changes=sensor_changes, converter=converter)
    formats = KernelFormats.parse(task.q_formats, task.rounding)
    fixed = OnlineStepAlgorithm if formats.shipped else functools.partial(OnlineStepAlgorithm, formats=formats)
    result = compare_walk(sw, subject, adc_bits=task.adc_bits, calibration_sections=task.calibration_sections,
                          fixed_algorithm=fixed, m4_exponent=task.m4_exponent)
    fx = result.runs["online-fixed"]
    config = dict(adc_bits=task.adc_bits, sampling_rate_hz=task.sampling_rate_hz,
                  noise_density_g_rthz=task.noise_density_g_rthz, q_formats=task.q_formats,
                  misalignment_deg=task.misalignment_deg, population=task.population, protocol=task.protocol,
                  seed=task.seed, **task.effects(), rounding=task.rounding, m4_exponent=task.m4_exponent)
    keep = set(task.estimators)
    theory = predicted_step_errors_mm(sw, subject, result, task.adc_bits, formats, task.m4_exponent)
    sections = [config | {k: _plain(s[k]) for k in SECTION_COLUMNS if k in s and k not in config}
                for s in result.segments if s["estimator"] in keep]
    splits = [config | {"subject": subject.subject_id} | {k: _plain(d[k]) for k in SPLIT_COLUMNS if k in d}
              | {"theory_median_abs_mm": theory.get((d["share"], d["estimator"]), math.nan)}
              for d in result.step_diffs if d["estimator"] in keep]
    scalars = config | dict(subject=subject.subject_id, timing_rms_ms=_plain(result.timing["rms_ms"]),
                            saturated=int(fx.saturated), wrapped=int(fx.wrapped),
                            saturation=result.saturation, cycles_per_sample=_plain(fx.cycles_per_sample),
                            step_config=fx.step_config.hex())
    return {"sections": sections, "splits": splits, "task": scalars}


def predicted_step_errors_mm(sw: Any, subject: Any, result: Any, adc_bits: int, kernel_formats: KernelFormats,
                             m4_exponent: float = M4_EXPONENT) -> dict[tuple[str, str], float]:
    """The quantisation theory's median per-step ``|error|``, mm, of the ADC share and of the arithmetic share
    (:mod:`gaitlog.host.studies.quantisation_theory`), per estimator, over the offline chain's steps (multi-speed K;
    M4 with ``m4_exponent``): ``{(share, estimator): mm}``."""
    table = result.runs["offline"].tables["multi-speed"]
    cal = sw.calibration(adc_bits)
    var_av = adc_vertical_variance_m2_s4(cal, np.mean(cal.apply(sw.codes(adc_bits)), axis=0))
    adc = adc_sigma_m(table, var_av, leg_length_m=subject.leg_length_m, exponent=m4_exponent)
    arith, bias = arithmetic_sigma_m(table, leg_length_m=subject.leg_length_m, exponent=m4_exponent,
                                     **kernel_formats.theory_bits())
    out = {}
    for est in ESTIMATORS:
        out[("adc", est)] = 1e3 * median_abs_of_mixture(adc[est])
        out[("arithmetic", est)] = 1e3 * median_abs_of_mixture(arith[est], bias[est])
    return out


def effects_of(effects: dict[str, float], walk: AnalogWalk) -> tuple[dict[str, Any], dict[str, Any]]:
    """The sensor changes and the converter fields (:meth:`AnalogWalk.sample`) of a task's effects on ``walk``
    (module notes; empty when all are off; an effect missing from ``effects`` is off)."""
    effects = with_effects(effects)
    sensor: dict[str, Any] = {}
    if effects["flicker_corner_hz"]:
        sensor["flicker_corner_hz"] = effects["flicker_corner_hz"]
    if effects["temperature_swing_c"]:
        ref = REFERENCE_TEMPERATURE_C
        sensor.update(datasheet_tempcos(walk.sensor_.seed), temperature=TemperatureProfile.ramp(
            ref, ref + effects["temperature_swing_c"], walk.t_last_s_ - walk.t0_s_))
    converter = {k: effects[e] for k, e in (("inl_lsb", "inl_lsb"), ("dnl_lsb", "dnl_lsb"),
                                            ("offset_error_lsb", "adc_offset_lsb"),
                                            ("gain_error_lsb", "adc_gain_error_lsb"),
                                            ("source_impedance_ohm", "source_impedance_ohm")) if effects[e]}
    if effects["acquisition_time_us"]:
        converter["acquisition_time_s"] = effects["acquisition_time_us"] * 1e-6
    if effects["source_capacitance_nf"]:
        converter["source_capacitance_f"] = effects["source_capacitance_nf"] * 1e-9
    return sensor, converter


#: Short names of the effects in labels (:func:`effects_label`).
_EFFECT_SHORT = {"inl_lsb": "inl", "dnl_lsb": "dnl", "adc_offset_lsb": "off", "adc_gain_error_lsb": "gain",
                 "acquisition_time_us": "acq", "source_impedance_ohm": "rs", "source_capacitance_nf": "cs",
                 "flicker_corner_hz": "fc",
                 "temperature_swing_c": "dT"}


def effects_label(row: dict, *, sep: str = " ") -> str:
    """The effects that are on in ``row`` as ``inl1 dT25`` (each followed by ``sep`` when ``sep`` is ``-``;
    empty when none; ``-`` for a printed row without any)."""
    on = [f"{_EFFECT_SHORT[k]}{row[k]:g}" for k in EFFECT_DIMENSIONS if row.get(k, 0.0)]
    if sep == "-":
        return "".join(f"{x}-" for x in on)
    return sep.join(on) or "-"


#: The value of each later-added dimension that rows written before it had (:func:`with_effects`; a task's key
#: leaves a field at this value out, so earlier results folders resume).
_DEFAULTS: dict[str, Any] = {**dict.fromkeys(EFFECT_DIMENSIONS, 0.0), "rounding": "shipped",
                             "m4_exponent": M4_EXPONENT}


def with_effects(row: dict) -> dict:
    """``row`` with the :data:`EFFECT_DIMENSIONS` it lacks at 0 (off), the shipped rounding and the default M4
    exponent: rows of a results folder written before these were dimensions resume as what they were."""
    if all(k in row for k in _DEFAULTS):
        return row
    return _DEFAULTS | row


def _order(values: list) -> dict:
    """Position of each distinct value in order of first appearance (the grid's order)."""
    out: dict = {}
    for v in values:
        out.setdefault(v, len(out))
    return out


def reference(values: list | tuple, preferred: Any) -> Any:
    """``preferred`` when it is among ``values``, else the first of them (what the other figures and answers hold
    fixed while one dimension varies)."""
    return preferred if preferred in values else values[0]


def median_iqr(v: np.ndarray) -> tuple[float, float]:
    """Median and interquartile range of the finite values of ``v`` (NaN, NaN when there are none)."""
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return float(med), float(q3 - q1)


def _range(v: list[float]) -> tuple[float, float, float]:
    v = [x for x in v if math.isfinite(x)]
    return (float(np.median(v)), float(min(v)), float(max(v))) if v else (math.nan, math.nan, math.nan)


def summarise(sections: list[dict], splits: list[dict], tasks: list[dict] | None = None) -> list[dict]:
    """One row per configuration (:data:`SUMMARY_KEYS`), mode and estimator, pooled over seeds and subjects.

    ``median_<chain>`` / ``iqr_<chain>``: pooled 20 m section ratios; ``subject_median_offline_lo/hi``: the
    range over subjects of each subject's median offline ratio (the interval over subjects);
    ``adc_ratio_abs_max`` / ``arith_ratio_abs_max``: the largest per-section ``|offline - ideal|`` and
    ``|online-fixed - online-float|`` ratio; ``adc_step_mm`` / ``arith_step_mm``: median over subjects of the
    per-step median ``|offline - ideal|`` and ``|online-fixed - online-float|`` (multi-speed lengths), ``*_lo`` /
    ``*_hi`` their range over subjects; ``adc_step_mm_theory`` / ``arith_step_mm_theory`` the quantisation theory's
    prediction of the same medians (:func:`predicted_step_errors_mm`; NaN for results stored without it).
    ``ram_bytes``, ``cycles_per_sample``, ``cpu_load``: the configuration's cost in ``gaitlog budget``'s model
    (:func:`configuration_cost`, from the ``tasks`` rows' counted cycles; NaN without them).
    """
    sections, splits = [with_effects(r) for r in sections], [with_effects(r) for r in splits]
    labels = {s: pair_label(a, b) for s, (a, b) in SHARES.items()}
    q_order = _order([s["q_formats"] for s in sections])
    pop_order = _order([s["population"] for s in sections])
    groups: dict[tuple, list[dict]] = {}
    for s in sections:
        groups.setdefault(tuple(s[k] for k in SUMMARY_KEYS) + (s["mode"], s["estimator"]), []).append(s)
    split_groups: dict[tuple, list[dict]] = {}
    for d in splits:
        split_groups.setdefault(tuple(d[k] for k in SUMMARY_KEYS) + (d["pair"], d["estimator"]), []).append(d)
    cycles: dict[tuple, list[float]] = {}
    for t in map(with_effects, tasks or []):
        cycles.setdefault(tuple(t[k] for k in SUMMARY_KEYS), []).append(t.get("cycles_per_sample", math.nan))
    out = []
    r_order = _order([s["rounding"] for s in sections])
    for key in sorted(groups, key=lambda k: (k[1], k[2], k[4], pop_order[k[5]], k[6:-4], k[-3], r_order[k[-4]],
                                             q_order[k[3]], k[0], MODES.index(k[-2]), ESTIMATORS.index(k[-1]))):
        out.append(_summary_row(key, groups[key], split_groups, cycles, labels))
    return [{k: r[k] for k in SUMMARY_COLUMNS} for r in out]


def _summary_row(key: tuple, seg: list[dict], split_groups: dict[tuple, list[dict]],
                 cycles: dict[tuple, list[float]], labels: dict[str, str]) -> dict[str, Any]:
    """:func:`summarise`'s row of one configuration, mode and estimator (``key``) from its sections ``seg``."""
    *config, mode, est = key
    row: dict[str, Any] = dict(zip(SUMMARY_KEYS, config, strict=True))
    row.update(mode=mode, estimator=est, n_subjects=len({(s["seed"], s["subject"]) for s in seg}),
               n_sections=len(seg))
    ratio = {k: np.array([s[f"ratio_{k}"] for s in seg], float) for k in RATIO_KINDS}
    for k in RATIO_KINDS[:-1]:
        row[f"median_{k}"], row[f"iqr_{k}"] = median_iqr(ratio[k])
    per_subject = [median_iqr(np.array([s["ratio_offline"] for s in seg if (s["seed"], s["subject"]) == subj], float))[0]
                   for subj in sorted({(s["seed"], s["subject"]) for s in seg})]
    _, row["subject_median_offline_lo"], row["subject_median_offline_hi"] = _range(per_subject)
    for share, a, b in (("adc", "offline", "ideal"), ("arith", "online_fixed", "online_float")):
        d = ratio[a] - ratio[b]
        row[f"{share}_ratio_abs_max"] = float(np.nanmax(np.abs(d))) if np.isfinite(d).any() else math.nan
    for share, col in (("adc", "adc_step_mm"), ("arithmetic", "arith_step_mm")):
        found = split_groups.get(tuple(config) + (labels[share], est), [])
        row[col], row[f"{col}_lo"], row[f"{col}_hi"] = _range([x["median_abs_mm"] for x in found])
        row[f"{col}_theory"] = _range([x.get("theory_median_abs_mm", math.nan) for x in found])[0]
    row.update(configuration_cost(row["sampling_rate_hz"], _range(cycles.get(tuple(config), []))[0],
                                  row["q_formats"]))
    return row


def configuration_cost(sampling_rate_hz: float, cycles_per_sample: float,
                       q_formats: str = "shipped") -> dict[str, float]:
    """A configuration's cost in ``gaitlog budget``'s model (:mod:`gaitlog.firmware_sim.budget`): the logger's RAM
    at the rate with the algorithm's state in the words of ``q_formats`` (a :class:`KernelFormats` label:
    ``ram_bytes``, of the PIC16F877's 368; a narrower word saves whole bytes of the state variables, not of the
    temporaries), the on-line algorithm's mean cycles per sample as its fixed-point run counted them
    (``cycles_per_sample``: rounding modes and formats change the operations; a word of 16 bits or fewer is
    counted with the 16-bit additions), and the CPU load with the logging interrupt (``cpu_load``, 1 = every
    cycle of a sample period)."""
    logging = logging_cycles_per_sample(LoggerConfig("alvarez", float(sampling_rate_hz), 3))
    ram = ram_budget(sampling_rate_hz, formats=KernelFormats.parse(q_formats))
    return dict(ram_bytes=ram.total_bytes, cycles_per_sample=cycles_per_sample,
                cpu_load=(cycles_per_sample + logging) / cycles_per_sample_available(sampling_rate_hz))


def _within(r: dict, share: str) -> bool:
    """The share (``adc`` or ``arith``) within :data:`STEP_TOLERANCE_MM` per step and :data:`RATIO_TOLERANCE` per
    section (NaN: not within)."""
    return bool(r[f"{share}_step_mm"] <= STEP_TOLERANCE_MM and r[f"{share}_ratio_abs_max"] <= RATIO_TOLERANCE)


def _smallest(rows: list[dict], size: str, share: str | Callable[[dict], bool]) -> Any:
    """The smallest ``size`` from which on every larger one of ``rows`` is within the tolerances (``share``: ``adc``
    or ``arith`` per :func:`_within`, or a test of a row; None: none)."""
    holds = share if callable(share) else functools.partial(_within, share=share)
    best = None
    for r in sorted(rows, key=lambda r: r[size], reverse=True):
        if not holds(r):
            break
        best = r[size]
    return best


def smallest_adc_bits(summary: list[dict], *, mode: str = "multi-speed") -> list[dict]:
    """Per (rate, noise, misalignment, population, estimator): the smallest swept ADC width from which on every
    wider one the ADC share stays within :data:`STEP_TOLERANCE_MM` per step (median) and :data:`RATIO_TOLERANCE`
    per 20 m section (largest ``|offline - ideal|`` ratio); ``smallest_adc_bits`` is None when no swept width does.
    The ADC share does not involve the fixed-point chain: the rows of one Q-format set are used (the shipped one
    when swept)."""
    rows = [with_effects(r) for r in summary if r["mode"] == mode]
    if not rows:
        return []
    q = reference([r["q_formats"] for r in rows], "shipped")
    rd = reference([r["rounding"] for r in rows], "shipped")
    keys = ("sampling_rate_hz", "noise_density_g_rthz", "misalignment_deg", "population", *EFFECT_DIMENSIONS,
            "m4_exponent", "estimator")
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["q_formats"] == q and r["rounding"] == rd:
            groups.setdefault(tuple(r[k] for k in keys), []).append(r)
    return [dict(zip(keys, k, strict=True)) | dict(smallest_adc_bits=_smallest(g, "adc_bits", "adc"),
                                                  swept_bits="/".join(str(r["adc_bits"]) for r in g))
            for k, g in groups.items()]


#: What :func:`smallest_formats` reports at the width it names, measured and predicted (summary columns).
FORMAT_ERROR_COLUMNS = ("adc_step_mm", "adc_step_mm_theory", "arith_step_mm", "arith_step_mm_theory",
                        "adc_ratio_abs_max", "arith_ratio_abs_max")


def _predicted_within(r: dict) -> bool:
    """The quantisation theory's per-step medians of both shares within :data:`STEP_TOLERANCE_MM` (NaN: not)."""
    return bool(r["adc_step_mm_theory"] <= STEP_TOLERANCE_MM and r["arith_step_mm_theory"] <= STEP_TOLERANCE_MM)


def smallest_formats(summary: list[dict], *, mode: str = "multi-speed") -> list[dict]:
    """The smallest formats under a real converter: per converter/sensor setting, Q-format set, rounding (and rate,
    noise, misalignment, population) and estimator, the smallest swept ADC width from which on every wider one keeps
    both shares within the tolerances: the ADC share (offline - ideal, what the converter costs, its INL and DNL
    included) and the arithmetic share (online-fixed - online-float, what the Q formats and the rounding cost),
    each within :data:`STEP_TOLERANCE_MM` per step and :data:`RATIO_TOLERANCE` per 20 m section.

    Beside it, ``predicted_adc_bits``: the same answer from the quantisation theory's per-step predictions alone
    (``adc_step_mm_theory``, ``arith_step_mm_theory``; the theory has no section-ratio prediction, and models
    neither INL/DNL nor truncation's bias, so where these matter the two answers part). The measured and predicted
    errors (:data:`FORMAT_ERROR_COLUMNS`) are those at ``at_bits``: the measured answer, or the widest swept width
    when no width holds (``smallest_adc_bits`` None)."""
    rows = [with_effects(r) for r in summary if r["mode"] == mode]
    keys = ("sampling_rate_hz", "noise_density_g_rthz", "misalignment_deg", "population", *EFFECT_DIMENSIONS,
            "m4_exponent", "q_formats", "rounding", "estimator")
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in keys), []).append(r)
    out = []
    for k, g in groups.items():
        g = sorted(g, key=lambda r: r["adc_bits"])
        bits = _smallest(g, "adc_bits", lambda r: _within(r, "adc") and _within(r, "arith"))
        at = next(r for r in g if r["adc_bits"] == (g[-1]["adc_bits"] if bits is None else bits))
        out.append(dict(zip(keys, k, strict=True)) | dict(
            smallest_adc_bits=bits, predicted_adc_bits=_smallest(g, "adc_bits", _predicted_within),
            at_bits=at["adc_bits"], swept_bits="/".join(str(r["adc_bits"]) for r in g))
            | {c: at[c] for c in FORMAT_ERROR_COLUMNS})
    return out


def smallest_q_formats(summary: list[dict], *, mode: str = "multi-speed") -> list[dict]:
    """Per variable of :class:`KernelFormats` swept alone (the format sets that differ from the shipped one in that
    variable only, with the shipped set as its widest), per configuration and estimator: the fewest fraction
    bits from which on every wider swept one keeps the arithmetic share (online-fixed - online-float) within
    :data:`STEP_TOLERANCE_MM` per step and :data:`RATIO_TOLERANCE` per 20 m section. ``smallest_frac_bits``
    is None when no swept width does; the shipped width is then the one to keep (or widen)."""
    rows = [with_effects(r) for r in summary if r["mode"] == mode]
    shipped = KernelFormats()
    by_field: dict[str, dict[str, int]] = {}
    for label in _order([r["q_formats"] for r in rows]):
        f = KernelFormats.parse(label)
        differ = [n for n in KernelFormats.field_names() if getattr(f, n) != getattr(shipped, n)]
        alone = len(differ) == 1 and replace(f, **{differ[0]: getattr(shipped, differ[0])}).label() == "shipped"
        for n in differ if alone else (KernelFormats.field_names() if f.label() == "shipped" else ()):
            by_field.setdefault(n, {})[label] = getattr(f, n)
    keys = ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "misalignment_deg", "population",
            *EFFECT_DIMENSIONS, "rounding", "m4_exponent", "estimator")
    out = []
    for name, labels in by_field.items():
        if len(labels) < 2:
            continue
        groups: dict[tuple, list[dict]] = {}
        for r in rows:
            if r["q_formats"] in labels:
                groups.setdefault(tuple(r[k] for k in keys), []).append(r | {"frac_bits": labels[r["q_formats"]]})
        for k, g in groups.items():
            out.append(dict(zip(keys, k, strict=True)) | dict(
                variable=name, shipped_frac_bits=getattr(shipped, name), smallest_frac_bits=_smallest(g, "frac_bits", "arith"),
                swept_frac_bits="/".join(str(r["frac_bits"]) for r in sorted(g, key=lambda r: -r["frac_bits"]))))
    return out


def m5_rate_answer(sections: list[dict]) -> dict:
    """M5's section-ratio spread vs sample rate with the sampled and the world's exact step durations (the same K):
    ``timing_part = sqrt(var(sampled) - var(exact))`` is what the step timing adds; it stops mattering at the
    lowest swept rate from which on it stays within :data:`RATIO_TOLERANCE` in both calibration modes.

    The offline chain at one ADC width (10 bits when swept), the Q formats, noise, misalignment and population
    held at their reference (:func:`reference`). Returns ``{"rows": [...], "rate_hz": float | None, "verdict":
    str}``; a row per (mode, rate) with ``n``, ``iqr``, ``std``, ``iqr_exact``, ``std_exact``, ``timing_part``
    and ``timing_part_lo/hi``: its range over subjects (each subject's own sampled and exact spread).
    """
    m5 = [with_effects(s) for s in sections if s["estimator"] == "M5"]
    if not m5:
        return {"rows": [], "rate_hz": None, "verdict": ""}
    ref = {k: reference(list(_order([s[k] for s in m5])), p) for k, p in
           (("adc_bits", 10), ("q_formats", "shipped"), ("noise_density_g_rthz", SENSOR_NOISE_G_RTHZ),
            ("misalignment_deg", 0.0), ("population", DEFAULT_POPULATION), *((k, 0.0) for k in EFFECT_DIMENSIONS),
            ("rounding", "shipped"), ("m4_exponent", M4_EXPONENT))}
    m5 = [s for s in m5 if all(s[k] == v for k, v in ref.items())]
    rates = sorted({s["sampling_rate_hz"] for s in m5})
    rows = []
    for mode in MODES:
        for rate in rates:
            seg = [s for s in m5 if s["mode"] == mode and s["sampling_rate_hz"] == rate]
            if seg:
                rows.append(_m5_rate_row(seg, mode, rate) | ref)
    ok = {rate: all(r["timing_part"] <= RATIO_TOLERANCE for r in rows if r["sampling_rate_hz"] == rate)
          for rate in rates}
    rate_hz = None
    for rate in reversed(rates):
        if not ok[rate]:
            break
        rate_hz = rate
    return {"rows": rows, "rate_hz": rate_hz, "verdict": _m5_verdict(rates, rate_hz)}


def _m5_spread(seg: list[dict]) -> tuple[float, float, float, float, float, int]:
    """IQR and standard deviation of the sampled and of the exact-timing ratios of ``seg``, the timing part
    ``sqrt(var(sampled) - var(exact))`` and the number of finite pairs (NaNs below 3 pairs)."""
    a = np.array([s["ratio_offline"] for s in seg], float)
    e = np.array([s["ratio_exact_timing"] for s in seg], float)
    g = np.isfinite(a) & np.isfinite(e)
    a, e = a[g], e[g]
    if a.size < 3:
        return (math.nan,) * 5 + (int(a.size),)
    va, ve = float(np.var(a, ddof=1)), float(np.var(e, ddof=1))
    return (median_iqr(a)[1], math.sqrt(va), median_iqr(e)[1], math.sqrt(ve), math.sqrt(max(va - ve, 0.0)),
            int(a.size))


def _m5_rate_row(seg: list[dict], mode: str, rate: float) -> dict:
    """:func:`m5_rate_answer`'s row of one mode and rate from its sections ``seg`` (pooled, and per subject)."""
    iqr, std, iqr_e, std_e, part, n = _m5_spread(seg)
    subj = [_m5_spread([s for s in seg if (s["seed"], s["subject"]) == k])[4]
            for k in sorted({(s["seed"], s["subject"]) for s in seg})]
    _, lo, hi = _range(subj)
    return dict(mode=mode, sampling_rate_hz=rate, n=n, iqr=iqr, std=std, iqr_exact=iqr_e, std_exact=std_e,
                timing_part=part, timing_part_lo=lo, timing_part_hi=hi)


def _m5_verdict(rates: list[float], rate_hz: float | None) -> str:
    """The sentence of :func:`m5_rate_answer`: from which swept rate on the step timing stops mattering."""
    swept = "/".join(f"{r:g}" for r in rates)
    if rate_hz is None:
        return (f"M5's step-timing error matters at every swept rate ({swept} Hz): it adds more than "
                f"{100 * RATIO_TOLERANCE:g} % to M5's section-ratio spread")
    if rate_hz == rates[0]:
        return (f"M5's step-timing error does not matter from the lowest swept rate, {rate_hz:g} Hz, on (swept "
                f"{swept} Hz): it adds at most {100 * RATIO_TOLERANCE:g} % to M5's section-ratio spread")
    return (f"M5's step-timing error stops mattering at {rate_hz:g} Hz (swept {swept} Hz): from there on it "
            f"adds at most {100 * RATIO_TOLERANCE:g} % to M5's section-ratio spread")


def _q_label(r: dict) -> str:
    """A row's fixed-point chain: its Q formats, and its rounding when not the shipped one (``acc10/truncate``)."""
    rounding = r.get("rounding", "shipped")
    return r["q_formats"] + ("" if rounding == "shipped" else f"/{rounding}")


def format_summary(summary: list[dict], *, mode: str = "multi-speed") -> str:
    """Printed summary of one calibration mode: accuracy, the quantisation theory beside it, and the cost."""
    rows = [with_effects(r) for r in summary if r["mode"] == mode]
    width = max([12] + [len(effects_label(r)) + 1 for r in rows])
    qw = max([10] + [len(_q_label(r)) + 1 for r in rows])
    lines = [f"{mode} calibration (one K per configuration, fitted on its offline chain); section ratio "
             "estimated / real, pooled median and IQR; subj. range: subjects' median offline ratio; ADC mm / arith "
             "mm: per-step median |offline - ideal| / |online-fixed - online-float|, each with the quantisation "
             "theory's prediction beside it (theory: q^2/12 carried through the estimator); Q: fixed-point formats "
             "(/rounding when not the shipped), tilt: extra misalignment, deg; M4 p: M4's exponent; conv/sensor: the "
             "converter's and "
             "sensor's effects that are on; RAM B, cycles, load: the configuration's cost in gaitlog budget's model "
             "(RAM of 368 bytes, the algorithm's mean cycles per sample, CPU load with the logging)",
             f"{'bits':>4}{'Hz':>6}{'noise ug':>9} {'Q':<{qw}}{'tilt':>5}{'M4 p':>6} {'pop':<7}"
             f"{'conv/sensor':<{width}}{'est':<4}"
             f"{'subj':>5}{'n':>6}{'ideal':>8}{'offline':>8}{'IQR':>7}{'on-fx':>8}{'subj. range':>14}{'ADC max':>9}"
             f"{'ADC mm':>8}{'theory':>8}{'arith mm':>9}{'theory':>8}{'arith max':>10}{'RAM B':>6}{'cycles':>8}"
             f"{'load':>6}"]
    for r in rows:
        lines.append(f"{r['adc_bits']:>4}{r['sampling_rate_hz']:>6g}{1e6 * r['noise_density_g_rthz']:>9.0f} "
                     f"{_q_label(r):<{qw}}{r['misalignment_deg']:>5g}{r['m4_exponent']:>6g} {r['population']:<7}"
                     f"{effects_label(r):<{width}}{r['estimator']:<4}{r['n_subjects']:>5}{r['n_sections']:>6}"
                     f"{r['median_ideal']:>8.3f}{r['median_offline']:>8.3f}{r['iqr_offline']:>7.3f}"
                     f"{r['median_online_fixed']:>8.3f}"
                     f"{r['subject_median_offline_lo']:>7.3f}-{r['subject_median_offline_hi']:<6.3f}"
                     f"{r['adc_ratio_abs_max']:>9.4f}{r['adc_step_mm']:>8.3f}{r.get('adc_step_mm_theory', math.nan):>8.3f}"
                     f"{r['arith_step_mm']:>9.3f}{r.get('arith_step_mm_theory', math.nan):>8.3f}"
                     f"{r['arith_ratio_abs_max']:>10.4f}{r.get('ram_bytes', 0):>6}"
                     f"{r.get('cycles_per_sample', math.nan):>8.0f}{r.get('cpu_load', math.nan):>6.2f}")
    return "\n".join(lines)


def _held(r: dict) -> str:
    """A row's rate, noise, extra tilt and population, as printed."""
    return (f"{r['sampling_rate_hz']:g} Hz, noise {1e6 * r['noise_density_g_rthz']:.0f} ug/rtHz, tilt "
            f"{r['misalignment_deg']:g} deg, {r['population']}")


def _where(r: dict) -> str:
    effects = effects_label(r)
    rounding = r.get("rounding", "shipped")
    p = r.get("m4_exponent", M4_EXPONENT)
    return (_held(r) + (f", {effects}" if effects != "-" else "")
            + (f", rounding {rounding}" if rounding != "shipped" else "")
            + (f", M4 p {p:g}" if p != M4_EXPONENT else ""))


def format_smallest_bits(rows: list[dict]) -> str:
    """Printed answer: the smallest ADC width within the tolerances, per configuration and estimator."""
    lines = [f"smallest swept ADC width keeping the ADC share (offline - ideal) within {STEP_TOLERANCE_MM:g} mm per "
             f"step and {100 * RATIO_TOLERANCE:g} % per 20 m section (multi-speed K)"]
    for r in rows:
        b = r["smallest_adc_bits"]
        lines.append(f"  {_where(r)}, {r['estimator']}: {b if b is not None else 'none'} bits (swept {r['swept_bits']})")
    return "\n".join(lines)


def format_smallest_formats(rows: list[dict]) -> str:
    """Printed answer of :func:`smallest_formats`: per converter/sensor setting, fixed-point chain and estimator, the
    smallest ADC width measured and predicted, and the errors at it, measured beside predicted."""
    if not rows or all("/" not in r["swept_bits"] for r in rows):
        return ("smallest formats under the converter: only one ADC width swept (--adc-bits 8,9,10,11,12 asks which "
                "width each setting needs)")
    width = max([12] + [len(effects_label(r)) + 1 for r in rows])
    qw = max([12] + [len(_q_label(r)) + 1 for r in rows])
    lines = [f"smallest formats under the converter: the smallest swept ADC width from which on both the ADC share "
             f"(offline - ideal) and the arithmetic share (online-fixed - online-float) stay within "
             f"{STEP_TOLERANCE_MM:g} mm per step and {100 * RATIO_TOLERANCE:g} % per 20 m section (multi-speed K); "
             "theory: the width the quantisation theory's per-step predictions give (it models neither INL/DNL nor "
             "truncation's bias); at that width (the widest swept when none holds), per-step median |error| measured "
             "beside predicted, mm, and the largest section error, %",
             f"{'conv/sensor':<{width}}{'Q/rounding':<{qw}}{'est':<4}{'bits':>5}{'theory':>7}{'at':>4}"
             f"{'ADC mm':>8}{'theory':>8}{'arith mm':>9}{'theory':>8}{'ADC %':>7}{'arith %':>8}"]
    for r in rows:
        where = "" if len({_held(x) for x in rows}) == 1 else f"  ({_held(r)})"
        lines.append(f"{effects_label(r):<{width}}{_q_label(r):<{qw}}{r['estimator']:<4}"
                     f"{_bits_text(r['smallest_adc_bits']):>5}{_bits_text(r['predicted_adc_bits']):>7}"
                     f"{r['at_bits']:>4}{r['adc_step_mm']:>8.3f}{r['adc_step_mm_theory']:>8.3f}"
                     f"{r['arith_step_mm']:>9.3f}{r['arith_step_mm_theory']:>8.3f}"
                     f"{100 * r['adc_ratio_abs_max']:>7.2f}{100 * r['arith_ratio_abs_max']:>8.2f}{where}")
    return "\n".join(lines)


def _bits_text(bits: int | None) -> str:
    return "none" if bits is None else str(bits)


def format_smallest_q(rows: list[dict]) -> str:
    """Printed answer: per variable, the fewest fraction bits within the tolerances for every estimator."""
    if not rows:
        return ("Q formats: only one set per variable swept (--q-formats shipped,acc10,acc8,lp12... asks which "
                "fraction bits keep each estimator within tolerance)")
    lines = [f"fewest swept fraction bits keeping the arithmetic share (online-fixed - online-float) within "
             f"{STEP_TOLERANCE_MM:g} mm per step and {100 * RATIO_TOLERANCE:g} % per 20 m section (multi-speed K), "
             "each variable swept alone; all = what every estimator needs"]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["variable"], r["adc_bits"], r["sampling_rate_hz"], r["noise_density_g_rthz"],
                           r["misalignment_deg"], r["population"], *(r[k] for k in EFFECT_DIMENSIONS),
                           r.get("rounding", "shipped"), r.get("m4_exponent", M4_EXPONENT)), []).append(r)
    for (name, bits, *_), g in groups.items():
        need = [r["smallest_frac_bits"] for r in g]
        total = None if None in need else max(need)
        each = ", ".join(f"{r['estimator']} {r['smallest_frac_bits'] if r['smallest_frac_bits'] is not None else 'none'}"
                         for r in g)
        lines.append(f"  {name} (shipped {g[0]['shipped_frac_bits']}), {bits} bits, {_where(g[0])}: all "
                     f"{total if total is not None else 'none'} ({each}; swept {g[0]['swept_frac_bits']})")
    return "\n".join(lines)


def format_m5_rate(m5: dict) -> str:
    """Printed M5-vs-rate table and the answer."""
    if not m5["rows"]:
        return "M5: not in the estimators kept"
    r0 = m5["rows"][0]
    lines = [f"M5 (offline chain, {r0['adc_bits']} bits): pooled 20 m section ratios vs rate, with the sampled and "
             "the world's exact step durations (same K); timing = sqrt(var sampled - var exact), its range over "
             "subjects",
             f"{'mode':<13}{'Hz':>6}{'n':>5}{'IQR':>8}{'std':>8}{'IQR exact':>11}{'std exact':>11}{'timing':>8}"
             f"{'subjects':>16}"]
    for r in m5["rows"]:
        lines.append(f"{r['mode']:<13}{r['sampling_rate_hz']:>6g}{r['n']:>5}{r['iqr']:>8.4f}{r['std']:>8.4f}"
                     f"{r['iqr_exact']:>11.4f}{r['std_exact']:>11.4f}{r['timing_part']:>8.4f}"
                     f"{r['timing_part_lo']:>8.4f}-{r['timing_part_hi']:<7.4f}")
    lines.append(m5["verdict"])
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------------
# Every dimension of the question, sweepable or not yet (gaitlog sweep --list-dimensions)

#: The ``gaitlog sweep`` option of each grid key (the effects: ``--`` + the key with dashes).
OPTIONS = {"adc_bits": "--adc-bits", "sampling_rate_hz": "--logger-rate", "noise_density_g_rthz": "--noise-density",
           "q_formats": "--q-formats", "misalignment_deg": "--misalignment", "m4_exponent": "--m4-exponent",
           "population": "--population",
           "subjects": "--subjects", "seeds": "--seeds", "rounding": "--rounding",
           **{k: "--" + k.replace("_", "-") for k in EFFECT_DIMENSIONS}}
#: Units of the grid keys that are not effects.
_UNITS = {"adc_bits": "bits", "sampling_rate_hz": "Hz", "noise_density_g_rthz": "g/√Hz", "q_formats": "set",
          "misalignment_deg": "degrees", "m4_exponent": "1", "population": "name", "subjects": "count", "seeds": "seed",
          "rounding": "mode"}
#: Formats whose fraction bits are a_v's (:class:`KernelFormats`: the accumulators keep them).
_FOLLOWS_ACC = ("VELOCITY_Q", "POSITION_Q")


@dataclass(frozen=True)
class Dimension:
    """One dimension of a quantisation study: its name, unit, default, and the ``gaitlog sweep`` option that
    sweeps it (None: not yet sweepable)."""

    name: str
    unit: str
    default: str
    option: str | None
    what: str

    def line(self) -> str:
        """One printed line: name, unit, default, option or "not yet sweepable", meaning."""
        how = self.option if self.option is not None else "not yet sweepable"
        return f"{self.name:<28} {self.unit:<8} default {self.default:<22} {how:<26} {self.what}"


def _default_text(value: Any) -> str:
    values = value if isinstance(value, tuple) else (value,)
    return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in values)


def _format_dimensions() -> list[Dimension]:
    """Word and fraction bits of every Q format of :mod:`gaitlog.firmware_sim.algorithms.formats` (and of the
    centred codes, ``centred_q``), each with the ``--q-formats`` token that sweeps it (:class:`KernelFormats`)."""
    code = formats.centred_q(10)
    out = [Dimension("CENTRED_Q.word_bits", "bits", str(code.total_bits), "--q-formats wcodeN",
                     _word_meaning(code, "code_word_bits")),
           Dimension("CENTRED_Q.frac_bits", "bits", str(code.frac_bits), "--adc-bits",
                     "fraction bits of the centred codes and calibration offsets: 15 - max(10, ADC bits)")]
    for name in formats.__all__:
        q = getattr(formats, name)
        if not isinstance(q, QFormat):
            continue
        frac, word = KernelFormats.sweep_fields(q)
        if name == "LOWPASS_Q":
            out.append(Dimension(f"{name}.word_bits", "bits", str(KernelFormats().lowpass_word_bits), "--q-formats lpintN",
                                 f"word of {q} where it saturates: sign + N integer bits + fraction bits"))
        elif word is None:
            out.append(Dimension(f"{name}.word_bits", "bits", str(q.total_bits),
                                 f"--q-formats {KernelFormats.token(frac)}N",
                                 f"word of {q}: 1 + N fraction bits (block floating point: the shared exponent "
                                 "keeps the range)"))
        else:
            out.append(Dimension(f"{name}.word_bits", "bits", str(q.total_bits),
                                 f"--q-formats {KernelFormats.token(word)}N", _word_meaning(q, word)))
        follows = " (follows ACC_Q's)" if name in _FOLLOWS_ACC else ""
        out.append(Dimension(f"{name}.frac_bits", "bits", str(q.frac_bits), f"--q-formats {KernelFormats.token(frac)}N",
                             f"fraction bits of {q} (fewer than shipped only){follows}"))
    return out


def _word_meaning(q: QFormat, word_field: str) -> str:
    """The meaning of a word dimension: where its values saturate, how narrow it may be."""
    where = ("the configured values saturate" if KernelFormats.configuration_only(word_field)
             else "every value stored saturates")
    return f"word of {q}, sign included: {where} at N bits (2 .. its {q.word_bits}-bit container)"


def dimensions() -> list[Dimension]:
    """Every dimension of the question (module notes): the grid's (sweepable, with their default grid values; the
    rounding and M4's exponent among them) and the fixed-point chain's formats, each with the option that sweeps
    it."""
    grid = SweepGrid()
    out = []
    for key, option in OPTIONS.items():
        if key in EFFECT_DIMENSIONS:
            what, unit, _ = EFFECT_DIMENSIONS[key]
        else:
            what, unit = SPEC_KEYS[key], _UNITS[key]
        out.append(Dimension(key, unit, _default_text(getattr(grid, key)), option, what))
    out += _format_dimensions()
    return out


def format_dimensions() -> str:
    """The printed list of :func:`dimensions`, one a line, with a header line."""
    head = f"{'dimension':<28} {'unit':<8} {'default':<30} {'gaitlog sweep option':<26} meaning"
    return "\n".join([head] + [d.line() for d in dimensions()])
