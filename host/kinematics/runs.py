"""The kinematics runs of ``gaitlog kinematics``: Morris' or Hall's method on a recording
(:func:`analyse_recording`), or both on simulated instruments with their errors against the truth
(:func:`simulate_and_analyse`). Each writes its files and returns a :class:`KinematicsReport` whose
:meth:`~KinematicsReport.format_table` is the printed summary."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.budget import CONFIGURATIONS, instrument_fit
from gaitlog.host.kinematics.cfc_filter import cfc_coefficients
from gaitlog.host.kinematics.joints import joint_angles_yxz
from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
from gaitlog.host.kinematics.platform_description import HallPlatform, MorrisPlatform
from gaitlog.host.kinematics.reports import (
    analyse_hall,
    as_recording,
    hall_outputs,
    morris_errors,
    morris_outputs,
    truth_from_columns,
    write_outputs,
)
from gaitlog.host.kinematics.sensor_csv import read_sensor_csv
from gaitlog.host.kinematics.simulated_instruments import simulate_hall, simulate_morris, write_instrument

__all__ = ["KinematicsReport", "analyse_recording", "cfc_coefficients", "simulate_and_analyse"]


@dataclass
class KinematicsReport:
    """The summary lines of a kinematics run and, for ``-v``, the detail lines (the files written)."""

    lines: list[str] = field(default_factory=list)
    detail: list[str] = field(default_factory=list)

    def format_table(self, *, verbose: bool = False) -> str:
        """The summary, and the detail lines too when ``verbose``."""
        return "\n".join(self.lines + (self.detail if verbose else []))


def analyse_recording(method: str, recording: Path, platform: Path, out: Path, *, cycle: tuple[float, float] | None,
                      azimuth: float, elevation: float, animation: bool, cfc: float, angle_mode: str) -> KinematicsReport:
    """Morris' (``method = "morris"``) or Hall's (``"hall"``) method on the sensor CSV ``recording`` with the
    platform description ``platform``; the CSVs and figures written into ``out``."""
    report = KinematicsReport()
    say = report.lines.append
    recording = read_sensor_csv(recording)
    if method == "morris":
        platform = MorrisPlatform.load(platform)
        cycles = analyse_morris_recording(recording, platform, cycle_s=cycle)
        outputs = morris_outputs(cycles, recording, platform, azimuth, elevation, animation)
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
    else:
        if cfc:
            cfc_coefficients(cfc, recording.sampling_rate_hz)
        platform = HallPlatform.load(platform)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            hall = analyse_hall(recording, platform, cfc, angle_mode)
        outputs = hall_outputs(hall, recording, platform.sequence)
        write_outputs(out, outputs)
        final = np.degrees(hall.angles_rad_[-1])
        say(f"Hall: sequence {platform.sequence}, {platform.side} side, {recording.sampling_rate_hz:g} Hz, "
            f"CFC {cfc:g}, {hall.angles_rad_.shape[0]} samples; final angles "
            f"({', '.join(f'{x:.2f}' for x in final)}) deg")
        for w in caught:
            say(f"  warning: {w.message}")
    say(f"written to {out}/: {' '.join(outputs)}")
    return report


def simulate_and_analyse(*, out: Path | None, write_recording: Path | None, accelerometers: int, snr_db: float,
                         morris_rate_hz: float, hall_rate_hz: float, gyro_noise_rad_s: float, cfc: float, seed: int,
                         azimuth: float, elevation: float, animation: bool) -> KinematicsReport:
    """Morris' platform and Hall's two links simulated; their recordings written into ``write_recording`` (when
    given); both methods run on them and their errors against the truth reported, with the figures and results
    written into ``out`` (when given). ``snr_db`` ``inf``: no noise."""
    report = KinematicsReport()
    say = report.lines.append
    snr = None if math.isinf(snr_db) else snr_db
    kw = {"snr_db": snr, "sampling_rate_hz": morris_rate_hz, "seed": seed}
    morris = simulate_morris(n_accelerometers=accelerometers, **kw)
    hall = simulate_hall(sampling_rate_hz=hall_rate_hz, noise_rad_s=gyro_noise_rad_s, seed=seed)
    if write_recording is not None:
        paths = write_instrument(morris, write_recording, "morris") + write_instrument(hall, write_recording, "hall")
        say(f"recordings written to {write_recording}/: {' '.join(p.name for p in paths)}")
    if out is None:
        return report
    # Morris as published, and what its ω3 = 0 assumption costs
    rec = as_recording(morris, morris_rate_hz)
    cycles = analyse_morris_recording(rec, morris.platform)
    variants = [("as simulated", cycles, truth_from_columns(morris))]
    for label, sim in (("no axial rotation", simulate_morris(n_accelerometers=accelerometers,
                                                              axial_rotation=False, **kw)),
                       ("6 accelerometers" if accelerometers == 5 else "5 accelerometers",
                        simulate_morris(n_accelerometers=11 - accelerometers, **kw))):
        variants.append((label, analyse_morris_recording(as_recording(sim, morris_rate_hz), sim.platform),
                         truth_from_columns(sim)))
    hall_rec = as_recording(hall, hall_rate_hz)
    result = analyse_hall(hall_rec, hall.platform, cfc, "absolute")
    literal = analyse_hall(hall_rec, hall.platform, cfc, "incremental_sum")
    identity = hall.platform.__class__(hall.platform.link_a, hall.platform.link_b, "yxz", "left",
                                       hall.platform.pretest_s, np.zeros(3))
    naive = analyse_hall(hall_rec, identity, cfc, "absolute")
    tr = hall.truth
    true_angles = np.stack([tr["phi_rad"], tr["theta_rad"], tr["psi_rad"]], axis=1)
    outputs = morris_outputs(cycles, rec, morris.platform, azimuth, elevation, animation)
    outputs.update(hall_outputs(result, hall_rec, "yxz"))
    outputs["hall_joint_angles.png"] = (outputs["hall_joint_angles.png"][0], outputs["hall_joint_angles.png"][1],
                                        {"sequence": "yxz", "truth_rad": true_angles})
    write_outputs(out, outputs)
    noise = "no noise" if snr is None else f"{snr:g} dB SNR"
    say(f"Morris shank, {accelerometers} accelerometers, {morris_rate_hz:g} Hz, {noise}, "
        f"{len(cycles)} cycle(s) found from foot-flat:")
    report.lines += [_morris_error_line(label, cs, truth) for label, cs, truth in variants]
    err = np.degrees(np.abs(result.angles_rad_ - true_angles).max(axis=0))
    err_naive = np.degrees(np.abs(naive.angles_rad_ - true_angles).max(axis=0))
    say(f"Hall two links, {hall_rate_hz:g} Hz, CFC {cfc:g}, gyro noise {gyro_noise_rad_s:g} rad/s:")
    say(f"  joint angles      max error {_fmt3(err)} deg (phi, theta, psi), initial A-B from the pre-test gravity")
    say(f"  with identity     max error {_fmt3(err_naive)} deg (initial A-B taken as identity)")
    say(f"  final angles      {_fmt3(np.degrees(result.angles_rad_[-1]))} deg, truth "
        f"{_fmt3(np.degrees(true_angles[-1]))} deg")
    say(f"  literal sum of incremental Euler angles ends at {_fmt3(np.degrees(literal.angles_rad_[-1]))} deg")
    say(f"  initial posture   {_fmt3(np.degrees(joint_angles_yxz(result.joint_matrix_[0])[0]))} deg")
    report.lines += _instrument_fit_lines(morris, hall, morris_rate_hz, hall_rate_hz)
    say(f"figures and results written to {out}/: {' '.join(outputs)}")
    report.detail += [f"  {out / name}" for name in outputs]
    return report


def _fmt3(xs) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in xs) + ")"


def _morris_error_line(label: str, cycles, truth) -> str:
    errs = [morris_errors(c, truth) for c in cycles]
    return (f"  {label:<18} orientation max error {max(e['orientation_deg'] for e in errs):.3g} deg "
            f"(tilt {max(e['tilt_deg'] for e in errs):.3g} deg), ω max error "
            f"{max(e['omega_rad_s'] for e in errs):.3g} rad/s (axial rate peak "
            f"{max(e['omega_axial_peak_rad_s'] for e in errs):.2f} rad/s), position max error "
            f"{max(e['position_m'] for e in errs):.3g} m")


def _instrument_fit_lines(morris, hall, morris_rate_hz: float, hall_rate_hz: float) -> list[str]:
    """Whether the simulated instruments fit the PIC16F877 logger
    (:func:`gaitlog.firmware_sim.budget.instrument_fit`)."""
    n_acc = len(morris.platform.sensors)
    n_rate = len(hall.platform.link_a.rate_sensors) + len(hall.platform.link_b.rate_sensors)
    lines = []
    for name, config in (("Morris", replace(CONFIGURATIONS["morris-6" if n_acc == 6 else "morris-5"],
                                            sampling_rate_hz=morris_rate_hz, adc_channels=n_acc)),
                         ("Hall", replace(CONFIGURATIONS["hall"], sampling_rate_hz=hall_rate_hz, adc_channels=n_rate))):
        short, fastest = instrument_fit(config)
        verdict = ("fits" if not short else "does not fit: " + "; ".join(short)
                   + f"; the closest that fits: {config.adc_channels} channels at {int(fastest)} Hz")
        lines.append(f"on the PIC16F877 logger, {name} ({config.adc_channels} channels at {config.sampling_rate_hz:g} Hz, "
                     f"`gaitlog budget --config {config.name}`): {verdict}")
    return lines
