"""``gaitlog budget``: does a logger configuration fit a PIC16F877 (ADC, cycles, RAM, program memory, EEPROM
bandwidth, dump time)? ``--measure-kernels`` re-measures the arithmetic kernels' cycles in gpsim."""

from __future__ import annotations

import argparse
import dataclasses
import json

# numpy and everything that imports it (firmware_sim, protocol.steps, the decoders) is imported inside the
# functions that use it: `gaitlog --help` must not load it.
from gaitlog.host.commands._options import (
    SEED,
    add_logger_rate_option,
    add_verbosity_options,
    logger_rate_hz,
    number,
    verbosity,
    whole,
)
from gaitlog.host.errors import HostError, UsageError

HELP = ("RAM, cycles per sample, program memory, EEPROM bandwidth and dump time of a logger configuration "
        "against the PIC16F877")
#: Shown under "examples:" by ``gaitlog budget --help``.
EXAMPLES = (
    "gaitlog budget",
    "gaitlog budget --all --json",
    "gaitlog budget --logger-rate 100 --crystal 20",
    "gaitlog budget --measure",
    "gaitlog budget --measure --recording walk.glimg --json",
)
#: Samples ``--measure`` runs in gpsim by default (a minute of walking at 50 Hz).
MEASURE_SAMPLES = 3000
CONFIG_NAMES = ("alvarez-50", "alvarez-100", "morris-5", "morris-6", "hall")


def configure(parser: argparse.ArgumentParser) -> None:

    parser.add_argument("--config", metavar="NAME",
                        help="a configuration of the seed papers: " + ", ".join(CONFIG_NAMES) + " (default "
                             "alvarez-50: the Alvarez logger; --logger-rate, --crystal, --channels and --estimator "
                             "change it)")
    parser.add_argument("--all", action="store_true", help="budget the five configurations, one after the other")
    add_logger_rate_option(parser)
    parser.add_argument("--crystal", type=number(minimum=0.032, maximum=20, unit="MHz"), metavar="MHZ",
                        help="PIC oscillator, MHz (default 18.432, the baud-rate crystal; hall: 20; at most 20)")
    parser.add_argument("--channels", type=whole(minimum=1, maximum=8), metavar="N",
                        help="ADC channels sampled, 1-8 (default: the configuration's)")
    parser.add_argument("--estimator", choices=("on", "off"),
                        help="the on-line step estimator (default: on for the Alvarez logger, off otherwise)")
    parser.add_argument("--seed", type=SEED, default=0, help="simulated walker whose walk is counted (default 0)")
    parser.add_argument("--json", action="store_true", help="print the budget as one JSON document instead")
    parser.add_argument("--measure-kernels", action="store_true",
                        help="run the PIC assembly kernels in gpsim (bit-exact check against fixedpoint.py, cycles "
                             "per call) and rewrite firmware_sim/pic/kernel_cycles.json; needs gputils and gpsim")
    parser.add_argument("--measure", action="store_true",
                        help="run the firmware's assembly part (sampling interrupt, steps 1-3 of the algorithm) in "
                             "gpsim on a walk and report its cycles per sample, RAM and program words as measured, "
                             "beside the model's estimate and error; without gputils/gpsim, the model's figures "
                             "marked estimated")
    parser.add_argument("--recording", metavar="FILE",
                        help="with --measure: the recording to run (any file gaitlog decode reads; 10-bit codes; "
                             "default: the simulated walker of --seed)")
    parser.add_argument("--limit", type=whole(minimum=1), metavar="N",
                        help=f"with --measure: run the first N valid samples (default {MEASURE_SAMPLES:,}: a minute "
                             "at 50 Hz, about ten seconds of gpsim)")
    add_verbosity_options(parser)


def _config(args: argparse.Namespace):
    """The configuration the options ask for (a :class:`gaitlog.firmware_sim.budget.LoggerConfig`)."""

    from gaitlog.firmware_sim.budget import CONFIGURATIONS

    name = args.config or "alvarez-50"
    if name not in CONFIGURATIONS:
        raise UsageError(f"--config {name!r} is not one of {', '.join(CONFIGURATIONS)}")
    c = CONFIGURATIONS[name]
    changes = {}
    if args.logger_rate is not None:
        changes["sampling_rate_hz"] = float(args.logger_rate)
    if args.crystal is not None:
        changes["fosc_hz"] = args.crystal * 1e6
    if args.channels is not None:
        changes["adc_channels"] = args.channels
    if args.estimator is not None:
        changes["online_estimator"] = args.estimator == "on"
    return dataclasses.replace(c, **changes) if changes else c


