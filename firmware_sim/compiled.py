"""Where the firmware's compiled (numba) code is cached, keyed by the sources it is compiled from.

The PIC arithmetic (:mod:`firmware_sim.fixedpoint`) and the on-line step algorithm
(:mod:`firmware_sim.algorithms`) are plain Python functions that numba compiles to machine code on first
use (``cache=True`` keeps the result on disk, so a later process loads it in milliseconds instead of
compiling for seconds). numba checks only the timestamp of the file that holds the *calling* function, not
of the functions it inlines from other files: after an edit of ``fixedpoint.py`` a cached kernel of
``algorithms/online.py`` would still run the old arithmetic. This module therefore points numba's cache at
a directory named after a hash of every source file whose code ends up in a compiled kernel; any edit gives
a new directory and a fresh compilation.

Import it before any module that decorates with ``cache=True`` (``fixedpoint`` does, first thing).

Location: ``$GAITLOG_CACHE_DIR``, else ``$XDG_CACHE_HOME/gaitlog``, else ``~/.cache/gaitlog``, with a
sub-folder ``numba-<hash>``. A ``NUMBA_CACHE_DIR`` set by the user wins (numba's own variable); a cache
folder that cannot be created leaves numba's default in place.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba

__all__ = ["COMPILED_SOURCES", "source_hash", "cache_dir"]

_ROOT = Path(__file__).resolve().parents[1]

#: Source files whose functions or constants are compiled into the kernels (relative to the repository root;
#: the step flags of ``protocol/steps.py`` are frozen into the kernel as constants).
COMPILED_SOURCES: tuple[str, ...] = ("firmware_sim/compiled.py", "firmware_sim/fixedpoint.py",
                                     "firmware_sim/algorithms", "protocol/steps.py",
                                     "firmware_sim/pic/kernel_cycles.json")


def source_hash() -> str:
    """First 16 hex digits of the SHA-256 of the compiled sources (file names and contents, sorted)."""
    h = hashlib.sha256()
    for rel in COMPILED_SOURCES:
        p = _ROOT / rel
        files = sorted(p.rglob("*.py")) if p.is_dir() else [p]
        for f in files:
            h.update(str(f.relative_to(_ROOT)).encode())
            h.update(f.read_bytes())
    h.update(numba.__version__.encode())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    """The cache folder for this version of the compiled sources."""
    base = os.environ.get("GAITLOG_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME")
        base = str(Path(xdg) / "gaitlog") if xdg else str(Path.home() / ".cache" / "gaitlog")
    return Path(base) / f"numba-{source_hash()}"


def _configure() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    d = cache_dir()
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError:
        return
    if os.access(d, os.W_OK):
        numba.config.CACHE_DIR = str(d)


_configure()
