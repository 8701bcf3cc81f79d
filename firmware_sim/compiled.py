"""The firmware's compiled (numba) code: loaded only when it runs, cached by the sources it is compiled from.

The PIC arithmetic (:mod:`gaitlog.firmware_sim.fixedpoint`) and the on-line step algorithm
(:mod:`gaitlog.firmware_sim.algorithms`) are plain Python functions that numba compiles to machine code on first
use. Importing numba and loading its cached code costs a process about 0.4 s, so nothing here imports numba
until a compiled function is actually called:

* :func:`njit` marks a function for ``numba.njit(cache=True)`` and returns a :class:`LazyDispatcher`; its
  first call (any one's) loads numba, compiles (or loads from the cache) every marked function, and puts
  the dispatchers in place of the markers in their modules, so compiled functions call each other as numba
  requires;
* :func:`register_jitable` and :func:`overload` record what numba's own decorators of the same names do and
  apply it then;
* :data:`numba_types` is ``numba.types``, imported at its first attribute access (an overload's typing code).

When ``gaitlog.firmware_sim.algorithms.aot_kernel`` has built the on-line kernel ahead of time, a process that only runs
that kernel never imports numba.

Cache: numba checks only the timestamp of the file that holds the *calling* function, not of the functions
it inlines from other files: after an edit of ``fixedpoint.py`` a cached kernel of
``algorithms/kernel.py`` would still run the old arithmetic. numba's cache is therefore pointed at a
directory named after a hash of every source file whose code ends up in a compiled kernel
(:func:`source_hash`); any edit gives a new directory and a fresh compilation. Location: :func:`cache_base`
(``$GAITLOG_CACHE_DIR``, else ``$XDG_CACHE_HOME/gaitlog``, else ``~/.cache/gaitlog``), sub-folder
``numba-<hash>`` (the kernel compiled ahead of time: ``aot-<hash>``). A ``NUMBA_CACHE_DIR`` set by the user wins
(numba's own variable); a cache folder that cannot be created leaves numba's default in place. Folders of
other hashes unused for :data:`PRUNE_AFTER_DAYS` are removed when a new one is made (:func:`prune_cache`).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = ["COMPILED_SOURCES", "PRUNE_AFTER_DAYS", "LazyDispatcher", "announce_compile", "cache_base", "cache_dir",
           "compile_listeners", "jit_options", "load_numba", "njit", "numba_types", "overload", "prune_cache",
           "register_jitable", "source_hash", "touch"]

_ROOT = Path(__file__).resolve().parents[1]

#: Source files whose functions or constants are compiled into the kernels (relative to the repository root;
#: the step flags of ``protocol/steps.py`` are frozen into the kernel as constants; ``aot_kernel.py`` holds the
#: signatures the kernel is compiled ahead of time with).
COMPILED_SOURCES: tuple[str, ...] = ("firmware_sim/compiled.py", "firmware_sim/fixedpoint.py",
                                     "firmware_sim/algorithms", "protocol/steps.py",
                                     "firmware_sim/pic/kernel_cycles.json")
#: Cache folders (``numba-*``, ``aot-*``) of other source versions not used for this long are removed.
PRUNE_AFTER_DAYS = 14.0

#: Called with one line saying what is compiled, just before code is compiled rather than loaded from the
#: cache (a first run, or a run after an edit of :data:`COMPILED_SOURCES`): the ``gaitlog`` command line
#: registers one that prints it on stderr. This module prints nothing itself.
compile_listeners: list[Callable[[str], None]] = []


def announce_compile(what: str) -> None:
    """Tell every :data:`compile_listeners` that ``what`` is being compiled now."""
    for listener in list(compile_listeners):
        listener(what)


def _numba_version_text() -> bytes:
    """numba's ``_version.py`` (its version), read without importing numba; empty if numba is absent."""
    spec = importlib.util.find_spec("numba")
    if spec is None or spec.origin is None:
        return b""
    try:
        return (Path(spec.origin).parent / "_version.py").read_bytes()
    except OSError:
        return spec.origin.encode()


