"""The paper's evaluation on the IPOL lower-back recordings, replayed through the emulated logger.

For every trial of an IPOL folder (:mod:`host.files.ipol`):

1. *Replay*: the recording is the physical input of the logger (:class:`firmware_sim.world.replay.Replay`),
   sampled by the emulated device (:class:`firmware_sim.device.Logger`) at ``sampling_rate_hz`` (50 Hz) with a
   ``adc_bits``-bit ADC (10), **with its on-line step algorithm on** (``StepConfig`` with the subject's leg and
   foot length, uncalibrated: the records hold the raw lengths), as a logger worn without K would record.
   The offline chain converts the codes back to g with the header's calibration (the nominal map). Replay
   interpolates the physical input over lost packets to keep it continuous; every logger sample whose
   instant falls on such an interpolated stretch (on a lost packet, or between two packets one of which was
   lost) is marked missing for the offline chain, so no offline estimate rests on an invented sample. The
   on-line algorithm sees every stored code, as on the device.
2. *Device = host*: the logger's stored step records are compared with the host's replay of the algorithm
   on the stored codes, flags and header (:func:`host.files.replay.check_records`), byte for byte; a trial
   whose records differ is an error (:class:`HostError` naming the trial and the first record).
3. *Steps*: the offline chain (:class:`host.gait.pipeline.StepPipeline`, the paper's PC processing) on
   the whole recording, and the on-line algorithm (:class:`firmware_sim.algorithms.online.
   OnlineStepAlgorithm`) on the same codes in floating point and in fixed point; a trial's steps are
   those whose heel-strike (or foot-flat) lies within ``TrialBoundaries`` shifted by ``+0.25 s`` at the
   start (the trial starts at the first toe-off; no heel strike can follow it sooner than a swing,
   > 0.25 s) and by ``+0.2 s`` at the end (less than half a step: the detection latency of the last, weak
   heel strike).
4. *U-turn* (``uturn="exclude"``, the default): the estimators assume straight walking and the paper's
   sections were timed between lap marks on straight corridor, so steps whose heel-strike lies within
   ``UTurnBoundaries`` do not contribute to the distance (they still count as steps). The reference
   distance stays 20 m (10 m out + 10 m back). ``uturn="include"`` sums every step instead.
   Both the per-subject calibration and the evaluation use the same rule, so K absorbs the part of the
   20 m walked during the turn; M3, which has no K, is the one the choice affects (see the README numbers).
5. *Calibration*: per subject, **one K** (M1/M2/M4 and the M5 line) is fitted on the first trial with
   the **offline** chain (20 m, one speed: M5 uses its walk-ratio fallback,
   :func:`host.gait.k_calibration.calibrate`); every arithmetic uses that K: ``apply_calibration``
   for the offline chain, the step configuration (``calibrated=True``) for the on-line algorithm, which
   applies it in its own arithmetic. M3 is never calibrated. Separately, and labelled so (``k_from =
   "own"``), the on-line algorithm is also run *as the device would be used*: with its own K, fitted on
   its own uncalibrated records of the calibration trial -- a different K, not a comparison.
6. *Robustness*: a trial that cannot be read is skipped, and so is a subject whose calibration trial has
   no usable step; every skip is returned (``IpolResult.skipped``, printed by the command), not warned.
7. *Rows*: every other trial gives one row per estimator and arithmetic (``offline``, ``online-float``,
   ``online-fixed``; ``k_from = "offline"``) and the own-K rows (``online-fixed``, ``k_from = "own"``):
   ``subject, trial, estimator, arithmetic, k_from, distance_m, ratio, steps, reference_steps`` (ratio =
   distance / 20 m; steps = detected steps in the trial; reference = heel strikes in the JSON within the
   trial boundaries). Per-step rows (:data:`STEP_COLUMNS`, every trial of a calibrated subject, the
   offline K) pair each on-line float step with its fixed-point and offline twins (:func:`host.studies.compare.
   match_steps`).

:func:`done_figures` computes the issue's figures from the rows (device = host, the arithmetic and
algorithm shares, the calibrated medians); :func:`format_done` prints them.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ, Adc
from firmware_sim.algorithms.online import OnlineSteps
from firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from firmware_sim.device import Logger
from firmware_sim.errors import DeviceError
from firmware_sim.world.replay import Replay
from host.errors import HostError
from host.files.ipol import height_m_of, list_trials, read_trial
from host.files.replay import check_records, online_step_table, run_starts
from host.gait.anthropometry import choose_lengths
from host.gait.k_calibration import KFit, calibrate
from host.gait.pipeline import StepPipeline, apply_calibration
from host.studies.compare import match_steps
from protocol.steps import StepConfig

#: Reference distance of an IPOL trial: 10 m out + 10 m back.
IPOL_DISTANCE_M = 20.0
#: A heel strike counts for the trial when it is >= start + SECTION_START_DELAY_S and <= end + SECTION_END_TOLERANCE_S.
SECTION_START_DELAY_S = 0.25
SECTION_END_TOLERANCE_S = 0.2
#: The chains evaluated: the offline float chain and the on-line algorithm in both arithmetics.
ARITHMETICS = ("offline", "online-float", "online-fixed")
#: Where a row's K comes from: ``offline`` (the comparison, one K for every arithmetic) or ``own`` (the
#: on-line algorithm's own K, fitted on its own records: a different K, not a comparison).
K_FROM = ("offline", "own")

CSV_COLUMNS = ("subject", "trial", "estimator", "arithmetic", "k_from", "distance_m", "ratio", "steps",
               "reference_steps")
STEP_COLUMNS = (("subject", "trial", "calibration_trial", "step", "foot_flat_s", "offline_step", "online_fixed_step",
                 "same_events_algorithm", "same_events_arithmetic")
                + tuple(f"{e.lower()}_{a.replace('-', '_')}_m" for e in ESTIMATORS for a in ARITHMETICS))


@dataclass(frozen=True, eq=False)
class ReplayedTrial:
    """A trial as the logger stored it.

    Attributes
    ----------
    subject, trial
        Identifiers.
    acc_g, valid
        ``(n, 3)`` g with the header's calibration (NaN where missing) and the validity mask of the offline
        chain (False on interpolated stretches of the physical input).
    sampling_rate_hz, t0_s
        Logger sample rate and the time of sample 0 on the recording's clock (packet index / 100 Hz).
    meta
        The trial JSON.
    source_rate_hz
        Rate of the recording (converts JSON packet indices to seconds).
    path
        The ``_lb.txt`` file.
    codes, adc_bits
        The ``(n, 3)`` ADC codes as stored (every sample: what the on-line algorithm saw) and the ADC width.
    flags, sample_numbers, header
        The stored sample flags, absolute sample numbers and the device header after the run (its step
        configuration, calibration, rate).
    device_records
        The step records the logger stored (:data:`protocol.steps.STEP_RECORD_DTYPE`, CRC-good).
    leg_length_m, foot_length_m
        The anatomy the logger's step configuration was given.
    """

    subject: int
    trial: int
    acc_g: np.ndarray
    valid: np.ndarray
    sampling_rate_hz: float
    t0_s: float
    meta: dict
    source_rate_hz: float
    path: Path
    codes: np.ndarray
    adc_bits: int
    flags: np.ndarray
    sample_numbers: np.ndarray
    header: Any
    device_records: np.ndarray
    leg_length_m: float
    foot_length_m: float

    def seconds(self, packet_index: float) -> float:
        """JSON packet index -> seconds on the logger clock."""
        return float(packet_index) / self.source_rate_hz

    @property
    def height_m(self) -> float | None:
        return height_m_of(self.meta)

    def reference_steps(self) -> int:
        lo, hi = self.meta["TrialBoundaries"]
        hs = [p[1] for p in list(self.meta.get("LeftFootEvents", [])) + list(self.meta.get("RightFootEvents", []))]
        return int(sum(lo <= h <= hi for h in hs))

    def run_starts(self) -> np.ndarray:
        """Rows where a logging run starts (SESSION_START; every sample of a replayed trial is present)."""
        return run_starts(np.ones(self.codes.shape[0], bool), self.flags)

    def check_records(self) -> Any:
        """The device's records against the host's replay (:func:`host.files.replay.check_records`)."""
        return check_records(self.codes, np.ones(self.codes.shape[0], bool), self.flags, self.sample_numbers,
                             self.header, self.device_records)

    def online_table(self, *, arithmetic: str, calibration: KFit | None = None) -> tuple[StepTable, Any]:
        """The on-line algorithm on the stored codes, the header's device calibration and rate, this trial's
        anatomy and ``calibration``'s K (:func:`host.files.replay.online_step_table`)."""
        return online_step_table(self.codes, sampling_rate_hz=self.header.sampling_rate_hz,
                                 leg_length_m=self.leg_length_m, foot_length_m=self.foot_length_m,
                                 calibration=calibration, adc_calibration=self.header.calibration,
                                 adc_bits=self.adc_bits, arithmetic=arithmetic, run_starts=self.run_starts(),
                                 t0_s=self.t0_s)

    def device_table(self) -> StepTable:
        """The logger's own records as a table (raw lengths: it ran uncalibrated)."""
        steps = OnlineSteps.from_records(self.device_records, first_sample_number=int(self.sample_numbers[0]),
                                         sampling_rate_hz=self.header.sampling_rate_hz)
        return StepTable.from_online(steps, t0_s=self.t0_s)



