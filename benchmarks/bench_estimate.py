"""Whole-process start-up and run time of ``gaitlog estimate`` and ``gaitlog --help``.

Run ``python benchmarks/bench_estimate.py [--mobgap-python PY]`` (a few minutes: the input is recorded first).
Prints each measured number, its target and the baselines measured in the same run, with the load average;
exits 1 if a target is missed.

Input: one full memory (65,536 samples, 1310.72 s at 50 Hz) of a simulated walker recorded by the emulated
logger with its on-line algorithm on (``benchmarks/_walker.py``), decoded to ``.npz`` as ``gaitlog decode``
writes it. Every number is the wall time of a fresh process (best of 5), the way a user meets it: after one
untimed run, which builds the on-line kernel ahead of time if this version of the sources has not built it yet
(``firmware_sim/algorithms/aot_kernel.py``; ~10-20 s, once), and writes the modules' bytecode cache. Beside each
wall time, the process's CPU time (user + system, from ``wait4``): on a shared machine the wall time follows the
load, the CPU time much less.

Two ways of loading the modules: with their bytecode cache (as ``pip install`` leaves them: pip compiles every
module, even with ``PYTHONDONTWRITEBYTECODE`` set), where the targets apply; and with ``PYTHONDONTWRITEBYTECODE=1``
and no cache in the source checkout's ``__pycache__`` use (every process compiles every module of gaitlog it imports
from source; an editable install run that way), printed, not a target. ``--arithmetic both`` with numba's JIT
instead of the ahead-of-time kernel (``GAITLOG_NO_AOT=1``) and with OpenBLAS's thread pool
(``OPENBLAS_NUM_THREADS`` = the CPU count; ``gaitlog`` runs it on one thread unless told otherwise) are printed too.

Targets (bytecode cached):
- ``gaitlog estimate REC.npz --arithmetic both --out STEPS.csv`` (offline float chain + the logger's on-line
  algorithm in fixed point, both per-step tables written) <= 0.5 s, and at most ``MOBGAP_LIMIT`` (0.1) times
  mobgap's equivalent script (``bench_long_recordings.MOBGAP``: Ionescu's initial contacts and Zijlstra's step
  lengths on the same acceleration, CSV out) when mobgap is installed (in this interpreter, or ``--mobgap-python
  PY``);
- ``gaitlog --help`` <= 0.1 s, printed beside the bare interpreter (``python -c pass``) of the same run.

Baselines (same run): the bare interpreter, ``python -c "import numpy"``, a simple equivalent script (numpy +
``scipy.signal.find_peaks``: load the file, counts to g, vertical acceleration, Gaussian low-pass, foot-flat peaks
with the same distance and prominence, one pendulum length per step, CSV out) and mobgap's, when installed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from _timing import process_seconds
from _walker import step_config, walker_motion
from bench_long_recordings import MOBGAP, MOBGAP_LIMIT

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.firmware_sim.device import Logger
from gaitlog.host.files.decode import decode_file, save_decoded

ESTIMATE_TARGET_S = 0.5
HELP_TARGET_S = 0.1
REPEAT = 5

#: The simple equivalent: what a researcher would write with numpy and scipy for foot-flats and M1 lengths.
SIMPLE = """
import sys
import numpy as np
from scipy.signal import find_peaks
z = np.load(sys.argv[1])
codes, fs = z["codes"].astype(float), 50.0
acc_g = (codes - 512.0) / 256.0
norm = np.linalg.norm(acc_g, axis=1)
acc_v = (norm - np.median(norm)) * 9.80665
sigma = 0.0442 * fs
x = np.arange(-int(4 * sigma + 0.5), int(4 * sigma + 0.5) + 1)
kernel = np.exp(-0.5 * (x / sigma) ** 2)
lp = np.convolve(acc_v, kernel / kernel.sum(), mode="same")
ff, _ = find_peaks(lp, distance=int(0.25 * fs), prominence=0.5)
v = np.cumsum(acc_v) / fs
h = np.array([np.ptp(np.cumsum(v[a:b] - v[a:b].mean()) / fs) for a, b in zip(ff[:-1], ff[1:])])
length = 2 * np.sqrt(np.maximum(2 * 0.9 * h - h * h, 0))
np.savetxt(sys.argv[2], np.c_[ff[1:] / fs, length], fmt="%.6g", delimiter=",", header="t_s,length_m")
"""

#: Runs ``gaitlog`` from a copy of the sources (the current folder) even when an editable install maps the
#: package to the checkout: the install's finder is taken out of ``sys.meta_path`` first.
FROM_COPY = """
import runpy, sys
sys.meta_path[:] = [f for f in sys.meta_path if "__editable__" not in getattr(f, "__module__", "")]
sys.argv[0] = "gaitlog"
runpy.run_module("gaitlog", run_name="__main__", alter_sys=True)
"""


def process(cmd: list[str], env: dict[str, str], cwd: Path = ROOT) -> tuple[float, float]:
    """Wall and CPU seconds of one fresh process (it must exit 0)."""
    return process_seconds(cmd, env, cwd)


def best(cmd: list[str], env: dict[str, str], cwd: Path = ROOT) -> tuple[float, float]:
    """Best wall and best CPU seconds of :data:`REPEAT` runs."""
    runs = [process(cmd, env, cwd) for _ in range(REPEAT)]
    return min(r[0] for r in runs), min(r[1] for r in runs)


def make_input(folder: Path) -> Path:
    """The walker's full memory, recorded and decoded: ``folder/walk.npz``."""
    motion, subject = walker_motion()
    logger = Logger(step_config=step_config(subject))
    logger.record(motion, start_time_s=1_700_000_000)
    logger.save_image(folder / "walk.glimg")
    save_decoded(decode_file(folder / "walk.glimg"), folder / "walk")
    return folder / "walk.npz"


