"""Exit codes and error lines of the ``gaitlog`` entry point that no single command owns."""

from __future__ import annotations

import subprocess
import sys

from gaitlog.host.cli import main


def test_closed_stdout_exits_141_without_a_traceback():
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog", "budget", "--json"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()                      # the reader is gone before the command writes (`| head -c 0`)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141
    # nothing on stderr but, on a first run, the one-line notice that code is being compiled
    assert [ln for ln in err.splitlines() if not ln.startswith(b"gaitlog: compiling once")] == []


def test_error_line_names_the_subcommand_action(tmp_path, capsys):
    assert main(["device", "status", "--port", str(tmp_path / "no-such-port")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gaitlog device status: error: ")
    assert len(err.strip().splitlines()) == 1
