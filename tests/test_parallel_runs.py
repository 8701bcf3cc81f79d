"""The suite on every core: ``tests/conftest.py`` turns pytest-xdist on (``-n auto --dist loadgroup``) only
when the plugin is loaded and no ``-n`` was given, so ``-n 0``, ``-n N`` and ``-p no:xdist`` keep working."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from argparse import Namespace
from pathlib import Path

import pytest

from tests.conftest import pytest_cmdline_main

ROOT = Path(__file__).resolve().parents[1]


class _Config:
    """The part of ``pytest.Config`` the hook reads: the plugins loaded and the parsed options."""

    def __init__(self, plugins: set[str], **options: object) -> None:
        self.option = Namespace(**options)
        self.pluginmanager = Namespace(hasplugin=plugins.__contains__)


@pytest.mark.parametrize(("given", "expected"), [
    ({"numprocesses": None, "dist": "no"}, {"numprocesses": "auto", "dist": "loadgroup"}),   # the README's
    ({"numprocesses": 0, "dist": "no"}, {"numprocesses": 0, "dist": "loadgroup"}),     # xdist then sets "no"
    ({"numprocesses": 3, "dist": "no"}, {"numprocesses": 3, "dist": "loadgroup"}),     # groups kept under -n 3
    ({"numprocesses": None, "dist": "worksteal"}, {"numprocesses": "auto", "dist": "worksteal"}),
])
def test_the_hook_fills_in_only_what_the_command_line_left_out(given: dict, expected: dict) -> None:
    config = _Config({"xdist"}, **given)
    pytest_cmdline_main(config)
    assert vars(config.option) == expected


def test_a_worker_takes_the_grouping_from_the_controller() -> None:
    """A worker parses only the command line, where ``--dist loadgroup`` need not be: the controller tells it."""
    worker = _Config({"xdist"}, numprocesses=None, dist="no", loadgroup=False)
    worker.workerinput = {"loadgroup": True}
    pytest_cmdline_main(worker)
    assert vars(worker.option) == {"numprocesses": None, "dist": "no", "loadgroup": True}


def test_a_run_without_xdist_is_left_alone() -> None:
    plain = _Config(set(), numprocesses=None, dist="no")
    pytest_cmdline_main(plain)
    assert vars(plain.option) == {"numprocesses": None, "dist": "no"}


@pytest.mark.parametrize("switch", [["-p", "no:xdist"], ["-n", "0"]])
def test_a_file_runs_in_one_process(switch: list[str]) -> None:
    """No ``-n`` in the ini's addopts: ``-p no:xdist`` would reject it as an unknown option."""
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *switch, "tests/test_atomic_write.py"]
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300, check=False,
                          env={k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")})
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "passed" in done.stdout and "workers" not in done.stdout


def test_the_default_run_keeps_a_group_on_one_worker(tmp_path: Path) -> None:
    """Four tests of one ``xdist_group`` under ``-n 2``: every test reports the group in its id, and one worker
    ran them all (pytest 9.2 with pytest-xdist 3.8 spread them instead)."""
    (tmp_path / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())
    (tmp_path / "test_grouped.py").write_text(
        "import time\nimport pytest\n\npytestmark = pytest.mark.xdist_group('together')\n\n"
        + "".join(f"def test_{i}():\n    time.sleep(0.2)\n\n" for i in range(4)))
    argv = [sys.executable, "-m", "pytest", "-v", "-p", "no:cacheprovider", "-n", "2", "--rootdir", str(tmp_path),
            str(tmp_path / "test_grouped.py")]
    done = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False,
                          env={k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")})
    ran = re.findall(r"^\[(gw\d+)\] .*PASSED (\S+)", done.stdout, re.M)
    assert done.returncode == 0 and len(ran) == 4, done.stdout[-2000:] + done.stderr[-2000:]
    assert all(nodeid.endswith("@together") for _, nodeid in ran), ran
    assert len({worker for worker, _ in ran}) == 1, ran
