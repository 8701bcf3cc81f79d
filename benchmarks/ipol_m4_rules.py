"""Report: M4's length rules for weak steps against Weinberg's length, on an IPOL folder.

Runs the offline chain of ``gaitlog evaluate ipol`` (the leave-one-subject-out event constants, K from each
subject's first trial, every step of the other trials summed) and scores M4 with each rule below, K refitted with
it, against the shipped chain (Weinberg's ``K range^(1/4)``) measured in the same run: median and IQR of the 20 m
ratio with 95 % subject-bootstrap intervals, and the gain in IQR and in the median ``|log ratio|`` (shipped minus
rule, the same subject draws for both). No rule has a constant chosen on the recordings, but choosing among them
on these nine subjects is a choice of its own: the rows `evaluate ipol` prints (``m4-range-share``,
``m4-duration-share``) were fixed before the others were tried. The table of ``docs/topics/accuracy.md`` ("M4's
weak steps") is this output on the dev subjects. About 40 s of CPU.

    python benchmarks/ipol_m4_rules.py [../shared/data/ipol-lowerback-dev]
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.gait.estimators.weinberg import range_share_length_m, weinberg_length_m  # noqa: E402
from gaitlog.host.studies.ipol_decomposition import Mix, decompose  # noqa: E402
from gaitlog.host.studies.ipol_evaluation import (  # noqa: E402
    IpolEvaluation,
    choice_gain,
    log_error_gain,
    section_mask,
    subject_intervals,
    trial_steps,
)

DEFAULT_FOLDER = ROOT.parent / "shared" / "data" / "ipol-lowerback-dev"


def _typical(values: np.ndarray, where: np.ndarray) -> float:
    v = values[where]
    return float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan")


def _bout_typical(table, values: np.ndarray) -> np.ndarray:
    """Per step, the median of ``values`` over its walking bout."""
    out = np.full(values.size, _typical(values, np.ones(values.size, bool)))
    for b in np.unique(table.bout):
        sel = table.bout == b
        if np.isfinite(values[sel]).any():
            out[sel] = np.nanmedian(values[sel])
    return out


#: Each rule: ``(table, section mask, the subject's calibration-trial median range) -> per step raw M4 (K = 1)``.
RULES: dict[str, Callable] = {
    "Weinberg, the shipped chain": lambda t, s, c: weinberg_length_m(t.acc_range_m_s2, k=1.0),
    "range share, typical = the trial's median (m4-range-share)": lambda t, s, c: range_share_length_m(
        t.acc_range_m_s2, _typical(t.acc_range_m_s2, s), k=1.0),
    "range share, typical = the bout's median": lambda t, s, c: range_share_length_m(
        t.acc_range_m_s2, _bout_typical(t, t.acc_range_m_s2), k=1.0),
    "range share, typical = the recording's median": lambda t, s, c: range_share_length_m(
        t.acc_range_m_s2, _typical(t.acc_range_m_s2, np.ones(t.n_steps, bool)), k=1.0),
    "range share, typical = the calibration trial's median": lambda t, s, c: range_share_length_m(
        t.acc_range_m_s2, c, k=1.0),
    "duration share (m4-duration-share)": lambda t, s, c: weinberg_length_m(t.acc_range_m_s2, k=1.0) * np.minimum(
        1.0, t.duration_s / _typical(t.duration_s, s)),
    "square-root range share below the median (pendulum, h ~ range)": lambda t, s, c: np.where(
        t.acc_range_m_s2 < (m := _typical(t.acc_range_m_s2, s)), m ** 0.25 * np.sqrt(t.acc_range_m_s2 / m),
        weinberg_length_m(t.acc_range_m_s2, k=1.0)),
    "square-root M2 excursion share below the median (pendulum)": lambda t, s, c: np.where(
        (h := t.vertical_excursion_m["M2"]) < (hm := _typical(h, s)),
        _typical(t.acc_range_m_s2, s) ** 0.25 * np.sqrt(h / hm), weinberg_length_m(t.acc_range_m_s2, k=1.0)),
    "steps below 1/4 of the median range left out": lambda t, s, c: np.where(
        t.acc_range_m_s2 < 0.25 * _typical(t.acc_range_m_s2, s), 0.0, weinberg_length_m(t.acc_range_m_s2, k=1.0)),
    "steps below 1/2 of the median range left out": lambda t, s, c: np.where(
        t.acc_range_m_s2 < 0.5 * _typical(t.acc_range_m_s2, s), 0.0, weinberg_length_m(t.acc_range_m_s2, k=1.0)),
    "Weinberg with the exponent 1/2": lambda t, s, c: weinberg_length_m(t.acc_range_m_s2, k=1.0, exponent=0.5),
}


def rule_rows(evaluation: IpolEvaluation, rule: Callable) -> list[dict]:
    """M4's ratio per scored trial with ``rule``, K = 20 m over the first trial's sum (scored as the main rows)."""
    rows = []
    for s, fit in evaluation.fits_.fits.items():
        trials = fit.replayed.trials
        sec0 = section_mask(trials[0], fit.offline[0])
        calib = _typical(fit.offline[0].acc_range_m_s2, sec0)
        sums = []
        for rt, table in zip(trials, fit.offline, strict=True):
            out = table.select(np.ones(table.n_steps, bool))
            out.raw_m = {**table.raw_m, "M4": rule(table, section_mask(rt, table), calib)}
            sec, counts = trial_steps(rt, out, uturn="include")
            sums.append(float(np.sum(sec.filled(sec.raw_m["M4"])[0][counts])))
        rows += [dict(subject=s, trial=rt.trial, estimator="M4", ratio=d / sums[0])
                 for rt, d in zip(trials[1:], sums[1:], strict=True)]
    return rows


def _line(label: str, rows: list[dict], shipped: list[dict]) -> str:
    ci = subject_intervals(rows, "M4")
    g, lg = choice_gain(shipped, rows, "M4"), log_error_gain(shipped, rows, "M4")
    return (f"  {label}: median {ci['median'][0]:.3f}, IQR {ci['iqr'][0]:.3f} [{ci['iqr'][1]:.3f}, "
            f"{ci['iqr'][2]:.3f}]; gain in IQR {g[0]:+.3f} [{g[1]:+.3f}, {g[2]:+.3f}], in median |log ratio| "
            f"{lg[0]:+.3f} [{lg[1]:+.3f}, {lg[2]:+.3f}]")


def main(argv: list[str]) -> int:
    folder = Path(argv[0]) if argv else DEFAULT_FOLDER
    if not folder.is_dir():
        print(f"ipol_m4_rules: {folder}: no such folder", file=sys.stderr)
        return 2
    evaluation = IpolEvaluation(arithmetic=("offline",)).run(folder)
    shipped = rule_rows(evaluation, RULES["Weinberg, the shipped chain"])
    main_m4 = [r for r in evaluation.result_.rows if r["variant"] == "main" and r["estimator"] == "M4"]
    worst = max(abs(a["ratio"] - b["ratio"]) for a, b in zip(shipped, main_m4, strict=True))
    print(f"M4 per rule (K refitted with it; 95 % subject-bootstrap intervals; gain = shipped - rule; the shipped "
          f"rows reproduce evaluate ipol's main M4 within {worst:.1e}):")
    for label, rule in RULES.items():
        print(_line(label, rule_rows(evaluation, rule), shipped))
    recipe = Mix(boundaries="recipe")
    print(_line("Weinberg over the recipe's step boundaries (M4 only)",
                decompose(evaluation, [recipe]).rows[recipe.label()], shipped))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
