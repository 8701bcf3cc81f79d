"""Replay of recorded files: the host reads them (:func:`gaitlog.host.files.inputs.read_acceleration`), the emulated
world replays the samples (:meth:`gaitlog.firmware_sim.world.replay.Replay.from_samples`): the IPOL packet grid and its
filled gaps, a CSV with a time column and a gap, units, resampling in band and through the logger."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.base import MotionSource
from gaitlog.firmware_sim.world.replay import Replay
from gaitlog.host.files.inputs import read_acceleration
from gaitlog.units import STANDARD_GRAVITY_M_S2


def _lowpass(x: np.ndarray, fc: float, sampling_rate_hz: float) -> np.ndarray:
    b, a = signal.butter(4, fc, fs=sampling_rate_hz)
    return signal.filtfilt(b, a, x, axis=0)


def replay(path: Path, **options) -> Replay:
    """A file as ``gaitlog record --motion replay`` replays it."""
    data = read_acceleration(path, **options)
    return Replay.from_samples(data.g(), data.valid, sampling_rate_hz=data.sampling_rate_hz, source=data.source)


def test_ipol_file_on_the_packet_grid_with_filled_gaps(shared_data: Path) -> None:
    path = shared_data / "ipol-lowerback-dev" / "GaitData" / "1-1_lb.txt"
    raw = np.loadtxt(path, skiprows=2)
    counter = raw[:, 0].astype(int)
    src = replay(path)
    assert isinstance(src, MotionSource)
    assert src.sampling_rate_hz == 100.0
    first = counter[0]
    assert src.acc_g.shape == (counter[-1] - first + 1, 3)
    # every received packet is at its counter position, converted to g
    np.testing.assert_allclose(src.acc_g[counter - first], raw[:, 1:4] / STANDARD_GRAVITY_M_S2, rtol=0, atol=1e-12)
    # every lost packet is reported, and filled between its neighbours (continuous input)
    lost = np.setdiff1d(np.arange(first, counter[-1] + 1), counter) - first
    assert src.truth["n_filled"] == lost.size > 0
    np.testing.assert_array_equal(np.flatnonzero(src.truth["filled"]), lost)
    ranges = src.truth["filled_packets"]
    assert sum(b - a + 1 for a, b in ranges) == lost.size
    np.testing.assert_allclose(src.truth["filled_ranges_s"][:, 0], ranges[:, 0] / 100.0)
    for a, b in ranges:
        lo, hi = src.acc_g[a - 1], src.acc_g[b + 1]
        assert np.all(src.acc_g[a:b + 1] >= np.minimum(lo, hi) - 1e-12)
        assert np.all(src.acc_g[a:b + 1] <= np.maximum(lo, hi) + 1e-12)


def test_ipol_resampled_signal_matches_the_original_in_band(shared_data: Path) -> None:
    src = replay(shared_data / "ipol-lowerback-dev" / "GaitData" / "2-1_lb.txt")
    m = src.render(500.0)
    assert m.sampling_rate_hz == 500.0 and m.n_samples == 5 * src.acc_g.shape[0]
    # the resampled signal at the original instants, both seen through the same 20 Hz low-pass
    x = _lowpass(src.acc_g, 20.0, 100.0)
    y = _lowpass(m.acc_g[::5], 20.0, 100.0)
    core = slice(100, -100)
    err = np.sqrt(np.mean((y[core] - x[core]) ** 2, axis=0))
    assert np.all(err < 0.01 * x[core].std(axis=0) + 1e-4)
    # and through the whole logger: the 50 Hz codes, back in g, are the recording seen through the
    # sensor's analog 20 Hz RC filter (simulated independently with lsim), within the quantisation
    lg = Logger(sensor=SensorModel.ideal(noise_density_g_rthz=0.0))
    res = lg.record(src)
    acc = (res.codes + 0.5 - 512.0) / (4 * 0.312 * 1024 / 5)
    t = np.arange(src.acc_g.shape[0]) / 100.0
    tau = 1.0 / (2 * np.pi * 20.0)
    rc = signal.StateSpace([[-1.0 / tau]], [[1.0 / tau]], [[1.0]], [[0.0]])  # dx/dt = (u - x) / tau, y = x
    ref = np.column_stack([signal.lsim(rc, src.acc_g[:, j], t, X0=[src.acc_g[0, j]])[1]
                           for j in range(3)])[::2][: acc.shape[0]]
    err = np.sqrt(np.mean((acc[25:-25] - ref[25:-25]) ** 2))
    assert err < 0.004  # one code is 0.0039 g


def test_csv_with_time_column_gap_and_units(tmp_path: Path) -> None:
    sampling_rate_hz = 200.0
    t = np.arange(2000) / sampling_rate_hz
    acc_g = np.c_[0.2 * np.sin(2 * np.pi * 1.5 * t), 0.1 * np.cos(2 * np.pi * 0.7 * t), 1.0 + 0 * t]
    keep = np.ones(t.size, bool)
    keep[500:507] = False  # 7 lost rows
    path = tmp_path / "rec.csv"
    rows = "\n".join(f"{tt:.5f},{a:.9f},{b:.9f},{c:.9f},42" for tt, (a, b, c) in
                     zip(t[keep], acc_g[keep] * STANDARD_GRAVITY_M_S2))
    path.write_text("# exported by a test\ntime_s,ax,ay,az,temp\n" + rows + "\n")
    src = replay(path)                      # ax/ay/az by name, m/s^2 from the norm, the rate from time_s
    assert src.sampling_rate_hz == pytest.approx(sampling_rate_hz)
    assert src.acc_g.shape == (2000, 3) and src.truth["n_filled"] == 7
    np.testing.assert_array_equal(src.truth["filled_packets"], [[500, 506]])
    np.testing.assert_allclose(src.acc_g[keep], acc_g[keep], atol=1e-8)
    # resampled to 500 Hz: the analytic signal in band
    m = src.render(500.0)
    tt = np.arange(m.n_samples) / 500.0
    truth = np.c_[0.2 * np.sin(2 * np.pi * 1.5 * tt), 0.1 * np.cos(2 * np.pi * 0.7 * tt), 1.0 + 0 * tt]
    core = (tt > 0.5) & (tt < 9.5) & ((tt < 2.4) | (tt > 2.6))
    np.testing.assert_allclose(m.acc_g[core], truth[core], atol=2e-3)
    # the same file with explicit units and a rate instead of the time column
    src_g = replay(path, columns="1,2,3", units="m/s2", sampling_rate_hz=sampling_rate_hz)
    assert src_g.acc_g.shape == (1993, 3)


def test_gaitpy_demo_csv_in_g(shared_data: Path) -> None:
    # GENEActiv export without a header: time stamp, x, y, z (g), light, button, temperature
    data = read_acceleration(shared_data / "gaitpy_demo" / "demo_data.csv", sampling_rate_hz=50.0, columns="1,2,3")
    src = Replay.from_samples(data.g(), data.valid, sampling_rate_hz=data.sampling_rate_hz)
    assert src.acc_g.shape[0] > 8000
    assert 0.9 < np.linalg.norm(src.acc_g, axis=1).mean() < 1.1


def test_readme_walkthrough_figures(shared_data: Path, tmp_path: Path, capsys) -> None:
    """The README's real-data walkthrough: subject 1's trial 1 gives K, trial 2 (20 m) is measured, offline and
    from the logger's fixed-point records; and trial 1's lost packets are counted."""
    import json

    from gaitlog.host.cli import main

    trials = shared_data / "ipol-lowerback-dev" / "GaitData"
    for t in ("1-1", "1-2"):
        assert main(["record", "--motion", "replay", str(trials / f"{t}_lb.txt"), "--out", str(tmp_path / f"{t}.glimg")]) == 0
        assert main(["decode", str(tmp_path / f"{t}.glimg"), "--out", str(tmp_path / t), "-q"]) == 0
    assert "124 of 3037 samples" in capsys.readouterr().err
    assert main(["calibrate-k", str(tmp_path / "1-1.npz"), "--distance", "20", "--out", str(tmp_path / "k.json")]) == 0
    capsys.readouterr()
    assert main(["estimate", str(tmp_path / "1-2.npz"), "--k-file", str(tmp_path / "k.json"), "--arithmetic", "both",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert (doc["leg_length_m"], doc["foot_length_m"]) == pytest.approx((0.927, 0.194), abs=6e-4)   # 1.75 m, JSON
    # on-line algorithm version 4 (M4 range^(1/4), no stop rule); version 3 gave float M1 20.89, M2 19.64, M3 21.71,
    # M4 19.67, M5 18.51 and fixed 20.98, 19.48, 21.56, 19.53, 18.52
    readme = {"float": {"M1": 20.51, "M2": 19.55, "M3": 21.06, "M4": 18.93, "M5": 18.56},
              "fixed": {"M1": 20.60, "M2": 19.36, "M3": 20.91, "M4": 18.87, "M5": 18.57}}
    got = {a: {m: doc["arithmetic"][a]["estimators"][m]["distance_m"] for m in readme[a]} for a in readme}
    for a in readme:
        assert got[a] == pytest.approx(readme[a], abs=0.006), a


def test_the_on_line_run_fed_in_pieces_gives_the_same_table(monkeypatch) -> None:
    """``online_step_table`` feeds a run a block at a time (bounded memory): the records are those of one feed."""
    import numpy as np

    import gaitlog.host.files.replay as replay

    t = np.arange(20_000) / 50.0
    g = np.stack([0.1 + 0.1 * np.sin(2 * np.pi * 1.8 * t), -0.2 + 0.05 * np.sin(np.pi * 1.8 * t),
                  0.97 + 0.25 * np.cos(2 * np.pi * 1.8 * t)], axis=1)
    codes = np.clip(np.round(512 + 256 * g), 0, 1023).astype(np.int64)
    valid = np.ones(t.size, bool)
    valid[7_000:7_010] = False

    def run() -> dict:
        table, _ = replay.online_step_table(codes, sampling_rate_hz=50.0, leg_length_m=0.9, foot_length_m=0.26,
                                            valid=valid)
        return table.columns()

    whole = run()
    monkeypatch.setattr(replay, "_FEED_SAMPLES", 997)
    pieces = run()
    assert whole.keys() == pieces.keys() and len(whole["step"]) > 100
    for k in whole:
        assert np.array_equal(np.asarray(whole[k]), np.asarray(pieces[k]),
                              equal_nan=np.asarray(whole[k]).dtype.kind == "f"), k
