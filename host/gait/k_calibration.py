"""Per-subject calibration of the estimators' constants (Alvarez et al. 2006, section III-IV).

* M1, M2, M4: ``K = real distance / distance estimated with K = 1`` on the calibration data (every section
  pooled: one section at preferred speed = single-speed, the first 40 m at every speed = multi-speed).
* M5: ``S = K1 / T + K2`` fitted by least squares through one (mean cadence, mean step length) point per
  calibration section (mean step length = real distance / steps, mean cadence = mean of ``1/T``).
  **Fallback** when the sections do not span speeds (fewer than two sections, or mean cadences within
  ``min_cadence_spread`` of each other, 5 %): the line cannot be identified, so K2 = 0 and K1 is fitted
  through the origin on the pooled data -- the *walk ratio* model (step length proportional to cadence,
  step length / cadence being nearly invariant across speeds in healthy adults: Sekiya & Nagasaki,
  Gait Posture 7, 1998). ``m5_fallback`` is True and ``notes`` says so.
* M3 has no constant.

*Calibrated range.* K is a ratio fitted on the steps of the calibration sections; it holds for steps like
those. :class:`KFit` stores the range of every quantity the fit saw (``calibrated_range``, the smallest and
largest positive value over the calibration steps with a window -- NaN when none was recorded, e.g. the
excursions in the logger's compact step records: step duration, the vertical excursions of M1 and M2,
M4's acceleration range, and the calibrated lengths of M1, M2, M4 and M5), and :meth:`KFit.outside_range`
says, per step of another walk and per estimator, when the step lies outside it (its K is then an
extrapolation: another speed, another step length). The commands write it as a column and count it.

:class:`KFit` saves/loads itself as versioned JSON (:class:`gaitlog.host.storage.versioned_json.VersionedJson`,
``format_version`` "1.3"; a "1.0" file, written before the calibrated range was stored, is read with
``calibrated_range`` None: nothing can then be said about the range; "1.0" and "1.1" files, written before
M4's exponent was stored, are read with ``m4_exponent`` 1/4, Weinberg's, which they were fitted with;
files before "1.3" have no ``shrinkage``: their K is the fitted one).

*Shrinkage.* A K fitted on one short walk may be shrunk toward the K of a population
(:meth:`gaitlog.host.gait.k_prior.KPrior.shrink`); ``shrinkage`` then records the fitted K, the population K and the
weights, and K is the shrunk one.

*M4's exponent.* ``k_m4`` is in m / (m/s^2)^p: it holds for the exponent it was fitted with
(``m4_exponent``). The offline chain applies it with that exponent (:func:`gaitlog.host.gait.pipeline.
apply_calibration`, from the step's range); the logger (on-line algorithm version 4) computes the exponent its
step configuration gives, whole eighths up to 1/2, so :meth:`KFit.step_constants` passes it on and refuses a K fitted
with another exponent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.protocol.steps import M4_EXPONENT_EIGHTHS_MAX
from gaitlog.host.errors import HostError
from gaitlog.host.storage.versioned_json import VersionedJson
from gaitlog.host.gait.sections import Section, pool_steps

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.firmware_sim.algorithms.steps import StepTable

#: The quantities of :attr:`KFit.calibrated_range` (names of the per-step CSV columns).
RANGE_QUANTITIES = ("duration_s", "h_m1_m", "h_m2_m", "acc_range_m4_m_s2", "length_m1_m", "length_m2_m",
                    "length_m4_m", "length_m5_m")
#: The keys of :attr:`KFit.shrinkage` (:meth:`gaitlog.host.gait.k_prior.KPrior.shrink`).
SHRINKAGE_KEYS = ("source", "fitted", "population", "weight", "prior_distance_m")
#: Per calibrated estimator, the quantities whose range its K holds for: the step duration (cadence: the
#: speed), the estimator's own input and its length.
RANGE_OF_ESTIMATOR = {"M1": ("duration_s", "h_m1_m", "length_m1_m"), "M2": ("duration_s", "h_m2_m", "length_m2_m"),
                      "M4": ("duration_s", "acc_range_m4_m_s2", "length_m4_m"), "M5": ("duration_s", "length_m5_m")}


def range_quantities(table: StepTable) -> dict[str, np.ndarray]:
    """Per step of ``table``, the quantities of :data:`RANGE_QUANTITIES` (NaN where the step has none)."""
    n = table.n_steps
    nan = np.full(n, np.nan)
    exc = table.vertical_excursion_m
    return {"duration_s": np.asarray(table.duration_s, np.float64), "h_m1_m": exc.get("M1", nan),
            "h_m2_m": exc.get("M2", nan),
            "acc_range_m4_m_s2": table.acc_range_m_s2 if table.acc_range_m_s2.size == n else nan,
            **{f"length_{e.lower()}_m": table.length_m.get(e, nan) for e in ("M1", "M2", "M4", "M5")}}


@dataclass(frozen=True)
class KFit(VersionedJson):
    """Calibrated constants of one subject.

    Attributes
    ----------
    k_m1, k_m2, k_m4
        K of M1, M2 (dimensionless) and M4 (m / (m/s^2)^p, p = ``m4_exponent``).
    k1_m5_m_s, k2_m5_m
        M5 line ``S = K1 / T + K2`` (K1 in m*s... m per Hz of cadence, K2 in m).
    mode
        ``"multi-speed"`` when the sections' mean cadences span at least ``min_cadence_spread`` (5 %),
        else ``"single-speed"`` (one section, or several at one pace).
    m5_fallback
        True when M5 used the walk-ratio fallback (K2 = 0).
    leg_length_m, foot_length_m
        Anatomical inputs used while calibrating (M1-M3 must be run with the same).
    n_sections, n_steps, distance_m
        What the fit saw.
    subject
        Free text label.
    calibrated_range
        ``{quantity: [min, max]}`` over the calibration steps (:data:`RANGE_QUANTITIES`, module notes); None
        when unknown (a format "1.0" file).
    m4_exponent
        M4's exponent ``p`` that ``k_m4`` was fitted with (module notes; 1/4 in a "1.0" or "1.1" file).
    shrinkage
        None when K is the fitted one; else how K of M1, M2 and M4 was shrunk toward a population
        (:meth:`gaitlog.host.gait.k_prior.KPrior.shrink`): ``source``, and per estimator the ``fitted`` K, the
        ``population`` K, the fitted K's ``weight`` and the prior's ``prior_distance_m``.
    """

    SCHEMA: ClassVar[str] = "gaitlog.KCalibration"
    FORMAT_VERSION: ClassVar[str] = "1.3"
    #: Older format versions this gaitlog still reads (:meth:`from_dict`).
    OLD_VERSIONS: ClassVar[tuple[str, ...]] = ("1.0", "1.1", "1.2")
    #: M4's exponent of the files written before it was stored (Weinberg's).
    OLD_M4_EXPONENT: ClassVar[float] = 0.25
    KIND: ClassVar[str] = "K calibration"
    REDO: ClassVar[str] = "re-run 'gaitlog calibrate-k'"

    k_m1: float
    k_m2: float
    k_m4: float
    k1_m5_m_s: float
    k2_m5_m: float
    mode: str
    m5_fallback: bool
    leg_length_m: float
    foot_length_m: float
    n_sections: int
    n_steps: int
    distance_m: float
    subject: str = ""
    notes: list[str] = field(default_factory=list)
    calibrated_range: dict[str, list[float]] | None = None
    m4_exponent: float = M4_EXPONENT
    shrinkage: dict[str, Any] | None = None

    def step_constants(self) -> dict[str, object]:
        """The K fields of the device's step configuration (:class:`gaitlog.protocol.steps.StepConfig`, PROTOCOL.md 2.2):
        ``calibrated`` and the constants of M1, M2, M4 and M5 (the leg and foot lengths are the caller's).

        and M4's exponent ``k_m4`` was fitted with (the logger computes it: whole eighths up to 1/2).

        Raises :class:`HostError` when ``k_m4`` was fitted with an exponent the logger cannot compute."""
        eighths = self.m4_exponent * 8
        if not (abs(eighths - round(eighths)) < 1e-9 and 1 <= round(eighths) <= M4_EXPONENT_EIGHTHS_MAX):
            raise HostError(f"K calibration: M4's K was fitted with the exponent {self.m4_exponent:g}; the logger "
                            f"computes whole eighths up to {M4_EXPONENT_EIGHTHS_MAX}/8; {self.REDO}")
        return dict(calibrated=True, k_m1=float(self.k_m1), k_m2=float(self.k_m2), k_m4=float(self.k_m4),
                    k1_m5_m_s=float(self.k1_m5_m_s), k2_m5_m=float(self.k2_m5_m), m4_exponent=float(self.m4_exponent))

    def fields_to_dict(self) -> dict[str, object]:
        """The fields, as stored in the JSON file (NaN for a K that could not be fitted)."""
        return asdict(self)

    @classmethod
    def fields_from_dict(cls, data: dict[str, object], *, source: str) -> KFit:
        """Rebuild from the file's keys; :class:`HostError` naming ``source`` on a missing, extra or bad field."""
        try:
            fit = cls(**data)  # type: ignore[arg-type]
        except TypeError as err:
            raise HostError(f"{source}: bad fields: {err}") from err
        problem = _field_problem(fit)
        if problem is not None:
            raise HostError(f"{source}: {problem}")
        return fit

    @classmethod
    def from_dict(cls, data: object, *, source: str | None = None) -> Self:
        """:meth:`VersionedJson.from_dict`, also reading the format versions of :attr:`OLD_VERSIONS` ("1.0":
        no calibrated range, ``calibrated_range`` None; "1.0" and "1.1": ``m4_exponent`` 1/4; all of them:
        ``shrinkage`` None)."""
        if isinstance(data, dict) and data.get("cal_type") == cls.SCHEMA and data.get("format_version") in cls.OLD_VERSIONS:
            old = data.get("format_version")
            where = source or "<K calibration>"
            if "shrinkage" in data:
                raise HostError(f"{where}: key 'shrinkage' in a format {old} file")
            if old == "1.2":
                data = {**data, "format_version": cls.FORMAT_VERSION}
                return super().from_dict(data, source=source)
            if "m4_exponent" in data:
                raise HostError(f"{where}: key 'm4_exponent' in a format {old} file")
            if old == "1.0" and "calibrated_range" in data:
                raise HostError(f"{where}: key 'calibrated_range' in a format 1.0 file")
            data = {**data, "format_version": cls.FORMAT_VERSION, "m4_exponent": cls.OLD_M4_EXPONENT}
        return super().from_dict(data, source=source)

    def outside_range(self, table: StepTable) -> dict[str, np.ndarray]:
        """Per step of ``table``: which quantities lie outside :attr:`calibrated_range`.

        Returns ``{quantity: bool array}`` for :data:`RANGE_QUANTITIES` and ``{estimator: bool array}`` for the
        calibrated estimators (:data:`RANGE_OF_ESTIMATOR`: the step's duration, the estimator's input or its
        length outside the range), plus ``"any"``. A NaN quantity is not flagged (the step has no window:
        it is filled, not measured); everything is False when the range is unknown (a "1.0" file).
        """
        q = range_quantities(table)
        out: dict[str, np.ndarray] = {}
        for name, v in q.items():
            if self.calibrated_range is None:
                out[name] = np.zeros(table.n_steps, bool)
                continue
            lo, hi = self.calibrated_range[name]
            with np.errstate(invalid="ignore"):
                out[name] = np.isfinite(v) & ((v < lo) | (v > hi))
        for e, names in RANGE_OF_ESTIMATOR.items():
            out[e] = np.logical_or.reduce([out[n] for n in names])
        out["any"] = np.logical_or.reduce([out[e] for e in RANGE_OF_ESTIMATOR])
        return out

    def describe_range(self) -> str:
        """One line: the calibrated range (or that it is unknown)."""
        if self.calibrated_range is None:
            return "calibrated range unknown (a format 1.0 K file: re-run 'gaitlog calibrate-k' to store it)"
        r = self.calibrated_range
        return ("calibrated on steps of " + f"{r['duration_s'][0]:.2f}-{r['duration_s'][1]:.2f} s, "
                + ", ".join(f"{e} {r[f'length_{e.lower()}_m'][0]:.2f}-{r[f'length_{e.lower()}_m'][1]:.2f} m"
                            for e in RANGE_OF_ESTIMATOR))


#: The fields of :class:`KFit` that are numbers in its file.
_NUMBER_FIELDS = ("k_m1", "k_m2", "k_m4", "k1_m5_m_s", "k2_m5_m", "leg_length_m", "foot_length_m", "m4_exponent")
#: The estimators of :attr:`KFit.shrinkage`'s per-estimator maps.
_SHRUNK_ESTIMATORS = {"M1", "M2", "M4"}


def _field_problem(fit: KFit) -> str | None:
    """What is wrong with the fields of a K calibration read from a file (the first thing, as the message's
    text), or None."""
    for name in _NUMBER_FIELDS:
        if not _is_number(getattr(fit, name)):
            return f"key {name!r} must be a number"
    if fit.calibrated_range is not None and not _is_range_map(fit.calibrated_range):
        return f"key 'calibrated_range' must map {', '.join(RANGE_QUANTITIES)} to [min, max]"
    if fit.shrinkage is not None and not _is_shrinkage(fit.shrinkage):
        return (f"key 'shrinkage' must map source to text and "
                f"{', '.join(k for k in SHRINKAGE_KEYS if k != 'source')} to {{M1, M2, M4: number}}")
    if not (math.isfinite(fit.m4_exponent) and 0 < fit.m4_exponent <= 1):
        return f"key 'm4_exponent' must be in (0, 1], got {fit.m4_exponent!r}"
    for name in ("leg_length_m", "foot_length_m"):
        length_m = getattr(fit, name)
        if not (math.isfinite(length_m) and length_m > 0):
            return f"key {name!r} must be a positive length in metres, got {length_m!r}"
    return None


def _is_number(value: object) -> bool:
    """A JSON number: an int or a float, not a bool."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_range_map(value: object) -> bool:
    """``{quantity: [min, max]}`` over exactly :data:`RANGE_QUANTITIES`, numbers."""
    return isinstance(value, dict) and set(value) == set(RANGE_QUANTITIES) and all(
        isinstance(pair, list) and len(pair) == 2 and all(map(_is_number, pair)) for pair in value.values())


def _is_shrinkage(value: object) -> bool:
    """Exactly the keys :data:`SHRINKAGE_KEYS`: ``source`` a text, each other ``{M1, M2, M4: number}``."""
    return (isinstance(value, dict) and set(value) == set(SHRINKAGE_KEYS) and isinstance(value["source"], str)
            and all(isinstance(value[k], dict) and set(value[k]) == _SHRUNK_ESTIMATORS
                    and all(map(_is_number, value[k].values())) for k in SHRINKAGE_KEYS if k != "source"))


def _range_of(tables: Sequence[StepTable], k: dict[str, Any]) -> dict[str, list[float]]:
    """The calibrated range (:data:`RANGE_QUANTITIES`) of the calibration steps with K applied."""
    pooled: dict[str, list[np.ndarray]] = {n: [] for n in RANGE_QUANTITIES}
    for t in tables:
        q = range_quantities(t)
        raw = t.raw_m
        q["length_m1_m"] = k["M1"] * raw["M1"]
        q["length_m2_m"] = k["M2"] * raw["M2"]
        q["length_m4_m"] = k["M4"] * raw["M4"]
        q["length_m5_m"] = k["k1"] * raw["M5"] + k["k2"]         # raw M5 = cadence 1/T
        window = np.isfinite(np.asarray(t.duration_s, np.float64))
        for n in RANGE_QUANTITIES:
            pooled[n].append(np.asarray(q[n], np.float64)[window])
    out = {}
    for n, parts in pooled.items():
        v = np.concatenate(parts) if parts else np.zeros(0)
        v = v[np.isfinite(v) & (v > 0)]            # every quantity is positive; 0 = not recorded (a step record)
        out[n] = [float(v.min()), float(v.max())] if v.size else [math.nan, math.nan]
    return out


def calibrate(
    sections: Sequence[tuple[StepTable, float]],
    *,
    leg_length_m: float,
    foot_length_m: float,
    subject: str = "",
    min_cadence_spread: float = 0.05,
    m4_exponent: float = M4_EXPONENT,
) -> KFit:
    """Fit K (M1, M2, M4) and the M5 line from step tables of sections with known distance.

    Parameters
    ----------
    sections
        ``(steps, real_distance_m)`` per calibration section (steps: the :class:`StepTable` rows of the
        section, from a pipeline run without calibration, same leg/foot lengths).
    leg_length_m, foot_length_m
        The anatomical inputs those tables were computed with (stored in the result).
    min_cadence_spread
        Relative spread of the sections' mean cadences below which the M5 line is not identifiable.
    m4_exponent
        M4's exponent the tables' raw M4 lengths were computed with (stored in the result).

    Raises
    ------
    HostError
        No section, a non-positive distance, or no step with a measurable length.
    """
    if not sections:
        raise HostError("K calibration needs at least one section with a known distance")
    est = {"M1": 0.0, "M2": 0.0, "M4": 0.0}
    total = 0.0
    n_steps = 0
    cad_points: list[tuple[float, float, int]] = []  # (mean cadence Hz, mean step length m, steps)
    notes: list[str] = []
    for i, (table, dist) in enumerate(sections):
        if not (math.isfinite(dist) and dist > 0):
            raise HostError(f"calibration section {i}: distance must be positive, got {dist!r}")
        if table.n_steps == 0:
            raise HostError(f"calibration section {i}: no step detected, cannot calibrate")
        for name in est:
            d, filled = table.distance_m(name, raw=True)
            if not math.isfinite(d):
                raise HostError(f"calibration section {i}: no measurable {name} step, cannot calibrate")
            est[name] += d
        total += dist
        n_steps += table.n_steps
        cad, _ = table.filled(table.raw_m["M5"])
        if np.all(np.isfinite(cad)):
            cad_points.append((float(np.mean(cad)), dist / table.n_steps, table.n_steps))
    ks = {name: total / v if v > 0 else float("nan") for name, v in est.items()}
    # M5
    if not cad_points:
        raise HostError("calibration: no step duration measured, cannot fit M5")
    c = np.array([p[0] for p in cad_points])
    s = np.array([p[1] for p in cad_points])
    wts = np.array([p[2] for p in cad_points], float)
    spread = (c.max() - c.min()) / c.mean()
    fallback = len(cad_points) < 2 or spread < min_cadence_spread
    if fallback:
        # walk-ratio model through the origin, pooled: sum(K1 * cadence_i) over steps = real distance
        k1 = total / float(np.sum(c * wts))
        k2 = 0.0
        msg = (f"M5: calibration data do not span speeds ({len(cad_points)} section(s), cadence spread "
               f"{spread:.1%} < {min_cadence_spread:.0%}); using the walk-ratio fallback S = K1 / T (K2 = 0)")
        notes.append(msg)
    else:
        A = np.column_stack([c, np.ones_like(c)]) * np.sqrt(wts)[:, None]
        k1, k2 = np.linalg.lstsq(A, s * np.sqrt(wts), rcond=None)[0]
        k1, k2 = float(k1), float(k2)
    rng = _range_of([t for t, _ in sections], dict(M1=ks["M1"], M2=ks["M2"], M4=ks["M4"], k1=float(k1), k2=float(k2)))
    return KFit(
        k_m1=ks["M1"], k_m2=ks["M2"], k_m4=ks["M4"], k1_m5_m_s=float(k1), k2_m5_m=float(k2),
        mode="single-speed" if fallback else "multi-speed", m5_fallback=bool(fallback),
        leg_length_m=float(leg_length_m), foot_length_m=float(foot_length_m), n_sections=len(sections),
        n_steps=int(n_steps), distance_m=float(total), subject=subject, notes=notes, calibrated_range=rng,
        m4_exponent=float(m4_exponent),
    )


def calibrate_on_sections(table: StepTable, pools: Sequence[Sequence[Section]], *, leg_length_m: float,
                          foot_length_m: float, subject: str = "", m4_exponent: float = M4_EXPONENT) -> KFit:
    """:func:`calibrate` on the steps of ``table`` pooled per run of lap sections (:func:`~gaitlog.host.gait.sections.pool_steps`).

    ``pools``: one list of consecutive sections per calibration point, e.g. a mode of
    :func:`gaitlog.host.gait.sections.calibration_sets`; ``table`` is a step table without K (raw lengths, M4's
    computed with ``m4_exponent``).
    """
    return calibrate([pool_steps(table, secs) for secs in pools], leg_length_m=leg_length_m,
                     foot_length_m=foot_length_m, subject=subject, m4_exponent=m4_exponent)
