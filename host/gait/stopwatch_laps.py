"""An observer's stopwatch sheet placed on a recording (Alvarez et al. 2006, II-C: "Time laps were taken at
20m intervals with a stopwatch").

The sheet (:meth:`gaitlog.firmware_sim.world.stopwatch.Stopwatch.time_laps`) holds, per excursion, the splits read on
the stopwatch from the moment the observer started it as the walker set off. The logger knows nothing of the
stopwatch, so the host anchors each excursion's splits at the set-off it sees in the recording
(:func:`set_off_times`): the walker stands still at the start line when the logger is STARTed, and the
set-off is the first moment the specific force leaves that standing posture by more than
:data:`SET_OFF_THRESHOLD_G` (0.2 s moving mean of the deviation, 5-10 times the standing noise). One
logging run per excursion (the logger stopped during the rests, as the paper's had to be) pairs the sheet's
excursion ``k`` with run ``k``.

The anchor's error (detected set-off vs the stopwatch's start press, both a few tenths of a second after
the real set-off) shifts every lap of an excursion by the same amount, which moves a 20 m section along
the walk but barely changes its duration in steady walking; the split presses' own scatter does change it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from gaitlog.host.errors import HostError

__all__ = ["SET_OFF_THRESHOLD_G", "lap_table", "set_off_times"]

#: Deviation from the standing posture (g, 0.2 s moving mean of ``|a - a_standing|``) taken as the set-off.
SET_OFF_THRESHOLD_G = 0.02
#: Quiet standing at the start of each logging run from which the standing posture is taken (s).
STANDING_S = 1.0
#: Moving-mean window of the deviation (s).
SMOOTHING_S = 0.2


def set_off_times(acc_g: np.ndarray, valid: np.ndarray, run_rows: Sequence[tuple[int, int]], *,
                  sampling_rate_hz: float, t0_s: float = 0.0,
                  threshold_g: float = SET_OFF_THRESHOLD_G) -> np.ndarray:
    """The set-off time (recording clock) in each logging run.

    Parameters
    ----------
    acc_g, valid
        ``(n, 3)`` calibrated specific force and its validity mask.
    run_rows
        ``[start, stop)`` rows of each logging run.
    sampling_rate_hz, t0_s
        Rate and time of row 0.
    threshold_g
        Deviation from the standing posture taken as the set-off.

    Raises
    ------
    HostError
        A run does not start with :data:`STANDING_S` of valid quiet standing, or never leaves it.
    """
    acc = np.asarray(acc_g, np.float64)
    ok = np.asarray(valid, bool)
    n_stand = max(1, round(STANDING_S * sampling_rate_hz))
    out = []
    for k, (a, b) in enumerate(run_rows):
        seg, good = acc[a:b], ok[a:b]
        if seg.shape[0] <= n_stand or not good[:n_stand].all():
            raise HostError(f"logging run {k + 1} (rows {a}-{b}): no {STANDING_S:g} s of valid standing at its "
                            "start to anchor the stopwatch on")
        standing = np.median(seg[:n_stand], axis=0)
        dev = np.where(good, np.linalg.norm(np.nan_to_num(seg - standing), axis=1), 0.0)
        smooth = uniform_filter1d(dev, max(1, round(SMOOTHING_S * sampling_rate_hz)), mode="nearest")
        if smooth[n_stand // 2] > threshold_g:
            raise HostError(f"logging run {k + 1} (rows {a}-{b}): the walker is not standing still when the "
                            "run starts")
        moved = np.flatnonzero(smooth > threshold_g)
        if moved.size == 0:
            raise HostError(f"logging run {k + 1} (rows {a}-{b}): the walker never sets off")
        out.append(t0_s + (a + moved[0]) / sampling_rate_hz)
    return np.asarray(out, np.float64)


def lap_table(sheet: Mapping[str, Any], set_off_s: np.ndarray) -> dict[str, np.ndarray]:
    """The sheet's laps on the recording clock: split + the excursion's set-off.

    Returns the lap table of :func:`gaitlog.host.gait.sections.sections_from_marks` (``time_s``, ``excursion``,
    ``distance_m``, ``speed_label``); pass ``time_s`` as the marks.

    Raises
    ------
    HostError
        The sheet has a different number of excursions than there are set-offs (logging runs).
    """
    exc = np.asarray(sheet["excursion"], np.int64)
    n_exc = int(exc.max()) + 1 if exc.size else 0
    set_off = np.asarray(set_off_s, np.float64)
    if n_exc != set_off.size:
        raise HostError(f"the stopwatch sheet has {n_exc} excursions for {set_off.size} logging runs (stopwatch "
                        "laps need the logger STARTed and STOPped around each excursion)")
    return {"time_s": set_off[exc] + np.asarray(sheet["split_s"], np.float64), "excursion": exc,
            "distance_m": np.asarray(sheet["distance_m"], np.float64),
            "speed_label": np.asarray(sheet["speed_label"]).astype(str)}
