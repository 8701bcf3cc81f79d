"""A shank-like rigid segment carrying Morris' (1973) accelerometer platform, with exact ground truth.

Frames: body axes 1 = anterior, 2 = left, 3 = along the shank towards the knee; space axes 1' = walking
direction, 2' = left, 3' = up. The orientation ``R`` (``dcm``) maps body to space, so a device at rest
upright has ``R = I`` and reads ``(0, 0, +1) g`` (the project convention of :mod:`gaitlog.firmware_sim.world.base`).

Motion (periodic, one gait cycle of ``cycle_s`` starting in foot-flat):

- orientation ``R = Ry(θ) Rx(φ) Rz(ψ)`` (intrinsic y - x' - z''): sagittal angle θ (positive = knee ahead of
  the ankle), coronal angle φ and axial angle ψ, each a short Fourier series, so angular velocity and
  acceleration are analytic (:func:`rotation_chain`);
- the ankle pivot rests during stance and moves forward one stride (and lifts) during swing with a C²
  profile; the platform origin sits ``origin_height_m`` up the shank axis from the pivot, so during
  foot-flat the shank rotates about a fixed point (Morris eq 11).

Platform: a triad of single-axis accelerometers at the origin plus two (``n_accelerometers=5``, Morris'
platform: no transverse rotation sensed) or three (``6``) accelerometers offset by ``arm_m``:

======  ====================  =========================
index   sensitive axis        position (body, m)
======  ====================  =========================
0-2     e1, e2, e3            origin
3       e1                    arm · e3  (senses ω̇2)
4       e2                    arm · e3  (senses ω̇1)
5       e2                    arm · e1  (senses ω̇3)
======  ====================  =========================

``render(sampling_rate_hz)`` returns the :class:`Motion` of the origin triad (the logger's single triaxial point);
``render_platform(sampling_rate_hz)`` the readings of every platform accelerometer with the same truth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gaitlog.firmware_sim.world.base import Motion
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["PlatformRecording", "RigidBodyShank", "elementary_rotations", "fourier_series", "rotation_chain"]

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def elementary_rotations(axis: str, angle_rad: np.ndarray) -> np.ndarray:
    """Rotation matrices about a coordinate axis (``"x"``, ``"y"`` or ``"z"``), shape ``angle.shape + (3, 3)``."""
    a = np.asarray(angle_rad, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    i = _AXIS_INDEX[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    out = np.zeros(a.shape + (3, 3))
    out[..., i, i] = 1.0
    out[..., j, j] = c
    out[..., k, k] = c
    out[..., j, k] = -s
    out[..., k, j] = s
    return out


def rotation_chain(
    axes: str, angles_rad: np.ndarray, rates_rad_s: np.ndarray, accels_rad_s2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orientation, body angular velocity and body angular acceleration of a chain of axis rotations.

    ``R = R_{a1}(q1) R_{a2}(q2) … R_{ak}(qk)`` (intrinsic sequence, equal to scipy's upper-case
    ``Rotation.from_euler``). With ``C_i = R_{a_{i+1}} … R_{ak}`` and ``u_i = C_iᵀ e_{a_i}``:

    .. math:: ω = Σ_i \\dot q_i u_i,\\qquad \\dot ω = Σ_i \\ddot q_i u_i + Σ_i \\dot q_i\\, u_i × Σ_{j>i} \\dot q_j u_j

    Parameters
    ----------
    axes
        Rotation axes, e.g. ``"yxz"``.
    angles_rad, rates_rad_s, accels_rad_s2
        ``(n, k)`` angles, their first and second time derivatives.

    Returns
    -------
    dcm, omega_rad_s, alpha_rad_s2
        ``(n, 3, 3)`` body-to-space matrices, ``(n, 3)`` body rates, ``(n, 3)`` body angular accelerations.
    """
    q = np.atleast_2d(np.asarray(angles_rad, dtype=np.float64))
    qd = np.atleast_2d(np.asarray(rates_rad_s, dtype=np.float64))
    qdd = np.atleast_2d(np.asarray(accels_rad_s2, dtype=np.float64))
    n, k = q.shape
    if len(axes) != k:
        raise ValueError(f"{len(axes)} axes for {k} angle columns")
    rots = [elementary_rotations(ax, q[:, i]) for i, ax in enumerate(axes)]
    u = np.empty((k, n, 3))
    tail = np.broadcast_to(np.eye(3), (n, 3, 3))
    for i in range(k - 1, -1, -1):
        u[i] = np.swapaxes(tail, 1, 2)[:, :, _AXIS_INDEX[axes[i]]]  # C_iᵀ e_ai
        tail = rots[i] @ tail
    dcm = tail
    omega = np.einsum("kn,knj->nj", qd.T, u)
    alpha = np.einsum("kn,knj->nj", qdd.T, u)
    outer = np.zeros((n, 3))
    for i in range(k - 1, -1, -1):  # outer = Σ_{j>i} q̇_j u_j
        alpha += qd[:, i : i + 1] * np.cross(u[i], outer)
        outer = outer + qd[:, i : i + 1] * u[i]
    return dcm, omega, alpha


