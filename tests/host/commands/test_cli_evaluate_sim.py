"""``gaitlog evaluate sim``: simulated subjects through the emulated logger, scored against the world's truth."""

from __future__ import annotations

import csv

import pytest

from gaitlog.host.cli import main


def test_evaluate_sim_writes_sections_summary_and_figure(tmp_path, capsys):
    out = tmp_path / "sim"
    assert main(["evaluate", "sim", str(out), "--subjects", "1", "--seed", "3"]) == 0
    printed = capsys.readouterr().out
    assert "single-speed M2" in printed and "multi-speed  M5" in printed
    for name in ("simulated_sections.csv", "simulated_summary.csv", "simulated_boxplots.png"):
        assert (out / name).stat().st_size > 0, name
    with (out / "simulated_summary.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    medians = {(r["mode"], r["estimator"]): float(r["median"]) for r in rows}
    # ratios are estimated / true distance of each 20 m section of the simulated corridor; calibrated
    # estimators must be centred near 1 (the truth comes from the world, not from the estimators)
    # M4 within 6 %: the 'v1' walkers follow the walk-ratio law, under which the range of a pendulum's vertical
    # acceleration grows as the step length^4 (Weinberg's range^(1/4)); M4's exponent 1/2 is chosen on real
    # people (gaitlog.host.studies.tuning): multi-speed median 1.050 on this subject, 1.028 on 4
    for est, tol in (("M2", 0.05), ("M4", 0.06), ("M5", 0.05)):
        ratio = medians[("multi-speed", est)]
        assert abs(ratio - 1) < tol, (est, ratio)


def test_evaluate_sim_needs_an_output_folder(capsys):
    assert main(["evaluate", "sim"]) == 2
    assert "output folder" in capsys.readouterr().err


def test_evaluate_ipol_needs_folder_and_out(tmp_path, capsys):
    assert main(["evaluate", "ipol", str(tmp_path)]) == 2
    assert "--out" in capsys.readouterr().err


def test_evaluate_ipol_refuses_a_missing_output_folder_before_any_work(tmp_path, capsys):
    """The data folder does not even exist: the output folder is checked first, nothing is written."""
    out = tmp_path / "no-such-folder" / "eval.csv"
    assert main(["evaluate", "ipol", str(tmp_path / "no-data"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"folder {out.parent} does not exist" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("flag", [["--arithmetic", "offline"], ["--figure", "x.png"], ["--uturn", "include"],
                                  ["--distance-m", "40"]])
def test_evaluate_sim_refuses_the_flags_it_cannot_honour(tmp_path, capsys, flag):
    assert main(["evaluate", "sim", str(tmp_path / "o"), "--subjects", "1", *flag]) == 2
    assert f"{flag[0]}: only for 'evaluate ipol'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("flag", [["--subjects", "4"], ["--seed", "1"], ["--workers", "2"], ["--population", "v1"],
                                  ["--protocol", "compact"], ["--laps", "mark"]])
def test_evaluate_ipol_refuses_the_flags_of_sim(tmp_path, capsys, flag):
    """A simulation option given to ``evaluate ipol`` is a usage error (it was silently ignored), before any work."""
    out = tmp_path / "eval.csv"
    assert main(["evaluate", "ipol", str(tmp_path / "no-data"), "--out", str(out), *flag]) == 2
    err = capsys.readouterr().err
    assert f"{flag[0]}: only for 'evaluate sim'" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
