"""Figures in the spirit of Morris (1973) Figs 4-7 and of Hall et al. (1997), written atomically as PNG.

- :func:`plot_angular_velocity` -- Fig 4a/b: coronal and sagittal angular velocity before and after the
  cycle drift filter;
- :func:`plot_dcm` -- Fig 5: the nine direction cosines over one cycle;
- :func:`plot_translation` -- Fig 6: translational acceleration, velocity and position (rows: forwards,
  sideways, vertical);
- :func:`plot_stick_figure` -- Fig 7: a multiple exposure of shank and foot in the sagittal plane at
  12.5 frames/s (the foot is kept perpendicular to the shank, and the toe is kept above a ground line
  drawn at the lowest heel excursion, as in Morris' simulation);
- :func:`body_model_points`, :func:`project_view`, :func:`plot_body_model`, :func:`write_body_model_gif` --
  Fig 7 as published: Morris' 26-point shank-and-foot model moved by the computed orientation and
  translation, viewed from any azimuth/elevation, as a multiple exposure (PNG) and as the "true-speed
  moving picture" (GIF through matplotlib's :class:`~matplotlib.animation.PillowWriter`);
- :func:`plot_joint_angles` -- Hall: joint angles against the truth.

Figures are :class:`matplotlib.figure.Figure` objects rendered straight to PNG (no pyplot, no global backend:
importing this module changes nothing for a program that uses matplotlib itself); every figure goes through
:func:`gaitlog.host.storage.png_figure.write_figure_png` (the GIF through a temporary file renamed into place). Only ``gaitlog kinematics`` imports this module.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.figure import Figure

from gaitlog.host.storage.png_figure import write_figure_png

__all__ = [
    "BODY_MODEL_POINTS_M",
    "body_model_points",
    "plot_angular_velocity",
    "plot_body_model",
    "plot_dcm",
    "plot_joint_angles",
    "plot_stick_figure",
    "plot_translation",
    "project_view",
    "stick_figure_points",
    "write_body_model_gif",
]

_AXIS_NAMES = ("forwards-backwards", "sideways", "vertical")


def _save(fig: Figure, path: str | os.PathLike[str]) -> None:
    write_figure_png(fig, path, dpi=110)


def plot_angular_velocity(
    t_s: np.ndarray,
    omega_raw_rad_s: np.ndarray,
    omega_filtered_rad_s: np.ndarray,
    path: str | os.PathLike[str],
    *,
    truth_rad_s: np.ndarray | None = None,
    record: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Fig 4a/b: coronal (body axis 1) and sagittal (body axis 2) angular velocity, before/after filtering.

    With ``record = (t_s, ω)`` panel (a) shows the whole record (Morris: 2.56 s) as integrated before any
    filtering, with cursors at the cycle's start and end; else the cycle before the drift filter.
    """
    fig = Figure(figsize=(8, 5.5))
    axes = fig.subplots(2, 1, sharex=record is None)
    t_a, w_a = (t_s, omega_raw_rad_s) if record is None else record
    title_a = "(a) as integrated" if record is None else "(a) the record as integrated, cursors at the cycle"
    for ax, tt, data, title in ((axes[0], t_a, w_a, title_a), (axes[1], t_s, omega_filtered_rad_s,
                                                               "(b) the cycle, drift removed")):
        ax.plot(tt, data[:, 0], label="coronal (about axis 1)")
        ax.plot(tt, data[:, 1], label="sagittal (about axis 2)")
        if truth_rad_s is not None and tt is t_s:
            ax.plot(t_s, truth_rad_s[:, 0], "k:", lw=1, label="truth")
            ax.plot(t_s, truth_rad_s[:, 1], "k:", lw=1)
        ax.set_ylabel("rad/s")
        ax.set_title(f"Angular velocity {title}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.set_xlabel("time (s)")
    if record is not None:
        for x in (t_s[0], t_s[-1]):
            axes[0].axvline(x, color="k", lw=0.8, ls="--")
    axes[0].legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    _save(fig, path)


def plot_dcm(
    t_s: np.ndarray, dcm: np.ndarray, path: str | os.PathLike[str], *, truth: np.ndarray | None = None
) -> None:
    """Fig 5: the direction-cosine matrix ``λpq`` over one cycle, one panel per element."""
    fig = Figure(figsize=(8, 6.5))
    axes = fig.subplots(3, 3, sharex=True, sharey=True)
    for p in range(3):
        for q in range(3):
            ax = axes[p, q]
            ax.plot(t_s, dcm[:, p, q])
            if truth is not None:
                ax.plot(t_s, truth[:, p, q], "k:", lw=1)
            ax.set_title(f"λ{p + 1}{q + 1}", fontsize=9)
            ax.set_ylim(-1.05, 1.05)
            ax.grid(alpha=0.3)
    for q in range(3):
        axes[2, q].set_xlabel("time (s)")
    fig.suptitle("Direction cosines of the shank over one cycle (dotted: truth)", fontsize=10)
    fig.tight_layout()
    _save(fig, path)


def plot_translation(
    t_s: np.ndarray,
    acc_m_s2: np.ndarray,
    vel_m_s: np.ndarray,
    pos_m: np.ndarray,
    path: str | os.PathLike[str],
    *,
    truth: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> None:
    """Fig 6: translational acceleration, velocity and position of the mid-shank origin (space axes)."""
    fig = Figure(figsize=(10, 6.5))
    axes = fig.subplots(3, 3, sharex=True)
    cols = ((acc_m_s2, "acceleration (m/s²)"), (vel_m_s, "velocity (m/s)"), (pos_m, "position (m)"))
    for c, (data, label) in enumerate(cols):
        for r in range(3):
            ax = axes[r, c]
            ax.plot(t_s, data[:, r])
            if truth is not None:
                ax.plot(t_s, truth[c][:, r], "k:", lw=1)
            ax.grid(alpha=0.3)
            if r == 0:
                ax.set_title(label, fontsize=10)
            if c == 0:
                ax.set_ylabel(_AXIS_NAMES[r], fontsize=9)
        axes[2, c].set_xlabel("time (s)")
    fig.suptitle("Translation of the mid-shank origin (dotted: truth)", fontsize=10)
    fig.tight_layout()
    _save(fig, path)


def stick_figure_points(
    dcm: np.ndarray,
    origin_m: np.ndarray,
    origin_from_ankle_m: np.ndarray,
    *,
    shank_length_m: float = 0.42,
    heel_m: float = 0.06,
    toe_m: float = 0.18,
    sole_m: float = 0.07,
) -> dict[str, np.ndarray]:
    """Sagittal (x, z) points of ankle, knee, heel and toe for each frame.

    The foot lies perpendicular to the shank, ``sole_m`` below the ankle, from ``heel_m`` behind to ``toe_m``
    in front of it; if the toe would go below the ground (the lowest heel excursion over all frames) the
    foot is rotated about the ankle to put the toe on the ground (Morris' simulated ankle articulation).

    Returns
    -------
    dict
        ``ankle``, ``knee``, ``heel``, ``toe``: ``(n, 2)`` arrays of (forwards, vertical) in m.
    """
    lam = np.asarray(dcm, dtype=np.float64)
    o = np.asarray(origin_m, dtype=np.float64)
    ankle3 = o - lam @ np.asarray(origin_from_ankle_m, dtype=np.float64)
    knee3 = ankle3 + lam[:, :, 2] * shank_length_m
    ankle = ankle3[:, [0, 2]]
    knee = knee3[:, [0, 2]]
    s = knee - ankle
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    d = np.stack([s[:, 1], -s[:, 0]], axis=1)  # perpendicular, forwards
    heel = ankle - heel_m * d - sole_m * s
    toe = ankle + toe_m * d - sole_m * s
    ground = heel[:, 1].min()
    low = toe[:, 1] < ground
    if np.any(low):
        # rotate the foot about the ankle (dorsiflexion) until the toe is on the ground
        rel = toe[low] - ankle[low]
        radius = np.linalg.norm(rel, axis=1)
        target_z = ground - ankle[low, 1]
        ok = np.abs(target_z) <= radius
        ang_now = np.arctan2(rel[:, 1], rel[:, 0])
        ang_new = np.where(ok, np.arcsin(np.clip(target_z / radius, -1, 1)), ang_now)
        turn = ang_new - ang_now
        c, sn = np.cos(turn), np.sin(turn)
        for pts in (toe, heel):
            r = pts[low] - ankle[low]
            pts[low] = ankle[low] + np.stack([c * r[:, 0] - sn * r[:, 1], sn * r[:, 0] + c * r[:, 1]], axis=1)
    return {"ankle": ankle, "knee": knee, "heel": heel, "toe": toe}


def plot_stick_figure(
    t_s: np.ndarray,
    dcm: np.ndarray,
    origin_m: np.ndarray,
    origin_from_ankle_m: np.ndarray,
    path: str | os.PathLike[str],
    *,
    frame_rate_hz: float = 12.5,
    truth: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Fig 7: multiple exposure of shank and foot over the cycle, one exposure per ``1/frame_rate_hz`` s."""
    t = np.asarray(t_s, dtype=np.float64)
    frames = np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 1.0 / frame_rate_hz))
    frames = frames[frames < t.size]
    fig = Figure(figsize=(9, 4))
    ax = fig.subplots()
    sets = [(dcm, origin_m, "C0", 1.2, "estimated")]
    if truth is not None:
        sets.append((truth[0], truth[1], "0.6", 0.8, "truth"))
    for lam, org, colour, lw, label in sets:
        pts = stick_figure_points(lam, org, origin_from_ankle_m)
        for i, k in enumerate(frames):
            xs = [pts["knee"][k, 0], pts["ankle"][k, 0], pts["heel"][k, 0], pts["toe"][k, 0], pts["ankle"][k, 0]]
            zs = [pts["knee"][k, 1], pts["ankle"][k, 1], pts["heel"][k, 1], pts["toe"][k, 1], pts["ankle"][k, 1]]
            ax.plot(xs, zs, color=colour, lw=lw, label=label if i == 0 else None)
    ax.set_aspect("equal")
    ax.set_xlabel("forwards (m)")
    ax.set_ylabel("vertical (m)")
    ax.set_title(f"Multiple exposure of the shank and foot, {frame_rate_hz:g} frames/s", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _save(fig, path)


def _body_model() -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """Morris' 26 points (segment frame, m, relative to the ankle), the foot mask and the drawn edges."""
    length = 0.42
    ring = np.radians(np.arange(8) * 45.0)
    knee = np.stack([0.05 * np.cos(ring), 0.05 * np.sin(ring), np.full(8, length)], axis=1)
    ankle_ring = np.stack([0.035 * np.cos(ring), 0.03 * np.sin(ring), np.full(8, 0.04)], axis=1)
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, length]])
    foot = np.array([[-0.06, 0.03, -0.07], [-0.06, -0.03, -0.07],  # heel
                     [0.18, 0.04, -0.07], [0.18, -0.04, -0.07],  # toe
                     [0.12, 0.045, -0.035], [0.12, -0.045, -0.035],  # ball, top
                     [0.03, 0.035, -0.01], [0.03, -0.035, -0.01]])  # instep
    pts = np.concatenate([centres, knee, ankle_ring, foot])
    is_foot = np.zeros(26, dtype=bool)
    is_foot[18:] = True
    edges = [(0, 1)] + [(2 + i, 2 + (i + 1) % 8) for i in range(8)] + [(10 + i, 10 + (i + 1) % 8) for i in range(8)]
    edges += [(2 + i, 10 + i) for i in range(0, 8, 2)]
    edges += [(18, 19), (20, 21), (18, 20), (19, 21), (20, 22), (21, 23), (22, 24), (23, 25), (24, 25), (24, 18),
              (25, 19), (22, 23)]
    return pts, is_foot, edges


