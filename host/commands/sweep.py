"""``gaitlog sweep``: a grid over ADC bits x logger rate x sensor noise x Q formats x mounting misalignment x
simulated population x subjects x seeds (:mod:`gaitlog.host.studies.sweep_grid`), run as independent tasks on Dask (a local cluster by default, ``--scheduler``
for an existing one) or in this process (``--serial``); resumable.

Everything goes to the ``--out`` folder: ``tasks/`` (one JSON file per finished task: a re-run with the same
``--out`` computes only the missing ones), ``spec.json`` (the grid), ``sections.csv`` (one row per configuration
x subject x 20 m section x calibration mode x estimator), ``splits.csv`` (per-step error split per
configuration x subject x estimator), ``tasks.csv`` (timing error, saturation), ``summary.csv``, the answers
``smallest_bits.csv``, ``smallest_q_formats.csv``, ``smallest_formats.csv`` (the smallest ADC width per converter
setting, Q-format set and rounding, measured beside predicted) and ``m5_rate.csv``, and
``figures/error_vs_<dimension>.png`` for each swept dimension (:mod:`gaitlog.host.studies.sweep_figures`). The
summary prints, beside each measured quantisation error, the quantisation theory's prediction, and each
configuration's RAM, cycles and CPU load. The results do not depend on where or in which order the tasks ran.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from gaitlog.host.commands._options import (
    SEED,
    add_verbosity_options,
    check_output_folder,
    number,
    printer,
    verbosity,
    whole,
)
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import HostError, UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib, and of
# the few standard modules that `gaitlog --help` does without (tempfile, dataclasses): it imports every
# command module and must stay light (tests/host/commands/test_cli_startup.py).

#: Larger summary tables are only written (and printed with -v).
MAX_PRINTED_ROWS = 60

HELP = ("parameter sweep (ADC bits x rate x noise x converter and sensor errors x Q formats x rounding x "
        "misalignment x population x subjects) on Dask or in-process; resumable, CSV + figures")
#: Shown under "examples:" by ``gaitlog sweep --help``.
EXAMPLES = (
    "gaitlog sweep --out sweep-out --adc-bits 8,10,12 --logger-rate 25,50 --subjects 2",
    "gaitlog sweep --list-dimensions",
)


def _list(item: Callable[[str], object]) -> Callable[[str], list]:
    """An argparse ``type`` for a comma-separated, non-empty list of ``item`` values (a usage error naming the
    option and the bad element)."""
    def parse(text: str) -> list:
        parts = [x.strip() for x in text.split(",")]
        if not text.strip() or any(not x for x in parts):
            raise argparse.ArgumentTypeError(f"must be a comma-separated list without empty items, got {text!r}")
        out = []
        for x in parts:
            try:
                out.append(item(x))
            except (argparse.ArgumentTypeError, ValueError) as err:
                raise argparse.ArgumentTypeError(f"{x!r}: {err}") from None
        return out

    parse.__name__ = "list"
    return parse


def _estimator(text: str) -> str:
    if text not in ESTIMATOR_NAMES:
        raise argparse.ArgumentTypeError(f"must be one of {', '.join(ESTIMATOR_NAMES)}")
    return text


def _fixed_point_label(text: str, *, rounding: bool) -> str:
    """The canonical label of a Q-format set (or of a rounding), a usage error naming what is wrong."""
    from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats

    try:
        return (KernelFormats.parse("shipped", text).rounding_label() if rounding
                else KernelFormats.parse(text).label())
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _q_formats(text: str) -> str:
    return _fixed_point_label(text, rounding=False)


def _rounding(text: str) -> str:
    return _fixed_point_label(text, rounding=True)


#: The estimators' names (as :data:`gaitlog.firmware_sim.algorithms.steps.ESTIMATORS`; not imported: --help stays light).
ESTIMATOR_NAMES = ("M1", "M2", "M3", "M4", "M5")


class _ListDimensions(argparse.Action):
    """``--list-dimensions``: print every dimension (:func:`gaitlog.host.studies.sweep_grid.format_dimensions`) and
    exit 0, before the required options are checked (as ``--help``)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        from gaitlog.host.studies.sweep_grid import format_dimensions

        print(format_dimensions())
        parser.exit(0)


