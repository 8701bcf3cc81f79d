"""The overview of one recording: what a gait researcher looks at first (``gaitlog plot``).

:func:`recording_overview` gathers, for a time window of a decoded recording: the acceleration (3 axes, g;
missing samples NaN), the gaps (runs of missing samples), the lap marks, the events of the host's offline
chain (foot-flat, heel-strike, toe-off: :class:`gaitlog.host.gait.pipeline.StepPipeline`, run on the whole recording so
the window's edges change nothing), the device's own step records when the recording holds some, and the
per-step lengths of the chosen estimators (offline, and the device's beside them). The figure is drawn by
:func:`gaitlog.host.studies.plots.render_overview_png`; the data are returned so that callers and tests read exactly
what was drawn.

Times are seconds since the recording's first row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gaitlog.firmware_sim.algorithms.online import OnlineSteps
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.host.errors import HostError
from gaitlog.host.files.recording import Recording
from gaitlog.host.gait.k_calibration import KFit
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.protocol.packing import FLAG_MARK

#: Event names, in the order of the legend.
EVENTS = ("foot-flat", "heel-strike", "toe-off", "device step")


@dataclass(frozen=True, eq=False)
class RecordingOverview:
    """What the overview of a recording's window shows (times in s since the first row).

    Attributes
    ----------
    source
        The file it was read from.
    window_s
        ``(start, end)`` of the window.
    time_s, acc_g
        ``(n,)`` sample times and ``(n, 3)`` acceleration in g of the window (NaN where missing).
    gaps_s
        ``(start, end)`` of every run of missing samples in the window (from its first missing sample to
        the next measured one).
    marks_s
        Times of the lap marks in the window.
    events_s
        ``{name: times}`` for :data:`EVENTS` (``device step`` = the end of each device step record; empty when
        the recording holds none).
    lengths_m
        ``{label: (times, lengths)}``: per estimator the offline chain's lengths at each step's foot-flat
        (``"M1"``), and the device's (``"M1 device"``) when it stored records; NaN lengths are left out.
    length_kinds
        ``{label: kind}`` for the legend: ``"host, K"`` or ``"host, no K"`` (the offline chain, with or without
        the K file), ``"device, K"`` (the logger's calibrated lengths) or ``"device, raw K = 1"`` (a logger without
        K: uncalibrated lengths, not comparable with calibrated ones).
    """

    source: str
    window_s: tuple[float, float]
    time_s: np.ndarray
    acc_g: np.ndarray
    gaps_s: list[tuple[float, float]]
    marks_s: np.ndarray
    events_s: dict[str, np.ndarray]
    lengths_m: dict[str, tuple[np.ndarray, np.ndarray]]
    length_kinds: dict[str, str] = field(default_factory=dict)

    def __repr__(self) -> str:
        counts = ", ".join(f"{k} {v.size}" for k, v in self.events_s.items())
        return (f"RecordingOverview({self.source!r}, {self.window_s[0]:g}-{self.window_s[1]:g} s, "
                f"{self.time_s.size} samples, {len(self.gaps_s)} gaps, {self.marks_s.size} marks, {counts})")


def recording_overview(rec: Recording, *, leg_length_m: float, foot_length_m: float,
                       k_fit: KFit | None = None, start_s: float = 0.0,
                       duration_s: float | None = None,
                       estimators: Sequence[str] = ESTIMATORS) -> RecordingOverview:
    """The overview data of ``rec`` between ``start_s`` and ``start_s + duration_s`` (default: to the end), the
    host chain's lengths with the step constants ``k_fit`` (None: no K).

    Raises
    ------
    HostError
        An empty recording, a window outside it, or an unknown estimator.
    """
    source = str(rec.source or "recording")
    unknown = [e for e in estimators if e not in ESTIMATORS]
    if unknown or not estimators:
        raise HostError(f"--estimators: unknown {', '.join(unknown) or '(none given)'}; choose from "
                        f"{','.join(ESTIMATORS)}")
    sampling_rate_hz = float(rec.sampling_rate_hz)
    n = rec.n_samples
    if n == 0:
        raise HostError(f"{source}: the recording holds no samples")
    total_s = n / sampling_rate_hz
    if not (np.isfinite(start_s) and 0 <= start_s < total_s):
        raise HostError(f"--start {start_s:g} s: outside the recording (0 to {total_s:g} s)")
    if duration_s is not None and not (np.isfinite(duration_s) and duration_s > 0):
        raise HostError(f"--duration {duration_s:g} s: must be positive")
    end_s = total_s if duration_s is None else min(total_s, start_s + duration_s)
    i0, i1 = int(np.ceil(start_s * sampling_rate_hz - 1e-9)), int(np.ceil(end_s * sampling_rate_hz - 1e-9))
    acc = rec.acc_g()
    valid = np.asarray(rec.valid, bool)
    pipe = StepPipeline(leg_length_m=leg_length_m, foot_length_m=foot_length_m, k_fit=k_fit).run(
        acc, sampling_rate_hz=sampling_rate_hz, valid=valid)
    offline = pipe.steps_
    tables = {"": offline}
    if rec.n_step_records:
        online = OnlineSteps.from_records(rec.step_records, first_sample_number=int(rec.sample_numbers[0]),
                                          sampling_rate_hz=sampling_rate_hz)
        tables[" device"] = StepTable.from_online(online)

    def inside(index: np.ndarray) -> np.ndarray:
        index = np.asarray(index, np.int64)
        return index[(index >= i0) & (index < i1)]

    events = {"foot-flat": inside(offline.foot_flat) / sampling_rate_hz, "heel-strike": inside(offline.heel_strike) / sampling_rate_hz,
              "toe-off": inside(offline.toe_off) / sampling_rate_hz,
              "device step": inside(tables[" device"].foot_flat) / sampling_rate_hz if " device" in tables else np.zeros(0)}
    kinds = {"": "host, K" if k_fit is not None else "host, no K",
             " device": "device, K" if rec.n_step_records and online.calibrated else "device, raw K = 1"}
    lengths, length_kinds = {}, {}
    for suffix, table in tables.items():
        for name in estimators:
            sel = (table.foot_flat >= i0) & (table.foot_flat < i1) & np.isfinite(table.length_m[name])
            lengths[name + suffix] = (table.foot_flat[sel] / sampling_rate_hz, table.length_m[name][sel])
            length_kinds[name + suffix] = kinds[suffix]
    miss = np.flatnonzero(np.diff(np.r_[0, (~valid[i0:i1]).astype(np.int8), 0]))
    gaps = [((i0 + a) / sampling_rate_hz, (i0 + b) / sampling_rate_hz) for a, b in zip(miss[::2], miss[1::2], strict=True)]
    marks = np.flatnonzero(np.asarray(rec.flags[i0:i1]) & FLAG_MARK)
    return RecordingOverview(source, (start_s, end_s), np.arange(i0, i1) / sampling_rate_hz, acc[i0:i1], gaps,
                             (i0 + marks) / sampling_rate_hz, events, lengths, length_kinds)
