"""Step-by-step plan of one walking excursion: gait events and the knots of the body's trajectory.

Every step ``i`` runs from the heel strike ``HS_i`` of one foot to the heel strike ``HS_{i+1}`` of the
other and contains, in order::

    HS_i ─ FF_i (foot-flat of the leading foot) ─ TO_i (toe-off of the trailing foot: end of double
    support) ─ single stance (centre of mass over the stance leg, highest at PEAK_i) ─ HS_{i+1}

with the centre of mass lowest early in double support (``com_min_fraction``, ~40 ms after heel strike and
~100 ms before the trailing toe-off, as in real lower-back recordings), generally *not* at the anatomical
foot-flat. Vertically the centre of mass oscillates once per step as a
phase-warped cosine (broad crest in single stance, sharp trough in double support) whose peak-to-valley
depth is the sum of Alvarez Fig. 3's two pendulums: ``h1`` = the drop of an arc of radius
``l_eff = pendulum_ratio · leg_length · f(v / v_pref)`` (see :class:`Subject`) over the mean half-chord
of single stance, and ``h2 = d_ds² / (8 · double_support_radius_m)`` over the double-support travel.
Forward it moves fastest in double support and slowest at mid-stance (``ap_speed_fluctuation``). Every
channel is C2 with exact derivatives (:func:`gaitlog.firmware_sim.world.hermite.quintic_hermite` knots, and
:class:`CosineProfile` / :class:`WarpedPhase` composed analytically), so the rendered acceleration is the
exact second derivative of the truth positions.

Speeds and step lengths: the excursion's speed times a gait-initiation ramp (first metres), a slow-down
around the turn and a slow-down before the stop; step length from the walk ratio at that speed, with
step-to-step variability and left/right asymmetry; the last steps are rescaled so the walker stops with
the centre of mass exactly at the end of the path.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PPoly

from gaitlog.firmware_sim.world.corridor import CorridorPath
from gaitlog.firmware_sim.world.hermite import evaluate, quintic_hermite
from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.units import STANDARD_GRAVITY_M_S2



@dataclass(frozen=True, eq=False)
class ExcursionPlan:
    """One excursion, planned (times in s on the recording clock, lengths in m).

    Attributes
    ----------
    t_start_s, t_stop_s
        Set off (centre of mass starts moving) and standstill.
    path
        The centre-of-mass path; ``s`` channel values are arc lengths along it.
    s, z, phase, envelope, pitch_mean
        C2 channels (PPoly, or :class:`CosineProfile` for ``z``): path progress (m), centre-of-mass height (m), gait phase (rad; advances pi per step,
        0 mod 2 pi at a left heel strike), amplitude envelope of the periodic trunk motions (0 standing,
        1 walking), mean trunk pitch (rad, forward lean positive).
    heel_strike_s, foot_flat_s, side
        Every foot contact (``n_steps + 1``: the last is the closing contact beside the other foot) and
        its foot (``"L"``/``"R"``).
    toe_off_s, com_peak_s
        Per step (``n_steps``): toe-off of the trailing foot, centre-of-mass high point (knot).
    step_phase
        Per step: ``"initiation"``, ``"steady"``, ``"turn"`` or ``"termination"``.
    leg_arc_radius_m
        Per step: the radius of the single-stance arc used.
    transient_t_s, transient_vertical_m_s2, transient_ap_m_s2, transient_sigma_s
        Contact transients, sorted by time: peak time, peak accelerations (vertical, forward) and Gaussian
        width. Heel strikes: an upward impact and a braking peak (``heel_strike_delay_s`` after contact);
        around each trailing toe-off: the end of push-off, a short drop of the vertical and forward
        accelerations (``toe_off_lead_s`` before it), and the leading leg's loading-response peak
        (``loading_response_delay_s`` after it).
    speed_m_s
        The excursion's nominal speed.
    """

    label: str
    speed_m_s: float
    t_start_s: float
    t_stop_s: float
    path: CorridorPath
    s: PPoly
    z: CosineProfile
    phase: PPoly
    envelope: PPoly
    pitch_mean: PPoly
    heel_strike_s: np.ndarray
    foot_flat_s: np.ndarray
    side: np.ndarray
    toe_off_s: np.ndarray
    com_peak_s: np.ndarray
    step_phase: np.ndarray
    leg_arc_radius_m: np.ndarray
    transient_t_s: np.ndarray
    transient_vertical_m_s2: np.ndarray
    transient_ap_m_s2: np.ndarray
    transient_sigma_s: np.ndarray
    amplitude_scale: float
    #: Per-step gain of the lateral stride harmonics (``Subject.ml_step_variability``), None when constant.
    ml_gain: PPoly | None = None

    @property
    def n_steps(self) -> int:
        """Number of steps (heel strike to next heel strike)."""
        return int(self.toe_off_s.size)


def _smooth_bump(x: np.ndarray | float) -> np.ndarray:
    """cos² window: 1 at 0, 0 for ``|x| >= 1``, C1."""
    x = np.clip(np.abs(np.asarray(x, dtype=np.float64)), 0.0, 1.0)
    return np.cos(0.5 * np.pi * x) ** 2


def _arc(l_eff: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop below the apex, slope dz/ds (magnitude) and curvature d²z/ds² at horizontal distance ``d``.

    Circle of radius ``l_eff`` through the apex: ``drop = l - sqrt(l² - d²)``.
    """
    root = np.sqrt(l_eff**2 - d**2)
    return l_eff - root, d / root, -(l_eff**2) / root**3