def fourier_series(
    t_s: np.ndarray, period_s: float, terms: tuple[tuple[int, float, float], ...], offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q = offset + Σ a_k cos(kΩt) + b_k sin(kΩt)`` and its first two derivatives, ``Ω = 2π/period``.

    ``terms`` holds ``(k, a_k, b_k)`` triples (same unit as ``offset``).
    """
    t = np.asarray(t_s, dtype=np.float64)
    w0 = 2 * np.pi / period_s
    q = np.full_like(t, offset)
    qd = np.zeros_like(t)
    qdd = np.zeros_like(t)
    for k, a, b in terms:
        w = k * w0
        c, s = np.cos(w * t), np.sin(w * t)
        q += a * c + b * s
        qd += w * (-a * s + b * c)
        qdd += -w * w * (a * c + b * s)
    return q, qd, qdd


@dataclass(frozen=True, eq=False)
class PlatformRecording:
    """Readings of every platform accelerometer plus the platform geometry.

    Attributes
    ----------
    readings_g
        ``(n, m)`` specific force along each accelerometer's sensitive axis, g.
    positions_m
        ``(m, 3)`` accelerometer positions in body axes relative to the platform origin, m.
    axes
        ``(m, 3)`` unit sensitive axes in body axes.
    motion
        The :class:`Motion` of the origin triad, carrying the truth.
    """

    readings_g: np.ndarray
    positions_m: np.ndarray
    axes: np.ndarray
    motion: Motion = field(repr=False)


class RigidBodyShank:
    """Shank segment with the Morris accelerometer platform; a :class:`MotionSource`.

    Parameters
    ----------
    cycle_s
        Gait-cycle duration, s.
    n_cycles
        Number of cycles rendered (the first starts in foot-flat at t = 0).
    sagittal_deg, coronal_deg, axial_deg
        Fourier terms ``(k, a_k, b_k)`` of θ, φ, ψ in degrees (defaults: a walking-like sagittal swing of
        about ±30°, a few degrees of coronal and axial rotation). Pass ``()`` for zero.
    stride_m
        Forward pivot displacement per cycle, m.
    lift_m
        Peak pivot lift during swing, m.
    swing
        Fractions of the cycle ``(start, end)`` during which the pivot moves (stance otherwise).
    origin_height_m
        Distance of the platform origin from the ankle pivot along body axis 3, m.
    n_accelerometers
        5 (Morris' platform) or 6.
    arm_m
        Offset of the non-origin accelerometers, m.
    """

    def __init__(
        self,
        *,
        cycle_s: float = 1.1,
        n_cycles: int = 2,
        sagittal_deg: tuple[tuple[int, float, float], ...] = ((1, 0.0, 28.0), (2, -6.0, 8.0), (3, 2.0, 0.0)),
        coronal_deg: tuple[tuple[int, float, float], ...] = ((1, 1.0, 3.0), (2, 0.0, 1.0)),
        axial_deg: tuple[tuple[int, float, float], ...] = ((1, 0.0, 4.0),),
        stride_m: float = 1.4,
        lift_m: float = 0.12,
        swing: tuple[float, float] = (0.35, 0.95),
        origin_height_m: float = 0.2,
        n_accelerometers: int = 6,
        arm_m: float = 0.05,
    ) -> None:
        self.cycle_s = cycle_s
        self.n_cycles = n_cycles
        self.sagittal_deg = sagittal_deg
        self.coronal_deg = coronal_deg
        self.axial_deg = axial_deg
        self.stride_m = stride_m
        self.lift_m = lift_m
        self.swing = swing
        self.origin_height_m = origin_height_m
        self.n_accelerometers = n_accelerometers
        self.arm_m = arm_m

    # ------------------------------------------------------------------ geometry
    def platform_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """``(positions_m, axes)`` of the platform accelerometers, each ``(m, 3)`` in body axes."""
        if self.n_accelerometers not in (5, 6):
            raise ValueError(f"n_accelerometers must be 5 or 6, got {self.n_accelerometers}")
        d = self.arm_m
        pos = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, d], [0, 0, d], [d, 0, 0]], dtype=float)
        axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 1, 0]], dtype=float)
        m = self.n_accelerometers
        return pos[:m], axes[:m]

    # ------------------------------------------------------------------ kinematics
    def _pivot(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ankle pivot position, velocity, acceleration in space (m, m/s, m/s²)."""
        s0, s1 = self.swing
        cycle = np.floor(t / self.cycle_s)
        phase = t / self.cycle_s - cycle
        tsw = (s1 - s0) * self.cycle_s
        tau = np.clip((phase - s0) / (s1 - s0), 0.0, 1.0)
        moving = (phase > s0) & (phase < s1)
        two_pi = 2 * np.pi
        fwd = self.stride_m * (tau - np.sin(two_pi * tau) / two_pi)
        fwd_d = np.where(moving, self.stride_m * (1 - np.cos(two_pi * tau)) / tsw, 0.0)
        fwd_dd = np.where(moving, self.stride_m * two_pi * np.sin(two_pi * tau) / tsw**2, 0.0)
        u = (1 - np.cos(two_pi * tau)) / 2
        ud = np.pi * np.sin(two_pi * tau)
        udd = 2 * np.pi**2 * np.cos(two_pi * tau)
        up = self.lift_m * u * u
        up_d = np.where(moving, 2 * self.lift_m * u * ud / tsw, 0.0)
        up_dd = np.where(moving, 2 * self.lift_m * (ud * ud + u * udd) / tsw**2, 0.0)
        pos = np.stack([cycle * self.stride_m + fwd, np.zeros_like(t), up], axis=-1)
        vel = np.stack([fwd_d, np.zeros_like(t), up_d], axis=-1)
        acc = np.stack([fwd_dd, np.zeros_like(t), up_dd], axis=-1)
        return pos, vel, acc

    def kinematics(self, t_s: np.ndarray) -> dict[str, np.ndarray]:
        """Exact truth at times ``t_s``: dcm, omega_rad_s, alpha_rad_s2 (body), pivot/origin position,
        velocity and acceleration (space, m, m/s, m/s²)."""
        t = np.asarray(t_s, dtype=np.float64)
        cols = [fourier_series(t, self.cycle_s, terms) for terms in (self.sagittal_deg, self.coronal_deg, self.axial_deg)]
        q = np.radians(np.stack([c[0] for c in cols], axis=1))
        qd = np.radians(np.stack([c[1] for c in cols], axis=1))
        qdd = np.radians(np.stack([c[2] for c in cols], axis=1))
        dcm, omega, alpha = rotation_chain("yxz", q, qd, qdd)
        piv, piv_v, piv_a = self._pivot(t)
        r_o = np.array([0.0, 0.0, self.origin_height_m])
        w_r = np.cross(omega, r_o)
        origin = piv + dcm @ r_o
        origin_v = piv_v + np.einsum("nij,nj->ni", dcm, w_r)
        origin_a = piv_a + np.einsum("nij,nj->ni", dcm, np.cross(alpha, r_o) + np.cross(omega, w_r))
        return {
            "t_s": t,
            "dcm": dcm,
            "omega_rad_s": omega,
            "alpha_rad_s2": alpha,
            "angles_rad": q,
            "pivot_m": piv,
            "pivot_velocity_m_s": piv_v,
            "position_m": origin,
            "velocity_m_s": origin_v,
            "acceleration_m_s2": origin_a,
        }

    def _truth(self, kin: dict[str, np.ndarray]) -> dict[str, Any]:
        s0, s1 = self.swing
        starts = np.arange(self.n_cycles) * self.cycle_s
        truth: dict[str, Any] = dict(kin)
        truth.update(
            cycle_s=self.cycle_s,
            cycle_start_times_s=starts,
            stance_intervals_s=np.stack([starts + s1 * self.cycle_s - self.cycle_s, starts + s0 * self.cycle_s], axis=1).clip(0),
            origin_offset_m=np.array([0.0, 0.0, self.origin_height_m]),
            stride_m=self.stride_m,
        )
        return truth

    def _specific_force_g(self, kin: dict[str, np.ndarray], points_m: np.ndarray) -> np.ndarray:
        """``(n, p, 3)`` specific force in body axes (g) at body points ``points_m`` (p, 3) rel. to origin."""
        om, al = kin["omega_rad_s"][:, None, :], kin["alpha_rad_s2"][:, None, :]
        rel = np.cross(al, points_m) + np.cross(om, np.cross(om, points_m))  # body
        a0_body = np.einsum("nji,nj->ni", kin["dcm"], kin["acceleration_m_s2"])  # Rᵀ a_origin
        up_body = kin["dcm"][:, 2, :]  # Rᵀ e3
        return (a0_body[:, None, :] + rel) / STANDARD_GRAVITY_M_S2 + up_body[:, None, :]

    def render(self, sampling_rate_hz: float) -> Motion:
        """The origin triad's specific force (g, body axes) with the full truth."""
        n = int(round(self.n_cycles * self.cycle_s * sampling_rate_hz)) + 1
        t = np.arange(n) / sampling_rate_hz
        kin = self.kinematics(t)
        acc = self._specific_force_g(kin, np.zeros((1, 3)))[:, 0, :]
        return Motion(acc_g=acc, sampling_rate_hz=sampling_rate_hz, truth=self._truth(kin))

    def render_platform(self, sampling_rate_hz: float) -> PlatformRecording:
        """Readings (g) of every platform accelerometer, plus geometry and the origin :class:`Motion`."""
        pos, axes = self.platform_geometry()
        motion = self.render(sampling_rate_hz)
        kin = {k: motion.truth[k] for k in ("dcm", "omega_rad_s", "alpha_rad_s2", "acceleration_m_s2")}
        f = self._specific_force_g(kin, pos)
        readings = np.einsum("npj,pj->np", f, axes)
        truth = dict(motion.truth)
        truth.update(platform_positions_m=pos, platform_axes=axes)
        motion = Motion(acc_g=motion.acc_g, sampling_rate_hz=sampling_rate_hz, truth=truth)
        return PlatformRecording(readings_g=readings, positions_m=pos, axes=axes, motion=motion)
