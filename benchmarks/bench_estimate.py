"""Whole-process start-up and run time of ``gaitlog estimate`` and ``gaitlog --help`` (issue 11).

Run ``python benchmarks/bench_estimate.py`` (about a minute: the input is recorded first). Prints each
measured number, its target and the baselines measured in the same run; exits 1 if a target is missed.

Input: one full memory (65,536 samples, 1310.72 s at 50 Hz) of a simulated walker recorded by the emulated
logger with its on-line algorithm on (``benchmarks/_walker.py``), decoded to ``.npz`` as ``gaitlog decode``
writes it. Every number is the wall time of a fresh process (best of 5), the way a user meets it: after one
untimed run, which builds the on-line kernel ahead of time if this version of the sources has not built it yet
(``firmware_sim/algorithms/aot_kernel.py``; ~10-20 s, once). ``--arithmetic both`` with numba's JIT instead
(``GAITLOG_NO_AOT=1``: numba imported and its cached code loaded) is printed too, not a target.

Targets:
- ``gaitlog estimate REC.npz --arithmetic both --out STEPS.csv`` (offline float chain + the logger's on-line
  algorithm in fixed point, both per-step tables written) <= 0.5 s;
- ``gaitlog --help`` <= 0.1 s.

Baselines (same run): the bare interpreter, ``python -c "import numpy"``, and a simple equivalent script
(numpy + ``scipy.signal.find_peaks``: load the file, counts to g, vertical acceleration, Gaussian low-pass,
foot-flat peaks with the same distance and prominence, one pendulum length per step, CSV out). With
``--mobgap-python PY`` (an interpreter with ``mobgap`` installed), mobgap's Ionescu initial-contact detector on
the same acceleration is timed as well.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _timing import best_of
from _walker import step_config, walker_motion

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

#: mobgap (the Mobilise-D pipeline's building blocks): initial contacts by Ionescu's detector.
MOBGAP = """
import sys
import numpy as np
import pandas as pd
from mobgap.initial_contacts import IcdIonescu
z = np.load(sys.argv[1])
codes, fs = z["codes"].astype(float), 50.0
acc = (codes - 512.0) / 256.0 * 9.80665
data = pd.DataFrame(acc, columns=["acc_is", "acc_ml", "acc_pa"])
ic = IcdIonescu().detect(data, sampling_rate_hz=fs).ic_list_
ic.to_csv(sys.argv[2])
"""


def wall(cmd: list[str], env: dict[str, str]) -> float:
    """Wall time of one fresh process (it must exit 0)."""
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, check=False)
    dt = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stderr[-2000:]}")
    return dt


def make_input(folder: Path) -> Path:
    """The walker's full memory, recorded and decoded: ``folder/walk.npz``."""
    motion, subject = walker_motion()
    logger = Logger(step_config=step_config(subject))
    logger.record(motion, start_time_s=1_700_000_000)
    logger.save_image(folder / "walk.glimg")
    save_decoded(decode_file(folder / "walk.glimg"), folder / "walk")
    return folder / "walk.npz"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mobgap-python", metavar="PY", help="an interpreter with mobgap installed (baseline)")
    args = ap.parse_args(argv)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_JIT"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    py = sys.executable
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rec = make_input(folder)
        out = str(folder / "steps.csv")
        estimate = [py, "-m", "gaitlog", "estimate", str(rec), "--out", out, "--force"]  # rewritten each run
        wall(estimate + ["--arithmetic", "both"], env)  # warm the file cache; build the kernel if not yet built
        wall(estimate + ["--arithmetic", "both"], dict(env, GAITLOG_NO_AOT="1"))  # ... and numba's JIT cache
        t = {
            "bare": lambda: wall([py, "-c", "pass"], env),
            "numpy": lambda: wall([py, "-c", "import numpy"], env),
            "help": lambda: wall([py, "-m", "gaitlog", "--help"], env),
            "float": lambda: wall(estimate + ["--arithmetic", "float"], env),
            "both": lambda: wall(estimate + ["--arithmetic", "both"], env),
            "jit": lambda: wall(estimate + ["--arithmetic", "both"], dict(env, GAITLOG_NO_AOT="1")),
            "simple": lambda: wall([py, "-c", SIMPLE, str(rec), str(folder / "simple.csv")], env),
        }
        if args.mobgap_python:
            t["mobgap"] = lambda: wall([args.mobgap_python, "-c", MOBGAP, str(rec), str(folder / "mg.csv")], env)
        best = {name: best_of(fn, REPEAT) for name, fn in t.items()}
    load = os.getloadavg()[0]
    print(f"input: 65,536 samples of a simulated walker, decoded .npz; fresh processes, best of {REPEAT}; "
          f"load average {load:.1f} on {os.cpu_count()} CPUs")
    for name, label, target in (("both", "gaitlog estimate --arithmetic both", ESTIMATE_TARGET_S),
                                ("float", "gaitlog estimate --arithmetic float", None),
                                ("jit", "... both, numba's JIT (GAITLOG_NO_AOT=1)", None),
                                ("help", "gaitlog --help", HELP_TARGET_S)):
        hit = target is None or best[name] <= target
        ok &= hit
        tgt = f"target <= {target} s  [{'ok' if hit else 'MISSED'}]" if target is not None else "(not a target)"
        print(f"  {label:38s} {best[name]:.3f} s  {tgt}; {best[name] / best['numpy']:.1f}x `import numpy`")
    print(f"  baseline: bare interpreter {best['bare']:.3f} s, `python -c \"import numpy\"` {best['numpy']:.3f} s")
    if env.get("PYTHONDONTWRITEBYTECODE"):
        print("  note: PYTHONDONTWRITEBYTECODE is set: every process above compiled every module it imported from "
              "source (~0.1 s of gaitlog's times; an installed gaitlog has its bytecode cached)")
    print(f"  baseline: simple numpy + scipy.signal.find_peaks script (foot-flats + one length per step) "
          f"{best['simple']:.3f} s -> estimate --arithmetic both is {best['both'] / best['simple']:.2f}x its time, "
          f"--arithmetic float {best['float'] / best['simple']:.2f}x")
    if "mobgap" in best:
        print(f"  baseline: mobgap IcdIonescu on the same acceleration {best['mobgap']:.3f} s -> estimate --arithmetic "
              f"both is {best['both'] / best['mobgap']:.2f}x its time")
    else:
        print("  baseline: mobgap not measured (give --mobgap-python PY: an interpreter with mobgap installed)")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