#: The converter's and the sensor's sweep options: grid key, unit, meaning, allowed range (as
#: :data:`gaitlog.host.studies.sweep_grid.EFFECT_DIMENSIONS`; not imported: --help stays light; a test holds them equal).
EFFECT_OPTIONS = (("inl_lsb", "LSB", "converter INL (PIC16F877: < 1)", 0, 8),
                  ("dnl_lsb", "LSB", "converter DNL (PIC16F877: < 1)", 0, 1),
                  ("adc_offset_lsb", "LSB", "converter offset error (PIC16F877: < ±2)", -16, 16),
                  ("adc_gain_error_lsb", "LSB", "converter gain error (PIC16F877: < ±1)", -16, 16),
                  ("acquisition_time_us", "µs", "acquisition time per channel: sequential sampling, the channel skew "
                   "(0: simultaneous; data sheet example 19.72)", 0, 1000),
                  ("source_impedance_ohm", "Ω", "source impedance: the settling error (with an acquisition time; "
                   "ADXL202 unbuffered 32000)", 0, 1e6),
                  ("source_capacitance_nf", "nF", "capacitance at the pin behind the source impedance (ADXL202 "
                   "unbuffered: its filter capacitor, 250)", 0, 1e4),
                  ("flicker_corner_hz", "Hz", "sensor 1/f noise corner (0: white only)", 0, 100),
                  ("temperature_swing_c", "°C", "temperature ramp from 25 °C over the walk, ADXL202E typical drift",
                   -100, 100))


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--list-dimensions", action=_ListDimensions, nargs=0,
                        help="print every dimension (unit, default, option or 'not yet sweepable') and exit")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="results folder (created; re-running with the same folder resumes)")
    parser.add_argument("--spec", metavar="FILE", help="grid spec, .json or .toml (keys: adc_bits, sampling_rate_hz, "
                        "noise_density_g_rthz, q_formats, rounding, misalignment_deg, m4_exponent, population, "
                        "the converter/sensor keys of "
                        "--list-dimensions, subjects, seeds, estimators, protocol); "
                        "the options below override it")
    grid = parser.add_argument_group("grid (default: 8,10,12 bits x 25,50,100 Hz, the sensor's noise, 4 subjects, seed 0)")
    grid.add_argument("--adc-bits", type=_list(whole(minimum=1, maximum=12)), metavar="B,B", help="ADC widths, bits")
    grid.add_argument("--logger-rate", type=_list(number(minimum=10, maximum=1000, unit="Hz")), metavar="HZ,HZ", help="logger sampling rates, Hz")
    grid.add_argument("--noise-density", type=_list(number(minimum=0, maximum=0.01, unit="g/√Hz")), metavar="G,G",
                      help="sensor white-noise densities, g/√Hz (the ADXL202E's: 200e-6)")
    grid.add_argument("--q-formats", type=_list(_q_formats), metavar="SET,SET",
                      help="Q-format sets of the fixed-point chain: 'shipped' or the bits of the formats changed, "
                      "e.g. shipped,acc10,acc8,lp12,grav20,m2pos13,k12,wgrav24,wstep15: NAME+N fewer fraction bits "
                      "(acc: a_v and its integrals, grav: gravity, lp: lowpass outputs, m2pos: M2's position; sq, fir, "
                      "kern, exc, excc, leg, twoleg, parg, pargc, root, step, k, kw, cad, mant: the other formats), "
                      "wNAME+N a narrower word where the format's values saturate (sign included, at most its "
                      "container; wvel, wpos: M1's integrals, wcode: the centred codes), lpintN the lowpass's "
                      "integer bits; every name in --list-dimensions; each non-shipped set is compiled once per "
                      "machine (~10-25 s), kept in the compile cache")
    grid.add_argument("--rounding", type=_list(_rounding), metavar="R,R",
                      help="rounding of the fixed-point chain: shipped, truncate, half-up, convergent (every "
                      "operation class) or per class, e.g. shipped,truncate,mul:truncate+div:convergent (classes "
                      "mul, shift, div)")
    grid.add_argument("--misalignment", type=_list(number(minimum=-45, maximum=45, unit="degrees")), metavar="DEG,DEG",
                      help="extra mounting tilt of the logger (pitch), degrees (negative: --misalignment=-5,0,5)")
    grid.add_argument("--m4-exponent", type=_list(str), metavar="P,P",
                      help="M4's exponent p in S = K (a_max - a_min)^p, as the step configuration stores it: "
                      "0.125, 0.25, 0.375 or 0.5 (default 0.25, Weinberg's); the offline chains, their K and the "
                      "logger's step configuration all use it")
    grid.add_argument("--population", type=_list(str), metavar="P,P",
                      help="simulated populations (gaitlog.firmware_sim.world.walk_plan.POPULATION_PLANS: v1, people...)")
    for key, unit, what, lo, hi in EFFECT_OPTIONS:
        grid.add_argument("--" + key.replace("_", "-"), dest=key, type=_list(number(minimum=lo, maximum=hi, unit=unit)),
                          metavar="X,X", help=f"{what}, {unit} (default 0: off)")
    grid.add_argument("--subjects", type=whole(minimum=1, maximum=1000), metavar="N", help="simulated subjects per seed")
    grid.add_argument("--seeds", type=_list(SEED), metavar="S,S", help="seeds of the subject draws")
    grid.add_argument("--estimators", type=_list(_estimator), metavar="M1,M2", help="estimators kept (default all)")
    grid.add_argument("--protocol", choices=("paper", "short"), help="walking protocol (default paper; short: "
                      "4 x 40 m, for quick looks)")
    run = parser.add_argument_group("where it runs")
    run.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="an existing Dask scheduler: its address or "
                     "the scheduler file it wrote (dask scheduler --scheduler-file FILE); default: a local cluster")
    run.add_argument("--workers", type=whole(minimum=1, maximum=256), default=2, help="worker processes of the local cluster (default 2)")
    run.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.atomic_write import atomic_write_text
    from gaitlog.host.studies.sweep_grid import M4_EXPONENTS, SweepGrid, run_task
    from gaitlog.host.studies.task_store import TaskStore, run_serial

    if args.serial and args.scheduler:
        raise UsageError("--serial and --scheduler exclude each other")
    if args.scheduler:
        _check_scheduler(args.scheduler)
    m4_exponents = None if args.m4_exponent is None else [_m4_exponent(p, M4_EXPONENTS) for p in args.m4_exponent]
    spec = SweepGrid.load(args.spec).to_spec() if args.spec else {}
    for key, value in (("adc_bits", args.adc_bits), ("sampling_rate_hz", args.logger_rate),
                       ("noise_density_g_rthz", args.noise_density), ("q_formats", args.q_formats),
                       ("rounding", args.rounding),
                       ("misalignment_deg", args.misalignment), ("m4_exponent", m4_exponents),
                       ("population", args.population),
                       *((key, getattr(args, key)) for key, *_ in EFFECT_OPTIONS), ("subjects", args.subjects),
                       ("seeds", args.seeds), ("estimators", args.estimators), ("protocol", args.protocol)):
        if value is not None:
            spec[key] = value
    grid = SweepGrid.from_spec(spec, source="the grid options")
    out = Path(args.out)
    check_output_folder("--out", out)
    out.mkdir(parents=True, exist_ok=True)
    say, detail = printer(args), printer(args, 1)
    tasks = grid.tasks()
    store = TaskStore(out)
    n_done = len(tasks) - len(store.pending(tasks))
    atomic_write_text(out / "spec.json", json.dumps(grid.to_spec(), indent=2) + "\n")
    say(f"sweep: {len(tasks)} tasks ({len(grid.seeds)} seed(s) x {len(grid.population)} population(s) x "
        f"{len(grid.misalignment_deg)} misalignment(s) x {grid.subjects} subject(s) x "
        f"{len(grid.sampling_rate_hz)} rate(s) x {len(grid.noise_density_g_rthz)} noise level(s) x "
        f"{len(grid.effect_sets())} converter/sensor setting(s) x "
        f"{len(grid.m4_exponent)} M4 exponent(s) x {len(grid.rounding)} rounding(s) x "
        f"{len(grid.q_formats)} Q-format set(s) x {len(grid.adc_bits)} ADC "
        f"width(s)), {n_done} already in "
        f"{store.tasks_folder}")
    t = time.perf_counter()
    with progress_bar(args, len(tasks) - n_done, "task") as tick:
        if args.serial:
            computed = run_serial(run_task, tasks, store, progress=tick)
            where = "this process"
        else:
            from gaitlog.host.studies.dask_runner import run_on_dask

            computed = run_on_dask(run_task, tasks, store, scheduler=args.scheduler, workers=args.workers,
                                   progress=tick, on_start=lambda w: detail(f"running on {w}"))
            where = args.scheduler or f"a local cluster of {args.workers} worker(s)"
    say(f"computed {computed} task(s) on {where} in {time.perf_counter() - t:.1f} s")
    from gaitlog.host.studies.sweep_report import sweep_report

    report = sweep_report(store.collect(tasks), out, max_printed_rows=MAX_PRINTED_ROWS)
    report.write_outputs(out)
    printer(args)(report.format_table(verbosity(args)))
    return 0


