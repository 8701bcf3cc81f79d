"""Figures of a parameter sweep (``gaitlog sweep``): error vs ADC bits, vs rate, vs Q format (and vs any other
swept dimension), with intervals over subjects.

One figure per swept dimension with more than one value; the other dimensions are held at their reference
(:func:`gaitlog.host.studies.sweep_grid.reference`: 10 bits, 50 Hz, the sensor's noise, the shipped Q formats, no extra
misalignment, the default population, when swept). One line per estimator (multi-speed K); each point is the
median over subjects, its bar the range over subjects (each subject's own per-step median, or section-ratio
median):

* ADC share, per-step median ``|offline - ideal|``, mm;
* arithmetic share, per-step median ``|online-fixed - online-float|``, mm (what the Q formats cost);
* the offline chain's section ratio estimated / real, % (vs Q format: the on-line fixed-point chain's, pooled
  median only);
* vs rate only: what the step timing adds to M5's section-ratio spread
  (:func:`gaitlog.host.studies.sweep_grid.m5_rate_answer`), with its range over subjects.

The dashed lines are the tolerances of the printed answers (1 mm; 1 %). Rendered straight to PNG (no pyplot);
only ``gaitlog sweep`` imports this module.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.storage.png_figure import figure_png_bytes
from gaitlog.host.studies.sweep_grid import (
    DEFAULT_POPULATION,
    EFFECT_DIMENSIONS,
    M4_EXPONENT,
    RATIO_TOLERANCE,
    SENSOR_NOISE_G_RTHZ,
    STEP_TOLERANCE_MM,
    SUMMARY_KEYS,
    reference,
    with_effects,
)

__all__ = ["DIMENSIONS", "figure_dimensions", "render_error_vs_png"]

#: Each dimension's axis label and preferred reference value.
DIMENSIONS = {"adc_bits": ("ADC width, bits", 10), "sampling_rate_hz": ("logger sampling rate, Hz", 50.0),
              "noise_density_g_rthz": ("sensor noise density, µg/√Hz", SENSOR_NOISE_G_RTHZ),
              "q_formats": ("Q formats of the fixed-point chain", "shipped"),
              "rounding": ("rounding of the fixed-point chain", "shipped"),
              "misalignment_deg": ("extra mounting tilt, degrees", 0.0),
              "m4_exponent": ("M4's exponent p", M4_EXPONENT),
              "population": ("simulated population", DEFAULT_POPULATION),
              **{k: (f"{label}, {EFFECT_DIMENSIONS[k][1]}", 0.0) for k, label in (
                  ("inl_lsb", "converter INL"), ("dnl_lsb", "converter DNL"), ("adc_offset_lsb", "converter offset"),
                  ("adc_gain_error_lsb", "converter gain error"), ("acquisition_time_us", "acquisition time"),
                  ("source_impedance_ohm", "source impedance"),
                  ("source_capacitance_nf", "source capacitance"), ("flicker_corner_hz", "1/f corner"),
                  ("temperature_swing_c", "temperature swing"))}}
#: Dimensions that change only the on-line fixed-point chain (its section ratio is drawn, not the offline one).
_FIXED_POINT_ONLY = ("q_formats", "rounding")
#: Dimensions drawn as categories (in the grid's order), not on a numeric axis.
_CATEGORICAL = ("q_formats", "population", "rounding")


def _values(summary: list[dict], key: str) -> list:
    out: list = []
    for r in summary:
        if r.get(key, 0.0) not in out:                    # an effect missing from a row is off
            out.append(r.get(key, 0.0))
    return out


def figure_dimensions(summary: list[dict]) -> list[str]:
    """The swept dimensions (more than one value), in :data:`SUMMARY_KEYS` order."""
    return [k for k in SUMMARY_KEYS if len(_values(summary, k)) > 1]


def render_error_vs_png(summary: list[dict], dimension: str, *, m5: dict | None = None, mode: str = "multi-speed",
                        dpi: int = 110) -> bytes:
    """The figure of ``dimension`` (module notes) as PNG bytes; ``m5`` (:func:`m5_rate_answer`) adds the timing
    panel to the rate figure. Raises ValueError for an unknown dimension or one with fewer than two values."""
    if dimension not in DIMENSIONS:
        raise ValueError(f"unknown sweep dimension {dimension!r}; known: {', '.join(DIMENSIONS)}")
    xs = _values(summary, dimension)
    if len(xs) < 2:
        raise ValueError(f"{dimension}: fewer than two swept values, nothing to plot")
    held = {k: reference(_values(summary, k), DIMENSIONS[k][1]) for k in SUMMARY_KEYS if k != dimension}
    rows = [with_effects(r) for r in summary]
    rows = [r for r in rows if r["mode"] == mode and all(r[k] == v for k, v in held.items())]
    xs, pos, scale = _positions(xs, dimension)
    with_m5 = dimension == "sampling_rate_hz" and m5 is not None and bool(m5.get("rows"))
    fig = Figure(figsize=(3.4 * (len(_PANELS) + with_m5), 3.4))
    axes = fig.subplots(1, len(_PANELS) + with_m5, squeeze=False)[0]
    ests = [e for e in ESTIMATORS if any(r["estimator"] == e for r in rows)]
    width = 0.08 * (max(pos.values()) - min(pos.values()) or 1.0)
    for ax, panel in zip(axes, _PANELS, strict=False):
        for j, est in enumerate(ests):
            pts = [r for x in xs for r in rows if r[dimension] == x and r["estimator"] == est]
            x = np.array([pos[r[dimension]] for r in pts], float) + (j - (len(ests) - 1) / 2) * width / len(ests)
            _draw_estimator(ax, panel, dimension, est, pts, x)
        _finish_panel(ax, panel, dimension)
    if with_m5:
        _draw_m5_panel(axes[-1], m5)
    _label_axes(axes, dimension, xs, pos, scale)
    fig.suptitle(f"error vs {DIMENSIONS[dimension][0]} ({mode} K; median and range over subjects)\n{_held_text(held)}",
                 fontsize=8)
    return figure_png_bytes(fig, dpi=dpi)


def _positions(xs: list, dimension: str) -> tuple[list, dict, float]:
    """The swept values in plotting order (the grid's for a category, else sorted), each one's position on the x
    axis, and the axis scale (µg/√Hz for the noise)."""
    categorical = dimension in _CATEGORICAL
    if not categorical:
        xs = sorted(xs)
    scale = 1e6 if dimension == "noise_density_g_rthz" else 1.0
    return xs, {x: (i if categorical else x * scale) for i, x in enumerate(xs)}, scale


def _label_axes(axes: Any, dimension: str, xs: list, pos: dict, scale: float) -> None:
    """Every panel's x label, ticks (the swept values) and grid; the estimators' legend on the first."""
    for ax in axes:
        ax.set_xlabel(DIMENSIONS[dimension][0], fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if dimension in _CATEGORICAL:
            ax.set_xticks(range(len(xs)), [str(x) for x in xs], rotation=30, ha="right")
        else:
            ax.set_xticks([pos[x] for x in xs], [f"{x * scale:g}" for x in xs])
    axes[0].legend(fontsize=7)


def _held_text(held: dict) -> str:
    """The dimensions held at their reference, for the title (the converter's and sensor's effects when on)."""
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) and not math.isnan(v) else f"{k}={v}"
                     for k, v in held.items() if k not in EFFECT_DIMENSIONS or v != 0.0)


#: The panels of every figure: summary column, title, tolerance line (None: the real distance), scale.
_PANELS = (("adc_step_mm", "ADC share |offline − ideal|, mm/step (x: theory)", STEP_TOLERANCE_MM, 1.0),
           ("arith_step_mm", "arithmetic share |fixed − float|, mm/step (x: theory)", STEP_TOLERANCE_MM, 1.0),
           ("subject_median_offline", "offline section ratio, % of real", None, 100.0))


def _draw_estimator(ax: Any, panel: tuple, dimension: str, est: str, pts: list[dict], x: np.ndarray) -> None:
    """One estimator's points ``pts`` (at ``x``) on a panel of :data:`_PANELS`: median and range over subjects,
    and the quantisation theory's prediction as crosses on the shares' panels."""
    col, _, _, k = panel
    if col == "subject_median_offline" and dimension in _FIXED_POINT_ONLY:      # only the fixed chain changes
        mid = [k * r["median_online_fixed"] for r in pts]
        lo = hi = mid
    else:
        mid = [k * r["median_offline" if col == "subject_median_offline" else col] for r in pts]
        lo = [k * r[f"{col}_lo"] for r in pts]
        hi = [k * r[f"{col}_hi"] for r in pts]
    m, lo_, hi_ = (np.array(v, float) for v in (mid, lo, hi))
    err = np.vstack([np.clip(m - lo_, 0, None), np.clip(hi_ - m, 0, None)])
    ax.errorbar(x, m, yerr=np.where(np.isfinite(err), err, 0.0), marker="o", ms=3, lw=1, capsize=2,
                color=f"C{ESTIMATORS.index(est)}", label=est)
    if col in ("adc_step_mm", "arith_step_mm"):                   # the quantisation theory beside it
        theory = np.array([k * r.get(f"{col}_theory", np.nan) for r in pts], float)
        ax.plot(x, np.where(theory > 0, theory, np.nan), ls=":", marker="x", ms=4, lw=1,
                color=f"C{ESTIMATORS.index(est)}")


def _finish_panel(ax: Any, panel: tuple, dimension: str) -> None:
    """A panel's tolerance line (log scale for the shares; 100 % for the ratio) and title."""
    col, label, tol, _ = panel
    if tol is not None:
        ax.axhline(tol, color="0.4", ls="--", lw=0.8)
        ax.set_yscale("log")
    else:
        ax.axhline(100.0, color="0.4", ls="--", lw=0.8)
    ax.set_title(label.replace("offline", "on-line fixed-point") if col == "subject_median_offline"
                 and dimension in _FIXED_POINT_ONLY else label, fontsize=8)


def _draw_m5_panel(ax: Any, m5: dict) -> None:
    """The rate figure's last panel: what the step timing adds to M5's spread per mode (:func:`m5_rate_answer`)."""
    for j, mode_ in enumerate(("single-speed", "multi-speed")):
        rs = sorted((r for r in m5["rows"] if r["mode"] == mode_), key=lambda r: r["sampling_rate_hz"])
        if not rs:
            continue
        m = np.array([100 * r["timing_part"] for r in rs])
        lo = np.array([100 * r["timing_part_lo"] for r in rs])
        hi = np.array([100 * r["timing_part_hi"] for r in rs])
        err = np.vstack([np.clip(m - lo, 0, None), np.clip(hi - m, 0, None)])
        ax.errorbar([r["sampling_rate_hz"] for r in rs], m, yerr=np.where(np.isfinite(err), err, 0.0),
                    marker="s", ms=3, lw=1, capsize=2, color=f"C{5 + j}", label=mode_)
    ax.axhline(100 * RATIO_TOLERANCE, color="0.4", ls="--", lw=0.8)
    ax.set_title("M5: what the step timing adds to the spread, %", fontsize=8)
    ax.legend(fontsize=7)
