"""The budget of a logger configuration on a PIC16F877 (``gaitlog budget``): ADC, cycles, RAM, program memory,
EEPROM bandwidth and wear, dump time, and optionally the assembly part measured in gpsim.

:func:`logger_budget` returns a :class:`BudgetReport` (one :class:`ConfigurationBudget` a configuration) whose
:meth:`~BudgetReport.format_table` and :meth:`~BudgetReport.to_json` are what the command prints. The walk counted
is a simulated walker's, logged by the emulated device at the configuration's rate and crystal.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence

import numpy as np

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from gaitlog.firmware_sim.budget import (
    CONFIGURATIONS,
    LIFETIME_HOURS_PER_DAY,
    LIFETIME_TARGET_YEARS,
    PIC_PROGRAM_WORDS,
    WEAR_RUN_SAMPLES,
    LoggerConfig,
    adc_max_sampling_rate_hz,
    algorithm_cycles_per_sample,
    cycle_budget,
    endurance_budget,
    program_budget,
    ram_budget,
    shortfalls,
    storage_budget,
    typical_cycles_per_sample,
)
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.pic import gpsim_journal, gpsim_logger
from gaitlog.firmware_sim.pic.chip_budget import chip_budget
from gaitlog.firmware_sim.pic.gpsim_logger import PicError
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.studies.pic_runs import assembly_input
from gaitlog.protocol.packing import FLAG_SESSION_START
from gaitlog.protocol.steps import StepConfig

__all__ = ["CONFIGURATIONS", "BudgetReport", "ConfigurationBudget", "Measure", "logger_budget"]


@dataclasses.dataclass(frozen=True)
class Measure:
    """The assembly part to run in gpsim: on ``recording`` (any file ``gaitlog decode`` reads; 10-bit codes) or,
    when it is ``None``, on the budget's simulated walker; its first ``limit`` valid samples."""

    recording: str | None
    limit: int


@dataclasses.dataclass(frozen=True)
class ConfigurationBudget:
    """One configuration's budget: ``doc`` (its JSON document) and ``lines`` (its printed text)."""

    doc: dict
    lines: list[str]

    @property
    def fits(self) -> bool:
        """Whether everything fits."""
        return bool(self.doc["fits"])


@dataclasses.dataclass(frozen=True)
class BudgetReport:
    """The budgets of one configuration or, with ``all_configurations``, of each of :data:`CONFIGURATIONS`."""

    budgets: list[ConfigurationBudget]
    all_configurations: bool = False

    @property
    def fits(self) -> bool:
        """Whether every configuration fits."""
        return all(b.fits for b in self.budgets)

    def to_json(self) -> str:
        """One JSON document (a list of them with ``all_configurations``)."""
        doc = [b.doc for b in self.budgets] if self.all_configurations else self.budgets[0].doc
        return json.dumps(doc, indent=2)

    def format_table(self) -> str:
        """The budgets as text, a blank line pair between configurations."""
        return "\n\n".join("\n".join(b.lines) for b in self.budgets)


def logger_budget(configs: Sequence[LoggerConfig], *, seed: int = 0, measure: Measure | None = None,
                  all_configurations: bool = False) -> BudgetReport:
    """Budget each of ``configs`` with the simulated walker ``seed``; ``measure`` runs the assembly part in gpsim
    too (:func:`gaitlog.firmware_sim.pic.chip_budget.chip_budget`).

    Raises
    ------
    HostError
        ``measure`` cannot run (no cycles left for the algorithm, a recording that is not 10-bit, gpsim's error).
    """
    return BudgetReport([_budget(c, seed, measure) for c in configs], all_configurations=all_configurations)


def _walk(c, seed: int) -> dict:
    """The on-line algorithm on a simulated walker at ``c``'s rate and crystal: its counters."""

    subject = random_subjects(1, seed=seed)[0]
    logger = Logger(adc=Adc(sampling_rate_hz=c.sampling_rate_hz), sampling_rate_hz=c.sampling_rate_hz,
                    step_config=StepConfig(step_format=1, leg_length_m=subject.leg_length_m,
                                           foot_length_m=subject.foot_length_m))
    logger.firmware.fosc_hz = c.fosc_hz
    res = logger.record(Walking(subject=subject, seed=seed))
    alg = logger.firmware.step_algorithm
    return {"alg": alg, "subject": subject.subject_id, "n_samples": int(res.n_samples),
            "steps": int(logger.header.steps_written), "codes": res.codes, "step_config": logger.header.step_config,
            "calibration": logger.header.calibration}