def replay_trial(lb_path: str | Path, *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10, leg_length_m: float | None = None,
                 foot_length_m: float | None = None) -> ReplayedTrial:
    """Replay one IPOL trial through the emulated logger with its on-line algorithm on (module notes).

    ``leg_length_m`` / ``foot_length_m`` configure the logger's step algorithm; missing ones come from the
    trial's height (:func:`host.gait.anthropometry.choose_lengths`).
    """
    lb_path = Path(lb_path)
    trial = read_trial(lb_path)         # the host's reader: the packet grid, lost packets missing, the JSON
    try:
        replay = Replay.from_samples(trial.acc_g, trial.valid, sampling_rate_hz=trial.sampling_rate_hz,
                                     source=str(lb_path))
    except DeviceError as err:
        raise HostError(str(err)) from err
    meta = trial.meta
    try:                                                  # no height: the default stature, as the paper's inputs
        lengths = choose_lengths(leg_length_m=leg_length_m, foot_length_m=foot_length_m,
                                 trial_height_m=height_m_of(meta))
    except HostError as err:
        raise HostError(f"{lb_path.with_name(lb_path.name.replace('_lb.txt', '.json'))}: {err}") from None
    leg, foot = lengths.leg_length_m, lengths.foot_length_m
    src_rate = replay.sampling_rate_hz
    filled = np.asarray(replay.truth.get("filled", np.zeros(replay.acc_g.shape[0], bool)), bool)
    logger = Logger(adc=Adc(adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz), sampling_rate_hz=sampling_rate_hz,
                    step_config=StepConfig(step_format=1, leg_length_m=leg, foot_length_m=foot))
    result = logger.record(replay)
    records, crc_ok = logger.steps.records_in_order()
    codes = np.asarray(result.codes, np.int64)
    times_s = np.asarray(result.sample_times_s, np.float64)
    header = logger.header
    acc = header.calibration.apply(codes.astype(np.float64))
    # a sample is missing when its instant lies between the last and the next received packet around a
    # filled (interpolated) stretch of the physical input
    x = (times_s - replay.t0_s) * src_rate                 # position on the packet grid
    j = np.clip(np.floor(x + 1e-6).astype(np.int64), 0, filled.size - 1)
    on_packet = np.abs(x - np.round(x)) < 1e-6
    j1 = np.clip(j + 1, 0, filled.size - 1)
    valid = ~(filled[j] | (filled[j1] & ~on_packet))
    acc[~valid] = np.nan
    rate = float(1.0 / np.median(np.diff(times_s)))
    return ReplayedTrial(trial.subject, trial.trial, acc, valid, rate, float(times_s[0]), meta, src_rate,
                         lb_path, codes, int(adc_bits), np.asarray(result.flags), np.asarray(result.sample_numbers,
                                                                                         np.int64),
                         header, records[crc_ok], float(leg), float(foot))


