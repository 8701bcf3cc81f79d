"""``gaitlog kinematics``: Morris (1973) and Hall (1997) on recordings, or on simulated instruments.

Forms::

    gaitlog kinematics morris REC.csv --platform P.json --out DIR [--cycle START END] [--azimuth DEG ...]
    gaitlog kinematics hall REC.csv --platform P.json --out DIR [--cfc 180]
    gaitlog kinematics simulate --write-recording DIR     # the instruments' recordings + platforms + truth
    gaitlog kinematics [simulate] --out DIR               # simulate, analyse, report errors against the truth

The recording format is :mod:`gaitlog.host.kinematics.sensor_csv`, the platform files
:mod:`gaitlog.host.kinematics.platform_description`. Morris: every cycle from foot-flat to foot-flat
(:mod:`gaitlog.host.kinematics.morris_analysis`), or the one given by ``--cycle``; outputs ``morris_orientation.csv``
(direction cosines), ``morris_angular_velocity.csv``, ``morris_translation.csv`` (one row per sample, a
``cycle`` column) and Figs 4-7 of the first (or selected) cycle, Fig 7 also as ``morris_animation.gif``.
Hall: ``hall_joint_angles.csv``, ``hall_link_orientation.csv``, ``hall_angular_velocity.csv`` and the angle
plot. Everything is computed before the first file is written (no partial output on an error).

Simulate: Morris' platform as published (five accelerometers, ω3 assumed zero, 40 dB noise) and, for
comparison, the same shank without axial rotation and a six-accelerometer platform; Hall's two links at
10 kHz. The errors against the truth are printed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gaitlog.host.commands._options import (
    SEED,
    add_force_option,
    add_verbosity_options,
    check_output_folder,
    number,
    printer,
    verbosity,
)
from gaitlog.host.errors import UsageError

# The kinematics runs load numpy, scipy and matplotlib: imported inside the functions that run them, so that
# `gaitlog --help` stays light (tests/host/commands/test_cli_startup.py).

HELP = "Morris' and Hall's kinematics on a recording (morris / hall) or on simulated instruments (simulate)."
#: Shown under "examples:" by ``gaitlog kinematics --help``.
EXAMPLES = (
    "gaitlog kinematics --out kin",
    "gaitlog kinematics morris rec.csv --platform platform.json --out kin",
)

#: Files written by ``morris`` and ``hall`` into ``--out``.
MORRIS_FILES = ("morris_orientation.csv", "morris_angular_velocity.csv", "morris_translation.csv",
                "morris_angular_velocity.png", "morris_dcm.png", "morris_translation.png", "morris_stick_figure.png",
                "morris_animation.gif")
HALL_FILES = ("hall_joint_angles.csv", "hall_link_orientation.csv", "hall_angular_velocity.csv",
              "hall_joint_angles.png")


def _snr_db(text: str) -> float:
    """``--snr-db``: a finite number of dB in 0..200, or ``inf`` (no noise)."""
    return float("inf") if text.strip().lower() == "inf" else number(minimum=0, maximum=200, unit="dB")(text)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``gaitlog kinematics``."""
    parser.add_argument("method", nargs="?", choices=("simulate", "morris", "hall"), default="simulate",
                        help="morris or hall: analyse RECORDING; simulate (default): simulated instruments")
    parser.add_argument("recording", nargs="?", type=Path, metavar="RECORDING",
                        help="recording CSV: time_s, then one column per sensor axis with its unit (morris, hall)")
    parser.add_argument("--platform", type=Path, metavar="JSON",
                        help="platform description: accelerometer positions/axes (morris) or rate-sensor links (hall)")
    parser.add_argument("--out", type=Path, metavar="DIR", help="folder for the results and figures (created)")
    parser.add_argument("--cycle", type=number(minimum=0, unit="s"), nargs=2, metavar=("START", "END"),
                        help="morris: the cycle in the recording's seconds, START in foot-flat (Morris' cursors); "
                        "default: every cycle from foot-flat to foot-flat, figures of the first")
    parser.add_argument("--azimuth", type=number(minimum=-360, maximum=360, unit="deg"), default=0.0, metavar="DEG",
                        help="Fig 7 view: azimuth (0: from the right side, 90: from behind; default 0)")
    parser.add_argument("--elevation", type=number(minimum=-90, maximum=90, unit="deg"), default=0.0, metavar="DEG",
                        help="Fig 7 view: elevation (0: level, 90: from above; default 0)")
    parser.add_argument("--no-animation", action="store_true", help="morris: skip morris_animation.gif")
    parser.add_argument("--cfc", type=number(minimum=0, maximum=10_000), default=180.0, metavar="CFC",
                        help="hall: SAE J211 channel class of the zero-phase low-pass (default 180, Hall's; 0: none)")
    parser.add_argument("--angle-mode", choices=("absolute", "incremental_sum"), default="absolute",
                        help="hall: angles of the integrated matrices (default) or the literal sum of incremental "
                        "Euler angles")
    parser.add_argument("--write-recording", type=Path, metavar="DIR",
                        help="simulate: write morris.csv, hall.csv, their *_platform.json and *_truth.csv to DIR")
    parser.add_argument("--accelerometers", type=int, choices=(5, 6), default=5,
                        help="simulate: Morris platform of 5 (as published, ω3 assumed zero) or 6 accelerometers")
    parser.add_argument("--snr-db", type=_snr_db, default=40.0, metavar="DB",
                        help="simulate: accelerometer signal-to-noise ratio (default 40 dB, Morris' 'better than "
                        "40 db'; 'inf' for none)")
    parser.add_argument("--morris-rate", type=number(minimum=20, maximum=10_000, unit="Hz"), default=100.0, metavar="HZ",
                        help="simulate: Morris sampling rate (default 100 Hz, his 10 ms)")
    parser.add_argument("--hall-rate", type=number(minimum=100, maximum=100_000, unit="Hz"), default=10_000.0, metavar="HZ",
                        help="simulate: angular-rate sampling rate for Hall (default 10 kHz; CFC 180 needs > 747.9 Hz)")
    parser.add_argument("--gyro-noise", type=number(minimum=0, maximum=100, unit="rad/s"), default=0.01, metavar="RAD_S",
                        help="simulate: angular-rate sensor noise, rad/s (default 0.01)")
    parser.add_argument("--seed", type=SEED, default=0, help="simulate: noise seed (default 0)")
    add_force_option(parser)
    add_verbosity_options(parser)


