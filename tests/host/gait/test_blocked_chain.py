"""The float chain's block-wise stages equal the whole-array computation bit for bit.

``body_axes``, the masked Gaussian low-passes and the moving mean work in blocks of
:data:`gaitlog.host.gait.masked_filter.BLOCK_SAMPLES` samples. One block holding the whole signal is the
whole-array computation; small blocks of an odd size put block edges inside steps and at missing samples.
"""

from __future__ import annotations

import numpy as np
import pytest

import gaitlog.host.gait.masked_filter as masked_filter
from gaitlog.host.gait.masked_filter import halo_blocks, masked_gaussian_lowpass, masked_moving_mean
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.units import STANDARD_GRAVITY_M_S2

RATE_HZ = 50.0
BLOCK = 1_009          # prime: edges fall at every phase of the ~28-sample step


def walk(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Tilted trunk acceleration (g) at 1.8 steps/s with noise, and its validity mask with gaps at block edges."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    f = 1.8
    dyn = np.stack([0.15 * np.sin(2 * np.pi * f * t + 0.3), 0.1 * np.sin(np.pi * f * t),
                    0.25 * np.cos(2 * np.pi * f * t) + 0.08 * np.cos(4 * np.pi * f * t + 0.5)], axis=1)
    acc = dyn + np.array([0.1, -0.2, 0.97]) + 0.02 * rng.standard_normal((n, 3))
    valid = np.ones(n, bool)
    edges = np.arange(BLOCK, n, BLOCK)
    valid[edges[0] - 2:edges[0] + 3] = False            # a short gap across an edge (interpolated)
    valid[edges[1] - 15:edges[1] + 15] = False          # a long gap across an edge (ends a bout)
    valid[edges[2]] = False                             # one sample at an edge
    valid[edges[3] - 1] = False                         # the last sample of a block
    valid[:3] = valid[-4:] = False                      # both ends
    acc[edges[4], 1] = np.nan                           # NaN on one axis at an edge, marked valid
    acc[~valid] = np.nan
    return acc, valid


def chain_outputs(acc: np.ndarray, valid: np.ndarray) -> dict[str, np.ndarray]:
    """Every array the chain returns: filled input, body axes, events, step table."""
    p = StepPipeline(leg_length_m=0.9, foot_length_m=0.26).run(acc, sampling_rate_hz=RATE_HZ, valid=valid)
    out = {"acc": p.gaps_.acc_, "gap_valid": p.gaps_.valid_, "acc_v": p.axes_.acc_v_m_s2,
           "acc_ap": p.axes_.acc_ap_m_s2, "gravity": p.axes_.gravity_g, "axes_valid": p.axes_.valid}
    out |= {f"events.{k}": v for k, v in vars(p.events_).items() if isinstance(v, np.ndarray)}
    for k, v in vars(p.steps_).items():
        if isinstance(v, np.ndarray):
            out[f"steps.{k}"] = v
        elif isinstance(v, dict):
            out |= {f"steps.{k}.{e}": np.asarray(x) for e, x in v.items()}
    return out


def assert_identical(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype, k
        # bit for bit: the same bytes (NaN payloads and signed zeros included)
        assert a[k].shape == b[k].shape and a[k].tobytes() == b[k].tobytes(), k


def test_chain_blocked_equals_whole_array(monkeypatch: pytest.MonkeyPatch) -> None:
    acc, valid = walk(7 * BLOCK + 333)
    monkeypatch.setattr(masked_filter, "BLOCK_SAMPLES", 10 ** 9)
    whole = chain_outputs(acc, valid)
    assert whole["steps.foot_flat"].size > 200 and np.any(np.isnan(whole["acc_v"]))
    monkeypatch.setattr(masked_filter, "BLOCK_SAMPLES", BLOCK)
    assert_identical(chain_outputs(acc, valid), whole)


@pytest.mark.parametrize("window", [1, 2, 200, 3 * BLOCK])
def test_moving_mean_blocked_equals_whole_array(monkeypatch: pytest.MonkeyPatch, window: int) -> None:
    acc, valid = walk(5 * BLOCK + 7, seed=1)
    x = acc[:, 2] * STANDARD_GRAVITY_M_S2 * 1e3       # large values: rounding in the running sums shows
    monkeypatch.setattr(masked_filter, "BLOCK_SAMPLES", 10 ** 9)
    whole = masked_moving_mean(x, valid, window=window), masked_gaussian_lowpass(
        x, valid, cutoff_hz=3.0, sampling_rate_hz=RATE_HZ)
    monkeypatch.setattr(masked_filter, "BLOCK_SAMPLES", BLOCK)
    blocked = masked_moving_mean(x, valid, window=window), masked_gaussian_lowpass(
        x, valid, cutoff_hz=3.0, sampling_rate_hz=RATE_HZ)
    for w, b in zip(whole, blocked, strict=True):
        assert w.tobytes() == b.tobytes()


def test_halo_blocks_cover_every_sample_once() -> None:
    for n, halo, block in [(0, 3, 4), (1, 3, 4), (10, 2, 4), (12, 0, 4), (100, 40, 7)]:
        own = np.concatenate([np.arange(lo + a, lo + b) for lo, hi, a, b in halo_blocks(n, halo, block)] or [[]])
        assert own.tolist() == list(range(n))
        assert all(0 <= lo <= lo + a <= lo + b <= hi <= n and hi - (lo + b) <= halo and a <= halo
                   for lo, hi, a, b in halo_blocks(n, halo, block))
