"""K fitted on walks of a known distance (``gaitlog calibrate-k``): :func:`fit_k_on_walks` runs the offline
chain on each walk, cuts it into sections (the whole walk over ``--distance``, or the laps between MARK flags)
and fits K and the M5 line (:func:`gaitlog.host.gait.k_calibration.calibrate`), shrunk toward a population K when
asked (:data:`gaitlog.host.gait.k_prior.PRIORS`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import AccelerationInput
from gaitlog.host.gait.k_calibration import KFit, calibrate
from gaitlog.host.gait.k_prior import PRIORS
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.host.gait.sections import pool_steps, sections_from_marks

__all__ = ["KWalksReport", "fit_k_on_walks"]


@dataclass
class KWalksReport:
    """The fitted K, the walks' sections, the lengths used (``lengths``: their choice, with its source and
    note) and the notes for standard error (``notes``: the chain's and the assumed lengths'; K's own are
    :attr:`KFit.notes`)."""

    k: KFit
    n_sections: int
    lengths: Any
    notes: list[str] = field(default_factory=list)

    @property
    def warnings(self) -> list[str]:
        """Every note, the fit's after the walks'."""
        return self.notes + list(self.k.notes)

    def format_table(self) -> str:
        """The sections, the lengths, K, its shrinkage, the M5 line and K's calibrated range."""
        k, lengths = self.k, self.lengths
        lines = [f"{self.n_sections} section(s), {k.n_steps} steps, {k.distance_m:g} m ({k.mode}); leg length "
                 f"{lengths.leg_length_m:.3f} m, foot length {lengths.foot_length_m:.3f} m, from: {lengths.source}"
                 + (f" ({lengths.note})" if lengths.note and not lengths.assumed else ""),
                 f"K  M1 {k.k_m1:.4f}  M2 {k.k_m2:.4f}  M4 {k.k_m4:.4f} m/(m/s^2)^{k.m4_exponent:g}"]
        if k.shrinkage is not None:
            sh = k.shrinkage
            lines.append(f"   shrunk toward the population K ({sh['source']}): fitted " + ", ".join(
                f"{e} {sh['fitted'][e]:.4f} (weight {sh['weight'][e]:.2f}), population {sh['population'][e]:.4f}"
                for e in sh["fitted"]))
        lines.append(f"M5 S = {k.k1_m5_m_s:.4f} / T + {k.k2_m5_m:.4f} m" + ("  (walk-ratio fallback)" if k.m5_fallback else ""))
        lines.append(f"K {k.describe_range()} (stored: 'gaitlog estimate' flags the steps outside it)")
        return "\n".join(lines)


def fit_k_on_walks(paths: Sequence[str], inputs: Sequence[AccelerationInput], *,
                   lengths_for: Callable[[AccelerationInput | None], Any], anatomy_given: bool,
                   distance_m: Sequence[float] | None, lap_m: float | None, subject: str = "",
                   prior: str = "none") -> KWalksReport:
    """K of the walks ``inputs`` (read from ``paths``): each walked ``distance_m`` (one value for all, or one
    per walk) or, without it, laps of ``lap_m`` between MARK flags. ``lengths_for(data)``: the leg and foot
    lengths (``data``: the first walk that states them, IPOL trials first); ``anatomy_given``: the user gave
    them, so walks of different subjects are allowed.

    Raises
    ------
    HostError
        The walks state different heights or leg/foot lengths (K is per subject) and none was given, or a walk
        has fewer than two MARK flags for its laps.
    """
    heights = {d.ipol_trial.height_m for d in inputs if d.ipol_trial is not None and d.ipol_trial.height_m}
    if len(heights) > 1 and not anatomy_given:
        raise HostError(f"the inputs are IPOL trials of subjects of different heights ("
                        f"{', '.join(f'{h:.2f}' for h in sorted(heights))} m) and K is per subject; give --height")
    configs = {(c.leg_length_m, c.foot_length_m) for c in (d.recording.step_config for d in inputs
                                                           if d.recording is not None) if c is not None and c.step_format}
    if len(configs) > 1 and not anatomy_given:
        raise HostError("the inputs are logger recordings with different leg/foot lengths in their step "
                        "configurations and K is per subject; give --height (or --leg-length and --foot-length)")
    described = [d for d in inputs if d.ipol_trial is not None] + [d for d in inputs if d.recording is not None]
    lengths = lengths_for(described[0] if described else None)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    notes = [lengths.note] if lengths.assumed else []
    sections = []
    for i, (path, data) in enumerate(zip(paths, inputs)):
        pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
            data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
        notes += [f"{path}: {n}" for n in pipe.notes_]
        if distance_m is not None:
            sections.append((pipe.steps_, float(distance_m[0] if len(distance_m) == 1 else distance_m[i])))
        else:
            sections += _laps(path, data, pipe.steps_, lap_m)
    k = calibrate(sections, leg_length_m=leg, foot_length_m=foot, subject=subject)
    if prior != "none":
        k = PRIORS[prior].shrink(k)
    return KWalksReport(k=k, n_sections=len(sections), lengths=lengths, notes=notes)


def _laps(path: str, data: AccelerationInput, steps, lap_m: float | None) -> list:
    """The laps between the MARK flags of one walk, as pooled sections with steps."""
    marks = data.mark_index
    if marks.size < 2:
        raise HostError(f"{path}: --lap-marks needs at least two MARK flags, found {marks.size}")
    laps = sections_from_marks(steps.time_s(marks), lap_m=float(lap_m), sampling_rate_hz=data.sampling_rate_hz)
    return [pool for pool in (pool_steps(steps, [lap]) for lap in laps) if pool[0].n_steps]
