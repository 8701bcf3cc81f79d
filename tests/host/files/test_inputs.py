"""gaitlog.host.files.inputs: one reader for every input, checked against what was written; the .npz reader of
gaitlog.host.files.acceleration against it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gaitlog.host.errors import HostError
from gaitlog.host.files.acceleration import is_npz, read_npz
from gaitlog.host.files.inputs import read_acceleration
from gaitlog.host.files.losses import MissingSamplesWarning
from gaitlog.host.files.recording import Recording
from gaitlog.protocol.packing import FLAG_MARK

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


def _npz(tmp_path) -> Path:
    """A decoded recording with a gap and a lap mark."""
    n = 500
    codes = np.clip(512 + np.random.default_rng(1).normal(0, 20, (n, 3)), 0, 1023).astype(np.uint16)
    valid = np.ones(n, bool)
    valid[100:110] = False
    flags = np.zeros(n, np.uint8)
    flags[300] = FLAG_MARK
    path = tmp_path / "rec.npz"
    Recording.from_arrays(codes, valid=valid, flags=flags, reason="block damaged").save_npz(path)
    return path


def _fields(data) -> dict:
    out = {f.name: getattr(data, f.name) for f in dataclasses.fields(data) if f.name not in ("recording", "to_g")}
    out["codes"] = data.recording.codes
    return out


@pytest.mark.parametrize("arrays", [True, False])
def test_the_npz_reader_reads_what_the_reader_of_every_input_reads(tmp_path, arrays):
    """read_npz (the decoders not loaded) and read_acceleration give the same input, warnings and errors."""
    path = _npz(tmp_path)
    with pytest.warns(MissingSamplesWarning) as said_general:
        general = read_acceleration(path, arrays=arrays)
    with pytest.warns(MissingSamplesWarning) as said_npz:
        npz = read_npz(path, arrays=arrays)
    assert [str(w.message) for w in said_npz] == [str(w.message) for w in said_general]
    assert "10 of 500 samples missing" in str(said_npz[0].message)
    a, b = _fields(general), _fields(npz)
    assert a.keys() == b.keys() and a["mark_index"].tolist() == [300]
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    for bad in (dict(columns="x,y,z"), dict(units="g"), dict(skip_rows=1), dict(sampling_rate_hz=40.0),
                dict(sampling_rate_hz=-1.0), dict(units="furlongs"), dict(calibration=tmp_path / "none.json")):
        with pytest.raises(HostError) as general_error:
            read_acceleration(path, **bad)
        with pytest.raises(HostError) as npz_error:
            read_npz(path, **bad)
        assert str(npz_error.value) == str(general_error.value)


def test_is_npz_accepts_only_what_the_reader_of_every_input_reads_as_an_npz(tmp_path):
    path = _npz(tmp_path)
    assert is_npz(path) and is_npz(str(path))
    text = tmp_path / "a.csv"
    text.write_text("x,y,z\n0,0,1\n")
    named = tmp_path / "1-1_lb.txt"                     # an IPOL name is read as IPOL, whatever its bytes
    named.write_bytes(path.read_bytes())
    assert not any(is_npz(p) for p in (text, named, named.with_name("1-1.json"), tmp_path, tmp_path / "none.npz"))
