"""Linear time on long recordings: the offline float chain at 64K, 256K, 1M and 4M samples.

The chain (:class:`gaitlog.host.gait.pipeline.StepPipeline`: gaps, tilt correction, events, M1-M5) on a
synthetic walk at 50 Hz: a sum of sines at step frequency (1.8 steps/s) and its harmonic, gravity on z with a
tilt, noise, and a few short and long gaps. For each length: the best time of a few runs per sample, and the
peak memory traced by ``tracemalloc`` (numpy's allocations) in a separate run, per sample. The baseline is the
64K run of the same process: each row gives its per-sample time as a ratio to it. The load average is printed
(the machine is shared; a ratio is comparable across loads, an absolute time is not).

Exit status 1 when the 4M per-sample time exceeds ``LIMIT`` (1.3) times the 64K one.

Whole process (``--process``): ``gaitlog estimate`` in a fresh process, as a user runs it, on files of the same
synthetic walk: a CSV at 50 Hz (``x_g,y_g,z_g``) with ``--arithmetic float`` and a decoded-recording ``.npz``
(10-bit codes of the same walk, nominal map) with ``--arithmetic both``, each at 64K, 1M and 4M samples: wall
time (best of ``--repeat`` at 64K, one run above), time per sample as a ratio to the 64K run of the same file
kind, and peak resident memory of the process (``wait4``'s ``ru_maxrss``). Targets: 4M <= 200 MB and within 1.3x
of the 64K time per sample. Then ``estimate --arithmetic both`` on the 64K ``.npz`` against the same work done with mobgap when it is
installed (Ionescu's initial contacts and Zijlstra's step lengths on the same acceleration, in a fresh process:
imports, reading, detection, lengths, CSV out), target <= 0.1x mobgap's time; without mobgap only the 64K figure.

Run: ``python benchmarks/bench_long_recordings.py [--quick] [--process [--repeat N]]`` (``--quick``: up to 1M
samples, no verdict).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
from _timing import best_of

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.files.recording import Recording  # noqa: E402
from gaitlog.host.gait.pipeline import StepPipeline  # noqa: E402

RATE_HZ = 50.0
SIZES = (65_536, 262_144, 1_048_576, 4_194_304)
#: Largest allowed ratio of the 4M run's per-sample time to the 64K run's.
LIMIT = 1.3
#: Whole-process sizes, and the peak memory allowed at the largest.
PROCESS_SIZES = (65_536, 1_048_576, 4_194_304)
PEAK_LIMIT_MB = 200.0
#: Whole-process ``estimate --arithmetic both`` at 64K over mobgap's equivalent script, at most.
MOBGAP_LIMIT = 0.1

#: mobgap's equivalent of ``estimate``: initial contacts (Ionescu) and step lengths (Zijlstra's inverted pendulum,
#: the model of M1/M2) on the acceleration of the same ``.npz``, the table written as CSV.
MOBGAP = """
import sys
import numpy as np
import pandas as pd
from mobgap.initial_contacts import IcdIonescu
from mobgap.stride_length import SlZijlstra
z = np.load(sys.argv[1])
codes, fs = z["codes"].astype(float), 50.0
acc = (codes - 512.0) / 256.0 * 9.80665
data = pd.DataFrame(np.c_[acc[:, [2, 1, 0]], np.zeros((len(acc), 3))],
                    columns=["acc_is", "acc_ml", "acc_pa", "gyr_is", "gyr_ml", "gyr_pa"])
