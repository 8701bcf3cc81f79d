"""M4's exponent as a sweep dimension (``gaitlog sweep --m4-exponent``): each task's M4 is the estimator with its
exponent in the offline chains, their K and the step configuration the emulated logger runs with; the other
estimators do not move. One subject, the short protocol, one width and rate, serial."""

from __future__ import annotations

import csv
import math

import pytest

from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.studies.sweep_grid import SweepGrid

#: PROTOCOL.md 2.2: byte 20 of the 32-byte step configuration block is M4's exponent in eighths.
EXPONENT_BYTE = 20
#: Summary columns that are results (not the configuration or the cost model's constants).
RESULT_PREFIXES = ("median_", "iqr_", "subject_median_", "adc_", "arith_")


@pytest.fixture(scope="module")
def swept(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("m4sweep") / "out"
    main(["sweep", "--out", str(out), "--serial", "--protocol", "short", "--subjects", "1", "--seeds", "2",
          "--adc-bits", "10", "--logger-rate", "50", "--m4-exponent", "0.25,0.5", "-q"])
    read = {name: list(csv.DictReader((out / name).open(encoding="utf-8"))) for name in ("summary.csv", "tasks.csv")}
    return read | {"figures": sorted(p.name for p in (out / "figures").glob("*.png"))}


def _rows(swept: dict, est: str, mode: str = "multi-speed") -> dict[float, dict]:
    return {float(r["m4_exponent"]): r for r in swept["summary.csv"] if r["estimator"] == est and r["mode"] == mode}


def test_the_device_stores_each_tasks_exponent_in_eighths(swept) -> None:
    """The step configuration the fixed-point run used, read from its stored bytes: 2/8 and 4/8."""
    stored = {float(t["m4_exponent"]): bytes.fromhex(t["step_config"]) for t in swept["tasks.csv"]}
    assert sorted(stored) == [0.25, 0.5]
    assert all(len(b) == 32 for b in stored.values())
    assert stored[0.25][EXPONENT_BYTE] == 2 and stored[0.5][EXPONENT_BYTE] == 4


@pytest.mark.parametrize("mode", ["single-speed", "multi-speed"])
def test_m4_differs_and_the_other_estimators_do_not(swept, mode) -> None:
    m4 = _rows(swept, "M4", mode)
    assert set(m4) == {0.25, 0.5}
    for col in ("median_offline", "median_online_fixed", "median_ideal"):
        assert math.isfinite(float(m4[0.25][col])) and m4[0.25][col] != m4[0.5][col], col
    for est in ("M1", "M2", "M3", "M5"):
        rows = _rows(swept, est, mode)
        results = [c for c in rows[0.25] if c.startswith(RESULT_PREFIXES)]
        assert len(results) > 10
        assert {c: rows[0.25][c] for c in results} == {c: rows[0.5][c] for c in results}, est


def test_the_logger_computes_m4_with_the_exponent_its_k_was_fitted_with(swept) -> None:
    """Each variant's K is fitted under its own exponent on the offline chain and the logger applies it with the
    exponent its step configuration stores: the on-line fixed-point M4 follows the offline one within the
    arithmetic share (a K for p = 1/2 applied with 1/4 would be off by range^-1/4, about 0.56 at 10 m/s^2)."""
    for p, r in _rows(swept, "M4").items():
        assert abs(float(r["median_offline"]) - 1.0) < 0.1, p
        assert abs(float(r["median_online_fixed"]) - float(r["median_offline"])) < 0.02, p
        assert float(r["arith_step_mm"]) < 1.0, p


def test_the_figure_of_the_dimension_is_drawn(swept) -> None:
    assert "error_vs_m4_exponent.png" in swept["figures"]


@pytest.mark.parametrize("bad", ["0.3", "0", "0.625", "x"])
def test_an_exponent_the_configuration_cannot_store_is_a_usage_error(bad, tmp_path, capsys) -> None:
    assert main(["sweep", "--out", str(tmp_path / "x"), "--serial", "--m4-exponent", f"0.25,{bad}"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--m4-exponent" in err and "0.125, 0.25, 0.375, 0.5" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()
    with pytest.raises(HostError, match="M4 exponent"):
        SweepGrid(m4_exponent=(0.3,))
