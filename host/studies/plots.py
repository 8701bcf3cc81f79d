"""Box plots of the estimated/real distance ratio per estimator, in the manner of Alvarez et al. Figs 5-6.

One panel per calibration mode: single-speed (M1-M4; M3 is never calibrated) and multi-speed (M1-M5, as
Fig. 6 adds M5). Each box is the median and quartiles of the 20 m section ratios; the whiskers reach the
extreme values (the paper plots "median, quartiles and extreme values"), so no point is drawn as an
outlier. The dashed line is 100 %. Figures are :class:`matplotlib.figure.Figure` objects
rendered straight to PNG (no pyplot, no global backend); the PNG is written atomically
(:func:`gaitlog.atomic_write.atomic_write_bytes`). Only the commands that draw import this module.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.errors import HostError
from gaitlog.host.files.inputs import read_acceleration
from gaitlog.host.gait.k_calibration import KFit
from gaitlog.host.storage.png_figure import figure_png_bytes
from gaitlog.host.studies.overview import recording_overview
from gaitlog.atomic_write import atomic_write_bytes

PANELS = (("single-speed", ESTIMATORS[:4], "Calibration at preferred speed"),
          ("multi-speed", ESTIMATORS, "Calibration at every speed"))


def ratios_by_panel(rows: Iterable[dict]) -> dict[str, dict[str, np.ndarray]]:
    """``{mode: {estimator: ratios}}`` from evaluation rows (``mode``, ``estimator``, ``ratio``)."""
    out: dict[str, dict[str, list[float]]] = {}
    for r in rows:
        out.setdefault(str(r["mode"]), {}).setdefault(str(r["estimator"]), []).append(float(r["ratio"]))
    return {m: {e: np.asarray(v, np.float64)[np.isfinite(v)] for e, v in d.items()} for m, d in out.items()}


def render_boxplots_png(rows: Sequence[dict], *, title: str | None = None, dpi: int = 120) -> bytes:
    """The figure as PNG bytes (raises ValueError when no panel has data)."""
    data = ratios_by_panel(rows)
    panels = [(mode, [e for e in ests if data.get(mode, {}).get(e, np.zeros(0)).size], label)
              for mode, ests, label in PANELS]
    panels = [p for p in panels if p[1]]
    if not panels:
        raise ValueError("no section ratios to plot")
    fig = Figure(figsize=(4.2 * len(panels), 4.2))
    axes = fig.subplots(1, len(panels), sharey=True, squeeze=False)
    for ax, (mode, ests, label) in zip(axes[0], panels):
        values = [100.0 * data[mode][e] for e in ests]
        ax.boxplot(values, whis=(0, 100), widths=0.5, medianprops={"color": "k"})
        ax.set_xticks(range(1, len(ests) + 1), [e + (" (no K)" if e == "M3" else "") for e in ests],
                      fontsize=8)
        ax.axhline(100.0, color="0.5", linestyle="--", linewidth=0.8)
        n = min(v.size for v in values)
        ax.set_title(f"{label}\n({mode}, {n} sections)", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].set_ylabel("estimated / real distance (%)")
    if title:
        fig.suptitle(title, fontsize=10)
    return figure_png_bytes(fig, dpi=dpi)


def plot_boxplots(rows: Sequence[dict], path: str | Path, *, title: str | None = None, dpi: int = 120) -> Path:
    """Write the Figs 5-6 style box plots of ``rows`` (see :mod:`gaitlog.host.studies.evaluation`) to ``path`` (PNG)."""
    png = render_boxplots_png(rows, title=title, dpi=dpi)
    atomic_write_bytes(path, png)
    return Path(path)


def render_chain_boxplots_png(rows: Sequence[dict], chains: Sequence[str], *, title: str | None = None,
                              dpi: int = 120) -> bytes:
    """Box plots of per-trial ratios (``estimator``, ``arithmetic``, ``k_from``, ``ratio`` rows of
    :mod:`gaitlog.host.studies.ipol_evaluation`): one box per chain side by side for each estimator, the rows with the offline
    chain's K only (the comparison). Raises ValueError when there is nothing to plot."""
    ests = ESTIMATORS
    data = {(a, e): np.asarray([float(r["ratio"]) for r in rows if r["estimator"] == e and r["arithmetic"] == a
                                and r.get("k_from", "offline") == "offline"], np.float64) for a in chains for e in ests}
    data = {k: v[np.isfinite(v)] for k, v in data.items()}
    if not any(v.size for v in data.values()):
        raise ValueError("no ratios to plot")
    fig = Figure(figsize=(7.5, 4.0))
    ax = fig.subplots()
    width = 0.8 / len(chains)
    for j, a in enumerate(chains):
        pos = [i + 1 + (j - (len(chains) - 1) / 2) * width for i in range(len(ests))]
        bp = ax.boxplot([100.0 * data[(a, e)] for e in ests], positions=pos, widths=0.9 * width, whis=(0, 100),
                        patch_artist=True, manage_ticks=False, medianprops={"color": "k"})
        for box in bp["boxes"]:
            box.set_facecolor(f"C{j}")
            box.set_alpha(0.5)
        ax.plot([], [], color=f"C{j}", lw=6, alpha=0.5, label=a)
    ax.set_xticks(range(1, len(ests) + 1), [e + (" (no K)" if e == "M3" else "") for e in ests], fontsize=8)
    ax.axhline(100.0, color="0.5", linestyle="--", linewidth=0.8)
    ax.set_ylabel("estimated / real distance (%)")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    if title:
        ax.set_title(title, fontsize=9)
    return figure_png_bytes(fig, dpi=dpi)


