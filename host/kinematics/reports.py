"""Morris' and Hall's analyses as ``gaitlog kinematics`` reports them: Hall's method on a recording, the errors of
an analysed Morris cycle against a simulation's truth, and the output files of each analysis (CSV texts and
figures, computed before anything is written, then written by :func:`write_outputs`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.atomic_write import atomic_write_text
from gaitlog.firmware_sim.algorithms.steps import columns_csv_text
from gaitlog.host.errors import HostError
from gaitlog.host.kinematics import plots
from gaitlog.host.kinematics.accelerometer_pairs import AngularVelocityFromAccelerometers
from gaitlog.host.kinematics.joints import JOINT_MATRICES, HallJointKinematics
from gaitlog.host.kinematics.orientation import geodesic_distance_rad, initial_dcm_from_gravity
from gaitlog.host.kinematics.sensor_csv import SensorRecording, split_unit


def analyse_hall(recording: Any, platform: Any, cfc: float, angle_mode: str) -> Any:
    """Hall's method on a recording: pre-test posture, offsets, CFC, link matrices, joint angles."""
    ra = recording.columns(platform.link_a.rate_sensors, "angular rate")
    rb = recording.columns(platform.link_b.rate_sensors, "angular rate")
    n_pre = int(np.floor(platform.pretest_s * recording.sampling_rate_hz)) + 1 if platform.pretest_s > 0 else 0
    if n_pre >= ra.shape[0]:
        raise HostError(f"{recording.source}: the pre-test window of {platform.pretest_s:g} s covers the whole "
                        f"recording ({ra.shape[0]} samples)")
    if platform.initial_joint_deg is not None:  # Hall: TA = I, TB = the initial A-B matrix
        ta0, tb0 = np.eye(3), JOINT_MATRICES[platform.sequence](np.radians(platform.initial_joint_deg))
    else:  # the pre-test posture from gravity in each link (heading λ12 = 0 for both)
        up_a = recording.columns(platform.link_a.gravity_sensors, "specific force")[:n_pre].mean(axis=0)
        up_b = recording.columns(platform.link_b.gravity_sensors, "specific force")[:n_pre].mean(axis=0)
        ta0 = initial_dcm_from_gravity(up_a, on_singular="axis1").T
        tb0 = initial_dcm_from_gravity(up_b, on_singular="axis1").T
    return HallJointKinematics(
        sensor_to_link_a=platform.link_a.sensor_to_link, sensor_to_link_b=platform.link_b.sensor_to_link,
        initial_ta=ta0, initial_tb=tb0, pretest_samples=n_pre, cfc=cfc or None, side=platform.side,
        angle_mode=angle_mode, sequence=platform.sequence,
    ).compute(ra, rb, sampling_rate_hz=recording.sampling_rate_hz)


def morris_errors(cycle: Any, truth: dict[str, Any]) -> dict[str, float]:
    """Errors of one analysed cycle against the simulation's truth, the heading aligned at the cycle start
    (accelerometers cannot sense it)."""
    sel = slice(cycle.start, cycle.stop + 1)
    true_dcm = truth["dcm"][sel]
    heading = cycle.dcm[0] @ true_dcm[0].T
    aligned = heading @ true_dcm
    tilt = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", cycle.dcm[:, 2], true_dcm[:, 2]), -1, 1)))
    w_err = np.abs(cycle.omega_rad_s - truth["omega_rad_s"][sel])
    pos = truth["position_m"][sel] - truth["position_m"][sel][0]  # both frames walk along axis 1
    return {"orientation_deg": float(np.degrees(geodesic_distance_rad(cycle.dcm, aligned).max())),
            "position_m": float(np.abs(cycle.position_m - pos).max()),
            "tilt_deg": float(tilt.max()), "omega_rad_s": float(w_err.max()),
            "omega_axial_peak_rad_s": float(np.abs(truth["omega_rad_s"][sel, 2]).max())}


def truth_from_columns(sim: Any) -> dict[str, Any]:
    """A simulated instrument's truth columns (``dcm11``..., ``omega1_rad_s``..., ``position1_m``...) as arrays:
    ``dcm`` (n, 3, 3), ``omega_rad_s`` and ``position_m`` (n, 3)."""
    tr = sim.truth
    dcm = np.stack([[tr[f"dcm{i + 1}{j + 1}"] for j in range(3)] for i in range(3)]).transpose(2, 0, 1)
    return {"dcm": dcm, "omega_rad_s": np.stack([tr[f"omega{k + 1}_rad_s"] for k in range(3)], axis=1),
            "position_m": np.stack([tr[f"position{k + 1}_m"] for k in range(3)], axis=1)}


def as_recording(sim: Any, rate: float) -> SensorRecording:
    """A simulated instrument's columns as a :class:`~gaitlog.host.kinematics.sensor_csv.SensorRecording` at
    ``rate`` Hz (the units of the column names applied)."""
    ch, q = {}, {}
    for name, v in sim.columns.items():
        s, quantity, factor = split_unit(name)
        ch[s], q[s] = v * factor, quantity
    return SensorRecording(sim.t_s, ch, q, rate, "<simulated>")