ic = IcdIonescu().detect(data, sampling_rate_hz=fs).ic_list_
sl = SlZijlstra().calculate(data, ic, sampling_rate_hz=fs, sensor_height_m=0.95).stride_length_per_sec_
sl.to_csv(sys.argv[2])
"""


def synthetic_walk(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 3)`` acceleration in g and its validity mask: sines at step frequency, gravity on z, gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    f = 1.8
    acc = np.empty((n, 3))
    acc[:, 0] = 0.1 + 0.15 * np.sin(2 * np.pi * f * t + 0.3)
    acc[:, 1] = -0.2 + 0.1 * np.sin(np.pi * f * t)
    acc[:, 2] = 0.97 + 0.25 * np.cos(2 * np.pi * f * t) + 0.08 * np.cos(4 * np.pi * f * t + 0.5)
    acc += 0.02 * rng.standard_normal((n, 3))
    valid = np.ones(n, bool)
    for s in rng.integers(0, n - 100, size=n // 5_000):
        valid[s:s + rng.integers(1, 40)] = False
    acc[~valid] = np.nan
    return acc, valid


def measure(n: int) -> tuple[float, int, int]:
    """Best seconds of the chain on ``n`` samples, its traced peak bytes, and the number of steps."""
    acc, valid = synthetic_walk(n)
    pipe = StepPipeline(leg_length_m=0.9, foot_length_m=0.26)

    def run() -> None:
        pipe.run(acc, sampling_rate_hz=RATE_HZ, valid=valid)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seconds = best_of(run, repeat=5 if n <= 262_144 else 3, warmup=n <= 262_144)
        tracemalloc.start()
        run()
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return seconds, peak, pipe.steps_.n_steps


def write_inputs(folder: Path, n: int) -> tuple[Path, Path]:
    """The synthetic walk of ``n`` samples as a CSV in g and as a decoded-recording ``.npz`` of 10-bit codes."""
    acc, valid = synthetic_walk(n)
    csv = folder / f"walk_{n}.csv"
    with open(csv, "w", encoding="utf-8") as fh:
        fh.write("x_g,y_g,z_g\n")
        for lo in range(0, n, 1 << 16):
            block = acc[lo:lo + (1 << 16)]
            text = "\n".join(",".join("" if v != v else f"{v:.5f}" for v in row) for row in block.tolist())
            fh.write(text + "\n")
    codes = np.clip(np.round(512.0 + 256.0 * np.nan_to_num(acc, nan=0.0)), 0, 1023).astype(np.uint16)
    rec = Recording(codes=codes, valid=valid, flags=np.zeros(n, np.uint8), sample_numbers=np.arange(n, dtype=np.int64),
                    sampling_rate_hz=RATE_HZ, source="synthetic walk")
    npz = folder / f"walk_{n}.npz"
    rec.save_npz(npz)
    return csv, npz


#: The children's environment: Python writes and reuses its bytecode cache, as on a user's machine (a shell that
#: sets PYTHONDONTWRITEBYTECODE would compile every module on every run).
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run_process(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident MB of one fresh process (it must exit 0)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT, env=CHILD_ENV)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err[-2000:]}")
    return seconds, usage.ru_maxrss / 1024.0


def best_process(cmd: list[str], repeat: int) -> tuple[float, float]:
    """Best wall time of ``repeat`` runs and the largest peak memory."""
    runs = [run_process(cmd) for _ in range(repeat)]
    return min(r[0] for r in runs), max(r[1] for r in runs)


def whole_process(sizes: tuple[int, ...], repeat: int) -> bool:
    """``gaitlog estimate`` in fresh processes (module notes); True when the targets are met."""
    gaitlog = [sys.executable, "-m", "gaitlog", "estimate"]
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        # the inputs are written by a child: this process stays small, so a child's peak (which counts what it
        # shares with this process until it starts gaitlog) is gaitlog's own
        subprocess.run([sys.executable, __file__, "--write-inputs", str(folder), *map(str, sizes)], check=True)
        files = {n: (folder / f"walk_{n}.csv", folder / f"walk_{n}.npz") for n in sizes}
        run_process(gaitlog + [str(files[sizes[0]][1]), "--arithmetic", "both", "-q", "--force",
                               "--out", str(folder / "warm.csv")])          # builds the on-line kernel if needed
        print(f"whole process: gaitlog estimate in a fresh process, best of {repeat}; load average "
              f"{os.getloadavg()[0]:.1f}; baseline: the 64K run of the same kind")
        print(f"{'input':>26} {'samples':>9} {'time s':>8} {'us/sample':>10} {'ratio':>6} {'peak MB':>8}")
        for kind, index, extra in (("CSV, float", 0, ["--arithmetic", "float", "--rate", "50"]),
                                   (".npz, both", 1, ["--arithmetic", "both"])):
            base = None
            for n in sizes:
                seconds, peak = best_process(gaitlog + [str(files[n][index]), *extra, "-q", "--force",
                                                        "--out", str(folder / "steps.csv")],
                                             repeat if n <= SIZES[0] else 1)
                us = seconds / n * 1e6
                base = us if base is None else base
                print(f"{kind:>26} {n:>9} {seconds:>8.3f} {us:>10.3f} {us / base:>6.2f} {peak:>8.0f}", flush=True)
                if n == SIZES[-1]:
                    met = peak <= PEAK_LIMIT_MB and us / base <= LIMIT
                    ok &= met
                    print(f"{'':>26} 4M: peak {peak:.0f} MB (limit {PEAK_LIMIT_MB:g}), {us / base:.2f}x the 64K "
                          f"time per sample (limit {LIMIT}): {'ok' if met else 'MISSED'}")
        ok &= versus_mobgap(gaitlog, files[sizes[0]][1], folder, repeat)
    return ok


def versus_mobgap(gaitlog: list[str], npz: Path, folder: Path, repeat: int) -> bool:
    """``estimate --arithmetic both`` at 64K against mobgap's equivalent script, same run."""
    ours, our_peak = best_process(gaitlog + [str(npz), "--arithmetic", "both", "-q", "--force",
                                             "--out", str(folder / "both.csv")], repeat)
    try:
        import mobgap  # noqa: F401
    except ImportError:
        print(f"estimate --arithmetic both at 64K: {ours:.3f} s, {our_peak:.0f} MB; mobgap not installed: no baseline")
        return True
    mobgap = [sys.executable, "-c", MOBGAP, str(npz), str(folder / "mg.csv")]
    run_process(mobgap)                                   # untimed: writes the bytecode cache of mobgap's modules
    theirs, their_peak = best_process(mobgap, repeat)
    ratio = ours / theirs
    print(f"estimate --arithmetic both at 64K: {ours:.3f} s, {our_peak:.0f} MB; mobgap's equivalent script "
          f"{theirs:.3f} s, {their_peak:.0f} MB (same run): {ratio:.2f}x (target <= {MOBGAP_LIMIT}x): "
          f"{'ok' if ratio <= MOBGAP_LIMIT else 'MISSED'}")
    return ratio <= MOBGAP_LIMIT