def _chip(measure: Measure, c, walk: dict | None):
    """The assembly part measured in gpsim (:func:`gaitlog.firmware_sim.pic.chip_budget.chip_budget`) on
    ``--recording`` or the budget's simulated walk."""
    limit = measure.limit
    if measure.recording is None and walk is None:
        raise HostError(f"--measure: no walk to run at {c.sampling_rate_hz:g} Hz (no cycles left for the algorithm)")
    if measure.recording is None:
        codes = np.asarray(walk["codes"], np.int64)[:limit]
        flags = np.zeros(codes.shape[0], np.int64)
        flags[0] = FLAG_SESSION_START
        cal = walk["calibration"]
        cal_q = CalibrationQ.from_protocol(cal) if cal is not None else nominal_calibration_q()
        rate, first, source = c.sampling_rate_hz, 0, f"simulated walker {walk['subject']}"
    else:
        rec = decode_file(measure.recording)
        run = assembly_input(rec, measure.recording, limit)
        if rec.adc_bits != 10 or run.codes.shape[0] == 0:
            raise HostError(f"{measure.recording}: {rec.adc_bits}-bit codes, {run.codes.shape[0]} valid samples; the "
                            "assembly runs on the PIC16F877's 10-bit codes")
        codes, flags, rate, cal_q = run.codes, run.flags, run.sampling_rate_hz, run.calibration_q
        first, source = run.first_sample_number, run.source
    try:
        return chip_budget(codes, flags, cal_q, sampling_rate_hz=rate, fosc_hz=c.fosc_hz, source=source,
                           first_sample_number=first)
    except (PicError, ValueError) as err:
        raise HostError(f"--measure: {err}") from err


