"""gaitlog batch: every recording of a folder, each estimated as `gaitlog estimate` does, failures listed
without stopping the batch, finished recordings skipped on a re-run."""

from __future__ import annotations

import csv
import json

import pytest

from gaitlog.host.cli import main


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch_in")
    for name, height in (("a.glimg", "1.75"), ("b.glimg", "1.60")):
        assert main(["record", "--motion", "walk", "--height", height, "--out", str(d / name), "-q"]) == 0
    (d / "c_truncated.glimg").write_bytes((d / "a.glimg").read_bytes()[:5000])
    (d / "junk.bin").write_bytes(b"\x00\xff" * 100)
    (d / "a.glimg.json").write_text("{}")            # a sidecar: not an input
    return d


def _table(path):
    with open(path, newline="") as f:
        return {r["recording"]: r for r in csv.DictReader(f)}


def test_batch_estimates_each_recording_as_estimate_does(folder, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["batch", str(folder), "--out", str(out), "-q"]) == 1       # one file failed: exit 1
    err = capsys.readouterr().err
    assert "junk.bin" in err and "Traceback" not in err
    rows = _table(out / "batch.csv")
    assert set(rows) == {"a.glimg", "b.glimg", "c_truncated.glimg", "junk.bin"}
    assert rows["junk.bin"]["status"] == "failed" and rows["junk.bin"]["error"]
    assert not (out / "junk.bin.json").exists() and not (out / "junk.bin.steps.csv").exists()
    assert int(rows["c_truncated.glimg"]["n_missing"]) > 0 and "truncated" in rows["c_truncated.glimg"]["warnings"]
    for name in ("a.glimg", "b.glimg"):
        assert rows[name]["status"] == "done"
        # the independent reference: the estimate command on the same file
        assert main(["estimate", str(folder / name), "--json"]) == 0
        ref = json.loads(capsys.readouterr().out)["arithmetic"]["float"]
        assert int(rows[name]["n_steps"]) == ref["n_steps"]
        for est in ("M1", "M2", "M3"):
            assert float(rows[name][f"distance_{est.lower()}_m"]) == pytest.approx(ref["estimators"][est]["distance_m"],
                                                                                   rel=1e-5)
        steps = (out / f"{name}.steps.csv").read_text().splitlines()
        assert len(steps) == ref["n_steps"] + 1


def test_rerun_skips_finished_recordings_and_recomputes_changed_ones(folder, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    main(["batch", str(folder), "--out", str(out), "-q"])
    stamps = {p.name: p.stat().st_mtime_ns for p in out.glob("*.json")}
    assert main(["batch", str(folder), "--out", str(out)]) == 1
    text = capsys.readouterr().out
    assert "0 computed, 3 finished before (skipped), 1 failed" in text
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.json")} == stamps
    # other lengths: every recording is recomputed (the settings are part of what finished means)
    assert main(["batch", str(folder), "--out", str(out), "--height", "1.9"]) == 1
    assert "3 computed, 0 finished before" in capsys.readouterr().out


def test_batch_refuses_an_empty_folder_and_writing_into_its_input(tmp_path, capsys) -> None:
    assert main(["batch", str(tmp_path), "--out", str(tmp_path / "o")]) == 1
    assert "no input file" in capsys.readouterr().err
    (tmp_path / "x.npz").write_bytes(b"PK\x03\x04")
    assert main(["batch", str(tmp_path), "--out", str(tmp_path)]) == 1
    assert "other than the input folder" in capsys.readouterr().err


def test_a_summary_row_with_commas_reads_back_as_the_header_columns(tmp_path, capsys) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    name = "junk, with commas; and \"quotes\".bin"
    (folder / name).write_bytes(b"\x00\xff" * 100)
    assert main(["batch", str(folder), "--out", str(tmp_path / "out"), "-q"]) == 1
    capsys.readouterr()
    with open(tmp_path / "out" / "batch.csv", newline="") as f:
        header, *rows = list(csv.reader(f))
    assert len(rows) == 1 and len(rows[0]) == len(header)
    row = dict(zip(header, rows[0], strict=True))
    assert row["recording"] == name and row["status"] == "failed" and "," in row["error"]


def _outputs(out):
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.name != "batch.csv"} | {
        "batch.csv": "\n".join(sorted(open(out / "batch.csv").read().splitlines()[1:]))}


def test_dask_workers_give_the_serial_results_and_the_same_failures(folder, tmp_path, capsys) -> None:
    pytest.importorskip("distributed")
    serial, dask = tmp_path / "serial", tmp_path / "dask"
    assert main(["batch", str(folder), "--out", str(serial), "-q"]) == 1
    first = capsys.readouterr().err
    assert main(["batch", str(folder), "--out", str(dask), "-q", "--workers", "2"]) == 1
    assert capsys.readouterr().err == first                    # the same failures, said the same way
    a, b = _outputs(serial), _outputs(dask)
    assert a.keys() == b.keys() and {"a.glimg.steps.csv", "b.glimg.steps.csv"} <= a.keys()
    for name in a:
        if name.endswith(".json"):        # the input's path differs (the same folder): compare the summary
            assert json.loads(a[name])["summary"] == json.loads(b[name])["summary"], name
        else:
            assert a[name] == b[name], name


def test_a_scheduler_started_separately_gives_the_serial_results(folder, tmp_path, capsys,
                                                                  dask_scheduler_file) -> None:
    """``--scheduler`` with the scheduler file of a scheduler and worker started apart (port 0: no free port
    needed), as ``gaitlog sweep`` is tested."""
    serial, remote = tmp_path / "serial", tmp_path / "remote"
    assert main(["batch", str(folder), "--out", str(serial), "-q"]) == 1
    first = capsys.readouterr().err
    assert main(["batch", str(folder), "--out", str(remote), "-q", "--scheduler", str(dask_scheduler_file)]) == 1
    assert capsys.readouterr().err == first
    assert _outputs(serial) == _outputs(remote)
