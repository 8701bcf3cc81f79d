"""``gaitlog compare`` and ``gaitlog estimate --arithmetic`` on a decoded recording of a simulated walk.

The logger runs its on-line step algorithm while it records (uncalibrated, the subject's leg and foot), so the
recording's own step records can be checked against the host's replay.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from gaitlog.host.cli import main


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import Subject
    from gaitlog.firmware_sim.world.walk_plan import WalkPlan
    from gaitlog.firmware_sim.world.walking import Walking
    from gaitlog.host.files.decode import decode_file, save_outputs
    from gaitlog.protocol.steps import StepConfig

    d = tmp_path_factory.mktemp("cmp")
    walk_plan = WalkPlan(corridor_length_m=50.0, speeds=("preferred",), lap_marks_m=(0.0, 10.0, 30.0, 50.0,
                                                                                          70.0, 90.0, 100.0))
    subject = Subject()
    logger = Logger(device_id=3, step_config=StepConfig(step_format=1, leg_length_m=subject.leg_length_m,
                                                        foot_length_m=subject.foot_length_m))
    res = logger.record(Walking(subject=subject, walk_plan=walk_plan, seed=2))
    logger.save_image(d / "walk.glimg")
    path, _ = save_outputs(decode_file(d / "walk.glimg"), d / "walk")
    records, ok = logger.steps.records_in_order()
    assert ok.all() and records.size > 30
    return path, res, records


def _with_records(monkeypatch, records) -> None:
    """Recordings loaded from now on carry these device step records instead of their own (a device whose
    firmware computed differently)."""
    from gaitlog.host.files.recording import Recording

    load = Recording.load.__func__

    def loader(cls, path):
        rec = load(cls, path)
        rec.step_records = records
        return rec

    monkeypatch.setattr(Recording, "load", classmethod(loader))


def test_compare_recording_writes_tables(npz, tmp_path, capsys) -> None:
    path, res, records = npz
    out = tmp_path / "steps.csv"
    assert main(["compare", str(path), "--out", str(out), "--height", "1.75"]) == 0
    text = capsys.readouterr().out
    assert "online-fixed - online-float" in text and "online-float - offline" in text
    assert "saturation/wrap in the fixed-point run: none" in text
    # the decoded recording carries the device's own records: they are checked against the replay
    assert f"device step records vs host replay: {records.size} of {records.size} identical byte for byte" in text
    with open(out, newline="") as fh:
        steps = list(csv.DictReader(fh))
    # truth: the world's steps (one row per foot-flat; the closing contact ends the last step)
    n_truth = len(res.truth["steps"]["length_m"])
    assert abs(len(steps) - n_truth) <= 2
    d = [abs(float(r["m2_online_fixed_m"]) - float(r["m2_online_float_m"])) for r in steps
         if r["m2_online_fixed_m"] and r["m2_online_float_m"]]
    assert len(d) >= n_truth - 4 and np.median(d) <= 1e-4
    a = [abs(float(r["m2_online_float_m"]) - float(r["m2_offline_m"])) for r in steps
         if r["m2_online_float_m"] and r["m2_offline_m"]]
    assert len(a) >= n_truth - 4 and np.median(a) <= 0.02        # the algorithms differ by ~1 % of a step
    with open(tmp_path / "steps_segments.csv", newline="") as fh:
        seg = list(csv.DictReader(fh))
    # MARK flags every lap: 6 intervals x 5 estimators
    assert len(seg) == 6 * 5 and {r["estimator"] for r in seg} == {"M1", "M2", "M3", "M4", "M5"}
    with open(tmp_path / "steps_split.csv", newline="") as fh:
        assert [r["pair"] for r in csv.DictReader(fh)] == (["online-float - offline"] * 5
                                                           + ["online-fixed - online-float"] * 5)


def test_compare_checks_the_device_records(npz, tmp_path, capsys) -> None:
    """The recording's own step records equal the host's replay byte for byte, and the command says so."""
    path, _, records = npz
    assert main(["compare", str(path), "--height", "1.75"]) == 0
    text = capsys.readouterr().out
    assert f"device step records vs host replay: {records.size} of {records.size} identical byte for byte" in text


def test_compare_refuses_device_records_that_differ(npz, tmp_path, monkeypatch, capsys) -> None:
    """A record the device computed differently (here M2 of one record, CRC recomputed: a firmware bug, not
    a transmission error) is an error naming the record; nothing is written."""
    from gaitlog.protocol.steps import STEP_RECORD_DTYPE, pack_step_records

    path, _, records = npz
    bad = records.copy()
    bad["length_m2_q14"][7] += 3
    bad = np.frombuffer(pack_step_records(bad), dtype=STEP_RECORD_DTYPE).copy()
    _with_records(monkeypatch, bad)
    out = tmp_path / "steps.csv"
    assert main(["compare", str(path), "--out", str(out), "--height", "1.75"]) == 1
    err = capsys.readouterr().err
    assert "1 DIFFERENT" in err and f"ends at sample {int(records['end_sample'][7])}" in err
    assert "length_m2_q14: device" in err
    assert not out.exists()


def test_estimate_arithmetic_both(npz, tmp_path, capsys) -> None:
    path, _, _ = npz
    out = tmp_path / "e.csv"
    assert main(["estimate", str(path), "--arithmetic", "both", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "arithmetic = float" in text and "arithmetic = fixed" in text
    with open(out, newline="") as fh:
        a = list(csv.DictReader(fh))
    with open(tmp_path / "e_fixed.csv", newline="") as fh:
        b = list(csv.DictReader(fh))
    assert len(a) == len(b) > 30
    x = np.array([float(r["length_m2_m"] or "nan") for r in a])
    y = np.array([float(r["length_m2_m"] or "nan") for r in b])
    g = np.isfinite(x) & np.isfinite(y)
    assert np.median(np.abs(x[g] - y[g])) <= 0.02                # offline vs the on-line algorithm


def test_estimate_fixed_is_the_device_algorithm(npz, tmp_path, capsys) -> None:
    """--arithmetic fixed without K: the raw M1-M3 of the on-line algorithm in fixed point, i.e. what the
    logger stored (its records hold the raw UQ2.14 lengths)."""
    from gaitlog.firmware_sim.world.subject import Subject

    path, res, records = npz
    s = Subject()                             # the walker of the fixture, whose leg and foot the logger has
    out = tmp_path / "fx.csv"
    assert main(["estimate", str(path), "--arithmetic", "fixed", "--out", str(out), "--leg-length",
                 repr(s.leg_length_m), "--foot-length", repr(s.foot_length_m)]) == 0
    capsys.readouterr()
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == records.size
    for name in ("m1", "m2", "m3"):
        dev = records[f"length_{name}_q14"] / 2.0 ** 14
        got = np.array([float(r[f"length_{name}_m"] or 0) for r in rows])
        np.testing.assert_allclose(got, dev, atol=1e-6)


def test_a_k_the_step_configuration_cannot_hold_is_an_error(npz, tmp_path, capsys) -> None:
    """K of M1 is stored as unsigned Q1.15 (below 2): a K file with 2.5 cannot be given to the on-line algorithm."""
    from gaitlog.host.gait.k_calibration import KFit

    path, _, _ = npz
    k = tmp_path / "k.json"
    KFit(k_m1=2.5, k_m2=1.0, k_m4=0.5, k1_m5_m_s=0.4, k2_m5_m=0.0, mode="single-speed", m5_fallback=True,
                 leg_length_m=0.94, foot_length_m=0.2, n_sections=1, n_steps=30, distance_m=20.0).save(k)
    out = tmp_path / "steps.csv"
    assert main(["compare", str(path), "--k-file", str(k), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "step configuration cannot hold" in err and "k_m1" in err
    assert not out.exists()


def test_bad_invocations(npz, tmp_path, capsys) -> None:
    path, _, _ = npz
    assert main(["compare"]) == 2                             # usage errors the command finds: exit 2 too
    assert main(["compare", str(path), "--sweep"]) == 2
    assert main(["compare", str(tmp_path / "missing.npz")]) == 1
    with pytest.raises(SystemExit) as usage:                  # a bad number is a usage error (exit 2)
        main(["compare", "--simulate", "0"])
    assert usage.value.code == 2
    csv_in = tmp_path / "g.csv"
    csv_in.write_text("x_g,y_g,z_g\n" + "0,0,1\n" * 100)
    assert main(["estimate", str(csv_in), "--rate", "50", "--arithmetic", "fixed"]) == 1
    err = capsys.readouterr().err
    assert "needs ADC codes" in err and "exactly one of" in err
    assert main(["compare", "--sweep", "--population", "v1", "--out", "s.csv"]) == 2  # moved: the line to run instead
    assert ("--sweep: moved to gaitlog sweep; the same grid (ADC 8/10/12 bits x 25/50/100 Hz) is `gaitlog sweep "
            "--out s --subjects 4 --seeds 0 --population v1 --workers 2`") in capsys.readouterr().err


def test_demo_walks_estimates_and_compares(tmp_path, capsys) -> None:
    """The demo's walking stages: 20 m table and box plots (offline chain), the device's own step records
    with the subject's K beside the offline chain (bit for bit against the replay), the error split."""
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for stage in ("[walk]", "[estimate]", "[device]", "[split]"):
        assert stage in out
    assert (tmp_path / "walk_boxplots.png").stat().st_size > 1000
    with open(tmp_path / "walk_sections.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["mode"] for r in rows} == {"single-speed", "multi-speed"}
    # the world walked 20 m per section: multi-speed M2 within 10 % of it
    m2 = [float(r["ratio"]) for r in rows if r["mode"] == "multi-speed" and r["estimator"] == "M2"]
    assert len(m2) >= 20 and abs(np.median(m2) - 1.0) < 0.10
    # the device's records: as many as the walk's foot-flats, identical to the host's replay
    device = out.split("[device]")[1].split("[split]")[0]
    n = int(device.split("->")[1].split(":")[1].split()[0])
    assert n > 1000 and f"{n} of {n} identical byte for byte" in device
    table = {ln.split()[0]: [float(x) for x in ln.split()[1:]] for ln in device.splitlines()
             if ln.strip()[:2] in ("M1", "M2", "M3", "M4", "M5")}
    for est, (n_sec, dev, off, worst, step_mm) in table.items():
        assert n_sec >= 20 and abs(dev - off) < 0.02, est          # the same K: device ~ offline chain
        assert abs(dev - 1.0) < 0.1, est
    with open(tmp_path / "walk_split.csv", newline="") as fh:
        seg = list(csv.DictReader(fh))
    for est in ("M1", "M2", "M3", "M4", "M5"):
        d = np.array([abs(float(r["ratio_online_fixed"]) - float(r["ratio_online_float"])) for r in seg
                      if r["estimator"] == est])
        assert np.median(d) <= 1e-4, est                             # the arithmetic alone: one K for both
        assert d.max() < 0.04, est      # a step whose events differ moves a section by less than one step / 20 m
    assert "saturation/wrap: none" in out


def test_compare_quiet_and_verbose(npz, tmp_path, capsys) -> None:
    """-q prints nothing and still writes what --out asks for; -v adds detail lines to the default output."""
    path, _, _ = npz
    out = tmp_path / "q.csv"
    assert main(["compare", str(path), "--out", str(out), "--height", "1.75", "-q"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert out.stat().st_size > 0 and (tmp_path / "q_segments.csv").exists()
    assert main(["compare", str(path), "--height", "1.75"]) == 0
    default = capsys.readouterr().out
    assert main(["compare", str(path), "--height", "1.75", "-v"]) == 0
    verbose = capsys.readouterr().out
    assert "run(s) of contiguous samples" in verbose and "run(s) of contiguous samples" not in default
    assert set(default.splitlines()) <= set(verbose.splitlines())
