"""Replay of recorded samples (:meth:`Replay.from_samples`): holes interpolated and reported, anti-aliased
resampling. Files are read by the host (tests/host/files/test_replay_files.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.world.replay import Replay


def test_missing_samples_are_filled_between_their_neighbours_and_reported() -> None:
    sampling_rate_hz = 100.0
    t = np.arange(1000) / sampling_rate_hz
    acc = np.c_[0.3 * np.sin(2 * np.pi * 1.1 * t), 0.1 * t, 1.0 + 0 * t]
    valid = np.ones(t.size, bool)
    valid[[0, 1]] = False                    # leading holes: the replay starts at the first measured sample
    valid[200:205] = False
    valid[700] = False
    acc[~valid] = np.nan
    src = Replay.from_samples(acc, valid, sampling_rate_hz=sampling_rate_hz, source="test")
    assert src.t0_s == pytest.approx(0.02) and src.acc_g.shape == (998, 3)
    assert src.n_interpolated == 6 and src.truth["source"] == "test"
    np.testing.assert_array_equal(src.truth["filled_packets"], [[198, 202], [698, 698]])
    np.testing.assert_allclose(src.truth["filled_ranges_s"], [[1.98, 2.03], [6.98, 6.99]])
    np.testing.assert_array_equal(src.acc_g[~src.truth["filled"]], acc[valid])
    # linear between the neighbours: the y axis is a straight line, so it is filled exactly
    np.testing.assert_allclose(src.acc_g[:, 1], 0.1 * t[2:], atol=1e-12)
    lo, hi = acc[199, 0], acc[205, 0]
    np.testing.assert_allclose(src.acc_g[198:203, 0], lo + (hi - lo) * np.arange(1, 6) / 6, atol=1e-12)


def test_fewer_than_two_measured_samples_is_an_error() -> None:
    with pytest.raises(DeviceError, match="x.csv: fewer than 2 measured samples"):
        Replay.from_samples(np.ones((4, 3)), np.array([0, 1, 0, 0], bool), sampling_rate_hz=10.0, source="x.csv")
    with pytest.raises(DeviceError, match=r"\(n >= 2, 3\) acceleration array"):
        Replay(np.ones((4, 2)), sampling_rate_hz=10.0).render(50.0)


def test_downsampling_is_anti_aliased() -> None:
    sampling_rate_hz = 1000.0
    t = np.arange(20_000) / sampling_rate_hz
    x = 0.3 * np.sin(2 * np.pi * 5.0 * t) + 0.2 * np.sin(2 * np.pi * 290.0 * t)  # 290 Hz would alias to 90 Hz
    m = Replay(np.c_[x, 0 * x, 1 + 0 * x], sampling_rate_hz=sampling_rate_hz).render(200.0)
    f, p = signal.welch(m.acc_g[:, 0], fs=200.0, nperseg=1024)
    assert p[np.argmin(np.abs(f - 5.0))] > 1e4 * p[np.argmin(np.abs(f - 90.0))]
    tt = np.arange(m.n_samples) / 200.0
    np.testing.assert_allclose(m.acc_g[200:-200, 0], 0.3 * np.sin(2 * np.pi * 5.0 * tt[200:-200]), atol=5e-3)
    # naive indexing would have kept the 290 Hz tone (aliased onto 90 Hz)
    naive = x[::5]
    assert np.abs(naive - 0.3 * np.sin(2 * np.pi * 5.0 * t[::5])).max() > 0.1
