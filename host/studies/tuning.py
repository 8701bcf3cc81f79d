"""Constants chosen from recordings, chosen leave-one-subject-out (LOSO).

Some rules of the event detector were chosen by looking at real recordings (the IPOL lower-back trials with
foot-sensor events): which heel-strike rule, and how long before the impact the contact is. A figure scored
on the same recordings the constant was chosen on is in-sample. This module declares every such constant
once (:data:`TUNED_PARAMETERS`: its name, its candidate values, the default the code ships with and where it
is used), the one selection criterion (:data:`CRITERION`) and the LOSO procedure (:func:`choose_loso`): for
each subject, the value is chosen on the *other* subjects' trials, and that subject is scored with it.

* ``heel_strike_rule``: ``"impact"`` (the maximum of the 5-10 Hz band of the vertical acceleration,
  :mod:`gaitlog.host.gait.events` notes 2, the default) or ``"steepest-rise"`` (the largest sample-to-sample rise of
  the 10 Hz vertical acceleration, Zijlstra & Hof 2003's initial contact; :class:`SteepestRiseDetector`).
* ``hs_delay_s``: the heel strike this long before the impact (:class:`gaitlog.firmware_sim.algorithms.parameters.
  EventParameters`; 0-80 ms, whole samples at 50 Hz; ignored by the steepest-rise rule).
* ``m4_exponent``: M4's ``S = K (a_max - a_min)^p`` (:data:`gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT`;
  1/4 (Weinberg), 3/8, 1/2: why these, in that module's notes). Its criterion is the one K must meet
  (:data:`K_CRITERION`, :func:`least_spread` on the training subjects' ratios): the IQR of the calibrated M4
  distance ratio, K fitted on each training subject's first trial, shrunk as the evaluation uses it (toward
  the other training subjects' K, with the prior chosen on them for that exponent) and scored on its other
  trials, pooled; ties go to the earlier candidate (the default first). Only the M4 lengths are recomputed per candidate (from each step's range).
* ``k_prior_distance_m``: the weight ``d0`` of the population prior K is shrunk toward, per estimator
  (:mod:`gaitlog.host.gait.k_prior`), chosen with the population K of the training subjects by
  :data:`K_PRIOR_CRITERION` (:func:`least_error`; ``gaitlog.host.studies.ipol_evaluation.choose_prior``).
* ``stop_prominence_m_s2`` (the stop rule: a bout's weak last step, :mod:`gaitlog.host.gait.events` notes 5) is no
  longer tuned: chosen per fold by the step count (0.2 in 7 of 9 folds, 0.4 in 2), its cross-validated gain over
  no stop rule was -0.058 [-0.154, +0.043] steps per trial (95 % subject-bootstrap interval), so the rule for
  choices keeps the simpler choice, off (the default since on-line algorithm version 4; ``gaitlog evaluate ipol``
  still scores the versions-1-3 value in the on-line chain, ``gaitlog.host.studies.ipol_evaluation.ONLINE_CHOICES``).
* M4's weak-step rules (``gaitlog.host.studies.ipol_evaluation.M4_STEP_RULES``: a step counted as its share of the
  trial's typical step, by range or by duration) have no constant, so nothing of them is tuned here; they are scored
  against Weinberg's length by the rule for choices and not kept (their gains' intervals include zero).
* ``prominence_fraction``: the foot-flat threshold's share of the walk's recent step amplitude
  (:mod:`gaitlog.firmware_sim.algorithms.parameters` notes; 0: the floor alone), chosen by the step count. It was
  chosen on these recordings once (0.25 of 0.2, 0.25, 0.3) and is now chosen inside the folds like the others.

A parameter whose name is a field of :class:`~gaitlog.firmware_sim.algorithms.parameters.EventParameters` needs
nothing else: add a :class:`TunedParameter` and it is searched (the grid is the product of the candidates).

Criteria: for the heel-strike constants, heel strikes within :data:`MATCH_TOLERANCE_S` (40 ms) of the foot
sensors, F1 pooled over the training subjects' trials (more matched, fewer missed and fewer extra); ties go
to the smaller median ``|timing error|``, then to the earlier candidate (the default comes first). For the
step-counting constants (``criterion = "step count"``), chosen second with the heel-strike constants of the
fold: the sum over the training trials of ``|detected - reference steps|`` (the trial section, U-turn steps
included; ties: the earlier candidate). Only the event detection is re-run per candidate (the offline chain
on cached trials, milliseconds per trial), never the logger's replay. M4's exponent (``criterion =
"k-transfer"``) is chosen apart, by :data:`K_CRITERION` (:func:`least_spread`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT, EventParameters, samples
from gaitlog.host.gait.events import GaitEventDetector, link_steps
from gaitlog.host.gait.k_prior import LOWER_BACK_PRIOR, PRIOR_DISTANCE_CANDIDATES_M
from gaitlog.host.gait.masked_filter import masked_gaussian_lowpass
from gaitlog.host.studies.compare import match_events

__all__ = ["COUNT_CRITERION", "CRITERION", "SIMPLER_COUNT_CHOICE",
           "K_CRITERION", "K_PRIOR_CRITERION", "MATCH_TOLERANCE_S",
           "TIMING_TOLERANCE_S", "TUNED_PARAMETERS", "EventScore", "LosoChoice", "SteepestRiseDetector",
           "TunedParameter", "candidates", "choose_loso", "detector_for", "k_parameters",
           "least_error", "least_spread", "score_events"]

#: An event matches a reference event within this (the F1 criterion of the event figures).
MATCH_TOLERANCE_S = 0.04
#: Timing errors are measured on events paired within this (every event found, not only the F1's matches).
TIMING_TOLERANCE_S = 0.15


@dataclass(frozen=True)
class TunedParameter:
    """A constant chosen from recordings: its candidates (the grid searched), the shipped default, where it
    is used and its criterion (``"heel-strike F1"``: :data:`CRITERION`; ``"step count"``: :data:`COUNT_CRITERION`;
    ``"k-transfer"``: :data:`K_CRITERION`)."""

    name: str
    candidates: tuple[Any, ...]
    default: Any
    used_in: str
    criterion: str = "heel-strike F1"


#: Every constant chosen from the IPOL recordings (module notes).
TUNED_PARAMETERS: tuple[TunedParameter, ...] = (
    TunedParameter("heel_strike_rule", ("impact", "steepest-rise"), "impact",
                   "gaitlog.host.gait.events (heel-strike = the impact in the 5-10 Hz band) and the on-line algorithm"),
    TunedParameter("hs_delay_s", (0.04, 0.0, 0.02, 0.06, 0.08), EventParameters().hs_delay_s,
                   "EventParameters.hs_delay_s (heel-strike before the impact), both chains"),
    TunedParameter("m4_exponent", tuple(dict.fromkeys((M4_EXPONENT, 0.25, 0.375, 0.5))), M4_EXPONENT,
                   "gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT (M4 = K range^p), both chains",
                   criterion="k-transfer"),
    TunedParameter("k_prior_distance_m", PRIOR_DISTANCE_CANDIDATES_M, dict(LOWER_BACK_PRIOR.distance_m),
                   "gaitlog.host.gait.k_prior.LOWER_BACK_PRIOR (K shrunk toward the other subjects' K), the host's K",
                   criterion="k-prior"),
    TunedParameter("prominence_fraction", (0.25, 0.2, 0.3, 0.0), EventParameters().prominence_fraction,
                   "EventParameters.prominence_fraction (the foot-flat threshold's share of the recent step "
                   "amplitude; 0: the floor alone), both chains", criterion="step count"),
)

#: The simpler choice of each step-counting constant (the rule off), which its chosen value must beat
#: (``gaitlog.host.studies.ipol_evaluation.count_gains``).
SIMPLER_COUNT_CHOICE = {"prominence_fraction": 0.0}

#: The selection criterion, in words (printed by ``gaitlog evaluate ipol``).
CRITERION = (f"heel strikes within {1e3 * MATCH_TOLERANCE_S:.0f} ms of the foot sensors, F1 pooled over the "
             "training subjects' trials (ties: smaller median |error|)")
#: The criterion of the ``"k-transfer"`` parameters.
K_CRITERION = ("IQR of the calibrated distance ratio, K from each training subject's first trial as the main rows use "
               "it (shrunk toward the other training subjects' K only when the K prior is in the main rows) scored on "
               "its other trials, pooled over the training subjects (ties: the earlier candidate)")


#: The criterion of the K prior's weight (:func:`least_error`; :mod:`gaitlog.host.gait.k_prior`).
K_PRIOR_CRITERION = ("mean squared log distance ratio, K from each training subject's first trial shrunk toward the "
                     "median K of the other training subjects, scored on its other trials, pooled (ties: the "
                     "smaller prior weight)")


def k_parameters(parameters: Sequence[TunedParameter] = TUNED_PARAMETERS) -> list[TunedParameter]:
    """The parameters chosen on calibrated distance ratios (:data:`K_CRITERION`, :data:`K_PRIOR_CRITERION`; not
    part of the event grid, :func:`candidates`).

    >>> [p.name for p in k_parameters()]
    ['m4_exponent', 'k_prior_distance_m']
    """
    return [p for p in parameters if p.criterion in ("k-transfer", "k-prior")]


#: The step-counting constants' criterion (``TunedParameter.criterion == "step count"``), in words.
COUNT_CRITERION = ("sum over the training subjects' trials of |detected - reference steps| (U-turn steps "
                   "included), with the fold's heel-strike constants")


def candidates(parameters: Sequence[TunedParameter] = TUNED_PARAMETERS) -> list[dict[str, Any]]:
    """The grid: every combination of candidate values, the defaults first (the steepest-rise rule only with
    the default ``hs_delay_s``, which it ignores).

    The :func:`k_parameters` are not part of the grid (:func:`least_spread`, :func:`least_error`).

    >>> len(candidates()), candidates()[0]
    (24, {'heel_strike_rule': 'impact', 'hs_delay_s': 0.04, 'prominence_fraction': 0.25})
    """
    parameters = [p for p in parameters if p not in k_parameters(parameters)]
    default = {p.name: p.default for p in parameters}
    grid = [dict(zip([p.name for p in parameters], combo))
            for combo in itertools.product(*[p.candidates for p in parameters])]
    grid = [c for c in grid if not (c.get("heel_strike_rule") == "steepest-rise"
                                    and c.get("hs_delay_s", default.get("hs_delay_s")) != default.get("hs_delay_s"))]
    return [default] + [c for c in grid if c != default]


class SteepestRiseDetector(GaitEventDetector):
    """:class:`GaitEventDetector` with the heel strike at the steepest rise of the 10 Hz vertical acceleration
    within the heel-strike search window (the alternative rule, module notes); everything else unchanged."""

    def clone(self) -> SteepestRiseDetector:
        return SteepestRiseDetector(self.parameters, max_gap_s=self.max_gap_s, min_weight=self.min_weight)

    def detect(self, acc_v_m_s2: np.ndarray, *args: Any, sampling_rate_hz: float, valid: np.ndarray | None = None,
               **kwargs: Any) -> SteepestRiseDetector:
        super().detect(acc_v_m_s2, *args, sampling_rate_hz=sampling_rate_hz, valid=valid, **kwargs)
        p = self.parameters
        a = np.asarray(acc_v_m_s2, np.float64)
        ok = np.isfinite(a) if valid is None else (np.asarray(valid, bool) & np.isfinite(a))
        ff = self.foot_flat_
        if ff.size == 0:
            return self
        det = masked_gaussian_lowpass(a, ok, cutoff_hz=p.detail_cutoff_hz, sampling_rate_hz=sampling_rate_hz,
                                      min_weight=self.min_weight)
        rise = np.concatenate([[np.nan], np.diff(det)])
        hs = self._search(rise, ff, -samples(p.hs_search_s, sampling_rate_hz),
                          samples(p.hs_after_s, sampling_rate_hz), mode="argmax")
        for name, value in link_steps(ff, hs, self.toe_off_, ok, sampling_rate_hz=sampling_rate_hz,
                                      max_gap_s=self.max_gap_s, max_step_s=p.max_step_s).items():
            setattr(self, name, value)
        return self


def detector_for(candidate: Mapping[str, Any]) -> GaitEventDetector:
    """The offline event detector of one candidate (its EventParameters fields set, its heel-strike rule)."""
    names = {f.name for f in fields(EventParameters)}
    unknown = set(candidate) - names - {"heel_strike_rule"}
    if unknown:
        raise ValueError(f"tuned parameter(s) {sorted(unknown)} are neither EventParameters fields nor a rule")
    params = EventParameters(**{k: v for k, v in candidate.items() if k in names})
    rule = candidate.get("heel_strike_rule", "impact")
    if rule == "impact":
        return GaitEventDetector(params)
    if rule == "steepest-rise":
        return SteepestRiseDetector(params)
    raise ValueError(f"heel_strike_rule must be 'impact' or 'steepest-rise', got {rule!r}")


@dataclass(frozen=True)
class EventScore:
    """Detected events of one trial against the reference: counts and timing errors (detected - reference)."""

    n_reference: int
    n_detected: int
    n_matched: int
    errors_s: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @staticmethod
    def pooled(scores: Sequence[EventScore]) -> EventScore:
        """The scores of several trials as one."""
        return EventScore(sum(s.n_reference for s in scores), sum(s.n_detected for s in scores),
                          sum(s.n_matched for s in scores),
                          np.concatenate([s.errors_s for s in scores]) if scores else np.zeros(0))

    @property
    def f1(self) -> float:
        """``2 matched / (reference + detected)`` (NaN when both are empty)."""
        total = self.n_reference + self.n_detected
        return 2.0 * self.n_matched / total if total else float("nan")

    @property
    def median_abs_error_s(self) -> float:
        return float(np.median(np.abs(self.errors_s))) if self.errors_s.size else float("nan")

    @property
    def median_error_s(self) -> float:
        return float(np.median(self.errors_s)) if self.errors_s.size else float("nan")


def score_events(reference_s: np.ndarray, detected_s: np.ndarray, *, margin_s: float = 0.3) -> EventScore:
    """Score detected event times against reference times of one trial.

    Only detected events from ``margin_s`` before the first to ``margin_s`` after the last reference event
    count (the reference covers the trial, the recording is longer). Matched: one-to-one within
    :data:`MATCH_TOLERANCE_S`; errors: of the pairs within :data:`TIMING_TOLERANCE_S`
    (:func:`gaitlog.host.studies.compare.match_events`).

    >>> s = score_events(np.array([1.0, 2.0, 3.0]), np.array([1.02, 2.1, 3.0, 9.0]))
    >>> (s.n_reference, s.n_detected, s.n_matched, round(s.f1, 3), round(s.median_abs_error_s, 3))
    (3, 3, 2, 0.667, 0.02)
    """
    ref = np.sort(np.asarray(reference_s, np.float64))
    det = np.sort(np.asarray(detected_s, np.float64))
    if ref.size == 0:
        return EventScore(0, 0, 0)
    det = det[(det >= ref[0] - margin_s) & (det <= ref[-1] + margin_s)]
    it, _ = match_events(ref, det, MATCH_TOLERANCE_S)
    iw, jw = match_events(ref, det, TIMING_TOLERANCE_S)
    return EventScore(int(ref.size), int(det.size), int(it.size), det[jw] - ref[iw])


@dataclass(frozen=True)
class LosoChoice:
    """The outcome of :func:`choose_loso`.

    Attributes
    ----------
    chosen
        Per held-out subject, the index of the candidate chosen on the other subjects.
    training_f1
        Per held-out subject, the criterion's F1 of the chosen candidate on the other subjects.
    """

    chosen: dict[int, int]
    training_f1: dict[int, float]


def _event_key(pooled: EventScore) -> tuple[float, float]:
    """:data:`CRITERION` as an ordering key (larger is better): the F1, then the smaller median ``|timing
    error|`` (an undefined one last)."""
    err = pooled.median_abs_error_s
    return (pooled.f1, -err if np.isfinite(err) else -np.inf)


def _best_on_events(scores: Mapping[int, Sequence[Sequence[EventScore]]], training: Sequence[int],
                    among: Sequence[int]) -> tuple[int, float]:
    """The candidate of ``among`` with the best :data:`CRITERION` on the ``training`` subjects' trials (ties: the
    earlier), and its F1."""
    best, key_best = among[0], None
    for c in among:
        key = _event_key(EventScore.pooled([t[c] for o in training for t in scores[o]]))
        if key_best is None or key > key_best:
            best, key_best = c, key
    return best, float(key_best[0]) if key_best is not None else float("nan")


def _fewest_count_errors(count_errors: Mapping[int, Sequence[Sequence[int]]], training: Sequence[int],
                         among: Sequence[int]) -> int:
    """The candidate of ``among`` with the smallest :data:`COUNT_CRITERION` on the ``training`` subjects' trials
    (ties: the earlier)."""
    cost = {c: sum(abs(int(t[c])) for o in training for t in count_errors[o]) for c in among}
    return min(among, key=lambda c: (cost[c], c))


def _sharing(grid: Sequence[Mapping[str, Any]], n_candidates: int, like: Mapping[str, Any],
             names: Sequence[str]) -> list[int]:
    """The candidates (of the first ``n_candidates`` of ``grid``) whose ``names`` take ``like``'s values."""
    return [c for c in range(n_candidates) if all(grid[c][n] == like[n] for n in names)]