def _wear(c, walk: dict):
    """The memories' write cycles: a fresh logger as shipped (header version 3, the default: the page-commit
    journal in the step EEPROM's journal ring, PROTOCOL.md 2.7) in overwrite mode logs the walk over and over
    (continuous logging) for :data:`~gaitlog.firmware_sim.budget.WEAR_RUN_SAMPLES`, in blocks shorter than a step (the
    records are stored one by one, as they come); its endurance budget."""

    logger = Logger(adc=Adc(sampling_rate_hz=c.sampling_rate_hz), sampling_rate_hz=c.sampling_rate_hz,
                    step_config=walk["step_config"], overwrite=True)
    fw = logger.firmware
    fw.fosc_hz = c.fosc_hz
    before = (logger.bank.wear, logger.step_eeprom.wear.copy(), logger.data_eeprom.wear.copy())  # the run's own
    fw.start_logging(start_time_s=0, overwrite=True)
    codes = np.asarray(walk["codes"], np.int64)
    codes = np.tile(codes, (-(-WEAR_RUN_SAMPLES // codes.shape[0]), 1))[:WEAR_RUN_SAMPLES]
    block = fw.step_algorithm.config.counts.min_step       # at most one step record a block: each its own write
    for a in range(0, codes.shape[0], block):
        fw.log_samples(codes[a:a + block])
    flush = int(fw.step_algorithm.config.cfg_i[kernel.CI_FLUSH])
    fw.stop_logging()
    return endurance_budget(c, duration_s=codes.shape[0] / c.sampling_rate_hz, bank_wear=logger.bank.wear - before[0],
                            step_wear=logger.step_eeprom.wear - before[1],
                            data_wear=logger.data_eeprom.wear - before[2],
                            flush_samples=flush, journal_ring=logger.ring.ring_journal,
                            scratch_tail_writes=fw.step_algorithm.scratch_tail_samples.size)


def _journal_entry(measure: Measure | None) -> float | None:
    """With ``--measure``: the page-commit journal entry's cycles measured in gpsim (``journal.asm``); None (the
    budget's estimate) without it or without gputils/gpsim."""
    if measure is None or gpsim_logger.missing_tools() is not None:
        return None
    try:
        return gpsim_journal.journal_entry_cycles()
    except PicError as err:
        raise HostError(f"--measure: {err}") from err


def _budget(c: LoggerConfig, seed: int, measure: Measure | None = None) -> ConfigurationBudget:
    """One configuration: the JSON document and the printed lines."""
    ram = ram_budget(c.sampling_rate_hz, online_estimator=c.online_estimator)
    program = program_budget(c.online_estimator)
    storage = storage_budget(c)
    walk = None
    if c.online_estimator and algorithm_cycles_per_sample(c.sampling_rate_hz, c.fosc_hz, c) > 0:
        walk = _walk(c, seed)
    entry = _journal_entry(measure)
    cycles = cycle_budget(walk["alg"].cycles if walk else None, c.sampling_rate_hz, fosc_hz=c.fosc_hz, config=c,
                          journal_entry_cycles=entry)
    lines = [f"== {c.name}: {c.sampling_rate_hz:g} Hz, {c.adc_channels} ADC channels, {c.fosc_hz / 1e6:g} MHz, "
             f"on-line estimator {'on' if c.online_estimator else 'off'}", f"   {c.source}" if c.source else "",
             f"ADC: at most {adc_max_sampling_rate_hz(c.adc_channels, c.fosc_hz, c.source_impedance_ohm):,.0f} Hz "
             f"for {c.adc_channels} channels (acquisition + conversion, nothing else)", ""]
    lines += ram.lines() + [""]
    doc = {"config": c.name, "source": c.source, "heading": lines[:3], "sampling_rate_hz": c.sampling_rate_hz, "fosc_hz": c.fosc_hz,
           "adc_channels": c.adc_channels, "online_estimator": c.online_estimator,
           "adc_max_sampling_rate_hz": adc_max_sampling_rate_hz(c.adc_channels, c.fosc_hz, c.source_impedance_ohm),
           "ram": {"fits": ram.fits, "total_bytes": ram.total_bytes, "algorithm_bytes": ram.algorithm_bytes,
                   "firmware_bytes": ram.firmware_bytes, "lines": ram.lines()}}
    cyc = {"fits": cycles.fits and cycles.logging <= cycles.available, "available_per_sample": cycles.available,
           "logging_per_sample": cycles.logging, "page_commit_per_sample": cycles.page_commit[0],
           "page_commit_source": cycles.page_commit[1], "mean_algorithm": cycles.mean_algorithm,
           "worst_algorithm": cycles.worst_algorithm, "worst_backlog_samples": cycles.backlog_samples
           if walk else 0.0, "mean_load": cycles.mean_load}
    if walk:
        alg = walk["alg"]
        ctx = alg.arithmetic_context()
        n = alg.cycles.samples
        from_counts, typical = typical_cycles_per_sample(dict(ctx.calls), n)
        by_primitive = {k: v / max(1, n) for k, v in sorted(ctx.cycles.items(), key=lambda kv: -kv[1])}
        lines += [f"counted on a simulated walker ({walk['subject']}, {walk['n_samples']} samples, {walk['steps']} "
                  "step records; fixed point, the logger's own run):"] + cycles.lines()
        lines.append(f"  algorithm, mean at the kernels' mean costs {typical:10,.0f}   (worst-case costs: "
                     f"{from_counts:,.0f})")
        lines.append("  by primitive (cycles per sample): "
                     + ", ".join(f"{k} {v:,.0f}" for k, v in list(by_primitive.items())[:6]))
        if alg.saturations:
            lines.append(f"  saturations: {ctx.report()}")
        cyc.update({"lines": cycles.lines(), "per_sample_by_primitive": by_primitive,
                    "mean_from_operation_counts": from_counts, "mean_at_kernel_mean_costs": typical,
                    "operation_counts": dict(ctx.calls)})
        doc["ram"]["algorithm_bytes_of_the_run"] = alg.ram_bytes()
        doc.update({"walker": walk["subject"], "n_samples": walk["n_samples"], "step_records": walk["steps"],
                    "saturations": ctx.report() if alg.saturations else None})
    else:
        lines += [f"cycles at {c.sampling_rate_hz:g} Hz, {c.fosc_hz / 1e6:g} MHz: {cycles.available:,.0f} per sample",
                  f"  logging interrupt            {cycles.logging:10,.0f}   "
                  f"(load {100 * cycles.logging / cycles.available:.0f} %)"]
        if c.online_estimator:
            lines.append("  on-line algorithm: no cycles left after the logging interrupt")
        cyc["lines"] = lines[-2:]
    doc["cycles"] = cyc
    lines += [""] + program.lines() + [""] + storage.lines()
    doc["program"] = {"fits": program.fits, "total_words": program.total_words, "limit_words": PIC_PROGRAM_WORDS,
                      "items": [{"name": n, "words": w, "source": s} for n, w, s in program.items],
                      "lines": program.lines()}
    doc["eeprom"] = {"fits": storage.fits, "bytes_per_sample": c.bytes_per_sample,
                     "write_bytes_per_s": storage.write_bytes_per_s,
                     "capacity_bytes_per_s": storage.capacity_bytes_per_s, "page_cycle_ms": 1e3 * storage.page_cycle_s,
                     "recording_s": storage.recording_s, "lines": storage.lines()}
    doc["dump_s"] = storage.dump_s
    endurance = _wear(c, walk) if walk else endurance_budget(c)
    lines += [""] + endurance.lines()
    doc["endurance"] = {
        "measured": endurance.measured, "duration_s": endurance.duration_s, "lines": endurance.lines(),
        "header_version": endurance.header_version,
        "fits_10_years": endurance.fits(), "lifetime_target_years": LIFETIME_TARGET_YEARS,
        "limiting": endurance.limiting.name,
        **{f"years_at_{h:g}_h_a_day": endurance.years(h) for h in LIFETIME_HOURS_PER_DAY},
        "regions": [{"name": r.name, "unit": r.unit, "worst_unit": r.worst_unit, "worst_cycles": r.worst_cycles,
                     "cycles_per_s": endurance.rate_per_s(r), "endurance_cycles": r.endurance_cycles,
                     **{f"years_at_{h:g}_h_a_day": endurance.lifetime_years(r, h) for h in LIFETIME_HOURS_PER_DAY},
                     "source": r.source} for r in endurance.regions]}
    if measure is not None:
        chip = _chip(measure, c, walk)
        lines += [""] + chip.lines()
        doc["assembly_part"] = chip.to_dict()
    short = shortfalls(c, ram, cycles, program, storage)
    doc["does_not_fit"] = short
    doc["fits"] = not short
    lines += [""] + (["does not fit:"] + [f"  - {s}" for s in short] if short else ["everything fits"])
    return ConfigurationBudget(doc, lines)
