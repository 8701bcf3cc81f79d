"""``gaitlog demo`` keeps its files in ./gaitlog-demo/ (or --out), refuses a folder that is not its own, and
ends with commands that run on the files it wrote."""

from __future__ import annotations

import json
import shlex

from gaitlog.host.cli import main
from gaitlog.host.commands import demo
from gaitlog.host.studies import demo as demo_stages


def test_demo_keeps_its_files_and_its_next_commands_run(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--poses", "4"]) == 0
    out = capsys.readouterr().out
    folder = tmp_path / demo.DEFAULT_OUT
    marker = json.loads((folder / demo.MARKER).read_text())
    assert marker["complete"] and {"walk_k.png", "walk_k.npz", "k.json", "walk_boxplots.png"} <= set(marker["files"])
    assert all((folder / name).is_file() for name in marker["files"])
    nxt = out.split("[next]")[1]
    assert "walk_k.png" in nxt and "walk_boxplots.png" in nxt
    commands = [ln.strip() for ln in nxt.split("then try:")[1].splitlines() if ln.strip().startswith("gaitlog ")]
    assert len(commands) >= 4 and not any("calibrate " in c for c in commands)  # 4 poses: no calibration
    for command in commands:
        assert main(shlex.split(command)[1:]) == 0, command
    assert (folder / "next.png").stat().st_size > 1000 and (folder / "steps.csv").is_file()


def short_demo(ctx) -> list[str]:
    (ctx["dir"] / "one.txt").write_text("demo")
    return ["wrote one.txt"]


def test_demo_refuses_a_folder_that_is_not_its_own(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setattr(demo_stages, "STAGES", [demo_stages.Stage("short", short_demo)])
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep")
    assert main(["demo", "--out", str(other)]) == 1
    err = capsys.readouterr().err
    assert "not a previous 'gaitlog demo' output" in err and "--force" in err
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]  # nothing written
    # --force writes into it; the marker lists only the demo's files
    assert main(["demo", "--out", str(other), "--force"]) == 0
    assert json.loads((other / demo.MARKER).read_text())["files"] == ["one.txt"]
    assert (other / "notes.txt").read_text() == "keep"
    # a file in the way of the folder
    (tmp_path / "file").write_text("x")
    assert main(["demo", "--out", str(tmp_path / "file")]) == 1
    assert "exists and is not a folder" in capsys.readouterr().err


def test_demo_replaces_a_previous_demo_output(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(demo_stages, "STAGES", [demo_stages.Stage("short", short_demo)])
    folder = tmp_path / "d"
    assert main(["demo", "--out", str(folder)]) == 0
    (folder / "one.txt").write_text("old")
    assert main(["demo", "--out", str(folder)]) == 0
    assert (folder / "one.txt").read_text() == "demo"
    assert json.loads((folder / demo.MARKER).read_text()) == {"written_by": "gaitlog demo", "complete": True,
                                                              "files": ["one.txt"]}