def choose_loso(scores: Mapping[int, Sequence[Sequence[EventScore]]],
                count_errors: Mapping[int, Sequence[Sequence[int]]] | None = None,
                grid: Sequence[Mapping[str, Any]] | None = None,
                parameters: Sequence[TunedParameter] = TUNED_PARAMETERS) -> LosoChoice:
    """For each subject, the candidate chosen on the other subjects' trials (module notes).

    ``scores[subject][trial][candidate]``: the heel-strike :class:`EventScore` of every trial of every
    subject for every candidate (same candidate order everywhere). Without ``count_errors`` every candidate
    competes on :data:`CRITERION`. With ``count_errors[subject][trial][candidate]`` (detected - reference
    steps) and the ``grid`` of candidates (:func:`candidates`), two stages: the heel-strike constants by
    :data:`CRITERION` among the candidates whose step-counting constants are the defaults, then the
    step-counting constants by :data:`COUNT_CRITERION` among the candidates with those heel-strike constants.

    >>> good, bad = EventScore(10, 10, 9, np.zeros(9)), EventScore(10, 10, 5, np.zeros(5))
    >>> choose_loso({1: [[good, bad]], 2: [[bad, good]], 3: [[bad, good]]}).chosen
    {1: 1, 2: 0, 3: 0}
    >>> p = [TunedParameter("a", (0, 1), 0, ""), TunedParameter("b", (0, 1), 0, "", criterion="step count")]
    >>> g = candidates(p)
    >>> e = {1: [[good, good, bad, bad]], 2: [[good, good, bad, bad]]}
    >>> choose_loso(e, {1: [[2, 0, 0, 0]], 2: [[2, 1, 0, 0]]}, g, p).chosen
    {1: 1, 2: 1}
    """
    subjects = list(scores)
    # the grid says how many candidates there are (a subject may have no scored trial)
    n_cand = len(grid) if grid is not None else len(next(t for trials in scores.values() for t in trials))
    count_names = [p.name for p in parameters if p.criterion == "step count"]
    two_stage = count_errors is not None and grid is not None and bool(count_names)
    first = list(range(n_cand))
    if two_stage:
        first = _sharing(grid, n_cand, {p.name: p.default for p in parameters}, count_names)
    chosen, f1s = {}, {}
    for s in subjects:
        training = [o for o in subjects if o != s]
        chosen[s], f1s[s] = _best_on_events(scores, training, first)
        if two_stage:
            event_names = [n for n in grid[chosen[s]] if n not in count_names]
            chosen[s] = _fewest_count_errors(count_errors, training,
                                             _sharing(grid, n_cand, grid[chosen[s]], event_names))
    return LosoChoice(chosen, f1s)


