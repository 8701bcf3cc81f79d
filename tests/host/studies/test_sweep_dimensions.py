"""gaitlog sweep's dimensions beyond ADC x rate x noise: Q formats (only the fixed-point chain changes),
mounting misalignment (a rotation of the device by the given angle), population (the population's subjects and
walk habits); the printed answers on rows whose answer is known; the figures."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walk_plan import POPULATION_PLANS
from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.studies.sweep_figures import figure_dimensions, render_error_vs_png
from gaitlog.host.studies.sweep_grid import (
    SUMMARY_KEYS,
    SweepGrid,
    SweepTask,
    analog_walk,
    format_smallest_formats,
    m5_rate_answer,
    misaligned,
    run_task,
    smallest_formats,
    smallest_q_formats,
    walk_plan,
)

PNG = b"\x89PNG\r\n\x1a\n"


def _task(**kw) -> SweepTask:
    base = dict(seed=0, subject_index=0, n_subjects=1, adc_bits=10, sampling_rate_hz=50.0, noise_density_g_rthz=2e-4,
                protocol="short", estimators=("M1", "M2", "M4"))
    return SweepTask(**(base | kw))


def test_q_formats_change_only_the_fixed_point_chain() -> None:
    """acc8 (a_v with 8 fraction bits instead of 13): ideal, offline and on-line float rows are the shipped task's
    exactly; the fixed-point chain moves away from float (per step, M1 by more than 5x the shipped share)."""
    ref, coarse = run_task(_task()), run_task(_task(q_formats="acc8"))
    assert [s["q_formats"] for s in coarse["sections"]][:1] == ["acc8"]
    for a, b in zip(ref["sections"], coarse["sections"], strict=True):
        for k in ("ratio_ideal", "ratio_offline", "ratio_online_float", "ratio_exact_timing"):
            assert a[k] == b[k] or (np.isnan(a[k]) and np.isnan(b[k])), k
    arith = {name: {d["estimator"]: d["median_abs_mm"] for d in res["splits"] if d["share"] == "arithmetic"}
             for name, res in (("ref", ref), ("coarse", coarse))}
    assert arith["coarse"]["M1"] > 5 * arith["ref"]["M1"] and arith["ref"]["M1"] < 0.2, arith


def test_misalignment_rotates_the_device_by_the_angle() -> None:
    s = random_subjects(1, seed=3)[0]
    assert misaligned(s, 0.0) is s
    tilted = misaligned(s, 12.0)
    a = Rotation.from_rotvec(s.mounting_rotation_deg, degrees=True)
    b = Rotation.from_rotvec(tilted.mounting_rotation_deg, degrees=True)
    assert np.degrees((b * a.inv()).magnitude()) == pytest.approx(12.0)
    assert np.allclose((b * a.inv()).as_rotvec(degrees=True), [0.0, 12.0, 0.0])      # a pitch about device y
    assert dataclasses.replace(tilted, mounting_rotation_deg=s.mounting_rotation_deg) == s     # nothing else changed
    with pytest.raises(HostError, match="misalignment"):
        SweepGrid(misalignment_deg=(60.0,))


def test_population_is_the_populations_subjects_and_habits() -> None:
    subject, _ = analog_walk(0, 1, 2, "short", "people", 0.0)
    assert subject == random_subjects(2, seed=0, population="people")[1]
    plan = walk_plan("short", "people")
    for k, v in POPULATION_PLANS["people"].items():
        assert getattr(plan, k) == v
    assert plan.corridor_length_m == 40.0 and walk_plan("paper", "v1") is None
    with pytest.raises(HostError, match="population"):
        SweepGrid(population=("martians",))


def test_grid_checks_and_canonical_labels(tmp_path) -> None:
    g = SweepGrid(q_formats=("shipped", "lp12-acc10"))
    assert g.q_formats == ("shipped", "acc10-lp12") and SweepGrid.from_spec(g.to_spec()) == g
    assert {t.q_formats for t in g.tasks()} == {"shipped", "acc10-lp12"}
    with pytest.raises(HostError, match="acc99"):
        SweepGrid(q_formats=("acc99",))
    with pytest.raises(HostError, match="twice"):
        SweepGrid(q_formats=("acc10", "acc10"))
    with pytest.raises(HostError, match="q_formats"):
        SweepGrid.from_spec({"q_formats": [10]})
    with pytest.raises(SystemExit) as exc:                                   # a usage error, nothing written
        main(["sweep", "--out", str(tmp_path / "x"), "--q-formats", "acc10,bogus3", "--serial"])
    assert exc.value.code == 2
    assert not (tmp_path / "x").exists()


def _summary_row(**kw) -> dict:
    row = dict(adc_bits=10, sampling_rate_hz=50.0, noise_density_g_rthz=2e-4, q_formats="shipped", misalignment_deg=0.0,
               population="v1", mode="multi-speed", estimator="M1", arith_step_mm=0.05, arith_ratio_abs_max=1e-4)
    return row | kw


def test_smallest_q_formats_is_the_last_width_of_an_unbroken_run_within_tolerance() -> None:
    """acc: 13 (shipped), 11, 10 within 1 mm and 1 %, 9 out on the step, 8 back in (noise): the answer is 10,
    never 8. lp: 12 breaks the section tolerance: 16. A set changing two variables answers nothing."""
    rows = [_summary_row(),
            _summary_row(q_formats="acc11", arith_step_mm=0.3), _summary_row(q_formats="acc10", arith_step_mm=0.9),
            _summary_row(q_formats="acc9", arith_step_mm=1.5), _summary_row(q_formats="acc8", arith_step_mm=0.8),
            _summary_row(q_formats="lp12", arith_ratio_abs_max=0.02),
            _summary_row(q_formats="acc4-lp4", arith_step_mm=0.01)]
    got = {r["variable"]: r for r in smallest_q_formats(rows)}
    assert set(got) == {"acc_frac_bits", "lowpass_frac_bits"}
    assert got["acc_frac_bits"]["smallest_frac_bits"] == 10 and got["acc_frac_bits"]["swept_frac_bits"] == "13/11/10/9/8"
    assert got["lowpass_frac_bits"]["smallest_frac_bits"] == 16
    assert smallest_q_formats([_summary_row(arith_step_mm=2.0), _summary_row(q_formats="acc10")])[0][
        "smallest_frac_bits"] is None                                               # the shipped set itself fails
    # a narrower word (alone, or beside fewer fraction bits) is no fraction-bits width: it answers nothing, and
    # is not taken for the shipped set
    words = [_summary_row(), _summary_row(q_formats="acc10"), _summary_row(q_formats="wacc12", arith_step_mm=9.0),
             _summary_row(q_formats="acc9-wacc14", arith_step_mm=9.0)]
    got = smallest_q_formats(words)
    assert [(r["variable"], r["swept_frac_bits"], r["smallest_frac_bits"]) for r in got] == [
        ("acc_frac_bits", "13/10", 10)]


def _width_row(bits: int, **kw) -> dict:
    """A summary row at ``bits`` whose shares halve per bit, as q does: 1.6 mm at 8 bits, 0.8 at 9, 0.4 at 10...;
    the theory predicts half of it (a converter error it does not model); the arithmetic share is small."""
    row = _summary_row(adc_bits=bits, adc_step_mm=1.6 / 2 ** (bits - 8), adc_step_mm_theory=0.8 / 2 ** (bits - 8),
                       arith_step_mm_theory=0.04, adc_ratio_abs_max=0.001)
    return row | kw


def test_smallest_formats_names_the_width_holding_both_shares_measured_beside_predicted() -> None:
    """Measured: 8 bits fails the step (1.6 mm), so 9; predicted (half the measurement) 8. Under INL the section
    error breaks at 9 bits (1.5 %): 10, the theory still 8. Under truncation the arithmetic share fails at every
    width below 11 (1.2 mm): 11, which the theory (0.04 mm) does not see. M5 fails at the widest width: none, and
    the errors are reported at the widest. Each row carries the errors at its width."""
    rows = [_width_row(b) for b in (8, 9, 10, 11, 12)]
    rows += [_width_row(b, inl_lsb=1.0, **({"adc_ratio_abs_max": 0.015} if b <= 9 else {})) for b in (8, 9, 10, 11, 12)]
    rows += [_width_row(b, rounding="truncate", **({"arith_step_mm": 1.2} if b < 11 else {}))
             for b in (8, 9, 10, 11, 12)]
    rows += [_width_row(b, estimator="M5", adc_ratio_abs_max=0.02 if b == 12 else 0.001) for b in (10, 12, 8)]
    rows += [_width_row(10, mode="single-speed", adc_step_mm=5.0)]                            # not the mode asked
    got = {(r["inl_lsb"], r["rounding"], r["estimator"]): r for r in smallest_formats(rows)}
    assert len(got) == 4
    shipped = got[(0.0, "shipped", "M1")]
    assert (shipped["smallest_adc_bits"], shipped["predicted_adc_bits"], shipped["at_bits"]) == (9, 8, 9)
    assert (shipped["adc_step_mm"], shipped["adc_step_mm_theory"]) == (0.8, 0.4)
    inl = got[(1.0, "shipped", "M1")]
    assert (inl["smallest_adc_bits"], inl["predicted_adc_bits"]) == (10, 8)
    trunc = got[(0.0, "truncate", "M1")]
    assert (trunc["smallest_adc_bits"], trunc["predicted_adc_bits"], trunc["arith_step_mm"]) == (11, 8, 0.05)
    m5 = got[(0.0, "shipped", "M5")]
    assert (m5["smallest_adc_bits"], m5["at_bits"], m5["swept_bits"]) == (None, 12, "8/10/12")
    assert m5["adc_ratio_abs_max"] == 0.02
    text = format_smallest_formats(smallest_formats(rows))
    assert text.splitlines()[2].split()[:6] == ["-", "shipped", "M1", "9", "8", "9"]
    assert "inl1" in text and "shipped/truncate" in text and " none " in text
    assert "only one ADC width swept" in format_smallest_formats(smallest_formats([_width_row(10)]))


def _m5_sections(timing_sd: dict[float, float], n_subjects: int = 4, n: int = 60) -> list[dict]:
    rng = np.random.default_rng(5)
    out = []
    for rate, sd in timing_sd.items():
        for subj in range(n_subjects):
            exact = 1.0 + rng.normal(0.0, 0.01, n)
            for mode in ("single-speed", "multi-speed"):
                sampled = exact + rng.normal(0.0, sd, n)
                out += [dict(adc_bits=10, sampling_rate_hz=rate, noise_density_g_rthz=2e-4, q_formats="shipped",
                             misalignment_deg=0.0, population="v1", seed=0, subject=f"S{subj:02d}", mode=mode,
                             estimator="M5", ratio_offline=float(a), ratio_exact_timing=float(e))
                        for a, e in zip(sampled, exact, strict=True)]
    return out


def test_m5_rate_answer_finds_where_the_timing_stops_mattering() -> None:
    """Timing noise of 3 % at 25 Hz, 0.2 % from 50 Hz: the timing part measures it, and the answer is 50 Hz."""
    ans = m5_rate_answer(_m5_sections({25.0: 0.03, 50.0: 0.002, 100.0: 0.002}))
    assert ans["rate_hz"] == 50.0 and "stops mattering at 50 Hz" in ans["verdict"]
    part = {(r["mode"], r["sampling_rate_hz"]): r["timing_part"] for r in ans["rows"]}
    assert part[("multi-speed", 25.0)] == pytest.approx(0.03, rel=0.15)
    assert part[("multi-speed", 100.0)] < 0.006
    assert all(r["timing_part_lo"] <= r["timing_part_hi"] for r in ans["rows"])
    assert m5_rate_answer(_m5_sections({25.0: 0.03, 50.0: 0.03}))["rate_hz"] is None
    assert m5_rate_answer(_m5_sections({25.0: 0.0, 50.0: 0.0}))["rate_hz"] == 25.0


def test_figures_one_per_swept_dimension() -> None:
    rows = [_summary_row(adc_bits=b, q_formats=q, estimator=e, adc_step_mm=2.0 ** (10 - b), adc_step_mm_lo=0.5,
                         adc_step_mm_hi=3.0, arith_step_mm_lo=0.04, arith_step_mm_hi=0.06, median_offline=0.99, median_online_fixed=0.98,
                         subject_median_offline_lo=0.98, subject_median_offline_hi=1.0)
            for b in (8, 10) for q in ("shipped", "acc10") for e in ("M1", "M2")]
    assert set(SUMMARY_KEYS) >= {"adc_bits", "q_formats"}
    assert figure_dimensions(rows) == ["adc_bits", "q_formats"]
    for dim in ("adc_bits", "q_formats"):
        assert render_error_vs_png(rows, dim)[:8] == PNG
    with pytest.raises(ValueError, match="fewer than two"):
        render_error_vs_png(rows, "sampling_rate_hz")
    assert KernelFormats.parse("acc10").label() == "acc10"


def test_rounding_is_a_grid_dimension_and_the_shipped_one_keeps_every_task_name(tmp_path) -> None:
    """--rounding sweeps the fixed-point chain's rounding; at the shipped rounding (and M4's default exponent) a
    task's name is the one it had before these were dimensions (the hash of its other fields), so earlier results
    folders resume."""
    import hashlib
    import json

    with pytest.raises(HostError, match="twice"):          # half-up is the shipped rounding, named
        SweepGrid(rounding=("shipped", "half-up"))
    g = SweepGrid(rounding=("shipped", "mul:truncate+div:convergent"), q_formats=("shipped", "k12"), subjects=1,
                  adc_bits=(10,), sampling_rate_hz=(50.0,))
    assert SweepGrid.from_spec(g.to_spec()) == g and len(g.tasks()) == 4
    t = _task()
    old = {k: v for k, v in dataclasses.asdict(t).items() if k not in ("rounding", "m4_exponent")
           and (not isinstance(v, float) or v != 0.0 or k in ("misalignment_deg",))}
    digest = hashlib.sha256(json.dumps(old, sort_keys=True).encode()).hexdigest()[:12]
    assert t.key.endswith(digest) and "rounding" not in t.key
    r = _task(rounding="truncate")
    assert r.key != t.key and "truncate" in r.key
    assert _task(m4_exponent=0.5).key not in (t.key, r.key)            # M4's exponent: a task of its own
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--out", str(tmp_path / "x"), "--rounding", "shipped,floor", "--serial"])
    assert exc.value.code == 2 and not (tmp_path / "x").exists()