def main(argv: list[str]) -> int:
    if argv[:1] == ["--write-inputs"]:
        for n in argv[2:]:
            write_inputs(Path(argv[1]), int(n))
        return 0
    if "--process" in argv:
        repeat = int(argv[argv.index("--repeat") + 1]) if "--repeat" in argv else 3
        sizes = PROCESS_SIZES[:2] if "--quick" in argv else PROCESS_SIZES
        return 0 if whole_process(sizes, repeat) or "--quick" in argv else 1
    sizes = SIZES[:3] if "--quick" in argv else SIZES
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"offline float chain (StepPipeline) on a synthetic walk at {RATE_HZ:g} Hz; "
          f"load average {load:.1f} on {os.cpu_count()} CPUs; baseline: the 64K run")
    print(f"{'samples':>9} {'steps':>7} {'time s':>8} {'us/sample':>10} {'ratio':>6} {'peak MB':>8} {'B/sample':>9}")
    base = None
    per_sample = {}
    for n in sizes:
        seconds, peak, steps = measure(n)
        per_sample[n] = us = seconds / n * 1e6
        base = us if base is None else base
        print(f"{n:>9} {steps:>7} {seconds:>8.3f} {us:>10.3f} {us / base:>6.2f} {peak / 2 ** 20:>8.0f} "
              f"{peak / n:>9.0f}", flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average at the end {load:.1f}")
    if SIZES[-1] not in per_sample:
        return 0
    ratio = per_sample[SIZES[-1]] / per_sample[SIZES[0]]
    ok = ratio <= LIMIT
    print(f"4M per-sample time {ratio:.2f}x the 64K one (limit {LIMIT}x): {'ok' if ok else 'MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