def trial_steps(rt: ReplayedTrial, table: StepTable, *, uturn: str = "exclude") -> tuple[StepTable, np.ndarray]:
    """Steps of the trial section and a mask of those that count for the distance (U-turn rule)."""
    lo, hi = rt.meta["TrialBoundaries"]
    t = table.event_time_s()
    inside = (t >= rt.seconds(lo) + SECTION_START_DELAY_S) & (t <= rt.seconds(hi) + SECTION_END_TOLERANCE_S)
    sec = table.select(inside)
    counts = np.ones(sec.n_steps, bool)
    ub = rt.meta.get("UTurnBoundaries")
    if uturn == "exclude" and ub:
        ts = sec.event_time_s()
        counts = ~((ts >= rt.seconds(ub[0])) & (ts <= rt.seconds(ub[1])))
    elif uturn not in ("exclude", "include"):
        raise ValueError(f"uturn must be 'exclude' or 'include', got {uturn!r}")
    return sec, counts


def section_distance(sec: StepTable, counts: np.ndarray, estimator: str, *, raw: bool = False) -> float:
    """Distance of the counted steps of a section (NaN steps filled as in :meth:`StepTable.distance_m`)."""
    src = sec.raw_m if raw else sec.length_m
    v, _ = sec.filled(src[estimator])
    return float(np.sum(v[counts]))


