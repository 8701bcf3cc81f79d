"""The on-line step kernel compiled ahead of time: an extension module that runs without importing numba.

numba's JIT, even with its disk cache warm, costs a process about 0.4 s before the first sample (importing
numba, setting up its compiler, loading the cached code at the first call). The same kernel
(:mod:`gaitlog.firmware_sim.algorithms.kernel`: ``process``, ``flush``, ``reset``), compiled once by ``numba.pycc`` into
an ordinary extension module, loads in a millisecond with numpy alone. Its code is numba's, from the same
text: the records, counters and state are the JIT's bit for bit (tested).

Where: ``aot-<hash>/`` beside numba's cache folder (:mod:`gaitlog.firmware_sim.compiled`: the same hash of the
compiled sources, this file included), so any edit of them, or another numba, builds a new module. Exports,
one per entry point and arithmetic: ``process_fixed``, ``flush_fixed``, ``reset_fixed`` (int64 values: the
PIC's fixed point) and ``process_float``, ``flush_float``, ``reset_float`` (float64), for the array layouts
the driver (:class:`gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`) passes: C-contiguous arrays, ``k``
an int64.

The exports release the GIL while they run (as numba's ``nogil=True``; so do the JIT's entry points): a thread can
run the kernel beside Python code in another (``gaitlog estimate --arithmetic both`` runs the two chains so).

Building needs numba, setuptools and a C compiler with the Python headers; it takes about 10 s, less than
numba's first JIT compilation of both arithmetics (about 16 s), and happens once per version of the sources,
in the first process that needs the kernel (:func:`entry_points`). It is done in a temporary folder renamed
into place, under a lock file: a reader never sees a half-written module, and a second process waits for
the first's build instead of compiling too. A failed build (no compiler) leaves ``aot-<hash>.failed`` (the
error) and is not retried for that hash: numba's JIT is used instead. ``GAITLOG_NO_AOT=1`` (or numba's
``NUMBA_DISABLE_JIT=1``) turns the module off. A build removes the cache folders of other versions of the
sources unused for two weeks (:func:`gaitlog.firmware_sim.compiled.prune_cache`).

Run ``python -m gaitlog.firmware_sim.algorithms.aot_kernel`` to build it now and print its path.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import os
import shutil
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.compiled import announce_compile, cache_base, load_numba, prune_cache, source_hash, touch

__all__ = ["ARITHMETIC_TYPES", "ENTRY_POINTS", "MODULE_NAME", "EntryPoint", "aot_dir", "build", "build_or_wait",
           "enabled", "entry_points", "kernel_exports", "load"]

#: Name of the extension module.
MODULE_NAME = "gaitlog_online_kernel"
#: numba's value type of each arithmetic (the driver's ``OnlineConfig.value_dtype``).
ARITHMETIC_TYPES = {"fixed": "int64", "float": "float64"}
#: The kernel's entry points; exported as ``<name>_<arithmetic>``.
ENTRY_POINTS = ("process", "flush", "reset")
#: A build lock older than this (or whose process is gone) is a crashed build's: taken over.
STALE_LOCK_S = 600.0
#: How long a process waits for another process's build before it uses numba's JIT.
BUILD_WAIT_S = 180.0

#: Per arithmetic: the kernel's (process, flush, reset) and who compiled them, chosen once per process.
_ENTRY_POINTS: dict[str, tuple[tuple[EntryPoint, EntryPoint, EntryPoint], str]] = {}


def _signatures(v: str) -> dict[str, str]:
    """numba signatures of the entry points with value type ``v`` (see ``kernel.process`` etc.)."""
    i1, i2, v1, v2 = "int64[::1]", "int64[:, ::1]", f"{v}[::1]", f"{v}[:, ::1]"
    return {
        # codes, cfg_i, cfg_v, st_i, st_v, line, durs, scr, out_i, out_v, k, cnt, cyc
        "process": f"int64({v2}, {i1}, {v1}, {i1}, {v1}, {v1}, {i1}, {v1}, {i2}, {v2}, int64, {i1}, {i1})",
        # cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt
        "flush": f"int64({i1}, {v1}, {i1}, {v1}, {v1}, {i2}, {v2}, int64, {i1})",
        # cfg_i, st_i, st_v, line, durs
        "reset": f"void({i1}, {i1}, {v1}, {v1}, {i1})",
    }


def enabled() -> bool:
    """False when ``GAITLOG_NO_AOT=1`` or ``NUMBA_DISABLE_JIT=1`` (the Python text must run then)."""
    return os.environ.get("GAITLOG_NO_AOT", "") in ("", "0") and os.environ.get("NUMBA_DISABLE_JIT", "") in ("", "0")


def aot_dir() -> Path:
    """The module's folder for this version of the compiled sources: ``<cache>/aot-<hash>``."""
    return cache_base() / f"aot-{source_hash()}"