# ---------------------------------------------------------------------------------------------- Morris
def _check_out(out: Path | None, what: str, *, force: bool) -> Path:
    if out is None:
        raise UsageError(f"{what}: give --out DIR for the results")
    check_output_folder("--out", out, force=force)
    return out


def _run_recording(args: argparse.Namespace) -> int:
    if args.recording is None or args.platform is None:
        raise UsageError(f"kinematics {args.method}: give the RECORDING csv and --platform JSON")
    out = _check_out(args.out, f"kinematics {args.method}", force=args.force)
    from gaitlog.host.kinematics.runs import analyse_recording

    report = analyse_recording(args.method, args.recording, args.platform, out,
                               cycle=tuple(args.cycle) if args.cycle else None, azimuth=args.azimuth,
                               elevation=args.elevation, animation=not args.no_animation, cfc=args.cfc,
                               angle_mode=args.angle_mode)
    printer(args)(report.format_table())
    return 0


# ---------------------------------------------------------------------------------------------- simulate
def _run_simulate(args: argparse.Namespace) -> int:
    if args.out is None and args.write_recording is None:
        raise UsageError("kinematics simulate: give --out DIR (figures and errors) and/or --write-recording DIR")
    if args.out is not None:
        _check_out(args.out, "kinematics simulate", force=args.force)
    if args.write_recording is not None:
        check_output_folder("--write-recording", args.write_recording, force=args.force)
    from gaitlog.host.kinematics.runs import cfc_coefficients, simulate_and_analyse

    if args.cfc:
        cfc_coefficients(args.cfc, args.hall_rate)  # reject an invalid rate before any work
    report = simulate_and_analyse(out=args.out, write_recording=args.write_recording,
                                  accelerometers=args.accelerometers, snr_db=args.snr_db,
                                  morris_rate_hz=args.morris_rate, hall_rate_hz=args.hall_rate,
                                  gyro_noise_rad_s=args.gyro_noise, cfc=args.cfc, seed=args.seed,
                                  azimuth=args.azimuth, elevation=args.elevation, animation=not args.no_animation)
    if report.lines:
        printer(args)(report.format_table(verbose=verbosity(args) > 0))
    return 0


def run(args: argparse.Namespace) -> int:
    """Dispatch on the method (module notes)."""
    if args.method == "simulate":
        if args.recording is not None:
            raise UsageError("kinematics simulate takes no RECORDING (did you mean 'kinematics morris REC.csv'?)")
        return _run_simulate(args)
    return _run_recording(args)