def _counted(sec: StepTable, counts: np.ndarray) -> StepTable:
    """The counted steps, with NaN lengths pre-filled from the whole section (calibration input)."""
    out = sec.select(np.ones(sec.n_steps, bool))
    out.raw_m = {k: sec.filled(v)[0] for k, v in sec.raw_m.items()}
    return out.select(counts)




@dataclass
class IpolResult:
    """Rows of the evaluation, the per-subject calibrations and the device checks.

    Attributes
    ----------
    rows
        One per scored trial, estimator, arithmetic and K source (:data:`CSV_COLUMNS`).
    calibrations
        The one K per subject, fitted on the offline chain's calibration trial (every arithmetic uses it).
    n_trials
        Scored trials (the calibration trials excluded).
    skipped
        What was skipped and why.
    calibrations_own
        The on-line algorithm's own K per subject (fitted on the logger's own records of the calibration
        trial): the device as it would be used, not a comparison.
    saturation
        Fixed-point saturation/wrap reports (none expected).
    replay_checks
        Per replayed trial: ``trial``, ``n_device``, ``n_compared``, ``n_identical`` (device records vs host
        replay, byte for byte).
    step_rows
        Per on-line float step of every trial of a calibrated subject: its fixed-point and offline twins'
        lengths with the offline K (:data:`STEP_COLUMNS`); empty unless all three arithmetics ran.
    arithmetics
        The arithmetics evaluated.
    """

    rows: list[dict]
    calibrations: dict[int, KFit]
    n_trials: int
    skipped: list[str] = field(default_factory=list)
    calibrations_own: dict[int, KFit] = field(default_factory=dict)
    saturation: list[str] = field(default_factory=list)
    replay_checks: list[dict] = field(default_factory=list)
    step_rows: list[dict] = field(default_factory=list)
    arithmetics: tuple[str, ...] = ARITHMETICS


def _calibrate_on(rt: ReplayedTrial, table: StepTable, *, uturn: str, leg: float, foot: float) -> KFit:
    sec, counts = trial_steps(rt, table, uturn=uturn)
    # one trial at one speed: the M5 walk-ratio fallback is expected (its note stays in the result)
    return calibrate([(_counted(sec, counts), IPOL_DISTANCE_M)], leg_length_m=leg, foot_length_m=foot,
                     subject=str(rt.subject))


