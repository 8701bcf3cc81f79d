"""ADC width x sample rate sweep over simulated subjects, and the paper's open question about M5.

For every subject (:func:`gaitlog.firmware_sim.world.subject.random_subjects`) the walk and the sensor's analog
response are computed once (:class:`gaitlog.host.studies.simulation.AnalogWalk`); each sample rate (25, 50, 100 Hz) samples
that same analog output (same sensor, same noise seed), and each ADC width (8, 10, 12 bits) quantises the
same samples. Every configuration then runs the comparison of :func:`gaitlog.host.studies.compare.compare_walk`: the
ideal (no ADC) and offline float chains and the on-line algorithm in float and in fixed point, with **one
K per configuration and mode** (single- and multi-speed), fitted on that configuration's offline chain and
used by all four chains; 20 m section ratios and the per-step error split (ADC = offline - ideal,
algorithm = online-float - offline, arithmetic = online-fixed - online-float). Only the ADC width and the
rate change between configurations: the subjects, walks, sensors, calibration procedure and sections are
held fixed. (K follows the configuration, as a real calibration walk would be recorded with the device
being calibrated; it is never refitted per chain.)

**M5 and the step timing** (Alvarez et al. left open whether M5's spread comes from timing steps at
50 Hz). M5 is ``K1 / T + K2`` with ``T`` counted in samples, so timing enters M5 alone. The sweep measures
(:func:`m5_timing_answer`), for the offline chain on 10-bit codes:

* the pooled M5 section-ratio IQR and standard deviation at 25, 50 and 100 Hz;
* the same with every step's duration replaced by the world's exact one (``exact-timing``: no sampling and
  no detection error on ``T``, everything else unchanged, the same K: the sampled chain's);
* the timing part itself: ``1 - var(exact T) / var(sampled T)`` of the section ratios is the share of M5's
  spread that the step timing explains.

Parallel runs (``workers``) give the same numbers as serial ones (everything is seeded per subject).

Measured (``gaitlog compare --sweep``: 4 subjects, seed 0, the paper's protocol, 96 evaluated 20 m sections
per configuration, ~10 s on 2 cores; pinned by ``tests/host/commands/test_compare_figures.py``):

* ADC share, per step (median ``|offline - ideal|``, multi-speed K, 50 Hz): M1 2.9 / 0.71 / 0.18 mm at
  8 / 10 / 12 bits, M2 1.05 / 0.28 / 0.07 mm, M4 0.54 / 0.14 / 0.03 mm (a quarter per two bits); the pooled
  section-ratio medians and IQRs move by at most 0.005.
* Algorithm share (median ``|online-float - offline|``): M1 10.4-12.6 mm, M2 9.4-9.7 mm, M4 3.9 mm in every
  configuration (the same at every width: it is the two algorithms', not the converter's); per section up to
  0.03 in ratio, and the on-line algorithm's multi-speed M2 IQR is narrower (0.024-0.030 vs 0.046-0.050).
* Arithmetic share, per step (median ``|online-fixed - online-float|``): 0.015-0.11 mm in every
  configuration, at most 0.32 % of a step except one 2 cm "step" at 25 Hz (h = 0.05 mm, three
  resolution steps of the UQ0.16 excursion: 25 % of its M1, 5 mm); 5-26 steps per configuration (of ~4,300)
  with different events; no saturation, no wrap.
* M5 (offline chain, 10 bits, pooled IQR at 25 / 50 / 100 Hz): multi-speed 0.0147 / 0.0141 / 0.0151, with
  exact step durations and the same K 0.0131 at 50 Hz; single-speed 0.0248 / 0.0214 / 0.0240 vs 0.0241.
  The step timing adds 4 % (multi-speed) and nothing measurable (single-speed) of M5's section-ratio
  variance at 50 Hz: the step durations are off by 20 ms rms at 50 Hz and still 18 ms at 100 Hz, while
  the sample period alone explains 8 ms (4 ms). **M5's spread does not come from the 50 Hz step timing**:
  faster sampling does not narrow it; what there is of a timing error is the event detector's jitter, and
  the rest is the cadence-length line itself (how each walker's step length departs from ``K1/T + K2``
  within and across speeds). This is a statement about the simulated walkers; on the IPOL trials M5's
  spread (IQR 0.149 with the single-speed fallback) is likewise the model's, as the reference-event
  analysis of ``tests/host/studies/test_ipol_evaluation_real.py`` notes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.host.errors import HostError
from gaitlog.host.gait.sections import MODES
from gaitlog.host.studies.compare import (
    CHAINS,
    SHARES,
    SampledWalk,
    column_key,
    compare_walk,
    pair_label,
)
from gaitlog.host.studies.simulation import AnalogWalk, map_subjects, simulated_population
from gaitlog.protocol.adc_bits import MAX_SIMULATED_ADC_BITS, check_adc_bits

ADC_BITS = (8, 10, 12)
RATES_HZ = (DEFAULT_SAMPLING_RATE_HZ / 2, DEFAULT_SAMPLING_RATE_HZ, DEFAULT_SAMPLING_RATE_HZ * 2)
#: Section-ratio columns summarised per configuration: the chains and the exact-timing offline chain.
KINDS = tuple(column_key(c) for c in CHAINS) + ("exact_timing",)
#: Short names of the shares in the summary's columns.
SHARE_COLUMNS = {"adc": "adc", "algorithm": "algorithm", "arithmetic": "arith"}
SUMMARY_COLUMNS = (("adc_bits", "sampling_rate_hz", "mode", "estimator", "n")
                   + tuple(f"{q}_{k}" for k in KINDS[:-1] for q in ("median", "iqr")) + ("iqr_exact_timing",)
                   + tuple(f"{c}_step_mm" for c in SHARE_COLUMNS.values()) + ("arith_step_max_rel",)
                   + tuple(f"{c}_ratio_abs_max" for c in SHARE_COLUMNS.values())
                   + tuple(f"different_events_{c}" for c in SHARE_COLUMNS.values()) + ("saturated",))


@dataclass(frozen=True)
class ConfigResult:
    """What one (subject, bits, rate) run keeps: small rows, no signals."""

    subject_id: str
    adc_bits: int
    sampling_rate_hz: float
    step_diffs: list[dict]
    segments: list[dict]
    timing: dict
    saturation: str
    saturated: int
    wrapped: int
    cycles_per_sample: float


def run_config(sw: SampledWalk, subject: Any, adc_bits: int, *, ideal_table: StepTable | None = None,
               **options: Any) -> tuple[ConfigResult, StepTable]:
    """One configuration (one ADC width on one sampled walk): :func:`gaitlog.host.studies.compare.compare_walk` kept as
    a :class:`ConfigResult`, and the ideal chain's table (the analog input: the same at every width, reusable
    as ``ideal_table`` for the next width). The one home of the per-configuration work of this sweep and of
    :mod:`gaitlog.host.studies.sweep_grid`."""
    wc = compare_walk(sw, subject, adc_bits=adc_bits, ideal_table=ideal_table, **options)
    fx = wc.runs["online-fixed"]
    return (ConfigResult(subject.subject_id, int(adc_bits), float(sw.sampling_rate_hz), wc.step_diffs, wc.segments,
                         wc.timing, wc.saturation, fx.saturated, fx.wrapped, fx.cycles_per_sample),
            wc.runs["ideal"].table)


def _subject_job(job: tuple) -> list[ConfigResult]:
    subject, seed, walk_plan, adc_bits_list, rates, options = job
    walk = AnalogWalk(subject=subject, seed=seed, walk_plan=walk_plan).run()
    out = []
    for rate in rates:
        sw = walk.sample(rate)
        ideal = None
        for adc_bits in adc_bits_list:
            result, ideal = run_config(sw, subject, adc_bits, ideal_table=ideal, **options)
            out.append(result)
    return out


class AdcRateSweep:
    """The 9-configuration sweep (module notes).

    Parameters
    ----------
    n_subjects, seed
        Subjects of :func:`~gaitlog.firmware_sim.world.subject.random_subjects`; subject ``i`` walks with seed
        ``seed * 1000 + i`` (as :class:`gaitlog.host.studies.evaluation.SimulatedEvaluation`).
    adc_bits, rates_hz
        ADC widths and sample rates.
    walk_plan
        :class:`~gaitlog.firmware_sim.world.walk_plan.WalkPlan` (default: the paper's, with the population's habits).
    population
        ``"people"`` (default) or ``"v1"`` (:func:`gaitlog.host.studies.simulation.simulated_population`).
    workers
        Processes; results do not depend on it.
    calibration_sections, include_turn
        See :func:`gaitlog.host.studies.compare.compare_walk`.

    Attributes
    ----------
    results_
        One :class:`ConfigResult` per subject and configuration.
    summary_
        :func:`summarise` of them (one row per configuration, mode and estimator).
    m5_
        :func:`m5_timing_answer`.
    """

    def __init__(self, *, n_subjects: int = 4, seed: int = 0, adc_bits: tuple[int, ...] = ADC_BITS,
                 rates_hz: tuple[float, ...] = RATES_HZ, walk_plan: Any = None, workers: int = 1,
                 calibration_sections: int = 2, include_turn: bool = False, population: str = "people") -> None:
        self.n_subjects = n_subjects
        self.population = population
        self.seed = seed
        self.adc_bits = adc_bits
        self.rates_hz = rates_hz
        self.walk_plan = walk_plan
        self.workers = workers
        self.calibration_sections = calibration_sections
        self.include_turn = include_turn

    def run(self, progress: Callable[[], object] | None = None) -> Self:
        """Simulate every subject once and run every configuration on it; ``progress()`` is called after each
        subject (all its configurations)."""
        if self.n_subjects < 1:
            raise HostError(f"n_subjects must be >= 1, got {self.n_subjects}")
        for b in self.adc_bits:
            check_adc_bits(b, max_bits=MAX_SIMULATED_ADC_BITS, what="ADC bits", error=HostError)
        options = dict(calibration_sections=self.calibration_sections, include_turn=self.include_turn)
        subjects, walk_plan = simulated_population(self.n_subjects, seed=self.seed, population=self.population,
                                                   walk_plan=self.walk_plan)
        jobs = [(s, self.seed * 1000 + i, walk_plan, tuple(int(b) for b in self.adc_bits),
                 tuple(float(r) for r in self.rates_hz), options)
                for i, s in enumerate(subjects)]
        per_subject = map_subjects(_subject_job, jobs, workers=self.workers, progress=progress)
        self.results_ = [r for rs in per_subject for r in rs]
        self.summary_ = summarise(self.results_)
        self.m5_ = m5_timing_answer(self.results_)
        return self

    def format_table(self) -> str:
        """Printed summary: the multi-speed rows, the error split and the M5 answer."""
        return format_summary(self.summary_) + "\n\n" + format_m5(self.m5_)



def median_iqr(v: np.ndarray) -> tuple[float, float]:
    """Median and interquartile range of the finite values of ``v`` (NaN, NaN when there are none)."""
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return float(med), float(q3 - q1)


def summarise(results: list[ConfigResult]) -> list[dict]:
    """One row per (bits, rate, mode, estimator): pooled section ratios and the per-step error split.

    ``median_<chain>`` / ``iqr_<chain>``: the pooled 20 m section ratios of each chain (one K per
    configuration and mode, from its offline chain). ``adc_step_mm`` / ``algorithm_step_mm`` /
    ``arith_step_mm``: median over subjects of the per-step median ``|offline - ideal|``,
    ``|online-float - offline|`` and ``|online-fixed - online-float|`` (multi-speed lengths, steps with the same
    events);
    ``arith_step_max_rel``: the largest per-step relative online-fixed - online-float difference;
    ``*_ratio_abs_max``: largest per-section ``|ratio difference|`` of each share.
    """
    out = []
    configs = sorted({(r.adc_bits, r.sampling_rate_hz) for r in results}, key=lambda c: (c[1], c[0]))
    labels = {s: pair_label(a, b) for s, (a, b) in SHARES.items()}
    for adc_bits, rate in configs:
        rs = [r for r in results if r.adc_bits == adc_bits and r.sampling_rate_hz == rate]
        for mode in MODES:
            for est in ESTIMATORS:
                seg = [s for r in rs for s in r.segments if s["mode"] == mode and s["estimator"] == est]
                ratio = {k: np.array([s[f"ratio_{k}"] for s in seg], float) for k in KINDS}
                row: dict[str, Any] = dict(adc_bits=adc_bits, sampling_rate_hz=rate, mode=mode, estimator=est, n=len(seg))
                for k in KINDS[:-1]:
                    row[f"median_{k}"], row[f"iqr_{k}"] = median_iqr(ratio[k])
                row["iqr_exact_timing"] = median_iqr(ratio["exact_timing"])[1]
                d = {s: [x for r in rs for x in r.step_diffs if x["pair"] == labels[s] and x["estimator"] == est]
                     for s in SHARES}
                for s, (a, b) in SHARES.items():
                    c = SHARE_COLUMNS[s]
                    row[f"{c}_step_mm"] = float(np.nanmedian([x["median_abs_mm"] for x in d[s]]))
                    dr = ratio[column_key(a)] - ratio[column_key(b)]
                    row[f"{c}_ratio_abs_max"] = float(np.nanmax(np.abs(dr))) if np.any(np.isfinite(dr)) else math.nan
                    row[f"different_events_{c}"] = int(sum(x["n_different_events"] for x in d[s]))
                row["arith_step_max_rel"] = float(np.nanmax([x["max_rel"] for x in d["arithmetic"]]))
                row["saturated"] = int(sum(r.saturated + r.wrapped for r in rs))
                out.append(row)
    return [{k: r[k] for k in SUMMARY_COLUMNS} for r in out]


def m5_timing_answer(results: list[ConfigResult], *, adc_bits: int = 10) -> dict:
    """M5's section-ratio spread vs sample rate, with and without the step-timing error (module notes).

    Returns ``{"rows": [...], "verdict": str}``; one row per (mode, rate): ``iqr``, ``std`` of M5's pooled
    section ratio (offline chain on ``adc_bits``-bit codes), ``iqr_exact`` / ``std_exact`` with the world's exact
    step durations (the same K), ``timing_share`` = ``1 - std_exact² / std²`` (the part of the
    variance the step timing adds), the rms step-duration error ``timing_rms_ms`` against the truth and
    ``sampling_rms_ms``, the part of it a sample period alone explains (``1 / (rate √6)``: the difference of
    two independent uniform roundings).

    The verdict says whether the spread comes from the **50 Hz** timing: that needs the timing share at
    50 Hz to be large *and* the spread to shrink at 100 Hz.
    """
    rows = []
    rates = sorted({r.sampling_rate_hz for r in results if r.adc_bits == adc_bits})
    for mode in MODES:
        for rate in rates:
            rs = [r for r in results if r.adc_bits == adc_bits and r.sampling_rate_hz == rate]
            seg = [s for r in rs for s in r.segments if s["mode"] == mode and s["estimator"] == "M5"]
            a = np.array([s["ratio_offline"] for s in seg], float)
            e = np.array([s["ratio_exact_timing"] for s in seg], float)
            g = np.isfinite(a) & np.isfinite(e)
            a, e = a[g], e[g]
            if a.size < 2:
                continue
            va, ve = float(np.var(a, ddof=1)), float(np.var(e, ddof=1))
            rows.append(dict(mode=mode, sampling_rate_hz=rate, n=int(a.size), iqr=median_iqr(a)[1], std=math.sqrt(va),
                             iqr_exact=median_iqr(e)[1], std_exact=math.sqrt(ve),
                             timing_share=float(np.clip(1.0 - ve / va, 0.0, 1.0)) if va > 0 else math.nan,
                             timing_rms_ms=float(np.sqrt(np.mean([r.timing["rms_ms"] ** 2 for r in rs]))),
                             sampling_rms_ms=1e3 / rate / math.sqrt(6.0)))
    verdict = ""
    by = {(r["mode"], r["sampling_rate_hz"]): r for r in rows}
    if any(k[1] == DEFAULT_SAMPLING_RATE_HZ for k in by):
        parts, answers = [], []
        for mode in MODES:
            r50 = by.get((mode, DEFAULT_SAMPLING_RATE_HZ))
            if r50 is None:
                continue
            iqrs = "/".join(f"{by[(mode, f)]['iqr']:.4f}" for f in rates if (mode, f) in by)
            parts.append(f"{mode}: M5 IQR {iqrs} at {'/'.join(f'{f:g}' for f in rates)} Hz, "
                         f"{r50['iqr_exact']:.4f} with exact step durations; the timing adds "
                         f"{100 * r50['timing_share']:.0f} % of the variance at 50 Hz; step durations off by "
                         f"{r50['timing_rms_ms']:.0f} ms rms, of which the 20 ms sample period explains "
                         f"{r50['sampling_rms_ms']:.0f} ms")
            r100 = by.get((mode, 100.0))
            shrinks = r100 is not None and r100["std"] < 0.9 * r50["std"]
            answers.append("yes" if r50["timing_share"] >= 0.5 and shrinks else
                           "partly" if r50["timing_share"] >= 0.25 and shrinks else "no")
        ans = ("yes" if "yes" in answers else "partly" if "partly" in answers else "no")
        text = {"yes": "yes: the 50 Hz step timing is the major part of M5's spread",
                "partly": "partly: the 50 Hz step timing is a visible part of M5's spread",
                "no": "no: M5's spread does not come from the 50 Hz step timing (sampling faster does not narrow "
                      "it; what remains is the cadence-length model and the event detection)"}[ans]
        verdict = text + " (" + "; ".join(parts) + ")"
    return {"rows": rows, "verdict": verdict}


def format_summary(summary: list[dict], *, mode: str = "multi-speed") -> str:
    """Printed table of one calibration mode: section ratios and the error split per configuration."""
    lines = [f"{mode} calibration, one K per configuration (fitted on its offline chain, used by every chain); "
             "ratio = estimated / real per 20 m section (median, IQR); per-step split (median |d|, mm): "
             "ADC = offline - ideal, alg = online-float - offline, arith = online-fixed - online-float",
             f"{'bits':>4}{'Hz':>5} {'est':<4}{'n':>4}{'ideal':>8}{'IQR':>7}{'offline':>8}{'IQR':>7}{'on-fl':>8}"
             f"{'IQR':>7}{'on-fx':>8}{'IQR':>7}{'ADC mm':>8}{'alg mm':>8}{'arith mm':>9}{'arith max%':>11}"
             f"{'diff.ev':>8}{'sat':>5}"]
    for r in summary:
        if r["mode"] != mode:
            continue
        lines.append(f"{r['adc_bits']:>4}{r['sampling_rate_hz']:>5.0f} {r['estimator']:<4}{r['n']:>4}"
                     + "".join(f"{r['median_' + k]:>8.3f}{r['iqr_' + k]:>7.3f}" for k in KINDS[:-1])
                     + f"{r['adc_step_mm']:>8.3f}{r['algorithm_step_mm']:>8.3f}{r['arith_step_mm']:>9.3f}"
                     f"{100 * r['arith_step_max_rel']:>11.3f}{r['different_events_arith']:>8}{r['saturated']:>5}")
    return "\n".join(lines)


def format_m5(m5: dict) -> str:
    """Printed M5-vs-rate table and the verdict."""
    lines = ["M5 (offline chain, 10-bit codes): pooled 20 m section ratios vs sample rate; exact T = the world's "
             "step durations (the same K)",
             f"{'mode':<13}{'Hz':>5}{'n':>5}{'IQR':>8}{'std':>8}{'IQR exact T':>13}{'std exact T':>13}"
             f"{'timing share':>14}{'T rms ms':>10}{'sampling ms':>13}"]
    for r in m5["rows"]:
        lines.append(f"{r['mode']:<13}{r['sampling_rate_hz']:>5.0f}{r['n']:>5}{r['iqr']:>8.4f}{r['std']:>8.4f}"
                     f"{r['iqr_exact']:>13.4f}{r['std_exact']:>13.4f}{100 * r['timing_share']:>13.1f}%"
                     f"{r['timing_rms_ms']:>10.1f}{r['sampling_rms_ms']:>13.1f}")
    if m5.get("verdict"):
        lines.append("M5 and the 50 Hz step timing: " + m5["verdict"])
    return "\n".join(lines)