def _check(c) -> None:

    if not (1.0 <= c.sampling_rate_hz <= 100_000.0):
        raise UsageError(f"--logger-rate {c.sampling_rate_hz:g} Hz is outside 1 .. 100000 Hz")
    if not (0.032e6 <= c.fosc_hz <= 20e6):
        raise UsageError(f"--crystal {c.fosc_hz / 1e6} MHz is outside the PIC16F877's 0.032 .. 20 MHz")
    if not (1 <= c.adc_channels <= 8):
        raise UsageError(f"--channels {c.adc_channels} is outside the PIC16F877's 1 .. 8 analog inputs")
    if c.online_estimator and c.adc_channels != 3:
        raise UsageError(f"--estimator on reads the Alvarez logger's three axes; --channels is {c.adc_channels}")
    if c.online_estimator and c.sampling_rate_hz > 1000.0:
        raise UsageError(f"--estimator on: the walk is simulated at 1 .. 1000 Hz, not {c.sampling_rate_hz:g} Hz")


def _check_measure(args: argparse.Namespace, configs: list) -> None:
    """``--measure``, ``--recording`` and ``--limit`` go together, and only with the Alvarez logger."""

    if (args.recording is not None or args.limit is not None) and not args.measure:
        raise UsageError("--recording and --limit choose the walk of --measure; add --measure")
    if args.measure and (args.all or not configs[0].online_estimator or configs[0].adc_channels != 3):
        raise UsageError("--measure runs the Alvarez logger's assembly (three axes, on-line estimator on); "
                         "it takes no --all, --estimator off or --channels other than 3")


def _walk(c, seed: int) -> dict:
    """The on-line algorithm on a simulated walker at ``c``'s rate and crystal: its counters."""
    from gaitlog.firmware_sim.adc import Adc
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walking import Walking
    from gaitlog.protocol.steps import StepConfig

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


def _chip(args: argparse.Namespace, c, walk: dict | None):
    """The assembly part measured in gpsim (:func:`gaitlog.firmware_sim.pic.chip_budget.chip_budget`) on
    ``--recording`` or the budget's simulated walk."""
    import numpy as np

    from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
    from gaitlog.firmware_sim.pic.chip_budget import chip_budget
    from gaitlog.firmware_sim.pic.gpsim_logger import PicError
    from gaitlog.protocol.packing import FLAG_SESSION_START

    limit = args.limit or MEASURE_SAMPLES
    if args.recording is None and walk is None:
        raise HostError(f"--measure: no walk to run at {c.sampling_rate_hz:g} Hz (no cycles left for the algorithm)")
    if args.recording is None:
        codes = np.asarray(walk["codes"], np.int64)[:limit]
        flags = np.zeros(codes.shape[0], np.int64)
        flags[0] = FLAG_SESSION_START
        cal, rate, first, source = walk["calibration"], c.sampling_rate_hz, 0, f"simulated walker {walk['subject']}"
    else:
        from gaitlog.host.files.decode import decode_file

        rec = decode_file(args.recording)
        keep = np.flatnonzero(rec.valid)[:limit]
        if rec.adc_bits != 10 or keep.size == 0:
            raise HostError(f"{args.recording}: {rec.adc_bits}-bit codes, {keep.size} valid samples; the assembly "
                            "runs on the PIC16F877's 10-bit codes")
        codes, flags, rate = rec.codes[keep], rec.flags[keep], rec.sampling_rate_hz
        cal = rec.header.calibration if rec.header is not None else None
        first, source = int(rec.sample_numbers[keep[0]]), str(args.recording)
    cal_q = CalibrationQ.from_protocol(cal) if cal is not None else nominal_calibration_q()
    try:
        return chip_budget(codes, flags, cal_q, sampling_rate_hz=rate, fosc_hz=c.fosc_hz, source=source,
                           first_sample_number=first)
    except (PicError, ValueError) as err:
        raise HostError(f"--measure: {err}") from err


