"""Replay the logger's on-line step algorithm on dumped codes, and check the device's records bit for bit.

The firmware runs :class:`gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm` (fixed point) on every
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

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps, step_algorithm_for
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.host.errors import HostError
from gaitlog.host.files.recording import Recording
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.packing import FLAG_SESSION_START
from gaitlog.protocol.steps import (
    ALGORITHM_VERSIONS,
    ONLINE_ALGORITHM_VERSION,
    STEP_RECORD_DTYPE,
    StepConfig,
    StepFormat,
    pack_step_records,
)

__all__ = ["RunCheck", "ReplayCheck", "run_starts", "replay_records", "check_records", "verify_step_records",
           "step_config_for", "online_step_table"]


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
        The replayed records (:data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`, CRC set), every replayable run.
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
    algorithm_version
        The header's ``step_format``: the on-line algorithm version that wrote the records. Only
        :data:`gaitlog.protocol.steps.ONLINE_ALGORITHM_VERSION`'s are replayed; an older version's are not compared.
    """

    replay: np.ndarray
    runs: list[RunCheck]
    n_device: int
    n_compared: int
    n_identical: int
    mismatches: list[tuple[int, str]] = field(default_factory=list)
    n_unverifiable: int = 0
    n_replay_unknown: int = 0
    algorithm_version: int = int(ONLINE_ALGORITHM_VERSION)

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
        if self.algorithm_version not in (0, ONLINE_ALGORITHM_VERSION):
            return (f"device step records: {self.n_device} stored by "
                    f"{ALGORITHM_VERSIONS[StepFormat(self.algorithm_version)]}; "
                    f"this host replays version {int(ONLINE_ALGORITHM_VERSION)}, so they are not verified (their "
                    f"lengths are version {self.algorithm_version}'s)")
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
    Records of an older on-line algorithm version (the header's ``step_format``) are not compared at all.
    ``unknown_end_samples`` are open intervals ``(lo, hi)`` of ``end_sample`` where the device stored records
    that could not be read (a decoder dropped them): replayed records inside are not compared.
    """
    dev = np.sort(np.asarray(device_records, STEP_RECORD_DTYPE), order="end_sample")
    if header.step_config is not None and header.step_config.older_algorithm:   # not this host's replay
        version = int(header.step_config.step_format)
        return ReplayCheck(replay=np.zeros(0, STEP_RECORD_DTYPE), runs=[], n_device=int(dev.size), n_compared=0,
                           n_identical=0, n_unverifiable=int(dev.size), algorithm_version=version)
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
    return ReplayCheck(replay=replay, runs=runs, n_device=int(dev.size), n_compared=n_cmp, n_identical=n_same,
                       mismatches=mismatches, n_unverifiable=int(np.count_nonzero(~covered)),
                       n_replay_unknown=n_hidden)


def _difference(device: np.void | None, replay: np.void | None) -> str:
    if device is None:
        return "a record the host's replay finds but the device did not store"
    if replay is None:
        return "a device record the host's replay does not find"
    fields = [n for n in STEP_RECORD_DTYPE.names if device[n] != replay[n]]
    return "; ".join(f"{n}: device {int(device[n])}, replay {int(replay[n])}" for n in fields)


def verify_step_records(recording: Recording) -> ReplayCheck | None:
    """Check the recording's device step records against the host's replay of the device algorithm.

    The records the decoder dropped are unknown, so the replayed records that fall where they were (between
    the usable records around each loss, by ``end_sample``) are not compared (``ReplayCheck.n_replay_unknown``).

    Returns
    -------
    ReplayCheck or None
        None when there is nothing to check: no header, or the header's step algorithm off and no records.
    """
    header = recording.header
    if header is None or (not header.step_config.enabled and recording.n_step_records == 0):
        return None
    ends = recording.step_records["end_sample"].astype(np.int64)
    numbers = recording.step_record_numbers
    unknown = []
    for loss in recording.step_losses:
        k = int(np.searchsorted(numbers, loss.first_record_number))
        lo = float(ends[k - 1]) if k > 0 else -np.inf
        hi = float(ends[k]) if k < ends.size else np.inf
        unknown.append((lo, hi))
    return check_records(recording.codes, recording.valid, recording.flags, recording.sample_numbers, header,
                         recording.step_records, unknown_end_samples=unknown)


# ---------------------------------------------------------------------------------------------------------
# The on-line algorithm on a recording's codes, as a host StepTable


def step_config_for(*, leg_length_m: float, foot_length_m: float, k_fit: Any = None) -> Any:
    """The on-line algorithm's step configuration: the anatomy and, when given, the K of ``k_fit``.

    ``k_fit`` is a :class:`~gaitlog.host.gait.k_calibration.KFit` (K applied by the algorithm, in
    its arithmetic) or None (raw lengths, K = 1, records flagged UNCALIBRATED). Raises :class:`HostError`
    when a value does not fit the header's step configuration block (PROTOCOL.md 2.2).
    """
    kw: dict[str, Any] = dict(step_format=ONLINE_ALGORITHM_VERSION, leg_length_m=float(leg_length_m), foot_length_m=float(foot_length_m))
    if k_fit is not None:
        kw.update(k_fit.step_constants())
    cfg = StepConfig(**kw)
    try:
        cfg.raw
    except ProtocolError as err:
        raise HostError(f"the on-line algorithm's step configuration cannot hold these values: {err}") from err
    return cfg


#: Samples of a run fed to the on-line algorithm at a time (its ``feed`` is block-wise: the same records).
_FEED_SAMPLES = 1 << 16


def online_step_table(codes: np.ndarray, *, sampling_rate_hz: float, leg_length_m: float, foot_length_m: float,
                      k_fit: Any = None, adc_calibration: Any = None, adc_bits: int = 10,
                      arithmetic: str = "fixed", valid: np.ndarray | None = None,
                      run_starts: np.ndarray | None = None, t0_s: float = 0.0,
                      algorithm: Callable[..., OnlineStepAlgorithm] = OnlineStepAlgorithm,
                      ) -> tuple[StepTable, OnlineStepAlgorithm]:
    """The on-line algorithm on ``codes`` as a ``StepTable`` (:meth:`StepTable.from_online`).

    Parameters
    ----------
    codes
        ``(n, 3)`` ADC codes (``adc_bits`` bits).
    k_fit
        :class:`~gaitlog.host.gait.k_calibration.KFit` (the one K of the comparison) or None (raw).
    adc_calibration
        The device calibration (a :class:`gaitlog.protocol.header.CalibrationSlot`) or None for the nominal map.
    arithmetic
        ``"fixed"`` (the logger's) or ``"float"``.
    valid, run_starts
        The algorithm starts afresh (START) at index 0, at every index of ``run_starts`` (a logging run's
        SESSION_START sample) and after every missing sample (``valid`` false: the device had the sample,
        the dump lost it; a causal algorithm cannot be fed a hole), and ends (STOP) before each.
    algorithm
        The class (or a factory with its signature) that is run; tests wrap it to inject errors.

    Returns
    -------
    table, algorithm
        The table (lengths with K when ``k_fit`` is given, else the raw values in ``raw_m``) and the
        algorithm after the run (``saturations``, ``cycles``, ``arithmetic_context()``).
    """
    c = np.asarray(codes)
    n = c.shape[0]
    ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
    cfg = step_config_for(leg_length_m=leg_length_m, foot_length_m=foot_length_m, k_fit=k_fit)
    alg = algorithm(sampling_rate_hz=sampling_rate_hz, step_config=cfg, calibration=adc_calibration,
                    arithmetic=arithmetic, adc_bits=adc_bits)
    # stretches of present samples, cut at every run start: [a, b) with b the next cut or missing sample
    cut = np.zeros(n, bool)
    rs = np.asarray(run_starts if run_starts is not None else [], np.int64)
    cut[rs[(rs >= 0) & (rs < n)]] = True
    if n:
        cut[0] = True
    starts = np.flatnonzero(ok & (cut | ~np.r_[False, ok[:-1]])) if n else np.zeros(0, np.int64)
    bounds = np.flatnonzero(~ok | cut)
    stops = np.append(bounds, n)[np.searchsorted(bounds, starts, side="right")]
    parts = []
    for a, b in zip(starts.tolist(), stops.tolist()):
        alg.reset()
        for lo in range(a, b, _FEED_SAMPLES):       # a run in pieces: no (n, 3) int64 copy of a long recording
            parts.append(alg.feed(c[lo:min(b, lo + _FEED_SAMPLES)].astype(np.int64), offset=a))
        parts.append(alg.flush(offset=a))
    steps = (OnlineSteps.concatenate(parts) if parts else
             OnlineSteps.empty(arithmetic, alg.sampling_rate_hz, k_fit is not None))
    return StepTable.from_online(steps, t0_s=t0_s), alg
