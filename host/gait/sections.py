"""Lap sections: the stretches of a walk between two lap marks, and which steps fall in each.

* :func:`sections_from_marks` pairs the recording's MARK samples with lap distances -- a protocol's lap
  table (excursions, distances, speed labels) or, without one, consecutive marks ``lap_m`` apart -- and
  cuts sections of ``section_m``.
* :func:`section_fractions` weighs each step of a step table in a section (overlapping fraction of its
  window, or whole steps by window midpoint, as counting steps between stopwatch laps).
* :func:`calibration_sets` chooses the sections K is calibrated on in both modes, and :func:`pool_steps`
  pools the steps of a run of sections with their real distance (the input of
  :func:`gaitlog.host.gait.k_calibration.calibrate`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np

from gaitlog.firmware_sim.sampling import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.host.errors import HostError

if TYPE_CHECKING:  # pragma: no cover
    from gaitlog.firmware_sim.algorithms.steps import StepTable

__all__ = ["MODES", "Section", "calibration_sets", "pool_steps", "section_fractions", "sections_from_marks"]

#: The two K-calibration modes: the keys of :func:`calibration_sets` (one speed, or every speed).
MODES = ("single-speed", "multi-speed")


@dataclass(frozen=True)
class Section:
    """One stretch between two lap marks (times on the recording clock, distances along the corridor)."""

    excursion: int
    speed_label: str
    index: int
    start_m: float
    end_m: float
    t_start_s: float
    t_end_s: float
    turn: bool

    @property
    def real_m(self) -> float:
        """Real distance (corridor) of the section."""
        return self.end_m - self.start_m


def sections_from_marks(mark_times_s: np.ndarray, laps: Mapping[str, Sequence] | None = None, *,
                        corridor_length_m: float = 100.0, section_m: float = 20.0, lap_m: float | None = None,
                        sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ) -> list[Section]:
    """Pair the MARK samples with lap distances and cut ``section_m`` sections.

    Parameters
    ----------
    mark_times_s
        Times of the MARK samples on the recording clock.
    laps
        The walking plan's lap table (``time_s``, ``excursion``, ``distance_m``, ``speed_label``); each MARK
        must fall within one sample period after its lap (the firmware flags the first sample at or after
        the button press). None: the marks are consecutive laps ``lap_m`` apart (default ``section_m``),
        one excursion, no turn.
    corridor_length_m
        A section holding this distance holds the turn (``turn`` True).

    Raises
    ------
    HostError
        Marks and laps disagree.
    """
    marks = np.asarray(mark_times_s, np.float64)
    if laps is None:
        step_m = section_m if lap_m is None else lap_m
        marks = np.sort(marks)
        laps = {"time_s": marks, "excursion": np.zeros(marks.size, np.int64),
                "distance_m": step_m * np.arange(marks.size), "speed_label": np.full(marks.size, "")}
        section_m, corridor_length_m = step_m, np.inf
    t_lap = np.asarray(laps["time_s"], np.float64)
    if marks.size != t_lap.size:
        raise HostError(f"{marks.size} MARK samples for {t_lap.size} lap marks of the walking plan")
    lag = marks - t_lap
    if np.any(lag < -1e-9) or np.any(lag > 1.0 / sampling_rate_hz + 1e-9):
        k = int(np.argmax((lag < -1e-9) | (lag > 1.0 / sampling_rate_hz + 1e-9)))
        raise HostError(f"MARK {k} at {marks[k]:.3f} s does not follow lap {k} at {t_lap[k]:.3f} s")
    out: list[Section] = []
    exc = np.asarray(laps["excursion"])
    dist = np.asarray(laps["distance_m"], np.float64)
    labels = np.asarray(laps["speed_label"]).astype(str)
    for k in np.unique(exc):
        idx = np.flatnonzero(exc == k)
        j = 0
        for a, b in pairwise(idx):
            if abs(dist[b] - dist[a] - section_m) > 1e-6:
                continue
            out.append(Section(int(k), str(labels[a]), j, float(dist[a]), float(dist[b]), float(marks[a]),
                               float(marks[b]), bool(dist[a] < corridor_length_m < dist[b])))
            j += 1
    return out


def _windows(table: StepTable) -> tuple[np.ndarray, np.ndarray]:
    """Start and end time of every step's window; windowless steps get the bout's median duration."""
    end = table.time_s(table.foot_flat)
    start = table.time_s(table.start)
    dur = end - start
    med = np.nanmedian(dur) if np.any(np.isfinite(dur)) else 0.5
    start = np.where(np.isfinite(start), start, end - med)
    return start, end


def section_fractions(table: StepTable, t_start_s: float, t_end_s: float, *, edge: str = "fraction") -> np.ndarray:
    """Weight of each step of ``table`` in a section: overlapping fraction of its window, or 0/1.

    ``edge="fraction"``: the fraction of the step's window inside ``[t_start_s, t_end_s]``;
    ``edge="whole"``: 1 when the window's midpoint is inside, else 0.
    """
    a, b = _windows(table)
    if edge == "whole":
        mid = 0.5 * (a + b)
        return ((mid >= t_start_s) & (mid < t_end_s)).astype(np.float64)
    if edge != "fraction":
        raise ValueError(f"edge must be 'fraction' or 'whole', got {edge!r}")
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (np.minimum(b, t_end_s) - np.maximum(a, t_start_s)) / (b - a)
    return np.clip(np.nan_to_num(f), 0.0, 1.0)


def pool_steps(table: StepTable, sections: Sequence[Section]) -> tuple[StepTable, float]:
    """The whole steps (by window midpoint) from the start of the first section to the end of the last, and
    the sections' real distance: one calibration section of :func:`gaitlog.host.gait.k_calibration.calibrate`."""
    mask = section_fractions(table, sections[0].t_start_s, sections[-1].t_end_s, edge="whole") > 0
    return table.select(mask), float(sum(s.real_m for s in sections))


def calibration_sets(sections: Sequence[Section], *, calibration_sections: int = 2) -> dict[str, list[list[Section]]]:
    """The sections K is calibrated on, per mode (one list of sections per pool).

    Single-speed: the first ``calibration_sections`` straight sections of the preferred-speed excursion (else
    the first excursion), one pool; multi-speed: those of every excursion, one pool per excursion.

    Raises
    ------
    HostError
        No straight section.
    """
    by_exc: dict[int, list[Section]] = {}
    for s in sections:
        if not s.turn:
            by_exc.setdefault(s.excursion, []).append(s)
    sets = {k: v[:calibration_sections] for k, v in sorted(by_exc.items()) if v}
    if not sets:
        raise HostError("no straight section between lap marks to calibrate K on")
    pref = [k for k, v in sets.items() if v[0].speed_label == "preferred"]
    single = pref[0] if pref else min(sets)
    return {"single-speed": [sets[single]], "multi-speed": list(sets.values())}
