"""``gaitlog kinematics``: simulate Morris' shank platform and Hall's two links, run both methods, draw figures.

Morris (1973), one gait cycle starting in foot-flat, simulated by :class:`RigidBodyShank` (six accelerometers):

1. angular velocity from the accelerometer pairs (eqs 5-8); the integration constant (eq 6) is chosen so that
   the orientation at the end of the cycle equals that at its start (Newton iteration), then the cycle
   drift filter makes the start and end values of the angular velocity equal (Fig 4b);
2. initial direction cosines at foot-flat from the pivot constraint (eq 11) and gravity (eqs 12-16);
3. strapdown integration of the direction cosines (eqs 9-10);
4. gravity removal, double integration, cycle drift removal (velocity start = end; the vertical position
   returns to its start; the initial velocity follows from the fixed pivot, ``λ(ω × r)``; the walking
   direction is not known in the ``λ12 = 0`` frame, so the horizontal positions are left open).

The estimated space frame has the heading fixed by ``λ12 = 0``; truths are rotated about the vertical into
it before comparison. Hall (1997): :class:`TwoLinkJoint` at 10 kHz with sensor offsets and noise,
:class:`HallJointKinematics` with pre-test offset removal and CFC 180.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

#: The figures written to ``--out``.
FIGURES = ("morris_angular_velocity.png", "morris_dcm.png", "morris_translation.png", "morris_stick_figure.png",
           "hall_joint_angles.png")

HELP = "Simulate the Morris shank platform and Hall's two links, run both kinematics, write figures."


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``gaitlog kinematics``."""
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder for the PNG figures (created)")
    from host.commands._options import SEED, add_verbosity_options, number

    parser.add_argument("--morris-rate", type=number(minimum=10, maximum=10_000, unit="Hz"), default=100.0, metavar="HZ",
                        help="sampling rate of the simulated Morris platform (default 100 Hz, Morris' 10 ms); "
                        "kinematics takes no recording: Morris needs six accelerometers at known places on the "
                        "shank and Hall angular rates, which a tri-axial logger does not record")
    parser.add_argument("--noise-mg", type=number(minimum=0, maximum=10_000, unit="mg"), default=0.0, metavar="MG",
                        help="white noise added to each platform accelerometer, mg (default 0)")
    parser.add_argument("--hall-rate", type=number(minimum=100, maximum=100_000, unit="Hz"), default=10_000.0, metavar="HZ",
                        help="angular-rate sampling rate for Hall (default 10 kHz; CFC 180 needs > 747.9 Hz)")
    parser.add_argument("--gyro-noise", type=number(minimum=0, maximum=100, unit="rad/s"), default=0.01, metavar="RAD_S",
                        help="angular-rate sensor noise, rad/s (default 0.01)")
    parser.add_argument("--seed", type=SEED, default=0, help="noise seed (default 0)")
    add_verbosity_options(parser)


