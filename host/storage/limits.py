"""How much the host reads from one input file, judged by what the file really holds and checked *before* it is
allocated: a small hostile file (a CSV with a 2 x 10^5 s time gap, a zip bomb inside an NPZ, a ``.npy`` header
claiming terabytes) is a one-line :class:`~gaitlog.host.errors.HostError` naming the file, not a crash or gigabytes
of memory, while a genuine recording of any length that fits in memory is read.

There is no fixed sample count. A CSV's rows are what it parses (bounded by its bytes; the table is checked
against the memory available as it grows); a time grid may spread them over at most
:data:`MAX_GRID_SAMPLES_PER_ROW` samples each, or over :data:`GRID_SAMPLES_ALWAYS_READ` whatever their number (a short
recording with a long pause); an NPZ's arrays are judged by their declared shapes against the
zip's declared and compressed sizes (:data:`MAX_NPZ_EXPANSION`) and against the memory available
(:func:`check_memory`).
"""

from __future__ import annotations

import os
from pathlib import Path

from gaitlog.host.errors import HostError

__all__ = ["DEFAULT_MAX_MISSING_PERCENT", "GRID_SAMPLES_ALWAYS_READ", "MAX_GRID_SAMPLES_PER_ROW", "MAX_JSON_BYTES", "MAX_NPZ_EXPANSION",
           "MAX_TEXT_BYTES", "MEMORY_SHARE", "NPZ_SMALL_BYTES", "available_memory_bytes", "check_file_size",
           "check_grid", "check_memory", "grid_limit"]

#: Missing share of a recording (percent of its stored samples) above which ``decode``, ``estimate`` and ``batch``
#: exit 1 (``--max-missing``; :mod:`gaitlog.host.files.losses`).
DEFAULT_MAX_MISSING_PERCENT = 5.0
#: Samples of a regular time grid (rows of a CSV on its time column, IPOL packets on their counter) per sample the
#: file holds: a genuine gap (the logger paused over lunch) is within it, a 68-byte file spreading four rows over
#: 2 x 10^8 grid samples is not.
MAX_GRID_SAMPLES_PER_ROW = 100
#: Samples of a time grid read whatever the rows (2^21: 11.6 h at 50 Hz, about 100 MB as the chain holds it): a few
#: minutes of walking either side of an overnight pause is a genuine recording, not a hostile file.
GRID_SAMPLES_ALWAYS_READ = 1 << 21
#: How many times the arrays of a recording NPZ may be larger than their compressed size in the zip: a recording's
#: sample numbers are distinct int64 values, which deflate shrinks about 5 times, so even constant codes compress
#: only about 10 times (a zip bomb of zeros: about 1,000 times).
MAX_NPZ_EXPANSION = 64
#: Arrays of an NPZ at most this large (bytes) are read whatever their expansion (a short recording's metadata).
NPZ_SMALL_BYTES = 64 << 20
#: Share of the memory available that one input may take when it is held (the chain's blocks need the rest).
MEMORY_SHARE = 0.5
#: Largest file read whole (a logger file, an IPOL ``_lb.txt``), bytes; a CSV larger than
#: :data:`gaitlog.host.files.inputs.STREAM_TEXT_BYTES` is parsed line by line and judged by its rows instead.
MAX_TEXT_BYTES = 320 << 20
#: Largest JSON file (calibration, K, trial metadata) read, bytes; a genuine one is a few kB.
MAX_JSON_BYTES = 4 << 20


def available_memory_bytes() -> int:
    """Memory this process may still take: the kernel's ``MemAvailable``, and the room left under an address-space
    limit (``RLIMIT_AS``) when one is set."""
    avail = 1 << 62
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            avail = next(int(ln.split()[1]) * 1024 for ln in fh if ln.startswith("MemAvailable:"))
    except (OSError, StopIteration, ValueError, IndexError):
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            pass
    try:
        with open("/proc/self/limits", encoding="ascii") as fh:      # an address-space limit (RLIMIT_AS), if set
            soft = next(ln.split()[3] for ln in fh if ln.startswith("Max address space"))
        if soft != "unlimited":
            with open("/proc/self/statm", encoding="ascii") as fh:
                used = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            avail = min(avail, max(int(soft) - used, 0))
    except (OSError, StopIteration, ValueError, IndexError):
        pass
    return avail


def check_memory(n_bytes: int, source: object, what: str) -> None:
    """Raise :class:`HostError` when holding ``n_bytes`` (``what``: "its arrays", "line 9: the table") would take
    more than :data:`MEMORY_SHARE` of the memory available."""
    avail = available_memory_bytes()
    if n_bytes > MEMORY_SHARE * avail:
        raise HostError(f"{source}: {what} would take {n_bytes / 2**20:,.0f} MB, more than "
                        f"{MEMORY_SHARE:.0%} of the {avail / 2**20:,.0f} MB of memory available; split the input")


def grid_limit(n_rows: int) -> int:
    """Most samples a regular time grid may spread ``n_rows`` read samples over: :data:`MAX_GRID_SAMPLES_PER_ROW`
    a row, and at least :data:`GRID_SAMPLES_ALWAYS_READ`.

    >>> grid_limit(4), grid_limit(1_000_000)
    (2097152, 100000000)
    """
    return max(MAX_GRID_SAMPLES_PER_ROW * max(n_rows, 1), GRID_SAMPLES_ALWAYS_READ)


def check_grid(n_grid: int, n_rows: int, source: object, what: str) -> None:
    """Raise :class:`HostError` when a regular grid of ``n_grid`` samples would spread ``n_rows`` read samples
    over more than :func:`grid_limit` samples (``what`` names the gap).

    >>> check_grid(200_000_001, 4, "gap.csv", "line 5: a time gap of 200000 s")
    Traceback (most recent call last):
    ...
    gaitlog.host.errors.HostError: gap.csv: line 5: a time gap of 200000 s: 4 rows on a grid of 200000001 samples, more than 100 a row or 2097152 in all; check the times
    """
    if n_grid > grid_limit(n_rows):
        raise HostError(f"{source}: {what + ': ' if what else ''}{n_rows} rows on a grid of {n_grid} samples, more "
                        f"than {MAX_GRID_SAMPLES_PER_ROW} a row or {GRID_SAMPLES_ALWAYS_READ} in all; check the times")


def check_file_size(path: str | os.PathLike[str], limit_bytes: int, what: str) -> None:
    """Raise :class:`HostError` when ``path`` is larger than ``limit_bytes`` (``what``: "a CSV", "a JSON file")."""
    try:
        size = Path(path).stat().st_size
    except OSError:
        return                                    # the reader names the problem
    if size > limit_bytes:
        raise HostError(f"{path}: {size} bytes, more than {what} may hold ({limit_bytes} bytes)")
