"""Speed, start-up and memory of the on-line step algorithm replayed on the host (issue 10).

Run: ``python benchmarks/bench_online.py`` (about 1.5 min; ``--no-compile`` skips the ~25 s cold-compile
measurement). Prints each measured number, its target and a baseline measured in the same run; exits 1 if a
target is missed.

Input: a full memory (65,536 samples = 1310.72 s at 50 Hz) of realistic 10-bit codes: a simulated walker
(``benchmarks/_walker.py``) recorded by the emulated logger with the on-line algorithm on. Before any
timing, the host replay in fixed point is checked to give the device's step records byte for byte.

1. Replay (in-process, warm, best of 7): ``OnlineStepAlgorithm.run`` on the 65,536 samples. Targets
   <= 0.1 s in float, <= 0.2 s in fixed point. Baselines: the offline float chain
   (``gaitlog.host.gait.pipeline.StepPipeline``) on the same codes in g, and the same per-sample kernel run by
   CPython (``NUMBA_DISABLE_JIT=1`` in a subprocess, on a 4,096-sample walking slice, scaled per sample).
2. Cold start (not a target): the wall time of a fresh ``python -c`` that imports the algorithm and runs it
   once on the 65,536 samples with the compiled-kernel cache present (normal use), the import alone, and the
   bare interpreter; an instrumented child splits it (numpy, numba import, project import, first run =
   cache load + run, warm run). The cache is keyed by a hash of the compiled sources
   (``firmware_sim/compiled.py``); a child with an empty ``GAITLOG_CACHE_DIR`` measures the one-off compile.
3. Long recordings: 1x, 4x, 16x and 64x the memory (64x = 4,194,304 samples, 23.3 h at 50 Hz) fed to
   ``OnlineStepAlgorithm.feed`` in 65,536-sample blocks (one run, records kept), each length in a fresh
   process, 3 passes or more (48 at 1x, 12 at 4x): the time of the best pass, and for the time per sample
   each block's best time over the passes, summed (a 2 s pass on a shared machine is rarely undisturbed).
   Peak memory = the child's peak resident set (``VmHWM`` of ``/proc/self/status``; ``getrusage``
   ``ru_maxrss`` is not used on Linux: it keeps the high-water mark of the forking parent, this benchmark
   with its rendered walk, across ``exec``): what the OS had to provide, numba's and LLVM's allocations
   included (``tracemalloc`` sees only Python's and numpy's). Targets: peak <= 300 MB at 64x; time per
   sample at 64x <= 1.3x that at 1x (linear growth). Baselines in the same run: the interpreter + imports
   floor (the same child after imports and a short warm-up run, before any data),
   ``OnlineStepAlgorithm.run`` on the whole 64x array at once (the array and the kernel's input copy in
   memory: ``feed`` in blocks is the streaming API), and the offline chain (``StepPipeline``, which needs
   the whole recording in g) at the lengths that fit in 2 GB. The baselines are timed once.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from _timing import best_of
from _walker import N_SAMPLES, RATE_HZ, step_config, walker_motion

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm  # noqa: E402
from gaitlog.firmware_sim.device import Logger  # noqa: E402
from gaitlog.protocol.header import CalibrationSlot  # noqa: E402
from gaitlog.protocol.steps import STEP_RECORD_SIZE, pack_step_records  # noqa: E402

FLOAT_TARGET_S = 0.1
FIXED_TARGET_S = 0.2
MEMORY_TARGET_MB = 300.0
LINEAR_TARGET = 1.3
LENGTHS = (1, 4, 16, 64)
OFFLINE_LIMIT_MB = 2048.0
CPYTHON_SAMPLES = 4096
WALK_START = 500          # the first excursion starts after 10 s of standing

_IMPORTS = ("import json, resource, sys, time\n"
            "import numpy as np\n")
_SETUP = ("from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps\n"
          "from gaitlog.protocol.steps import StepConfig\n"
          "path, arithmetic, leg, foot = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])\n"
          "cfg = StepConfig(step_format=1, leg_length_m=leg, foot_length_m=foot)\n"
          "new = lambda: OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg, arithmetic=arithmetic)\n"
          "codes = np.load(path)\n")

#: Cold start, plain: what a user's process does.
COLD_PLAIN = _IMPORTS + _SETUP + "new().run(codes)\n"
#: Import alone.
IMPORT_ONLY = "import numpy\nimport gaitlog.firmware_sim.algorithms.online, gaitlog.protocol.steps\n"
#: Cold start, instrumented.
COLD_SPLIT = """
import time
t0 = time.perf_counter()
import json, sys
import numpy as np
t1 = time.perf_counter()
import numba
t2 = time.perf_counter()
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.protocol.steps import StepConfig
t3 = time.perf_counter()
path, arithmetic, leg, foot = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
codes = np.load(path)
alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=leg,
                          foot_length_m=foot), arithmetic=arithmetic)