def least_spread(ratios: Sequence[Sequence[float]]) -> tuple[int, float]:
    """The candidate whose ratios have the smallest IQR, and that IQR (:data:`K_CRITERION`).

    ``ratios[candidate]``: distance ratios (estimated / real; NaN ones are left out). Ties go to the earlier
    candidate; a candidate without a ratio is never chosen (``(0, inf)`` when none has one).

    >>> least_spread([[0.8, 1.2, 0.9, 1.1], [1.0, 1.01, 0.99, 1.0]])[0]
    1
    """
    best, best_iqr = 0, math.inf
    for c, r in enumerate(ratios):
        v = np.asarray(r, np.float64)
        v = v[np.isfinite(v)]
        if v.size == 0:
            continue
        q1, q3 = np.percentile(v, [25, 75])
        if q3 - q1 < best_iqr:
            best, best_iqr = c, float(q3 - q1)
    return best, best_iqr


def least_error(ratios: Sequence[Sequence[float]]) -> tuple[int, float]:
    """The candidate whose ratios have the smallest mean squared log ratio (:data:`K_PRIOR_CRITERION`), and it.

    ``ratios[candidate]``: distance ratios (estimated / real; NaN ones are left out). ``log(ratio)`` weighs
    over- and underestimation alike. Ties go to the earlier candidate; a candidate without a ratio is never
    chosen (``(0, inf)`` when none has one).

    >>> least_error([[0.9, 1.1], [1.0, 1.02]])
    (1, 0.000196...)
    """
    best, best_err = 0, math.inf
    for c, r in enumerate(ratios):
        v = np.asarray(r, np.float64)
        v = v[np.isfinite(v) & (v > 0)]
        if v.size == 0:
            continue
        err = float(np.mean(np.log(v) ** 2))
        if err < best_err:
            best, best_err = c, err
    return best, best_err
