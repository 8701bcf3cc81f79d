"""The one timing helper of the benchmark scripts (imported as ``from _timing import best_of``)."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_of(fn: Callable[[], object], repeat: int = 7, *, warmup: bool = False) -> float:
    """Best wall time of ``fn()`` in seconds over ``repeat`` runs (after one untimed call if ``warmup``)."""
    if warmup:
        fn()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best
