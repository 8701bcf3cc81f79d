"""The paper's evaluation on the IPOL lower-back recordings, replayed through the emulated logger.

For every trial of an IPOL folder (:mod:`host.ipol`):

1. *Replay*: the recording is the physical input of the logger (:class:`firmware_sim.world.replay.Replay`),
   sampled by the emulated device at ``rate_hz`` (50 Hz) with a ``bits``-bit ADC (10) and converted back to
   g with the nominal calibration of the header (:meth:`protocol.header.Calibration.nominal`). Replay
   interpolates the physical input over lost packets to keep it continuous; every logger sample whose
   instant falls on such an interpolated stretch (on a lost packet, or between two packets one of which was
   lost) is marked missing here, so no estimate rests on an invented sample.
2. *Steps*: :class:`host.gait.pipeline.StepPipeline` on the whole recording; the trial's steps are those
   whose heel-strike (or foot-flat) lies within ``TrialBoundaries`` shifted by ``+0.25 s`` at the start
   (the trial starts at the first toe-off; no heel strike can follow it sooner than a swing, > 0.25 s) and
   by ``+0.2 s`` at the end (less than half a step: the detection latency of the last, weak heel strike).
3. *U-turn* (``uturn="exclude"``, the default): the estimators assume straight walking and the paper's
   sections were timed between lap marks on straight corridor, so steps whose heel-strike lies within
   ``UTurnBoundaries`` do not contribute to the distance (they still count as steps). The reference
   distance stays 20 m (10 m out + 10 m back). ``uturn="include"`` sums every step instead.
   Both the per-subject calibration and the evaluation use the same rule, so K absorbs the part of the
   20 m walked during the turn; M3, which has no K, is the one the choice affects (see the README numbers).
4. *Calibration*: per subject, K of M1/M2/M4 and the M5 line are fitted on the first trial (20 m, one speed:
   M5 uses its walk-ratio fallback, :func:`host.estimators.calibration.calibrate`); M3 is never calibrated.
5. *Robustness*: a trial that cannot be read is skipped, and so is a subject whose calibration trial has
   no usable step; every skip is warned about and listed (``IpolResult.skipped``, printed by the command).
6. *Rows*: every other trial gives one row per estimator: ``subject, trial, estimator, arithmetic,
   distance_m, ratio, steps, reference_steps`` (ratio = distance / 20 m; steps = detected steps in the
   trial; reference = heel strikes in the JSON within the trial boundaries).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host.errors import HostError
from firmware_sim.algorithms.steps import ESTIMATORS
from host.estimators.anthropometry import anatomical_lengths
from host.estimators.calibration import KCalibration, calibrate
from firmware_sim.algorithms.steps import StepTable
from host.gait.pipeline import StepPipeline, apply_calibration
from host.ipol import list_trials

#: Reference distance of an IPOL trial: 10 m out + 10 m back.
IPOL_DISTANCE_M = 20.0
#: A heel strike counts for the trial when it is >= start + SECTION_START_DELAY_S and <= end + SECTION_END_TOLERANCE_S.
SECTION_START_DELAY_S = 0.25
SECTION_END_TOLERANCE_S = 0.2

CSV_COLUMNS = ("subject", "trial", "estimator", "arithmetic", "distance_m", "ratio", "steps", "reference_steps")


@dataclass(frozen=True, eq=False)
class ReplayedTrial:
    """A trial as the logger stored it, converted to g.

    Attributes
    ----------
    subject, trial
        Identifiers.
    acc_g, valid
        ``(n, 3)`` g (NaN where missing) and the validity mask.
    sampling_rate_hz, t0_s
        Logger sample rate and the time of sample 0 on the recording's clock (packet index / 100 Hz).
    meta
        The trial JSON.
    source_rate_hz
        Rate of the recording (converts JSON packet indices to seconds).
    path
        The ``_lb.txt`` file.
    emulated
        True when the samples went through the emulated logger (``firmware_sim.device.Logger``).
    codes, bits
        The ``(n, 3)`` ADC codes as stored (0 where missing) and the ADC width (input of the fixed-point chain).
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
    emulated: bool
    codes: np.ndarray | None = None
    bits: int = 10

    def seconds(self, packet_index: float) -> float:
        """JSON packet index -> seconds on the logger clock."""
        return float(packet_index) / self.source_rate_hz

    @property
    def height_m(self) -> float | None:
        h = self.meta.get("Height")
        try:
            h = float(h)
        except (TypeError, ValueError):
            return None
        return h / 100.0 if np.isfinite(h) and 80 <= h <= 250 else None

    def reference_steps(self) -> int:
        lo, hi = self.meta["TrialBoundaries"]
        hs = [p[1] for p in list(self.meta.get("LeftFootEvents", [])) + list(self.meta.get("RightFootEvents", []))]
        return int(sum(lo <= h <= hi for h in hs))


