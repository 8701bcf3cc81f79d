"""How much the host reads from one input file: checked *before* allocating, so that a small hostile file (a CSV
with a 2 x 10^5 s time gap, a zip bomb inside an NPZ, a ``.npy`` header claiming terabytes) is a one-line
:class:`~gaitlog.host.errors.HostError` naming the file, not a crash or gigabytes of memory.

The bounds hold every genuine input with room to spare: the emulated logger stores at most
:data:`gaitlog.protocol.header.MAX_CAPACITY_SAMPLES` (2^20) samples; :data:`MAX_INPUT_SAMPLES` is 2^22 (23 h at 50 Hz,
11.6 h at 100 Hz), 100 MB per ``(n, 3)`` float64 array, so that reading stays well under 500 MB.
"""

from __future__ import annotations

import os
from pathlib import Path

from gaitlog.host.errors import HostError

__all__ = ["DEFAULT_MAX_MISSING_PERCENT", "MAX_INPUT_SAMPLES", "MAX_JSON_BYTES", "MAX_TEXT_BYTES", "check_file_size", "check_samples"]

#: Missing share of a recording (percent of its stored samples) above which ``decode``, ``estimate`` and ``batch``
#: exit 1 (``--max-missing``; :mod:`gaitlog.host.files.losses`).
DEFAULT_MAX_MISSING_PERCENT = 5.0
#: Most samples (rows of the regular grid, gaps included) one input may hold.
MAX_INPUT_SAMPLES = 1 << 22
#: Largest text input (CSV, IPOL ``_lb.txt``) read, bytes: 2^22 rows of a decoded CSV (about 70 bytes each) fit.
MAX_TEXT_BYTES = 320 << 20
#: Largest JSON file (calibration, K, trial metadata) read, bytes; a genuine one is a few kB.
MAX_JSON_BYTES = 4 << 20


def check_samples(n_samples: int, source: object, what: str = "") -> None:
    """Raise :class:`HostError` when an input would hold more than :data:`MAX_INPUT_SAMPLES` samples.

    >>> check_samples(200_000_001, "gap.csv", "line 5: a time gap of 200000 s")
    Traceback (most recent call last):
    ...
    gaitlog.host.errors.HostError: gap.csv: line 5: a time gap of 200000 s: the input would hold 200000001 samples, more than the 4194304 one input may hold; split it or check the times
    """
    if n_samples > MAX_INPUT_SAMPLES:
        raise HostError(f"{source}: {what + ': ' if what else ''}the input would hold {n_samples} samples, more than "
                        f"the {MAX_INPUT_SAMPLES} one input may hold; split it or check the times")


def check_file_size(path: str | os.PathLike[str], limit_bytes: int, what: str) -> None:
    """Raise :class:`HostError` when ``path`` is larger than ``limit_bytes`` (``what``: "a CSV", "a JSON file")."""
    try:
        size = Path(path).stat().st_size
    except OSError:
        return                                    # the reader names the problem
    if size > limit_bytes:
        raise HostError(f"{path}: {size} bytes, more than {what} may hold ({limit_bytes} bytes)")
