"""``gaitlog calibrate`` on CSV files: units, rate, columns, header detection, and every refusal (exit 1)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.cli import main
from gaitlog.units import STANDARD_GRAVITY_M_S2

RATE_HZ = 50.0
OFFSET_G = np.array([0.05, -0.03, 0.02])
SCALE = np.array([1.02, 0.98, 1.01])


def session_g(n_poses: int = 14, seed: int = 0, orientations=None) -> np.ndarray:
    motion = CalibrationPoses(n_poses=n_poses, hold_s=4.0, move_s=1.5, seed=seed,
                              orientations=orientations).render(RATE_HZ)
    rng = np.random.default_rng(seed)
    return OFFSET_G + SCALE * motion.acc_g + 0.002 * rng.standard_normal(motion.acc_g.shape)


def write(path, header: str | None, rows: np.ndarray, prefix: list[str] | None = None, fmt: str = "%.6f"):
    lines = list(prefix or [])
    if header is not None:
        lines.append(header)
    lines += [",".join(fmt % v for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(["calibrate", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_csv_in_g_with_header_time_column_and_units_from_names(tmp_path, capsys):
    acc = session_g()
    t = np.arange(len(acc)) / RATE_HZ
    csv_path = write(tmp_path / "s.csv", "sample_number,time_s,x_g,y_g,z_g",
                     np.c_[np.arange(len(acc)), t, acc])
    out = tmp_path / "cal.json"
    code, text, err = run_cli(capsys, str(csv_path), "--out", str(out), "--model", "6-param")
    assert code == 0, err
    assert "static poses: 14 used" in text and "50 Hz, g" in text and "|a|-1 (mg)" in text
    cal = AccCalibration.load(out)
    assert cal.input_unit == "g" and cal.model == "6-param"
    np.testing.assert_allclose(cal.offset, OFFSET_G, atol=2e-3)
    np.testing.assert_allclose(cal.scale_per_g, SCALE, rtol=2e-3)


def test_csv_in_m_s2_without_header(tmp_path, capsys):
    acc = session_g(seed=1) * STANDARD_GRAVITY_M_S2
    csv_path = write(tmp_path / "s.csv", None, acc)
    out = tmp_path / "cal.json"
    code, text, err = run_cli(capsys, str(csv_path), "--out", str(out), "--units", "m/s2", "--rate", "50")
    assert code == 0, err
    cal = AccCalibration.load(out)
    assert cal.input_unit == "g" and cal.model == "9-param"  # m/s^2 are converted to g before the fit
    np.testing.assert_allclose(cal.offset, OFFSET_G, atol=2e-3)


def test_csv_counts_with_columns_by_index_and_skipped_preamble(tmp_path, capsys):
    acc = session_g(seed=2)
    counts = np.round(512 + 255.6 * acc)
    rows = np.c_[np.arange(len(acc)), counts, np.zeros(len(acc))]
    csv_path = write(tmp_path / "s.csv", "n;ignored;a;b;c".replace(";", ","), rows[:, [0, 4, 1, 2, 3]],
                     prefix=["# exported by some tool", "# device 12"], fmt="%.0f")
    out = tmp_path / "cal.json"
    code, text, err = run_cli(capsys, str(csv_path), "--out", str(out), "--units", "counts", "--rate", "50",
                              "--columns", "2,3,4", "--skip-rows", "2")
    assert code == 0, err
    cal = AccCalibration.load(out)
    assert cal.input_unit == "counts"
    np.testing.assert_allclose(cal.offset, 512 + 255.6 * OFFSET_G, atol=0.5)
    np.testing.assert_allclose(cal.scale_per_g, 255.6 * SCALE, rtol=2e-3)
    # by name
    code, _, err = run_cli(capsys, str(csv_path), "--out", str(out), "--units", "counts", "--rate", "50",
                           "--columns", "a,b,c", "--skip-rows", "2", "--force")
    assert code == 0, err


@pytest.mark.parametrize(
    ("mutate", "args", "message"),
    [
        (lambda lines: lines.__setitem__(40, "0.1,abc,0.9"), ["--units", "g", "--rate", "50"],
         r"line 41, y_g: not a number: 'abc'"),
        (lambda lines: None, ["--units", "g"], r"no time column \(time_s/time/t/t_s\) to take the rate from; give --rate"),
        (lambda lines: lines.__setitem__(0, "a,b,c"), ["--rate", "50", "--units", "m/s2"],
         r"median acceleration norm is 1, not what gravity gives in m/s2"),
        (lambda lines: None, ["--units", "g", "--rate", "50", "--columns", "x_g,y_g,w"], r"no column 'w'"),
        (lambda lines: None, ["--units", "g", "--rate", "50", "--columns", "0,1"], r"expected three columns"),
    ],
)
def test_csv_errors_name_the_place_exit_1_and_write_nothing(tmp_path, capsys, mutate, args, message):
    acc = session_g(n_poses=10)
    lines = ["x_g,y_g,z_g"] + [",".join(f"{v:.6f}" for v in r) for r in acc]
    mutate(lines)
    csv_path = tmp_path / "s.csv"
    csv_path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cal.json"
    code, text, err = run_cli(capsys, str(csv_path), "--out", str(out), *args)
    assert code == 1
    assert err.startswith("gaitlog calibrate: error:")
    import re

    assert re.search(message, err), err
    assert not out.exists()


def test_too_few_poses_and_unobserved_axis_are_refused(tmp_path, capsys):
    from scipy.spatial.transform import Rotation

    out = tmp_path / "cal.json"
    few = write(tmp_path / "few.csv", "x_g,y_g,z_g", session_g(n_poses=7))
    code, _, err = run_cli(capsys, str(few), "--out", str(out), "--rate", "50")
    assert code == 1 and "found 7 static poses" in err and "needs at least 9" in err
    # 12 poses turning only about the device's x axis: gravity never has an x component
    rots = Rotation.from_rotvec(np.c_[np.linspace(0, 2 * np.pi, 12, endpoint=False), np.zeros((12, 2))])
    flat = write(tmp_path / "flat.csv", "x_g,y_g,z_g", session_g(orientations=rots))
    code, _, err = run_cli(capsys, str(flat), "--out", str(out), "--rate", "50")
    assert code == 1 and "mostly the x axis" in err and "unobserved" in err
    assert not out.exists()


def test_missing_input_file(tmp_path, capsys):
    code, _, err = run_cli(capsys, str(tmp_path / "nope.csv"), "--out", str(tmp_path / "c.json"))
    assert code == 1 and "no such file" in err


def test_help_lists_the_options(capsys):
    with pytest.raises(SystemExit) as info:
        main(["calibrate", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for opt in ("--out", "--model", "--units", "--rate", "--columns", "--skip-rows", "--hold", "--min-angle"):
        assert opt in text


def test_binary_file_is_not_taken_for_a_csv(tmp_path, capsys):
    path = tmp_path / "b.csv"
    path.write_bytes(b"\xff\xfe\x00\x01binary")
    code, _, err = run_cli(capsys, str(path), "--out", str(tmp_path / "c.json"))
    assert code == 1 and "not a logger file, a decoded .npz, an IPOL file or a CSV text" in err


@pytest.mark.parametrize("cell", ["", "nan"])
def test_empty_or_nan_cell_is_a_missing_sample(tmp_path, capsys, cell):
    acc = session_g(n_poses=12)
    lines = ["x_g,y_g,z_g"] + [",".join(f"{v:.6f}" for v in r) for r in acc]
    lines[40] = f"0.1,{cell},0.9"
    path = tmp_path / "s.csv"
    path.write_text("\n".join(lines) + "\n")
    code, text, err = run_cli(capsys, str(path), "--out", str(tmp_path / "c.json"), "--rate", "50")
    assert code == 0, err
    assert f"({len(acc) - 1} valid samples of {len(acc)}, 50 Hz, g)" in text


def test_units_told_by_the_data_when_the_names_do_not(tmp_path, capsys):
    acc = session_g(n_poses=12)
    for scale, unit in ((1.0, "g"), (9.80665, "m/s2")):
        path = write(tmp_path / f"s{scale}.csv", "a,b,c", acc * scale)
        code, text, err = run_cli(capsys, str(path), "--out", str(tmp_path / "c.json"), "--rate", "50",
                                  "--model", "6-param", "--force")
        assert code == 0, err
        assert "rms" in text and f"(CSV, {unit}" not in text   # the fit runs in g either way
        assert ", 50 Hz, g)" in text