def _step_rows(rt: ReplayedTrial, tables: dict[str, StepTable], calibration_trial: bool) -> list[dict]:
    """Each on-line float step with its online-fixed and offline twins (module notes, step 7)."""
    fl, fx, off = tables["online-float"], tables["online-fixed"], tables["offline"]
    ar, alg = match_steps(fx, fl), match_steps(fl, off)
    fixed_of, off_of = ar.a_of_b(fl.n_steps), alg.b_of_a(fl.n_steps)
    same_ar = np.zeros(fl.n_steps, bool)
    same_ar[ar.b] = ar.same_events
    same_alg = np.zeros(fl.n_steps, bool)
    same_alg[alg.a] = alg.same_events
    t = fl.time_s(fl.foot_flat)
    out = []
    for i in range(fl.n_steps):
        row: dict[str, Any] = dict(subject=rt.subject, trial=rt.trial, calibration_trial=int(calibration_trial),
                                   step=i, foot_flat_s=float(t[i]), offline_step=int(off_of[i]),
                                   online_fixed_step=int(fixed_of[i]), same_events_algorithm=int(same_alg[i]),
                                   same_events_arithmetic=int(same_ar[i]))
        for e in ESTIMATORS:
            k = e.lower()
            row[f"{k}_offline_m"] = float(off.length_m[e][off_of[i]]) if off_of[i] >= 0 else math.nan
            row[f"{k}_online_float_m"] = float(fl.length_m[e][i])
            row[f"{k}_online_fixed_m"] = float(fx.length_m[e][fixed_of[i]]) if fixed_of[i] >= 0 else math.nan
        out.append(row)
    return out


def evaluate_folder(
    folder: str | Path, *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10, uturn: str = "exclude",
    progress=None, arithmetic: tuple[str, ...] = ARITHMETICS,
) -> IpolResult:
    """Run the whole evaluation on an IPOL folder (see the module notes). Library code: no printing.

    ``progress`` (optional) is called with each trial name as it starts. ``arithmetic``: any of
    :data:`ARITHMETICS`; every one uses the offline chain's K of the subject's calibration trial. With
    ``online-fixed``, the own-K rows are added (``k_from = "own"``).

    Raises
    ------
    HostError
        A trial whose device records differ from the host's replay (naming the first record), or nothing
        to evaluate.
    """
    for a in arithmetic:
        if a not in ARITHMETICS:
            raise ValueError(f"arithmetic must be one of {ARITHMETICS}, got {a!r}")
    if uturn not in ("exclude", "include"):
        raise ValueError(f"uturn must be 'exclude' or 'include', got {uturn!r}")
    files = list_trials(folder)
    by_subject: dict[int, list[Path]] = {}
    for f in files:
        by_subject.setdefault(int(f.name.split("-")[0]), []).append(f)
    res = IpolResult([], {}, 0, arithmetics=tuple(arithmetic))
    for subject, paths in by_subject.items():
        if len(paths) < 2:
            res.skipped.append(f"subject {subject}: only one trial, nothing to evaluate after calibration")
            continue
        trials: list[tuple[ReplayedTrial, StepTable]] = []
        leg = foot = None
        for p in paths:
            if progress is not None:
                progress(p.name)
            try:   # the anatomy of the subject's first readable trial configures every later one
                rt = replay_trial(p, sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits, leg_length_m=leg, foot_length_m=foot)
            except HostError as err:   # one unreadable trial must not sink the whole evaluation
                res.skipped.append(f"{p.name}: {err}")
                continue
            leg, foot = rt.leg_length_m, rt.foot_length_m
            check = rt.check_records()
            res.replay_checks.append(dict(trial=p.name, n_device=check.n_device, n_compared=check.n_compared,
                                          n_identical=check.n_identical))
            if check.differs:
                raise HostError(check.error_message(p))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                off = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
                    rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s).steps_
            trials.append((rt, off))
        if len(trials) < 2:
            res.skipped.append(f"subject {subject}: fewer than two readable trials")
            continue
        rt0, off0 = trials[0]
        try:
            k = _calibrate_on(rt0, off0, uturn=uturn, leg=leg, foot=foot)
        except HostError as err:
            res.skipped.append(f"subject {subject}: calibration on {rt0.path.name} failed: {err}")
            continue
        res.calibrations[subject] = k
        own = None
        if "online-fixed" in arithmetic:
            try:
                own = _calibrate_on(rt0, rt0.device_table(), uturn=uturn, leg=leg, foot=foot)
                res.calibrations_own[subject] = own
            except HostError as err:
                res.skipped.append(f"subject {subject}: own-K calibration of the on-line algorithm failed: {err}")
        for i, (rt, off) in enumerate(trials):
            tables: dict[str, StepTable] = {}
            for a in arithmetic:
                if a == "offline":
                    tables[a] = off.select(np.ones(off.n_steps, bool))
                    tables[a].length_m = apply_calibration(off, k)
                else:
                    tables[a] = _online(rt, a, k, res.saturation)
            if set(tables) == set(ARITHMETICS):
                res.step_rows += _step_rows(rt, tables, i == 0)
            if i == 0:
                continue
            res.n_trials += 1
            runs = [(a, "offline", tables[a]) for a in arithmetic]
            if own is not None:
                runs.append(("online-fixed", "own", _online(rt, "fixed", own, res.saturation)))
            for a, k_from, table in runs:
                sec, counts = trial_steps(rt, table, uturn=uturn)
                for name in ESTIMATORS:
                    d = section_distance(sec, counts, name)
                    res.rows.append(dict(subject=rt.subject, trial=rt.trial, estimator=name, arithmetic=a,
                                         k_from=k_from, distance_m=d, ratio=d / IPOL_DISTANCE_M, steps=sec.n_steps,
                                         reference_steps=rt.reference_steps()))
    if not res.rows:
        raise HostError(f"{folder}: nothing to evaluate (" + "; ".join(res.skipped) + ")")
    return res


