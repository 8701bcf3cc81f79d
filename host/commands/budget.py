"""``gaitlog budget``: does the logger with its on-line step algorithm fit a PIC16F877 (RAM and cycles)?"""

from __future__ import annotations

import argparse

from host.commands._options import SEED, add_logger_rate_option, logger_rate_hz, number

HELP = "RAM and cycles per sample of the logger with the on-line step algorithm, against the PIC16F877"


def configure(parser: argparse.ArgumentParser) -> None:
    from host.commands._options import add_verbosity_options

    add_logger_rate_option(parser)
    parser.add_argument("--crystal", type=number(minimum=0.032, maximum=20, unit="MHz"), default=18.432, metavar="MHZ",
                        help="PIC oscillator, MHz (default 18.432, the baud-rate crystal; at most 20)")
    parser.add_argument("--seed", type=SEED, default=0, help="simulated walker whose walk is counted (default 0)")
    parser.add_argument("--json", action="store_true", help="print the budget as one JSON document instead")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from firmware_sim.adc import Adc
    from firmware_sim.budget import (
        algorithm_cycles_per_sample,
        cycle_budget,
        ram_budget,
    )
    from firmware_sim.device import Logger
    from firmware_sim.world.subject import random_subjects
    from firmware_sim.world.walking import Walking
    from host.commands._options import verbosity
    from host.errors import HostError
    from protocol.steps import StepConfig

    args.logger_rate = logger_rate_hz(args)
    fosc = args.crystal * 1e6
    if algorithm_cycles_per_sample(args.logger_rate, fosc) <= 0:
        raise HostError(f"at {args.logger_rate:g} Hz and {args.crystal:g} MHz the logging interrupt alone takes every cycle")
    ram = ram_budget(args.logger_rate)
    subject = random_subjects(1, seed=args.seed)[0]
    logger = Logger(adc=Adc(sampling_rate_hz=args.logger_rate), sampling_rate_hz=args.logger_rate,
                    step_config=StepConfig(step_format=1, leg_length_m=subject.leg_length_m,
                                           foot_length_m=subject.foot_length_m))
    logger.firmware.fosc_hz = fosc
    res = logger.record(Walking(subject=subject, seed=args.seed))
    alg = logger.firmware.step_algorithm
    cycles = cycle_budget(alg.cycles, args.logger_rate, fosc_hz=fosc)
    code = 0 if (ram.fits and cycles.fits) else 1
    ctx = alg.arithmetic_context()
    by_primitive = {k: v / max(1, alg.cycles.samples) for k, v in sorted(ctx.cycles.items(), key=lambda kv: -kv[1])}
    if args.json:
        import json

        doc = {"sampling_rate_hz": args.logger_rate, "fosc_hz": fosc, "fits": code == 0,
               "ram": {"fits": ram.fits, "total_bytes": ram.total_bytes, "algorithm_bytes": ram.algorithm_bytes,
                       "firmware_bytes": ram.firmware_bytes, "lines": ram.lines()},
               "cycles": {"fits": cycles.fits, "available_per_sample": cycles.available,
                          "mean_algorithm": cycles.mean_algorithm, "worst_algorithm": cycles.worst_algorithm,
                          "worst_backlog_samples": cycles.backlog_samples, "mean_load": cycles.mean_load,
                          "lines": cycles.lines(), "per_sample_by_primitive": by_primitive},
               "walker": subject.subject_id, "n_samples": int(res.n_samples),
               "step_records": int(logger.header.steps_written),
               "saturations": ctx.report() if alg.saturations else None}
        print(json.dumps(doc, indent=2))
        return code
    if verbosity(args) < 0:
        return code
    print("\n".join(ram.lines()))
    print()
    print(f"counted on a simulated walker ({subject.subject_id}, {res.n_samples} samples, "
          f"{logger.header.steps_written} step records; fixed point, the logger's own run):")
    print("\n".join(cycles.lines()))
    print("  by primitive (cycles per sample): " + ", ".join(f"{k} {v:,.0f}" for k, v in list(by_primitive.items())[:6]))
    if alg.saturations:
        print(f"  saturations: {ctx.report()}")
    return code
