"""What the command line imports: ``gaitlog --help`` and ``gaitlog estimate`` stay light (no timing here:
``benchmarks/bench_estimate.py`` measures; these tests keep the heavy imports from coming back)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from gaitlog.host.files.recording import Recording

ROOT = Path(__file__).resolve().parents[3]

PROBE = """
import contextlib, io, json, sys
from gaitlog.host.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def modules_after(args: list[str]) -> tuple[int, set[str]]:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, env=env, cwd=ROOT,
                         check=False)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    return result["code"], set(result["modules"])


def test_help_imports_no_numeric_library() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    probe = "import sys\nfrom gaitlog.host.cli import build_parser\nbuild_parser()\nprint(' '.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=ROOT,
                         check=True)
    loaded = set(out.stdout.split())
    assert "gaitlog.host.commands.estimate" in loaded  # the probe did build the parser
    assert not loaded & {"numpy", "scipy", "numba", "matplotlib", "importlib.metadata"}


def test_help_process_imports_no_numpy() -> None:
    """The whole ``gaitlog --help`` process, as a user starts it, read from ``python -X importtime``: no numpy
    (``import numpy`` alone takes longer than --help's 0.1 s budget on a loaded machine), and none of the
    standard modules only a run needs (inspect with ast/dis/tokenize, tempfile, dataclasses, pkgutil, difflib)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-X", "importtime", "-m", "gaitlog", "--help"], capture_output=True,
                         text=True, env=env, cwd=ROOT, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("usage: gaitlog")
    loaded = {line.rsplit("|", 1)[1].strip() for line in out.stderr.splitlines() if line.startswith("import time:")}
    assert {"gaitlog.host.cli", "gaitlog.host.commands._options", "argparse"} <= loaded  # the commands were loaded
    assert not {m for m in loaded if m.split(".")[0] in ("numpy", "scipy", "numba", "matplotlib", "dask")}
    assert not loaded & {"inspect", "tempfile", "dataclasses", "pkgutil", "difflib"}


def test_estimate_imports_no_scipy(tmp_path) -> None:
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) / 50.0
    codes = np.clip(512 + rng.normal(0, 3, (n, 3)), 0, 1023).astype(np.uint16)
    codes[:, 2] = np.clip(512 + 100 + 60 * np.sin(2 * np.pi * 1.8 * t), 0, 1023).astype(np.uint16)
    path = tmp_path / "rec.npz"
    Recording.from_arrays(codes, sampling_rate_hz=50.0, adc_bits=10).save_npz(path)
    code, loaded = modules_after(["estimate", str(path), "--arithmetic", "both", "--out", str(tmp_path / "s.csv")])
    assert code == 0
    assert "gaitlog.firmware_sim.algorithms.online" in loaded  # the fixed-point chain did run
    # only estimate's subcommand was registered: no other command module imported
    assert not loaded & {"gaitlog.host.commands.decode", "gaitlog.host.commands.sweep", "gaitlog.host.commands.demo"}
    # a decoded .npz needs none of the logger-file decoders nor the IPOL reader
    assert not loaded & {"gaitlog.host.files.decode", "gaitlog.host.files.inputs", "gaitlog.host.files.ipol",
                         "gaitlog.protocol.image", "gaitlog.protocol.frames", "gaitlog.protocol.raw_dump"}
    # (numba itself loads scipy.linalg for its BLAS bindings: not ours to avoid)
    assert not any(m.startswith(("scipy.signal", "scipy.ndimage", "matplotlib", "gaitlog.firmware_sim.sensor")) for m in loaded)


def test_a_run_parses_as_the_whole_parser_does() -> None:
    """Registering only the named subcommand (what ``main`` does) parses a command line into the same namespace
    as the parser with every subcommand; a mistyped or missing command registers them all."""
    from gaitlog.host import cli

    for argv in (["estimate", "walk.npz", "--arithmetic", "both", "--out", "s.csv", "-q"],
                 ["calibrate-k", "a.npz", "--distance", "20", "--out", "K.json"], ["decode", "walk.glimg", "--out", "walk"]):
        only = cli._named_command(argv)
        assert only == argv[0].replace("-", "_")
        whole = vars(cli.build_parser().parse_args(argv))
        assert vars(cli._build(lazy=True, only=only).parse_args(argv)) == whole
    assert cli._named_command(["estimat", "x"]) is None
    assert cli._named_command(["calibrate_k", "x"]) is None
    assert cli._named_command(["--version"]) is None and cli._named_command([]) is None
