"""The one rule for saying that samples are missing: :class:`SampleLosses` and its stderr line.

Whenever a recording read by a command has missing samples, the command prints one line on stderr (also with
``-q``): how many, what percentage, where (sample ranges, counted from 0 = the first stored sample, the row
order of the decoded CSV; the first :data:`RANGES_SHOWN` and how many more) and why (each reason with its
count). :func:`say_losses` emits it as a :class:`MissingSamplesWarning`, which ``gaitlog`` prints as one
``gaitlog CMD: warning: ...`` line. ``--max-missing PCT`` (default :data:`DEFAULT_MAX_MISSING_PERCENT`) makes
``decode``, ``estimate`` and ``batch`` exit 1 above it, with their outputs written and marked
(:meth:`SampleLosses.above`, :meth:`SampleLosses.limit_text`).

Examples
--------
>>> valid = np.ones(1000, bool); valid[64:128] = False; valid[900:] = False
>>> losses = SampleLosses.from_mask(valid, "cap.bin", "block damaged")
>>> print(losses.line())
cap.bin: 164 of 1,000 samples missing (16.4 %) at samples 64-127, 900-999: block damaged
>>> losses.above(5.0), SampleLosses.from_mask(np.ones(3, bool), "x").line()
(True, '')
"""

from __future__ import annotations

import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np

from gaitlog.host.storage.limits import DEFAULT_MAX_MISSING_PERCENT

__all__ = ["DEFAULT_MAX_MISSING_PERCENT", "RANGES_SHOWN", "MissingSamplesWarning", "SampleLosses", "say_losses"]

#: Sample ranges the line lists before "and N more".
RANGES_SHOWN = 4


class MissingSamplesWarning(UserWarning):
    """Samples of a recording are missing (the line of :meth:`SampleLosses.line`)."""


@dataclass(frozen=True)
class SampleLosses:
    """Which samples of a recording are missing, and why.

    Attributes
    ----------
    source
        The file, as named in messages.
    n_samples
        Samples of the recording (stored samples; the rows of the decoded CSV).
    ranges
        ``(first, last)`` inclusive sample indices (0 = first stored sample) of each run of missing samples.
    reasons
        ``(reason, n_samples)`` pairs, most samples first.
    """

    source: str
    n_samples: int
    ranges: tuple[tuple[int, int], ...]
    reasons: tuple[tuple[str, int], ...]

    @classmethod
    def from_mask(cls, valid: np.ndarray, source: str, reason: str = "missing",
                  reason_runs: list[tuple[int, int, str]] | None = None) -> SampleLosses:
        """From a validity mask; ``reason_runs`` (``(first, last, reason)`` inclusive indices) name the reason
        of each run, ``reason`` covers the missing samples they do not."""
        valid = np.asarray(valid, dtype=bool)
        missing = ~valid
        if not missing.any():
            return cls(source, int(valid.size), (), ())
        edge = np.zeros(1, np.int8)                           # int8 throughout: 1 byte a sample, not 8
        d = np.diff(np.concatenate((edge, missing.view(np.int8), edge)))
        starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
        counts: Counter[str] = Counter()
        covered = 0
        for first, last, why in reason_runs or []:
            n = int(missing[max(first, 0): last + 1].sum())
            if n:
                counts[why] += n
                covered += n
        if int(missing.sum()) > covered:
            counts[reason] += int(missing.sum()) - covered
        return cls(source, int(valid.size), tuple(zip(starts.tolist(), stops.tolist())),
                   tuple(counts.most_common()))

    @classmethod
    def from_recording(cls, recording, valid: np.ndarray | None = None, source: str | None = None) -> SampleLosses:
        """From a :class:`~gaitlog.host.files.recording.Recording` and its gaps' reasons (``valid`` may narrow its
        own mask, e.g. samples whose g is not finite)."""
        numbers = np.asarray(recording.sample_numbers)
        first = int(numbers[0]) if numbers.size else 0
        runs = [(g.first_sample_number - first, g.last_sample_number - first, g.reason) for g in recording.gaps]
        mask = recording.valid if valid is None else valid
        return cls.from_mask(mask, source or str(recording.source or "recording"), "not a finite acceleration",
                             runs)

    @property
    def n_missing(self) -> int:
        return int(sum(b - a + 1 for a, b in self.ranges))

    @property
    def percent(self) -> float:
        """Missing share in percent (100 for a recording of no sample)."""
        return 100.0 * self.n_missing / self.n_samples if self.n_samples else 0.0

    def above(self, max_percent: float) -> bool:
        """More than ``max_percent`` percent missing."""
        return self.percent > float(max_percent)

    def line(self) -> str:
        """The stderr line ('' when nothing is missing)."""
        if not self.ranges:
            return ""
        shown = ", ".join(f"{a:,}" if a == b else f"{a:,}-{b:,}" for a, b in self.ranges[:RANGES_SHOWN])
        more = len(self.ranges) - RANGES_SHOWN
        where = shown + (f" and {more:,} more range{'s' if more > 1 else ''}" if more > 0 else "")
        why = "; ".join(f"{n:,} {r}" if len(self.reasons) > 1 else r for r, n in self.reasons)
        return (f"{self.source}: {self.n_missing:,} of {self.n_samples:,} samples missing ({self.percent:.1f} %) "
                f"at samples {where}: {why}")

    def limit_text(self, max_percent: float) -> str:
        """The error of a recording above ``--max-missing``."""
        return (f"{self.source}: {self.percent:.1f} % of the samples missing, above --max-missing "
                f"{float(max_percent):g} %")


def say_losses(losses: SampleLosses, stacklevel: int = 3) -> None:
    """Warn with :meth:`SampleLosses.line` when samples are missing."""
    if losses.ranges:
        warnings.warn(losses.line(), MissingSamplesWarning, stacklevel=stacklevel)