def morris_outputs(cycles: list, recording: Any, platform: Any, azimuth: float, elevation: float,
                   animation: bool) -> dict[str, Any]:
    """``{file name: CSV text | (plot function, args, kwargs)}`` of a Morris analysis (nothing written yet)."""
    cyc = np.concatenate([np.full(c.t_s.size, i + 1) for i, c in enumerate(cycles)])
    t = np.concatenate([c.t_s for c in cycles])

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(c, name) for c in cycles])

    dcm = cat("dcm")
    orient = {"cycle": cyc, "time_s": t, **{f"dcm{i + 1}{j + 1}": dcm[:, i, j] for i in range(3) for j in range(3)}}
    w_raw, w, al = cat("omega_raw_rad_s"), cat("omega_rad_s"), cat("alpha_rad_s2")
    ang = {"cycle": cyc, "time_s": t, **{f"omega{k + 1}_rad_s": w[:, k] for k in range(3)},
           **{f"omega{k + 1}_before_drift_filter_rad_s": w_raw[:, k] for k in range(3)},
           **{f"alpha{k + 1}_rad_s2": al[:, k] for k in range(3)}}
    a, v, p = cat("acceleration_m_s2"), cat("velocity_m_s"), cat("position_m")
    trans = {"cycle": cyc, "time_s": t, **{f"acceleration{k + 1}_m_s2": a[:, k] for k in range(3)},
             **{f"velocity{k + 1}_m_s": v[:, k] for k in range(3)}, **{f"position{k + 1}_m": p[:, k] for k in range(3)}}
    c = cycles[0]
    r_o = platform.origin_from_pivot_m
    # Fig 4a: the whole record integrated from its start with the cycle's mean-rate start (no filtering)
    readings = recording.columns(platform.sensors, "specific force")
    solver = AngularVelocityFromAccelerometers(positions_m=platform.positions_m, axes=platform.axes,
                                               fixed_zero_axes=platform.assume_zero_rate_axes)
    whole = solver.estimate(readings, sampling_rate_hz=recording.sampling_rate_hz,
                            omega0_rad_s=c.omega_raw_rad_s[0]).omega_rad_s_
    whole = whole - whole[c.start] + c.omega_raw_rad_s[0]
    out: dict[str, Any] = {
        "morris_orientation.csv": columns_csv_text(orient),
        "morris_angular_velocity.csv": columns_csv_text(ang),
        "morris_translation.csv": columns_csv_text(trans),
        "morris_angular_velocity.png": (plots.plot_angular_velocity, (c.t_s, c.omega_raw_rad_s, c.omega_rad_s),
                                        {"record": (recording.t_s, whole)}),
        "morris_dcm.png": (plots.plot_dcm, (c.t_s, c.dcm), {}),
        "morris_translation.png": (plots.plot_translation, (c.t_s, c.acceleration_m_s2, c.velocity_m_s, c.position_m),
                                   {}),
        "morris_stick_figure.png": (plots.plot_body_model, (c.t_s, c.dcm, c.position_m + r_o, r_o),
                                    {"azimuth_deg": azimuth, "elevation_deg": elevation}),
    }
    if animation:
        out["morris_animation.gif"] = (plots.write_body_model_gif, (c.t_s, c.dcm, c.position_m + r_o, r_o),
                                       {"azimuth_deg": azimuth, "elevation_deg": elevation})
    return out


def hall_outputs(hall: Any, recording: Any, sequence: str) -> dict[str, Any]:
    """``{file name: CSV text | plot}`` of a Hall analysis."""
    t = recording.t_s
    names = ("flexion_deg", "version_deg", "axial_rotation_deg") if sequence == "yxz" else (
        "tilt_deg", "rotation_deg", "flexion_deg")
    deg = np.degrees(hall.angles_rad_)
    angles = {"time_s": t, **{n: deg[:, k] for k, n in enumerate(names)},
              "gimbal_lock": hall.gimbal_lock_.astype(bool)}
    links = {"time_s": t, **{f"TA{i + 1}{j + 1}": hall.ta_[:, i, j] for i in range(3) for j in range(3)},
             **{f"TB{i + 1}{j + 1}": hall.tb_[:, i, j] for i in range(3) for j in range(3)}}
    rates = {"time_s": t, **{f"A_{x}_rad_s": hall.rate_a_link_rad_s_[:, k] for k, x in enumerate("xyz")},
             **{f"B_{x}_rad_s": hall.rate_b_link_rad_s_[:, k] for k, x in enumerate("xyz")}}
    return {
        "hall_joint_angles.csv": columns_csv_text(angles),
        "hall_link_orientation.csv": columns_csv_text(links),
        "hall_angular_velocity.csv": columns_csv_text(rates),
        "hall_joint_angles.png": (plots.plot_joint_angles, (t, hall.angles_rad_), {"sequence": sequence}),
    }


def write_outputs(out: Path, outputs: dict[str, Any]) -> None:
    """Create ``out`` and write every output (texts atomically, figures through their atomic writers)."""
    out.mkdir(parents=True, exist_ok=True)
    for name, item in outputs.items():
        if isinstance(item, str):
            atomic_write_text(out / name, item)
        else:
            fn, fargs, kwargs = item
            fn(*fargs, out / name, **kwargs)