def replay_trial(lb_path: str | Path, *, rate_hz: float = 50.0, bits: int = 10, seed: int = 0) -> ReplayedTrial:
    """Replay one IPOL trial through the emulated logger (see the module notes).

    Uses ``firmware_sim.device.Logger`` when available; otherwise the same physical input is sampled by
    the sensor-free path (anti-aliased resampling to ``rate_hz`` and an ideal ``bits``-bit ±2 g
    quantiser), and ``emulated`` is False.
    """
    import re

    from firmware_sim.errors import DeviceError
    from firmware_sim.world.replay import Replay
    from protocol.header import Calibration

    lb_path = Path(lb_path)
    m = re.match(r"^(\d+)-(\d+)_lb\.txt$", lb_path.name)
    if not m:
        raise HostError(f"{lb_path}: expected a file name '<subject>-<trial>_lb.txt'")
    try:
        replay = Replay.from_file(lb_path, units="m/s^2")
    except DeviceError as err:
        raise HostError(str(err)) from err
    meta = replay.truth.get("ipol_meta")
    if not isinstance(meta, dict) or "TrialBoundaries" not in meta:
        raise HostError(f"{lb_path}: no trial JSON with 'TrialBoundaries' beside it")
    src_rate = replay.rate_hz
    filled = np.asarray(replay.truth.get("filled", np.zeros(replay.acc_g.shape[0], bool)), bool)
    emulated = False
    try:
        from firmware_sim.device import Logger  # noqa: F401  (the device helper's emulator)
        codes, times_s = _record_with_logger(replay, rate_hz=rate_hz, bits=bits, seed=seed)
        emulated = True
    except ImportError:
        codes, times_s = _record_ideal(replay, rate_hz=rate_hz, bits=bits)
    acc = Calibration.nominal(bits).apply(codes)
    # a sample is missing when its instant lies between the last and the next received packet around a
    # filled (interpolated) stretch of the physical input
    x = (times_s - replay.t0_s) * src_rate                 # position on the packet grid
    j = np.clip(np.floor(x + 1e-6).astype(np.int64), 0, filled.size - 1)
    on_packet = np.abs(x - np.round(x)) < 1e-6
    j1 = np.clip(j + 1, 0, filled.size - 1)
    valid = ~(filled[j] | (filled[j1] & ~on_packet))
    acc[~valid] = np.nan
    rate = rate_hz if not emulated else float(1.0 / np.median(np.diff(times_s)))
    codes_int = np.where(valid[:, None], np.asarray(codes), 0).astype(np.int64)
    return ReplayedTrial(int(m.group(1)), int(m.group(2)), acc, valid, float(rate), float(times_s[0]), meta,
                         src_rate, lb_path, emulated, codes_int, int(bits))