def _wear(c, walk: dict):
    """The memories' write cycles: a fresh logger in overwrite mode logs the walk over and over (continuous
    logging) for :data:`~gaitlog.firmware_sim.budget.WEAR_RUN_SAMPLES`, in blocks shorter than a step (the
    records are stored one by one, as they come); its endurance budget."""
    import numpy as np

    from gaitlog.firmware_sim.adc import Adc
    from gaitlog.firmware_sim.algorithms import kernel
    from gaitlog.firmware_sim.budget import WEAR_RUN_SAMPLES, endurance_budget
    from gaitlog.firmware_sim.device import Logger

    logger = Logger(adc=Adc(sampling_rate_hz=c.sampling_rate_hz), sampling_rate_hz=c.sampling_rate_hz,
                    step_config=walk["step_config"], overwrite=True)
    fw = logger.firmware
    fw.fosc_hz = c.fosc_hz
    fw.start_logging(start_time_s=0, overwrite=True)
    codes = np.asarray(walk["codes"], np.int64)
    codes = np.tile(codes, (-(-WEAR_RUN_SAMPLES // codes.shape[0]), 1))[:WEAR_RUN_SAMPLES]
    block = fw.step_algorithm.config.counts.min_step       # at most one step record a block: each its own write
    for a in range(0, codes.shape[0], block):
        fw.log_samples(codes[a:a + block])
    flush = int(fw.step_algorithm.config.cfg_i[kernel.CI_FLUSH])
    fw.stop_logging()
    return endurance_budget(c, duration_s=codes.shape[0] / c.sampling_rate_hz, bank_wear=logger.bank.wear,
                            step_wear=logger.step_eeprom.wear, data_wear=logger.data_eeprom.wear,
                            flush_samples=flush)


def _budget(c, seed: int, args: argparse.Namespace | None = None) -> tuple[dict, list[str]]:
    """One configuration: the JSON document and the printed lines."""
    from gaitlog.firmware_sim.budget import (
        LIFETIME_HOURS_PER_DAY,
        LIFETIME_TARGET_YEARS,
        PIC_PROGRAM_WORDS,
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

    ram = ram_budget(c.sampling_rate_hz, online_estimator=c.online_estimator)
    program = program_budget(c.online_estimator)
    storage = storage_budget(c)
    walk = None
    if c.online_estimator and algorithm_cycles_per_sample(c.sampling_rate_hz, c.fosc_hz, c) > 0:
        walk = _walk(c, seed)
    cycles = cycle_budget(walk["alg"].cycles if walk else None, c.sampling_rate_hz, fosc_hz=c.fosc_hz, config=c)
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
           "logging_per_sample": cycles.logging, "mean_algorithm": cycles.mean_algorithm,
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
        "fits_10_years": endurance.fits(), "lifetime_target_years": LIFETIME_TARGET_YEARS,
        "limiting": endurance.limiting.name,
        **{f"years_at_{h:g}_h_a_day": endurance.years(h) for h in LIFETIME_HOURS_PER_DAY},
        "regions": [{"name": r.name, "unit": r.unit, "worst_unit": r.worst_unit, "worst_cycles": r.worst_cycles,
                     "cycles_per_s": endurance.rate_per_s(r), "endurance_cycles": r.endurance_cycles,
                     **{f"years_at_{h:g}_h_a_day": endurance.lifetime_years(r, h) for h in LIFETIME_HOURS_PER_DAY},
                     "source": r.source} for r in endurance.regions]}
    if args is not None and args.measure:
        chip = _chip(args, c, walk)
        lines += [""] + chip.lines()
        doc["assembly_part"] = chip.to_dict()
    short = shortfalls(c, ram, cycles, program, storage)
    doc["does_not_fit"] = short
    doc["fits"] = not short
    lines += [""] + (["does not fit:"] + [f"  - {s}" for s in short] if short else ["everything fits"])
    return doc, lines


def _measure_kernels(args: argparse.Namespace) -> int:
    from gaitlog.firmware_sim.pic.gpsim_bench import (
        CYCLE_TABLE_PATH,
        cycle_table,
        gpsim_version,
        markdown_table,
        measure,
        missing_tools,
        write_cycle_table,
    )

    reason = missing_tools()
    if reason:
        raise HostError(f"--measure-kernels: {reason}")
    runs, words = measure()
    bad = {n: r.mismatches[:3] for n, r in runs.items() if r.mismatches}
    for r in runs.values():
        s = r.summary()
        print(f"{s['kernel']:<9s} {s['vectors']:6,d} vectors, {s['mismatches']} differ; cycles min {s['cycles_min']}, "
              f"mean {s['cycles_mean']:g}, max {s['cycles_max']}  ({s['doc']})")
    if bad:
        raise HostError(f"kernels differ from fixedpoint.py (operands, gpsim, fixedpoint): {bad}; table not written")
    table = cycle_table(runs, gpsim_version(), words)
    write_cycle_table(table)
    print(f"kernels: {words} program words; wrote {CYCLE_TABLE_PATH}; the table of docs/FIXED_POINT.md:\n")
    print(markdown_table(table))
    return 0


def run(args: argparse.Namespace) -> int:

    from gaitlog.firmware_sim.budget import CONFIGURATIONS

    if args.measure_kernels:
        return _measure_kernels(args)
    if args.logger_rate is not None:
        args.logger_rate = logger_rate_hz(args)
    if args.all:
        if any(v is not None for v in (args.config, args.logger_rate, args.crystal, args.channels, args.estimator)):
            raise UsageError("--all budgets the five configurations as they are; it takes no --config, --logger-rate, "
                            "--crystal, --channels or --estimator")
        configs = list(CONFIGURATIONS.values())
    else:
        configs = [_config(args)]
    for c in configs:
        _check(c)
    _check_measure(args, configs)
    results = [_budget(c, args.seed, args) for c in configs]
    code = 0 if all(d["fits"] for d, _ in results) else 1
    if args.json:
        print(json.dumps(results[0][0] if not args.all else [d for d, _ in results], indent=2))
        return code
    if verbosity(args) >= 0:
        print("\n\n".join("\n".join(ln for ln in lines) for _, lines in results))
    return code
