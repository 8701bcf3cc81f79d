"""gaitlog estimate / calibrate-k / evaluate: outputs, exit codes, no partial output on bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaitlog.host.cli import main
from gaitlog.units import STANDARD_GRAVITY_M_S2

G = STANDARD_GRAVITY_M_S2


def walk_acc_g(sampling_rate_hz: float = 50.0, step_s: float = 0.55, n_steps: int = 40, amp_m: float = 0.02, seed: int = 0):
    """Tilted device on a sinusoidal CoM with loading pulses (see test_gait_events.synthetic_walk)."""
    rng = np.random.default_rng(seed)
    stand = 2.0
    t = np.arange(int((2 * stand + n_steps * step_s) * sampling_rate_hz)) / sampling_rate_hz
    tw = t - stand
    inside = (tw >= 0) & (tw <= n_steps * step_s)
    w = 2 * np.pi / step_s
    a = np.where(inside, amp_m * w * w * np.cos(w * tw), 0.0)
    for k in range(n_steps + 1):
        a += 3.0 * np.exp(-0.5 * ((tw - k * step_s + 0.06) / 0.02) ** 2)
    a += rng.normal(0, 0.05, t.size)
    up = 1.0 + a / G
    tilt = np.radians(30.0)
    acc = np.c_[up * np.sin(tilt), np.zeros_like(up), up * np.cos(tilt)]
    marks = np.zeros(t.size, np.uint8)
    return acc, marks


def write_csv(path, acc, header=True):
    lines = (["x_g,y_g,z_g"] if header else []) + [f"{x:.6f},{y:.6f},{z:.6f}" for x, y, z in acc]
    path.write_text("\n".join(lines) + "\n")


def write_npz(path, acc, sampling_rate_hz=50.0, valid=None, flags=None):
    from gaitlog.host.files.recording import Recording

    codes = np.clip(np.floor(512 + acc * 256), 0, 1023)
    rec = Recording.from_arrays(codes, valid=valid, flags=flags, sampling_rate_hz=sampling_rate_hz)
    rec.save_npz(path)


def test_estimate_csv_writes_table_and_summary(tmp_path, capsys) -> None:
    acc, _ = walk_acc_g()
    inp = tmp_path / "walk.csv"
    write_csv(inp, acc)
    out = tmp_path / "steps.csv"
    assert main(["estimate", str(inp), "--rate", "50", "--height", "1.75", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "41 steps" in text and "M3" in text
    rows = out.read_text().splitlines()
    assert rows[0].startswith("step,bout,start_s,toe_off_s,heel_strike_s,foot_flat_s,duration_s")
    assert len(rows) == 42
    assert "length_m5_m" in rows[0]


def test_estimate_npz_with_gaps_and_k_file(tmp_path, capsys) -> None:
    acc, _ = walk_acc_g(n_steps=30)
    valid = np.ones(acc.shape[0], bool)
    valid[np.random.default_rng(2).choice(acc.shape[0], 30, replace=False)] = False
    rec = tmp_path / "rec.npz"
    write_npz(rec, acc, valid=valid)
    k = tmp_path / "k.json"
    assert main(["calibrate-k", str(rec), "--distance", "18", "--height", "1.75", "--out", str(k)]) == 0
    out1 = capsys.readouterr().out
    assert "walk-ratio fallback" in out1
    d = json.loads(k.read_text())
    assert d["mode"] == "single-speed" and d["m5_fallback"] is True
    assert main(["estimate", str(rec), "--k-file", str(k)]) == 0
    out2 = capsys.readouterr().out
    line = [ln for ln in out2.splitlines() if ln.startswith("M2")][0]
    assert float(line.split()[1]) == pytest.approx(18.0, rel=1e-6)    # fitted on this recording


def test_estimate_warns_when_k_is_extrapolated(tmp_path, capsys) -> None:
    """Issue 12 (4): K from one walk applied to a walk with slower, deeper steps: the steps outside K's
    calibrated range are counted in the summary and said on stderr; on the calibration walk itself, nothing."""
    cal, other = tmp_path / "cal.npz", tmp_path / "other.npz"
    write_npz(cal, walk_acc_g(n_steps=30)[0], valid=None)
    write_npz(other, walk_acc_g(n_steps=30, step_s=0.7, amp_m=0.035, seed=1)[0], valid=None)
    k = tmp_path / "k.json"
    assert main(["calibrate-k", str(cal), "--distance", "18", "--height", "1.75", "--out", str(k)]) == 0
    capsys.readouterr()
    assert main(["estimate", str(cal), "--k-file", str(k)]) == 0
    assert "outside the range K" not in capsys.readouterr().err
    assert main(["estimate", str(other), "--k-file", str(k)]) == 0
    captured = capsys.readouterr()
    warning = [ln for ln in captured.err.splitlines() if "outside the range K was calibrated on" in ln]
    assert len(warning) == 1 and warning[0].startswith("gaitlog estimate: warning: ")
    line = next(ln for ln in captured.out.splitlines() if ln.startswith("M2"))
    n_out = int(line.split()[-1])
    assert n_out > 20 and f"M2 {n_out} of " in warning[0]


def test_calibrate_k_with_lap_marks(tmp_path, capsys) -> None:
    acc, _ = walk_acc_g(n_steps=40)
    flags = np.zeros(acc.shape[0], np.uint8)
    flags[[150, 600, 1050]] = 2                                      # MARK at three laps
    rec = tmp_path / "laps.npz"
    write_npz(rec, acc, flags=flags)
    k = tmp_path / "k.json"
    assert main(["calibrate-k", str(rec), "--lap-marks", "5", "--height", "1.7", "--out", str(k)]) == 0
    assert json.loads(k.read_text())["n_sections"] == 2


@pytest.mark.parametrize("argv, message", [
    (["estimate", "{d}/missing.csv", "--rate", "50"], "no such file"),
    (["estimate", "{d}/walk.csv"], "--rate"),
    (["estimate", "{d}/bad.csv", "--rate", "50"], "not a number"),
    (["estimate", "{d}/walk.csv", "--rate", "50", "--k-file", "{d}/bad.json"], "format_version"),
    (["calibrate-k", "{d}/walk.csv", "--rate", "50", "--lap-marks", "20", "--out", "{d}/o.json"], "MARK"),
    (["evaluate", "ipol", "{d}", "--out", "{d}/o.csv"], "IPOL layout"),
])
def test_bad_input_exit_1_and_no_output(tmp_path, capsys, argv, message) -> None:
    acc, _ = walk_acc_g(n_steps=10)
    write_csv(tmp_path / "walk.csv", acc)
    (tmp_path / "bad.csv").write_text("x_g,y_g,z_g\n0,0,1\n0,zz,1\n")
    (tmp_path / "bad.json").write_text(json.dumps({"cal_type": "gaitlog.KCalibration", "format_version": "0.1"}))
    before = set(p.name for p in tmp_path.iterdir())
    code = main([a.format(d=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert code == 1 and message in err
    assert set(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("argv, message", [
    (["estimate", "{d}/walk.csv", "--rate", "50", "--height", "175"], "metres"),
    (["estimate", "{d}/walk.csv", "--rate", "50", "--height", "17.5"], "metres"),
    (["calibrate-k", "{d}/walk.csv", "--rate", "50", "--distance", "1", "--distance", "2", "--out", "{d}/o.json"],
     "one value"),
])
def test_bad_option_values_exit_2_and_no_output(tmp_path, capsys, argv, message) -> None:
    acc, _ = walk_acc_g(n_steps=10)
    write_csv(tmp_path / "walk.csv", acc)
    before = set(p.name for p in tmp_path.iterdir())
    try:
        code = main([a.format(d=tmp_path) for a in argv])
    except SystemExit as exc:                      # the parser's own usage error
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert set(p.name for p in tmp_path.iterdir()) == before


def test_cli_help_lists_gait_commands(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "estimate" in out and "calibrate-k" in out and "evaluate" in out


def test_calibrate_k_two_speeds_fits_the_m5_line(tmp_path, capsys) -> None:
    slow, _ = walk_acc_g(step_s=0.62, n_steps=30, seed=4)
    fast, _ = walk_acc_g(step_s=0.48, n_steps=30, seed=5)
    write_npz(tmp_path / "slow.npz", slow)
    write_npz(tmp_path / "fast.npz", fast)
    k = tmp_path / "k.json"
    # 31 steps each (30 + initiation); slow 0.60 m, fast 0.75 m per step: S = K1 / T + K2
    assert main(["calibrate-k", str(tmp_path / "slow.npz"), str(tmp_path / "fast.npz"), "--distance", "18.6",
                 "--distance", "23.25", "--height", "1.75", "--out", str(k)]) == 0
    d = json.loads(k.read_text())
    assert d["mode"] == "multi-speed" and d["m5_fallback"] is False
    k1, k2 = d["k1_m5_m_s"], d["k2_m5_m"]
    assert k1 / 0.62 + k2 == pytest.approx(0.60, abs=0.02)
    assert k1 / 0.48 + k2 == pytest.approx(0.75, abs=0.02)


def test_lengths_default_to_the_logger_step_configuration(tmp_path, capsys) -> None:
    """A decoded recording of a logger that ran its on-line algorithm for a 1.80 m wearer: estimate and
    calibrate-k use those lengths (0.530 H, 0.111 H), not a 1.70 m adult, and say where they came from."""
    acc, _ = walk_acc_g()
    write_csv(tmp_path / "walk.csv", acc)
    assert main(["record", "--motion", "replay", str(tmp_path / "walk.csv"), "--rate", "50", "--height", "1.80",
                 "--out", str(tmp_path / "w.glimg"), "-q"]) == 0
    assert main(["decode", str(tmp_path / "w.glimg"), "--out", str(tmp_path / "w"), "-q"]) == 0
    capsys.readouterr()
    assert main(["estimate", str(tmp_path / "w.npz"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["leg_length_m"] == pytest.approx(0.954, abs=1e-4)       # UQ1.15 in the header: within 3e-5
    assert doc["foot_length_m"] == pytest.approx(0.1998, abs=1e-4)
    assert main(["calibrate-k", str(tmp_path / "w.npz"), "--distance", "22", "--out", str(tmp_path / "k.json")]) == 0
    captured = capsys.readouterr()
    assert "step configuration" in captured.out and "1.70 m adult" not in captured.err
    assert json.loads((tmp_path / "k.json").read_text())["leg_length_m"] == pytest.approx(0.954, abs=1e-4)


def test_calibrate_k_with_the_lower_back_prior(tmp_path, capsys) -> None:
    """--prior lower-back: the file's K is the fitted K shrunk toward the shipped population K with weights
    d / (d + d0), the fitted K and weights are stored and printed; the default is the fitted K alone."""
    from gaitlog.host.gait.k_calibration import KFit
    from gaitlog.host.gait.k_prior import LOWER_BACK_PRIOR

    acc, _ = walk_acc_g(n_steps=30)
    rec = tmp_path / "rec.npz"
    write_npz(rec, acc)
    plain, shrunk = tmp_path / "k.json", tmp_path / "k_prior.json"
    assert main(["calibrate-k", str(rec), "--distance", "18", "--height", "1.75", "--out", str(plain)]) == 0
    capsys.readouterr()
    assert main(["calibrate-k", str(rec), "--distance", "18", "--height", "1.75", "--prior", "lower-back",
                 "--out", str(shrunk)]) == 0
    cap = capsys.readouterr()
    out = cap.out
    assert "shrunk" not in cap.err                        # said once, on stdout: a choice, not a warning
    a, b = KFit.load(plain), KFit.load(shrunk)
    assert a.shrinkage is None and b.shrinkage["source"] == LOWER_BACK_PRIOR.source
    for e in ("M1", "M2", "M4"):
        d0 = LOWER_BACK_PRIOR.distance_m[e]
        pop = LOWER_BACK_PRIOR.population_k(e, a.leg_length_m)
        k = getattr(a, f"k_{e.lower()}")
        assert getattr(b, f"k_{e.lower()}") == pytest.approx((18 * k + d0 * pop) / (18 + d0))
    assert (b.k1_m5_m_s, b.k2_m5_m) == (a.k1_m5_m_s, a.k2_m5_m)
    assert f"K  M1 {b.k_m1:.4f}" in out and "shrunk toward the population K (IPOL lower back" in out
    assert f"M2 {a.k_m2:.4f} (weight {18 / (18 + LOWER_BACK_PRIOR.distance_m['M2']):.2f})" in out


def test_estimate_both_csvs_are_the_library_tables_byte_for_byte(tmp_path, capsys) -> None:
    """``estimate --arithmetic both``'s two CSVs are, byte for byte, the whole-array float chain's table
    (:class:`StepPipeline`, not the streaming one the command runs) and the on-line algorithm's fixed-point table
    on the recording's codes, each formatted by ``columns_csv_text`` with the lengths' source column."""
    from gaitlog.firmware_sim.algorithms.steps import columns_csv_text
    from gaitlog.host.files.inputs import read_acceleration
    from gaitlog.host.files.replay import online_step_table, run_starts
    from gaitlog.host.gait.anthropometry import anatomical_lengths
    from gaitlog.host.gait.pipeline import StepPipeline

    acc, _ = walk_acc_g(n_steps=60)
    inp = tmp_path / "walk.npz"
    write_npz(inp, acc)
    out = tmp_path / "steps.csv"
    assert main(["estimate", str(inp), "--arithmetic", "both", "--height", "1.75", "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    leg, foot = anatomical_lengths(height_m=1.75)
    data = read_acceleration(inp)
    rec = data.recording
    whole = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
        data.g(), sampling_rate_hz=data.sampling_rate_hz, valid=data.valid).steps_
    valid = np.asarray(rec.valid, bool)
    fixed, _ = online_step_table(np.asarray(rec.codes), sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=leg,
                                 foot_length_m=foot, adc_calibration=rec.default_calibration()[0],
                                 adc_bits=int(rec.adc_bits), arithmetic="fixed", valid=valid,
                                 run_starts=run_starts(valid, rec.flags))
    for table, path in ((whole, out), (fixed, tmp_path / "steps_fixed.csv")):
        assert table.n_steps > 40
        expected = columns_csv_text({**table.columns(), "lengths_source": ["height"] * table.n_steps,
                                     "outside_k_range": [""] * table.n_steps})
        assert path.read_bytes() == expected.encode("utf-8")


def test_estimate_both_reports_the_fixed_chains_error_first(tmp_path, capsys, monkeypatch) -> None:
    """``--arithmetic both`` runs the fixed-point chain in a thread beside the float chain: an error is reported as
    when they ran one after the other (the fixed chain's first), exit 1, no table written."""
    from gaitlog.host.errors import HostError
    from gaitlog.host.studies import estimate

    def failing(which: str):
        def fail(*args, **kwargs):
            raise HostError(f"the {which} chain failed")
        return fail

    acc, _ = walk_acc_g()
    inp = tmp_path / "walk.npz"
    write_npz(inp, acc)
    out = tmp_path / "steps.csv"
    for broken, message in ((("fixed", "float"), "the fixed chain failed"), (("float",), "the float chain failed"),
                            (("fixed",), "the fixed chain failed")):
        with monkeypatch.context() as m:
            for which in broken:
                m.setattr(estimate, f"{which}_steps", failing(which))
            assert main(["estimate", str(inp), "--arithmetic", "both", "--height", "1.75", "--out", str(out)]) == 1
        captured = capsys.readouterr()
        assert message in captured.err and "chain failed" not in captured.err.replace(message, "")
        assert not out.exists() and not (tmp_path / "steps_fixed.csv").exists()
