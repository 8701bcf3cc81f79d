"""Two links joined by a 3-DOF joint, each carrying a triaxial angular-rate sensor (Hall et al. 1997).

Link orientations follow Hall's convention: ``TA`` maps reference coordinates to link-A coordinates, so the
project's body-to-space matrix is ``λA = TAᵀ``. Link A (e.g. the leg) moves as ``λA = Ry(α1) Rx(α2)``;
the joint rotates link B relative to A by ``y − x′ − z″`` angles ``(φ, θ, ψ)`` (flexion, version, axial
rotation), ``λB = λA Ry(φ) Rx(θ) Rz(ψ)``, hence ``T = TB·TAᵀ`` is Hall's eq (3) of those angles.

Every angle follows the same smooth profile: rest for ``pretest_s`` (the pre-test window), then a
minimum-jerk move ``10τ³ − 15τ⁴ + 6τ⁵`` to its final value over ``move_s``, optionally with a superposed
oscillation, so rates and truth are analytic. Each sensor reads the link's body rate in sensor axes,
``ω_sensor = Sᵀ ω_link`` for ``{î_link} = S {î_sensor}`` (Hall eqs 5-6, sign-corrected, see
:data:`HALL_SENSOR_TO_LINK`), plus a constant offset and white
noise (seeded).

``render_rates(sampling_rate_hz)`` gives the sensor rates and truth; ``render(sampling_rate_hz)`` wraps them into a
:class:`Motion` whose ``acc_g`` is the specific force of a point of link A at the joint centre (pure rotation:
the up direction in link-A axes), with everything else in ``truth``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gaitlog.firmware_sim.world.base import Motion
from gaitlog.firmware_sim.world.rigid_body import rotation_chain

__all__ = ["HALL_SENSOR_TO_LINK", "TwoLinkJoint", "TwoLinkRates"]

#: Sensor-to-link mount after Hall eqs (5)-(6), ``{î_seg} = S {î_sen}``. The printed matrix
#: ``[[0, 1, 0], [0, 0, 1], [−1, 0, 0]]`` has determinant −1 (a reflection, impossible between two
#: right-handed frames), so the sign of the last row is flipped here: a cyclic permutation of the axes.
HALL_SENSOR_TO_LINK = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def _min_jerk(
    t: np.ndarray, start_s: float, duration_s: float, amp: float, osc_amp: float, osc_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest, then a minimum-jerk ramp to ``amp`` with an oscillation ``osc_amp·sin²``-windowed; q, q̇, q̈."""
    tau = np.clip((t - start_s) / duration_s, 0.0, 1.0)
    inside = (t > start_s) & (t < start_s + duration_s)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    sd = np.where(inside, 30 * tau**2 * (1 - tau) ** 2 / duration_s, 0.0)
    sdd = np.where(inside, 60 * tau * (1 - tau) * (1 - 2 * tau) / duration_s**2, 0.0)
    q, qd, qdd = amp * s, amp * sd, amp * sdd
    if osc_amp:
        # osc_amp · sin(πτ)² · sin(2π f (t − start)), zero with its derivative outside the move
        w = 2 * np.pi * osc_hz
        tt = np.clip(t - start_s, 0.0, duration_s)
        win = np.sin(np.pi * tau) ** 2
        wind = np.where(inside, np.pi * np.sin(2 * np.pi * tau) / duration_s, 0.0)
        windd = np.where(inside, 2 * np.pi**2 * np.cos(2 * np.pi * tau) / duration_s**2, 0.0)
        sn, cs = np.sin(w * tt), np.cos(w * tt)
        q = q + osc_amp * win * sn
        qd = qd + osc_amp * np.where(inside, wind * sn + win * w * cs, 0.0)
        qdd = qdd + osc_amp * np.where(inside, windd * sn + 2 * wind * w * cs - win * w * w * sn, 0.0)
    return q, qd, qdd


@dataclass(frozen=True, eq=False)
class TwoLinkRates:
    """Sensor rates of the two links with their ground truth.

    Attributes
    ----------
    rate_a_rad_s, rate_b_rad_s
        ``(n, 3)`` measured rates in sensor axes (offset and noise included), rad/s.
    sampling_rate_hz
        Sampling rate, Hz.
    pretest_samples
        Number of leading samples at rest.
    truth
        ``joint_angles_rad`` ``(n, 3)`` (φ, θ, ψ); ``ta``, ``tb``, ``joint_matrix`` ``(n, 3, 3)``;
        ``omega_a_link_rad_s``, ``omega_b_link_rad_s`` (true link rates); ``sensor_to_link_a/b``;
        ``offset_a_rad_s``, ``offset_b_rad_s``; ``t_s``.
    """

    rate_a_rad_s: np.ndarray
    rate_b_rad_s: np.ndarray
    sampling_rate_hz: float
    pretest_samples: int
    truth: dict[str, Any] = field(default_factory=dict)


