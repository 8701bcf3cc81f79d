"""IPOL reader: regular packet grid, lost packets marked missing (never invented), JSON indices in packets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaitlog.host.errors import HostError
from gaitlog.host.files.ipol import list_trials, read_lb_file, read_trial
from gaitlog.units import STANDARD_GRAVITY_M_S2

HEADER = "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\n"


def write_trial(folder, name="3-2", counters=(5, 6, 8, 9, 9, 12), meta=None):
    rows = []
    for c in counters:
        rows.append(f"{float(c)}\t{STANDARD_GRAVITY_M_S2 + c}\t{c * 0.1}\t0.5\t0\t0\t0\n")
    (folder / f"{name}_lb.txt").write_text("Acquisition frequency: 100 Hz\n" + HEADER + "".join(rows))
    meta = meta or {"TrialBoundaries": [1, 6], "UTurnBoundaries": [3, 4], "Height": 170,
                    "LeftFootEvents": [[1, 3], [5, 9]], "RightFootEvents": [[2, 6]]}
    (folder / f"{name}.json").write_text(json.dumps(meta))
    return folder / f"{name}_lb.txt"


def test_grid_marks_lost_packets_and_keeps_first_duplicate(tmp_path) -> None:
    p = write_trial(tmp_path)
    acc, valid, rate, first = read_lb_file(p)
    assert rate == 100.0 and first == 5
    assert acc.shape == (8, 3)                       # packets 5..12
    assert valid.tolist() == [True, True, False, True, True, False, False, True]
    assert np.isnan(acc[~valid]).all()               # nothing interpolated
    assert acc[4, 0] * STANDARD_GRAVITY_M_S2 == pytest.approx(STANDARD_GRAVITY_M_S2 + 9)
    assert acc[7, 1] * STANDARD_GRAVITY_M_S2 == pytest.approx(1.2)


def test_trial_metadata(tmp_path) -> None:
    t = read_trial(write_trial(tmp_path))
    assert (t.subject, t.trial, t.name) == (3, 2, "3-2")
    assert t.trial_bounds == (1, 6) and t.uturn_bounds == (3, 4)
    assert t.height_m == pytest.approx(1.70)
    to, hs = t.foot_events()
    assert to.tolist() == [1, 2, 5] and hs.tolist() == [3, 6, 9]
    assert t.reference_steps() == 2                  # heel strikes 3 and 6 inside [1, 6]


def test_duplicate_with_different_values_warns(tmp_path) -> None:
    p = write_trial(tmp_path)
    lines = p.read_text().splitlines(keepends=True)
    lines[-2] = "9.0\t1.0\t2.0\t3.0\t0\t0\t0\n"      # second copy of packet 9, other values
    p.write_text("".join(lines))
    with pytest.warns(UserWarning, match="duplicated"):
        read_lb_file(p)


@pytest.mark.parametrize("mutate, match", [
    (lambda s: s.replace("Acquisition frequency: 100 Hz", "hello"), "Acquisition frequency"),
    (lambda s: s.replace("Acc_Y", "Foo"), "missing column"),
    (lambda s: s.replace("8.0\t", "7.5\t", 1), "not an integer"),
    (lambda s: s.replace("12.0\t", "2.0\t", 1), "backwards"),
    (lambda s: s.replace("0.5\t0", "abc\t0", 1), "bad numeric row"),
])
def test_bad_files_raise_with_place(tmp_path, mutate, match) -> None:
    p = write_trial(tmp_path)
    p.write_text(mutate(p.read_text()))
    with pytest.raises(HostError, match=match):
        read_lb_file(p)


def test_bad_names_and_folders(tmp_path) -> None:
    with pytest.raises(HostError, match="not a directory"):
        list_trials(tmp_path / "nope")
    with pytest.raises(HostError, match="no '<subject>-<trial>_lb.txt'"):
        list_trials(tmp_path)
    bad = tmp_path / "x_lb.txt"
    bad.write_text("")
    with pytest.raises(HostError, match="file name"):
        read_trial(bad)
    p = write_trial(tmp_path)
    (tmp_path / "3-2.json").write_text("{}")
    with pytest.raises(HostError, match="TrialBoundaries"):
        read_trial(p)


def test_real_ipol_trial_on_packet_grid(shared_data) -> None:
    folder = shared_data / "ipol-lowerback-dev"
    files = list_trials(folder)
    assert len(files) == 52 and files[0].name == "1-1_lb.txt"
    t = read_trial(folder / "GaitData" / "3-3_lb.txt")      # 651 lost packets
    assert t.acc_g.shape[0] == 4233 - 1 + 1 and int((~t.valid).sum()) == 651
    norm = np.linalg.norm(t.acc_g[t.valid][:100], axis=1)
    assert np.allclose(norm, 1.0, atol=0.05)                # standing still: 1 g
    assert t.reference_steps() == 41
