"""``compare`` runs the offline chain block by block: its table equals the whole-array chain's, bit for bit,
wherever the recording is cut.

Truth: :func:`gaitlog.host.studies.compare.offline_step_table` on the whole ``(n, 3)`` array in g (the chain
``compare`` ran before it streamed), on codes of a walk with standing still, short gaps and a gap longer than a
block, converted by a calibration with cross-axis terms; blocks of sizes that are multiples of nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.host.gait.k_calibration import KFit
from gaitlog.host.studies.compare import compare_recording, offline_step_table, streamed_offline_table
from gaitlog.protocol.header import CalibrationSlot

RATE_HZ = 50.0
K = KFit(k_m1=1.1, k_m2=0.97, k_m4=0.45, k1_m5_m_s=0.3, k2_m5_m=0.2, mode="single-speed", m5_fallback=False,
         leg_length_m=0.9, foot_length_m=0.26, n_sections=2, n_steps=40, distance_m=30.0)
CAL = CalibrationSlot(np.array([511.3, 514.8, 509.1]),
                      np.array([[0.00392, 0.00004, -0.00002],
                                [-0.00003, 0.00389, 0.00005],
                                [0.00001, 0.00002, 0.00395]]), valid=True)


def walk_codes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """10-bit codes of a walk at changing cadence, standing still, with gaps; and their validity."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    phase = 2 * np.pi * np.cumsum(1.8 + 0.3 * np.sin(2 * np.pi * t / 97.0)) / RATE_HZ
    amp = 0.25 * (1.0 + 0.6 * np.sin(2 * np.pi * t / 41.0))
    g = np.stack([0.1 + 0.15 * np.sin(phase + 0.3), -0.2 + 0.1 * np.sin(phase / 2),
                  0.97 + amp * np.cos(phase) + 0.08 * np.cos(2 * phase + 0.5)], axis=1)
    g[n // 5:n // 5 + 3_000] = [0.1, -0.2, 0.97]
    codes = np.clip(np.round(512 + 256 * g + rng.normal(0, 0.7, g.shape)), 0, 1023).astype(np.uint16)
    valid = np.ones(n, bool)
    valid[:7] = valid[-5:] = False
    for s in rng.integers(50, n - 100, size=n // 2_000):
        valid[s:s + rng.integers(1, 12)] = False
    valid[n // 2:n // 2 + 2_345] = False
    return codes, valid


def whole_array(codes, valid, k, t0_s=0.0):
    acc = np.asarray(CAL.apply(codes.astype(np.float64)), np.float64)
    acc[~valid] = np.nan
    return offline_step_table(acc, sampling_rate_hz=RATE_HZ, leg_length_m=0.9, foot_length_m=0.26, k_fit=k,
                              valid=valid, t0_s=t0_s)


def differing_columns(a, b) -> list[str]:
    ca, cb = a.columns(), b.columns()
    assert list(ca) == list(cb)
    return [c for c in ca if not np.array_equal(np.asarray(ca[c]), np.asarray(cb[c]),
                                                equal_nan=np.asarray(ca[c]).dtype.kind == "f")]


@pytest.mark.parametrize("n, seed, block", [(30_001, 1, 997), (70_001, 2, 4_099), (140_000, 3, 65_536)])
@pytest.mark.parametrize("k", [None, K], ids=["raw", "K"])
def test_streamed_offline_table_is_the_whole_array_one(n, seed, block, k) -> None:
    codes, valid = walk_codes(n, seed)
    ref = whole_array(codes, valid, k, t0_s=12.5)
    assert ref.n_steps > n / 60
    got = streamed_offline_table(codes, valid, CAL, sampling_rate_hz=RATE_HZ, leg_length_m=0.9, foot_length_m=0.26,
                                 k_fit=k, t0_s=12.5, block=block)
    assert got.n_steps == ref.n_steps
    assert differing_columns(ref, got) == []


def test_compare_recording_streams_its_offline_chain() -> None:
    """The whole comparison with blocks of 3,001 samples: its offline table is the whole-array one, and its
    matching, sections and step columns those of the default blocks."""
    codes, valid = walk_codes(40_000, 4)
    kw = dict(sampling_rate_hz=RATE_HZ, leg_length_m=0.9, foot_length_m=0.26, adc_calibration=CAL, valid=valid,
              k_fit=K)
    odd, usual = compare_recording(codes, block=3_001, **kw), compare_recording(codes, **kw)
    assert differing_columns(whole_array(codes, valid, K), odd.tables["offline"]) == []
    assert len(odd.segments) == len(usual.segments) > 0
    assert all(a.keys() == b.keys() and all(a[c] == b[c] or (a[c] != a[c] and b[c] != b[c]) for c in a)
               for a, b in zip(odd.segments, usual.segments))
    assert all(np.array_equal(odd.steps[c], usual.steps[c], equal_nan=odd.steps[c].dtype.kind == "f")
               for c in usual.steps)
