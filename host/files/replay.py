"""Replay the logger's on-line step algorithm on dumped codes, and check the device's records bit for bit.

The firmware runs :class:`firmware_sim.algorithms.online.OnlineStepAlgorithm` (fixed point) on every
sample it stores and keeps one 20-byte record per foot-flat (PROTOCOL.md 2.3). The host has the same
samples and the same configuration (the header: sampling rate, ADC width, calibration slot, step
configuration), so it can run the same algorithm and must get the same records, byte for byte. A
difference means the device and the host do not run the same algorithm (a firmware bug, a wrong header, a
corrupted record that still passed its CRC) and is an error for whoever relies on the device's numbers.

What can be checked: each logging run starts afresh at a sample flagged SESSION_START (START). A run is
replayed from that sample, and only while its samples are all present: a run whose first sample was
overwritten (the ring wrapped) cannot be replayed, and after a missing sample (a damaged dump) the rest of
the run cannot. A record is verifiable when everything its computation read was replayed: its run's
samples up to ``max_step + r3 + 2`` after its foot-flat (the longest the algorithm waits before a foot-flat
is final), or up to the run's end when the run ends within the dump (STOP or a full memory: the pending
foot-flat is finalised there). The header keeps the step configuration of the last run; a run logged
before the configuration was changed replays with the new one and is reported as different.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from firmware_sim.firmware import step_algorithm_for
from protocol.packing import FLAG_SESSION_START
from protocol.steps import STEP_RECORD_DTYPE, pack_step_records

__all__ = ["RunCheck", "ReplayCheck", "run_starts", "replay_records", "check_records"]


@dataclass(frozen=True)
class RunCheck:
    """One logging run: its samples, how far it could be replayed, and what was compared."""

    first_sample: int
    last_sample: int
    replayed_to: int
    complete: bool
    reason: str
    n_compared: int
    n_identical: int


@dataclass(eq=False)
class ReplayCheck:
    """Device records against the host's replay.

    Attributes
    ----------
    replay
        The replayed records (:data:`protocol.steps.STEP_RECORD_DTYPE`, CRC set), every replayable run.
    runs
        One :class:`RunCheck` per logging run found in the samples.
    n_device
        Device records given (with a good CRC).
    n_compared, n_identical
        Verifiable records, and how many are identical byte for byte (a replayed record the device does
        not have, or the reverse, counts as compared and not identical).
    mismatches
        Up to ``max_mismatches`` ``(end_sample, what)`` descriptions.
    n_unverifiable
        Device records outside every verifiable span (their run's start or samples are missing).
    n_replay_unknown
        Replayed records inside a verifiable span that were not compared because the device's records there
        are unknown (stored, but dropped by the decoder: ``unknown_end_samples`` of :func:`check_records`).
    """

    replay: np.ndarray
    runs: list[RunCheck]
    n_device: int
    n_compared: int
    n_identical: int
    mismatches: list[tuple[int, str]] = field(default_factory=list)
    n_unverifiable: int = 0
    n_replay_unknown: int = 0

    @property
    def identical(self) -> bool:
        """Every verifiable record is identical (and at least one was compared)."""
        return self.n_compared > 0 and self.n_identical == self.n_compared

    @property
    def differs(self) -> bool:
        """At least one verifiable record differs (none compared: nothing differs)."""
        return self.n_identical < self.n_compared

    def error_message(self, source: object) -> str:
        """One line for a check that :attr:`differs`: the summary and the first differing record."""
        end, what = self.mismatches[0]
        return f"{source}: {self.summary()}; the first differing record ends at sample {end}: {what}"

    def summary(self) -> str:
        """One line."""
        if self.n_compared == 0:
            return (f"device step records: none verifiable ({self.n_device} stored, {self.n_unverifiable} outside "
                    f"the replayable runs)")
        verdict = "identical" if self.identical else f"{self.n_compared - self.n_identical} DIFFERENT"
        extra = f", {self.n_unverifiable} not verifiable" if self.n_unverifiable else ""
        if self.n_replay_unknown:
            extra += f", {self.n_replay_unknown} replayed where the device's records were dropped"
        return (f"device step records vs host replay: {self.n_identical} of {self.n_compared} {verdict} "
                f"byte for byte{extra}")


def run_starts(valid: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """Rows where a logging run starts: the present samples flagged SESSION_START (START)."""
    return np.flatnonzero(np.asarray(valid, bool) & ((np.asarray(flags) & FLAG_SESSION_START) != 0))


def _runs(valid: np.ndarray, flags: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` row ranges of the logging runs: from each SESSION_START row to the next (the rows
    before the first one belong to a run whose start is not in the dump)."""
    n = valid.size
    starts = run_starts(valid, flags)
    if n == 0:
        return []
    bounds = list(starts)
    if not bounds or bounds[0] != 0:
        bounds = [0] + bounds
    return [(int(a), int(b)) for a, b in zip(bounds, bounds[1:] + [n])]


def replay_records(codes: np.ndarray, valid: np.ndarray, flags: np.ndarray, sample_numbers: np.ndarray,
                   header: object) -> tuple[np.ndarray, list[tuple[int, int, int, bool, str]]]:
    """Run the device's algorithm over every replayable run.

    Returns
    -------
    records, spans
        The replayed records (CRC set) and, per run, ``(first_sample, last_sample, verifiable_to, complete,
        reason)``: records ending at or before ``verifiable_to`` (absolute sample number) are comparable;
        ``complete`` says the run ended inside the dump (its last record was finalised at the run's end).
    """
    c = np.asarray(codes, np.int64)
    ok = np.asarray(valid, bool)
    fl = np.asarray(flags)
    sn = np.asarray(sample_numbers, np.int64)
    parts, spans = [], []
    cfg = header.step_config
    for a, b in _runs(ok, fl):
        first, last = int(sn[a]), int(sn[b - 1])
        if not (fl[a] & FLAG_SESSION_START and ok[a]):
            spans.append((first, last, first - 1, False, "the run's first sample is not in the dump"))
            continue
        if not cfg.enabled:
            spans.append((first, last, first - 1, False, "the on-line step algorithm is off in the header"))
            continue
        missing = np.flatnonzero(~ok[a:b])
        stop = b if missing.size == 0 else a + int(missing[0])
        alg = step_algorithm_for(header)
        steps = alg.feed(c[a:stop])
        # the run ended inside the dump: another run follows it, or it is the last and the device stopped
        complete = stop == b and (b < c.shape[0] or not header.logging)
        if complete:
            steps = type(steps).concatenate([steps, alg.flush()])
            limit, reason = last, "replayed"
        else:
            lag = alg.config.counts.max_step + alg.config.counts.r3 + 2
            limit = int(sn[stop - 1]) - lag if stop > a else first - 1
            reason = "replayed up to a missing sample" if stop < b else "replayed (the run continues)"
        parts.append(steps.to_records(first))
        spans.append((first, last, limit, complete, reason))
    recs = np.concatenate(parts) if parts else np.zeros(0, STEP_RECORD_DTYPE)
    return _with_crc(recs), spans


def _with_crc(records: np.ndarray) -> np.ndarray:
    return np.frombuffer(pack_step_records(records), dtype=STEP_RECORD_DTYPE).copy() if records.size else records


def check_records(codes: np.ndarray, valid: np.ndarray, flags: np.ndarray, sample_numbers: np.ndarray,
                  header: object, device_records: np.ndarray, *, max_mismatches: int = 10,
                  unknown_end_samples: Sequence[tuple[float, float]] = ()) -> ReplayCheck:
    """Replay (:func:`replay_records`) and compare with ``device_records`` (CRC-good records, any order).

    Within each run's verifiable span, records are matched by ``end_sample``; the 20 bytes must be equal.
    Records older than the oldest device record are not compared (the step ring may have overwritten them).
    ``unknown_end_samples`` are open intervals ``(lo, hi)`` of ``end_sample`` where the device stored records
    that could not be read (a decoder dropped them): replayed records inside are not compared.
    """
    dev = np.sort(np.asarray(device_records, STEP_RECORD_DTYPE), order="end_sample")
    replay, spans = replay_records(codes, valid, flags, sample_numbers, header)
    oldest = int(dev["end_sample"][0]) if dev.size else None
    mismatches: list[tuple[int, str]] = []
    runs: list[RunCheck] = []
    n_cmp = n_same = n_hidden = 0
    covered = np.zeros(dev.size, bool)
    for first, last, limit, complete, reason in spans:
        dsel = (dev["end_sample"] >= first) & (dev["end_sample"] <= limit)
        rsel = (replay["end_sample"] >= first) & (replay["end_sample"] <= limit)
        if oldest is not None:
            rsel &= replay["end_sample"] >= oldest
        for lo, hi in unknown_end_samples:
            hidden = rsel & (replay["end_sample"] > lo) & (replay["end_sample"] < hi)
            n_hidden += int(np.count_nonzero(hidden))
            rsel &= ~hidden
        covered |= dsel
        d, r = dev[dsel], replay[rsel]
        ends = np.union1d(d["end_sample"], r["end_sample"])
        same = 0
        for e in ends:                      # one comparison per record: few thousand at most
            di = np.flatnonzero(d["end_sample"] == e)
            ri = np.flatnonzero(r["end_sample"] == e)
            if di.size == 1 and ri.size == 1 and d[di[0]].tobytes() == r[ri[0]].tobytes():
                same += 1
            elif len(mismatches) < max_mismatches:
                mismatches.append((int(e), _difference(d[di[0]] if di.size else None, r[ri[0]] if ri.size else None)))
        n_cmp += ends.size
        n_same += same
        runs.append(RunCheck(first, last, limit, complete, reason, int(ends.size), int(same)))
    return ReplayCheck(replay, runs, int(dev.size), n_cmp, n_same, mismatches, int(np.count_nonzero(~covered)),
                       n_hidden)


def _difference(device: np.void | None, replay: np.void | None) -> str:
    if device is None:
        return "a record the host's replay finds but the device did not store"
    if replay is None:
        return "a device record the host's replay does not find"
    fields = [n for n in STEP_RECORD_DTYPE.names if device[n] != replay[n]]
    return "; ".join(f"{n}: device {int(device[n])}, replay {int(replay[n])}" for n in fields)
