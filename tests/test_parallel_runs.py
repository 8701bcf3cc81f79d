"""The suite on every core: ``tests/conftest.py`` turns pytest-xdist on (``-n auto --dist loadgroup``) only
when the plugin is loaded and no ``-n`` was given, so ``-n 0``, ``-n N`` and ``-p no:xdist`` keep working."""

from __future__ import annotations

import os
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


def test_the_hook_leaves_a_worker_and_a_run_without_xdist_alone() -> None:
    worker = _Config({"xdist"}, numprocesses=None, dist="no")
    worker.workerinput = {}
    plain = _Config(set())
    for config in (worker, plain):
        before = dict(vars(config.option))
        pytest_cmdline_main(config)
        assert vars(config.option) == before


@pytest.mark.parametrize("switch", [["-p", "no:xdist"], ["-n", "0"]])
def test_a_file_runs_in_one_process(switch: list[str]) -> None:
    """No ``-n`` in the ini's addopts: ``-p no:xdist`` would reject it as an unknown option."""
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *switch, "tests/test_atomic_write.py"]
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300, check=False,
                          env={k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")})
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "passed" in done.stdout and "workers" not in done.stdout