def _record_ideal(replay, *, rate_hz: float, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Sensor-free sampling: anti-aliased resampling and an ideal ±2 g quantiser (development fallback)."""
    motion = replay.render(rate_hz)
    span = 1 << bits
    codes = np.clip(np.floor(span / 2 + motion.acc_g * span / 4.0), 0, span - 1)
    return codes, motion.t_s


def _record_with_logger(replay, *, rate_hz: float, bits: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample the physical input with the emulated logger (nominal ADC, default sensor)."""
    from firmware_sim.device import Logger

    logger = _make_logger(Logger, rate_hz=rate_hz, bits=bits, seed=seed)
    result = logger.record(replay)
    codes = np.asarray(result.codes, np.float64)
    times = np.asarray(result.sample_times_s, np.float64)
    return codes, times


def _make_logger(Logger, *, rate_hz: float, bits: int, seed: int):  # noqa: N803
    from firmware_sim.adc import Adc

    return Logger(adc=Adc(bits=bits, rate_hz=rate_hz), sample_rate_hz=rate_hz)


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
    """Rows of the evaluation and the per-subject calibrations."""

    rows: list[dict]
    calibrations: dict[int, KCalibration]
    emulated: bool
    n_trials: int
    skipped: list[str] = field(default_factory=list)
    calibrations_fixed: dict[int, KCalibration] = field(default_factory=dict)
    saturation: list[str] = field(default_factory=list)


def _fixed_table(rt: ReplayedTrial, leg: float, foot: float, cal: KCalibration | None,
                 saturation: list[str]) -> StepTable:
    """The fixed-point chain (``firmware_sim.algorithms``) on the trial's codes, nominal device calibration."""
    from host.compare import fixed_step_table
    from protocol.header import Calibration

    if rt.codes is None:
        raise HostError(f"{rt.path}: no ADC codes kept, cannot run the fixed-point chain")
    table, chain = fixed_step_table(rt.codes, sampling_rate_hz=rt.sampling_rate_hz, leg_length_m=leg,
                                    foot_length_m=foot, calibration=cal, adc_calibration=Calibration.nominal(rt.bits),
                                    code_bits=rt.bits, valid=rt.valid, t0_s=rt.t0_s)
    if chain.ctx_.report():
        saturation.append(f"{rt.path.name}: {chain.ctx_.report()}")
    return table


def evaluate_folder(
    folder: str | Path, *, rate_hz: float = 50.0, bits: int = 10, uturn: str = "exclude",
    progress=None, arithmetic: tuple[str, ...] = ("float",),
) -> IpolResult:
    """Run the whole evaluation on an IPOL folder (see the module notes). Library code: no printing.

    ``progress`` (optional) is called with each trial name as it starts. ``arithmetic``: ``"float"`` (the
    host chain on the codes converted to g) and/or ``"fixed"`` (the firmware's fixed-point chain on the same
    codes, :func:`host.compare.fixed_step_table`); each fits its own K on the calibration trial, and the
    fixed rows' calibrated lengths are computed in fixed point. Saturation of the fixed chain is listed in
    ``IpolResult.saturation`` (and warned about).
    """
    for a in arithmetic:
        if a not in ("float", "fixed"):
            raise ValueError(f"arithmetic must be 'float' or 'fixed', got {a!r}")
    files = list_trials(folder)
    by_subject: dict[int, list[Path]] = {}
    for f in files:
        by_subject.setdefault(int(f.name.split("-")[0]), []).append(f)
    rows: list[dict] = []
    cals: dict[int, KCalibration] = {}
    cals_fixed: dict[int, KCalibration] = {}
    skipped: list[str] = []
    saturation: list[str] = []
    emulated_all = True
    n_trials = 0
    for subject, paths in by_subject.items():
        if len(paths) < 2:
            skipped.append(f"subject {subject}: only one trial, nothing to evaluate after calibration")
            continue
        trials: list[tuple[ReplayedTrial, dict[str, tuple[StepTable, np.ndarray]]]] = []
        leg = foot = float("nan")
        for p in paths:
            if progress is not None:
                progress(p.name)
            try:
                rt = replay_trial(p, rate_hz=rate_hz, bits=bits)
            except HostError as err:   # one unreadable trial must not sink the whole evaluation
                skipped.append(f"{p.name}: {err}")
                continue
            if not trials:             # anatomy from the subject's first readable trial
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)
                    leg, foot = anatomical_lengths(height_m=rt.height_m)
            secs: dict[str, tuple[StepTable, np.ndarray]] = {}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if "float" in arithmetic:
                    pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot).run(
                        rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s)
                    secs["float"] = trial_steps(rt, pipe.steps_, uturn=uturn)
                if "fixed" in arithmetic:
                    secs["fixed"] = trial_steps(rt, _fixed_table(rt, leg, foot, None, saturation), uturn=uturn)
            trials.append((rt, secs))
        if len(trials) < 2:
            skipped.append(f"subject {subject}: fewer than two readable trials")
            continue
        emulated_all &= all(rt.emulated for rt, _ in trials)
        rt0, secs0 = trials[0]
        fitted: dict[str, KCalibration] = {}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # the one-speed M5 fallback is expected here
                for a in arithmetic:
                    sec0, counts0 = secs0[a]
                    fitted[a] = calibrate([(_counted(sec0, counts0), IPOL_DISTANCE_M)], leg_length_m=leg,
                                          foot_length_m=foot, subject=str(subject))
        except HostError as err:
            skipped.append(f"subject {subject}: calibration on {rt0.path.name} failed: {err}")
            continue
        if "float" in fitted:
            cals[subject] = fitted["float"]
        if "fixed" in fitted:
            cals_fixed[subject] = fitted["fixed"]
        for rt, secs in trials[1:]:
            n_trials += 1
            for a in arithmetic:
                sec, counts = secs[a]
                if a == "float":
                    sec.length_m = apply_calibration(sec, fitted[a])
                else:                  # calibrated lengths in fixed point: the chain again, with K
                    sec, counts = trial_steps(rt, _fixed_table(rt, leg, foot, fitted[a], saturation), uturn=uturn)
                for name in ESTIMATORS:
                    d = section_distance(sec, counts, name)
                    rows.append(dict(subject=rt.subject, trial=rt.trial, estimator=name, arithmetic=a,
                                     distance_m=d, ratio=d / IPOL_DISTANCE_M, steps=sec.n_steps,
                                     reference_steps=rt.reference_steps()))
    for msg in skipped:
        warnings.warn(f"IPOL evaluation: skipped {msg}", stacklevel=2)
    for msg in saturation:
        warnings.warn(f"IPOL evaluation: fixed-point saturation in {msg}", stacklevel=2)
    if not rows:
        raise HostError(f"{folder}: nothing to evaluate (" + "; ".join(skipped) + ")")
    return IpolResult(rows, cals, emulated_all, n_trials, skipped, cals_fixed, saturation)


def summarise(rows: list[dict], *, arithmetic: str | None = None) -> list[dict]:
    """Per estimator: n, median, quartiles, IQR, min, max of the ratio; step-count median |error| %.

    ``arithmetic`` keeps only the rows of that arithmetic (default: every row).
    """
    if arithmetic is not None:
        rows = [r for r in rows if r.get("arithmetic", "float") == arithmetic]
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