def _module_file(folder: Path, module_name: str = MODULE_NAME) -> Path | None:
    found = sorted(folder.glob(module_name + ".*so")) + sorted(folder.glob(module_name + ".*pyd"))
    return found[0] if found else None


#: The exports of the shipped module: ``<entry point>_<arithmetic>``.
_EXPORTS = tuple(f"{n}_{a}" for n in ENTRY_POINTS for a in ARITHMETIC_TYPES)


def load(folder: Path | None = None, *, module_name: str = MODULE_NAME,
         exports: tuple[str, ...] = _EXPORTS) -> ModuleType | None:
    """The built module, imported by path (numba is not imported); None if not built or unloadable."""
    folder = folder if folder is not None else aot_dir()
    path = _module_file(folder, module_name)
    if path is None:
        return None
    try:
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (ImportError, OSError):
        return None
    if not all(hasattr(module, name) for name in exports):
        return None
    touch(folder)
    return module


def kernel_exports(namespace: dict | None = None, arithmetics: tuple[str, ...] = tuple(ARITHMETIC_TYPES)
                   ) -> list[tuple[str, str, Callable]]:
    """``(export name, numba signature, Python function)`` of the entry points of the kernel whose compiled
    functions are ``namespace``'s (default the shipped kernel module's), for ``arithmetics``."""
    ns = namespace if namespace is not None else vars(kernel)
    return [(f"{name}_{arithmetic}", sig, ns[name].py_func) for arithmetic in arithmetics
            for name, sig in _signatures(ARITHMETIC_TYPES[arithmetic]).items()]


def build(folder: Path | None = None, *, module_name: str = MODULE_NAME,
          exports: Callable[[], list[tuple[str, str, Callable]]] | None = None, what: str = "") -> Path:
    """Compile the module into ``folder`` (default :func:`aot_dir`) unless it is there; return its path.
    ``exports`` gives what it exports (:func:`kernel_exports`, called only when a build is needed; default the
    shipped kernel's entry points in both arithmetics).

    Raises whatever the compilation raises (no compiler, no Python headers, no setuptools).
    """
    final = folder if folder is not None else aot_dir()
    existing = _module_file(final, module_name)
    if existing is not None:
        return existing
    announce_compile(f"the on-line step kernel{what} is compiled ahead of time into {final}")
    load_numba()                                     # the kernel's functions as numba dispatchers
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.with_name(f"{final.name}.build-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)           # a crashed build of a process with this id
    tmp.mkdir()                                      # the user's umask, as the folder it becomes
    try:
        with warnings.catch_warnings():
            # numba.pycc is "pending deprecation" (numba 0.57+; still shipped and working in 0.68): only that
            # warning is silenced, the replacement (PIXIE) is not released yet
            warnings.filterwarnings("ignore", message=".*pycc.*", category=PendingDeprecationWarning)
            warnings.filterwarnings("ignore", message=".*pycc.*", category=DeprecationWarning)
            pycc = importlib.import_module("numba.pycc")
            cc = pycc.CC(module_name, source_module=kernel)
            cc.output_dir = str(tmp)
            cc.verbose = False
            for name, sig, fn in (exports() if exports is not None else kernel_exports()):
                cc.export(name, sig)(fn)
            with _releasing_the_gil():
                cc.compile()
        try:
            os.rename(tmp, final)                    # atomic; fails if another process got there first
        except OSError:
            if _module_file(final, module_name) is None:
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return _module_file(final, module_name)


@contextlib.contextmanager
def _releasing_the_gil():
    """While it is open, the modules ``numba.pycc`` compiles export functions that release the GIL while they run
    (numba's ``release_gil`` flag, which ``nogil=True`` sets for the JIT; ``numba.pycc`` has no option of its own):
    a thread can run the kernel while another runs Python. The kernel touches no Python object."""
    compiler = importlib.import_module("numba.pycc.compiler")
    base = compiler.Flags

    class ReleasingFlags(base):
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)
            self.release_gil = True

    compiler.Flags = ReleasingFlags
    try:
        yield
    finally:
        compiler.Flags = base