def run_morris(sampling_rate_hz: float, noise_mg: float = 0.0, seed: int = 0) -> dict[str, Any]:
    """Simulate one cycle, run Morris' method; returns estimates, heading-aligned truth and error numbers."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from firmware_sim.world.rigid_body import RigidBodyShank
    from host.errors import HostError
    from host.kinematics.accelerometer_pairs import (
        AngularVelocityFromAccelerometers,
        gravity_from_pivot,
    )
    from host.kinematics.orientation import (
        geodesic_distance_rad,
        initial_dcm_from_gravity,
        integrate_dcm,
    )
    from host.kinematics.strapdown import (
        CycleTranslation,
        remove_cycle_drift,
        remove_gravity,
    )

    if not (np.isfinite(sampling_rate_hz) and 20 <= sampling_rate_hz <= 100_000):
        raise HostError(f"--morris-rate must be between 20 and 100000 Hz, got {sampling_rate_hz:g}")
    src = RigidBodyShank(n_cycles=1)
    rec = src.render_platform(sampling_rate_hz)
    tr = rec.motion.truth
    readings = rec.readings_g + np.random.default_rng(seed).normal(0.0, noise_mg * 1e-3, rec.readings_g.shape)
    solver = AngularVelocityFromAccelerometers(positions_m=rec.positions_m, axes=rec.axes)
    # 1. ω: the constant C of eq (6) from the cycle: the orientation returns to its start (Newton on the
    #    rotation vector of λ(0)ᵀλ(T), finite-difference Jacobian), then the Fig 4b drift filter
    def closure(c: np.ndarray) -> tuple[np.ndarray, Any]:
        e = solver.estimate(readings, sampling_rate_hz=sampling_rate_hz, omega0_rad_s=c)
        lam = integrate_dcm(e.omega_rad_s_, sampling_rate_hz)
        return Rotation.from_matrix(lam[-1]).as_rotvec(), e

    omega0 = np.zeros(3)
    weights = np.full(readings.shape[0], 1.0 / (readings.shape[0] - 1))
    weights[[0, -1]] *= 0.5
    for _ in range(3):  # start: mean rate zero over the cycle (exact for planar motion)
        omega0 = omega0 - weights @ solver.estimate(readings, sampling_rate_hz=sampling_rate_hz, omega0_rad_s=omega0).omega_rad_s_
    for _ in range(3):
        f0, est = closure(omega0)
        jac = np.stack([(closure(omega0 + 1e-4 * np.eye(3)[j])[0] - f0) / 1e-4 for j in range(3)], axis=1)
        omega0 = omega0 - np.linalg.solve(jac, f0)
    est = solver.estimate(readings, sampling_rate_hz=sampling_rate_hz, omega0_rad_s=omega0)
    omega_raw = est.omega_rad_s_
    omega = remove_cycle_drift(omega_raw)
    # 2. initial direction cosines at foot-flat (eq 11, eqs 12-16)
    r_o = tr["origin_offset_m"]
    up0 = gravity_from_pivot(est.origin_specific_force_g_[0], omega[0], est.alpha_rad_s2_[0], r_o)
    lam0 = initial_dcm_from_gravity(up0)
    # 3. strapdown direction cosines
    dcm = integrate_dcm(omega, sampling_rate_hz, lam0)
    # 4. translation of the origin
    acc = remove_gravity(est.origin_specific_force_g_, dcm)
    v0 = lam0 @ np.cross(omega[0], r_o)
    trans = CycleTranslation(closed_axes=(2,), initial_velocity_m_s=v0).integrate(acc, sampling_rate_hz=sampling_rate_hz)
    # truth in the estimated space frame (rotation about the vertical fixed at t = 0)
    heading = lam0 @ tr["dcm"][0].T
    true_dcm = heading @ tr["dcm"]
    true_acc = tr["acceleration_m_s2"] @ heading.T
    true_vel = tr["velocity_m_s"] @ heading.T
    true_pos = (tr["position_m"] - tr["position_m"][0]) @ heading.T
    t = tr["t_s"]
    tilt = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", dcm[:, 2], true_dcm[:, 2]), -1, 1)))
    return {
        "t_s": t,
        "omega_raw_rad_s": omega_raw,
        "omega_rad_s": omega,
        "omega_true_rad_s": tr["omega_rad_s"],
        "dcm": dcm,
        "dcm_true": true_dcm,
        "acc_m_s2": trans.acceleration_m_s2_,
        "vel_m_s": trans.velocity_m_s_,
        "pos_m": trans.position_m_,
        "truth_translation": (true_acc, true_vel, true_pos),
        "origin_from_ankle_m": r_o,
        "pos0_true_m": tr["position_m"][0] @ heading.T,
        "errors": {
            "omega_rad_s": float(np.abs(omega - tr["omega_rad_s"]).max()),
            "omega_peak_rad_s": float(np.abs(tr["omega_rad_s"]).max()),
            "heading_deg": float(np.degrees(np.arctan2(heading[1, 0], heading[0, 0]))),
            "orientation_deg": float(np.degrees(geodesic_distance_rad(dcm, true_dcm).max())),
            "tilt_deg": float(tilt.max()),
            "velocity_m_s": float(np.abs(trans.velocity_m_s_ - true_vel).max()),
            "position_m": [float(x) for x in np.abs(trans.position_m_ - true_pos).max(axis=0)],
            "stride_est_m": float(np.linalg.norm(trans.position_m_[-1] - trans.position_m_[0])),
            "stride_true_m": float(np.linalg.norm(true_pos[-1] - true_pos[0])),
        },
    }


def run_hall(sampling_rate_hz: float, noise_rad_s: float = 0.01, seed: int = 0) -> dict[str, Any]:
    """Simulate the two links, run Hall's method (CFC 180) and the literal incremental-sum variant."""
    import numpy as np

    from firmware_sim.world.two_link import TwoLinkJoint
    from host.kinematics.joints import HallJointKinematics

    src = TwoLinkJoint(noise_rad_s=noise_rad_s, seed=seed)
    r = src.render_rates(sampling_rate_hz)
    kw = dict(
        sensor_to_link_a=r.truth["sensor_to_link_a"],
        sensor_to_link_b=r.truth["sensor_to_link_b"],
        pretest_samples=r.pretest_samples,
        cfc=180,
    )
    hall = HallJointKinematics(**kw).compute(r.rate_a_rad_s, r.rate_b_rad_s, sampling_rate_hz=sampling_rate_hz)
    literal = HallJointKinematics(**kw, angle_mode="incremental_sum").compute(
        r.rate_a_rad_s, r.rate_b_rad_s, sampling_rate_hz=sampling_rate_hz
    )
    truth = r.truth["joint_angles_rad"]
    return {
        "t_s": r.truth["t_s"],
        "angles_rad": hall.angles_rad_,
        "truth_rad": truth,
        "errors": {
            "angles_deg": [float(x) for x in np.degrees(np.abs(hall.angles_rad_ - truth).max(axis=0))],
            "final_deg": [float(x) for x in np.degrees(hall.angles_rad_[-1])],
            "final_true_deg": [float(x) for x in np.degrees(truth[-1])],
            "literal_final_deg": [float(x) for x in np.degrees(literal.angles_rad_[-1])],
            "gimbal_lock_samples": int(hall.gimbal_lock_.sum()),
        },
    }


