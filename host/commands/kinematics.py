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
import math
import warnings
from dataclasses import replace
from pathlib import Path

from gaitlog.host.commands._options import (
    SEED,
    add_force_option,
    add_verbosity_options,
    check_output_folder,
    number,
    printer,
)
from gaitlog.host.errors import UsageError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

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
    from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
    from gaitlog.host.kinematics.platform_description import HallPlatform, MorrisPlatform
    from gaitlog.host.kinematics.reports import analyse_hall, hall_outputs, morris_outputs, write_outputs
    from gaitlog.host.kinematics.sensor_csv import read_sensor_csv

    if args.recording is None or args.platform is None:
        raise UsageError(f"kinematics {args.method}: give the RECORDING csv and --platform JSON")
    out = _check_out(args.out, f"kinematics {args.method}", force=args.force)
    recording = read_sensor_csv(args.recording)
    say = printer(args)
    if args.method == "morris":
        platform = MorrisPlatform.load(args.platform)
        cycle = tuple(args.cycle) if args.cycle else None
        cycles = analyse_morris_recording(recording, platform, cycle_s=cycle)
        outputs = morris_outputs(cycles, recording, platform, args.azimuth, args.elevation, not args.no_animation)
        write_outputs(out, outputs)
        zero = f", rate about axis {'/'.join(str(a + 1) for a in platform.assume_zero_rate_axes)} assumed zero" \
            if platform.assume_zero_rate_axes else ""
        say(f"Morris: {len(platform.sensors)} accelerometers{zero}, {recording.sampling_rate_hz:g} Hz, "
            f"{len(cycles)} cycle(s): " + ", ".join(f"{c.t_s[0]:.2f}-{c.t_s[-1]:.2f} s" for c in cycles))
        for i, c in enumerate(cycles):
            disp = c.position_m[-1] - c.position_m[0]
            say(f"  cycle {i + 1}: peak |ω| {float(abs(c.omega_rad_s).max()):.2f} rad/s, displacement "
                f"{float(disp[0]):.3f} m forwards, {float(disp[1]):.3f} m sideways")
            if abs(c.pivot_misfit_g) > 0.1:
                say(f"  warning: cycle {i + 1} starts at {c.t_s[0]:.2f} s where the shank is not turning about a "
                    f"fixed pivot (gravity from eq 11 is {1 + c.pivot_misfit_g:.2f} g, not 1 g): the initial direction "
                    "cosines need a start in foot-flat")
        names = list(outputs)
    else:
        if args.cfc:
            from gaitlog.host.kinematics.cfc_filter import cfc_coefficients

            cfc_coefficients(args.cfc, recording.sampling_rate_hz)
        platform = HallPlatform.load(args.platform)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            hall = analyse_hall(recording, platform, args.cfc, args.angle_mode)
        outputs = hall_outputs(hall, recording, platform.sequence)
        write_outputs(out, outputs)
        import numpy as np

        final = np.degrees(hall.angles_rad_[-1])
        say(f"Hall: sequence {platform.sequence}, {platform.side} side, {recording.sampling_rate_hz:g} Hz, "
            f"CFC {args.cfc:g}, {hall.angles_rad_.shape[0]} samples; final angles "
            f"({', '.join(f'{x:.2f}' for x in final)}) deg")
        for w in caught:
            say(f"  warning: {w.message}")
        names = list(outputs)
    say(f"written to {out}/: {' '.join(names)}")
    return 0