def _m4_exponent(text: str, allowed: tuple[float, ...]) -> float:
    """One ``--m4-exponent`` value among ``allowed`` (what the step configuration stores), else a usage error
    naming them."""
    try:
        ok = float(text) in allowed
    except ValueError:
        ok = False
    if not ok:
        raise UsageError(f"--m4-exponent {text}: not an exponent the step configuration stores; allowed: "
                         f"{', '.join(f'{e:g}' for e in allowed)}")
    return float(text)


def _check_scheduler(scheduler: str) -> None:
    """``--scheduler``: ``tcp://HOST:PORT`` (or another Dask protocol), or a scheduler file that is JSON with an
    ``address`` once it exists (a scheduler may still be writing it: a missing file is waited for)."""
    if "://" in scheduler:
        proto, _, rest = scheduler.partition("://")
        host, _, port = rest.rpartition(":")
        if not proto or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise UsageError(f"--scheduler {scheduler}: not an address PROTOCOL://HOST:PORT (e.g. tcp://10.0.0.5:8786)")
        return
    p = Path(scheduler)
    if not p.exists():
        if not p.parent.is_dir():
            raise HostError(f"--scheduler {scheduler}: neither an address tcp://HOST:PORT nor a scheduler file "
                            f"(the folder {p.parent} does not exist)")
        return
    try:
        with open(p, "rb") as f:
            doc = json.loads(f.read(1 << 20))
    except (OSError, ValueError, RecursionError) as err:
        raise HostError(f"--scheduler {scheduler}: not a scheduler file (JSON with the scheduler's address): "
                        f"{getattr(err, 'strerror', None) or type(err).__name__}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("address"), str):
        raise HostError(f"--scheduler {scheduler}: not a scheduler file (no \"address\")")
