"""Recording: save/load round trip (NPZ), CSV export, gaps, acc_g conversion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.host.errors import HostError
from gaitlog.host.files.recording import CSV_COLUMNS, Gap, Recording
from gaitlog.protocol.header import CalibrationSlot, DeviceHeader


@st.composite
def recordings(draw):
    n = draw(st.integers(0, 300))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    codes = rng.integers(0, 1024, size=(n, 3))
    valid = rng.random(n) > draw(st.sampled_from([0.0, 0.1, 0.5, 1.0]))
    flags = rng.integers(0, 4, size=n)
    first = draw(st.integers(0, 2**32 - 1 - 300))
    with_header = draw(st.booleans())
    header = None
    if with_header:
        header = DeviceHeader(device_id=draw(st.integers(0, 2**32 - 1)), samples_written=first + n,
                              write_index=(first + n) % 65536 if first + n >= 65536 else first + n,
                              flags=0x03 if first + n >= 65536 else 0, start_time_s=1_700_000_000)
    return codes, valid, flags, first, header


@settings(max_examples=40, deadline=None)
@given(recordings())
def test_npz_round_trip_is_exact(tmp_path_factory, rec_args):
    codes, valid, flags, first, header = rec_args
    rec = Recording.from_arrays(codes, valid=valid, flags=flags, first_sample_number=first, header=header,
                                sampling_rate_hz=50.0, start_time_s=1_700_000_000.0, source="test")
    path = tmp_path_factory.mktemp("npz") / "r.npz"
    rec.save_npz(path)
    back = Recording.load(path)
    # truth: the input arrays, with invalid rows zeroed
    exp_codes = np.where(valid[:, None], codes, 0)
    np.testing.assert_array_equal(back.codes, exp_codes)
    assert back.codes.dtype == np.uint16
    np.testing.assert_array_equal(back.valid, valid)
    np.testing.assert_array_equal(back.flags, np.where(valid, flags, 0))
    np.testing.assert_array_equal(back.sample_numbers, first + np.arange(codes.shape[0]))
    assert back.sampling_rate_hz == 50.0 and back.start_time_s == 1_700_000_000.0
    # gaps cover exactly the invalid rows
    covered = np.zeros(codes.shape[0], bool)
    for g in back.gaps:
        covered[g.first_sample_number - first: g.last_sample_number - first + 1] = True
    np.testing.assert_array_equal(covered, ~valid)
    assert back.gaps == rec.gaps
    if header is not None:
        assert back.header.to_bytes() == header.to_bytes()
    else:
        assert back.header is None


def test_csv_columns_and_values(tmp_path):
    codes = np.array([[512, 768, 256], [0, 1023, 512], [100, 200, 300]])
    rec = Recording.from_arrays(codes, valid=np.array([True, False, True]), flags=[1, 0, 2],
                                first_sample_number=10, sampling_rate_hz=50.0)
    rec.to_csv(tmp_path / "r.csv")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    assert lines[0] == ",".join(CSV_COLUMNS)
    cols = Recording.read_csv(tmp_path / "r.csv")
    np.testing.assert_array_equal(cols["sample_number"], [10, 11, 12])
    np.testing.assert_allclose(cols["time_s"], [0.2, 0.22, 0.24])
    # nominal map, computed independently: (code - 512) / 256 g
    np.testing.assert_allclose(cols["x_g"][[0, 2]], [0.0, (100 - 512) / 256], atol=1e-6)
    np.testing.assert_allclose(cols["y_g"][[0, 2]], [1.0, (200 - 512) / 256], atol=1e-6)
    assert np.isnan(cols["x_counts"][1]) and np.isnan(cols["z_g"][1]) and cols["valid"][1] == 0
    np.testing.assert_array_equal(cols["flags"][[0, 2]], [1, 2])


def test_acc_g_uses_header_calibration_when_valid():
    cal = CalibrationSlot(np.array([500.0, 510.0, 520.0]), np.diag([1 / 200, 1 / 250, 1 / 300]), True)
    header = DeviceHeader(samples_written=1, write_index=1, calibration=cal)
    rec = Recording.from_arrays(np.array([[700, 760, 820]]), header=header)
    np.testing.assert_allclose(rec.acc_g(), [[1.0, 1.0, 1.0]], atol=1e-6)
    assert "calibration slot" in rec.default_calibration()[1]
    rec2 = Recording.from_arrays(np.array([[768, 512, 256]]))
    np.testing.assert_allclose(rec2.acc_g(), [[1.0, 0.0, -1.0]])
    assert "nominal" in rec2.default_calibration()[1]


def test_load_rejects_other_files(tmp_path):
    p = tmp_path / "x.npz"
    p.write_bytes(b"not a zip")
    with pytest.raises(HostError, match="x.npz"):
        Recording.load(p)
    np.savez(tmp_path / "y.npz", a=np.zeros(3))
    with pytest.raises(HostError, match="missing arrays"):
        Recording.load(tmp_path / "y.npz")
    with pytest.raises(HostError, match="cannot read"):
        Recording.load(tmp_path / "absent.npz")


def _saved(tmp_path) -> tuple:
    rec = Recording.from_arrays(np.full((200, 3), 512), sampling_rate_hz=50.0)
    path = tmp_path / "r.npz"
    rec.save_npz(path)
    return path, path.read_bytes(), dict(np.load(path))


@pytest.mark.parametrize("cut", [100, 1000, -30])
def test_load_names_a_truncated_file(tmp_path, cut):
    """A recording cut short (an interrupted copy) is refused with its name, never a traceback."""
    path, data, _ = _saved(tmp_path)
    path.write_bytes(data[:cut])
    with pytest.raises(HostError, match=r"r\.npz: damaged or truncated"):
        Recording.load(path)


def test_load_names_bad_metadata(tmp_path):
    path, _, arrays = _saved(tmp_path)
    meta = arrays["metadata_json"]
    np.savez(path, **{**arrays, "metadata_json": np.array("{not json")})
    with pytest.raises(HostError, match="metadata_json is not JSON"):
        Recording.load(path)
    import json

    m = json.loads(str(meta))
    del m["sampling_rate_hz"]
    np.savez(path, **{**arrays, "metadata_json": np.array(json.dumps(m))})
    with pytest.raises(HostError, match="lacks the field 'sampling_rate_hz'"):
        Recording.load(path)


def test_gap_times():
    rec = Recording.from_arrays(np.zeros((10, 3)), valid=np.arange(10) < 5, first_sample_number=100)
    assert rec.gaps == [Gap(105, 109, "missing")]
    assert rec.gap_times_s(rec.gaps[0]) == (105 / 50, 110 / 50)


def test_summary_lists_at_most_max_listed_gaps_and_counts_the_rest():
    valid = np.ones(60, bool)
    valid[1::4] = False                     # 15 one-sample gaps
    rec = Recording.from_arrays(np.zeros((60, 3)), valid=valid)
    assert len(rec.gaps) == 15
    short = rec.summary(10).splitlines()
    assert sum(line.startswith("  samples ") for line in short) == 10
    assert "  ... 5 more gap(s) (-v lists them all)" in short
    full = rec.summary().splitlines()
    assert sum(line.startswith("  samples ") for line in full) == 15
    assert not any("more gap" in line for line in full)


def test_the_sample_csv_written_in_blocks_equals_one_block(tmp_path, monkeypatch) -> None:
    """``to_csv`` formats a block of rows at a time (bounded memory): the text is the one of a single block,
    cut anywhere (here at 7 rows, across missing samples)."""
    import gaitlog.host.files.recording as recording

    rng = np.random.default_rng(3)
    n = 100
    valid = rng.random(n) > 0.2
    rec = Recording(codes=rng.integers(0, 1024, (n, 3)), valid=valid, flags=rng.integers(0, 4, n),
                    sample_numbers=np.arange(n) + 17, sampling_rate_hz=50.0)
    rec.to_csv(tmp_path / "one.csv")
    monkeypatch.setattr(recording, "_CSV_ROWS", 7)
    rec.to_csv(tmp_path / "blocks.csv")
    assert (tmp_path / "blocks.csv").read_bytes() == (tmp_path / "one.csv").read_bytes()
    assert (tmp_path / "one.csv").read_text().count("\n") == n + 1