t4 = time.perf_counter()
n = alg.run(codes).n_steps
t5 = time.perf_counter()
alg.run(codes)
t6 = time.perf_counter()
print(json.dumps(dict(numpy=t1 - t0, numba=t2 - t1, project=t3 - t2, setup=t4 - t3, first=t5 - t4,
                      warm=t6 - t5, steps=n)))
"""
#: The per-sample kernel in CPython (run with NUMBA_DISABLE_JIT=1).
CPYTHON = _IMPORTS + _SETUP + """
t = time.perf_counter()
n = new().run(codes).n_steps
print(json.dumps(dict(time_s=time.perf_counter() - t, steps=n)))
"""
#: Long recordings: argv[5] = repetitions of the block, argv[6] = stream | whole | offline.
LONG = _IMPORTS + """
def kb():  # this process's peak resident set: VmHWM (ru_maxrss also counts the parent's, copied at fork)
    try:
        with open("/proc/self/status") as f:
            return int(next(line.split()[1] for line in f if line.startswith("VmHWM:")))
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
after_numpy = kb()
import numba
after_numba = kb()
""" + _SETUP + """
after_project = kb()
reps, mode = int(sys.argv[5]), sys.argv[6]
if mode == "offline":
    import warnings
    from gaitlog.host.gait.pipeline import StepPipeline
    from gaitlog.protocol.header import CalibrationSlot
    cal = CalibrationSlot.nominal(10)
    run_offline = lambda acc: StepPipeline(leg_length_m=leg, foot_length_m=foot).run(acc, sampling_rate_hz=50.0)
    warnings.simplefilter("ignore")
    run_offline(cal.apply(codes[:3000]))                       # warm-up: imports done, nothing kept
    floor = kb()
    acc = cal.apply(np.tile(codes, (reps, 1)))                 # the whole recording in g (the chain's input)
    t = time.perf_counter()
    n = run_offline(acc).steps_.n_steps
    dt = time.perf_counter() - t
else:
    new().run(codes[:3000])                                    # warm-up: compiled code loaded
    floor = kb()
    alg = new()
    if mode == "stream":                                       # one block of the long recording at a time
        passes = []
        for _ in range(max(3, 48 // reps)):                    # 3 passes or more (one pass's records kept)
            alg.reset()
            parts, ts = [], [time.perf_counter()]
            for _ in range(reps):
                parts.append(alg.feed(codes))
                ts.append(time.perf_counter())
            parts.append(alg.flush())
            n = OnlineSteps.concatenate(parts).n_steps
            ts.append(time.perf_counter())
            passes.append(np.diff(ts))                         # each block, then the flush and concatenation
            del parts
        passes = np.array(passes)
        dt = float(passes.sum(axis=1).min())                   # the best pass
        block_s = float(passes.min(axis=0).sum())              # each block's best over the passes, summed
    else:                                                      # the whole recording in memory at once
        whole = np.tile(codes, (reps, 1))
        t = time.perf_counter()
        n = alg.run(whole).n_steps
        dt = time.perf_counter() - t
print(json.dumps(dict(time_s=dt, block_s=block_s if mode == "stream" else dt, steps=n, peak_mb=kb() / 1024.0,
                      floor_mb=floor / 1024.0, numpy_mb=after_numpy / 1024.0, numba_mb=after_numba / 1024.0,
                      project_mb=after_project / 1024.0)))
"""


def child_env(cache_dir: str | None = None, *, no_jit: bool = False) -> dict[str, str]:
    """The environment of a child: numba's own cache variable removed (the project's cache decides)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    if cache_dir is not None:
        env["GAITLOG_CACHE_DIR"] = cache_dir
    if no_jit:
        env["NUMBA_DISABLE_JIT"] = "1"
    return env


def run_child(code: str, args: list[str], env: dict[str, str]) -> tuple[float, dict]:
    """Wall time of ``python -c code args`` and its JSON output (``{}`` when it prints none)."""
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"child failed ({out.returncode}):\n{out.stderr[-2000:]}")
    lines = out.stdout.strip().splitlines()
    return wall, (json.loads(lines[-1]) if lines else {})


