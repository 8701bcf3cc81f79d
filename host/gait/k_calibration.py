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

:class:`KFit` saves/loads itself as versioned JSON (:class:`host.files.versioned_json.VersionedJson`,
``format_version`` "1.0").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from host.errors import HostError
from host.files.versioned_json import VersionedJson
from host.gait.sections import Section, pool_steps

if TYPE_CHECKING:  # pragma: no cover
    from firmware_sim.algorithms.steps import StepTable


@dataclass(frozen=True)
class KFit(VersionedJson):
    """Calibrated constants of one subject.

    Attributes
    ----------
    k_m1, k_m2, k_m4
        K of M1, M2 (dimensionless) and M4 (m / (m/s^2)^(1/4)).
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
    """

    SCHEMA: ClassVar[str] = "gaitlog.KCalibration"
    FORMAT_VERSION: ClassVar[str] = "1.0"
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

    def step_constants(self) -> dict[str, object]:
        """The K fields of the device's step configuration (:class:`protocol.steps.StepConfig`, PROTOCOL.md 2.2):
        ``calibrated`` and the constants of M1, M2, M4 and M5 (the leg and foot lengths are the caller's)."""
        return dict(calibrated=True, k_m1=float(self.k_m1), k_m2=float(self.k_m2), k_m4=float(self.k_m4),
                    k1_m5_m_s=float(self.k1_m5_m_s), k2_m5_m=float(self.k2_m5_m))

    def fields_to_dict(self) -> dict[str, object]:
        """The fields, as stored in the JSON file (NaN for a K that could not be fitted)."""
        return asdict(self)

    @classmethod
    def fields_from_dict(cls, data: dict[str, object], *, source: str) -> KFit:
        """Rebuild from the file's keys; :class:`HostError` naming ``source`` on a missing, extra or bad field."""
        try:
            cal = cls(**data)  # type: ignore[arg-type]
        except TypeError as err:
            raise HostError(f"{source}: bad fields: {err}") from err
        for name in ("k_m1", "k_m2", "k_m4", "k1_m5_m_s", "k2_m5_m", "leg_length_m", "foot_length_m"):
            if isinstance(getattr(cal, name), bool) or not isinstance(getattr(cal, name), (int, float)):
                raise HostError(f"{source}: key {name!r} must be a number")
        for name in ("leg_length_m", "foot_length_m"):
            if not (math.isfinite(getattr(cal, name)) and getattr(cal, name) > 0):
                raise HostError(f"{source}: key {name!r} must be a positive length in metres, got "
                                f"{getattr(cal, name)!r}")
        return cal


def calibrate(
    sections: Sequence[tuple[StepTable, float]],
    *,
    leg_length_m: float,
    foot_length_m: float,
    subject: str = "",
    min_cadence_spread: float = 0.05,
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
    return KFit(
        k_m1=ks["M1"], k_m2=ks["M2"], k_m4=ks["M4"], k1_m5_m_s=float(k1), k2_m5_m=float(k2),
        mode="single-speed" if fallback else "multi-speed", m5_fallback=bool(fallback),
        leg_length_m=float(leg_length_m), foot_length_m=float(foot_length_m), n_sections=len(sections),
        n_steps=int(n_steps), distance_m=float(total), subject=subject, notes=notes,
    )


def calibrate_on_sections(table: StepTable, pools: Sequence[Sequence[Section]], *, leg_length_m: float,
                          foot_length_m: float, subject: str = "") -> KFit:
    """:func:`calibrate` on the steps of ``table`` pooled per run of lap sections (:func:`~host.gait.sections.pool_steps`).

    ``pools``: one list of consecutive sections per calibration point, e.g. a mode of
    :func:`host.gait.sections.calibration_sets`; ``table`` is a step table without K (raw lengths).
    """
    return calibrate([pool_steps(table, secs) for secs in pools], leg_length_m=leg_length_m,
                     foot_length_m=foot_length_m, subject=subject)
