"""M3 without K against the IPOL foot events: the pendulum term, the double-support term and the walked distance.

M3 (:class:`gaitlog.host.gait.estimators.two_phase.TwoPhasePendulumM3`) is ``S = S1 + S2``: the single-support
pendulum ``S1 = 2 sqrt(2 l h1 - h1^2)`` (``l`` = 0.530 x height) and the double-support length ``S2`` (Alvarez's
foot length, 0.111 x height). The IPOL trials give the distance walked (20 m between the trial boundaries unless
the evaluation or the trial's JSON says otherwise,
:attr:`~gaitlog.host.studies.ipol_evaluation.ReplayedTrial.distance_m`; "20 m" below stands for it; the U-turn
included) and the foot sensors' heel strikes, not each step's length, so the terms are judged by what the
trial's distance implies:

* per step of the offline chain (the fold's event constants, as ``gaitlog evaluate ipol`` runs it): its part
  (``turn`` when the heel strike lies within ``UTurnBoundaries``, else ``straight``), window ``T``, single support
  ``T_ss`` (toe-off to heel strike), ``S1`` and each double-support rule's ``S2``
  (:data:`~gaitlog.host.gait.estimators.two_phase.DOUBLE_SUPPORT_RULES`);
* per trial: the M3 ratio (sum of the steps over 20 m, a step without a length counted with its bout's median as
  the chain does) for each rule, with the turn and without it (``evaluate ipol``'s ``uturn-exclude`` rows: the
  straight steps over 20 m, a lower bound of how long the straight steps read: they cover less than 20 m), the
  mean straight step over 20 m / steps (an upper bound: the turn's steps are the shorter ones), and the *implied double-support length* ``D* = (20 m - sum S1) / steps``: what S2
  would have to be for the trial to come out right if the pendulum were exact;
* per subject (age, height, sex from the JSON; step / height = 20 m over the foot sensors' heel strikes, per metre
  of height) and per group of them (:data:`GROUPS`): the medians over the scored trials (every trial but the
  first, the trials ``evaluate ipol`` scores);
* per rule against Alvarez's foot length: the gain in median ``|log ratio|`` and in IQR (foot's minus the rule's:
  positive, the rule is better), with 95 % subject-bootstrap intervals over the same draws for both
  (:func:`gaitlog.host.studies.ipol_evaluation.choice_gain`). No rule has a constant chosen on recordings, so no
  fold is needed beyond the event constants';
* for comparison, the fitted answer (:data:`SCALED_RULE`, an exploration: nothing ships it): S2 = ``c`` x the foot
  length, ``c`` chosen leave-one-subject-out as the median ``D* / S2`` of the other subjects' trials (every trial
  of theirs), the held-out subject scored with its fold's ``c`` (``fold_scales_``).

:class:`M3Decomposition` runs it on an :class:`~gaitlog.host.studies.ipol_evaluation.IpolEvaluation` already run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from gaitlog.host.gait.estimators.two_phase import DOUBLE_SUPPORT_RULES, TwoPhasePendulumM3
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.host.studies.ipol_evaluation import (
    IPOL_DISTANCE_M,
    IpolEvaluation,
    ReplayedTrial,
    choice_gain,
    subject_groups,
    subject_intervals,
    trial_steps,
)
from gaitlog.host.studies.stats import BOOTSTRAP_LEVEL, BOOTSTRAP_RESAMPLES, subject_bootstrap, subject_resamples
from gaitlog.host.studies.tuning import detector_for

__all__ = ["GROUPS", "SCALED_RULE", "M3Decomposition", "TrialM3", "trial_m3"]

#: The fitted comparison's name (module notes): the foot length scaled by a constant chosen in the folds.
SCALED_RULE = "foot-scaled-per-fold"

#: The groups of subjects compared: name -> (subject field, threshold); below / at-or-above the threshold.
GROUPS: dict[str, tuple[str, float]] = {"age": ("age", 58.0), "height": ("height_m", 1.72),
                                        "step / height": ("step_per_height", 0.34)}


@dataclass(frozen=True, eq=False)
class TrialM3:
    """One trial's M3 steps: the offline chain's steps of the trial section (as ``evaluate ipol`` selects them).

    Attributes
    ----------
    subject, trial, scored
        Identifiers; ``scored``: not the subject's first trial (the rows ``evaluate ipol`` scores).
    turn
        ``(m,)`` the heel strike lies within ``UTurnBoundaries``.
    duration_s, single_support_s
        Window and toe-off to heel-strike time (NaN without them).
    pendulum_m
        ``S1`` (NaN without a window, events or a possible excursion).
    double_support_m
        Per rule, ``S2`` per step.
    length_m
        Per rule, ``S1 + S2`` with the NaN steps filled with their bout's median (the chain's distance rule).
    reference_steps, foot_length_m, height_m, age, sex
        The foot sensors' heel strikes in the trial, S2 of the foot rule, and the JSON's subject data.
    distance_m
        The distance walked between the trial boundaries (:attr:`~gaitlog.host.studies.ipol_evaluation.
        ReplayedTrial.distance_m`; "20 m" below stands for it).
    """

    subject: int
    trial: int
    scored: bool
    turn: np.ndarray
    duration_s: np.ndarray
    single_support_s: np.ndarray
    pendulum_m: np.ndarray
    double_support_m: dict[str, np.ndarray]
    length_m: dict[str, np.ndarray]
    reference_steps: int
    foot_length_m: float
    height_m: float
    age: float
    sex: str
    distance_m: float = IPOL_DISTANCE_M

    def ratio(self, rule: str, *, uturn: str = "include", scale: float = 1.0) -> float:
        """The rule's M3 distance over 20 m, every step (``include``) or the straight ones (``exclude``); ``scale``
        multiplies the foot rule's S2 (a filled step is its bout's median, so it moves by the same amount)."""
        v = self.length_m[rule] - (1.0 - scale) * self.foot_length_m * (rule == "foot")
        return float(np.sum(v if uturn == "include" else v[~self.turn])) / self.distance_m

    def straight_step_ratio(self, rule: str) -> float:
        """The rule's mean straight step over the trial's mean step (20 m / steps): the turn's steps are shorter than
        the straight ones, so the straight steps' true mean is longer than 20 m / steps and this bounds the straight
        steps' reading from above (:meth:`ratio` with ``uturn="exclude"``, over the full 20 m, from below)."""
        v = self.length_m[rule][~self.turn]
        return float(np.mean(v)) * self.turn.size / self.distance_m if v.size else math.nan

    def implied_double_support_m(self) -> float:
        """``D* = (20 m - sum S1) / steps``, S1 filled as the chain fills lengths (module notes)."""
        s1 = self.length_m["foot"] - self.foot_length_m
        return (self.distance_m - float(np.sum(s1))) / max(self.turn.size, 1)