def best_wall(code: str, args: list[str], env: dict[str, str], repeat: int = 3) -> float:
    return min(run_child(code, args, env)[0] for _ in range(repeat))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-compile", action="store_true", help="skip the cold-compile measurement (~25 s)")
    args = ap.parse_args(argv)
    ok = True
    load = os.getloadavg()[0]

    # ---- the input: a walker recorded by the emulated logger, the algorithm on
    motion, subject = walker_motion()
    cfg = step_config(subject)
    logger = Logger(step_config=cfg)
    res = logger.record(motion)
    codes = np.asarray(res.codes)
    n_dev = logger.header.steps_written
    cal = logger.header.calibration
    algs = {a: OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, step_config=cfg, calibration=cal, arithmetic=a)
            for a in ("float", "fixed")}
    fixed_steps = algs["fixed"].run(codes)
    identical = (pack_step_records(fixed_steps.to_records(0))
                 == logger.step_memory[:n_dev * STEP_RECORD_SIZE])
    print(f"input: {codes.shape[0]} samples of a simulated walker ({codes.shape[0] / RATE_HZ:.2f} s at "
          f"{RATE_HZ:g} Hz), {n_dev} device step records; host replay in fixed point identical byte for byte: "
          f"{identical}; load average {load:.1f} on {os.cpu_count()} CPUs")
    if codes.shape[0] != N_SAMPLES or not identical:
        ok = False
        print("  FAILED: the input is not a full memory or the replay differs from the device")

    # ---- 1. in-process replay, warm
    t_alg = {a: best_of(lambda a=a: algs[a].run(codes), warmup=True) for a in algs}
    n_steps = {a: algs[a].run(codes).n_steps for a in algs}
    acc = CalibrationSlot.nominal(10).apply(codes.astype(np.float64)) if cal is None else cal.apply(codes.astype(float))
    from gaitlog.host.gait.pipeline import StepPipeline

    pipe = StepPipeline(leg_length_m=cfg.leg_length_m, foot_length_m=cfg.foot_length_m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_pipe = best_of(lambda: pipe.run(acc, sampling_rate_hz=RATE_HZ), warmup=True)
    n_pipe = pipe.steps_.n_steps

    walk = np.ascontiguousarray(codes[WALK_START:WALK_START + CPYTHON_SAMPLES])
    with tempfile.TemporaryDirectory() as tmp:
        full_path, walk_path = str(Path(tmp) / "codes.npy"), str(Path(tmp) / "walk.npy")
        np.save(full_path, codes)
        np.save(walk_path, walk)
        leg_foot = [repr(cfg.leg_length_m), repr(cfg.foot_length_m)]
        env = child_env()
        py, jit = {}, {}
        for a in algs:
            _, py[a] = run_child(CPYTHON, [walk_path, a, *leg_foot], child_env(no_jit=True))
            jit[a] = best_of(lambda a=a: algs[a].run(walk), warmup=True)
            if py[a]["steps"] != algs[a].run(walk).n_steps:
                ok = False
                print(f"  FAILED: CPython and compiled {a} differ on the slice")

        print(f"\n1. replay of {N_SAMPLES} samples, in-process, warm (best of 7)")
        scale = N_SAMPLES / CPYTHON_SAMPLES
        for a, target in (("float", FLOAT_TARGET_S), ("fixed", FIXED_TARGET_S)):
            t = t_alg[a]
            hit = t <= target
            ok &= hit
            print(f"  OnlineStepAlgorithm.run ({a:5s})  {t:.3f} s  ({N_SAMPLES / RATE_HZ / t:,.0f}x real time, "
                  f"{t / N_SAMPLES * 1e6:.2f} us/sample, {n_steps[a]} steps)  target <= {target} s"
                  f"{'' if hit else '  MISSED'}")
            print(f"    baseline CPython, same kernel: {py[a]['time_s'] * scale:.1f} s (NUMBA_DISABLE_JIT=1 on a "
                  f"{CPYTHON_SAMPLES}-sample walking slice: {py[a]['time_s']:.2f} s, scaled x{scale:g}) -> "
                  f"{py[a]['time_s'] * scale / t:,.0f}x slower; compiled on the same slice {jit[a] * 1e3:.1f} ms "
                  f"({py[a]['time_s'] / jit[a]:,.0f}x)")
        print(f"    baseline offline float chain (StepPipeline, codes in g): {t_pipe:.3f} s ({n_pipe} steps); the "
              f"on-line algorithm takes {t_alg['float'] / t_pipe:.2f}x its time in float, "
              f"{t_alg['fixed'] / t_pipe:.2f}x in fixed point")

        # ---- 2. cold start
        bare = best_wall("pass", [], env)
        imp = best_wall(IMPORT_ONLY, [], env)
        print("\n2. cold start: a fresh `python -c` (best of 3), compiled cache present (not a target)")
        for a in algs:
            whole = best_wall(COLD_PLAIN, [full_path, a, *leg_foot], env)
            parts = [run_child(COLD_SPLIT, [full_path, a, *leg_foot], env)[1] for _ in range(3)]
            sp = {k: min(p[k] for p in parts) for k in ("numpy", "numba", "project", "setup", "first", "warm")}
            load_s = sp["first"] - sp["warm"]
            print(f"  import + run ({a:5s}) on {N_SAMPLES} samples: {whole:.2f} s wall; of which numba "
                  f"{sp['numba'] + load_s:.2f} s (import {sp['numba']:.2f} s + cache load {load_s:.2f} s = first "
                  f"run {sp['first']:.2f} s - warm run {sp['warm']:.3f} s); numpy {sp['numpy']:.2f} s, project "
                  f"{sp['project']:.2f} s")
        print(f"  import alone (numpy, the algorithm, gaitlog.protocol.steps): {imp:.2f} s wall; bare interpreter "
              f"{bare:.3f} s")
        if not args.no_compile:
            for a in algs:
                with tempfile.TemporaryDirectory() as cache:
                    wall, sp = run_child(COLD_SPLIT, [full_path, a, *leg_foot], child_env(cache))
                print(f"  empty cache ({a:5s}): {wall:.1f} s wall, one-off compile {sp['first'] - sp['warm']:.1f} s "
                      f"(first run {sp['first']:.1f} s - warm run {sp['warm']:.3f} s), then cached")

        # ---- 3. long recordings
        print(f"\n3. long recordings: the {N_SAMPLES}-sample recording repeated, one fresh process per row; "
              f"peak = VmHWM of the process;\n   feed rows: time = best pass, us/sample and x 1x from each block's "
              f"best time over the passes (robust to a shared machine); baselines: one run")
        print(f"  {'chain':34s} {'samples':>9s} {'time s':>8s} {'us/sample':>10s} {'x 1x':>6s} {'steps':>7s} "
              f"{'peak MB':>8s} {'floor MB':>9s}")

        def row(name: str, reps: int, r: dict, per_1x: float | None) -> None:
            n = reps * N_SAMPLES
            per = r["block_s"] / n * 1e6
            ratio = f"{per / per_1x:6.2f}" if per_1x else "     -"
            print(f"  {name:34s} {n:9d} {r['time_s']:8.2f} {per:10.3f} {ratio} {r['steps']:7d} {r['peak_mb']:8.0f} "
                  f"{r['floor_mb']:9.0f}")

        results = {}
        for a in ("fixed", "float"):
            per_1x = None
            for reps in LENGTHS:
                r = run_child(LONG, [full_path, a, *leg_foot, str(reps), "stream"], env)[1]
                results[(a, reps)] = r
                per_1x = per_1x or r["block_s"] / N_SAMPLES * 1e6
                row(f"feed in blocks ({a})", reps, r, per_1x)
            big = results[(a, LENGTHS[-1])]
            lin = (big["block_s"] / (LENGTHS[-1] * N_SAMPLES)) / (results[(a, 1)]["block_s"] / N_SAMPLES)
            hit_mem, hit_lin = big["peak_mb"] <= MEMORY_TARGET_MB, lin <= LINEAR_TARGET
            ok &= hit_mem and hit_lin
            print(f"    {a} at 64x: peak {big['peak_mb']:.0f} MB (target <= {MEMORY_TARGET_MB:.0f} MB"
                  f"{'' if hit_mem else ', MISSED'}), of which the interpreter + imports floor "
                  f"{big['floor_mb']:.0f} MB (interpreter + numpy {big['numpy_mb']:.0f}, import numba "
                  f"+{big['numba_mb'] - big['numpy_mb']:.0f}, the project +{big['project_mb'] - big['numba_mb']:.0f}"
                  f", the compiled kernels loaded +{big['floor_mb'] - big['project_mb']:.0f}); time per sample "
                  f"{lin:.2f}x that at 1x (target <= {LINEAR_TARGET}{'' if hit_lin else ', MISSED'})")
        for a in ("fixed", "float"):
            r = run_child(LONG, [full_path, a, *leg_foot, str(LENGTHS[-1]), "whole"], env)[1]
            row(f"run on the whole array ({a})", LENGTHS[-1], r, None)
        print("    (baseline: the whole recording in memory, then OnlineStepAlgorithm.run; feed() streams)")
        per_1x = None
        for reps in LENGTHS:
            r = run_child(LONG, [full_path, "float", *leg_foot, str(reps), "offline"], env)[1]
            per_1x = per_1x or r["block_s"] / N_SAMPLES * 1e6
            row("offline StepPipeline (float)", reps, r, per_1x)
            nxt = r["floor_mb"] + (r["peak_mb"] - r["floor_mb"]) * 4
            if reps != LENGTHS[-1] and nxt > OFFLINE_LIMIT_MB:
                print(f"    (next length not run: ~{nxt:.0f} MB expected, more than {OFFLINE_LIMIT_MB:.0f} MB)")
                break
        print("    (baseline: the offline chain holds the whole recording in g and its intermediate arrays)")
    print("PASS" if ok else "FAIL: a target was missed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
