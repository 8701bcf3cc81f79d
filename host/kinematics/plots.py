"""Figures in the spirit of Morris (1973) Figs 4-7 and of Hall et al. (1997), written atomically as PNG.

- :func:`plot_angular_velocity` -- Fig 4a/b: coronal and sagittal angular velocity before and after the
  cycle drift filter;
- :func:`plot_dcm` -- Fig 5: the nine direction cosines over one cycle;
- :func:`plot_translation` -- Fig 6: translational acceleration, velocity and position (rows: forwards,
  sideways, vertical);
- :func:`plot_stick_figure` -- Fig 7: a multiple exposure of shank and foot in the sagittal plane at
  12.5 frames/s (the foot is kept perpendicular to the shank, and the toe is kept above a ground line
  drawn at the lowest heel excursion, as in Morris' simulation);
- :func:`plot_joint_angles` -- Hall: joint angles against the truth.

Figures are :class:`matplotlib.figure.Figure` objects rendered straight to PNG (no pyplot, no global backend:
importing this module changes nothing for a program that uses matplotlib itself); every figure goes through
:func:`protocol.atomic_write.atomic_write_bytes`. Only ``gaitlog kinematics`` imports this module.
"""

from __future__ import annotations

import io
import os

import numpy as np
from matplotlib.figure import Figure

from protocol.atomic_write import atomic_write_bytes

__all__ = [
    "plot_angular_velocity",
    "plot_dcm",
    "plot_joint_angles",
    "plot_stick_figure",
    "plot_translation",
    "stick_figure_points",
]

_AXIS_NAMES = ("forwards-backwards", "sideways", "vertical")


def _save(fig: Figure, path: str | os.PathLike[str]) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write_bytes(path, buf.getvalue())


def plot_angular_velocity(
    t_s: np.ndarray,
    omega_raw_rad_s: np.ndarray,
    omega_filtered_rad_s: np.ndarray,
    path: str | os.PathLike[str],
    *,
    truth_rad_s: np.ndarray | None = None,
) -> None:
    """Fig 4a/b: coronal (body axis 1) and sagittal (body axis 2) angular velocity, before/after filtering."""
    fig = Figure(figsize=(8, 5.5))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, data, title in ((axes[0], omega_raw_rad_s, "(a) as integrated"), (axes[1], omega_filtered_rad_s, "(b) cycle drift removed")):
        ax.plot(t_s, data[:, 0], label="coronal (about axis 1)")
        ax.plot(t_s, data[:, 1], label="sagittal (about axis 2)")
        if truth_rad_s is not None:
            ax.plot(t_s, truth_rad_s[:, 0], "k:", lw=1, label="truth")
            ax.plot(t_s, truth_rad_s[:, 1], "k:", lw=1)
        ax.set_ylabel("rad/s")
        ax.set_title(f"Angular velocity {title}", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[1].set_xlabel("time (s)")
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


def plot_joint_angles(
    t_s: np.ndarray, angles_rad: np.ndarray, path: str | os.PathLike[str], *, truth_rad: np.ndarray | None = None
) -> None:
    """Hall: flexion φ, version θ and axial rotation ψ (degrees) against time, with the truth dotted."""
    fig = Figure(figsize=(7, 6))
    axes = fig.subplots(3, 1, sharex=True)
    names = ("flexion φ (about y)", "version θ (about x′)", "axial rotation ψ (about z″)")
    for i, ax in enumerate(axes):
        ax.plot(np.asarray(t_s) * 1e3, np.degrees(angles_rad[:, i]), label="angular-rate sensors")
        if truth_rad is not None:
            ax.plot(np.asarray(t_s) * 1e3, np.degrees(truth_rad[:, i]), "k:", lw=1, label="truth")
        ax.set_ylabel(f"{names[i]}\n(deg)", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("time (ms)")
    fig.suptitle("Joint angles, y-x'-z'' sequence", fontsize=10)
    fig.tight_layout()
    _save(fig, path)