def _online(rt: ReplayedTrial, arithmetic: str, k: KFit, saturation: list[str]) -> StepTable:
    ar = arithmetic.removeprefix("online-")
    table, alg = rt.online_table(arithmetic=ar, calibration=k)
    if ar == "fixed" and alg.arithmetic_context().report():
        saturation.append(f"{rt.path.name}: {alg.arithmetic_context().report()}")
    return table


def summarise(rows: list[dict], *, arithmetic: str | None = None, k_from: str | None = "offline") -> list[dict]:
    """Per estimator: n, median, quartiles, IQR, min, max of the ratio; step-count median |error| %.

    ``arithmetic`` / ``k_from`` keep only the rows of that arithmetic / K source (None: every row).
    """
    if arithmetic is not None:
        rows = [r for r in rows if r.get("arithmetic", "offline") == arithmetic]
    if k_from is not None:
        rows = [r for r in rows if r.get("k_from", "offline") == k_from]
    out = []
    for name in ESTIMATORS:
        r = np.array([row["ratio"] for row in rows if row["estimator"] == name], float)
        st = [(row["steps"], row["reference_steps"]) for row in rows if row["estimator"] == name]
        err = np.array([abs(s - ref) / ref * 100 for s, ref in st if ref > 0], float)
        r = r[np.isfinite(r)]
        if r.size == 0:
            out.append(dict(estimator=name, n=0))
            continue
        q1, med, q3 = np.percentile(r, [25, 50, 75])
        out.append(dict(estimator=name, n=int(r.size), median=float(med), q1=float(q1), q3=float(q3),
                        iqr=float(q3 - q1), min=float(r.min()), max=float(r.max()),
                        step_error_median_pct=float(np.median(err)) if err.size else float("nan")))
    return out


