"""``gaitlog record``: run the emulated logger on a motion source and write its memory image.

The logger runs its on-line step algorithm while logging (PROTOCOL.md 2.2, 2.3) unless ``--steps off``: the
step configuration is written to the header before START, from ``--height`` / ``--leg-length`` /
``--foot-length`` (:func:`gaitlog.host.gait.anthropometry.choose_lengths`: else a replayed IPOL trial's height, else a
1.70 m adult, with a warning) and, with ``--k-file``, the calibrated constants of a ``gaitlog calibrate-k`` file (whose
leg and foot lengths are the ones K was fitted with). Without K the device stores the raw values.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from gaitlog.host.commands._anatomy_options import (
    FOOT_LENGTH_M,
    HEIGHT_M,
    LEG_LENGTH_M,
    k_fit_from_args,
    lengths_from_args,
)
from gaitlog.host.commands._input_options import add_input_options, given_input_flags, read_input
from gaitlog.host.commands._options import (
    SEED,
    UNIX_TIME_S,
    add_force_option,
    add_logger_rate_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    logger_rate_hz,
    number,
    out_path,
    verbosity,
    whole,
)
from gaitlog.host.errors import HostError, UsageError
from gaitlog.protocol.errors import ProtocolError

# Imports inside functions are only of numpy, of modules that load numpy, scipy, numba, dask or matplotlib, and
# of gaitlog.firmware_sim.world.walk_plan (its dataclasses: ~3 ms):
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

if TYPE_CHECKING:
    from gaitlog.host.files.acceleration import AccelerationInput

HELP = ("record a motion (calibration poses, a simulated walk or a replayed recording) with the emulated logger, "
        "its on-line step algorithm on, to a memory image")
#: Shown under "examples:" by ``gaitlog record --help``.
EXAMPLES = (
    "gaitlog record --motion walk --height 1.75 --out walk.glimg",
    "gaitlog record --motion poses --out poses.glimg",
    "gaitlog record --motion replay trial_lb.txt --out trial.glimg",
)

#: One-way corridor length of ``--motion walk`` when not given, m (an out-and-back excursion of 40 m).
WALK_CORRIDOR_M = 20.0


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--motion", nargs="+", required=True, metavar=("KIND", "FILE"),
                        help="'poses' (static calibration poses), 'walk' (a simulated subject of --height walking "
                             "a corridor out and back at preferred speed), 'replay FILE' (a real recording: CSV, "
                             "IPOL trial, or any input the gait commands read; lost samples are interpolated and "
                             "counted), or an instrument on the logger's analog inputs: 'morris' (Morris' shank "
                             "platform, single-axis accelerometers) or 'hall' (Hall's two links, triaxial rate "
                             "sensors); an instrument also writes IMAGE's _platform.json and _truth.csv")
    parser.add_argument("--out", required=True, metavar="IMAGE", help="memory image to write (.glimg)")
    parser.add_argument("--poses", type=whole(minimum=1, maximum=1000), default=24, metavar="N", help="number of calibration poses (24)")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the sensor's errors and noise, and of the poses")
    add_logger_rate_option(parser, maximum_hz=100_000, default="the logger's, 50 Hz as in Alvarez et al.; "
                           "morris 100 Hz and hall 10 kHz, the papers' rates; above 1000 Hz only for an instrument")
    parser.add_argument("--start-time", type=UNIX_TIME_S, default=None, metavar="UNIX_S",
                        help="Unix time of the first sample (default: now)")
    parser.add_argument("--overwrite-oldest", action="store_true",
                        help="ring mode: when the memory is full, overwrite the oldest samples (default: stop)")
    parser.add_argument("--append", action="store_true",
                        help="start from the existing image at --out instead of an erased memory")
    parser.add_argument("--corridor-length", type=number(minimum=10, maximum=1000, unit="m"), default=WALK_CORRIDOR_M, metavar="M",
                        help=f"one-way corridor length of --motion walk, m (default {WALK_CORRIDOR_M:g}: 2 x "
                             f"{WALK_CORRIDOR_M:g} m walked)")
    inst = parser.add_argument_group("instruments (--motion morris / hall: PROTOCOL.md 2.6 channel map)")
    inst.add_argument("--accelerometers", type=int, choices=(5, 6), default=5,
                      help="morris: 5 accelerometers (as published, rate about the shank axis assumed zero) or 6")
    inst.add_argument("--duration", type=number(minimum=1.0, maximum=3600.0, unit="s"), default=2.56, metavar="S",
                      help="morris: seconds recorded (default 2.56, Morris' record)")
    inst.add_argument("--gravity-channels", action="store_true",
                      help="hall: also the links' triaxial gravity sensors Hall took the pre-test posture from "
                           "(12 channels: more than the PIC16F877's 8 inputs, refused)")
    inst.add_argument("--sensor-noise", choices=("on", "off"), default="on",
                      help="the sensors' noise (default on; off: quantisation, offsets and drift only)")
    steps = parser.add_argument_group("on-line step algorithm (one 20-byte record per foot-flat in the step memory)")
    steps.add_argument("--steps", choices=("on", "off"), default=None,
                       help="run the on-line step algorithm while logging (default: on; with --append and no "
                            "step option, the image's own setting)")
    steps.add_argument("--height", type=HEIGHT_M, metavar="M",
                       help="body height of the wearer, m: leg and foot length are estimated from it when not given "
                            "(Winter; ANSUR; gaitlog.host.gait.anthropometry; default: a 1.70 m adult, with a warning)")
    steps.add_argument("--leg-length", type=LEG_LENGTH_M, metavar="M",
                       help="leg length (greater trochanter to floor), m")
    steps.add_argument("--foot-length", type=FOOT_LENGTH_M, metavar="M",
                       help="foot length heel to first metatarsal head (M3's S2), m")
    steps.add_argument("--k-file", metavar="K.json",
                       help="calibrated constants (from `gaitlog calibrate-k`): the device stores calibrated "
                            "lengths; the leg and foot lengths come from this file")
    add_input_options(parser)
    add_force_option(parser)
    add_verbosity_options(parser)


def read_replayed(args: argparse.Namespace) -> AccelerationInput | None:
    """The file of ``--motion replay FILE`` (with the input flags), else None."""
    if args.motion[0] != "replay":
        return None
    if len(args.motion) != 2:
        raise UsageError("--motion replay needs exactly one FILE")
    return read_input(args, args.motion[1])


def build_motion(args: argparse.Namespace, data: AccelerationInput | None = None):
    """The motion source named by ``--motion``; ``data``: the replayed file (:func:`read_replayed`), read here
    when not given."""
    kind = args.motion[0]
    if kind == "poses":
        if len(args.motion) != 1:
            raise UsageError("--motion poses takes no file")
        from gaitlog.firmware_sim.world.poses import CalibrationPoses

        return CalibrationPoses(n_poses=args.poses, seed=args.seed)
    if kind == "replay":
        if len(args.motion) != 2:
            raise UsageError("--motion replay needs exactly one FILE")
        from gaitlog.firmware_sim.world.replay import Replay

        data = data if data is not None else read_replayed(args)
        return Replay.from_samples(data.g(), data.valid, sampling_rate_hz=data.sampling_rate_hz, source=data.source,
                                   marker_times_s=data.mark_index / data.sampling_rate_hz)
    if kind == "walk":
        if len(args.motion) != 1:
            raise UsageError("--motion walk takes no file")
        from gaitlog.firmware_sim.world.subject import Subject
        from gaitlog.firmware_sim.world.walk_plan import WalkPlan
        from gaitlog.firmware_sim.world.walking import Walking
        from gaitlog.host.gait.anthropometry import DEFAULT_HEIGHT_M, anatomical_lengths

        height = DEFAULT_HEIGHT_M if args.height is None else args.height
        anatomical_lengths(height_m=height)  # range check, named
        corridor = float(args.corridor_length)
        walk_plan = WalkPlan(corridor_length_m=corridor, speeds=("preferred",), initial_stand_s=3.0,
                                   final_stand_s=2.0, lap_marks_m=(0.0, corridor, 2.0 * corridor))
        return Walking(subject=Subject.from_height(height), walk_plan=walk_plan, seed=args.seed)
    raise UsageError(f"--motion: unknown kind {kind!r} (expected 'poses', 'walk' or 'replay FILE')")


def _refuse_input_flags(args: argparse.Namespace) -> None:
    """Input flags describe a replayed file: an error with any other motion."""
    extra = given_input_flags(args)
    if args.motion[0] != "replay" and extra:
        raise UsageError(f"{', '.join(extra)}: only for --motion replay FILE")


def step_config_from_args(args: argparse.Namespace, *, appending: bool = False, data: AccelerationInput | None = None):
    """The step configuration the options ask for, and the warnings to print; the leg and foot lengths by
    :func:`gaitlog.host.commands._anatomy_options.lengths_from_args` (``data``: the replayed input, whose IPOL height
    counts when no option gives one).

    Returns
    -------
    config, warnings
        A :class:`gaitlog.protocol.steps.StepConfig` (``StepConfig.off()`` with ``--steps off``), or None with
        ``appending`` and no step option (the image keeps its own), and warning lines.

    Raises
    ------
    HostError
        A length out of its plausible range, an unreadable or foreign ``--k-file``, lengths that contradict
        the ``--k-file``'s, or K values the step configuration cannot store (the field is named).
    """
    from gaitlog.protocol.steps import StepConfig, StepFormat

    given = {name: getattr(args, name) for name in ("height", "leg_length", "foot_length", "k_file")
             if getattr(args, name) is not None}
    if args.steps == "off":
        return StepConfig.off(), []
    if appending and args.steps is None and not given:
        return None, []
    k = k_fit_from_args(args)
    lengths = lengths_from_args(args, k=k, data=data)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    k_fields = {}
    if k is not None:
        fitted = StepConfig(step_format=StepFormat.V1, leg_length_m=k.leg_length_m,
                            foot_length_m=k.foot_length_m)
        try:
            fitted_q = fitted.quantised()
        except ProtocolError as err:
            raise HostError(f"{args.k_file}: its lengths cannot be stored: {err}") from err
        for name, chosen, value in (("leg", leg, fitted_q.leg_length_m), ("foot", foot, fitted_q.foot_length_m)):
            # a length the options set (the length itself, or the height it is derived from) must be K's
            if chosen != getattr(k, f"{name}_length_m") and abs(chosen - value) > 2.0 ** -15:
                raise HostError(f"{args.k_file}: K was fitted with a {name} length of {value:.4f} m, the options "
                                f"give {chosen:.4f} m: K holds only with the lengths it was fitted with (drop "
                                "--height/--leg-length/--foot-length, or fit K again)")
        leg, foot = k.leg_length_m, k.foot_length_m
        k_fields = k.step_constants()
    notes = [f"the on-line step algorithm: {lengths.note}; or --steps off for plain logging"] if lengths.assumed else []
    config = StepConfig(step_format=StepFormat.V1, leg_length_m=leg, foot_length_m=foot, **k_fields)
    try:
        config.to_bytes()
    except ProtocolError as err:
        where = f"{args.k_file}: " if args.k_file else ""
        raise HostError(f"{where}the step configuration cannot be stored: {err}") from err
    return config, notes


#: Longest motion ``record`` renders, in samples of the sensor's internal grid (500 Hz: 2.3 h): the emulator renders
#: a motion whole (resampled, filtered, held: about 100 bytes per internal sample at the peak), so this keeps it
#: under 500 MB. A stop-when-full memory needs only the part before it fills (:func:`fit_to_memory`).
MAX_RENDERED_SAMPLES = 1 << 22
#: Logger samples rendered past the instant a stop-when-full memory fills (the resampler's edge lies beyond them).
FULL_MARGIN_SAMPLES = 1024


def fit_to_memory(motion, logger, *, overwrite: bool, name: str):
    """The part of ``motion`` the logger can store, and the samples the whole motion gives the logger.

    In stop-when-full mode the run ends when the memory fills, so only the motion up to then (and
    :data:`FULL_MARGIN_SAMPLES` more) is rendered: a long replayed file costs the memory of what is stored, not
    of the file. In OVERWRITE mode the whole motion is logged; one longer than :data:`MAX_RENDERED_SAMPLES` on the
    sensor's grid is a :class:`HostError` naming ``name``.
    """
    import numpy as np

    from gaitlog.firmware_sim.world.base import Motion

    n = motion.acc_g.shape[0]
    rate = float(motion.sampling_rate_hz)
    t_last = motion.t0_s + (n - 1) / rate
    n_total = int(logger.adc.sample_times_s(motion.t0_s, t_last).size)
    room = None if overwrite else max(logger.header.capacity_samples - logger.header.samples_written, 0)
    keep = n if room is None else min(n, int(np.ceil((room + FULL_MARGIN_SAMPLES) / logger.adc.actual_rate_hz
                                                        * rate)) + 1)
    fine = int(np.ceil(keep / rate * logger.sensor.internal_rate_hz))
    if fine > MAX_RENDERED_SAMPLES:
        limit_h = MAX_RENDERED_SAMPLES / logger.sensor.internal_rate_hz / 3600
        raise HostError(f"{name}: {(n - 1) / rate / 3600:.1f} h of motion to log with --overwrite-oldest; the emulator "
                        f"renders it whole and takes at most {limit_h:.1f} h (the memory keeps only the last "
                        f"{logger.header.capacity_samples / logger.adc.actual_rate_hz / 60:.1f} min): cut the file")
    if keep == n:
        return motion, n_total
    end_s = motion.t0_s + keep / rate
    return Motion(acc_g=motion.acc_g[:keep], sampling_rate_hz=rate, t0_s=motion.t0_s, truth=motion.truth,
                  marker_times_s=motion.marker_times_s[motion.marker_times_s < end_s]), n_total


def instrument_paths(out) -> dict[str, object]:
    """The files ``record --motion morris|hall --out IMAGE`` writes: the image, ``<stem>_platform.json`` (the
    platform description of ``gaitlog kinematics``) and ``<stem>_truth.csv`` (the simulation's truth at the
    logger's sample instants)."""
    out = Path(out)
    return {"--out": out, "--out (platform)": out.with_name(f"{out.stem}_platform.json"),
            "--out (truth)": out.with_name(f"{out.stem}_truth.csv")}


def run_instrument(args: argparse.Namespace) -> int:
    """``record --motion morris|hall``: the instrument through sensor -> ADC -> memory, refused where the
    PIC16F877 cannot record it (:func:`gaitlog.host.kinematics.logger_instruments.check_fits`)."""
    from gaitlog.host.kinematics.logger_instruments import record_instrument
    from gaitlog.host.kinematics.sensor_csv import write_sensor_csv

    kind = args.motion[0]
    if len(args.motion) != 1:
        raise UsageError(f"--motion {kind} takes no file")
    extra = [f"--{n.replace('_', '-')}" for n in ("height", "leg_length", "foot_length", "k_file", "steps")
             if getattr(args, n) is not None] + [o for o, on in (("--append", args.append),
                                                                 ("--overwrite-oldest", args.overwrite_oldest)) if on]
    if extra:
        raise UsageError(f"{', '.join(extra)}: not with --motion {kind} (an instrument's channels, no step algorithm, "
                        "one run into an erased memory)")
    _refuse_input_flags(args)
    paths = instrument_paths(args.out)
    check_outputs(paths, {}, force=args.force)
    start = int(time.time()) if args.start_time is None else args.start_time
    li = record_instrument(kind, sampling_rate_hz=args.logger_rate, n_accelerometers=args.accelerometers,
                           duration_s=args.duration, gravity_channels=args.gravity_channels, seed=args.seed,
                           noise=args.sensor_noise == "on", start_time_s=start)
    li.logger.save_image(paths["--out"])
    li.platform.save(paths["--out (platform)"])
    write_sensor_csv(paths["--out (truth)"], li.t_s, li.truth, comment=f"truth of {paths['--out']}: {li.comment}",
                     check_units=False)
    if verbosity(args) >= 0:
        h = li.logger.header
        cmap = h.calibration
        print(f"{args.out}: {kind}, {cmap.n_channels} channels ({', '.join(c.name for c in cmap.channels)} on "
              f"AN0-AN{cmap.n_channels - 1}) at {h.sampling_rate_hz:g} Hz: {li.n_frames} frames "
              f"({li.n_frames / h.sampling_rate_hz:.2f} s, {h.n_stored} of {h.capacity_samples} words)")
        if li.n_frames < li.n_taken:
            print(f"gaitlog record: warning: the memory filled up: the last {li.n_taken - li.n_frames} of {li.n_taken} "
                  "frames were not stored", file=sys.stderr)
        print(f"wrote {' '.join(str(p) for p in paths.values())}")
    return 0


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.kinematics.logger_instruments import INSTRUMENTS

    replay = args.motion[0] == "replay" and len(args.motion) == 2
    args.out = out_path(args.out, f"{input_stem(args.motion[1]) if replay else args.motion[0]}.glimg")
    if args.motion[0] in INSTRUMENTS:
        return run_instrument(args)
    out = Path(args.out)
    replayed = args.motion[1] if replay else None
    if not _check_record_options(args, out, replayed):
        return 2
    appending = bool(args.append and out.exists())
    _refuse_input_flags(args)
    data = read_replayed(args)
    config, warnings_ = step_config_from_args(args, appending=appending, data=data)
    source = build_motion(args, data)
    motion = source.render(args.logger_rate)
    n_interpolated = getattr(source, "n_interpolated", 0)
    if n_interpolated and verbosity(args) >= 0:
        n = source.acc_g.shape[0]
        print(f"gaitlog record: warning: {n_interpolated} of {n} samples of {args.motion[1]} "
              f"({n_interpolated / n:.2%}) were missing (lost packets or gaps) and are interpolated in the "
              "replayed motion: those stretches are not measured motion", file=sys.stderr)
    start = int(time.time()) if args.start_time is None else args.start_time
    logger = _logger(args, out, appending, config, warnings_)
    for line in warnings_ if verbosity(args) >= 0 else ():
        print(f"gaitlog record: warning: {line}", file=sys.stderr)
    steps_before, written_before = logger.header.steps_written, logger.header.samples_written
    logged, n_taken = fit_to_memory(motion, logger, overwrite=args.overwrite_oldest,
                                    name=args.motion[1] if replayed else f"--motion {args.motion[0]}")
    logger.record(logged, start_time_s=start)
    not_stored = n_taken - (logger.header.samples_written - written_before)
    if not_stored > 0 and verbosity(args) >= 0:
        print(f"gaitlog record: warning: the memory filled up: the last {not_stored} of {n_taken} samples "
              "were not stored (logging stops when full; --overwrite-oldest keeps the newest instead)",
              file=sys.stderr)
    logger.save_image(out)
    if verbosity(args) >= 0:
        print(_recorded_lines(args, out, logger.header, n_taken, motion.duration_s, steps_before))
    return 0


def _check_record_options(args: argparse.Namespace, out: Path, replayed: str | None) -> bool:
    """The logger rate, the outputs and ``--steps off`` checked (False: the error is printed, exit 2)."""
    args.logger_rate = logger_rate_hz(args)
    if args.logger_rate > 1000:
        raise UsageError(f"--logger-rate {args.logger_rate:g}: above 1000 Hz only for --motion morris or hall")
    check_outputs({"--out": out}, {"--motion replay FILE": replayed, "--k-file": args.k_file,
                                   "--calibration": args.calibration}, force=None if args.append else args.force)
    if args.steps == "off":
        extra = [f"--{n.replace('_', '-')}" for n in ("height", "leg_length", "foot_length", "k_file")
                 if getattr(args, n) is not None]
        if extra:
            print(f"gaitlog record: error: --steps off runs no step algorithm: {', '.join(extra)} would be ignored; "
                  "drop them", file=sys.stderr)
            return False
    return True


def _logger(args: argparse.Namespace, out: Path, appending: bool, config, warnings_: list[str]):
    """The emulated logger to record with: the image at ``out`` when appending (``config``, when given, set as
    SET_STEP_CONFIG would before START; a note in ``warnings_`` when it replaces another), else a new one."""
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.sensor import SensorModel

    if not appending:
        return Logger(sensor=SensorModel.draw(seed=args.seed), sampling_rate_hz=args.logger_rate,
                      overwrite=args.overwrite_oldest, step_config=config)
    logger = Logger.from_image(out, overwrite=args.overwrite_oldest)  # the mode is START's, as on the device
    if config is not None:
        if logger.header.n_steps_stored and config.quantised() != logger.step_config:
            warnings_.append(f"{out} holds {logger.header.n_steps_stored} step records logged with another step "
                             "configuration; the header keeps only the new one, so `gaitlog decode` will find "
                             "those records different from its replay (--no-verify)")
        logger.step_config = config  # as SET_STEP_CONFIG before START
    return logger


def _recorded_lines(args: argparse.Namespace, out: Path, h, n_taken: int, duration_s: float,
                    steps_before: int) -> str:
    """What ``record`` says of the image it wrote (``h``: its header); ``-v``: the header's fields too."""
    lines = [f"{out}: recorded {n_taken} samples ({duration_s:.1f} s of {args.motion[0]}); "
             f"memory holds {h.n_stored} of {h.capacity_samples}" + (", wrapped" if h.wrapped else "")]
    cfg = h.step_config
    if cfg.enabled:
        q = cfg.quantised()
        lines.append(f"{h.steps_written - steps_before} step records stored by the on-line algorithm (leg "
                     f"{q.leg_length_m:.3f} m, foot {q.foot_length_m:.3f} m, "
                     + ("calibrated K" if cfg.calibrated else "raw: no K") + f"); step memory holds "
                     f"{h.n_steps_stored} of {h.step_capacity}")
    else:
        lines.append("on-line step algorithm off: no step records stored")
    if verbosity(args) > 0:                         # -v: the device as written into the image's header
        lines.append(f"header: device {h.device_id}, {h.sampling_rate_hz:g} Hz, {h.adc_bits}-bit ADC, "
                     f"start time {h.start_time}, samples written {h.samples_written}, write index {h.write_index}")
    return "\n".join(lines)