class TwoLinkJoint:
    """Two links and a 3-DOF joint with triaxial angular-rate sensors; a :class:`MotionSource`.

    Parameters
    ----------
    joint_final_deg
        Final joint angles ``(φ, θ, ψ)`` (flexion about y, version about x′, axial about z″), degrees.
    joint_oscillation_deg, oscillation_hz
        Amplitudes (deg) of a windowed oscillation superposed on each joint angle, and its frequency.
    link_a_final_deg
        Final ``(α1 about y, α2 about x′)`` of link A relative to the reference, degrees.
    pretest_s, move_s, duration_s
        Rest before the move, the move's duration, the total duration (s). Hall: 200 ms at 10 kHz.
    sensor_to_link_a, sensor_to_link_b
        Mounting matrices ``S`` (default Hall's eqs 5-6).
    offset_a_rad_s, offset_b_rad_s
        Constant sensor offsets in sensor axes, rad/s.
    noise_rad_s
        White-noise standard deviation per channel, rad/s.
    seed
        Seed of the noise.
    """

    def __init__(
        self,
        *,
        joint_final_deg: tuple[float, float, float] = (40.0, -20.0, 15.0),
        joint_oscillation_deg: tuple[float, float, float] = (5.0, 3.0, 4.0),
        oscillation_hz: float = 15.0,
        link_a_final_deg: tuple[float, float] = (30.0, 5.0),
        pretest_s: float = 0.02,
        move_s: float = 0.15,
        duration_s: float = 0.22,
        sensor_to_link_a: np.ndarray = HALL_SENSOR_TO_LINK,
        sensor_to_link_b: np.ndarray = HALL_SENSOR_TO_LINK,
        offset_a_rad_s: tuple[float, float, float] = (0.02, -0.015, 0.01),
        offset_b_rad_s: tuple[float, float, float] = (-0.01, 0.025, 0.005),
        noise_rad_s: float = 0.0,
        seed: int = 0,
    ) -> None:
        self.joint_final_deg = joint_final_deg
        self.joint_oscillation_deg = joint_oscillation_deg
        self.oscillation_hz = oscillation_hz
        self.link_a_final_deg = link_a_final_deg
        self.pretest_s = pretest_s
        self.move_s = move_s
        self.duration_s = duration_s
        self.sensor_to_link_a = sensor_to_link_a
        self.sensor_to_link_b = sensor_to_link_b
        self.offset_a_rad_s = offset_a_rad_s
        self.offset_b_rad_s = offset_b_rad_s
        self.noise_rad_s = noise_rad_s
        self.seed = seed

    def render_rates(self, sampling_rate_hz: float) -> TwoLinkRates:
        """Sensor rates and truth sampled at ``sampling_rate_hz``."""
        n = int(round(self.duration_s * sampling_rate_hz)) + 1
        t = np.arange(n) / sampling_rate_hz
        amps = np.radians([*self.link_a_final_deg, *self.joint_final_deg])
        osc = np.radians([0.0, 0.0, *self.joint_oscillation_deg])
        cols = [_min_jerk(t, self.pretest_s, self.move_s, a, o, self.oscillation_hz) for a, o in zip(amps, osc)]
        q = np.stack([c[0] for c in cols], axis=1)
        qd = np.stack([c[1] for c in cols], axis=1)
        qdd = np.stack([c[2] for c in cols], axis=1)
        lam_a, w_a, _ = rotation_chain("yx", q[:, :2], qd[:, :2], qdd[:, :2])
        lam_b, w_b, _ = rotation_chain("yxyxz", q, qd, qdd)
        sa = np.asarray(self.sensor_to_link_a, dtype=np.float64)
        sb = np.asarray(self.sensor_to_link_b, dtype=np.float64)
        rng = np.random.default_rng(self.seed)
        meas_a = w_a @ sa + np.asarray(self.offset_a_rad_s) + rng.normal(0.0, self.noise_rad_s, (n, 3))
        meas_b = w_b @ sb + np.asarray(self.offset_b_rad_s) + rng.normal(0.0, self.noise_rad_s, (n, 3))
        ta, tb = np.swapaxes(lam_a, 1, 2), np.swapaxes(lam_b, 1, 2)
        truth = {
            "t_s": t,
            "joint_angles_rad": q[:, 2:],
            "link_a_angles_rad": q[:, :2],
            "ta": ta,
            "tb": tb,
            "joint_matrix": tb @ lam_a,
            "omega_a_link_rad_s": w_a,
            "omega_b_link_rad_s": w_b,
            "sensor_to_link_a": sa,
            "sensor_to_link_b": sb,
            "offset_a_rad_s": np.asarray(self.offset_a_rad_s, dtype=np.float64),
            "offset_b_rad_s": np.asarray(self.offset_b_rad_s, dtype=np.float64),
        }
        pretest = int(np.floor(self.pretest_s * sampling_rate_hz)) + 1 if self.pretest_s > 0 else 0
        return TwoLinkRates(meas_a, meas_b, float(sampling_rate_hz), min(pretest, n), truth)

    def render(self, sampling_rate_hz: float) -> Motion:
        """:class:`Motion` of a point of link A at the joint centre; sensor rates and truth in ``truth``."""
        rates = self.render_rates(sampling_rate_hz)
        truth = dict(rates.truth)
        truth.update(
            rate_a_rad_s=rates.rate_a_rad_s, rate_b_rad_s=rates.rate_b_rad_s, pretest_samples=rates.pretest_samples
        )
        up_in_a = rates.truth["ta"][:, :, 2]  # TA · e3: the up direction in link-A axes
        return Motion(acc_g=up_in_a, sampling_rate_hz=sampling_rate_hz, truth=truth)
