"""``gaitlog kinematics`` end to end, and the figure helpers (PNG output, stick-figure ground rule)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.host.cli import main
from gaitlog.host.kinematics.plots import plot_dcm, stick_figure_points

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_kinematics_command_writes_figures_and_small_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "figs"
    assert main(["kinematics", "--out", str(out), "--morris-rate", "200", "--accelerometers", "6", "--snr-db", "inf",
                 "--no-animation"]) == 0
    text = capsys.readouterr().out
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted([
        "hall_joint_angles.png", "hall_joint_angles.csv", "hall_link_orientation.csv", "hall_angular_velocity.csv",
        "morris_angular_velocity.png", "morris_dcm.png", "morris_stick_figure.png", "morris_translation.png",
        "morris_orientation.csv", "morris_angular_velocity.csv", "morris_translation.csv",
    ])
    for p in out.glob("*.png"):
        assert p.read_bytes()[:8] == PNG_MAGIC
    orient = float(re.search(r"as simulated\s+orientation max error ([0-9.e+-]+) deg", text).group(1))
    assert orient < 0.05  # 200 Hz, noise-free, six accelerometers: trapezoid error only
    pos = float(re.search(r"as simulated.*position max error ([0-9.e+-]+) m", text).group(1))
    assert pos < 1e-3
    hall = re.search(r"joint angles\s+max error \(([^)]*)\) deg", text).group(1)
    assert max(float(x) for x in hall.split(",")) < 0.05
    # the non-neutral pre-test posture: the literal sum of incremental Euler angles misses the truth
    assert "literal sum of incremental Euler angles ends at (55.5, -12, 15.2) deg" in text
    assert "final angles      (53.7, -16.9, 11.3) deg, truth (53.7, -16.9, 11.3) deg" in text


def test_kinematics_command_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    afile = tmp_path / "x"
    afile.write_text("")
    assert main(["kinematics", "--out", str(afile)]) == 1
    assert "not a folder" in capsys.readouterr().err
    assert main(["kinematics", "--out", str(tmp_path / "y"), "--hall-rate", "500"]) == 1
    err = capsys.readouterr().err
    assert "CFC 180 filter is invalid at 500 Hz" in err
    assert not (tmp_path / "y").exists()  # no partial output


def test_plot_dcm_is_atomic_png(tmp_path: Path) -> None:
    t = np.linspace(0, 1, 50)
    dcm = Rotation.from_euler("y", t[:, None]).as_matrix()
    plot_dcm(t, dcm, tmp_path / "d.png")
    assert (tmp_path / "d.png").read_bytes()[:8] == PNG_MAGIC
    assert [p.name for p in tmp_path.iterdir()] == ["d.png"]


def test_stick_figure_keeps_the_toe_above_the_ground() -> None:
    ang = np.radians(np.linspace(-30, 30, 61))
    dcm = Rotation.from_euler("y", ang[:, None]).as_matrix()
    origin = np.einsum("nij,j->ni", dcm, [0.0, 0.0, 0.2])  # ankle fixed at 0
    pts = stick_figure_points(dcm, origin, np.array([0.0, 0.0, 0.2]))
    np.testing.assert_allclose(pts["ankle"], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(pts["knee"], axis=1), 0.42, atol=1e-12)
    ground = pts["heel"][:, 1].min()
    assert np.all(pts["toe"][:, 1] >= ground - 1e-12)
    # the foot stays rigid (heel-toe length) after the ankle articulation
    np.testing.assert_allclose(np.linalg.norm(pts["toe"] - pts["heel"], axis=1), 0.24, atol=1e-12)
