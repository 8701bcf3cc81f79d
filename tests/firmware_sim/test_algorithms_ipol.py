"""Fixed vs float chain on real lower-back recordings (IPOL development trials, replayed at 50 Hz, 10 bits)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from firmware_sim.algorithms.chain import FixedStepChain


@pytest.mark.parametrize("name", ["5-2_lb.txt", "8-5_lb.txt"])
def test_fixed_vs_float_on_real_trials(shared_data: Path, name: str) -> None:
    from host.estimators.anthropometry import anatomical_lengths
    from host.gait.pipeline import StepPipeline
    from host.ipol import list_trials
    from host.ipol_evaluation import replay_trial

    paths = [p for p in list_trials(shared_data / "ipol-lowerback-dev") if p.name == name]
    if not paths:
        pytest.skip(f"{name} not in {shared_data / 'ipol-lowerback-dev'}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr = replay_trial(paths[0])
        leg, foot = anatomical_lengths(height_m=tr.height_m or 1.7)
        fl = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(tr.acc_g, sampling_rate_hz=tr.sampling_rate_hz,
                                                                     valid=tr.valid)
    # the same 10-bit codes (the nominal map is exact on codes)
    codes = np.where(tr.valid[:, None], np.round(np.nan_to_num(tr.acc_g) * 256 + 512), 0).astype(np.int64)
    fx = FixedStepChain(leg_length_m=leg, foot_length_m=foot).run(codes, sampling_rate_hz=tr.sampling_rate_hz,
                                                                  valid=tr.valid)
    assert fx.ctx_.report() == ""
    a, b = fx.steps_, fl.steps_
    _, ia, ib = np.intersect1d(a.foot_flat, b.foot_flat, return_indices=True)
    same = (a.start[ia] == b.start[ib]) & (a.heel_strike[ia] == b.heel_strike[ib]) & (a.toe_off[ia] == b.toe_off[ib])
    assert max(a.n_steps, b.n_steps) - np.count_nonzero(same) <= 1
    for est in ("M1", "M2", "M3", "M4", "M5"):
        x, y = a.raw_m[est][ia[same]], b.raw_m[est][ib[same]]
        g = np.isfinite(x) & np.isfinite(y)
        assert np.count_nonzero(np.isfinite(x) != np.isfinite(y)) == 0, est
        d = np.abs(x[g] - y[g])
        if est != "M5":                                   # M5's raw value is a cadence (Hz)
            assert np.median(d) <= 1e-3, est
        assert np.max(d / np.abs(y[g])) <= 0.01, est
        assert abs(np.nansum(a.raw_m[est]) / np.nansum(b.raw_m[est]) - 1) <= 0.005, est