def trial_m3(rt: ReplayedTrial, leg_length_m: float, foot_length_m: float, candidate: dict[str, Any],
             scored: bool, rules: tuple[str, ...]) -> TrialM3:
    """The offline chain on ``rt`` with ``candidate``'s event constants, and M3 with each rule on its windows."""
    chain = StepPipeline(leg_length_m=leg_length_m, foot_length_m=foot_length_m, detector=detector_for(candidate)).run(
        rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s)
    sec, _ = trial_steps(rt, chain.steps_, uturn="include")
    ub = rt.meta.get("UTurnBoundaries")
    t = sec.event_time_s()
    turn = (t >= rt.seconds(ub[0])) & (t <= rt.seconds(ub[1])) if ub else np.zeros(sec.n_steps, bool)
    av = chain.axes_.acc_v_m_s2
    ok = chain.axes_.valid & np.isfinite(av)
    w = np.flatnonzero(sec.start >= 0)
    hs = np.where(sec.heel_strike[w] > sec.start[w], sec.heel_strike[w], -1)
    s1 = np.full(sec.n_steps, np.nan)
    ds: dict[str, np.ndarray] = {}
    length: dict[str, np.ndarray] = {}
    for rule in rules:
        m3 = TwoPhasePendulumM3(double_support=rule).estimate(
            np.where(ok, av, np.nan), step_start=sec.start[w], step_end=sec.foot_flat[w], step_toe_off=sec.toe_off[w],
            step_heel_strike=hs, sampling_rate_hz=rt.sampling_rate_hz, leg_length_m=leg_length_m,
            foot_length_m=foot_length_m, valid=ok) if w.size else None
        ds[rule] = np.full(sec.n_steps, np.nan)
        raw = np.full(sec.n_steps, np.nan)
        if m3 is not None:
            s1[w], ds[rule][w], raw[w] = m3.pendulum_length_m_, m3.double_support_length_m_, m3.step_length_m_
        length[rule] = sec.filled(raw)[0]
    has = (sec.toe_off >= 0) & (sec.heel_strike > sec.toe_off)
    single = np.where(has, (sec.heel_strike - sec.toe_off) / rt.sampling_rate_hz, np.nan)
    height = rt.height_m
    return TrialM3(rt.subject, rt.trial, scored, turn, sec.duration_s.copy(), single, s1, ds, length,
                   rt.reference_steps(), float(foot_length_m), math.nan if height is None else float(height),
                   float(rt.meta.get("Age", math.nan)), str(rt.meta.get("Gender", "")), rt.distance_m)


