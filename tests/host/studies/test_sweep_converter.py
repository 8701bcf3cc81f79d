"""The converter's and the sensor's effects as sweep dimensions: the sweep's sampled walk gives the codes the
emulated logger stores with the same real converter and drifting sensor; each effect lands where it should (INL
in the ADC share; a calibrated offset and gain error nowhere; drift and 1/f in every chain); ``--inl-lsb 0,1``
runs; ``--list-dimensions`` lists the grid's actual parameters, each with the option that sweeps it."""

from __future__ import annotations

import argparse
import csv
import io
import json
from dataclasses import fields, replace

import numpy as np
import pytest

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.cli import build_parser, main
from gaitlog.host.commands.sweep import EFFECT_OPTIONS
from gaitlog.host.errors import HostError
from gaitlog.host.studies.sweep_figures import DIMENSIONS as FIGURE_DIMENSIONS
from gaitlog.host.studies.sweep_grid import (
    EFFECT_DIMENSIONS,
    OPTIONS,
    SPEC_KEYS,
    SUMMARY_KEYS,
    SweepGrid,
    SweepTask,
    analog_walk,
    dimensions,
    effects_of,
    run_task,
)

BASE = dict(seed=0, subject_index=0, n_subjects=1, adc_bits=10, sampling_rate_hz=50.0, noise_density_g_rthz=2e-4,
            protocol="short", estimators=("M2", "M4"))


def _adc_share_mm(result: dict) -> dict[str, float]:
    return {d["estimator"]: d["median_abs_mm"] for d in result["splits"] if d["share"] == "adc"}


def test_sweep_codes_are_what_the_logger_stores_with_a_real_converter_and_a_drifting_sensor() -> None:
    """Every effect on at once (INL, DNL, offset, gain, 32 kOhm and 250 nF unbuffered after the data sheet's T_ACQ,
    a 1 Hz 1/f corner, +25 C): the sampled walk's 10-bit codes equal the emulated logger's, code for code."""
    effects = dict(inl_lsb=1.0, dnl_lsb=1.0, adc_offset_lsb=2.0, adc_gain_error_lsb=-1.0, acquisition_time_us=19.72,
                   source_impedance_ohm=32e3, source_capacitance_nf=250.0, flicker_corner_hz=1.0,
                   temperature_swing_c=25.0)
    subject, walk = analog_walk(0, 0, 1, "short")
    sensor_changes, converter = effects_of(effects, walk)
    sw = walk.sample(50.0, sensor_changes=sensor_changes, converter=converter)
    sensor = replace(walk.sensor_, **sensor_changes)
    adc = Adc(sampling_rate_hz=50.0, linearity_seed=sensor.seed, **converter)
    res = Logger(sensor=sensor, adc=adc).record(Walking(subject=subject, walk_plan=walk.walk_plan, seed=walk.seed))
    np.testing.assert_array_equal(sw.codes(10), np.asarray(res.codes, np.int64))
    assert res.truth["adc"]["source_impedance_ohm"] == 32e3 and res.truth["sensor"]["flicker_corner_hz"] == 1.0
    # and nothing on: the sampled walk is the ideal converter's, as before
    assert walk.sample(50.0, converter={}).converter is None


def test_each_effect_lands_in_its_share() -> None:
    """INL 1 LSB raises the ADC share (offline - ideal) of M2 and M4 more than 1.5x; a 2 LSB offset and 1 LSB gain
    error, calibrated away as a pose calibration would, leave it within 10 %; a 25 C swing moves the section
    ratios of every chain (ideal included) but not the ADC share."""
    ref = run_task(SweepTask(**BASE))
    inl = run_task(SweepTask(**BASE, inl_lsb=1.0))
    lin = run_task(SweepTask(**BASE, adc_offset_lsb=2.0, adc_gain_error_lsb=1.0))
    hot = run_task(SweepTask(**BASE, temperature_swing_c=25.0))
    for est in ("M2", "M4"):
        assert _adc_share_mm(inl)[est] > 1.5 * _adc_share_mm(ref)[est]
        assert _adc_share_mm(lin)[est] == pytest.approx(_adc_share_mm(ref)[est], rel=0.1)
        assert _adc_share_mm(hot)[est] == pytest.approx(_adc_share_mm(ref)[est], rel=0.2)
    moved = [a["ratio_ideal"] != b["ratio_ideal"] for a, b in zip(ref["sections"], hot["sections"], strict=True)]
    assert all(moved)
    assert inl["sections"][0]["inl_lsb"] == 1.0 and ref["sections"][0]["inl_lsb"] == 0.0


def test_default_tasks_keep_their_names_and_grids_check_the_effects() -> None:
    tasks = SweepGrid(subjects=1, adc_bits=(10,), sampling_rate_hz=(50.0,), protocol="short",
                      q_formats=("shipped", "acc10")).tasks()
    assert [t.key for t in tasks] == ["seed0-s0-10b-50Hz-n0.0002-shipped-eeb60b855f57",
                                      "seed0-s0-10b-50Hz-n0.0002-acc10-329fff21e92a"]     # as before the effects
    g = SweepGrid(subjects=1, adc_bits=(10,), sampling_rate_hz=(50.0,), inl_lsb=(0, 1), temperature_swing_c=(-10, 25))
    assert len(g.tasks()) == 4 and SweepGrid.from_spec(g.to_spec()) == g
    assert "inl1-" in g.tasks()[-1].key
    with pytest.raises(HostError, match="dnl_lsb"):
        SweepGrid(dnl_lsb=(2.0,))
    with pytest.raises(HostError, match="inl_lsb"):
        SweepGrid(inl_lsb=(-1.0,))


