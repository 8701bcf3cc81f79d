"""Why the shipped chain's calibrated M4 (and M2) spreads more than the recipe's: one ingredient swapped at a time.

The offline chain (:class:`gaitlog.host.gait.pipeline.StepPipeline`) and the recipe
(:class:`gaitlog.host.gait.recipe.RecipeBaseline`) differ in a handful of ingredients (:data:`INGREDIENTS`):

* ``boundaries``: where a step starts and ends -- the chain's foot-flats (its event detector, with each subject's
  fold-chosen constants) or the peaks of the recipe's 3 Hz zero-phase low-pass (>= 0.3 s apart, >= 1 m/s^2
  prominent);
* ``gravity``: the vertical -- the chain's 4 s centred moving mean of gravity, or the first second's mean
  (the walker stands);
* ``lowpass``: M4's 3 Hz signal -- the chain's Gaussian (-3 dB at 3 Hz) or the recipe's 4th-order Butterworth run
  forward and back (-6 dB at 3 Hz, flat to 2 Hz, far steeper above);
* ``selection``: which steps are the trial's -- the chain's heel strike (foot-flat when none) or the recipe's
  step end within the trial boundaries (the same shifts, :data:`~gaitlog.host.studies.ipol_evaluation.
  SECTION_START_DELAY_S` and :data:`~gaitlog.host.studies.ipol_evaluation.SECTION_END_TOLERANCE_S`);
* ``windowless``: a step without a window (the first of a walking bout, or after a long gap) -- counted with its
  bout's median length (chain) or left out (recipe);
* ``integration``: M2's drift correction -- the chain's eqs (2)-(3) (v back to zero, then x) or the recipe's
  joint correction (a constant and a ramp making v and x zero at both ends).

K's fit is the same in both (the walked distance, 20 m by default, over the first trial's sum, summed by the same
rule as the scored trials), so it is not an ingredient of its own: it follows ``selection`` and ``windowless``.

:func:`decompose` starts from each side and swaps one ingredient for the other side's, everything else fixed,
and scores every mix as ``gaitlog evaluate ipol`` scores its main rows (K from each subject's first trial,
its other trials scored, every step between the trial boundaries summed, M4 with Weinberg's 1/4): median and
IQR of the ratio over the walked distance with 95 % subject-bootstrap intervals, and the gain of each mix over
the chain (IQR of the chain minus IQR of the mix, the same draws for both; :func:`gaitlog.host.studies.ipol_evaluation.
choice_gain`). The all-chain mix reproduces the main rows and the all-recipe mix the ``baseline`` rows (checked:
:attr:`Decomposition.max_reproduction_error`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import EventParameters
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.host.gait.estimators.pendulum import PendulumDriftM2
from gaitlog.host.gait.estimators.weinberg import WeinbergM4
from gaitlog.host.gait.events import curve_foot_flats
from gaitlog.host.gait.masked_filter import masked_gaussian_lowpass
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.host.gait.recipe import RecipeBaseline, joint_correction_lengths_m, step_peaks, zero_phase_lowpass_m_s2
from gaitlog.host.studies.ipol_evaluation import (
    IPOL_DISTANCE_M,
    SECTION_END_TOLERANCE_S,
    SECTION_START_DELAY_S,
    IpolEvaluation,
    ReplayedTrial,
    SubjectFit,
    choice_gain,
    subject_intervals,
)
from gaitlog.host.studies.tuning import detector_for

#: The two sides an ingredient comes from.
SIDES = ("chain", "recipe")
#: The ingredients (:class:`Mix` fields), each ``(the chain's, the recipe's)`` in words.
INGREDIENTS = {
    "boundaries": ("foot-flats of the chain's detector", "peaks of the 3 Hz zero-phase low-pass"),
    "gravity": ("4 s moving mean", "first second's mean"),
    "lowpass": ("Gaussian, -3 dB at 3 Hz", "Butterworth 4th order at 3 Hz, zero phase"),
    "selection": ("heel strike in the trial", "step end in the trial"),
    "windowless": ("counted with the bout's median", "left out"),
    "integration": ("M2 eqs (2)-(3)", "v and x zero at both ends"),
}
#: Boundaries between the two sides' (:func:`boundary_mixes`): the chain's foot-flats without its bouts and heel
#: strikes, and each side's peak rule on the other side's 3 Hz signal.
BOUNDARY_VARIANTS = {
    "chain-peaks": "the chain's foot-flats, one bout, no heel strike",
    "recipe-rule-on-gaussian": "the recipe's peak rule on the chain's Gaussian 3 Hz signal",
    "chain-rule-on-butterworth": "the chain's foot-flat rule on the recipe's Butterworth 3 Hz signal",
}
#: The estimators decomposed, and the ingredients each depends on. ``count``: every step the same length (M4 with
#: the exponent 0, a step counter): what the boundaries and the counting rules alone give once K is fixed.
DEPENDS = {"M2": ("boundaries", "gravity", "integration", "selection", "windowless"),
           "M4": ("boundaries", "gravity", "lowpass", "selection", "windowless"),
           "count": ("boundaries", "selection", "windowless")}


@dataclass(frozen=True)
class Mix:
    """Which side (:data:`SIDES`) each ingredient (:data:`INGREDIENTS`) comes from."""

    boundaries: str = "chain"
    gravity: str = "chain"
    lowpass: str = "chain"
    selection: str = "chain"
    windowless: str = "chain"
    integration: str = "chain"

    @classmethod
    def side(cls, side: str) -> Mix:
        """Every ingredient from ``side``."""
        return cls(**dict.fromkeys(INGREDIENTS, side))

    def swapped(self, ingredient: str) -> Mix:
        """This mix with ``ingredient`` from the other side."""
        return replace(self, **{ingredient: SIDES[1 - SIDES.index(getattr(self, ingredient))]})

    def label(self) -> str:
        """``chain``, ``recipe``, or the base side with the ingredients taken from the other (or a boundary of
        :data:`BOUNDARY_VARIANTS`)."""
        sides = [getattr(self, f.name) for f in fields(self)]
        base = max(SIDES, key=sides.count)
        other = [f.name for f in fields(self) if getattr(self, f.name) != base]
        return base + "".join(f" + {SIDES[1 - SIDES.index(base)]}'s {name}" if getattr(self, name) in SIDES
                              else f" + boundaries: {getattr(self, name)}" for name in other)


def standard_mixes() -> list[Mix]:
    """The chain, each ingredient of the recipe swapped into it, the recipe, each ingredient of the chain swapped
    into it."""
    out = []
    for side in SIDES:
        base = Mix.side(side)
        out += [base] + [base.swapped(name) for name in INGREDIENTS]
    return out


def boundary_mixes() -> list[Mix]:
    """The chain with each boundary of :data:`BOUNDARY_VARIANTS` (everything else the chain's), and with the
    recipe's Butterworth for both its foot-flats and M4's range."""
    return [Mix(boundaries=b) for b in BOUNDARY_VARIANTS] + [Mix(boundaries="chain-rule-on-butterworth",
                                                                 lowpass="recipe")]


def _section_inside(rt: ReplayedTrial, t_s: np.ndarray) -> np.ndarray:
    """Which times lie within the trial boundaries as the evaluation shifts them."""
    lo, hi = rt.meta["TrialBoundaries"]
    return (t_s >= rt.seconds(lo) + SECTION_START_DELAY_S) & (t_s <= rt.seconds(hi) + SECTION_END_TOLERANCE_S)


def _peak_table(peaks: np.ndarray, rt: ReplayedTrial) -> StepTable:
    """The recipe's boundaries as a step table: one row per peak, the previous peak its window's start (the first
    peak has none), no heel strike, one bout."""
    m = peaks.size
    start = np.concatenate(([-1], peaks[:-1])).astype(np.int64) if m else np.zeros(0, np.int64)
    none = np.full(m, -1, np.int64)
    duration = np.where(start >= 0, (peaks - start) / rt.sampling_rate_hz, np.nan)
    return StepTable(rt.sampling_rate_hz, rt.t0_s, peaks.astype(np.int64), none, none.copy(), start,
                     np.zeros(m, np.int64), duration, np.zeros(m, np.int64), acc_range_m_s2=np.full(m, np.nan))


def _finite(x: np.ndarray) -> np.ndarray:
    """``x`` with its NaN samples interpolated (the recipe's step 1, for a filter that needs every sample)."""
    ok = np.isfinite(x)
    if ok.all():
        return x
    idx = np.arange(x.size)
    return np.interp(idx, idx[ok], x[ok])


@dataclass(eq=False)
class TrialParts:
    """One trial's ingredients from both sides, and the per-step lengths (K = 1) of each combination, computed once.

    Attributes
    ----------
    rt
        The replayed trial.
    tables
        Per side, the boundaries as a :class:`StepTable` (the chain's with the fold's event constants).
    verticals
        Per gravity side, ``(vertical m/s^2, where it is measured)``.
    leg_length_m
        M2's pendulum.
    """

    rt: ReplayedTrial
    tables: dict[str, StepTable]
    verticals: dict[str, tuple[np.ndarray, np.ndarray]]
    leg_length_m: float
    lowpassed: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    cache: dict[tuple[str, ...], np.ndarray] = field(default_factory=dict)

    @classmethod
    def of(cls, rt: ReplayedTrial, fit: SubjectFit, candidate: dict[str, Any]) -> TrialParts:
        """The chain (re-run with ``candidate``'s event constants, the fold's) and the recipe on ``rt``."""
        leg, foot = fit.replayed.leg_length_m, fit.replayed.foot_length_m
        chain = StepPipeline(leg_length_m=leg, foot_length_m=foot, detector=detector_for(candidate)).run(
            rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s)
        rec = RecipeBaseline(leg_length_m=leg).estimate(rt.acc_g, rt.valid, sampling_rate_hz=rt.sampling_rate_hz)
        av = chain.axes_.acc_v_m_s2
        rate, lp, params = rt.sampling_rate_hz, chain.events_.first_harmonic_m_s2_, chain.events_.parameters
        everywhere = np.ones(av.size, bool)
        tables = {"chain": chain.steps_, "recipe": _peak_table(rec.peak_, rt),
                  "chain-peaks": _peak_table(chain.events_.foot_flat_, rt),
                  "recipe-rule-on-gaussian": _peak_table(step_peaks(_finite(lp), sampling_rate_hz=rate), rt),
                  "chain-rule-on-butterworth": _peak_table(curve_foot_flats(
                      rec.lowpassed_m_s2_, None, lambda i: everywhere[i], params, rate), rt)}
        parts = cls(rt, tables,
                    {"chain": (av, chain.axes_.valid & np.isfinite(av)),
                     "recipe": (rec.vertical_m_s2_, np.ones(av.size, bool))}, leg)
        parts.lowpassed[("chain", "chain")] = chain.events_.first_harmonic_m_s2_
        parts.lowpassed[("recipe", "recipe")] = rec.lowpassed_m_s2_
        return parts

    def signal(self, gravity: str, lowpass: str) -> np.ndarray:
        """M4's 3 Hz vertical acceleration with ``gravity``'s vertical and ``lowpass``'s filter."""
        key = (gravity, lowpass)
        if key not in self.lowpassed:
            v, ok = self.verticals[gravity]
            rate = self.rt.sampling_rate_hz
            self.lowpassed[key] = (zero_phase_lowpass_m_s2(_finite(v), sampling_rate_hz=rate) if lowpass == "recipe"
                                   else masked_gaussian_lowpass(v, ok, cutoff_hz=EventParameters().ff_cutoff_hz,
                                                                sampling_rate_hz=rate))
        return self.lowpassed[key]

    def lengths(self, estimator: str, mix: Mix) -> np.ndarray:
        """Per row of ``mix``'s boundary table, ``estimator``'s length with K = 1 (NaN without a window)."""
        key = (estimator,) + tuple(getattr(mix, name) for name in DEPENDS[estimator] if name in
                                   ("boundaries", "gravity", "lowpass", "integration"))
        if key not in self.cache:
            table = self.tables[mix.boundaries]
            w = np.flatnonzero(table.start >= 0)
            out = np.full(table.n_steps, np.nan)
            if w.size:
                out[w] = self._window_lengths(estimator, mix, table.start[w], table.foot_flat[w])
            self.cache[key] = out
        return self.cache[key]

    def _window_lengths(self, estimator: str, mix: Mix, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        rate = self.rt.sampling_rate_hz
        if estimator == "count":
            return np.ones(start.size)
        if estimator == "M4":
            lp = self.signal(mix.gravity, mix.lowpass)
            return WeinbergM4().estimate(lp, step_start=start, step_end=end, sampling_rate_hz=rate,
                                         lowpassed=lp).step_length_m_
        v, ok = self.verticals[mix.gravity]
        if mix.integration == "recipe":
            return joint_correction_lengths_m(_finite(v), start, end, sampling_rate_hz=rate,
                                              leg_length_m=self.leg_length_m)
        return PendulumDriftM2().estimate(v, step_start=start, step_end=end, sampling_rate_hz=rate,
                                          leg_length_m=self.leg_length_m, valid=ok).step_length_m_

    def trial_sum(self, estimator: str, mix: Mix) -> tuple[float, int]:
        """``mix``'s distance of the trial with K = 1 (its selection and windowless rules) and its step count."""
        table = self.tables[mix.boundaries]
        t = table.event_time_s() if mix.selection == "chain" else table.time_s(table.foot_flat)
        inside = _section_inside(self.rt, t)
        sec = table.select(inside)
        v = self.lengths(estimator, mix)[inside]
        total = float(np.sum(sec.filled(v)[0])) if mix.windowless == "chain" else float(np.nansum(v))
        return total, int(np.count_nonzero(inside))


def mix_rows(subjects: list[list[TrialParts]], mix: Mix, estimators: tuple[str, ...] = tuple(DEPENDS)) -> list[dict]:
    """``mix`` scored as the evaluation's main rows: per subject, K per estimator = its first trial's walked
    distance over that trial's sum (:attr:`~gaitlog.host.studies.ipol_evaluation.ReplayedTrial.distance_m`),
    one row per other trial and estimator (``subject``, ``trial``, ``estimator``, ``ratio``, ``steps``,
    ``reference_steps``, and ``error_vs_first``: the trial's step-count error minus its first trial's, what moves a
    ratio once K is fitted on the first trial). A subject whose first trial sums to nothing is left out."""
    rows = []
    for trials in subjects:
        sums = [{e: p.trial_sum(e, mix) for e in estimators} for p in trials]
        if not all(sums[0][e][0] > 0 for e in estimators):
            continue
        first_error = sums[0][estimators[0]][1] - trials[0].rt.reference_steps()
        for p, s in zip(trials[1:], sums[1:], strict=True):
            for e in estimators:
                rows.append(dict(subject=p.rt.subject, trial=p.rt.trial, estimator=e,
                                 ratio=s[e][0] / sums[0][e][0] * (trials[0].rt.distance_m / p.rt.distance_m),
                                 steps=s[e][1], reference_steps=p.rt.reference_steps(),
                                 error_vs_first=s[e][1] - p.rt.reference_steps() - first_error))
    return rows


@dataclass(frozen=True)
class MixFigures:
    """One mix's figures per estimator: ``median`` and ``iqr`` (value, low, high), ``gain`` over the chain
    (IQR chain - IQR mix; value, low, high); per scored trial, the mean ``|detected - reference steps|``
    (``step_error``) and the mean of the absolute difference between that error and the first trial's
    (``step_error_vs_first``)."""

    mix: Mix
    median: dict[str, tuple[float, float, float]]
    iqr: dict[str, tuple[float, float, float]]
    gain: dict[str, tuple[float, float, float]]
    step_error: float
    step_error_vs_first: float


@dataclass(frozen=True)
class Decomposition:
    """:func:`decompose`'s result.

    Attributes
    ----------
    figures
        Per mix (:func:`standard_mixes` order), its :class:`MixFigures`.
    rows
        Per mix label, its rows (:func:`mix_rows`).
    max_reproduction_error
        The largest ``|ratio|`` difference between the all-chain mix and the evaluation's main rows, and between
        the all-recipe mix and its ``baseline`` rows (M2, M4): zero up to rounding when the decomposition scores
        what ``gaitlog evaluate ipol`` prints.
    reference_count
        The foot sensors' step count as a counter (:func:`reference_count_rows`): ``median`` and ``iqr`` (value,
        low, high), the spread a perfect step counter with one step length per subject would have.
    """

    figures: list[MixFigures]
    rows: dict[str, list[dict]]
    max_reproduction_error: float
    reference_count: dict[str, tuple[float, float, float]]

    def count_share(self, a: str, b: str, estimator: str = "M4") -> tuple[float, float]:
        """How much of the ratio difference between mixes ``a`` and ``b`` (labels) the step count explains: over the
        scored trials, the correlation of ``estimator``'s ratio ``a - b`` with the difference of their step-count
        errors against the first trial's (``error_vs_first``, what moves a ratio once K is fixed), and the
        least-squares slope (ratio per step)."""
        def by(label: str, key: str) -> dict[tuple[int, int], float]:
            return {(r["subject"], r["trial"]): float(r[key]) for r in self.rows[label] if r["estimator"] == estimator}
        ra, rb, ea, eb = by(a, "ratio"), by(b, "ratio"), by(a, "error_vs_first"), by(b, "error_vs_first")
        keys = sorted(k for k in ra if k in rb)
        x = np.array([ea[k] - eb[k] for k in keys])
        y = np.array([ra[k] - rb[k] for k in keys])
        if x.size < 3 or np.ptp(x) == 0:
            return math.nan, math.nan
        return float(np.corrcoef(x, y)[0, 1]), float(np.polyfit(x, y, 1)[0])

    def format(self) -> str:
        """The table as text: per mix, each estimator's median, IQR [interval] and gain over the chain [interval]."""
        lines = ["M2 and M4, one ingredient swapped at a time (K from each subject's first trial, its other trials "
                 "scored; [95 % subject-bootstrap interval]; gain = IQR of the chain - IQR of the mix; count = every "
                 "step the same length):"]
        for f in self.figures:
            cells = []
            for e in DEPENDS:
                (m, _, _), (q, ql, qh), (g, gl, gh) = f.median[e], f.iqr[e], f.gain[e]
                cells.append(f"{e} {m:.3f} IQR {q:.3f} [{ql:.3f}, {qh:.3f}] gain {g:+.3f} [{gl:+.3f}, {gh:+.3f}]")
            lines.append(f"  {f.mix.label()}: " + "; ".join(cells) + f"; mean |step error| {f.step_error:.2f}, "
                         f"against the first trial's {f.step_error_vs_first:.2f}")
        (m, _, _), (q, ql, qh) = self.reference_count["median"], self.reference_count["iqr"]
        lines.append(f"  the foot sensors' heel strikes counted (every step the same length): {m:.3f} IQR {q:.3f} "
                     f"[{ql:.3f}, {qh:.3f}]")
        swapped = Mix.side("chain").swapped("boundaries").label()
        corr, slope = self.count_share(Mix.side("chain").label(), swapped)
        lines.append(f"chain - ({swapped}), M4 ratio per trial against the difference of their step-count errors "
                     f"(each against its first trial's): correlation {corr:.3f}, {100 * slope:.1f} % per step")
        lines.append(f"the chain and the recipe reproduce evaluate ipol's main and baseline rows within "
                     f"{self.max_reproduction_error:.1e}")
        return "\n".join(lines)


def reference_count_rows(subjects: list[list[TrialParts]]) -> list[dict]:
    """The foot sensors' heel strikes as a step counter scored like :func:`mix_rows` (``estimator = "count"``): the
    ratio of a trial is its reference steps over the first trial's (K fitted on the first trial's count)."""
    return [dict(subject=p.rt.subject, trial=p.rt.trial, estimator="count",
                 ratio=p.rt.reference_steps() / trials[0].rt.reference_steps(), steps=p.rt.reference_steps(),
                 reference_steps=p.rt.reference_steps())
            for trials in subjects if trials[0].rt.reference_steps() > 0 for p in trials[1:]]


def _figures(mix: Mix, rows: list[dict], chain_rows: list[dict], done: dict[tuple, Any]) -> MixFigures:
    """One mix's :class:`MixFigures`; ``done`` holds the bootstraps already run, keyed by the ratios they ran on (a
    swap that leaves an estimator unchanged is not bootstrapped again)."""
    med, iqr, gain = {}, {}, {}
    for e in DEPENDS:
        key = tuple(r["ratio"] for r in rows if r["estimator"] == e)
        if key not in done:
            ci = subject_intervals(rows, e)
            done[key] = (ci["median"], ci["iqr"], choice_gain(chain_rows, rows, e))
        med[e], iqr[e], gain[e] = done[key]
    one = [r for r in rows if r["estimator"] == "count"]
    err = float(np.mean([abs(r["steps"] - r["reference_steps"]) for r in one])) if one else math.nan
    drift = float(np.mean([abs(r["error_vs_first"]) for r in one])) if one else math.nan
    return MixFigures(mix, med, iqr, gain, err, drift)


def _reproduction_error(evaluation: IpolEvaluation, rows: dict[str, list[dict]]) -> float:
    """:attr:`Decomposition.max_reproduction_error` (NaN when the evaluation has no offline rows)."""
    ref = {(r["variant"], r["subject"], r["trial"], r["estimator"]): r["ratio"] for r in evaluation.result_.rows
           if r["arithmetic"] == "offline" and r["k_from"] == "offline" and r["variant"] in ("main", "baseline")}
    diffs = [abs(r["ratio"] - ref[(variant, r["subject"], r["trial"], r["estimator"])])
             for label, variant in ((Mix.side("chain").label(), "main"), (Mix.side("recipe").label(), "baseline"))
             for r in rows[label] if (variant, r["subject"], r["trial"], r["estimator"]) in ref]
    return float(max(diffs)) if diffs else math.nan


def trial_parts(evaluation: IpolEvaluation) -> list[list[TrialParts]]:
    """Per fitted subject of a run :class:`IpolEvaluation`, its trials' :class:`TrialParts` (first trial first)."""
    chosen = evaluation.event_constants_.loso.chosen
    cands = evaluation.replay_.candidates
    return [[TrialParts.of(rt, fit, cands[chosen[s]]) for rt in fit.replayed.trials]
            for s, fit in evaluation.fits_.fits.items()]


def decompose(evaluation: IpolEvaluation, mixes: list[Mix] | None = None) -> Decomposition:
    """Score every mix (:func:`standard_mixes` and :func:`boundary_mixes` by default) on the subjects of a run :class:`IpolEvaluation` (its
    offline chain; module notes)."""
    subjects = trial_parts(evaluation)
    mixes = standard_mixes() + boundary_mixes() if mixes is None else mixes
    rows = {m.label(): mix_rows(subjects, m) for m in dict.fromkeys(mixes + [Mix.side("chain"), Mix.side("recipe")])}
    chain_rows = rows[Mix.side("chain").label()]
    done: dict[tuple, Any] = {}
    figures = [_figures(m, rows[m.label()], chain_rows, done) for m in mixes]
    return Decomposition(figures, rows, _reproduction_error(evaluation, rows),
                         subject_intervals(reference_count_rows(subjects), "count"))


def decompose_folder(folder: str | Path, *, progress: Callable[[str], object] | None = None,
                     distance_m: float = IPOL_DISTANCE_M) -> Decomposition:
    """:func:`decompose` on an IPOL folder, the offline chain evaluated as ``gaitlog evaluate ipol --arithmetic
    offline`` does (``distance_m``: as :class:`~gaitlog.host.studies.ipol_evaluation.IpolEvaluation`'s)."""
    evaluation = IpolEvaluation(arithmetic=("offline",), distance_m=distance_m).run(folder, progress=progress)
    return decompose(evaluation)


__all__ = ["BOUNDARY_VARIANTS", "DEPENDS", "INGREDIENTS", "SIDES", "Decomposition", "Mix", "MixFigures", "TrialParts",
           "decompose", "decompose_folder", "mix_rows", "reference_count_rows", "boundary_mixes", "standard_mixes", "trial_parts"]