def source_hash() -> str:
    """First 16 hex digits of the SHA-256 of the compiled sources (file names and contents, sorted) and of
    the installed numba's version."""
    h = hashlib.sha256()
    for rel in COMPILED_SOURCES:
        p = _ROOT / rel
        files = sorted(p.rglob("*.py")) if p.is_dir() else [p]
        for f in files:
            h.update(str(f.relative_to(_ROOT)).encode())
            h.update(f.read_bytes())
    h.update(_numba_version_text())
    return h.hexdigest()[:16]


def cache_base() -> Path:
    """gaitlog's cache folder: ``$GAITLOG_CACHE_DIR``, else ``$XDG_CACHE_HOME/gaitlog``, else ``~/.cache/gaitlog``."""
    base = os.environ.get("GAITLOG_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME")
        base = str(Path(xdg) / "gaitlog") if xdg else str(Path.home() / ".cache" / "gaitlog")
    return Path(base)


def cache_dir() -> Path:
    """numba's cache folder for this version of the compiled sources."""
    return cache_base() / f"numba-{source_hash()}"


def touch(folder: Path) -> None:
    """Mark a cache folder as used now (its modification time; :func:`prune_cache` keeps it)."""
    try:
        os.utime(folder)
    except OSError:
        pass


def prune_cache(keep: Path, *, max_age_days: float = PRUNE_AFTER_DAYS) -> list[Path]:
    """Remove the ``numba-*`` and ``aot-*`` folders beside ``keep`` not used for ``max_age_days``; return them.

    Other checkouts of gaitlog (other source versions) share the cache folder: a folder in use is touched
    (:func:`touch`) and stays; what is removed is only what no process has loaded for that long.
    """
    removed = []
    cutoff = time.time() - max_age_days * 86400.0
    try:
        siblings = list(keep.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        if p == keep or not p.name.startswith(("numba-", "aot-")):
            continue
        try:
            if p.stat().st_mtime >= cutoff:
                continue
            if p.is_dir():
                shutil.rmtree(p)
            else:
                p.unlink()
        except OSError:
            continue
        removed.append(p)
    return removed


class _Registry:
    """What numba must know once it is loaded: jitable functions, overloads, functions to compile."""

    def __init__(self) -> None:
        self.numba: ModuleType | None = None
        self.jitable: list[Callable] = []
        self.overloads: list[tuple[Callable, Callable, dict]] = []
        self.lazy: list[LazyDispatcher] = []
        self.lock = threading.RLock()

    def _configure_cache(self, numba: ModuleType) -> None:
        if os.environ.get("NUMBA_CACHE_DIR"):
            return
        d = cache_dir()
        try:
            new = not d.exists() or not any(d.iterdir())
            d.mkdir(parents=True, exist_ok=True)
        except OSError:
            return
        if new:
            announce_compile(f"numba compiles the firmware's code into {d}")
        if os.access(d, os.W_OK):
            numba.config.CACHE_DIR = str(d)
            touch(d)
            if new:
                prune_cache(d)

    def load(self) -> ModuleType:
        """Import numba, register everything recorded, compile the marked functions (from the cache)."""
        with self.lock:
            if self.numba is None:
                numba = importlib.import_module("numba")
                extending = importlib.import_module("numba.extending")
                self._configure_cache(numba)
                for fn in self.jitable:
                    extending.register_jitable(fn)
                for fn, impl, options in self.overloads:
                    extending.overload(fn, **options)(impl)
                for lazy in self.lazy:
                    lazy._materialise(numba)
                self.jitable, self.overloads, self.lazy = [], [], []
                self.numba = numba
            return self.numba


_REGISTRY = _Registry()


def load_numba() -> ModuleType:
    """numba, with every function marked by this module's decorators registered and compiled."""
    return _REGISTRY.load()


class LazyDispatcher:
    """A function numba compiles (``njit(cache=True)``) when it is first called, not when it is defined.

    The first call of any :class:`LazyDispatcher` loads numba (:func:`load_numba`) and replaces each one in its
    module by numba's dispatcher; a reference kept elsewhere forwards its calls to that dispatcher.

    Attributes
    ----------
    py_func
        The Python function (as on numba's dispatchers).
    """

    def __init__(self, py_func: Callable, options: dict[str, Any] | None = None) -> None:
        self.py_func = py_func
        self.options = dict(options or {})
        self.dispatcher: Callable | None = None
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func

    def _materialise(self, numba: ModuleType) -> None:
        self.dispatcher = numba.njit(cache=True, **self.options)(self.py_func)
        g = self.py_func.__globals__
        if g.get(self.__name__) is self:
            g[self.__name__] = self.dispatcher

    def __call__(self, *args: Any) -> Any:
        if self.dispatcher is None:
            load_numba()
        return self.dispatcher(*args)

    def __repr__(self) -> str:
        state = "compiled" if self.dispatcher is not None else "not loaded"
        return f"<LazyDispatcher {self.__module__}.{self.__qualname__} ({state})>"


def njit(*, cache: bool = True, nrt: bool | None = None, nogil: bool = False
         ) -> Callable[[Callable], LazyDispatcher]:
    """``numba.njit(cache=True)``, applied when a compiled function is first called (see the module).

    ``nrt``: numba's runtime (reference counts of arrays, allocation) on or off for this function (numba's
    ``_nrt``); None: numba's default, the caller's setting (on when called from Python). A function that
    allocates no array needs none: off, passing arrays to it and receiving them costs no atomic reference
    count (in the on-line kernel they were 40 % of its time). Its callees inherit the setting unless theirs is
    given: a function that allocates says ``nrt=True``. ``nogil``: numba's, the function releases the GIL while it
    runs (called from Python).
    """
    if not cache:
        raise ValueError("the firmware's compiled functions are always cached (cache=True)")
    options = ({} if nrt is None else {"_nrt": bool(nrt)}) | ({"nogil": True} if nogil else {})

    def mark(fn: Callable) -> LazyDispatcher:
        lazy = LazyDispatcher(fn, options)
        if _REGISTRY.numba is not None:
            lazy._materialise(_REGISTRY.numba)
        else:
            _REGISTRY.lazy.append(lazy)
        return lazy

    return mark


def jit_options(fn: Any) -> dict[str, Any]:
    """The options (besides the cache) a compiled function was marked with (:func:`njit`'s ``nrt`` as numba's
    ``_nrt``, ``nogil``), of a :class:`LazyDispatcher` or of the numba dispatcher that replaced it: a copy of the
    function compiled with other globals (:mod:`gaitlog.firmware_sim.algorithms.format_kernel`) takes the same."""
    if isinstance(fn, LazyDispatcher):
        return dict(fn.options)
    return {k: v for k, v in getattr(fn, "targetoptions", {}).items() if k in ("_nrt", "nogil")}


def register_jitable(fn: Callable) -> Callable:
    """``numba.extending.register_jitable``, applied when numba is loaded; returns ``fn`` itself."""
    if _REGISTRY.numba is not None:
        importlib.import_module("numba.extending").register_jitable(fn)
    else:
        _REGISTRY.jitable.append(fn)
    return fn


def overload(fn: Callable, **options: Any) -> Callable[[Callable], Callable]:
    """``numba.extending.overload(fn, **options)``, applied when numba is loaded."""

    def record(impl: Callable) -> Callable:
        if _REGISTRY.numba is not None:
            importlib.import_module("numba.extending").overload(fn, **options)(impl)
        else:
            _REGISTRY.overloads.append((fn, impl, options))
        return impl

    return record


class _LazyModule:
    """A module imported at its first attribute access."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(importlib.import_module(self._name), attr)


#: ``numba.types`` (numba's type classes), imported at first use: overloads' typing code runs only while numba
#: compiles.
numba_types = _LazyModule("numba.types")