def _median(x: list[float]) -> float:
    x = [v for v in x if math.isfinite(v)]
    return float(np.median(x)) if x else math.nan


def _abs_log_median(x: np.ndarray) -> np.ndarray:
    return np.array([np.median(np.abs(np.log(x))) if x.size else math.nan])


class M3Decomposition:
    """M3's terms against the IPOL foot events and the walked distance (module notes).

    Parameters
    ----------
    rules
        The double-support rules scored (:data:`~gaitlog.host.gait.estimators.two_phase.DOUBLE_SUPPORT_RULES`);
        the first is the reference the gains are taken against.
    n_resamples, seed, level
        The subject bootstrap.

    Attributes
    ----------
    trials_
        Every trial of every fitted subject, :class:`TrialM3`.
    subjects_
        Per subject: ``subject``, ``age``, ``sex``, ``height_m``, ``step_per_height``, ``foot_length_m``,
        ``implied_double_support_m`` (median ``D*``), ``straight_pendulum_m`` / ``turn_pendulum_m`` (mean S1 per
        step), ``double_support_fraction`` (median ``1 - T_ss / T`` of the chain's events), ``ratio_<rule>`` and
        ``ratio_<rule>_straight`` (median over the scored trials, the turn included / left out),
        ``straight_step_ratio_foot`` (:meth:`TrialM3.straight_step_ratio`, median).
    groups_
        Per group (:data:`GROUPS`) and side (``below`` / ``above``): ``subjects`` and the medians of the subjects'
        ``ratio_*``, ``implied_double_support_m / foot_length_m``.
    figures_
        Per rule and U-turn rule (``include``/``exclude``): ``median``, ``iqr`` (value, low, high),
        ``abs_log`` (median ``|log ratio|``, low, high) and, against the first rule, ``gain_iqr`` and
        ``gain_abs_log`` (value, low, high; positive: the rule is better).
    parts_
        Per part (``straight``, ``turn``), over the scored trials' steps: ``steps``, the means of ``S1``
        (``pendulum_m``), of each rule's ``S2`` (``double_support_m_<rule>``) and of the foot rule's step
        (``m3_m``, filled steps included), and ``trial_mean_step_m``, the mean of 20 m / steps over those steps'
        trials (what every step would be if all were equal).
    correlations_
        Per ``(subject field, quantity)`` (fields of :data:`GROUPS`; ``ratio_foot``, the shipped M3 ratio with the
        turn, or ``implied_per_foot``, ``D* / S2``): the correlation over the subjects and its subject-bootstrap
        interval (value, low, high).
    fold_scales_
        Per subject, the ``c`` of :data:`SCALED_RULE` chosen on the other subjects (module notes; not shipped).
    regression_
        Least squares over the scored trials of ``20 m = a sum S1 + b steps``: ``a`` (the pendulum's scale the
        distance asks for) and ``b`` (m per step, the double support it asks for).
    """

    def __init__(self, *, rules: tuple[str, ...] = DOUBLE_SUPPORT_RULES, n_resamples: int = BOOTSTRAP_RESAMPLES,
                 seed: int = 0, level: float = BOOTSTRAP_LEVEL) -> None:
        unknown = [r for r in rules if r not in DOUBLE_SUPPORT_RULES]
        if unknown or not rules or "foot" not in rules:
            raise ValueError(f"rules must be among {', '.join(DOUBLE_SUPPORT_RULES)} and include 'foot', got {rules!r}")
        self.rules = tuple(rules)
        self.n_resamples = n_resamples
        self.seed = seed
        self.level = level

    def run(self, evaluation: IpolEvaluation) -> Self:
        """Decompose M3 on the subjects of a run :class:`IpolEvaluation` (its offline chain, the fold's events)."""
        chosen = evaluation.event_constants_.loso.chosen
        cands = evaluation.replay_.candidates
        self.trials_ = [trial_m3(rt, fit.replayed.leg_length_m, fit.replayed.foot_length_m, cands[chosen[s]], i > 0,
                                 self.rules)
                        for s, fit in evaluation.fits_.fits.items() for i, rt in enumerate(fit.replayed.trials)]
        self.subjects_ = [self._subject(s) for s in sorted({t.subject for t in self.trials_})]
        self.groups_ = self._groups()
        self.parts_ = {part: self._part(part == "turn") for part in ("straight", "turn")}
        self.correlations_ = {(f, q): self._correlation(f, q) for f, _ in GROUPS.values()
                              for q in ("ratio_foot", "implied_per_foot")}
        self.fold_scales_ = self._fold_scales()
        self.figures_ = {(rule, u): self._figures(rule, u) for rule in self.rules + (SCALED_RULE,)
                         for u in ("include", "exclude")}
        scored = [t for t in self.trials_ if t.scored]
        a = np.array([[np.sum(t.length_m["foot"] - t.foot_length_m), t.turn.size] for t in scored])
        walked = np.array([t.distance_m for t in scored])
        coef = np.linalg.lstsq(a, walked, rcond=None)[0] if scored else (math.nan,) * 2
        self.regression_ = {"a": float(coef[0]), "b": float(coef[1])}
        return self

    def rows(self, rule: str, uturn: str = "include") -> list[dict]:
        """The rule's scored trials as ``evaluate ipol`` rows (``subject``, ``trial``, ``estimator`` = M3, ``ratio``)."""
        if rule == SCALED_RULE:
            return [dict(subject=t.subject, trial=t.trial, estimator="M3",
                         ratio=t.ratio("foot", uturn=uturn, scale=self.fold_scales_[t.subject]))
                    for t in self.trials_ if t.scored]
        return [dict(subject=t.subject, trial=t.trial, estimator="M3", ratio=t.ratio(rule, uturn=uturn))
                for t in self.trials_ if t.scored]

    def _part(self, turn: bool) -> dict[str, float]:
        scored = [t for t in self.trials_ if t.scored]

        def pooled(f: Any) -> np.ndarray:
            return np.concatenate([np.asarray(f(t), np.float64)[t.turn == turn] for t in scored])
        out = {"steps": float(pooled(lambda t: np.ones(t.turn.size)).size),
               "pendulum_m": float(np.nanmean(pooled(lambda t: t.pendulum_m))),
               "m3_m": float(np.mean(pooled(lambda t: t.length_m["foot"]))),
               "trial_mean_step_m": float(np.mean(pooled(lambda t: np.full(t.turn.size,
                                                                           t.distance_m / t.turn.size))))}
        out.update({f"double_support_m_{r}": float(np.nanmean(pooled(lambda t, r=r: t.double_support_m[r])))
                    for r in self.rules})
        return out

    def _correlation(self, field: str, quantity: str) -> tuple[float, float, float]:
        """Correlation of a subject field with a subject quantity, and its subject-bootstrap interval."""
        def value(s: dict[str, Any]) -> float:
            return s["implied_double_support_m"] / s["foot_length_m"] if quantity == "implied_per_foot" else s[quantity]
        mine = [s for s in self.subjects_ if math.isfinite(s[field]) and math.isfinite(value(s))]
        if len(mine) < 3:
            return (math.nan,) * 3

        def corr(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                return np.array([np.corrcoef(x, y)[0, 1] if np.ptp(x) > 0 and np.ptp(y) > 0 else math.nan])
        counts = subject_resamples(len(mine), n_resamples=self.n_resamples, seed=self.seed)
        r, lo, hi = subject_bootstrap([np.array([s[field]]) for s in mine], corr, counts,
                                      [np.array([value(s)]) for s in mine], level=self.level)
        return float(r[0]), float(lo[0]), float(hi[0])

    def _fold_scales(self) -> dict[int, float]:
        """Per subject, ``c`` = the median ``D* / S2`` over the other subjects' trials (module notes)."""
        implied = [(t.subject, t.implied_double_support_m() / t.foot_length_m) for t in self.trials_]
        return {s: _median([c for o, c in implied if o != s]) for s in sorted({t.subject for t in self.trials_})}

    def _subject(self, subject: int) -> dict[str, Any]:
        mine = [t for t in self.trials_ if t.subject == subject]
        scored = [t for t in mine if t.scored] or mine
        first = mine[0]
        s1 = np.concatenate([t.pendulum_m for t in mine])
        turn = np.concatenate([t.turn for t in mine])
        frac = np.concatenate([1 - t.single_support_s / t.duration_s for t in mine])
        out: dict[str, Any] = dict(
            subject=subject, age=first.age, sex=first.sex, height_m=first.height_m,
            step_per_height=_median([t.distance_m / t.reference_steps / t.height_m for t in scored
                                     if t.reference_steps]),
            foot_length_m=first.foot_length_m,
            implied_double_support_m=_median([t.implied_double_support_m() for t in scored]),
            straight_pendulum_m=float(np.nanmean(s1[~turn])), turn_pendulum_m=float(np.nanmean(s1[turn])),
            double_support_fraction=float(np.nanmedian(frac)))
        for rule in self.rules:
            out[f"ratio_{rule}"] = _median([t.ratio(rule) for t in scored])
            out[f"ratio_{rule}_straight"] = _median([t.ratio(rule, uturn="exclude") for t in scored])
        out["straight_step_ratio_foot"] = _median([t.straight_step_ratio("foot") for t in scored])
        return out

    def _groups(self) -> dict[tuple[str, str], dict[str, Any]]:
        out = {}
        keys = ([k for k in self.subjects_[0] if k.startswith("ratio_") or k == "straight_step_ratio_foot"]
                if self.subjects_ else [])
        for name, (field, threshold) in GROUPS.items():
            for side in ("below", "above"):
                mine = [s for s in self.subjects_ if math.isfinite(s[field])
                        and (s[field] < threshold) == (side == "below")]
                row: dict[str, Any] = {"subjects": [s["subject"] for s in mine]}
                row.update({k: _median([s[k] for s in mine]) for k in keys})
                row["implied_per_foot"] = _median([s["implied_double_support_m"] / s["foot_length_m"] for s in mine])
                out[(name, side)] = row
        return out

    def _figures(self, rule: str, uturn: str) -> dict[str, tuple[float, float, float]]:
        rows, ref = self.rows(rule, uturn), self.rows(self.rules[0], uturn)
        ci = subject_intervals(rows, "M3", n_resamples=self.n_resamples, seed=self.seed, level=self.level)
        groups = list(subject_groups(rows, "M3").values())
        counts = subject_resamples(len(groups), n_resamples=self.n_resamples, seed=self.seed)
        value, lo, hi = subject_bootstrap(groups, _abs_log_median, counts, level=self.level)
        out = dict(median=ci["median"], iqr=ci["iqr"], abs_log=(float(value[0]), float(lo[0]), float(hi[0])))
        out["gain_iqr"] = choice_gain(ref, rows, "M3", n_resamples=self.n_resamples, seed=self.seed, level=self.level)
        a, b = subject_groups(ref, "M3"), subject_groups(rows, "M3")
        value, lo, hi = subject_bootstrap([a[s] for s in a], lambda x, y: _abs_log_median(x) - _abs_log_median(y),
                                          counts, [b[s] for s in a], level=self.level)
        out["gain_abs_log"] = (float(value[0]), float(lo[0]), float(hi[0]))
        return out

    def format(self) -> str:
        """The per-subject and per-group tables and each rule's figures, as text ("20 m": the walked distance)."""
        walked = {t.distance_m for t in self.trials_}
        dist = f"{walked.pop():g} m" if len(walked) == 1 else "the walked distance"
        lines = [f"M3 without K against the foot events (scored trials; D* = ({dist} - sum S1) / steps, the double "
                 "support the distance implies if the pendulum is exact):",
                 "subject age sex height step/height S2(foot) D* D*/S2 S1 straight S1 turn DS fraction "
                 f"straight-step/({dist}/steps) "
                 + " ".join(f"ratio[{r}] straight" for r in self.rules)]
        for s in self.subjects_:
            lines.append(f"  {s['subject']} {s['age']:.0f} {s['sex']} {s['height_m']:.2f} {s['step_per_height']:.3f} "
                         f"{s['foot_length_m']:.3f} {s['implied_double_support_m']:.3f} "
                         f"{s['implied_double_support_m'] / s['foot_length_m']:.2f} {s['straight_pendulum_m']:.3f} "
                         f"{s['turn_pendulum_m']:.3f} {s['double_support_fraction']:.3f} "
                         f"{s['straight_step_ratio_foot']:.3f} "
                         + " ".join(f"{s[f'ratio_{r}']:.3f} {s[f'ratio_{r}_straight']:.3f}" for r in self.rules))
        for (name, side), g in self.groups_.items():
            lines.append(f"  {name} {side} {GROUPS[name][1]:g}: subjects {g['subjects']} D*/S2 "
                         f"{g['implied_per_foot']:.2f} straight-step/({dist}/steps) {g['straight_step_ratio_foot']:.3f} "
                         + " ".join(
                             f"{r} {g[f'ratio_{r}']:.3f} (straight {g[f'ratio_{r}_straight']:.3f})" for r in self.rules))
        for part, f in self.parts_.items():
            lines.append(f"{part} steps ({f['steps']:.0f}): mean S1 {f['pendulum_m']:.3f} m, S2 " + ", ".join(
                f"{r} {f[f'double_support_m_{r}']:.3f}" for r in self.rules) + f" m; M3 {f['m3_m']:.3f} m against "
                f"{dist} / steps {f['trial_mean_step_m']:.3f} m")
        lines.append(f"{dist} = a sum S1 + b steps over the scored trials: a = {self.regression_['a']:.3f}, "
                     f"b = {self.regression_['b']:.3f} m per step")
        lines += [f"correlation over the subjects of {q} with {f}: {r:+.2f} [{lo:+.2f}, {hi:+.2f}]"
                  for (f, q), (r, lo, hi) in self.correlations_.items()]
        c = list(self.fold_scales_.values())
        lines.append(f"{SCALED_RULE} (exploration, not shipped): c chosen per fold {min(c):.3f}-{max(c):.3f}")
        for (rule, u), f in self.figures_.items():
            cells = [f"{k} {v:.3f} [{lo:.3f}, {hi:.3f}]" for k, (v, lo, hi) in f.items() if not k.startswith("gain")]
            cells += [f"{k} {v:+.3f} [{lo:+.3f}, {hi:+.3f}]" for k, (v, lo, hi) in f.items() if k.startswith("gain")]
            lines.append(f"  {rule}, U-turn {u}: " + "; ".join(cells))
        return "\n".join(lines)