# ---------------------------------------------------------------------------------------------- simulate
def _run_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from gaitlog.host.kinematics.cfc_filter import cfc_coefficients
    from gaitlog.host.kinematics.joints import joint_angles_yxz
    from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
    from gaitlog.host.kinematics.reports import (
        analyse_hall,
        as_recording,
        hall_outputs,
        morris_errors,
        morris_outputs,
        truth_from_columns,
        write_outputs,
    )
    from gaitlog.host.kinematics.simulated_instruments import (
        simulate_hall,
        simulate_morris,
        write_instrument,
    )

    if args.out is None and args.write_recording is None:
        raise UsageError("kinematics simulate: give --out DIR (figures and errors) and/or --write-recording DIR")
    if args.out is not None:
        _check_out(args.out, "kinematics simulate", force=args.force)
    if args.write_recording is not None:
        check_output_folder("--write-recording", args.write_recording, force=args.force)
    if args.cfc:
        cfc_coefficients(args.cfc, args.hall_rate)  # reject an invalid rate before any work
    snr = None if math.isinf(args.snr_db) else args.snr_db
    kw = {"snr_db": snr, "sampling_rate_hz": args.morris_rate, "seed": args.seed}
    morris = simulate_morris(n_accelerometers=args.accelerometers, **kw)
    hall = simulate_hall(sampling_rate_hz=args.hall_rate, noise_rad_s=args.gyro_noise, seed=args.seed)
    say, detail = printer(args), printer(args, 1)
    if args.write_recording is not None:
        paths = write_instrument(morris, args.write_recording, "morris") + write_instrument(
            hall, args.write_recording, "hall")
        say(f"recordings written to {args.write_recording}/: {' '.join(p.name for p in paths)}")
    if args.out is None:
        return 0
    # Morris as published, and what its ω3 = 0 assumption costs
    rec = as_recording(morris, args.morris_rate)
    cycles = analyse_morris_recording(rec, morris.platform)
    variants = [("as simulated", cycles, truth_from_columns(morris))]
    for label, sim in (("no axial rotation", simulate_morris(n_accelerometers=args.accelerometers,
                                                              axial_rotation=False, **kw)),
                       ("6 accelerometers" if args.accelerometers == 5 else "5 accelerometers",
                        simulate_morris(n_accelerometers=11 - args.accelerometers, **kw))):
        variants.append((label, analyse_morris_recording(as_recording(sim, args.morris_rate), sim.platform),
                         truth_from_columns(sim)))
    hall_rec = as_recording(hall, args.hall_rate)
    result = analyse_hall(hall_rec, hall.platform, args.cfc, "absolute")
    literal = analyse_hall(hall_rec, hall.platform, args.cfc, "incremental_sum")
    identity = hall.platform.__class__(hall.platform.link_a, hall.platform.link_b, "yxz", "left",
                                       hall.platform.pretest_s, np.zeros(3))
    naive = analyse_hall(hall_rec, identity, args.cfc, "absolute")
    tr = hall.truth
    true_angles = np.stack([tr["phi_rad"], tr["theta_rad"], tr["psi_rad"]], axis=1)
    outputs = morris_outputs(cycles, rec, morris.platform, args.azimuth, args.elevation, not args.no_animation)
    outputs.update(hall_outputs(result, hall_rec, "yxz"))
    outputs["hall_joint_angles.png"] = (outputs["hall_joint_angles.png"][0], outputs["hall_joint_angles.png"][1],
                                        {"sequence": "yxz", "truth_rad": true_angles})
    write_outputs(args.out, outputs)
    noise = "no noise" if snr is None else f"{snr:g} dB SNR"
    say(f"Morris shank, {args.accelerometers} accelerometers, {args.morris_rate:g} Hz, {noise}, "
        f"{len(cycles)} cycle(s) found from foot-flat:")
    for label, cs, truth in variants:
        errs = [morris_errors(c, truth) for c in cs]
        say(f"  {label:<18} orientation max error {max(e['orientation_deg'] for e in errs):.3g} deg "
            f"(tilt {max(e['tilt_deg'] for e in errs):.3g} deg), ω max error "
            f"{max(e['omega_rad_s'] for e in errs):.3g} rad/s (axial rate peak "
            f"{max(e['omega_axial_peak_rad_s'] for e in errs):.2f} rad/s), position max error "
            f"{max(e['position_m'] for e in errs):.3g} m")
    err = np.degrees(np.abs(result.angles_rad_ - true_angles).max(axis=0))
    err_naive = np.degrees(np.abs(naive.angles_rad_ - true_angles).max(axis=0))
    fmt3 = lambda xs: "(" + ", ".join(f"{x:.3g}" for x in xs) + ")"  # noqa: E731
    say(f"Hall two links, {args.hall_rate:g} Hz, CFC {args.cfc:g}, gyro noise {args.gyro_noise:g} rad/s:")
    say(f"  joint angles      max error {fmt3(err)} deg (phi, theta, psi), initial A-B from the pre-test gravity")
    say(f"  with identity     max error {fmt3(err_naive)} deg (initial A-B taken as identity)")
    say(f"  final angles      {fmt3(np.degrees(result.angles_rad_[-1]))} deg, truth "
        f"{fmt3(np.degrees(true_angles[-1]))} deg")
    say(f"  literal sum of incremental Euler angles ends at {fmt3(np.degrees(literal.angles_rad_[-1]))} deg")
    say(f"  initial posture   {fmt3(np.degrees(joint_angles_yxz(result.joint_matrix_[0])[0]))} deg")
    from gaitlog.firmware_sim.budget import CONFIGURATIONS, instrument_fit

    n_acc = len(morris.platform.sensors)
    n_rate = len(hall.platform.link_a.rate_sensors) + len(hall.platform.link_b.rate_sensors)
    for name, config in (("Morris", replace(CONFIGURATIONS["morris-6" if n_acc == 6 else "morris-5"],
                                            sampling_rate_hz=args.morris_rate, adc_channels=n_acc)),
                         ("Hall", replace(CONFIGURATIONS["hall"], sampling_rate_hz=args.hall_rate, adc_channels=n_rate))):
        short, fastest = instrument_fit(config)
        verdict = ("fits" if not short else "does not fit: " + "; ".join(short)
                   + f"; the closest that fits: {config.adc_channels} channels at {int(fastest)} Hz")
        say(f"on the PIC16F877 logger, {name} ({config.adc_channels} channels at {config.sampling_rate_hz:g} Hz, "
            f"`gaitlog budget --config {config.name}`): {verdict}")
    say(f"figures and results written to {args.out}/: {' '.join(outputs)}")
    for name in outputs:
        detail(f"  {args.out / name}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Dispatch on the method (module notes)."""
    if args.method == "simulate":
        if args.recording is not None:
            raise UsageError("kinematics simulate takes no RECORDING (did you mean 'kinematics morris REC.csv'?)")
        return _run_simulate(args)
    return _run_recording(args)