def test_inl_sweep_runs_from_the_command_line(tmp_path, capsys) -> None:
    out = tmp_path / "sweep"
    rc = main(["sweep", "--out", str(out), "--serial", "--protocol", "short", "--subjects", "1", "--adc-bits", "10",
               "--logger-rate", "50", "--inl-lsb", "0,1", "--estimators", "M2", "-q"])
    assert rc == 0
    header, *rows = (out / "summary.csv").read_text().splitlines()
    assert "inl_lsb" in header.split(",") and len(rows) == 4                 # 2 INL x 2 modes x M2
    assert (out / "figures" / "error_vs_inl_lsb.png").exists()
    assert set(SUMMARY_KEYS) <= set(FIGURE_DIMENSIONS)                     # every dimension can be drawn
    with pytest.raises(SystemExit) as exit_info:                              # usage error: exit 2
        main(["sweep", "--out", str(out), "--inl-lsb", "0,9"])
    assert exit_info.value.code == 2 and "--inl-lsb" in capsys.readouterr().err


def _sweep_parser() -> argparse.ArgumentParser:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices["sweep"]


def test_list_dimensions_matches_the_sweeps_parameters(capsys) -> None:
    """Every grid dimension is listed as sweepable with the option that sweeps it (an option of the command),
    its unit and the grid's default; each Q format's word and fraction bits, the rounding and M4's exponent
    are listed, each with the option that sweeps it (none says "not yet sweepable")."""
    with pytest.raises(SystemExit) as exit_info:
        main(["sweep", "--list-dimensions"])
    assert exit_info.value.code in (0, None)
    lines = capsys.readouterr().out.splitlines()
    dims = dimensions()
    assert len(lines) == len(dims) + 1
    sweepable = {d.name for d in dims if d.option is not None and "." not in d.name}
    assert sweepable == set(SPEC_KEYS) - {"estimators", "protocol"}
    grid_fields = {f.name for f in fields(SweepGrid)}
    task_fields = {f.name for f in fields(SweepTask)}
    parser_options = {o for a in _sweep_parser()._actions for o in a.option_strings}
    for d in dims:
        line = next(x for x in lines if x.split()[0] == d.name)
        assert f"default {d.default}" in line and d.unit in line
        if d.option is None:
            assert "not yet sweepable" in line and d.name not in grid_fields
        else:
            assert d.option.split()[0] in parser_options
        if d.name in grid_fields and d.name not in ("subjects", "seeds", "q_formats", "population"):
            assert d.name in task_fields
    names = {d.name for d in dims}
    assert {"rounding", "m4_exponent", "K_Q.word_bits", "K_Q.frac_bits", "ACC_Q.frac_bits"} <= names
    # every format's word and fraction bits sweep, and M4's exponent
    assert {d.name for d in dims if d.option is None} == set()
    assert next(d for d in dims if d.name == "m4_exponent").option == "--m4-exponent"
    words = {d.name: d.option for d in dims if d.name.endswith(".word_bits")}
    assert len(words) == len([d for d in dims if d.name.endswith(".frac_bits")]) > 20
    for name, option in words.items():
        token = option.split()[-1].rstrip("N")
        if name not in ("LOWPASS_Q.word_bits", "MANTISSA_Q.word_bits"):
            q = KernelFormats.parse(f"{token}8")          # the token sweeps that format's word
            assert q.label() == f"{token}8", name
    lowpass_word = next(d for d in dims if d.name == "LOWPASS_Q.word_bits")
    assert lowpass_word.option == "--q-formats lpintN" and lowpass_word.default == "19"
    assert next(d for d in dims if d.name == "rounding").option == "--rounding"
    # the command's options are the grid's effects, with their units and ranges
    assert [(k, u, hi) for k, u, _, _, hi in EFFECT_OPTIONS] == [(k, v[1], v[2]) for k, v in EFFECT_DIMENSIONS.items()]
    assert set(OPTIONS) == sweepable


def test_a_results_folder_from_before_the_effects_resumes_as_effects_off(tmp_path) -> None:
    """A task stored without the effect columns (as every task was before) is found by its unchanged name and
    read as all effects off; a new INL value is computed beside it."""
    out = tmp_path / "old"
    args = ["sweep", "--out", str(out), "--serial", "--protocol", "short", "--subjects", "1", "--adc-bits", "10",
            "--logger-rate", "50", "--estimators", "M2", "-q"]
    assert main(args) == 0
    (stored,) = (out / "tasks").glob("*.json")
    doc = json.loads(stored.read_text())
    for part in ("sections", "splits"):
        for row in doc[part]:
            for k in EFFECT_DIMENSIONS:
                row.pop(k, None)
    stored.write_text(json.dumps(doc))
    assert main(args + ["--inl-lsb", "0,1"]) == 0
    assert len(list((out / "tasks").glob("*.json"))) == 2
    rows = list(csv.DictReader(io.StringIO((out / "sections.csv").read_text())))
    assert {r["inl_lsb"] for r in rows} == {"0", "1"}