def source_copy(folder: Path) -> Path:
    """The checkout's packages copied without their bytecode cache: ``folder/checkout``."""
    dest = folder / "checkout"
    for name in ("gaitlog", "protocol", "firmware_sim", "host"):
        shutil.copytree(ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", dest)
    return dest


def mobgap_python(given: str | None) -> str | None:
    """An interpreter with mobgap: ``given``, else this one when it has mobgap, else None."""
    if given:
        return given
    found = subprocess.run([sys.executable, "-c", "import mobgap"], capture_output=True, check=False)
    return sys.executable if found.returncode == 0 else None


def measure(rec: Path, folder: Path, mobgap: str | None) -> dict[str, tuple[float, float]]:
    """Every timed command of the module notes, in one run: name -> (wall s, CPU s)."""
    py = sys.executable
    cached = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "PYTHONDONTWRITEBYTECODE",
                                                                "OPENBLAS_NUM_THREADS")}
    cached["PYTHONPATH"] = str(ROOT) + os.pathsep + cached.get("PYTHONPATH", "")
    copy = source_copy(folder)
    uncached = dict(cached, PYTHONDONTWRITEBYTECODE="1", PYTHONPATH=str(copy))
    estimate = ["estimate", str(rec), "--out", str(folder / "steps.csv"), "--force", "-q"]  # rewritten each run
    both = [py, "-m", "gaitlog", *estimate, "--arithmetic", "both"]
    process(both, cached)                           # bytecode cache written; the kernel built if not yet built
    process(both, dict(cached, GAITLOG_NO_AOT="1"))  # ... and numba's JIT cache
    runs = {
        "bare": ([py, "-c", "pass"], cached, ROOT),
        "numpy": ([py, "-c", "import numpy"], cached, ROOT),
        "help": ([py, "-m", "gaitlog", "--help"], cached, ROOT),
        "help, uncached": ([py, "-c", FROM_COPY, "--help"], uncached, copy),
        "both": (both, cached, ROOT),
        "both, uncached": ([py, "-c", FROM_COPY, *estimate, "--arithmetic", "both"], uncached, copy),
        "float": ([py, "-m", "gaitlog", *estimate, "--arithmetic", "float"], cached, ROOT),
        "both, numba JIT": (both, dict(cached, GAITLOG_NO_AOT="1"), ROOT),
        "both, BLAS threads": (both, dict(cached, OPENBLAS_NUM_THREADS=str(os.cpu_count() or 1)), ROOT),
        "simple": ([py, "-c", SIMPLE, str(rec), str(folder / "simple.csv")], cached, ROOT),
    }
    if mobgap:
        runs["mobgap"] = ([mobgap, "-c", MOBGAP, str(rec), str(folder / "mg.csv")], cached, ROOT)
        process(*runs["mobgap"])                    # untimed: mobgap's bytecode cache
    return {name: best(*run) for name, run in runs.items()}


