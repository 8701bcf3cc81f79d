"""gaitlog sweep: the grid's tasks, their identity across 1 process, a 2-worker Dask LocalCluster and a
scheduler started separately on the loopback address (a Q-format set JIT-compiled in each worker included), and
resuming after a cut."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.studies.sweep_grid import (
    SENSOR_NOISE_G_RTHZ,
    SweepGrid,
    analog_walk,
    run_task,
)
from gaitlog.host.studies.task_store import TaskStore, run_serial

ROOT = Path(__file__).resolve().parents[3]
#: 8 tasks: one subject of the short protocol, 2 widths x 2 rates x 2 Q-format sets, two estimators kept.
GRID_ARGS = ["--protocol", "short", "--subjects", "1", "--seeds", "0", "--adc-bits", "8,10",
             "--logger-rate", "25,50", "--q-formats", "shipped,acc10", "--estimators", "M2,M5"]
OUTPUTS = ("sections.csv", "splits.csv", "tasks.csv", "summary.csv", "smallest_bits.csv", "smallest_q_formats.csv",
           "smallest_formats.csv", "m5_rate.csv")


def _grid() -> SweepGrid:
    return SweepGrid(adc_bits=(8, 10), sampling_rate_hz=(25.0, 50.0), q_formats=("shipped", "acc10"), subjects=1,
                     seeds=(0,), estimators=("M2", "M5"), protocol="short")


def _files(folder: Path) -> dict[str, bytes]:
    out = {f"tasks/{p.name}": p.read_bytes() for p in sorted((folder / "tasks").glob("*.json"))}
    return out | {n: (folder / n).read_bytes() for n in OUTPUTS if (folder / n).exists()}


@pytest.fixture(scope="module")
def serial(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sweep_serial")
    assert main(["sweep", "--out", str(out), "--serial", "-q", *GRID_ARGS]) == 0
    return out


def test_spec_file_and_options_make_the_same_grid(tmp_path) -> None:
    spec = tmp_path / "grid.toml"
    spec.write_text('adc_bits = [8, 10]\nsampling_rate_hz = [25, 50]\nsubjects = 1\nseeds = 0\n'
                    'q_formats = ["shipped", "acc10"]\nestimators = ["M2", "M5"]\nprotocol = "short"\n')
    assert SweepGrid.load(spec) == _grid()
    (tmp_path / "grid.json").write_text(json.dumps(_grid().to_spec()))
    assert SweepGrid.load(tmp_path / "grid.json") == _grid()
    assert len(_grid().tasks()) == 8 and len({t.key for t in _grid().tasks()}) == 8
    (tmp_path / "bad.toml").write_text("adc_bits = [8]\nbitz = 3\n")
    with pytest.raises(HostError, match="bad.toml: unknown key.*bitz"):
        SweepGrid.load(tmp_path / "bad.toml")
    with pytest.raises(HostError, match="ADC bits"):
        SweepGrid(adc_bits=(40,))


def test_noise_density_scales_the_sensor_noise() -> None:
    """The noise sweep: the sampled input differs from a noise-free one by the sensor's rms noise (analytic)."""
    _, walk = analog_walk(0, 0, 1, "short")
    quiet = walk.sample(50.0, noise_density_g_rthz=0.0)
    for density in (SENSOR_NOISE_G_RTHZ, 4 * SENSOR_NOISE_G_RTHZ):
        noisy = walk.sample(50.0, noise_density_g_rthz=density)
        inside = (quiet.code_10 > 1) & (quiet.code_10 < 1022) & (noisy.code_10 > 1) & (noisy.code_10 < 1022)
        d_code = np.where(inside, noisy.code_10 - quiet.code_10, np.nan)
        d_g = np.linalg.solve(quiet.gain_matrix_code_10, np.nan_to_num(d_code).T).T[inside.all(axis=1)]
        expected = density * np.sqrt(np.pi / 2.0 * walk.sensor_.cutoff_hz)       # white noise through the RC
        np.testing.assert_allclose(d_g.std(axis=0), expected, rtol=0.1)
    assert np.array_equal(walk.sample(50.0, noise_density_g_rthz=SENSOR_NOISE_G_RTHZ).code_10, walk.sample(50.0).code_10)


def test_serial_outputs(serial) -> None:
    lines = (serial / "sections.csv").read_text().splitlines()
    head = lines[0].split(",")
    assert head[:8] == ["adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "q_formats", "misalignment_deg",
                        "population", "protocol", "seed"]
    assert len(list((serial / "tasks").glob("*.json"))) == 8
    assert {ln.split(",")[head.index("estimator")] for ln in lines[1:]} == {"M2", "M5"}
    summary = (serial / "summary.csv").read_text().splitlines()
    assert len(summary) == 1 + 8 * 2 * 2                  # configurations x modes x estimators
    q = (serial / "smallest_q_formats.csv").read_text().splitlines()
    assert len(q) == 1 + 2 * 2 * 2 and all(",acc_frac_bits,13," in ln for ln in q[1:])   # widths x rates x estimators
    assert len((serial / "m5_rate.csv").read_text().splitlines()) == 1 + 2 * 2            # modes x rates
    for dim in ("adc_bits", "sampling_rate_hz", "q_formats"):
        assert (serial / "figures" / f"error_vs_{dim}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_two_worker_local_cluster_gives_the_serial_results(serial, tmp_path) -> None:
    pytest.importorskip("distributed")
    from gaitlog.host.studies.dask_runner import run_on_dask

    store = TaskStore(tmp_path)
    tasks = _grid().tasks()
    assert run_on_dask(run_task, tasks, store, workers=2, processes=False) == 8
    assert _files(tmp_path) == {k: v for k, v in _files(serial).items() if k.startswith("tasks/")}


def test_a_scheduler_started_separately_gives_the_serial_results(serial, tmp_path, dask_scheduler_file) -> None:
    addr = json.loads(dask_scheduler_file.read_text())["address"]
    out = tmp_path / "remote"
    assert main(["sweep", "--out", str(out), "--scheduler", addr, "-q", *GRID_ARGS]) == 0
    assert _files(out) == _files(serial)


@pytest.mark.parametrize("where", [["--serial"], ["--workers", "2"]])
def test_a_cut_run_resumes_without_recomputing_finished_tasks(serial, tmp_path, where) -> None:
    """Kill the whole run (and its workers) once some tasks are stored, re-run: the stored tasks are kept as
    they were, only the others are computed, and the results equal an uninterrupted run's."""
    out = tmp_path / "cut"
    tasks_dir = out / "tasks"
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog.host.cli", "sweep", "--out", str(out), "-q", *where, *GRID_ARGS],
                            env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if tasks_dir.is_dir() and any(tasks_dir.glob("*.json")):
                break
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    stored = {p.name: p.stat().st_mtime_ns for p in tasks_dir.glob("*.json")}
    if not 0 < len(stored) < 8:
        pytest.skip(f"the cut fell outside the run ({len(stored)} of 8 tasks stored)")
    grid = _grid()
    computed = run_serial(run_task, grid.tasks(), TaskStore(out))
    assert computed == 8 - len(stored)
    assert {n: t for n, t in ((p.name, p.stat().st_mtime_ns) for p in tasks_dir.glob("*.json")) if n in stored} == stored
    assert main(["sweep", "--out", str(out), "--serial", "-q", *GRID_ARGS]) == 0     # nothing left: just collects
    assert _files(out) == _files(serial)