def run(args: argparse.Namespace) -> int:
    """Run both simulations and methods, write the figures, print the errors against the truth (not with -q;
    each figure's path with -v)."""
    from host.commands._options import check_output_folder, printer
    from host.kinematics.plots import (
        plot_angular_velocity,
        plot_dcm,
        plot_joint_angles,
        plot_stick_figure,
        plot_translation,
    )

    out: Path = args.out
    check_output_folder("--out", out)
    from host.kinematics.cfc_filter import cfc_coefficients

    cfc_coefficients(180, args.hall_rate)  # reject an invalid rate before any work
    morris = run_morris(args.morris_rate, args.noise_mg, args.seed)
    hall = run_hall(args.hall_rate, args.gyro_noise, args.seed)
    out.mkdir(parents=True, exist_ok=True)
    t = morris["t_s"]
    plot_angular_velocity(t, morris["omega_raw_rad_s"], morris["omega_rad_s"], out / "morris_angular_velocity.png",
                          truth_rad_s=morris["omega_true_rad_s"])
    plot_dcm(t, morris["dcm"], out / "morris_dcm.png", truth=morris["dcm_true"])
    plot_translation(t, morris["acc_m_s2"], morris["vel_m_s"], morris["pos_m"], out / "morris_translation.png",
                     truth=morris["truth_translation"])
    p0 = morris["pos0_true_m"]
    plot_stick_figure(t, morris["dcm"], morris["pos_m"] + p0, morris["origin_from_ankle_m"],
                      out / "morris_stick_figure.png",
                      truth=(morris["dcm_true"], morris["truth_translation"][2] + p0))
    plot_joint_angles(hall["t_s"], hall["angles_rad"], out / "hall_joint_angles.png", truth_rad=hall["truth_rad"])
    say, detail = printer(args), printer(args, 1)
    me, he = morris["errors"], hall["errors"]
    fmt3 = lambda xs: "(" + ", ".join(f"{x:.3g}" for x in xs) + ")"  # noqa: E731
    say(f"Morris shank, 6 accelerometers, {args.morris_rate:g} Hz, one {t[-1]:.2f} s cycle, noise {args.noise_mg:g} mg:")
    say(f"  angular velocity  max error {me['omega_rad_s']:.3g} rad/s (peak {me['omega_peak_rad_s']:.2f} rad/s)")
    say(f"  orientation       max error {me['orientation_deg']:.3g} deg (tilt {me['tilt_deg']:.3g} deg; "
        f"heading of the λ12 = 0 frame {me['heading_deg']:.2f} deg)")
    say(f"  velocity          max error {me['velocity_m_s']:.3g} m/s")
    say(f"  position          max error {fmt3(me['position_m'])} m (fwd, side, vertical); "
        f"stride {me['stride_est_m']:.4f} m vs {me['stride_true_m']:.4f} m")
    say(f"Hall two links, {args.hall_rate:g} Hz, CFC 180, gyro noise {args.gyro_noise:g} rad/s:")
    say(f"  joint angles      max error {fmt3(he['angles_deg'])} deg (phi, theta, psi)")
    say(f"  final angles      {fmt3(he['final_deg'])} deg, truth {fmt3(he['final_true_deg'])} deg")
    say(f"  literal sum of incremental Euler angles ends at {fmt3(he['literal_final_deg'])} deg")
    say(f"  gimbal lock at {he['gimbal_lock_samples']} samples")
    say(f"figures written to {out}/: {' '.join(FIGURES)}")
    for name in FIGURES:
        detail(f"  {out / name}")
    return 0
