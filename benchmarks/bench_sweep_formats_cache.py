"""Benchmark: a sweep with a non-shipped Q-format set on 2 Dask workers, its compiled kernel shared by the workers
through the compile cache.

Three runs of the same grid (short protocol, 2 subjects, 10 bits, 50 Hz, ``--q-formats shipped,SET`` with a SET
whose module is not yet in the compile cache, so the first run has to build it), each by ``python -m
gaitlog.host.cli sweep`` into a fresh folder on a fresh local cluster of 2 workers:

* **baseline, JIT per worker** (``GAITLOG_NO_AOT=1``: what every sweep did before the cache): each worker
  JIT-compiles the set itself;
* **first run**: one worker builds the set's module into the compile cache, the other waits for it and loads it;
* **second run**: both workers load it (no compilation: the module's folder is not rebuilt, checked by its
  modification time).

The three result folders must hold the same rows (the kernel is the same text, compiled two ways). Run:
``python benchmarks/bench_sweep_formats_cache.py`` (exit status 1 when the second run compiled or the results
differ). The machine's load is printed: on a shared 2-core machine the times move with it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GRID = ["--protocol", "short", "--subjects", "2", "--adc-bits", "10", "--logger-rate", "50", "--workers", "2"]
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def fresh_formats() -> str:
    """A format set whose compiled module is not in the compile cache yet (the first such ``accA-gravG``)."""
    from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats, variant_folder

    for grav in range(28, 10, -1):
        for acc in range(12, 5, -1):
            f = KernelFormats(acc_frac_bits=acc, gravity_frac_bits=grav)
            if not variant_folder(f).exists():
                return f.label()
    raise SystemExit("no format set left without a cached module: clear the compile cache")


def sweep(out: Path, formats: str, **env: str) -> float:
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "gaitlog.host.cli", "sweep", "--out", str(out), "-q", *GRID,
                    "--q-formats", f"shipped,{formats}"], env=dict(ENV, **env), check=True)
    return time.perf_counter() - t


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats, variant_folder

    formats = fresh_formats()
    folder = variant_folder(KernelFormats.parse(formats))
    print(f"format set {formats} (module folder {folder.name}); load {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        t_jit = sweep(Path(tmp) / "jit", formats, GAITLOG_NO_AOT="1")
        assert not folder.exists(), "the JIT baseline must not build the module"
        t_first = sweep(Path(tmp) / "first", formats)
        built = folder.stat().st_mtime_ns if folder.exists() else None
        module = sorted(folder.glob("*.so")) if folder.exists() else []
        t_second = sweep(Path(tmp) / "second", formats)
        rebuilt = [p.stat().st_mtime_ns for p in sorted(folder.glob("*.so"))] != [p.stat().st_mtime_ns for p in module]
        same = all((Path(tmp) / "jit" / name).read_bytes() == (Path(tmp) / run / name).read_bytes()
                   for run in ("first", "second") for name in ("sections.csv", "splits.csv"))
    print(f"JIT in every worker (before): {t_jit:.1f} s")
    print(f"first run, built once in the compile cache: {t_first:.1f} s")
    print(f"second run, loaded by both workers: {t_second:.1f} s  ({t_first / t_second:.1f}x faster than the first,"
          f" {t_jit / t_second:.1f}x than JIT)")
    ok = built is not None and not rebuilt and same
    print(f"module built: {built is not None}; rebuilt by the second run: {rebuilt}; rows identical: {same}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