def done_figures(result: IpolResult) -> dict[str, Any]:
    """The issue's figures from an evaluation with every arithmetic (see :func:`format_done`).

    Returns
    -------
    dict
        ``identity``: trials and records compared and identical (device vs host replay);
        ``arithmetic_step``: per estimator, over the matched steps with the same events of every trial,
        ``n``, ``median_abs_mm`` and ``max_abs_mm`` of online-fixed - online-float and ``max_rel`` (|d| /
        the float length); ``different_events``: matched steps whose events differ, of ``matched``;
        ``algorithm_ratio`` / ``arithmetic_ratio``: per estimator, the median and max over the scored trials of
        |ratio online-float - ratio offline| and |ratio online-fixed - ratio online-float|; ``median_ratio``:
        per arithmetic and estimator, the median ratio with the offline K; ``own``: the on-line fixed rows
        with their own K, per estimator (median, IQR).
    """
    chk = result.replay_checks
    out: dict[str, Any] = dict(identity=dict(
        trials=len(chk), identical_trials=sum(c["n_identical"] == c["n_compared"] > 0 for c in chk),
        records=sum(c["n_compared"] for c in chk), identical_records=sum(c["n_identical"] for c in chk)))
    st = result.step_rows
    same = np.array([r["same_events_arithmetic"] for r in st], bool)
    matched = np.array([r["online_fixed_step"] >= 0 for r in st], bool)
    out["matched"], out["different_events"] = int(matched.sum()), int((matched & ~same).sum())
    out["arithmetic_step"] = {}
    for e in ESTIMATORS:
        k = e.lower()
        x = np.array([r[f"{k}_online_fixed_m"] for r in st], float)
        y = np.array([r[f"{k}_online_float_m"] for r in st], float)
        g = same & np.isfinite(x) & np.isfinite(y)
        d = np.abs(x[g] - y[g])
        out["arithmetic_step"][e] = dict(n=int(d.size), median_abs_mm=1e3 * float(np.median(d)) if d.size else math.nan,
                                         max_abs_mm=1e3 * float(d.max()) if d.size else math.nan,
                                         max_rel=float(np.max(d / y[g])) if d.size else math.nan)
    by = {(r["subject"], r["trial"], r["estimator"], r["arithmetic"]): r["ratio"] for r in result.rows
          if r["k_from"] == "offline"}
    for key, (a, b) in (("algorithm_ratio", ("online-float", "offline")),
                        ("arithmetic_ratio", ("online-fixed", "online-float"))):
        out[key] = {}
        for e in ESTIMATORS:
            d = np.abs([by[t[:3] + (a,)] - by[t] for t in by if t[2] == e and t[3] == b and t[:3] + (a,) in by])
            d = d[np.isfinite(d)]
            out[key][e] = dict(n=int(d.size), median=float(np.median(d)) if d.size else math.nan,
                               max=float(d.max()) if d.size else math.nan)
    out["median_ratio"] = {a: {s["estimator"]: s.get("median", math.nan) for s in summarise(result.rows, arithmetic=a)}
                           for a in result.arithmetics}
    out["own"] = {s["estimator"]: dict(median=s.get("median", math.nan), iqr=s.get("iqr", math.nan))
                  for s in summarise(result.rows, arithmetic="online-fixed", k_from="own")}
    return out


def format_done(fig: dict[str, Any]) -> str:
    """Printed :func:`done_figures`."""
    idn = fig["identity"]
    lines = [f"device step records = host replay, byte for byte: {idn['identical_trials']} of {idn['trials']} "
             f"trials, {idn['identical_records']} of {idn['records']} records"]
    a = fig["arithmetic_step"]
    lines.append(f"on-line fixed vs on-line float per step (offline K; {fig['matched']} matched steps, "
                 f"{fig['different_events']} with different events left out): " + ", ".join(
                     f"{e} median |d| {a[e]['median_abs_mm']:.3f} mm max {100 * a[e]['max_rel']:.2f} %"
                     for e in ESTIMATORS))
    for key, what in (("arithmetic_ratio", "on-line fixed vs on-line float"),
                      ("algorithm_ratio", "on-line float vs offline")):
        r = fig[key]
        lines.append(f"{what}, distance ratio per trial, median (max) |d|: " + ", ".join(
            f"{e} {r[e]['median']:.4f} ({r[e]['max']:.4f})" for e in ESTIMATORS))
    mr = fig["median_ratio"]
    lines.append("median ratio with the offline chain's K: " + "; ".join(
        f"{a} " + " ".join(f"{e} {mr[a][e]:.3f}" for e in ESTIMATORS) for a in mr))
    if fig["own"] and any(math.isfinite(v["median"]) for v in fig["own"].values()):
        lines.append("as the device would be used -- on-line fixed with its OWN K (fitted on its own records of the "
                     "calibration trial; a different K, not a comparison): " + ", ".join(
                         f"{e} median {v['median']:.3f} IQR {v['iqr']:.3f}" for e, v in fig["own"].items()))
    return "\n".join(lines)
