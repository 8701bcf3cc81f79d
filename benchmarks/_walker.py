"""The simulated walker of the step benchmarks (imported as ``from _walker import walker_motion, ...``).

One full memory of realistic input for the on-line step algorithm: a random subject
(:func:`gaitlog.firmware_sim.world.subject.random_subjects`, seed 0) walking the corridor protocol twice over
(:class:`gaitlog.firmware_sim.world.walking.Walking`: eight 200 m excursions at four speeds, sitting and standing
rests, ~1545 s), rendered at the sensor's internal rate and cut so that the emulated logger takes exactly
65,536 samples at 50 Hz (1310.72 s: 6 excursions and part of the 7th).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.firmware_sim.device import Logger  # noqa: E402
from gaitlog.firmware_sim.world.base import Motion  # noqa: E402
from gaitlog.firmware_sim.world.subject import Subject, random_subjects  # noqa: E402
from gaitlog.firmware_sim.world.walk_plan import SPEED_LABELS, WalkPlan  # noqa: E402
from gaitlog.firmware_sim.world.walking import Walking  # noqa: E402
from gaitlog.protocol.steps import StepConfig  # noqa: E402

#: One full sample memory.
N_SAMPLES = 65_536
RATE_HZ = 50.0


def walker_motion(n_samples: int = N_SAMPLES, seed: int = 0) -> tuple[Motion, Subject]:
    """The walker's motion at the sensor's internal rate, cut to give ``n_samples`` logger samples."""
    subject = random_subjects(1, seed=seed)[0]
    logger = Logger()
    fine_hz = logger.sensor.internal_rate_hz
    walking = Walking(subject=subject, walk_plan=WalkPlan(speeds=SPEED_LABELS * 2), seed=seed)
    motion = walking.render(fine_hz)
    # the ADC takes t0 + k / actual_rate up to the last fine-grid instant: keep just enough fine samples
    k = int(np.ceil((n_samples - 1) / logger.adc.actual_rate_hz * fine_hz - 1e-9)) + 1
    if k > motion.n_samples:
        raise RuntimeError(f"the walk is too short for {n_samples} samples ({motion.n_samples} < {k} fine samples)")
    t_last = motion.t0_s + (k - 1) / fine_hz
    marks = motion.marker_times_s[motion.marker_times_s <= t_last]
    return Motion(motion.acc_g[:k], fine_hz, motion.t0_s, {}, marks), subject


def step_config(subject: Subject) -> StepConfig:
    """The subject's step configuration (leg and foot length; K not calibrated: the raw values)."""
    return StepConfig(step_format=1, leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m)
