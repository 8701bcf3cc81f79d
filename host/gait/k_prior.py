"""A population prior for K: one walk's K shrunk toward the K of other people (empirical Bayes).

A K fitted on one short walk (an IPOL trial: 20 m, about 30 steps) carries that walk's peculiarities: on
the IPOL subjects, the calibrated M4 ratios of a subject's *other* trials are centred on 0.93 for one subject
and 1.06 for another, while the spread around each subject's own centre is 0.04 (IQR; M2 0.05). The K of
the first trial is then a noisy measurement of the subject's K, and the usual remedy is to combine it with
what is known before measuring, the K of the population, each weighted by its precision (the James-Stein /
empirical-Bayes estimate; Efron & Morris, J. Am. Stat. Assoc. 70, 1975):

    K = (d K_walk + d0 K_population) / (d + d0)

with ``d`` the calibration distance (m; the variance of ``K_walk`` falls as 1 / d) and ``d0`` the prior's
weight, in metres of calibration walking it is worth. ``d0 = 0`` is the paper's K (no prior); as ``d``
grows the fitted K takes over (40 m of calibration weigh twice as much as 20 m).

*The population K* (:func:`population_prior`) is the median of other people's K, fitted the same way:

* M1 and M2: K is a dimensionless correction of the inverted-pendulum model, which already scales with the
  leg length, so the population K is the median K.
* M4 (Weinberg): K is in m / (m/s^2)^p, a length: it scales with the body, so the population K is the median
  K per metre of leg length, times the subject's leg length. It holds for one exponent ``p`` only.
* M5 and M3 are left alone (M5 is a line fitted through the calibration walks; M3 has no K).

*Where the numbers come from.* :data:`LOWER_BACK_PRIOR` was learned on the nine IPOL lower-back subjects
(one K each, from their first trial, replayed through the emulated logger at 50 Hz with 10 bits, offline
chain with short gaps interpolated and the shipped defaults, M4 with Weinberg's exponent 1/4, every step of the trial
summed, U-turn included: the evaluation's scoring, ``gaitlog evaluate ipol``); ``d0`` per estimator is the value it
chooses on all of them (:data:`gaitlog.host.studies.tuning.K_PRIOR_CRITERION`). The prior does not pass the project's
rule for choices: shrinking each subject's K toward the other subjects' (nested leave-one-subject-out) narrows the
IQR of the 20 m ratio by M1 +0.010 [-0.013, +0.029], M2 +0.012 [-0.017, +0.021], M4 +0.039 [-0.035, +0.067] (95 %
subject-bootstrap intervals, all including zero), so the evaluation's main rows and ``gaitlog calibrate-k``'s
default keep each subject's own K; the prior is an option (``--prior lower-back``), not a recommendation. ``gaitlog evaluate ipol`` never scores a subject with it: each
subject's K is shrunk toward the median of the *other* subjects, with a ``d0`` chosen on the other subjects
(leave-one-subject-out, nested). It is a prior for a sensor at the lower back (L3-L5); a logger worn
elsewhere, or another step detector, has other K: fit a prior from its own people (:func:`population_prior`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.host.errors import HostError

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.host.gait.k_calibration import KFit

#: The estimators whose K the prior shrinks.
PRIOR_ESTIMATORS = ("M1", "M2", "M4")
#: The candidates of ``d0`` (m of calibration walking the prior is worth) searched by ``gaitlog evaluate ipol``;
#: 0 (no prior, the paper's K) first, so that ties keep the paper's K.
PRIOR_DISTANCE_CANDIDATES_M = (0.0, 2.5, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 40.0, 60.0, 80.0, 160.0)


@dataclass(frozen=True)
class KPrior:
    """The population K of M1, M2 and M4 and the weight of each (module notes).

    Attributes
    ----------
    k_m1, k_m2
        Population K of M1 and M2 (dimensionless).
    k_m4_per_leg
        Population K of M4 per metre of leg length ((m / (m/s^2)^p) / m).
    m4_exponent
        The exponent ``p`` of M4 the population K was fitted with.
    distance_m
        ``d0`` per estimator of :data:`PRIOR_ESTIMATORS`: the calibration distance the prior is worth, m.
    source
        Where the population K comes from (stored with every K shrunk toward it).
    n_subjects
        How many people the population K is the median of.
    """

    k_m1: float
    k_m2: float
    k_m4_per_leg: float
    m4_exponent: float
    distance_m: Mapping[str, float] = field(default_factory=lambda: dict.fromkeys(PRIOR_ESTIMATORS, 0.0))
    source: str = ""
    n_subjects: int = 0

    def population_k(self, estimator: str, leg_length_m: float) -> float:
        """The population K of ``estimator`` for a subject with this leg length (M4: per metre of leg)."""
        if estimator == "M4":
            return self.k_m4_per_leg * leg_length_m
        return {"M1": self.k_m1, "M2": self.k_m2}[estimator]

    def weight(self, estimator: str, calibration_distance_m: float) -> float:
        """The fitted K's weight ``d / (d + d0)`` (1: the fitted K alone)."""
        d0 = float(self.distance_m[estimator])
        return 1.0 if d0 == 0 else calibration_distance_m / (calibration_distance_m + d0)

    def shrink(self, fit: KFit) -> KFit:
        """``fit`` with K of M1, M2 and M4 shrunk toward the population (module notes; M5 unchanged).

        The calibrated range's lengths are rescaled with the new K; ``shrinkage`` records the fitted K, the
        population K, the weights and :attr:`source` (``notes`` are left alone: shrinking is no warning).
        ``fit`` itself when every ``d0`` is 0.

        Raises
        ------
        HostError
            ``fit`` was fitted with another M4 exponent than the prior, or was already shrunk.
        """
        if all(float(self.distance_m[e]) == 0 for e in PRIOR_ESTIMATORS):
            return fit
        if fit.shrinkage is not None:
            raise HostError("K calibration: K is already shrunk toward a population prior")
        if not math.isclose(fit.m4_exponent, self.m4_exponent):
            raise HostError(f"K prior: fitted with M4's exponent {self.m4_exponent:g}, the K with "
                            f"{fit.m4_exponent:g}")
        fitted = {e: float(getattr(fit, f"k_{e.lower()}")) for e in PRIOR_ESTIMATORS}
        new, weights, population = {}, {}, {}
        for e, k in fitted.items():
            w = self.weight(e, fit.distance_m)
            population[e] = self.population_k(e, fit.leg_length_m)
            weights[e] = w
            new[e] = w * k + (1 - w) * population[e] if math.isfinite(k) else k
        rng = fit.calibrated_range
        if rng is not None:
            of = {f"length_{e.lower()}_m": e for e in PRIOR_ESTIMATORS}
            rng = {q: [v * new[of[q]] / fitted[of[q]] for v in lo_hi] if q in of else lo_hi
                   for q, lo_hi in rng.items()}
        return dataclasses.replace(
            fit, k_m1=new["M1"], k_m2=new["M2"], k_m4=new["M4"], calibrated_range=rng,
            shrinkage=dict(source=self.source, fitted=fitted, population=population, weight=weights,
                           prior_distance_m={e: float(self.distance_m[e]) for e in PRIOR_ESTIMATORS}))