#: The 26 points of Morris' shank-and-foot model in the segment frame (m, ankle at 0; axis 1 anterior,
#: 2 left, 3 up the shank): the ankle and knee centres, an 8-point ring at the knee and above the ankle,
#: 8 points of the foot (heel, toe, ball, instep; left and right).
BODY_MODEL_POINTS_M, _IS_FOOT, _EDGES = _body_model()


def body_model_points(dcm: np.ndarray, origin_m: np.ndarray, origin_from_ankle_m: np.ndarray) -> np.ndarray:
    """Space positions ``(n, 26, 3)`` of the model, moved by orientation ``dcm`` and the origin's position.

    The foot is kept perpendicular to the shank, except that it is turned about the ankle's left-right axis
    (body axis 2) just enough to keep the toe from going below the ground, a level at the lowest heel
    excursion over all frames -- Morris' simulated ankle articulation.
    """
    lam = np.asarray(dcm, dtype=np.float64)
    ankle = np.asarray(origin_m, dtype=np.float64) - lam @ np.asarray(origin_from_ankle_m, dtype=np.float64)
    pts = np.einsum("nij,pj->npi", lam, BODY_MODEL_POINTS_M) + ankle[:, None, :]
    ground = pts[:, 18:20, 2].min()  # the lowest heel excursion
    toe = pts[:, 20:22].mean(axis=1) - ankle  # v = toe − ankle
    u = lam[:, :, 1]  # rotation axis: body axis 2 in space
    uv = np.einsum("ni,ni->n", u, toe)
    a = toe[:, 2] - u[:, 2] * uv
    b = np.cross(u, toe)[:, 2]
    d = ground - ankle[:, 2] - u[:, 2] * uv
    low = (toe[:, 2] + ankle[:, 2] < ground) & (np.hypot(a, b) >= np.abs(d))
    if np.any(low):
        base = np.arctan2(b, a)
        spread = np.arccos(np.clip(d / np.where(low, np.hypot(a, b), 1.0), -1.0, 1.0))
        cands = np.stack([base + spread, base - spread], axis=1)
        cands = (cands + np.pi) % (2 * np.pi) - np.pi
        beta = np.where(low, cands[np.arange(cands.shape[0]), np.argmin(np.abs(cands), axis=1)], 0.0)
        c, s = np.cos(beta)[:, None, None], np.sin(beta)[:, None, None]
        v = pts[:, _IS_FOOT] - ankle[:, None, :]
        uu = u[:, None, :]
        rot = v * c + np.cross(uu, v) * s + uu * np.einsum("npi,nqi->npq", v, uu) * (1 - c)
        pts[:, _IS_FOOT] = np.where(low[:, None, None], ankle[:, None, :] + rot, pts[:, _IS_FOOT])
    return pts


