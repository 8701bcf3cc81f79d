"""The report of ``gaitlog evaluate ipol``: :func:`evaluate_ipol` runs the IPOL evaluation
(:func:`gaitlog.host.studies.ipol_evaluation.evaluate_folder`) and returns an :class:`IpolReport`, which writes
the CSVs and the box plot (:meth:`~IpolReport.write_outputs`) and renders the printed tables
(:meth:`~IpolReport.format_table`) and the JSON document (:meth:`~IpolReport.to_json`)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text
from gaitlog.host.files.ipol import list_trials
from gaitlog.host.gait.anthropometry import LENGTH_MODEL
from gaitlog.host.storage.json_text import json_text
from gaitlog.host.studies.compare import rows_csv_text
from gaitlog.host.studies.ipol_evaluation import (
    ARITHMETICS,
    CSV_COLUMNS,
    EVENT_COLUMNS,
    IPOL_DISTANCE_M,
    K_PRIOR_IN_MAIN,
    STEP_COLUMNS,
    IpolResult,
    choice_gains,
    count_gains,
    done_figures,
    evaluate_folder,
    format_choices,
    format_done,
    format_events,
    format_tuning,
    main_rows,
    summarise,
)
from gaitlog.host.studies.plots import render_chain_boxplots_png
from gaitlog.host.studies.stats import BOOTSTRAP_RESAMPLES

#: ``list_trials`` is here too so that the command counts the trials of its progress bar with one import.
__all__ = ["IpolOutputs", "IpolReport", "evaluate_ipol", "list_trials"]

#: The offline chain's other tables: (variant, title, estimators shown or None for all). ``{other}`` is the
#: U-turn rule not in the main tables.
_OFFLINE_VARIANTS = (
    ("uturn-{other}", "arithmetic = offline, U-turn {other}d (the other rule; K fitted with it)", None),
    ("height-unknown", "arithmetic = offline, height UNKNOWN: a 1.70 m adult assumed for every subject (K fitted "
     "with those lengths; M3 has no K to absorb them)", None),
    ("m4-per-fold", "arithmetic = offline, M4 with the exponent chosen per fold (K refitted with it; M4 row only)", ("M4",)),
    ("m3-single-support-speed", "arithmetic = offline, M3's double support covered at the single support's speed "
     "(S1 (T - T_ss) / T_ss instead of the foot length; M3 row only)", ("M3",)),
    ("m4-range-share", "arithmetic = offline, M4 with a step below the trial's median range counted as its share of a "
     "typical step (K refitted with it; M4 row only; not kept: its gain's interval includes zero)", ("M4",)),
    ("m4-duration-share", "arithmetic = offline, M4 times the step's share of the trial's median duration (K refitted "
     "with it; M4 row only; not kept: its gain's interval includes zero)", ("M4",)),
    ("baseline", "baseline, the recipe (host/gait/recipe.py: gaps interpolated, gravity from the first second, "
     "steps between the peaks of the 3 Hz zero-phase low-pass, M2 h with v and x zero at both ends, "
     "M4 range^(1/4), K = {distance} / first trial's sum)", ("M2", "M4")),
)
#: Tables printed only when their variant was run.
_OPTIONAL_VARIANTS = (
    ("no-prior", "arithmetic = offline, NO K prior: K from trial 1 alone (the paper's K)"),
    ("k-prior", "arithmetic = offline, with the K prior: K from trial 1 shrunk toward the other subjects' K "
     "(not kept: its gain's interval includes zero)"),
)


@dataclass(frozen=True)
class IpolOutputs:
    """Where the evaluation's files go: ``out`` (one row per trial, estimator and arithmetic), ``steps`` and
    ``events`` (beside it, ``<stem>_steps.csv`` and ``<stem>_events.csv``) and ``figure`` (the box plot)."""

    out: Path
    figure: Path
    steps: Path
    events: Path

    @classmethod
    def beside(cls, out: str | Path, figure: str | Path | None = None) -> IpolOutputs:
        """The outputs of ``out``; the figure defaults to ``out`` with ``.png``."""
        out = Path(out)
        return cls(out=out, figure=Path(figure) if figure else out.with_suffix(".png"),
                   steps=out.with_name(out.stem + "_steps.csv"), events=out.with_name(out.stem + "_events.csv"))


@dataclass(frozen=True)
class IpolReport:
    """What ``gaitlog evaluate ipol`` writes and prints: the evaluation's result
    (:class:`~gaitlog.host.studies.ipol_evaluation.IpolResult`) and the settings it ran with."""

    result: IpolResult
    outputs: IpolOutputs
    sampling_rate_hz: float
    adc_bits: int
    uturn: str
    arithmetic: tuple[str, ...]
    n_resamples: int = BOOTSTRAP_RESAMPLES
    distance_m: float = IPOL_DISTANCE_M

    def write_outputs(self) -> None:
        """The figure first (it can fail on a broken matplotlib), then the CSVs, each written atomically."""
        res, paths = self.result, self.outputs
        rows = [{**{c: str(r[c]) for c in CSV_COLUMNS},
                 "walked_distance_m": f"{r['walked_distance_m']:.10g}", "distance_m": f"{r['distance_m']:.4f}",
                 "ratio": f"{r['ratio']:.5f}",
                 "steps_outside_k_range": "" if r["steps_outside_k_range"] is None else str(r["steps_outside_k_range"])}
                for r in res.rows]
        png = render_chain_boxplots_png(main_rows(res.rows), self.arithmetic,
                                        title=f"IPOL lower back, {self.sampling_rate_hz:g} Hz, {self.adc_bits} bits, "
                                        "K from trial 1 (offline chain) for every chain")
        atomic_write_bytes(paths.figure, png)
        atomic_write_text(paths.out, rows_csv_text(rows, CSV_COLUMNS))
        if res.step_rows:
            atomic_write_text(paths.steps, rows_csv_text(res.step_rows, STEP_COLUMNS))
        if res.trial_events:
            atomic_write_text(paths.events, rows_csv_text(res.trial_events, EVENT_COLUMNS))

    def to_json(self) -> str:
        """The rows and the per-trial events as one JSON document."""
        res = self.result
        return json_text({"out": str(self.outputs.out), "rows": res.rows, "trial_events": res.trial_events,
                          "calibration_trials": {str(s): t for s, t in res.calibration_trials.items()},
                          "skipped": res.skipped})

    def format_table(self) -> str:
        """The printed report: the heading, the tuned constants, the summary tables, the choices, the events, the
        device checks and the files written."""
        res, arith, resamples = self.result, self.arithmetic, self._resamples()
        lines = [self._heading(), format_tuning(res)]
        for a, k_from, title in self._main_tables():
            lines += _summary_table(title, summarise(res.rows, arithmetic=a, k_from=k_from, intervals=True,
                                                     n_resamples=resamples))
        if "offline" in arith:
            lines += self._offline_tables()
            lines.append(format_choices(choice_gains(res, n_resamples=resamples)
                                        + count_gains(res, n_resamples=resamples))
                         if resamples > 0 else "choices against the simpler one: not scored (" + (
                             "no bootstrap resamples" if self.n_resamples == 0 else "one subject: a bootstrap over "
                             "subjects has nothing to resample") + ", so no interval to keep a rule by)")
        lines.append("steps|err|: median over trials of |detected - reference steps| (% and steps); signed: median of "
                     "detected - reference; outside K: steps outside the range K was calibrated on (duration, the "
                     "estimator's input or length), of the steps in the trials")
        lines.append(format_events(res))
        lines.append(format_done(done_figures(res)) if set(arith) == set(ARITHMETICS) else self._replay_line())
        lines.append("fixed-point saturation/wrap: " + ("; ".join(res.saturation) if res.saturation else "none"))
        lines += [f"skipped: {msg}" for msg in res.skipped]
        paths = self.outputs
        lines.append(f"written: {paths.out}" + (f", {paths.steps}" if res.step_rows else "")
                     + (f", {paths.events}" if res.trial_events else "") + f", {paths.figure}")
        return "\n".join(lines)

    def _distance_text(self) -> str:
        """The walked distance as the headings name it: ``20 m``, or ``the walked distance`` when trials differ."""
        walked = {r["walked_distance_m"] for r in self.result.rows}
        return f"{walked.pop():g} m" if len(walked) == 1 else "the walked distance"

    def _resamples(self) -> int:
        """The subject bootstrap's resamples: none with one subject (every resample would be that subject: an
        interval of width zero, not a 95 % one)."""
        return self.n_resamples if len(self.result.calibrations) >= 2 else 0

    def _heading(self) -> str:
        res, arith = self.result, self.arithmetic
        mine = [r for r in main_rows(res.rows)
                if r["estimator"] == "M1" and r["arithmetic"] == arith[0] and r["k_from"] == "offline"]
        sources = Counter(r["lengths_source"] for r in mine)
        assumed = sorted({r["subject"] for r in mine if r["lengths_source"] != "subject-height"})
        return (f"{len(res.calibrations)} subjects, {res.n_trials} evaluated trials, {self.sampling_rate_hz:g} Hz, "
                f"{self.adc_bits} bits, ratio = estimated / {self._distance_text()} walked, U-turn {self.uturn}d, "
                "emulated logger with its on-line algorithm on; one K per "
                f"subject, fitted on {_calibration_text(res.calibration_trials)} with the offline chain, for every "
                "arithmetic"
                + (" and shrunk toward the other subjects' K (the K prior)" if K_PRIOR_IN_MAIN else "")
                + "; lengths from each subject's height ("
                + ", ".join(f"{n} trials {src}" for src, n in sources.items())
                + (f"; no height in the JSON of subject {', '.join(map(str, assumed))}" if assumed else "")
                + f"): {LENGTH_MODEL}")

    def _main_tables(self) -> list[tuple[str, str, str]]:
        tables = [(a, "offline", f"arithmetic = {a}") for a in self.arithmetic]
        if "online-fixed" in self.arithmetic:
            tables.append(("online-fixed", "own", "on-line fixed with its OWN K (fitted on its own records of trial "
                           "1; the device as it would be used -- a different K, not a comparison)"))
        return tables

    def _offline_tables(self) -> list[str]:
        rows = self.result.rows
        other = next(u for u in ("exclude", "include") if u != self.uturn)
        lines: list[str] = []
        for variant, title, shown in _OFFLINE_VARIANTS:
            summary = summarise(rows, arithmetic="offline", variant=variant.format(other=other), intervals=True,
                                n_resamples=self._resamples())
            lines += _summary_table(title.format(other=other, distance=self._distance_text()),
                                    [x for x in summary if shown is None or x["estimator"] in shown])
        for variant, title in _OPTIONAL_VARIANTS:
            if any(r["variant"] == variant for r in rows):
                lines += _summary_table(title, summarise(rows, arithmetic="offline", variant=variant, intervals=True,
                                                         n_resamples=self._resamples()))
        return lines

    def _replay_line(self) -> str:
        chk = self.result.replay_checks
        same = sum(c["n_identical"] == c["n_compared"] for c in chk)
        return (f"device step records = host replay, byte for byte: {same} of {len(chk)} trials, "
                f"{sum(c['n_identical'] for c in chk)} of {sum(c['n_compared'] for c in chk)} records")


def evaluate_ipol(folder: str | Path, outputs: IpolOutputs, *, sampling_rate_hz: float, adc_bits: int,
                  uturn: str = "include", arithmetic: str = "all", n_resamples: int = BOOTSTRAP_RESAMPLES,
                  progress: Callable[[str], object] | None = None, distance_m: float = IPOL_DISTANCE_M) -> IpolReport:
    """The IPOL evaluation of ``folder`` (:func:`gaitlog.host.studies.ipol_evaluation.evaluate_folder`) as a
    report whose files go to ``outputs``; nothing is written until :meth:`IpolReport.write_outputs`.
    ``arithmetic`` is one of :data:`~gaitlog.host.studies.ipol_evaluation.ARITHMETICS` or ``"all"``;
    ``n_resamples``: the subject bootstrap's resamples of the printed intervals (0: none, and no choice scored);
    ``distance_m``: the distance walked between each trial's boundaries (:class:`~gaitlog.host.studies.
    ipol_evaluation.IpolEvaluation`)."""
    arithmetic = ARITHMETICS if arithmetic == "all" else (arithmetic,)
    res = evaluate_folder(folder, sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits, uturn=uturn,
                          arithmetic=arithmetic, progress=progress, distance_m=distance_m)
    return IpolReport(result=res, outputs=outputs, sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits,
                      uturn=uturn, arithmetic=arithmetic, n_resamples=n_resamples, distance_m=distance_m)


def _calibration_text(trials: dict[int, int]) -> str:
    """Which trial each subject's K was fitted on: ``trial 1``, or the subjects whose first readable trial is
    another named."""
    other = {s: t for s, t in trials.items() if t != 1}
    if not other:
        return "trial 1"
    return ("its first readable trial (" + ("" if len(other) == len(trials) else "trial 1; ")
            + ", ".join(f"subject {s}: trial {s}-{t}" for s, t in other.items()) + ")")


def _ci(interval) -> str:
    return "" if interval is None else f"[{interval[0]:.3f}, {interval[1]:.3f}]"


def _summary_table(title: str, summary: list[dict]) -> list[str]:
    """One summary table (:func:`gaitlog.host.studies.ipol_evaluation.summarise`) as lines."""
    lines = [title, f"{'estimator':<10}{'n':>4}{'median':>8}{'q1':>8}{'q3':>8}{'IQR':>7}{'min':>8}{'max':>8}"
             f"{'median 95% CI':>16}{'IQR 95% CI':>16}{'steps|err|%':>13}{'|err|':>6}{'signed':>7}{'outside K':>14}"]
    for s in summary:
        if not s.get("n"):
            lines.append(f"{s['estimator']:<10}{0:>4}")
            continue
        out_k = "-" if s["steps_outside_k_range"] is None else f"{s['steps_outside_k_range']}/{s['steps_total']}"
        lines.append(f"{s['estimator']:<10}{s['n']:>4}{s['median']:>8.3f}{s['q1']:>8.3f}{s['q3']:>8.3f}"
                     f"{s['iqr']:>7.3f}{s['min']:>8.3f}{s['max']:>8.3f}{_ci(s.get('median_ci')):>16}"
                     f"{_ci(s.get('iqr_ci')):>16}{s['step_error_median_pct']:>13.2f}"
                     f"{s['step_error_median_abs']:>6.1f}{s['step_error_median_signed']:>+7.1f}{out_k:>14}")
    return lines
