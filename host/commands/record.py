"""``gaitlog record``: run the emulated logger on a motion source and write its memory image."""

from __future__ import annotations

import argparse

HELP = "record a motion (calibration poses or a replayed recording) with the emulated logger to a memory image"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--motion", nargs="+", required=True, metavar=("KIND", "FILE"),
                        help="'poses' (static calibration poses) or 'replay FILE' (CSV or IPOL recording)")
    parser.add_argument("--out", required=True, metavar="IMAGE", help="memory image to write (.glimg)")
    parser.add_argument("--units", choices=("g", "m/s2", "auto"), default="auto",
                        help="units of a replayed recording (default: auto-detect)")
    parser.add_argument("--rate", type=float, metavar="HZ",
                        help="sample rate of a replayed recording without time column")
    parser.add_argument("--columns", nargs=3, metavar=("X", "Y", "Z"),
                        help="acceleration columns of a replayed CSV (names or 0-based indices)")
    parser.add_argument("--time-column", metavar="COL",
                        help="column of sample times in seconds of a replayed CSV (name or 0-based index)")
    parser.add_argument("--poses", type=int, default=24, metavar="N", help="number of calibration poses (24)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor's errors and noise, and of the poses")
    parser.add_argument("--sample-rate", type=float, default=50.0, metavar="HZ",
                        help="the logger's sample rate (default 50 Hz)")
    parser.add_argument("--start-time", type=int, default=None, metavar="UNIX_S",
                        help="Unix time of the first sample (default: now)")
    parser.add_argument("--overwrite-oldest", action="store_true",
                        help="ring mode: when the memory is full, overwrite the oldest samples (default: stop)")
    parser.add_argument("--append", action="store_true",
                        help="start from the existing image at --out instead of an erased memory")
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")


def build_motion(args: argparse.Namespace):
    """The motion source named by ``--motion`` (with ``--units``/``--rate``/``--columns``)."""
    from host.errors import HostError

    kind = args.motion[0]
    if kind == "poses":
        if len(args.motion) != 1:
            raise HostError("--motion poses takes no file")
        from firmware_sim.world.poses import CalibrationPoses

        return CalibrationPoses(n_poses=args.poses, seed=args.seed)
    if kind == "replay":
        if len(args.motion) != 2:
            raise HostError("--motion replay needs exactly one FILE")
        from firmware_sim.world.replay import Replay

        columns = None
        if args.columns:
            columns = [int(c) if c.lstrip("-").isdigit() else c for c in args.columns]
        units = {"m/s2": "m/s^2"}.get(args.units, args.units)
        time_column = args.time_column
        if time_column is not None and time_column.isdigit():
            time_column = int(time_column)
        return Replay.from_file(args.motion[1], units=units, rate_hz=args.rate, columns=columns,
                                time_column=time_column)
    raise HostError(f"--motion: unknown kind {kind!r} (expected 'poses' or 'replay FILE')")


def run(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from firmware_sim.device import Logger
    from firmware_sim.sensor import SensorModel
    from host.errors import HostError

    out = Path(args.out)
    if not out.parent.is_dir():
        raise HostError(f"output directory {out.parent} does not exist")
    source = build_motion(args)
    motion = source.render(args.sample_rate)
    start = int(time.time()) if args.start_time is None else args.start_time
    if args.append and out.exists():
        logger = Logger.from_image(out)
    else:
        logger = Logger(sensor=SensorModel.draw(seed=args.seed), sample_rate_hz=args.sample_rate,
                        overwrite=args.overwrite_oldest)
    result = logger.record(motion, start_time_s=start)
    logger.save_image(out)
    if not args.quiet:
        h = logger.header
        print(f"{out}: recorded {len(result.codes)} samples ({motion.duration_s:.1f} s of {args.motion[0]}); "
              f"memory holds {h.n_stored} of {h.capacity_samples}" + (", wrapped" if h.wrapped else ""))
    return 0