def project_view(points_m: np.ndarray, azimuth_deg: float = 0.0, elevation_deg: float = 0.0) -> np.ndarray:
    """Orthographic view ``(..., 2)`` of space points ``(..., 3)`` (axis 1 forwards, 3 up).

    Azimuth 0, elevation 0 looks at the subject's right side, forwards to the right (the sagittal plane);
    azimuth turns the viewer about the vertical (90: from behind), elevation raises it (90: from above).

    Examples
    --------
    >>> project_view(np.array([1.0, 2.0, 3.0]))
    array([1., 3.])
    """
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    right = np.array([np.cos(az), np.sin(az), 0.0])
    toward = np.cos(el) * np.array([np.sin(az), -np.cos(az), 0.0]) + np.sin(el) * np.array([0.0, 0.0, 1.0])
    up = np.cross(toward, right)
    p = np.asarray(points_m, dtype=np.float64)
    return np.stack([p @ right, p @ up], axis=-1)


def _frames(t_s: np.ndarray, frame_rate_hz: float) -> np.ndarray:
    t = np.asarray(t_s, dtype=np.float64)
    idx = np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 1.0 / frame_rate_hz))
    return idx[idx < t.size]


def _draw_model(ax, xy: np.ndarray, colour: str, lw: float, label: str | None = None) -> list:
    lines = []
    for i, (a, b) in enumerate(_EDGES):
        lines += ax.plot(xy[[a, b], 0], xy[[a, b], 1], color=colour, lw=lw, label=label if i == 0 else None)
    lines += ax.plot(xy[:, 0], xy[:, 1], ".", color=colour, ms=2.5)
    return lines


