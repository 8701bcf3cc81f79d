"""The observer who times the laps with a stopwatch (Alvarez et al. 2006, II-C: "Time laps were taken at 20m
intervals with a stopwatch").

The stopwatch is not the logger: its splits are written on a sheet, on the stopwatch's own clock (zero when
the observer started it), and reach the host apart from the memory dump; the host has to place them on the
recording (:mod:`gaitlog.host.gait.stopwatch_laps`). Every press is late or early by a human timing error:

- start: the observer presses when they see the subject set off, a simple visual reaction, ~0.2 s late
  (SD 0.05 s): hand-started times run ~0.2-0.3 s short of electronic ones mostly through this start delay
  (Hetzler et al. 2008, J Strength Cond Res 22(6):1969-1976, hand vs electronic sprint timing);
- splits and the final stop: the walker is seen approaching the line, so the press is anticipated and unbiased
  on average, with a per-press scatter of ``split_sd_s`` (default 0.08 s; hand timing of anticipated events
  scatters by a few hundredths to a tenth of a second, the same study's trial-to-trial differences);
- the display shows hundredths of a second.

With the logger's MARK button instead (``gaitlog evaluate sim --laps mark``), the presses are taken as exact:
the firmware flags the first sample at or after each lap.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Stopwatch:
    """An observer's stopwatch.

    Parameters
    ----------
    start_delay_s, start_sd_s
        Mean and SD of the reaction delay of the start press after the set-off.
    split_sd_s
        SD of the error of every split press (and of the final stop), unbiased.
    resolution_s
        Display resolution.
    """

    start_delay_s: float = 0.2
    start_sd_s: float = 0.05
    split_sd_s: float = 0.08
    resolution_s: float = 0.01

    def time_laps(self, laps: Mapping[str, Any], excursions: Mapping[str, Any], *, seed: int) -> dict[str, np.ndarray]:
        """The lap sheet of a walk: one stopwatch run per excursion, started at its set-off.

        Parameters
        ----------
        laps, excursions
            The walk's truth (``truth["laps"]``, ``truth["excursions"]`` of
            :class:`gaitlog.firmware_sim.world.walking.Walking`); the lap at the excursion's 0 m is the set-off.
        seed
            Seed of the observer's errors.

        Returns
        -------
        dict
            ``excursion``, ``speed_label``, ``distance_m`` and ``split_s`` (stopwatch reading, from its
            start: 0 at the 0 m lap) per lap, and per excursion ``start_walk_s``: when the stopwatch was
            started, on the walk's clock (truth, for scoring the host's alignment; not on the sheet).
        """
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
        exc = np.asarray(laps["excursion"])
        t_lap = np.asarray(laps["time_s"], np.float64)
        dist = np.asarray(laps["distance_m"], np.float64)
        t_set_off = np.asarray(excursions["t_start_s"], np.float64)
        start = t_set_off + np.clip(rng.normal(self.start_delay_s, self.start_sd_s, t_set_off.size), 0.05, 0.5)
        press = t_lap + rng.normal(0.0, self.split_sd_s, t_lap.size)
        split = press - start[exc]
        split[dist <= 0.0] = 0.0
        split = np.maximum(np.round(split / self.resolution_s) * self.resolution_s, 0.0)
        return {"excursion": exc.copy(), "speed_label": np.asarray(laps["speed_label"]).astype(str),
                "distance_m": dist.copy(), "split_s": split, "start_walk_s": start}
