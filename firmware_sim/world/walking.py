"""Walking with ground truth: the corridor protocol of Alvarez et al. (2006) seen by a lower-back logger.

:class:`Walking` is a :class:`~gaitlog.firmware_sim.world.base.MotionSource`. A :class:`Subject` walks the
:class:`WalkPlan` (100 m out and back at preferred, fast, slow and medium speed, turns, rests,
lap marks); the logger, strapped over L3, reads the specific force of its own point of the trunk.

Device axes (nominal mounting; the project convention of :mod:`gaitlog.firmware_sim.world.base` applies)
--------------------------------------------------------------------------------------------------------
Like the Xsens MTw of the IPOL lower-back recordings: ``x`` **up** (vertical, reads +1 g standing),
``y`` **left** (medio-lateral), ``z`` **backward** (antero-posterior, pointing out of the back; forward
acceleration reads negative). The device is then rotated by the subject's ``mounting_rotation_deg``
(a few to 15 degrees, seeded), and the trunk leans and oscillates, so gravity leaks into every axis.

What is modelled (richer than any estimator's assumptions)
-----------------------------------------------------------
- centre-of-mass path with double support and single stance (:mod:`gaitlog.firmware_sim.world.gait_cycle`):
  one vertical oscillation per step whose depth is Alvarez's two pendulums (an arc flatter than the leg
  over single stance, a sag over double support), its low point early in double support and not at
  foot-flat, forward speed fluctuating within the step, speed-dependent step length and cadence (walk
  ratio), step-to-step variability and asymmetry, gait initiation, a slowed-down 180° turn on a smooth
  path, termination at the line;
- trunk/pelvis motion: forward lean, pitch oscillation at step frequency, obliquity (roll) and pelvic
  rotation (yaw) at stride frequency, medio-lateral sway at stride frequency (and, for subjects that have
  them, such as the ``"people"`` population, lateral stride harmonics 2-10 with a step-to-step gain and forward
  braking harmonics, :class:`~gaitlog.firmware_sim.world.subject.Subject`); the sensor's lever arm from
  the centre of mass adds tangential and centripetal accelerations, and its height differs from the
  centre of mass's;
- contact transients: shortly after heel strike an upward impact and braking peak, just before the
  trailing foot's toe-off a short drop of vertical and forward acceleration (end of push-off), just after
  it the leading leg's loading-response peak (timings from real lower-back recordings); each is the second
  derivative of a sub-millimetre Gaussian position bump, so it changes no velocity and no truth length;
- rests standing or sitting (sit-down and stand-up transitions) between excursions.

Every position channel is a C2 quintic spline and all accelerations are its exact derivatives, so the
rendered acceleration double-integrates to the truth positions.

Truth (``Motion.truth``)
------------------------
``steps``: dict of per-step arrays (a step runs from a heel strike to the next heel strike of the other
foot): ``excursion``, ``speed_label``, ``side`` (foot of the opening heel strike), ``phase``
(``initiation``/``steady``/``turn``/``termination``), ``heel_strike_s``, ``foot_flat_s``, ``toe_off_s``
(trailing foot), ``next_heel_strike_s``, ``next_foot_flat_s``, ``com_min_s``, ``length_m`` (centre-of-mass
travel along the path between the heel strikes), ``com_excursion_m`` / ``sensor_excursion_m`` (max - min
of the centre of mass's / sensor's height between foot-flat and the next foot-flat),
``com_excursion_single_stance_m`` / ``sensor_excursion_single_stance_m`` (toe-off to next heel strike),
``leg_arc_radius_m``, ``speed_m_s`` (length / duration), ``corridor_start_m`` (corridor distance at the
heel strike). ``laps``: ``excursion``, ``speed_label``, ``distance_m`` (corridor distance from the
excursion's start line), ``cumulative_distance_m``, ``time_s``, ``path_m``. ``excursions``: per excursion
``speed_label``, ``speed_m_s``, ``t_start_s``, ``t_stop_s``, ``corridor_distance_m``, ``path_length_m``,
``initiation_travel_m`` (set-off to first heel strike), ``termination_travel_m`` (last contact to stop),
``turn_start_s`` / ``turn_end_s`` (the centre of mass enters / leaves the curved part of the path).
``rests``: ``t_start_s``, ``t_stop_s``, ``posture``. ``subject`` (parameters), ``device_axes``,
``mounting_matrix`` (device-from-nominal), ``total_distance_m``, ``total_path_m``. With
``include_trajectory=True`` also ``trajectory``: ``t_s``, ``sensor_position_m``, ``sensor_velocity_m_s``,
``com_position_m`` (corridor frame of the current excursion, z up) and ``world_from_device``
(``(n, 3, 3)``: world vector = matrix @ device vector).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PPoly
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.base import Motion
from gaitlog.firmware_sim.world.corridor import CorridorPath
from gaitlog.firmware_sim.world.gait_cycle import ExcursionPlan, plan_excursion
from gaitlog.firmware_sim.world.hermite import constant_ppoly, evaluate, quintic_hermite
from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.units import STANDARD_GRAVITY_M_S2

#: Nominal device axes in trunk axes (rows: device x, y, z; columns: trunk forward, left, up).
DEVICE_FROM_TRUNK = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
DEVICE_AXES = {"x": "up (vertical)", "y": "left (medio-lateral)", "z": "backward (antero-posterior)"}

_CHUNK = 65536
_AXIS = {"x": 0, "y": 1, "z": 2}

@dataclass(frozen=True, eq=False)
class _Segment:
    """A stretch of the timeline with its channels (an excursion or a rest)."""

    kind: str
    t_a: float
    t_b: float
    path: CorridorPath
    s: PPoly
    z: PPoly
    phase: PPoly
    envelope: PPoly
    pitch_mean: PPoly
    amplitude_scale: float = 1.0
    transient_t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    transient_vertical_m_s2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    transient_ap_m_s2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    transient_sigma_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    plan: ExcursionPlan | None = None
    ml_gain: PPoly | None = None


class _Elementary:
    """An elementary rotation ``E = exp(a(t) [e]x)`` about a coordinate axis, applied to row vectors.

    ``E' v = a' e × (E v)`` and ``E'' v = a'' e × (E v) + a'² e × (e × (E v))``.
    """

    def __init__(self, axis: str, a: np.ndarray, ad: np.ndarray, add: np.ndarray) -> None:
        self.k = _AXIS[axis]
        self.i, self.j = (self.k + 1) % 3, (self.k + 2) % 3
        self.c, self.s = np.cos(a), np.sin(a)
        self.ad, self.add = ad[:, None], add[:, None]

    def _rot(self, v: np.ndarray, sign: float = 1.0) -> np.ndarray:
        i, j, k = self.i, self.j, self.k
        s = sign * self.s
        out = np.empty_like(v)
        out[:, k] = v[:, k]
        out[:, i] = self.c * v[:, i] - s * v[:, j]
        out[:, j] = s * v[:, i] + self.c * v[:, j]
        return out

    def _cross(self, w: np.ndarray) -> np.ndarray:
        out = np.zeros_like(w)
        out[:, self.i] = -w[:, self.j]
        out[:, self.j] = w[:, self.i]
        return out

    def d0(self, v: np.ndarray) -> np.ndarray:
        return self._rot(v)

    def d01(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ev = self._rot(v)
        return ev, self.ad * self._cross(ev)

    def d012(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ev = self._rot(v)
        kv = self._cross(ev)
        return ev, self.ad * kv, self.add * kv + self.ad**2 * self._cross(kv)

    def inverse(self, v: np.ndarray) -> np.ndarray:
        return self._rot(v, -1.0)


def _first_crossing(pp: PPoly, level: float) -> float:
    """First time a non-decreasing piecewise polynomial reaches ``level`` (root of one interval)."""
    values = pp(pp.x)
    i = int(np.clip(np.searchsorted(values, level, side="left") - 1, 0, pp.x.size - 2))
    coef = pp.c[:, i].copy()
    coef[-1] -= level
    h = pp.x[i + 1] - pp.x[i]
    roots = np.roots(coef)
    real = roots[np.abs(roots.imag) < 1e-9].real
    real = np.sort(real[(real >= -1e-9) & (real <= h + 1e-9)])
    if real.size == 0:  # pragma: no cover - guarded by the monotonic plan
        raise ValueError(f"level {level} not crossed in knot interval {i}")
    return float(pp.x[i] + real[0])


class Walking:
    """The walking protocol as a motion source for the logger emulator.

    Parameters
    ----------
    subject
        The walker (default: the population-mean :class:`Subject`).
    walk_plan
        The protocol (default: Alvarez's four excursions).
    seed
        Seed of the step-to-step variability (same seed, same walk).
    include_trajectory
        Also return the world-frame trajectory in ``truth["trajectory"]`` (memory: ~200 B per sample).

    Examples
    --------
    >>> w = Walking(walk_plan=WalkPlan(speeds=("preferred",), initial_stand_s=2, final_stand_s=1))
    >>> m = w.render(100.0)
    >>> float(m.truth["excursions"]["corridor_distance_m"][0])
    200.0
    >>> bool(abs(np.linalg.norm(m.acc_g[0]) - 1.0) < 1e-12)
    True
    """

    def __init__(self, *, subject: Subject | None = None, walk_plan: WalkPlan | None = None,
                 seed: int = 0, include_trajectory: bool = False) -> None:
        self.subject = subject if subject is not None else Subject()
        self.walk_plan = walk_plan if walk_plan is not None else WalkPlan()
        self.seed = seed
        self.include_trajectory = include_trajectory

    # ---- planning ---------------------------------------------------------------------------------
    def _segments(self) -> list[_Segment]:
        sub, walk_plan = self.subject, self.walk_plan
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 4]))
        z_stand = sub.com_height_m
        lean = np.deg2rad(sub.stand_lean_deg)
        segments: list[_Segment] = []
        t = 0.0
        side = "R"
        path = CorridorPath(corridor_length_m=walk_plan.corridor_length_m, turn_radius_m=walk_plan.turn_radius_m)
        segments.append(self._standing(t, t + walk_plan.initial_stand_s, path, 0.0, z_stand, lean, "stand"))
        t += walk_plan.initial_stand_s
        for k, label in enumerate(walk_plan.speeds):
            plan = plan_excursion(sub, walk_plan, label, t_start_s=t, rng=rng, first_side=side)
            segments.append(_Segment(
                kind=f"excursion:{label}", t_a=plan.t_start_s, t_b=plan.t_stop_s, path=plan.path, s=plan.s,
                z=plan.z, phase=plan.phase, envelope=plan.envelope, pitch_mean=plan.pitch_mean,
                amplitude_scale=plan.amplitude_scale, transient_t_s=plan.transient_t_s,
                transient_vertical_m_s2=plan.transient_vertical_m_s2, transient_ap_m_s2=plan.transient_ap_m_s2,
                transient_sigma_s=plan.transient_sigma_s,
                plan=plan, ml_gain=plan.ml_gain))
            t = plan.t_stop_s
            side = "L" if plan.side[-1] == "R" else "R"
            s_end = plan.path.length_m
            if k + 1 < len(walk_plan.speeds):
                posture = walk_plan.rest_posture(k)
                # logger STOPped during the rest: the walker is back on their feet at the start line, standing
                # still, when it is STARTed again (run_lead_s before the set-off)
                ready_s = walk_plan.run_lead_s if walk_plan.logger_runs == "per-excursion" else 0.0
                t_ready = t + walk_plan.rest_s - ready_s
                if posture == "standing":
                    segments.append(self._standing(t, t_ready, plan.path, s_end, z_stand, lean, "rest:standing"))
                else:
                    segments.append(self._sitting(t, t_ready, plan.path, s_end, z_stand, lean))
                if ready_s > 0:
                    segments.append(self._standing(t_ready, t + walk_plan.rest_s, plan.path, s_end, z_stand, lean,
                                                   "stand"))
                t += walk_plan.rest_s
            else:
                segments.append(self._standing(t, t + walk_plan.final_stand_s, plan.path, s_end, z_stand, lean,
                                               "stand"))
                t += walk_plan.final_stand_s
        return segments

    @staticmethod
    def _standing(t_a: float, t_b: float, path: CorridorPath, s: float, z: float, lean: float,
                  kind: str) -> _Segment:
        return _Segment(kind=kind, t_a=t_a, t_b=t_b, path=path, s=constant_ppoly(t_a, t_b, s),
                        z=constant_ppoly(t_a, t_b, z), phase=constant_ppoly(t_a, t_b, 0.0),
                        envelope=constant_ppoly(t_a, t_b, 0.0), pitch_mean=constant_ppoly(t_a, t_b, lean))

    def _sitting(self, t_a: float, t_b: float, path: CorridorPath, s: float, z: float,
                 lean: float) -> _Segment:
        tr = self.walk_plan.sit_transition_s
        knots = np.array([t_a, t_a + tr, t_b - tr, t_b])
        zero = np.zeros(4)

        def chan(stand: float, sit: float) -> PPoly:
            return quintic_hermite(knots, np.array([stand, sit, sit, stand]), zero, zero)

        # Sitting: centre of mass down and back (backward = decreasing s on the way back), trunk reclined.
        return _Segment(kind="rest:sitting", t_a=t_a, t_b=t_b, path=path, s=chan(s, s - 0.15),
                        z=chan(z, z - self.subject.sit_drop_m), phase=constant_ppoly(t_a, t_b, 0.0),
                        envelope=constant_ppoly(t_a, t_b, 0.0), pitch_mean=chan(lean, lean - np.deg2rad(12.0)))

    # ---- kinematics ---------------------------------------------------------------------------------
    def _kinematics(self, seg: _Segment, t: np.ndarray, want_rotation: bool = False) -> dict[str, np.ndarray]:
        """World-frame kinematics of the sensor on ``seg`` at times ``t`` (corridor frame, z up)."""
        sub = self.subject
        s, sd, sdd = evaluate(seg.s, t)
        z, zd, zdd = evaluate(seg.z, t)
        # Contact transients: position bumps -P·σ²·exp(-u²/2), whose second derivative peaks at +P (zero net
        # velocity change: the transient moves the body by a fraction of a millimetre and back).
        if seg.transient_t_s.size:
            lo = np.searchsorted(t, seg.transient_t_s - 6 * seg.transient_sigma_s)
            hi = np.searchsorted(t, seg.transient_t_s + 6 * seg.transient_sigma_s)
            for tc, pv, pa, sigma, i0, i1 in zip(seg.transient_t_s, seg.transient_vertical_m_s2,
                                                 seg.transient_ap_m_s2, seg.transient_sigma_s, lo, hi):
                if i1 <= i0:
                    continue
                u = (t[i0:i1] - tc) / sigma
                b = np.exp(-0.5 * u**2)
                for amp, (p, pd, pdd) in ((pv, (z, zd, zdd)), (pa, (s, sd, sdd))):
                    p[i0:i1] += -amp * sigma**2 * b
                    pd[i0:i1] += amp * sigma * u * b
                    pdd[i0:i1] += -amp * (u**2 - 1.0) * b
        ph, phd, phdd = evaluate(seg.phase, t)
        env0, envd0, envdd0 = evaluate(seg.envelope, t)

        def osc(amp: float, k: float, c: float, envelope: tuple | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            env, envd, envdd = envelope if envelope is not None else (env0, envd0, envdd0)
            arg = k * ph + c
            sn, cs = np.sin(arg), np.cos(arg)
            f = env * amp * sn
            fd = envd * amp * sn + env * amp * k * phd * cs
            fdd = (envdd * amp * sn + 2 * envd * amp * k * phd * cs + env * amp * k * phdd * cs
                   - env * amp * k**2 * phd**2 * sn)
            return f, fd, fdd

        y, yd, ydd = osc(sub.ml_sway_m / seg.amplitude_scale, 1.0, sub.sway_phase_rad)
        if sub.ml_harmonics_m_s2 or sub.ap_harmonics_m_s2:
            # Stride harmonics given as accelerations at the preferred stride rate w. The odd lateral ones peak
            # toward the new stance foot harmonic_lag_s after each heel strike (gait phase 0 = left), the
            # forward ones brake then; y'' = A cos(k (phase - lag)) <=> y = A/(k w)^2 sin(k phase - k lag - pi/2).
            w = sub.preferred_stride_rate_rad_s
            lag = w * sub.harmonic_lag_s
            ml_env = None
            if seg.ml_gain is not None:
                g, gd, gdd = evaluate(seg.ml_gain, t)
                ml_env = (env0 * g, envd0 * g + env0 * gd, envdd0 * g + 2.0 * envd0 * gd + env0 * gdd)
            for i, acc in enumerate(sub.ml_harmonics_m_s2):
                k = i + 2
                if k % 2:
                    c = -k * lag - 0.5 * np.pi
                else:   # even: relative to quadrature with the forward braking (uncorrelated with AP at offset 0)
                    c = (-k * lag + (0.5 * np.pi if k == 2 else 0.0)
                         + sub.ml_even_phases_rad[(k // 2 - 1) % len(sub.ml_even_phases_rad)])
                yk, ykd, ykdd = osc(acc * seg.amplitude_scale / (k * w) ** 2, float(k), c, ml_env)
                y, yd, ydd = y + yk, yd + ykd, ydd + ykdd
            for i, acc in enumerate(sub.ap_harmonics_m_s2):
                k = 2 * i + 4
                sk, skd, skdd = osc(acc * seg.amplitude_scale / (k * w) ** 2, float(k), -k * lag + 0.5 * np.pi)
                s, sd, sdd = s + sk, sd + skd, sdd + skdd
        psi = seg.path.heading_rad(s)
        kap = seg.path.curvature_per_m(s)
        kap_s = seg.path.curvature_slope_per_m2(s)
        tan = np.stack([np.cos(psi), np.sin(psi)], axis=-1)
        nor = np.stack([-np.sin(psi), np.cos(psi)], axis=-1)
        u = (1.0 - kap * y) * sd
        ud = (-kap_s * sd * y - kap * yd) * sd + (1.0 - kap * y) * sdd
        pos_h = seg.path.position_m(s) + y[:, None] * nor
        vel_h = u[:, None] * tan + yd[:, None] * nor
        acc_h = (ud - yd * kap * sd)[:, None] * tan + (u * kap * sd + ydd)[:, None] * nor
        com_p = np.column_stack([pos_h, z])
        com_v = np.column_stack([vel_h, zd])
        com_a = np.column_stack([acc_h, zdd])
        # Trunk orientation, body -> world: R = Rz(yaw) Ry(pitch) Rx(roll).
        yw, ywd, ywdd = osc(np.deg2rad(sub.yaw_amp_deg) * seg.amplitude_scale, 1.0, sub.yaw_phase_rad)
        yw, ywd, ywdd = yw + psi, ywd + kap * sd, ywdd + kap_s * sd**2 + kap * sdd
        pt, ptd, ptdd = osc(np.deg2rad(sub.pitch_amp_deg) * seg.amplitude_scale, 2.0, sub.pitch_phase_rad)
        pm, pmd, pmdd = evaluate(seg.pitch_mean, t)
        pt, ptd, ptdd = pt + pm, ptd + pmd, ptdd + pmdd
        rl, rld, rldd = osc(np.deg2rad(sub.roll_amp_deg) * seg.amplitude_scale, 1.0, sub.roll_phase_rad)
        ez, ey, ex = (_Elementary("z", yw, ywd, ywdd), _Elementary("y", pt, ptd, ptdd),
                      _Elementary("x", rl, rld, rldd))
        r = np.broadcast_to(np.asarray(sub.sensor_offset_m, dtype=np.float64), (t.size, 3))
        # R = Rz Ry Rx; product rule for R r, R' r, R'' r applied factor by factor to the vector.
        # (ABC)'' r = A''X0 + 2A'X1 + AX2 with X0 = BCr, X1 = (BC)'r, X2 = (BC)''r.
        c0, c1, c2 = ex.d012(r)
        b0c0, b1c0, b2c0 = ey.d012(c0)
        b0c1, b1c1 = ey.d01(c1)
        x1 = b1c0 + b0c1
        x2 = b2c0 + 2.0 * b1c1 + ey.d0(c2)
        a0x0, a1x0, a2x0 = ez.d012(b0c0)
        a0x1, a1x1 = ez.d01(x1)
        rot_r = a0x0
        rot1_r = a1x0 + a0x1
        rot2_r = a2x0 + 2.0 * a1x1 + ez.d0(x2)
        sen_p = com_p + rot_r
        sen_v = com_v + rot1_r
        sen_a = com_a + rot2_r
        f_world = sen_a + np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2])
        f_body = ex.inverse(ey.inverse(ez.inverse(f_world)))
        dev_from_body = self.mounting_matrix.T @ DEVICE_FROM_TRUNK
        f_dev = f_body @ dev_from_body.T / STANDARD_GRAVITY_M_S2
        out = {"acc_g": f_dev, "sensor_position_m": sen_p, "sensor_velocity_m_s": sen_v,
               "com_position_m": com_p, "s_m": s}
        if want_rotation:
            cols = [ez.d0(ey.d0(ex.d0(np.broadcast_to(e, (t.size, 3))))) for e in np.eye(3)]
            world_from_body = np.stack(cols, axis=-1)
            out["world_from_device"] = world_from_body @ dev_from_body.T
        return out
    @property
    def mounting_matrix(self) -> np.ndarray:
        """Actual device axes in nominal device coordinates (columns), from ``mounting_rotation_deg``."""
        return Rotation.from_rotvec(np.deg2rad(self.subject.mounting_rotation_deg)).as_matrix()

    def _evaluate(self, segments: list[_Segment], t: np.ndarray, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
        bounds = np.array([seg.t_a for seg in segments[1:]])
        which = np.searchsorted(bounds, t, side="right")
        out: dict[str, np.ndarray] = {}
        for i, seg in enumerate(segments):
            idx = np.flatnonzero(which == i)
            for j0 in range(0, idx.size, _CHUNK):
                sel = idx[j0:j0 + _CHUNK]
                kin = self._kinematics(seg, t[sel], want_rotation="world_from_device" in keys)
                for key in keys:
                    if key not in out:
                        out[key] = np.empty((t.size,) + kin[key].shape[1:])
                    out[key][sel] = kin[key]
        return out

    # ---- rendering and truth ------------------------------------------------------------------------
    def render(self, sampling_rate_hz: float) -> Motion:
        """Render the whole protocol at ``sampling_rate_hz`` (e.g. the sensor model's internal 500–1000 Hz)."""
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise ValueError(f"sampling_rate_hz must be a positive number, got {sampling_rate_hz!r}")
        segments = self._segments()
        duration = segments[-1].t_b
        n = int(np.floor(duration * sampling_rate_hz)) + 1
        t = np.arange(n) / sampling_rate_hz
        keys = ("acc_g",)
        if self.include_trajectory:
            keys = ("acc_g", "sensor_position_m", "sensor_velocity_m_s", "com_position_m", "world_from_device")
        kin = self._evaluate(segments, t, keys)
        truth = self._truth(segments)
        if self.include_trajectory:
            truth["trajectory"] = {"t_s": t, **{k: kin[k] for k in keys if k != "acc_g"}}
        return Motion(acc_g=kin["acc_g"], sampling_rate_hz=float(sampling_rate_hz), t0_s=0.0, truth=truth,
                      marker_times_s=truth["laps"]["time_s"].copy())

    def logger_spans(self, segments: list[_Segment] | None = None) -> list[tuple[float, float]]:
        """``(t_start_s, t_stop_s)`` of each logging run of the plan (:attr:`WalkPlan.logger_runs`): the whole
        protocol, or each excursion with ``run_lead_s`` of standing before and ``run_tail_s`` after it."""
        segs = self._segments() if segments is None else segments
        if self.walk_plan.logger_runs == "continuous":
            return [(segs[0].t_a, segs[-1].t_b)]
        out = []
        for i, seg in enumerate(segs):
            if seg.plan is not None:
                out.append((max(seg.t_a - self.walk_plan.run_lead_s, segs[i - 1].t_a if i else seg.t_a),
                            min(seg.t_b + self.walk_plan.run_tail_s, segs[i + 1].t_b if i + 1 < len(segs) else seg.t_b)))
        return out

    def render_runs(self, sampling_rate_hz: float) -> list[Motion]:
        """One :class:`Motion` per logging run (:meth:`logger_spans`), each on the walk's clock (``t0_s`` = the
        run's START), with the lap marks inside it as marker times; the truth (whole protocol) is shared."""
        if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise ValueError(f"sampling_rate_hz must be a positive number, got {sampling_rate_hz!r}")
        segments = self._segments()
        truth = self._truth(segments)
        laps = truth["laps"]["time_s"]
        out = []
        for t_a, t_b in self.logger_spans(segments):
            t = t_a + np.arange(int(np.floor((t_b - t_a) * sampling_rate_hz)) + 1) / sampling_rate_hz
            acc = self._evaluate(segments, t, ("acc_g",))["acc_g"]
            out.append(Motion(acc_g=acc, sampling_rate_hz=float(sampling_rate_hz), t0_s=float(t_a), truth=truth,
                              marker_times_s=laps[(laps >= t_a) & (laps <= t[-1])].copy()))
        return out

    def _truth(self, segments: list[_Segment]) -> dict:
        walk_plan = self.walk_plan
        steps: dict[str, list] = {}
        laps: dict[str, list] = {k: [] for k in ("excursion", "speed_label", "distance_m", "cumulative_distance_m",
                                                 "time_s", "path_m")}
        excs: dict[str, list] = {k: [] for k in ("speed_label", "speed_m_s", "t_start_s", "t_stop_s",
                                                 "corridor_distance_m", "path_length_m", "n_steps",
                                                 "initiation_travel_m", "termination_travel_m",
                                                 "turn_start_s", "turn_end_s")}
        rests: dict[str, list] = {"t_start_s": [], "t_stop_s": [], "posture": []}
        n_grid = 128
        k_exc = 0
        for seg in segments:
            if seg.kind.startswith("rest:"):
                rests["t_start_s"].append(seg.t_a)
                rests["t_stop_s"].append(seg.t_b)
                rests["posture"].append(seg.kind.split(":")[1])
            plan = seg.plan
            if plan is None:
                continue
            hs, ff, to = plan.heel_strike_s, plan.foot_flat_s, plan.toe_off_s
            n = plan.n_steps
            s_hs = plan.s(hs)
            # Excursions of height: dense grids over each step window, through the full kinematics.
            frac = np.linspace(0.0, 1.0, n_grid)
            win_ff = ff[:-1, None] + (ff[1:] - ff[:-1])[:, None] * frac
            win_ss = to[:, None] + (hs[1:] - to)[:, None] * frac
            win_ds = hs[:-1, None] + (0.5 * (to + hs[1:]) - hs[:-1])[:, None] * frac  # HS to mid single stance
            grid = np.concatenate([win_ff.ravel(), win_ss.ravel(), win_ds.ravel()])
            order = np.argsort(grid, kind="stable")
            kin_sorted = self._evaluate([seg], grid[order], ("sensor_position_m", "com_position_m"))
            zs = np.empty(grid.size)
            zc = np.empty(grid.size)
            zs[order] = kin_sorted["sensor_position_m"][:, 2]
            zc[order] = kin_sorted["com_position_m"][:, 2]
            zs_ff, zs_ss = zs[: n * n_grid].reshape(n, n_grid), zs[n * n_grid: 2 * n * n_grid].reshape(n, n_grid)
            zc_ff, zc_ss, zc_ds = (zc[k * n * n_grid: (k + 1) * n * n_grid].reshape(n, n_grid) for k in range(3))
            com_min_s = win_ds[np.arange(n), np.argmin(zc_ds, axis=1)]
            cols = {
                "excursion": np.full(n, k_exc),
                "speed_label": np.full(n, plan.label, dtype=object),
                "side": plan.side[:-1],
                "phase": plan.step_phase,
                "heel_strike_s": hs[:-1],
                "foot_flat_s": ff[:-1],
                "toe_off_s": to,
                "next_heel_strike_s": hs[1:],
                "next_foot_flat_s": ff[1:],
                "com_min_s": com_min_s,
                "length_m": np.diff(s_hs),
                "com_excursion_m": np.ptp(zc_ff, axis=1),
                "sensor_excursion_m": np.ptp(zs_ff, axis=1),
                "com_excursion_single_stance_m": np.ptp(zc_ss, axis=1),
                "sensor_excursion_single_stance_m": np.ptp(zs_ss, axis=1),
                "leg_arc_radius_m": plan.leg_arc_radius_m,
                "speed_m_s": np.diff(s_hs) / np.diff(hs),
                "corridor_start_m": plan.path.corridor_distance_m(s_hs[:-1]),
            }
            for key, val in cols.items():
                steps.setdefault(key, []).append(np.asarray(val))
            # Lap marks: when the centre of mass crosses each corridor distance.
            for d in walk_plan.lap_marks_m:
                s_mark = float(plan.path.s_at_corridor_distance(d))
                if s_mark <= 0.0:
                    t_mark = plan.t_start_s
                elif s_mark >= plan.path.length_m - 1e-9:
                    t_mark = plan.t_stop_s
                else:
                    t_mark = _first_crossing(plan.s, s_mark)
                laps["excursion"].append(k_exc)
                laps["speed_label"].append(plan.label)
                laps["distance_m"].append(float(d))
                laps["cumulative_distance_m"].append(k_exc * walk_plan.excursion_distance_m + float(d))
                laps["time_s"].append(t_mark)
                laps["path_m"].append(s_mark)
            excs["speed_label"].append(plan.label)
            excs["speed_m_s"].append(plan.speed_m_s)
            excs["t_start_s"].append(plan.t_start_s)
            excs["t_stop_s"].append(plan.t_stop_s)
            excs["corridor_distance_m"].append(walk_plan.excursion_distance_m)
            excs["path_length_m"].append(plan.path.length_m)
            excs["n_steps"].append(n)
            excs["initiation_travel_m"].append(float(s_hs[0]))
            excs["termination_travel_m"].append(float(plan.path.length_m - s_hs[-1]))
            excs["turn_start_s"].append(_first_crossing(plan.s, plan.path.turn_start_m))
            excs["turn_end_s"].append(_first_crossing(plan.s, plan.path.turn_end_m))
            k_exc += 1
        steps_out = {k: np.concatenate(v) for k, v in steps.items()}
        for key in ("speed_label", "side", "phase"):
            steps_out[key] = steps_out[key].astype(str)
        return {
            "steps": steps_out,
            "laps": {k: np.asarray(v) for k, v in laps.items()},
            "excursions": {k: np.asarray(v) for k, v in excs.items()},
            "rests": {k: np.asarray(v) for k, v in rests.items()},
            "subject": self.subject.as_dict(),
            "device_axes": dict(DEVICE_AXES),
            "mounting_matrix": self.mounting_matrix,
            "total_distance_m": walk_plan.excursion_distance_m * len(walk_plan.speeds),
            "total_path_m": float(np.sum(excs["path_length_m"])),
            "seed": self.seed,
        }