def population_prior(fits: Sequence[KFit], *, distance_m: Mapping[str, float] | None = None,
                     source: str = "") -> KPrior:
    """The population K of ``fits`` (one per person, none shrunk): the median K of M1 and M2 and the median
    K of M4 per metre of leg length (module notes).

    Raises
    ------
    HostError
        No fit, fits with different M4 exponents, or a shrunk fit.
    """
    if not fits:
        raise HostError("K prior: no K to take the population K from")
    exps = {round(f.m4_exponent, 9) for f in fits}
    if len(exps) > 1:
        raise HostError(f"K prior: the K were fitted with different M4 exponents ({sorted(exps)})")
    if any(f.shrinkage is not None for f in fits):
        raise HostError("K prior: the population K is taken from fitted K, not shrunk ones")

    def median(values: list[float]) -> float:
        v = np.asarray(values, np.float64)
        v = v[np.isfinite(v)]
        return float(np.median(v)) if v.size else math.nan

    return KPrior(k_m1=median([f.k_m1 for f in fits]), k_m2=median([f.k_m2 for f in fits]),
                  k_m4_per_leg=median([f.k_m4 / f.leg_length_m for f in fits]), m4_exponent=fits[0].m4_exponent,
                  distance_m=dict(distance_m) if distance_m is not None else dict.fromkeys(PRIOR_ESTIMATORS, 0.0),
                  source=source, n_subjects=len(fits))


#: The prior learned on the nine IPOL lower-back subjects (module notes; reproduced by ``gaitlog evaluate ipol``,
#: which prints it, and pinned by ``tests/host/studies/test_ipol_evaluation_real.py``).
LOWER_BACK_PRIOR = KPrior(k_m1=1.0276, k_m2=1.2581, k_m4_per_leg=0.4431, m4_exponent=M4_EXPONENT,
                          distance_m={"M1": 10.0, "M2": 15.0, "M4": 10.0},
                          source="IPOL lower back, 9 subjects, first trial each, 50 Hz, 10 bits", n_subjects=9)
#: The priors a user can name (``gaitlog calibrate-k --prior``).
PRIORS = {"lower-back": LOWER_BACK_PRIOR}
