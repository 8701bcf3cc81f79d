"""gaitlog.host.files.inputs: one reader for every input, checked against what was written."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.host.errors import HostError
from gaitlog.host.files.inputs import read_acceleration

RATE_HZ = 50.0


def _acc(n: int = 200) -> np.ndarray:
    t = np.arange(n) / RATE_HZ
    return np.c_[0.1 * np.sin(t), 0.2 * np.cos(t), np.sqrt(1 - 0.01 * np.sin(t) ** 2 - 0.04 * np.cos(t) ** 2)]


def test_any_column_order_by_header_name_and_units_from_names(tmp_path):
    acc = _acc()
    path = tmp_path / "a.csv"
    rows = [f"{z * 9.80665:.6f},{i / RATE_HZ:.4f},{x * 9.80665:.6f},7,{y * 9.80665:.6f}" for i, (x, y, z) in
            enumerate(acc)]
    path.write_text("z_m_s2,time_s,x_m_s2,temp,y_m_s2\n" + "\n".join(rows) + "\n")
    data = read_acceleration(path)
    assert data.sampling_rate_hz == pytest.approx(RATE_HZ)
    np.testing.assert_allclose(data.acc_g, acc, atol=1e-6)


def test_explicit_columns_and_missing_cells(tmp_path):
    acc = _acc()
    path = tmp_path / "b.csv"
    lines = [f"{i};{z:.6f};{y:.6f};{x:.6f}" for i, (x, y, z) in enumerate(acc)]
    lines[10] = "10;;0.2;0.1"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(HostError, match="give --columns"):       # four numeric columns, no header
        read_acceleration(path, sampling_rate_hz=RATE_HZ)
    data = read_acceleration(path, sampling_rate_hz=RATE_HZ, columns="3,2,1")
    assert data.n_missing == 1 and not data.valid[10] and np.isnan(data.acc_g[10]).all()
    keep = np.arange(len(acc)) != 10
    np.testing.assert_allclose(data.acc_g[keep], acc[keep], atol=1e-6)


def test_time_column_holes_become_missing_samples(tmp_path):
    acc = _acc()
    keep = np.ones(len(acc), bool)
    keep[50:55] = False
    path = tmp_path / "c.csv"
    path.write_text("t,x,y,z\n" + "\n".join(f"{i / RATE_HZ:.4f},{x},{y},{z}" for i, (x, y, z) in enumerate(acc)
                                          if keep[i]) + "\n")
    data = read_acceleration(path)
    assert data.n_samples == len(acc) and np.array_equal(data.valid, keep)


def test_errors_name_the_file_and_what_to_give(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("x,y,z\n" + "\n".join("0,0,1" for _ in range(10)) + "\n")
    with pytest.raises(HostError, match=r"d.csv: no time column .* give --rate"):
        read_acceleration(path)
    path.write_text("x,y,z\n" + "\n".join("0,0,3" for _ in range(10)) + "\n")
    with pytest.raises(HostError, match=r"cannot tell the unit .* give --units"):
        read_acceleration(path, sampling_rate_hz=RATE_HZ)
    with pytest.raises(HostError, match="no such file"):
        read_acceleration(tmp_path / "none.csv")


def test_ipol_trial_file_json_and_flags_that_do_not_apply(shared_data):
    lb = shared_data / "ipol-lowerback-dev" / "GaitData" / "1-1_lb.txt"
    a = read_acceleration(lb)
    b = read_acceleration(lb.with_name("1-1.json"))
    assert a.sampling_rate_hz == 100.0 and a.ipol_trial is not None and a.ipol_trial.name == "1-1"
    np.testing.assert_array_equal(a.valid, b.valid)
    assert 0 < a.n_missing < a.n_samples
    med = np.nanmedian(np.linalg.norm(a.acc_g, axis=1))
    assert 0.9 < med < 1.1
    with pytest.raises(HostError, match="--columns applies to a CSV input only"):
        read_acceleration(lb, columns="x,y,z")
    with pytest.raises(HostError, match="the file says 100 Hz, --rate says 50 Hz"):
        read_acceleration(lb, sampling_rate_hz=50.0)
