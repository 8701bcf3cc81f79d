"""``gaitlog budget``: does a logger configuration fit a PIC16F877 (ADC, cycles, RAM, program memory, EEPROM
bandwidth, dump time)? ``--measure-kernels`` re-measures the arithmetic kernels' cycles in gpsim."""

from __future__ import annotations

import argparse

# The budget library loads numpy, the emulated device and the decoders: imported inside run (and the gpsim bench
# inside _measure_kernels) so that `gaitlog --help` does not load them.
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
                        help="run the firmware's assembly part (sampling interrupt, steps 1-5 of the on-line "
                             "algorithm with its step records) in gpsim on a walk and report its cycles per sample "
                             "(mean, 99th percentile, worst), each step record's cycles, the backlog, RAM and program "
                             "words as measured, beside the model's estimate and error; without gputils/gpsim, the "
                             "model's figures marked estimated")
    parser.add_argument("--recording", metavar="FILE",
                        help="with --measure: the recording to run (any file gaitlog decode reads; 10-bit codes; "
                             "default: the simulated walker of --seed)")
    parser.add_argument("--limit", type=whole(minimum=1), metavar="N",
                        help=f"with --measure: run the first N valid samples (default {MEASURE_SAMPLES:,}: a minute "
                             "at 50 Hz, about ten seconds of gpsim)")
    add_verbosity_options(parser)


def _config(args: argparse.Namespace, configurations: dict):
    """The configuration of ``configurations`` the options ask for (a
    :class:`gaitlog.firmware_sim.budget.LoggerConfig`)."""
    import dataclasses  # not at the top: it loads inspect (ast, dis, tokenize), which `gaitlog --help` does without

    name = args.config or "alvarez-50"
    if name not in configurations:
        raise UsageError(f"--config {name!r} is not one of {', '.join(configurations)}")
    c = configurations[name]
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
    if args.measure_kernels:
        return _measure_kernels(args)
    from gaitlog.host.studies.logger_budget import CONFIGURATIONS, Measure, logger_budget

    if args.logger_rate is not None:
        args.logger_rate = logger_rate_hz(args)
    if args.all:
        if any(v is not None for v in (args.config, args.logger_rate, args.crystal, args.channels, args.estimator)):
            raise UsageError("--all budgets the five configurations as they are; it takes no --config, --logger-rate, "
                            "--crystal, --channels or --estimator")
        configs = list(CONFIGURATIONS.values())
    else:
        configs = [_config(args, CONFIGURATIONS)]
    for c in configs:
        _check(c)
    _check_measure(args, configs)
    report = logger_budget(configs, seed=args.seed, all_configurations=args.all,
                           measure=Measure(args.recording, args.limit or MEASURE_SAMPLES) if args.measure else None)
    code = 0 if report.fits else 1
    if args.json:
        print(report.to_json())
        return code
    if verbosity(args) >= 0:
        print(report.format_table())
    return code
