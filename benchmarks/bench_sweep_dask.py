"""Benchmark: ``gaitlog sweep`` on Dask, 1 vs 2 local workers, against a serial in-process run; and (``--thousand``)
a 1,000-task sweep cut mid-run and resumed.

Speed-up: the same 24-task grid (the paper's protocol, 4 subjects, 8/10/12 bits x 25/50 Hz) run (a) serially in this
process (``--serial``: no Dask), (b) on a LocalCluster of 1 worker process, (c) of 2 worker processes, each into
a fresh folder by ``python -m gaitlog.host.cli sweep`` in a child process (so every run pays its own imports; the Dask
runs include starting their cluster). The three result folders must be byte-identical.

1,000 tasks (``--thousand``): 5 subjects x 5 rates (25-100 Hz) x 5 noise densities (0-800 ug/rtHz) x ADC 5-12
bits on the short protocol, 2 workers; the run is killed (SIGKILL of its process group, workers included) when
about half the tasks are stored, then re-run: it must compute exactly the missing tasks and finish.

Run: ``python benchmarks/bench_sweep_dask.py [--thousand]`` (exit status 1 when the results differ or the
resumed run recomputes a stored task). The machine's load is printed: on a shared 2-core machine the
speed-up is bounded by the free cores.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GRID = ["--protocol", "paper", "--subjects", "4", "--adc-bits", "8,10,12", "--logger-rate", "25,50"]
THOUSAND = ["--protocol", "short", "--subjects", "5", "--adc-bits", "5,6,7,8,9,10,11,12",
            "--logger-rate", "25,40,50,80,100", "--noise-density", "0,0.0001,0.0002,0.0004,0.0008"]
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def sweep(out: Path, *args: str) -> float:
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "gaitlog.host.cli", "sweep", "--out", str(out), "-q", *args], env=ENV, check=True)
    return time.perf_counter() - t


def files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def speedup(tmp: Path) -> bool:
    # warm the numba cache once (not timed)
    sweep(tmp / "warm", "--serial", "--protocol", "short", "--subjects", "1", "--adc-bits", "10", "--logger-rate", "50")
    t_serial = sweep(tmp / "serial", "--serial", *GRID)
    t1 = sweep(tmp / "w1", "--workers", "1", *GRID)
    t2 = sweep(tmp / "w2", "--workers", "2", *GRID)
    same = files(tmp / "serial") == files(tmp / "w1") == files(tmp / "w2")
    n = len(list((tmp / "serial" / "tasks").glob("*.json")))
    print(f"{n} tasks (the paper's protocol, 4 subjects x 8/10/12 bits x 25/50 Hz); load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} CPUs")
    print(f"  serial in-process   {t_serial:7.1f} s")
    print(f"  Dask, 1 worker      {t1:7.1f} s   ({t_serial / t1:.2f}x serial)")
    print(f"  Dask, 2 workers     {t2:7.1f} s   speed-up {t1 / t2:.2f}x vs 1 worker, {t_serial / t2:.2f}x vs serial")
    print(f"  results identical (serial, 1 worker, 2 workers): {same}")
    return same


def thousand(tmp: Path) -> bool:
    out = tmp / "thousand"
    tasks = out / "tasks"
    t = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog.host.cli", "sweep", "--out", str(out), "-q", "--workers", "2",
                             *THOUSAND], env=ENV, start_new_session=True)
    while proc.poll() is None and (not tasks.is_dir() or len(list(tasks.glob("*.json"))) < 500):
        time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    t_cut = time.perf_counter() - t
    stored = {p.name: p.stat().st_mtime_ns for p in tasks.glob("*.json")}
    print(f"1,000-task sweep (5 subjects x 5 rates x 5 noise densities x 8 widths), 2 workers: cut after {t_cut:.0f} s "
          f"with {len(stored)} tasks stored")
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "gaitlog.host.cli", "sweep", "--out", str(out), "--workers", "2", *THOUSAND],
                       env=ENV, capture_output=True, text=True)
    t_resume = time.perf_counter() - t
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("computed")), r.stderr.strip()[-300:])
    total = len(list(tasks.glob("*.json")))
    kept = all(p.stat().st_mtime_ns == stored[p.name] for p in tasks.glob("*.json") if p.name in stored)
    ok = r.returncode == 0 and total == 1000 and kept and f"computed {1000 - len(stored)} task(s)" in line
    rows = (out / "sections.csv").read_text().count("\n") - 1 if (out / "sections.csv").exists() else 0
    print(f"  resumed: {line} (wall {t_resume:.0f} s); {total} tasks stored, {rows} section rows; "
          f"stored tasks untouched: {kept}")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--thousand", action="store_true", help="also the 1,000-task cut-and-resume run")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_dask_"))
    try:
        ok = speedup(tmp)
        if args.thousand:
            ok = thousand(tmp) and ok
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
