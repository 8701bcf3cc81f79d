"""The streaming offline chain equals the whole-array chain bit for bit, wherever the recording is cut.

:class:`gaitlog.host.gait.streaming.StreamingStepPipeline` against
:class:`gaitlog.host.gait.pipeline.StepPipeline` on walks with quiet stretches, plateaus, missing samples at the
ends and gaps longer than a block; fed in pieces cut inside steps, at foot-flats and at odd sizes, computed in
blocks of sizes that are multiples of nothing. Every column of the step table, every estimator, with and
without K.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gaitlog.host.gait.k_calibration import KFit
from gaitlog.host.gait.pipeline import StepPipeline
from gaitlog.host.gait.streaming import StreamingStepPipeline, TurningPoints

RATE_HZ = 50.0
K = KFit(k_m1=1.1, k_m2=0.97, k_m4=0.45, k1_m5_m_s=0.3, k2_m5_m=0.2, mode="single-speed", m5_fallback=False,
         leg_length_m=0.9, foot_length_m=0.26, n_sections=2, n_steps=40, distance_m=30.0)


def walk(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Walking at changing cadence and amplitude, standing still (exact constants: plateaus), slow drifts, short
    and long gaps, missing samples at both ends."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    f = 1.8 + 0.3 * np.sin(2 * np.pi * t / 97.0)
    phase = 2 * np.pi * np.cumsum(f) / RATE_HZ
    amp = 0.25 * (1.0 + 0.6 * np.sin(2 * np.pi * t / 41.0))
    acc = np.stack([0.1 + 0.15 * np.sin(phase + 0.3), -0.2 + 0.1 * np.sin(phase / 2),
                    0.97 + amp * np.cos(phase) + 0.08 * np.cos(2 * phase + 0.5)], axis=1)
    acc += 0.02 * rng.standard_normal((n, 3))
    acc[n // 5:n // 5 + 3_000] = [0.1, -0.2, 0.97]                        # standing still, exactly
    acc[n // 3:n // 3 + 1_500, 2] = 0.97 + np.linspace(0, 0.05, 1_500)    # a slow drift, no step
    valid = np.ones(n, bool)
    valid[:7] = valid[-5:] = False
    for s in rng.integers(50, n - 100, size=n // 2_000):
        valid[s:s + rng.integers(1, 12)] = False
    valid[n // 2:n // 2 + 2_345] = False                                   # longer than a block
    acc[~valid] = np.nan
    return acc, valid


def columns_equal(a, b) -> list[str]:
    ca, cb = a.columns(), b.columns()
    assert list(ca) == list(cb)
    return [k for k in ca if not np.array_equal(np.asarray(ca[k]), np.asarray(cb[k]),
                                                equal_nan=np.asarray(ca[k]).dtype.kind == "f")]


def stream(acc, valid, cuts, block, k=None):
    s = StreamingStepPipeline(leg_length_m=0.9, foot_length_m=0.26, sampling_rate_hz=RATE_HZ, k_fit=k,
                              block=block)
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        s.feed(acc[lo:hi], valid[lo:hi])
    return s.finish()


@pytest.mark.parametrize("n, seed, block", [(12_001, 1, 997), (30_000, 2, 2_048), (70_001, 3, 65_536),
                                            (140_000, 4, 13_331)])
@pytest.mark.parametrize("k", [None, K], ids=["raw", "K"])
def test_streaming_equals_the_whole_array(n, seed, block, k) -> None:
    acc, valid = walk(n, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = StepPipeline(leg_length_m=0.9, foot_length_m=0.26, k_fit=k).run(
            acc, sampling_rate_hz=RATE_HZ, valid=valid)
    steps = ref.steps_
    assert steps.n_steps > n / 60
    ff = steps.end_sample if hasattr(steps, "end_sample") else ref.events_.foot_flat_
    rng = np.random.default_rng(seed)
    mid = ((ff[1:] + ff[:-1]) // 2)[::7]                     # inside steps
    cuts = np.unique(np.r_[0, ff[::5], ff[3::11] + 1, mid, rng.integers(1, n, 20), n // 2 + 1_000, n])
    got = stream(acc, valid, cuts.tolist(), block, k)
    assert columns_equal(steps, got.steps_) == []
    assert got.steps_.n_steps == steps.n_steps
    for e in ("M1", "M2", "M3", "M4", "M5"):
        assert np.array_equal(steps.length_m[e], got.steps_.length_m[e], equal_nan=True), e
        assert steps.distance_m(e)[0] == got.steps_.distance_m(e)[0] or not np.isfinite(steps.distance_m(e)[0])
    assert got.n_impossible_ == ref.n_impossible_


def test_one_piece_and_sample_by_sample_pieces_agree() -> None:
    acc, valid = walk(4_000, 7)
    whole = stream(acc, valid, [0, 4_000], 65_536).steps_
    tiny = stream(acc, valid, list(range(0, 4_000, 13)) + [4_000], 101).steps_
    assert columns_equal(whole, tiny) == []


def test_nothing_measured_and_too_short() -> None:
    acc = np.full((500, 3), np.nan)
    assert stream(acc, np.zeros(500, bool), [0, 500], 64).steps_.n_steps == 0
    assert stream(np.ones((2, 3)), np.ones(2, bool), [0, 2], 64).steps_.n_steps == 0


def test_turning_points_keep_plateaus_and_ends() -> None:
    x = np.array([3.0, 3.0, 1.0, 2.0, 2.0, 2.0, 5.0, 5.0, 0.0, 0.0, 1.0])
    for cut in range(1, x.size):
        tp = TurningPoints()
        tp.feed(x[:cut])
        tp.feed(x[cut:])
        tp.finish()
        assert tp.values.tolist() == [3.0, 1.0, 5.0, 0.0, 1.0]
        assert tp.index.tolist() == [0, 2, 6, 8, 10]