#: Colour and marker of each event of the overview (:data:`gaitlog.host.studies.overview.EVENTS`).
_EVENT_STYLE = {"foot-flat": ("C3", "v"), "heel-strike": ("C0", "^"), "toe-off": ("C2", "o"),
                "device step": ("k", "|")}


def render_overview_png(overview, *, size_px: tuple[int, int] = (1400, 700), dpi: int = 100) -> bytes:
    """The overview of a recording's window (:class:`gaitlog.host.studies.overview.RecordingOverview`) as PNG bytes of
    exactly ``size_px`` (width, height) pixels: the acceleration (x, y, z in g) with the gaps shaded, the lap
    marks as vertical lines and the events as markers on the top panel; each step's length per estimator
    (offline chain filled markers, the device's records open markers) on the bottom panel."""
    width, height = size_px
    fig = Figure(figsize=(width / dpi, height / dpi))
    ax, ax_len = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    t, acc = overview.time_s, overview.acc_g
    for k, axis in enumerate("xyz"):
        ax.plot(t, acc[:, k], lw=0.6, color=f"C{k + 4}", label=f"{axis} (g)")
    for a, b in overview.gaps_s:
        for axes in (ax, ax_len):
            axes.axvspan(a, b, color="0.6", alpha=0.35, lw=0)
    for m in overview.marks_s:
        for axes in (ax, ax_len):
            axes.axvline(m, color="m", lw=0.8, ls="--")
    top = np.nanmax(acc) if np.isfinite(acc).any() else 1.0
    for j, (name, times) in enumerate(overview.events_s.items()):
        color, marker = _EVENT_STYLE[name]
        if times.size:
            ax.plot(times, np.full(times.size, top + 0.15 * (j + 1)), ls="none", marker=marker, color=color, ms=4,
                    label=name)
    if overview.gaps_s:
        ax.plot([], [], color="0.6", alpha=0.35, lw=6, label="missing")
    if overview.marks_s.size:
        ax.plot([], [], color="m", lw=0.8, ls="--", label="lap mark")
    ax.set_ylabel("acceleration (g)")
    ax.legend(fontsize=7, loc="upper right", ncol=4)
    ax.grid(alpha=0.3)
    ax.set_title(f"{overview.source}: {overview.window_s[0]:g}-{overview.window_s[1]:g} s", fontsize=9)
    for label, (times, lengths) in overview.lengths_m.items():
        if not times.size:
            continue
        device = label.endswith("device")
        color = f"C{ESTIMATORS.index(label.split()[0])}"
        kind = overview.length_kinds.get(label)                  # calibrated (K) or raw: said in the legend
        ax_len.plot(times, lengths, ls="none", marker="o", ms=3, color=color,
                    label=f"{label.split()[0]} {kind}" if kind else label,
                    markerfacecolor="none" if device else color)
    ax_len.set_ylabel("step length (m)")
    ax_len.set_xlabel("time since the first sample (s)")
    if any(times.size for times, _ in overview.lengths_m.values()):
        ax_len.legend(fontsize=7, loc="upper right", ncol=5)
    ax_len.grid(alpha=0.3)
    ax_len.set_xlim(*overview.window_s)
    return figure_png_bytes(fig, dpi=dpi)


def plot_recording(src: str | Path, out: str | Path, *, k_file: str | None, lengths_for, start_s: float | None,
                   duration_s: float | None, estimators: Sequence[str], size_px: tuple[int, int]) -> str:
    """``gaitlog plot``: the overview of the logger recording at ``src`` written as a PNG of ``size_px`` to
    ``out`` (:func:`gaitlog.host.studies.overview.recording_overview` with ``k_file``'s K, else none, and the
    lengths ``lengths_for(k, data)`` gives); the line that says what it shows.

    Raises
    ------
    HostError
        ``src`` is not a logger recording (acceleration in g has no codes to replay).
    """
    data = read_acceleration(src)
    if data.recording is None:
        raise HostError(f"{src}: plot draws a logger recording (memory image, raw dump, wire capture or decoded "
                        f".npz); this is {data.source}: record it first (gaitlog record --motion replay)")
    rec = data.recording
    k_fit = KFit.load(k_file) if k_file else None
    lengths = lengths_for(k_fit, data)
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    overview = recording_overview(rec, leg_length_m=leg, foot_length_m=foot, k_fit=k_fit, start_s=start_s,
                                  duration_s=duration_s, estimators=estimators)
    atomic_write_bytes(out, render_overview_png(overview, size_px=size_px))
    ev = ", ".join(f"{v.size} {k}" for k, v in overview.events_s.items() if v.size or k != "device step")
    return (f"{out}: {overview.window_s[0]:g}-{overview.window_s[1]:g} s of {src} ({overview.time_s.size} samples, "
            f"{len(overview.gaps_s)} gap(s), {overview.marks_s.size} lap mark(s)); {ev}; leg {leg:.3f} m, "
            f"foot {foot:.3f} m" + (f" ({lengths.note})" if lengths.note else ""))
