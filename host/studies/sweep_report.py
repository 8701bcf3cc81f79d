"""What ``gaitlog sweep`` makes of its tasks' results (:func:`sweep_report`): the summary per configuration and
estimator, the smallest ADC width and Q formats that hold, the smallest formats under the converter (ADC width per
converter setting, Q-format set and rounding, measured beside predicted), the M5 rate answer, their CSVs and figures
(:meth:`SweepReport.write_outputs`) and the printed text (:meth:`~SweepReport.format_table`; long tables only
with ``-v``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text
from gaitlog.host.studies.compare import rows_csv_text
from gaitlog.host.studies.compare_report import ReportLines
from gaitlog.host.studies.sweep_figures import figure_dimensions, render_error_vs_png
from gaitlog.host.studies.sweep_grid import (
    SECTION_COLUMNS,
    SPLIT_COLUMNS,
    SUMMARY_COLUMNS,
    format_m5_rate,
    format_smallest_bits,
    format_smallest_formats,
    format_smallest_q,
    format_summary,
    m5_rate_answer,
    smallest_adc_bits,
    smallest_formats,
    smallest_q_formats,
    summarise,
    with_effects,
)

__all__ = ["SweepReport", "sweep_report"]


@dataclass
class SweepReport(ReportLines):
    """The tables of a sweep's results (``results``: :meth:`gaitlog.host.studies.task_store.TaskStore.collect`'s)."""

    results: list[dict] = field(default_factory=list)
    sections: list[dict] = field(default_factory=list)
    splits: list[dict] = field(default_factory=list)
    summary: list[dict] = field(default_factory=list)
    smallest: list[dict] = field(default_factory=list)
    smallest_q: list[dict] = field(default_factory=list)
    smallest_formats: list[dict] = field(default_factory=list)
    m5: dict = field(default_factory=dict)

    def write_outputs(self, out: str | Path) -> list[Path]:
        """``sections.csv``, ``splits.csv``, ``tasks.csv``, ``summary.csv``, ``smallest_bits.csv``,
        ``smallest_q_formats.csv``, ``smallest_formats.csv``, ``m5_rate.csv`` and
        ``figures/error_vs_<dimension>.png`` into ``out``; the figures written. The text's closing lines
        (saturation and wrap, the files written) are added here."""
        out = Path(out)
        atomic_write_text(out / "sections.csv", rows_csv_text(self.sections, SECTION_COLUMNS))
        atomic_write_text(out / "splits.csv", rows_csv_text(self.splits, SPLIT_COLUMNS))
        atomic_write_text(out / "tasks.csv", rows_csv_text([res["task"] for res in self.results]))
        atomic_write_text(out / "summary.csv", rows_csv_text(self.summary, SUMMARY_COLUMNS))
        atomic_write_text(out / "smallest_bits.csv", rows_csv_text(self.smallest))
        atomic_write_text(out / "smallest_q_formats.csv", rows_csv_text(self.smallest_q))
        atomic_write_text(out / "smallest_formats.csv", rows_csv_text(self.smallest_formats))
        atomic_write_text(out / "m5_rate.csv", rows_csv_text(self.m5["rows"]))
        figures = []
        for dim in figure_dimensions(self.summary):
            (out / "figures").mkdir(exist_ok=True)
            figures.append(out / "figures" / f"error_vs_{dim}.png")
            atomic_write_bytes(figures[-1], render_error_vs_png(self.summary, dim, m5=self.m5))
        sat = sum(res["task"]["saturated"] + res["task"]["wrapped"] for res in self.results)
        self.say(f"fixed-point saturation/wrap over all tasks: {sat}")
        self.say(f"written: {out}/sections.csv ({len(self.sections)} rows), splits.csv, tasks.csv, summary.csv, "
                 "smallest_bits.csv, smallest_q_formats.csv, smallest_formats.csv, m5_rate.csv"
                 + (f", figures/ ({', '.join(p.name for p in figures)})" if figures else ""))
        return figures


def sweep_report(results: list[dict], out: str | Path, *, max_printed_rows: int) -> SweepReport:
    """The sweep's tables from its tasks' ``results`` (rows of a folder from before the effects were dimensions:
    effects off); a table longer than ``max_printed_rows`` rows (per calibration mode) is printed with ``-v``
    only. ``out``: the folder named in the text."""
    sections = [with_effects(r) for res in results for r in res["sections"]]
    splits = [with_effects(r) for res in results for r in res["splits"]]
    summary = summarise(sections, splits, [res["task"] for res in results])
    report = SweepReport(results=results, sections=sections, splits=splits, summary=summary,
                         smallest=smallest_adc_bits(summary), smallest_q=smallest_q_formats(summary),
                         smallest_formats=smallest_formats(summary),
                         m5=m5_rate_answer(sections))
    say = report.say
    big = len(summary) > 2 * max_printed_rows                    # both modes
    say(format_summary(summary), 1 if big else 0)
    say("", 1)
    say(format_summary(summary, mode="single-speed"), 1)
    if big:
        say(f"summary: {len(summary) // 2} configuration x estimator rows per calibration mode in {out}/summary.csv "
            "(-v prints them)")
    say()
    say(format_smallest_bits(report.smallest), 1 if len(report.smallest) > max_printed_rows else 0)
    say()
    say(format_smallest_q(report.smallest_q), 1 if len(report.smallest_q) > max_printed_rows else 0)
    say()
    say(format_smallest_formats(report.smallest_formats), 1 if len(report.smallest_formats) > max_printed_rows else 0)
    say()
    say(format_m5_rate(report.m5))
    return report