def report(t: dict[str, tuple[float, float]]) -> bool:
    """Print the numbers against their targets; True when every target is met."""
    ok = True
    print(f"input: 65,536 samples of a simulated walker, decoded .npz; fresh processes, best of {REPEAT}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; wall s (CPU s)")
    for name, label, target in (
            ("both", "gaitlog estimate --arithmetic both", ESTIMATE_TARGET_S),
            ("both, uncached", "... PYTHONDONTWRITEBYTECODE, no cache", None),
            ("float", "gaitlog estimate --arithmetic float", None),
            ("both, numba JIT", "... both, numba's JIT (GAITLOG_NO_AOT=1)", None),
            ("both, BLAS threads", f"... both, OPENBLAS_NUM_THREADS={os.cpu_count()}", None),
            ("help", "gaitlog --help", HELP_TARGET_S),
            ("help, uncached", "... PYTHONDONTWRITEBYTECODE, no cache", None)):
        hit = target is None or t[name][0] <= target
        ok &= hit
        tgt = f"target <= {target} s  [{'ok' if hit else 'MISSED'}]" if target is not None else "(not a target)"
        print(f"  {label:42s} {t[name][0]:.3f} s ({t[name][1]:.3f})  {tgt}")
    bare, help_ = t["bare"], t["help"]
    print(f"  baseline: bare interpreter `python -c pass` {bare[0]:.3f} s ({bare[1]:.3f}) -> gaitlog --help "
          f"{help_[0] - bare[0]:+.3f} s ({help_[1] - bare[1]:+.3f}) over it, {help_[0] / bare[0]:.1f}x; "
          f"`python -c \"import numpy\"` {t['numpy'][0]:.3f} s ({t['numpy'][1]:.3f})")
    print(f"  baseline: simple numpy + scipy.signal.find_peaks script (foot-flats + one length per step) "
          f"{t['simple'][0]:.3f} s -> estimate --arithmetic both is {t['both'][0] / t['simple'][0]:.2f}x its time, "
          f"--arithmetic float {t['float'][0] / t['simple'][0]:.2f}x")
    if "mobgap" in t:
        ratio, cpu_ratio = t["both"][0] / t["mobgap"][0], t["both"][1] / t["mobgap"][1]
        hit = ratio <= MOBGAP_LIMIT
        ok &= hit
        print(f"  baseline: mobgap's equivalent script (Ionescu + Zijlstra, CSV out) {t['mobgap'][0]:.3f} s "
              f"({t['mobgap'][1]:.3f}) -> estimate --arithmetic both is {ratio:.3f}x its time (CPU {cpu_ratio:.3f}x); "
              f"target <= {MOBGAP_LIMIT}x  [{'ok' if hit else 'MISSED'}]")
    else:
        print("  baseline: mobgap not installed (give --mobgap-python PY: an interpreter with mobgap)")
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mobgap-python", metavar="PY", help="an interpreter with mobgap installed (baseline)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        times = measure(make_input(folder), folder, mobgap_python(args.mobgap_python))
    return 0 if report(times) else 1


if __name__ == "__main__":
    raise SystemExit(main())
