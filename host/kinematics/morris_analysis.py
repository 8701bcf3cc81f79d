"""Morris (1973) on a recording: cycle selection from foot-flat, then the full analysis of each cycle.

Per cycle (foot-flat to foot-flat; Morris set cursors on a 2.56 s record, :func:`cycles_from_foot_flat`
finds them automatically):

1. angular velocity from the accelerometers (eqs 5-8, :class:`AngularVelocityFromAccelerometers`); the
   integration constant ``C`` of eq (6) -- the angular velocity at the cycle start -- is chosen so that the
   orientation at the end of the cycle equals that at its start (the movement is cyclic; Gauss-Newton on the
   rotation vector of ``λ(0)ᵀλ(T)`` over the free rate components), then the cycle drift filter makes the
   start and end values of ω equal (Fig 4b);
2. initial direction cosines at foot-flat from the pivot constraint (eq 11) and gravity (eqs 12-16);
3. strapdown integration of the direction cosines (eqs 9-10);
4. gravity removal, double integration, cycle drift removal (velocity start = end, the vertical position
   returns to its start; the initial velocity follows from the fixed pivot ``λ(ω × r)``; the walking
   direction is unknown in the ``λ12 = 0`` frame, so the horizontal positions are left open);
5. the space frame turned about the vertical so the stride points forwards (``align_walking``).

Foot-flat detection (:func:`foot_flat_intervals`): during foot-flat the shank turns about a fixed pivot, so
the origin's specific force minus the rotational acceleration about the pivot, ``f − (ω̇ × r + ω × (ω × r))``,
is gravity alone, of norm 1 g. ω for this test is integrated over the whole record with ``C = 0`` and
high-passed at the double-step period (Morris: "sets a lower frequency limit on the signal pass-band
corresponding to the double-step period"), the period itself found by autocorrelation. Samples within
``tolerance_g`` of 1 g for at least ``min_flat_s`` are foot-flat; a cycle runs from the middle of one
foot-flat to the middle of the next, its end moved by up to 3 samples to where the readings best repeat
those at its start.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.accelerometer_pairs import (
    AngularVelocityFromAccelerometers,
    gravity_from_pivot,
)
from gaitlog.host.kinematics.orientation import initial_dcm_from_gravity, integrate_dcm
from gaitlog.host.kinematics.platform_description import MorrisPlatform
from gaitlog.host.kinematics.sensor_csv import SensorRecording
from gaitlog.host.kinematics.strapdown import (
    CycleTranslation,
    remove_cycle_drift,
    remove_gravity,
)
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = [
    "MorrisAnalysis",
    "MorrisCycle",
    "analyse_morris_recording",
    "cycles_from_foot_flat",
    "foot_flat_intervals",
    "gait_period_s",
    "match_cycle_end",
]


@dataclass(frozen=True, eq=False)
class MorrisCycle:
    """One analysed cycle; arrays over its samples ``start`` to ``stop`` (inclusive).

    ``t_s`` is the recording's time; ``dcm`` body-to-space (space axis 3 up, heading ``λ12 = 0`` at the
    start); ``position_m`` of the platform origin relative to its start, space axes.
    """

    start: int
    stop: int
    t_s: np.ndarray
    omega_raw_rad_s: np.ndarray
    omega_rad_s: np.ndarray
    alpha_rad_s2: np.ndarray
    dcm: np.ndarray
    acceleration_m_s2: np.ndarray
    velocity_m_s: np.ndarray
    position_m: np.ndarray
    omega0_rad_s: np.ndarray
    #: ``‖gravity from the pivot constraint‖ − 1`` at the start, g: near 0 when the start is in foot-flat.
    pivot_misfit_g: float = 0.0


def gait_period_s(readings_g: np.ndarray, sampling_rate_hz: float, *, lo_s: float = 0.5, hi_s: float = 3.0) -> float:
    """The double-step period: the lag in ``[lo_s, hi_s]`` of the highest (biased) autocorrelation of the
    readings, whose taper ``1 − lag/n`` favours the period over its multiples."""
    x = np.asarray(readings_g, dtype=np.float64)
    x = (x - x.mean(axis=0)) / np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
    n = x.shape[0]
    lo, hi = int(lo_s * sampling_rate_hz), min(int(hi_s * sampling_rate_hz), n - 1)
    if hi <= lo + 1:
        raise HostError(f"the recording ({n / sampling_rate_hz:.2f} s) is too short to find a gait cycle of "
                        f"{lo_s:g}-{hi_s:g} s: give the cycle with --cycle START END")
    spec = np.fft.rfft(x, 2 * n, axis=0)
    acf = np.fft.irfft((spec * spec.conj()).real.sum(axis=1))[:n]  # biased: short lags win over multiples
    return float((lo + int(np.argmax(acf[lo:hi]))) / sampling_rate_hz)


def foot_flat_intervals(
    solver: AngularVelocityFromAccelerometers,
    readings_g: np.ndarray,
    sampling_rate_hz: float,
    origin_from_pivot_m: np.ndarray,
    *,
    tolerance_g: float = 0.05,
    min_flat_s: float = 0.1,
    period_s: float | None = None,
) -> list[tuple[int, int]]:
    """``(first, last)`` sample of each foot-flat period (module notes); quiet stretches closer than a
    quarter of the gait period are one period."""
    period = gait_period_s(readings_g, sampling_rate_hz) if period_s is None else period_s
    est = solver.estimate(readings_g, sampling_rate_hz=sampling_rate_hz)
    lag = max(round(period * sampling_rate_hz), 1)
    w = est.omega_rad_s_ - uniform_filter1d(est.omega_rad_s_, lag, axis=0, mode="nearest")
    up = gravity_from_pivot(est.origin_specific_force_g_, w, est.alpha_rad_s2_, origin_from_pivot_m)
    dev = uniform_filter1d(np.abs(np.linalg.norm(up, axis=1) - 1.0), max(round(0.1 * sampling_rate_hz), 1))
    flat = dev < tolerance_g
    gap = round(0.25 * period * sampling_rate_hz)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flat.astype(np.int8), [0]])))
    merged: list[list[int]] = []
    for a, b in zip(edges[::2].tolist(), (edges[1::2] - 1).tolist(), strict=True):
        if merged and a - merged[-1][1] - 1 <= gap:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    need = int(np.ceil(min_flat_s * sampling_rate_hz))
    return [(a, b) for a, b in merged if b - a + 1 >= need]


def match_cycle_end(readings_g: np.ndarray, start: int, end: int, *, search: int = 5, half_window: int = 3) -> int:
    """``end`` moved by up to ``search`` samples to where the readings around it best repeat those around
    ``start`` (sum of squared differences over ``±half_window`` samples): the cycle drift filter forces
    start = end, so both ends must be at the same phase of the gait (one sample off costs degrees)."""
    r = np.asarray(readings_g, dtype=np.float64)
    n = r.shape[0]
    k = np.arange(-half_window, half_window + 1)
    ref = r[np.clip(start + k, 0, n - 1)]
    cands = [c for c in range(end - search, end + search + 1) if start + 2 <= c <= n - 1]
    if not cands:
        return end
    cost = [float(((r[np.clip(c + k, 0, n - 1)] - ref) ** 2).sum()) for c in cands]
    return int(cands[int(np.argmin(cost))])


def cycles_from_foot_flat(intervals: list[tuple[int, int]], readings_g: np.ndarray, period_samples: float
                          ) -> list[tuple[int, int]]:
    """``(start, stop)`` of each cycle from the middle of one foot-flat to the middle of the next, kept when
    it lasts 0.75-1.25 gait periods, its end matched to its start (:func:`match_cycle_end`)."""
    mids = [(a + b) // 2 for a, b in intervals]
    out = []
    for s, e in itertools.pairwise(mids):
        if 0.75 * period_samples <= e - s <= 1.25 * period_samples:
            out.append((s, match_cycle_end(readings_g, s, e)))
    return out


def _final_rotvec(omega: np.ndarray, lengths: np.ndarray, dt: float) -> np.ndarray:
    """Rotation vector of ``λ(T)`` from ``λ(0) = I`` for each trajectory ``(K, L, 3)`` of body rates, over its
    first ``lengths[k]`` samples: the trapezoidal incremental rotations of :func:`integrate_dcm` chained as
    unit quaternions, one numpy step per sample for the whole batch."""
    phi = 0.5 * (omega[:, 1:] + omega[:, :-1]) * dt
    phi[np.arange(phi.shape[1])[None, :] >= (lengths - 1)[:, None]] = 0.0  # past the cycle end: identity
    theta = np.linalg.norm(phi, axis=2)
    half = 0.5 * theta
    scale = np.where(theta < 1e-8, 0.5, np.sin(half) / np.where(theta < 1e-8, 1.0, theta))
    qw, qv = np.cos(half), phi * scale[:, :, None]
    w, v = np.ones(omega.shape[0]), np.zeros((omega.shape[0], 3))
    for k in range(phi.shape[1]):  # q ← q ⊗ q_k (body-frame increments)
        bw, bv = qw[:, k], qv[:, k]
        w, v = (w * bw - np.einsum("ni,ni->n", v, bv),
                w[:, None] * bv + bw[:, None] * v + np.cross(v, bv))
    nv = np.linalg.norm(v, axis=1)
    ang = 2.0 * np.arctan2(nv, w)
    ang = np.where(ang > np.pi, ang - 2 * np.pi, ang)
    return v * np.where(nv > 1e-15, ang / np.where(nv > 1e-15, nv, 1.0), 2.0)[:, None]


class MorrisAnalysis:
    """Morris' analysis of a platform of single-axis accelerometers, cycle by cycle (module notes).

    Parameters
    ----------
    positions_m, axes
        ``(m, 3)`` accelerometer positions (m, from the platform origin) and sensing axes, segment frame.
    origin_from_pivot_m
        ``(3,)`` the platform origin relative to the foot-flat pivot, segment frame, m.
    assume_zero_rate_axes
        Segment axes whose angular velocity is taken as zero (Morris' five accelerometers: ``(2,)``).
    align_walking
        Step 5: turn the space frame about the vertical so that the cycle's horizontal displacement (the
        stride) lies along space axis 1 (forwards), as Figs 6-7 show it; else keep Morris' ``λ12 = 0``.
    """

    def __init__(self, *, positions_m: np.ndarray, axes: np.ndarray, origin_from_pivot_m: np.ndarray,
                 assume_zero_rate_axes: tuple[int, ...] = (), align_walking: bool = True) -> None:
        self.align_walking = align_walking
        self.solver = AngularVelocityFromAccelerometers(positions_m=positions_m, axes=axes,
                                                        fixed_zero_axes=assume_zero_rate_axes)
        self.solver._design()  # refuse a platform that cannot determine the motion, before any work
        self.origin_from_pivot_m = np.asarray(origin_from_pivot_m, dtype=np.float64)
        self.free = [k for k in range(3) if k not in set(assume_zero_rate_axes)]

    def find_cycles(self, readings_g: np.ndarray, sampling_rate_hz: float) -> list[tuple[int, int]]:
        """Cycles from foot-flat to foot-flat (:func:`foot_flat_intervals`, :func:`cycles_from_foot_flat`)."""
        period = gait_period_s(readings_g, sampling_rate_hz)
        flats = foot_flat_intervals(self.solver, readings_g, sampling_rate_hz, self.origin_from_pivot_m,
                                    period_s=period)
        cycles = cycles_from_foot_flat(flats, readings_g, period * sampling_rate_hz)
        if not cycles:
            raise HostError(f"found {len(flats)} foot-flat period(s), no complete cycle from one to the next: "
                            "record longer or give the cycle with --cycle START END")
        return cycles

    def _estimate(self, readings: np.ndarray, rate: float, omega0: np.ndarray) -> AngularVelocityFromAccelerometers:
        return self.solver.estimate(readings, sampling_rate_hz=rate, omega0_rad_s=omega0)

    def closing_omega0(self, readings_g: np.ndarray, sampling_rate_hz: float, cycles: list[tuple[int, int]],
                       *, iterations: int = 4) -> np.ndarray:
        """The integration constant of eq (6) of each cycle: ``ω`` at its start such that the orientation
        integrated over the cycle returns to its start (``(len(cycles), 3)``, rad/s, body axes).

        Start: the mean rate over the cycle is zero (exact for planar motion); then Gauss-Newton on the
        rotation vector of ``λ(0)ᵀλ(T)`` over the free rate components, its Jacobian by finite differences
        once (chord method). All cycles and all perturbed trajectories are integrated together, one numpy
        step per sample for the whole batch (the recursion is per sample, not per cycle).
        """
        _, pinv, q, free_arr = self.solver._design()
        free = [int(k) for k in free_arr]
        r = np.asarray(readings_g, dtype=np.float64) * STANDARD_GRAVITY_M_S2
        p_alpha = pinv[3:]
        g = np.zeros((3, 3, 3))
        gj = np.einsum("ji,iab->jab", p_alpha, q)
        g[free] = 0.5 * (gj + np.swapaxes(gj, 1, 2))
        lengths = np.array([e - s + 1 for s, e in cycles])
        n_max = int(lengths.max())
        c = np.zeros((len(cycles), n_max, 3))
        for b, (s, e) in enumerate(cycles):
            c[b, : e - s + 1, free] = (r[s : e + 1] @ p_alpha.T).T
            c[b, e - s + 1 :] = c[b, e - s]
        dt = 1.0 / sampling_rate_hz
        nb = len(cycles)

        def rates(w0: np.ndarray, reps: int) -> np.ndarray:
            cc = np.tile(c, (reps, 1, 1))
            out = np.empty(cc.shape)
            w = w0.copy()
            a = cc[:, 0] - np.einsum("jab,na,nb->nj", g, w, w)
            for k in range(n_max):
                out[:, k] = w
                if k + 1 == n_max:
                    break
                wp = w + dt * a
                ap = cc[:, k + 1] - np.einsum("jab,na,nb->nj", g, wp, wp)
                w = w + 0.5 * dt * (a + ap)
                a = cc[:, k + 1] - np.einsum("jab,na,nb->nj", g, w, w)
            return out

        def closure(w0: np.ndarray, reps: int = 1) -> np.ndarray:
            return _final_rotvec(rates(w0, reps), np.tile(lengths, reps), dt)

        weights = (np.arange(n_max)[None, :] < lengths[:, None]).astype(float)
        weights[:, 0] *= 0.5
        weights[np.arange(nb), lengths - 1] *= 0.5
        weights /= (lengths - 1)[:, None]
        omega0 = np.zeros((nb, 3))
        omega0 -= np.einsum("bk,bkj->bj", weights, rates(omega0, 1))
        h = 1e-4
        pert = np.concatenate([omega0] + [omega0 + h * np.eye(3)[j] for j in free])
        f_all = closure(pert, 1 + len(free)).reshape(1 + len(free), nb, 3)
        jac = np.stack([(f_all[1 + i] - f_all[0]) / h for i in range(len(free))], axis=2)  # (nb, 3, nfree)
        jinv = np.linalg.pinv(jac)
        f0 = f_all[0]
        for _ in range(iterations):
            step = np.einsum("bij,bj->bi", jinv, f0)
            omega0[:, free] -= step
            if np.abs(step).max() < 1e-10:
                break
            f0 = closure(omega0)
        return omega0

    def analyse_cycle(self, readings_g: np.ndarray, sampling_rate_hz: float, start: int, stop: int,
                      t_s: np.ndarray | None = None, omega0_rad_s: np.ndarray | None = None) -> MorrisCycle:
        """Analyse samples ``start .. stop`` (inclusive), ``start`` in foot-flat (module notes, steps 1-5);
        ``omega0_rad_s`` from :meth:`closing_omega0` (computed here when not given)."""
        r_all = np.asarray(readings_g, dtype=np.float64)
        if not (0 <= start < stop < r_all.shape[0]) or stop - start < 10:
            raise HostError(f"cycle {start}..{stop} must lie inside the {r_all.shape[0]} samples and span at "
                            "least 10 samples")
        rate = sampling_rate_hz
        r = r_all[start : stop + 1]
        # 1. ω, the constant of eq (6) from the cycle closure
        if omega0_rad_s is None:
            omega0_rad_s = self.closing_omega0(r_all, rate, [(start, stop)])[0]
        omega0 = np.asarray(omega0_rad_s, dtype=np.float64)
        est = self._estimate(r, rate, omega0)
        omega_raw = est.omega_rad_s_
        omega = remove_cycle_drift(omega_raw)
        # 2. initial direction cosines at foot-flat (eq 11, eqs 12-16)
        r_o = self.origin_from_pivot_m
        up0 = gravity_from_pivot(est.origin_specific_force_g_[0], omega[0], est.alpha_rad_s2_[0], r_o)
        lam0 = initial_dcm_from_gravity(up0, on_singular="axis1")
        # 3. strapdown direction cosines (eqs 9-10)
        dcm = integrate_dcm(omega, rate, lam0)
        # 4. translation of the origin
        acc = remove_gravity(est.origin_specific_force_g_, dcm)
        v0 = lam0 @ np.cross(omega[0], r_o)
        trans = CycleTranslation(closed_axes=(2,), initial_velocity_m_s=v0).integrate(acc, sampling_rate_hz=rate)
        acc, vel, pos = trans.acceleration_m_s2_, trans.velocity_m_s_, trans.position_m_
        # 5. walking frame: turn the λ12 = 0 space frame about the vertical so the cycle's displacement is +1'
        stride = pos[-1, :2] - pos[0, :2]
        if self.align_walking and np.hypot(*stride) > 0.05:
            h = np.arctan2(stride[1], stride[0])
            rz = np.array([[np.cos(h), np.sin(h), 0.0], [-np.sin(h), np.cos(h), 0.0], [0.0, 0.0, 1.0]])
            dcm, acc, vel, pos = rz @ dcm, acc @ rz.T, vel @ rz.T, pos @ rz.T
        t = (np.arange(start, stop + 1) / rate) if t_s is None else np.asarray(t_s)[start : stop + 1]
        return MorrisCycle(start, stop, t, omega_raw, omega, est.alpha_rad_s2_, dcm, acc, vel, pos, omega0,
                           float(np.linalg.norm(up0) - 1.0))


def analyse_morris_recording(recording: SensorRecording, platform: MorrisPlatform, *,
                             cycle_s: tuple[float, float] | None = None) -> list[MorrisCycle]:
    """Analyse a recording: the cycle ``cycle_s = (start, end)`` in the file's seconds (Morris' cursors;
    the start must be in foot-flat; the end is matched to the start's phase by :func:`match_cycle_end`), or
    every foot-flat-to-foot-flat cycle found."""
    readings = recording.columns(platform.sensors, "specific force")
    analysis = MorrisAnalysis(positions_m=platform.positions_m, axes=platform.axes,
                              origin_from_pivot_m=platform.origin_from_pivot_m,
                              assume_zero_rate_axes=platform.assume_zero_rate_axes)
    rate, t = recording.sampling_rate_hz, recording.t_s
    if cycle_s is None:
        cycles = analysis.find_cycles(readings, rate)
    else:
        a, b = cycle_s
        if not (t[0] <= a < b <= t[-1]):
            raise HostError(f"--cycle {a:g} {b:g}: must satisfy {t[0]:g} <= START < END <= {t[-1]:g} s "
                            f"(the time span of {recording.source})")
        first = int(np.argmin(np.abs(t - a)))
        cycles = [(first, match_cycle_end(readings, first, int(np.argmin(np.abs(t - b)))))]
    omega0 = analysis.closing_omega0(readings, rate, cycles)
    return [analysis.analyse_cycle(readings, rate, s, e, t, w0) for (s, e), w0 in zip(cycles, omega0, strict=True)]