class CosineProfile:
    """``z(t) = level(t) - depth(t) · (1 - cos(phase(t))) / 2`` with exact derivatives (PPoly-like call).

    ``phase`` is 0 mod 2 pi at the peaks and pi mod 2 pi at the valleys; ``level`` is the peak height and
    ``depth`` the peak-to-valley excursion, both C2 and slowly varying.
    """

    def __init__(self, level: PPoly, depth: PPoly, phase: PPoly) -> None:
        self.level, self.depth, self.phase = level, depth, phase

    def __call__(self, t: np.ndarray, nu: int = 0) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        ph, ph1, ph2 = self.phase(t), self.phase(t, 1), self.phase(t, 2)
        c = 0.5 * (1.0 - np.cos(ph))
        if nu == 0:
            return self.level(t) - self.depth(t) * c
        c1 = 0.5 * np.sin(ph) * ph1
        if nu == 1:
            return self.level(t, 1) - self.depth(t, 1) * c - self.depth(t) * c1
        if nu == 2:
            c2 = 0.5 * (np.cos(ph) * ph1**2 + np.sin(ph) * ph2)
            return (self.level(t, 2) - self.depth(t, 2) * c - 2.0 * self.depth(t, 1) * c1
                    - self.depth(t) * c2)
        raise ValueError(f"derivative order {nu} not available (0, 1, 2)")

    def d012(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value and first two derivatives at once (each channel evaluated once; as the three calls)."""
        t = np.asarray(t, dtype=np.float64)
        ph, ph1, ph2 = evaluate(self.phase, t)
        l0, l1, l2 = evaluate(self.level, t)
        d0, d1, d2 = evaluate(self.depth, t)
        cs, sn = np.cos(ph), np.sin(ph)
        c = 0.5 * (1.0 - cs)
        c1 = 0.5 * sn * ph1
        c2 = 0.5 * (cs * ph1**2 + sn * ph2)
        return l0 - d0 * c, l1 - d1 * c - d0 * c1, l2 - d2 * c - 2.0 * d1 * c1 - d0 * c2


class WarpedPhase:
    """Vertical phase ``psi = B - w·sin(B) + a·(cos(2B)/8 - cos(B)/2 - 5/8)``, ``B = 2·(gait_phase - phase_0) - theta + pi``.

    ``B`` advances 2 pi per step with the gait phase; ``theta`` (C2, per-step knots) places the valley
    (``B = pi``, where ``psi = pi``) at its fraction of the step. The warp ``w`` makes the phase linger near
    the peak and hurry through the valley (a broad single-stance crest, a sharp double-support trough). The
    skew ``a`` (its rate term ``a·sin(B)·(1 - cos(B))/2`` acts around the valley only) makes the phase
    hurry *into* the valley and linger after it, so the centre of mass bottoms out early in double support
    while its upward acceleration lasts into early single stance (as in the IPOL lower-back recordings: low
    point ~40 ms after heel strike, vertical acceleration above 1 g until ~80 ms after the trailing
    toe-off). PPoly-like call.
    """

    def __init__(self, gait_phase: PPoly, theta: PPoly, phase0: float, warp: float, skew: float = 0.0) -> None:
        grid = np.linspace(0.0, 2.0 * np.pi, 721)
        if np.min(self._rate(grid, warp, skew)) <= 0.05:
            raise ValueError(f"vertical phase not monotonic for warp {warp} and skew {skew}")
        self.gait_phase, self.theta, self.phase0, self.warp, self.skew = gait_phase, theta, phase0, warp, skew

    @staticmethod
    def _rate(b: np.ndarray, w: float, a: float) -> np.ndarray:
        """``d psi / d B``."""
        return 1.0 - w * np.cos(b) + a * (0.5 * np.sin(b) - 0.25 * np.sin(2.0 * b))

    def __call__(self, t: np.ndarray, nu: int = 0) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        b = 2.0 * (self.gait_phase(t) - self.phase0) - self.theta(t) + np.pi
        w, a = self.warp, self.skew
        if nu == 0:
            return b - w * np.sin(b) + a * (0.125 * np.cos(2.0 * b) - 0.5 * np.cos(b) - 0.625)
        b1 = 2.0 * self.gait_phase(t, 1) - self.theta(t, 1)
        r = self._rate(b, w, a)
        if nu == 1:
            return b1 * r
        if nu == 2:
            b2 = 2.0 * self.gait_phase(t, 2) - self.theta(t, 2)
            r1 = w * np.sin(b) + a * (0.5 * np.cos(b) - 0.5 * np.cos(2.0 * b))
            return b2 * r + b1**2 * r1
        raise ValueError(f"derivative order {nu} not available (0, 1, 2)")

    def d012(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value and first two derivatives at once (each channel evaluated once; as the three calls)."""
        t = np.asarray(t, dtype=np.float64)
        g0, g1, g2 = evaluate(self.gait_phase, t)
        h0, h1, h2 = evaluate(self.theta, t)
        b = 2.0 * (g0 - self.phase0) - h0 + np.pi
        w, a = self.warp, self.skew
        sb, cb, c2b = np.sin(b), np.cos(b), np.cos(2.0 * b)
        psi = b - w * sb + a * (0.125 * c2b - 0.5 * cb - 0.625)
        b1 = 2.0 * g1 - h1
        r = self._rate(b, w, a)
        b2 = 2.0 * g2 - h2
        r1 = w * sb + a * (0.5 * cb - 0.5 * c2b)
        return psi, b1 * r, b2 * r + b1**2 * r1


def _vertical_profile(t_start: float, t_stop: float, gait_phase: PPoly, phase0: float, hs: np.ndarray,
                      tau_min: np.ndarray, t_peak: np.ndarray, z_stand: float, z_target: np.ndarray,
                      drop: np.ndarray, valley_extra: np.ndarray, warp: float, skew: float = 0.0) -> CosineProfile:
    """Centre-of-mass height with one valley per heel strike (``tau_min``: its fraction of the step after
    heel strike ``hs[j]``) and the peaks in between (level ``z_target`` near ``t_peak``).

    The peak-to-valley depth of valley ``j`` is the single-stance arc drop of the preceding step
    (``drop[j-1]``; ``drop[0]`` for the first) plus the double-support term ``valley_extra[j]`` (the second
    pendulum of Alvarez Fig. 3).
    """
    knots = np.concatenate(([t_start], hs, [t_stop]))
    th = 2.0 * np.pi * np.concatenate((tau_min[:1], tau_min, tau_min[-1:]))
    theta = quintic_hermite(knots, th, np.zeros(knots.size), np.zeros(knots.size))
    phase = WarpedPhase(gait_phase, theta, phase0, warp, skew)
    lev_t = np.concatenate(([t_start], t_peak, [t_stop]))
    lev_y = np.concatenate(([z_stand], z_target, [z_stand]))
    level = quintic_hermite(lev_t, lev_y, np.zeros(lev_t.size), np.zeros(lev_t.size))
    depth_v = np.concatenate((drop[:1], drop)) + valley_extra
    t_valley = hs + tau_min * np.concatenate((np.diff(hs), np.diff(hs)[-1:]))
    t_valley[-1] = min(t_valley[-1], 0.5 * (hs[-1] + t_stop))
    dep_t = np.concatenate(([t_start], t_valley, [t_stop]))
    depth = quintic_hermite(dep_t, np.concatenate(([0.0], depth_v, [0.0])), np.zeros(dep_t.size),
                            np.zeros(dep_t.size))
    return CosineProfile(level, depth, phase)


def plan_excursion(
    subject: Subject,
    walk_plan: WalkPlan,
    label: str,
    *,
    t_start_s: float,
    rng: np.random.Generator,
    first_side: str = "R",
) -> ExcursionPlan:
    """Plan one out-and-back excursion at the speed labelled ``label``.

    The steps below draw from ``rng`` in this order (the plan of a seed depends on it): step lengths and
    durations (1), the events of each step (2), the pendulum depth (3), the heel-strike transients (6b), the
    lateral harmonics' step gains (7, only for subjects with lateral harmonics).

    Parameters
    ----------
    subject, walk_plan
        Who walks and how.
    label
        Speed label (``preferred``, ``fast``, ``slow``, ``medium``).
    t_start_s
        When the walker sets off (recording clock).
    rng
        Seeded generator for step-to-step variability.
    first_side
        Foot of the first heel strike.
    """
    path = CorridorPath(corridor_length_m=walk_plan.corridor_length_m, turn_radius_m=walk_plan.turn_radius_m)
    v_exc = subject.speed_m_s(label)
    v_pref = subject.preferred_speed_m_s
    steps = _plan_steps(subject, walk_plan, path, v_exc, t_start_s=t_start_s, rng=rng, first_side=first_side)
    cycle = _plan_step_cycle(subject, steps, v_pref=v_pref, v_exc=v_exc, rng=rng)
    pendulum = _plan_pendulum(subject, steps, cycle, v_pref=v_pref, rng=rng)
    track = _plan_forward_track(subject, steps, cycle, t_start_s=t_start_s, length_m=path.length_m)
    phase_pp, phase0 = _gait_phase(t_start_s, track.t_stop_s, track.heel_strike_s, track.side)
    z_pp = _vertical_profile(t_start_s, track.t_stop_s, phase_pp, phase0, steps.heel_strike_s,
                             np.concatenate((cycle.tau_min, cycle.tau_min[-1:])), track.com_peak_s[:-1],
                             subject.com_height_m, pendulum.z_target_m, pendulum.drop_m,
                             np.concatenate((pendulum.extra_m, pendulum.extra_m[-1:])),
                             subject.vertical_warp, subject.vertical_skew)
    envelope_pp, pitch_pp = _envelope_and_lean(subject, label, t_start_s, track, v_exc=v_exc, v_pref=v_pref)
    step_phase = _step_phase_labels(walk_plan, path, track, n_end=steps.n_end)
    tr_t, tr_v, tr_ap, tr_sig = _heel_strike_transients(subject, cycle.vbar, track, v_pref=v_pref, rng=rng)
    return ExcursionPlan(
        label=label,
        speed_m_s=v_exc,
        t_start_s=t_start_s,
        t_stop_s=float(track.t_stop_s),
        path=path,
        s=track.s,
        z=z_pp,
        phase=phase_pp,
        envelope=envelope_pp,
        pitch_mean=pitch_pp,
        heel_strike_s=track.heel_strike_s,
        foot_flat_s=track.foot_flat_s,
        side=track.side,
        toe_off_s=track.toe_off_s,
        com_peak_s=track.com_peak_s,
        step_phase=step_phase.astype(str),
        leg_arc_radius_m=np.concatenate((pendulum.l_eff_m, [pendulum.l_eff_m[-1]])),
        transient_t_s=tr_t,
        transient_vertical_m_s2=tr_v,
        transient_ap_m_s2=tr_ap,
        transient_sigma_s=tr_sig,
        amplitude_scale=float((v_exc / v_pref) ** 0.5),
        ml_gain=_ml_gain(subject, t_start_s, track, rng),
    )


@dataclass(frozen=True, eq=False)
class _Steps:
    """Step 1 of :func:`plan_excursion`: the regular steps (the closing half step is added by step 4)."""

    lengths_m: np.ndarray
    durations_s: np.ndarray
    #: Foot of each regular heel strike (one more than the steps).
    sides: tuple[str, ...]
    #: Steps of the termination (the last ``n_end`` regular steps).
    n_end: int
    #: Regular heel strikes, s (recording clock), and the CoM's path distance at each, m.
    heel_strike_s: np.ndarray
    s_heel_strike_m: np.ndarray

    @property
    def n_regular(self) -> int:
        """Number of regular steps."""
        return self.lengths_m.size

    @property
    def vbar(self) -> np.ndarray:
        """Mean forward speed of each regular step, m/s."""
        return self.lengths_m / self.durations_s


def _speed_factor(walk_plan: WalkPlan, path: CorridorPath) -> Callable[[float], float]:
    """Speed at path distance ``d`` relative to the excursion's: the ramp-up, the turn's slow-down, the stop."""
    length = path.length_m

    def speed_factor(d: float) -> float:
        ramp = 1.0 - walk_plan.initiation_speed_deficit * np.exp(-max(d, 0.0) / (walk_plan.initiation_distance_m / 4.6))
        turn = 1.0 - (1.0 - walk_plan.turn_speed_factor) * float(
            _smooth_bump((d - path.s_apex_m) / walk_plan.turn_slowdown_m))
        end = 0.6 + 0.4 * float(np.clip((length - d) / walk_plan.termination_distance_m, 0.0, 1.0))
        return float(ramp * turn * end)

    return speed_factor


def _plan_steps(subject: Subject, walk_plan: WalkPlan, path: CorridorPath, v_exc: float, *,
                t_start_s: float, rng: np.random.Generator, first_side: str) -> _Steps:
    """Step 1: step lengths and durations from setting off to the path end (draws from ``rng``)."""
    speed_factor = _speed_factor(walk_plan, path)
    length = path.length_m
    v0 = v_exc * speed_factor(0.0)
    s_first = 0.5 * v0 * walk_plan.initiation_time_s * 0.9  # CoM travel from setting off to the first heel strike
    sides = [first_side]
    lengths: list[float] = []
    durations: list[float] = []
    d = s_first
    term_start = length - walk_plan.termination_distance_m
    while d < term_start:
        v = v_exc * speed_factor(d + 0.35)
        s_nom = float(subject.step_length_m(v))
        sign = 1.0 if sides[-1] == "L" else -1.0
        e_length = rng.normal(0.0, subject.step_length_cv)
        e_time = rng.normal(0.0, subject.step_time_cv)
        step = s_nom * (1.0 + 0.5 * sign * subject.asymmetry + e_length
                        + subject.step_length_follows_time * e_time)
        lengths.append(step)
        durations.append(s_nom / v * (1.0 + e_time))
        sides.append("R" if sides[-1] == "L" else "L")
        d += step
    # Termination: an integer number of steps plus the closing half step end exactly at the path end.
    remaining = length - d
    v_end = v_exc * speed_factor(length - 0.5)
    s_end_nom = float(subject.step_length_m(v_end))
    n_end = max(1, int(round(remaining / s_end_nom - 0.5)))
    s_end = remaining / (n_end + 0.5)
    for _ in range(n_end):
        v = v_exc * speed_factor(d + 0.35)
        lengths.append(s_end)
        durations.append(float(subject.step_length_m(v)) / v * (1.0 + rng.normal(0.0, subject.step_time_cv)))
        sides.append("R" if sides[-1] == "L" else "L")
        d += s_end
    lengths_a = np.asarray(lengths)
    durations_a = np.asarray(durations)
    hs = t_start_s + walk_plan.initiation_time_s + np.concatenate(([0.0], np.cumsum(durations_a)))
    s_hs = s_first + np.concatenate(([0.0], np.cumsum(lengths_a)))
    return _Steps(lengths_a, durations_a, tuple(sides), n_end, hs, s_hs)


@dataclass(frozen=True, eq=False)
class _StepCycle:
    """Step 2 of :func:`plan_excursion`: the events within each regular step and the forward motion in it.

    Phases ``tau`` run from 0 at a heel strike to 1 at the next; toe-off at ``tau_to``, the CoM's lowest
    point at ``tau_min``, its highest at ``tau_peak``.
    """

    steps: _Steps
    ds_frac: np.ndarray
    toe_off_s: np.ndarray
    foot_flat_s: np.ndarray
    tau_min: np.ndarray
    tau_to: np.ndarray
    tau_peak: np.ndarray
    #: Relative fluctuation of the forward speed within the step.
    eps: np.ndarray

    @property
    def vbar(self) -> np.ndarray:
        """Mean forward speed of each regular step, m/s."""
        return self.steps.vbar

    def g_frac(self, tau: np.ndarray) -> np.ndarray:
        """Fraction of the step length covered at phase ``tau``."""
        eps, tau_min = self.eps, self.tau_min
        return tau + eps / (2 * np.pi) * (np.sin(2 * np.pi * (tau - tau_min)) + np.sin(2 * np.pi * tau_min))

    def v_at(self, tau: np.ndarray) -> np.ndarray:
        """Forward speed at phase ``tau``, m/s."""
        return self.vbar * (1.0 + self.eps * np.cos(2 * np.pi * (tau - self.tau_min)))

    def a_at(self, tau: np.ndarray) -> np.ndarray:
        """Forward acceleration at phase ``tau``, m/s^2."""
        return -self.vbar * self.eps * (2 * np.pi / self.steps.durations_s) * np.sin(2 * np.pi * (tau - self.tau_min))


def _plan_step_cycle(subject: Subject, steps: _Steps, *, v_pref: float, v_exc: float,
                     rng: np.random.Generator) -> _StepCycle:
    """Step 2: toe-off, foot-flat and the CoM's low and high points of each regular step (draws from ``rng``)."""
    n_reg, vbar, durations_a, hs = steps.n_regular, steps.vbar, steps.durations_s, steps.heel_strike_s
    ds_frac = np.clip(subject.double_support_fraction * (vbar / v_pref) ** -0.6, 0.08, 0.40)
    ds_frac *= np.clip(1.0 + rng.normal(0.0, 0.05, n_reg), 0.8, 1.2)
    t_ds = ds_frac * durations_a
    to = hs[:-1] + t_ds
    ff = hs[:-1] + np.clip(subject.foot_flat_fraction * (1.0 + rng.normal(0.0, 0.06, n_reg)), 0.1, 0.95) * t_ds
    tau_min = np.clip(subject.com_min_fraction + rng.normal(0.0, 0.08, n_reg), -0.2, 1.6) * ds_frac
    tau_to = ds_frac
    tau_peak = tau_to + np.clip(subject.peak_fraction + rng.normal(0.0, 0.03, n_reg), 0.25, 0.75) * (1 - tau_to)
    eps = np.full(n_reg, subject.ap_speed_fluctuation) * (vbar / v_exc) ** 0.5
    return _StepCycle(steps, ds_frac, to, ff, tau_min, tau_to, tau_peak, eps)


@dataclass(frozen=True, eq=False)
class _Pendulum:
    """Step 3 of :func:`plan_excursion`: the depth of the CoM's vertical motion in each regular step."""

    #: Effective pendulum (leg arc) radius, m.
    l_eff_m: np.ndarray
    #: CoM height at the single-stance peak, m.
    z_target_m: np.ndarray
    #: Drop of the single-stance arc over its mean half-chord, m.
    drop_m: np.ndarray
    #: Sag of the double-support arc, m.
    extra_m: np.ndarray


def _plan_pendulum(subject: Subject, steps: _Steps, cycle: _StepCycle, *, v_pref: float,
                   rng: np.random.Generator) -> _Pendulum:
    """Step 3: the CoM's vertical excursion (draws from ``rng``).

    The centre of mass peaks at PEAK_i in single stance and bottoms out at MIN_i, ``com_min_fraction`` of the
    double support after heel strike (> 1: in early single stance, the stance-knee flexion of the loading
    response); between them it follows a phase-warped cosine (:func:`_vertical_profile`). The pendulums of
    Alvarez Fig. 3 set the depth: h1 = the drop of an arc of radius l_eff over the mean half-chord of single
    stance, h2 = the sag of a concave-up arc of radius double_support_radius_m over the double-support travel.
    """
    vbar, lengths_a, n_reg = steps.vbar, steps.lengths_m, steps.n_regular
    rel_v = vbar / v_pref
    l_eff = (subject.leg_length_m * subject.pendulum_ratio * rel_v**subject.pendulum_speed_exponent
             * (1.0 + subject.pendulum_speed_curvature * np.log(rel_v) ** 2))
    z_stand = subject.com_height_m
    z_target = z_stand - subject.peak_drop_m * (vbar / v_pref) - np.abs(rng.normal(0.0, 0.001, n_reg))
    d_a = lengths_a * (cycle.g_frac(cycle.tau_peak) - cycle.g_frac(cycle.tau_to))  # TO -> PEAK
    d_b = lengths_a * (1.0 - cycle.g_frac(cycle.tau_peak))  # PEAK -> next HS
    drop, _, _ = _arc(l_eff, 0.5 * (d_a + d_b))
    left = np.array([side == "L" for side in steps.sides[:-1]])
    drop = drop * (1.0 + np.where(left, 0.5, -0.5) * subject.vertical_asymmetry)
    d_ds = lengths_a * cycle.g_frac(cycle.tau_to)  # CoM travel in double support
    extra = d_ds**2 / (8.0 * subject.double_support_radius_m)
    return _Pendulum(l_eff, z_target, drop, extra)


@dataclass(frozen=True, eq=False)
class _Track:
    """Step 4 of :func:`plan_excursion`: the CoM's forward path and the events of every step, closing step
    included (times in s on the recording clock)."""

    #: Forward path distance of the CoM, m (piecewise quintic of time).
    s: PPoly
    heel_strike_s: np.ndarray
    toe_off_s: np.ndarray
    foot_flat_s: np.ndarray
    #: CoM peak of each step (NaN for the closing step).
    com_peak_s: np.ndarray
    side: np.ndarray
    t_stop_s: float

    @property
    def n_steps(self) -> int:
        """Steps of the excursion, closing step included."""
        return self.heel_strike_s.size - 1


def _heel_strike_kinematics(cycle: _StepCycle) -> tuple[np.ndarray, np.ndarray]:
    """CoM forward speed and acceleration at each regular heel strike (mean of the steps on both sides)."""
    n_reg = cycle.steps.n_regular
    v_hs_end, a_hs_end = cycle.v_at(np.ones(n_reg)), cycle.a_at(np.ones(n_reg))
    v_hs_start, a_hs_start = cycle.v_at(np.zeros(n_reg)), cycle.a_at(np.zeros(n_reg))
    v_hs = np.empty(n_reg + 1)
    a_hs = np.empty(n_reg + 1)
    v_hs[0], a_hs[0] = v_hs_start[0], a_hs_start[0]
    v_hs[1:-1] = 0.5 * (v_hs_end[:-1] + v_hs_start[1:])
    a_hs[1:-1] = 0.5 * (a_hs_end[:-1] + a_hs_start[1:])
    v_hs[-1], a_hs[-1] = v_hs_end[-1], a_hs_end[-1]
    return v_hs, a_hs


def _plan_forward_track(subject: Subject, steps: _Steps, cycle: _StepCycle, *, t_start_s: float,
                        length_m: float) -> _Track:
    """Step 4: knots of the forward path at every heel strike, toe-off and CoM peak, and the closing step."""
    hs, s_hs, lengths_a, durations_a = steps.heel_strike_s, steps.s_heel_strike_m, steps.lengths_m, steps.durations_s
    v_hs, a_hs = _heel_strike_kinematics(cycle)
    v_to, a_to = cycle.v_at(cycle.tau_to), cycle.a_at(cycle.tau_to)
    v_pk, a_pk = cycle.v_at(cycle.tau_peak), cycle.a_at(cycle.tau_peak)
    t_knots = [np.array([t_start_s])]
    s_k = [np.array([[0.0, 0.0, 0.0]])]
    t_peak = hs[:-1] + cycle.tau_peak * durations_a
    t_st = np.stack([hs[:-1], cycle.toe_off_s, t_peak], axis=1).ravel()
    s_st = np.stack([
        np.stack([s_hs[:-1], v_hs[:-1], a_hs[:-1]], axis=1),
        np.stack([s_hs[:-1] + lengths_a * cycle.g_frac(cycle.tau_to), v_to, a_to], axis=1),
        np.stack([s_hs[:-1] + lengths_a * cycle.g_frac(cycle.tau_peak), v_pk, a_pk], axis=1),
    ], axis=1).reshape(-1, 3)
    t_knots.append(t_st)
    s_k.append(s_st)
    # Closing step: the last regular heel strike, the double support, then the trailing foot closes
    # beside the leading one while the centre of mass comes to rest over both feet at the path end.
    length = length_m
    i_last = steps.n_regular - 1
    t_hs_n = hs[-1]
    frac_ds = cycle.ds_frac[i_last]
    t_to_n = t_hs_n + frac_ds * durations_a[i_last]
    s_hs_n = s_hs[-1]
    v_n = v_hs[-1]
    s_to_n = s_hs_n + min(v_n * (t_to_n - t_hs_n) * 0.95, 0.5 * (length - s_hs_n))
    v_to_n = min(0.85 * v_n, 2.0 * (length - s_to_n) / (t_to_n - t_hs_n))
    t_stop = t_to_n + 2.1 * (length - s_to_n) / v_to_n
    t_knots.append(np.array([t_hs_n, t_to_n, t_stop]))
    s_k.append(np.array([[s_hs_n, v_n, a_hs[-1]], [s_to_n, v_to_n, -0.5 * v_n / (t_stop - t_to_n)],
                         [length, 0.0, 0.0]]))
    t_all = np.concatenate(t_knots)
    s_pp = quintic_hermite(t_all, *np.concatenate(s_k).T)
    hs_close = t_to_n + 0.7 * (t_stop - t_to_n)
    heel_strikes = np.concatenate((hs, [hs_close]))
    toe_offs = np.concatenate((cycle.toe_off_s, [t_to_n]))
    foot_flats = np.concatenate((cycle.foot_flat_s, [t_hs_n + subject.foot_flat_fraction * (t_to_n - t_hs_n),
                                                     hs_close + 0.06]))
    com_peak = np.concatenate((t_peak, [np.nan]))
    sides = steps.sides + ("R" if steps.sides[-1] == "L" else "L",)
    return _Track(s_pp, heel_strikes, toe_offs, foot_flats, com_peak, np.asarray(sides), t_stop)


def _gait_phase(t_start_s: float, t_stop_s: float, heel_strikes: np.ndarray, side: np.ndarray) -> tuple[PPoly, float]:
    """Step 5a: the gait phase (rad; advances by pi per step, 0 mod 2 pi at a left heel strike) and its start."""
    phase0 = 0.0 if side[0] == "L" else np.pi
    step_t = np.diff(heel_strikes)
    rate = np.pi / np.concatenate(([step_t[0]], 0.5 * (step_t[:-1] + step_t[1:]), [step_t[-1]]))
    ph_t = np.concatenate(([t_start_s], heel_strikes, [t_stop_s]))
    ph_y = np.concatenate(([phase0 - 0.5 * np.pi], phase0 + np.pi * np.arange(heel_strikes.size),
                           [phase0 + np.pi * (heel_strikes.size - 1) + 0.5 * np.pi]))
    ph_dy = np.concatenate(([0.0], rate, [0.0]))
    return quintic_hermite(ph_t, ph_y, ph_dy, np.zeros(ph_t.size)), phase0


def _envelope_and_lean(subject: Subject, label: str, t_start_s: float, track: _Track, *, v_exc: float,
                       v_pref: float) -> tuple[PPoly, PPoly]:
    """Step 5b: the gait envelope (0 standing, 1 walking) and the trunk's mean pitch, rad."""
    heel_strikes, n_steps, t_stop = track.heel_strike_s, track.n_steps, track.t_stop_s
    env_t = np.array([t_start_s, heel_strikes[min(subject.envelope_full_at_step, n_steps)], heel_strikes[-2],
                      t_stop])
    if np.any(np.diff(env_t) <= 0):
        raise ValueError(f"excursion {label!r} is too short to plan ({n_steps} steps)")
    envelope_pp = quintic_hermite(env_t, np.array([0.0, 1.0, 1.0, 0.0]), np.zeros(4), np.zeros(4))
    walk_lean = np.deg2rad(subject.trunk_lean_deg) * (v_exc / v_pref) ** 0.5
    stand_lean = np.deg2rad(subject.stand_lean_deg)
    pitch_pp = quintic_hermite(env_t, np.array([stand_lean, walk_lean, walk_lean, stand_lean]), np.zeros(4),
                               np.zeros(4))
    return envelope_pp, pitch_pp


def _step_phase_labels(walk_plan: WalkPlan, path: CorridorPath, track: _Track, *, n_end: int) -> np.ndarray:
    """Step 6a: ``initiation`` / ``steady`` / ``turn`` / ``termination`` for each step."""
    n_steps = track.n_steps
    s_at_hs = track.s(track.heel_strike_s)
    mid = 0.5 * (s_at_hs[:-1] + s_at_hs[1:])
    step_phase = np.full(n_steps, "steady", dtype=object)
    step_phase[s_at_hs[:-1] < walk_plan.initiation_distance_m] = "initiation"
    step_phase[np.abs(mid - path.s_apex_m) < 0.5 * path.turn_length_m + 0.5] = "turn"
    step_phase[n_steps - n_end - 1:] = "termination"
    return step_phase


def _ml_gain(subject: Subject, t_start_s: float, track: _Track, rng: np.random.Generator) -> PPoly | None:
    """Step 7: the step-to-step gain of the lateral harmonics, ``exp(N(0, ml_step_variability))`` at each heel
    strike, 1 at set-off and standstill (draws from ``rng`` only when the subject has lateral harmonics)."""
    if not subject.ml_harmonics_m_s2 or subject.ml_step_variability <= 0.0:
        return None
    hs = track.heel_strike_s
    knots = np.concatenate(([t_start_s], hs, [track.t_stop_s]))
    gain = np.concatenate(([1.0], np.exp(rng.normal(0.0, subject.ml_step_variability, hs.size)), [1.0]))
    return quintic_hermite(knots, gain, np.zeros(knots.size), np.zeros(knots.size))


def _heel_strike_transients(subject: Subject, vbar: np.ndarray, track: _Track, *, v_pref: float,
                            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 6b: the impact, push-off and loading-response pulses (draws from ``rng``), in time order:
    times (s), vertical and antero-posterior amplitudes (m/s^2) and widths (s)."""
    heel_strikes, toe_offs, n_steps = track.heel_strike_s, track.toe_off_s, track.n_steps
    v_contact = np.concatenate((vbar, [vbar[-1], vbar[-1] * 0.5]))
    scale = np.clip(v_contact, 0.2, None) / v_pref
    jitter = np.exp(rng.normal(0.0, 0.2, heel_strikes.size))
    g = STANDARD_GRAVITY_M_S2
    to_scale = scale[:-1] * np.exp(rng.normal(0.0, 0.2, n_steps))
    lr_scale = scale[:-1] * np.exp(rng.normal(0.0, 0.2, n_steps))
    tr_t = np.concatenate((heel_strikes + subject.heel_strike_delay_s, toe_offs - subject.toe_off_lead_s,
                           toe_offs + subject.loading_response_delay_s))
    tr_v = np.concatenate((subject.heel_strike_acc_g * g * scale * jitter, -subject.toe_off_acc_g * g * to_scale,
                           subject.loading_response_acc_g * g * lr_scale))
    tr_ap = np.concatenate((-subject.heel_strike_ap_acc_g * g * scale * jitter**subject.ap_contact_jitter_share,
                            -subject.toe_off_ap_acc_g * g * to_scale, np.zeros(n_steps)))
    tr_sig = np.concatenate((np.full(heel_strikes.size, subject.heel_strike_width_s),
                             np.full(n_steps, subject.toe_off_width_s),
                             np.full(n_steps, subject.loading_response_width_s)))
    # left/right asymmetry of loading (the leading foot of each contact): left contacts stronger by +a/2
    lead = np.concatenate((track.side, track.side[:-1], track.side[:-1]))
    side = np.where(lead == "L", 0.5, -0.5) * subject.vertical_asymmetry
    tr_v, tr_ap = tr_v * (1.0 + side), tr_ap * (1.0 + subject.ap_contact_asymmetry_share * side)
    order = np.argsort(tr_t, kind="stable")
    return tr_t[order], tr_v[order], tr_ap[order], tr_sig[order]
