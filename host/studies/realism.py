"""Whether the simulated walker looks like people: the criterion, statistic by statistic.

The statistics are those of ``../shared/tools/walking_stats.py`` (lower-back walking in the IPOL layout; the
project does not ship or import that tool: its per-trial CSV columns are named here). For each statistic the
median over simulated trials is compared with the real trials': it passes when it lies inside
the real 5-95 % band and within ±20 % of the real median. ``checked`` marks the statistics the realism criterion
names; the others are recording properties (lost packets, the sensor's standing noise and scale)
or follow from the checked ones, and are reported for information.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Largest relative difference of the simulated median from the real median.
MEDIAN_TOLERANCE = 0.20

#: (CSV column of walking_stats.py, label, checked).
STATISTICS: tuple[tuple[str, str, bool], ...] = (
    ("cadence_spm", "cadence, steps/min", True),
    ("step_duration_s", "mean step duration, s", False),
    ("step_duration_cv", "step duration CV", True),
    ("rms_v", "RMS vertical, m/s2", True),
    ("rms_ap", "RMS AP, m/s2", True),
    ("rms_ml", "RMS ML, m/s2", True),
    ("p2p_v_step_median", "vertical peak-to-peak per step, m/s2", True),
    ("hr_v", "harmonic ratio vertical", True),
    ("hr_ap", "harmonic ratio AP", True),
    ("hr_ml", "harmonic ratio ML (odd/even)", True),
    ("fdom_ml_over_stride_freq", "ML dominant freq / stride freq", True),
    ("ml_peak_harmonic", "strongest ML stride harmonic", False),
    ("fdom_v_over_step_freq", "vertical dominant freq / step freq", False),
    ("fdom_ap_over_step_freq", "AP dominant freq / step freq", False),
    ("ds_fraction", "double-support fraction", True),
    ("step_length_20m", "step length 20 m / steps, m", True),
    ("step_length_straight", "step length speed x duration, m", True),
    ("speed_mps", "walking speed, m/s", True),
    ("dur_uturn_s", "U-turn duration, s", True),
    ("ap_ml_var_ratio", "principal-axis variance ratio", True),
    ("n_steps_trial", "heel strikes in trial", False),
    ("dur_straight1_s", "straight 1 duration, s", False),
    ("dur_straight2_s", "straight 2 duration, s", False),
    ("absmean_ap", "|mean AP| (tilt leak), m/s2", False),
    ("absmean_ml", "|mean ML|, m/s2", False),
    ("apml_axis_err_deg", "angle AP (PCA) to AP (periodicity), deg", False),
    ("standing_sd", "SD of |a| standing (sensor noise), m/s2", False),
    ("g_standing", "|g| standing (sensor scale), m/s2", False),
)


@dataclass(frozen=True)
class Verdict:
    """One statistic: simulated median, real median and 5th/95th percentiles, and whether it passes."""

    sim_median: float
    real_median: float
    real_p5: float
    real_p95: float

    @property
    def in_band(self) -> bool:
        """Simulated median inside the real 5-95 % band."""
        return self.real_p5 <= self.sim_median <= self.real_p95

    @property
    def near_median(self) -> bool:
        """Simulated median within :data:`MEDIAN_TOLERANCE` of the real median."""
        return abs(self.sim_median - self.real_median) <= MEDIAN_TOLERANCE * abs(self.real_median)

    @property
    def passes(self) -> bool:
        """Both: the realism criterion."""
        return self.in_band and self.near_median


def judge(sim: np.ndarray, real: np.ndarray) -> Verdict:
    """The :class:`Verdict` of one statistic from its per-trial values (NaN ignored; numpy linear percentiles,
    as walking_stats.py's summary).

    Examples
    --------
    >>> v = judge(np.array([1.0, 1.1, 1.2]), np.linspace(0.5, 1.5, 101))
    >>> v.passes, judge(np.array([1.3]), np.linspace(0.5, 1.5, 101)).passes
    (True, False)
    """
    sim = np.asarray(sim, dtype=np.float64)
    real = np.asarray(real, dtype=np.float64)
    sim, real = sim[np.isfinite(sim)], real[np.isfinite(real)]
    if sim.size == 0 or real.size == 0:
        raise ValueError("judge: no finite value among the simulated or the real trials")
    p5, med, p95 = (float(x) for x in np.percentile(real, [5, 50, 95]))
    return Verdict(float(np.median(sim)), med, p5, p95)