def _lock_is_stale(lock: Path) -> bool:
    try:
        age = time.time() - lock.stat().st_mtime
        pid = int(lock.read_text().strip() or 0)
    except (OSError, ValueError):
        return True
    if age > STALE_LOCK_S:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    return False


def build_or_wait(final: Path | None = None, *, module_name: str = MODULE_NAME,
                  exports: Callable[[], list[tuple[str, str, Callable]]] | None = None,
                  names: tuple[str, ...] = _EXPORTS, what: str = "") -> ModuleType | None:
    """The module in ``final`` (default :func:`aot_dir`, the shipped kernel): loaded, else built by this process
    (under the lock) or by another one (waited for: processes of one machine build it once); None if the build
    failed, now or before, or took too long. ``module_name``, ``exports``, ``names``: another kernel's module
    (:mod:`gaitlog.firmware_sim.algorithms.format_kernel`'s variants)."""
    final = final if final is not None else aot_dir()
    module = load(final, module_name=module_name, exports=names)
    if module is not None:
        return module
    failed = final.with_name(final.name + ".failed")
    lock = final.with_name(final.name + ".lock")
    deadline = time.monotonic() + BUILD_WAIT_S
    while not failed.exists():
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _lock_is_stale(lock):
                lock.unlink(missing_ok=True)
                continue
            if time.monotonic() > deadline:
                return None
            time.sleep(0.2)
            module = load(final, module_name=module_name, exports=names)
            if module is not None:
                return module
            continue
        except OSError:
            return None                              # no writable cache folder
        try:
            os.write(fd, str(os.getpid()).encode())
            os.close(fd)
            build(final, module_name=module_name, exports=exports, what=what)
            prune_cache(final)                       # long-unused builds of other versions of the sources
        except Exception as exc:  # noqa: BLE001 - any build failure: recorded, numba's JIT is used instead
            try:
                failed.write_text(f"{type(exc).__name__}: {exc}\n")
            except OSError:
                pass
            return None
        finally:
            lock.unlink(missing_ok=True)
        return load(final, module_name=module_name, exports=names)
    return None


class EntryPoint:
    """One of the kernel's functions for one arithmetic; pickled by name, so that a process receiving an
    algorithm's object uses its own kernel (the module built ahead of time is loaded by path: it cannot be
    imported by name)."""

    def __init__(self, name: str, arithmetic: str, fn: Callable) -> None:
        self.name, self.arithmetic, self.fn = name, arithmetic, fn

    def __call__(self, *args: object) -> object:
        return self.fn(*args)

    def __reduce__(self) -> tuple:
        return _entry_point, (self.name, self.arithmetic)

    def __repr__(self) -> str:
        return f"<kernel {self.name} ({self.arithmetic}): {self.fn!r}>"


def _entry_point(name: str, arithmetic: str) -> EntryPoint:
    return entry_points(arithmetic)[0][ENTRY_POINTS.index(name)]


def entry_points(arithmetic: str) -> tuple[tuple[EntryPoint, EntryPoint, EntryPoint], str]:
    """The kernel's ``process``, ``flush``, ``reset`` for ``arithmetic``, and ``"aot"`` or ``"jit"``.

    From the module compiled ahead of time (built now if missing, see the module's docstring); numba's JIT
    (:mod:`gaitlog.firmware_sim.algorithms.kernel`) when that is off or cannot be built. Chosen once per process.
    """
    found = _ENTRY_POINTS.get(arithmetic)
    if found is None:
        module = build_or_wait() if enabled() else None
        if module is not None:
            fns, by = [getattr(module, f"{name}_{arithmetic}") for name in ENTRY_POINTS], "aot"
        else:
            fns, by = [getattr(kernel, name) for name in ENTRY_POINTS], "jit"
        found = (tuple(EntryPoint(n, arithmetic, f) for n, f in zip(ENTRY_POINTS, fns)), by)
        _ENTRY_POINTS[arithmetic] = found
    return found


def main(argv: list[str] | None = None) -> int:
    """``python -m gaitlog.firmware_sim.algorithms.aot_kernel``: build the module now, print its path."""
    if argv:
        print(f"usage: python -m {__name__} (builds the module; no arguments)", file=sys.stderr)
        return 2
    try:
        print(build())
    except Exception as exc:  # noqa: BLE001 - reported, one line
        print(f"error: building {MODULE_NAME} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