def plot_body_model(
    t_s: np.ndarray, dcm: np.ndarray, origin_m: np.ndarray, origin_from_ankle_m: np.ndarray,
    path: str | os.PathLike[str], *, azimuth_deg: float = 0.0, elevation_deg: float = 0.0,
    frame_rate_hz: float = 12.5,
) -> None:
    """Fig 7 as published: multiple exposure of the 26-point model at ``frame_rate_hz`` (Morris: 12.5/s)."""
    xy = project_view(body_model_points(dcm, origin_m, origin_from_ankle_m), azimuth_deg, elevation_deg)
    fig = Figure(figsize=(9, 4.5))
    ax = fig.subplots()
    for k in _frames(t_s, frame_rate_hz):
        _draw_model(ax, xy[k], "C0", 0.7)
    ax.set_aspect("equal")
    ax.set_xlabel("m")
    ax.set_ylabel("m")
    ax.set_title(f"Multiple exposure of the 26-point shank and foot, {frame_rate_hz:g} frames/s "
                 f"(azimuth {azimuth_deg:g}°, elevation {elevation_deg:g}°)", fontsize=9)
    ax.grid(alpha=0.3)
    _save(fig, path)


def write_body_model_gif(
    t_s: np.ndarray, dcm: np.ndarray, origin_m: np.ndarray, origin_from_ankle_m: np.ndarray,
    path: str | os.PathLike[str], *, azimuth_deg: float = 0.0, elevation_deg: float = 0.0,
    frame_rate_hz: float = 12.5, dpi: int = 60,
) -> int:
    """The "true-speed moving picture": one GIF frame per ``1/frame_rate_hz`` s of the recording (returns
    the number of frames). Written to a temporary file beside ``path`` and renamed into place."""
    xy = project_view(body_model_points(dcm, origin_m, origin_from_ankle_m), azimuth_deg, elevation_deg)
    frames = _frames(t_s, frame_rate_hz)
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    lo, hi = xy.reshape(-1, 2).min(axis=0) - 0.05, xy.reshape(-1, 2).max(axis=0) + 0.05
    out = Path(path)
    tmp = out.with_name(f".{out.name}.tmp.gif")
    writer = PillowWriter(fps=frame_rate_hz)
    try:
        with writer.saving(fig, str(tmp), dpi):
            for k in frames:
                ax.clear()
                ax.set_xlim(lo[0], hi[0])
                ax.set_ylim(lo[1], hi[1])
                ax.set_aspect("equal")
                ax.set_title(f"t = {float(np.asarray(t_s)[k]):.2f} s", fontsize=9)
                _draw_model(ax, xy[k], "C0", 1.0)
                writer.grab_frame()
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return int(frames.size)


def plot_joint_angles(
    t_s: np.ndarray, angles_rad: np.ndarray, path: str | os.PathLike[str], *, truth_rad: np.ndarray | None = None,
    sequence: str = "yxz",
) -> None:
    """Hall: the three joint angles (degrees) against time, with the truth dotted; ``sequence`` names them."""
    fig = Figure(figsize=(7, 6))
    axes = fig.subplots(3, 1, sharex=True)
    names = (("flexion φ (about y)", "version θ (about x′)", "axial rotation ψ (about z″)") if sequence == "yxz"
             else ("tilt (about x)", "rotation (about z′)", "flexion (about y″)"))
    for i, ax in enumerate(axes):
        ax.plot(np.asarray(t_s) * 1e3, np.degrees(angles_rad[:, i]), label="angular-rate sensors")
        if truth_rad is not None:
            ax.plot(np.asarray(t_s) * 1e3, np.degrees(truth_rad[:, i]), "k:", lw=1, label="truth")
        ax.set_ylabel(f"{names[i]}\n(deg)", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("time (ms)")
    fig.suptitle(f"Joint angles, {sequence[0]}-{sequence[1]}'-{sequence[2]}'' sequence", fontsize=10)
    fig.tight_layout()
    _save(fig, path)
