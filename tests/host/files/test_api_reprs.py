"""The objects of the README's Python API section print as one short line, never as arrays."""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.algorithms.online import OnlineSteps
from gaitlog.host.files.inputs import read_acceleration
from gaitlog.host.files.recording import Recording
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.units import STANDARD_GRAVITY_M_S2


def _walk_g(n: int = 3000, sampling_rate_hz: float = 50.0) -> np.ndarray:
    t = np.arange(n) / sampling_rate_hz
    acc = np.zeros((n, 3))
    acc[:, 2] = 1.0 - 0.02 * (2 * np.pi * 2.0) ** 2 * np.cos(2 * np.pi * 2.0 * t) / STANDARD_GRAVITY_M_S2
    return acc


def _short(text: str) -> bool:
    return "\n" not in text and "array" not in text and "[" not in text and len(text) < 300


def test_reprs_summarise(tmp_path):
    acc = _walk_g()
    rec = Recording.from_arrays(np.clip(np.round(512 + acc * 256), 0, 1023), source="walk")
    rec.save_npz(tmp_path / "walk.npz")
    data = read_acceleration(tmp_path / "walk.npz")
    pipe = StepPipeline(leg_length_m=0.9, foot_length_m=0.26)
    before = repr(pipe)
    pipe.run(data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid)
    texts = [repr(rec), repr(data), before, repr(pipe), repr(pipe.steps_),
             repr(OnlineSteps.empty("fixed", 50.0, calibrated=False))]
    assert all(_short(t) for t in texts), texts
    assert f"{pipe.steps_.n_steps} steps" in repr(pipe.steps_) and pipe.steps_.n_steps > 50
    assert "3000 samples" in repr(rec) and "fitted" in repr(pipe) and "fitted" not in before
