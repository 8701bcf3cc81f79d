"""The paper's evaluation on the IPOL lower-back recordings, replayed through the emulated logger.

For every trial of an IPOL folder (:mod:`gaitlog.host.files.ipol`):

1. *Replay*: the recording is the physical input of the logger (:class:`gaitlog.firmware_sim.world.replay.Replay`),
   sampled by the emulated device (:class:`gaitlog.firmware_sim.device.Logger`) at ``sampling_rate_hz`` (50 Hz) with a
   ``adc_bits``-bit ADC (10), **with its on-line step algorithm on** (``StepConfig`` with the subject's leg and
   foot length, uncalibrated: the records hold the raw lengths), as a logger worn without K would record.
   The offline chain converts the codes back to g with the header's calibration (the nominal map). Replay
   interpolates the physical input over lost packets to keep it continuous; every logger sample whose
   instant falls on such an interpolated stretch (on a lost packet, or between two packets one of which was
   lost) is marked missing for the offline chain, which then treats it as any missing sample
   (:mod:`gaitlog.host.gait.gaps`: runs up to 0.1 s interpolated on the logger's sample grid, longer ones end a
   walking bout; per trial, the missing fraction and the longest gap go to the events CSV). The on-line
   algorithm sees every stored code, as on the device.
2. *Device = host*: the logger's stored step records are compared with the host's replay of the algorithm
   on the stored codes, flags and header (:func:`gaitlog.host.files.replay.check_records`), byte for byte; a trial
   whose records differ is an error (:class:`HostError` naming the trial and the first record).
3. *Steps*: the offline chain (:class:`gaitlog.host.gait.pipeline.StepPipeline`, the paper's PC processing) on
   the whole recording, and the on-line algorithm (:class:`gaitlog.firmware_sim.algorithms.online.
   OnlineStepAlgorithm`) on the same codes in floating point and in fixed point; a trial's steps are
   those whose heel-strike (or foot-flat) lies within ``TrialBoundaries`` shifted by ``+0.25 s`` at the
   start (the trial starts at the first toe-off; no heel strike can follow it sooner than a swing,
   > 0.25 s) and by ``+0.2 s`` at the end (less than half a step: the detection latency of the last, weak
   heel strike).
4. *U-turn* (``uturn="include"``, the default): the score is what was walked: every step between the trial
   boundaries counts, the turn's included, against the distance walked (the IPOL protocol's 20 m, 10 m out +
   10 m back, the turn part of it; another with ``distance_m`` or a trial JSON's ``WalkedDistance_m``).
   ``uturn="exclude"`` leaves the steps whose heel strike lies within ``UTurnBoundaries`` out of the distance
   (they still count as steps). It was the default; it is not any more because the number of such steps
   differs from the calibration trial's by 1-2 in most trials and each moves a ratio by 2-2.6 %, and its dev
   gain (IQR 0.048 against 0.053) was far inside the noise (``docs/topics/accuracy.md``: the gain's interval).
   Both the per-subject calibration and the evaluation use the same rule, so K absorbs the turn either way;
   M3, which has no K, has fewer steps against the same distance when the turn's are left out
   (:mod:`gaitlog.host.studies.ipol_m3`: its pendulum term follows the turn's shorter steps, its foot length does not).
   The offline chain is scored with both rules (rows ``variant = "uturn-<other rule>"``), with the
   height unknown (``variant = "height-unknown"``: a 1.70 m adult's lengths for every subject, K refitted), and
   with the first trial's K alone (``variant = "no-prior"``: not shrunk, step 5b), and with M3's double
   support covered at the single support's speed (``variant = "m3-single-support-speed"``,
   :data:`M3_DOUBLE_SUPPORT_VARIANT`; the other estimators as the main rows).

   4b. *Tuned constants* (:mod:`gaitlog.host.studies.tuning`): the offline chain is run per trial for every candidate
   of the constants chosen from these recordings; for each subject the candidate is chosen on the other
   subjects' heel strikes against the foot sensors, and that subject's offline rows use it (cross-validated).
   The on-line chains run the shipped defaults (``cross_validated`` = 1 when the subject's fold chose them).
   M4's exponent (a ``"k-transfer"`` constant) is chosen per held-out subject on the other subjects' calibrated
   M4 ratios (K from their first trial, shrunk as in step 5b with the prior chosen on them for that exponent,
   their event constants those of the fold), and that subject's ``m4-per-fold`` rows use it (K fitted with it);
   it is not kept by the rule for choices (step 5c), so the main rows and the on-line chains compute the shipped
   exponent (:data:`gaitlog.firmware_sim.algorithms.parameters.M4_EXPONENT`, Weinberg's 1/4), K fitted with it.
5. *Calibration*: per subject, **one K** (M1/M2/M4 and the M5 line) is fitted on the first trial with
   the **offline** chain (20 m, one speed: M5 uses its walk-ratio fallback,
   :func:`gaitlog.host.gait.k_calibration.calibrate`); every arithmetic uses that K: ``apply_calibration``
   for the offline chain, the step configuration (``calibrated=True``) for the on-line algorithm, which
   applies it in its own arithmetic. M3 is never calibrated. Separately, and labelled so (``k_from =
   "own"``), the on-line algorithm is also run *as the device would be used*: with its own K, fitted on
   its own uncalibrated records of the calibration trial -- a different K, not a comparison.

   5b. *K prior* (:mod:`gaitlog.host.gait.k_prior`), only when :data:`K_PRIOR_IN_MAIN` (it is not: its gain's interval
   includes zero, step 5c; the k-prior rows shrink the main K alone): every K above is shrunk toward the median
   K of the *other* subjects
   (M4 per metre of leg), ``K = (d K_trial + d0 K_others) / (d + d0)`` with ``d`` the calibration trial's walked
   distance, ``d0`` per estimator chosen on the other subjects (:func:`choose_prior`, nested: each of them shrunk toward the rest);
   the variants (the other U-turn rule, the height unknown, the on-line chain's own K) toward the same
   variant of the other subjects with the fold's ``d0``. The prior learned on every subject is printed
   (:attr:`IpolResult.prior_all`; shipped as :data:`gaitlog.host.gait.k_prior.LOWER_BACK_PRIOR`), never used to score.

   5c. *Baseline and choices*: the recipe (:class:`gaitlog.host.gait.recipe.RecipeBaseline`) is scored the same way
   (rows ``variant = "baseline"``, :func:`baseline_rows`); every median and IQR of the tables carries a 95 %
   subject-bootstrap interval (:func:`subject_intervals`); each rule of :data:`CHOICES` is scored against its
   simpler choice (:func:`choice_gains`, :func:`count_gains`) and kept only when its gain's interval excludes
   zero. The on-line algorithm's own rules (:data:`ONLINE_CHOICES`) are scored the same way on the on-line fixed
   chain, re-run on the stored codes with the simpler choice (:data:`ONLINE_EVENT_VARIANTS`,
   :data:`ONLINE_M4_VARIANTS`; in-sample: those rules were chosen on these trials). M4's length rules without a
   constant (:data:`M4_STEP_RULES`, K fitted with each on the first trial) are rows ``variant = <rule>`` of the
   offline chain and of the on-line fixed chain's records, scored against Weinberg's length in IQR and in the median
   ``|log ratio|`` (:func:`log_error_gain`).
6. *Robustness*: a trial that cannot be read is skipped (:func:`gaitlog.host.files.ipol.read_trial` names the line
   or JSON field), and so is a subject whose calibration trial has no usable step; a trial with no foot-sensor heel
   strike between its boundaries is scored for distance but left out of the event and step-count criteria; files
   that look meant for the folder but are not read are listed (:func:`gaitlog.host.files.ipol.stray_files`); every
   skip is returned (``IpolResult.skipped``, printed by the command), not warned. K comes from each subject's first
   readable trial (``IpolResult.calibration_trials``).
7. *Rows*: every other trial gives one row per estimator and arithmetic (``offline``, ``online-float``,
   ``online-fixed``; ``k_from = "offline"``) and the own-K rows (``online-fixed``, ``k_from = "own"``):
   :data:`CSV_COLUMNS` (ratio = distance / the walked distance, ``walked_distance_m``; steps = detected steps in
   the trial; reference = heel strikes in the JSON within the trial boundaries; ``steps_outside_k_range``: counted steps outside the range K was
   calibrated on, :meth:`gaitlog.host.gait.k_calibration.KFit.outside_range`, empty for M3). Per-step rows (:data:`STEP_COLUMNS`, every trial of a calibrated subject, the
   offline K) pair each on-line float step with its fixed-point and offline twins (:func:`gaitlog.host.studies.compare.
   match_steps`).

:class:`IpolEvaluation` runs these steps as numbered stages (its notes), each returning a small dataclass;
:func:`evaluate_folder` is its result on a folder.

:func:`done_figures` computes the targets' figures from the rows (device = host, the arithmetic and
algorithm shares, the calibrated medians); :func:`format_done` prints them.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Self

import numpy as np

from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ, Adc
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps
from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT, EventParameters
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.world.replay import Replay
from gaitlog.host.errors import HostError
from gaitlog.host.files.ipol import (
    height_m_of,
    json_path_of,
    list_trials,
    read_trial,
    stray_files,
    trial_key,
    walked_distance_m_of,
)
from gaitlog.host.files.replay import check_records, online_step_table, run_starts
from gaitlog.host.gait.anthropometry import DEFAULT_HEIGHT_M, anatomical_lengths, choose_lengths
from gaitlog.host.gait.estimators.weinberg import duration_share_length_m, range_share_length_m, weinberg_length_m
from gaitlog.host.gait.gaps import MAX_INTERPOLATED_GAP_S, GapFiller
from gaitlog.host.gait.k_calibration import KFit, calibrate
from gaitlog.host.gait.k_prior import (
    PRIOR_DISTANCE_CANDIDATES_M,
    PRIOR_ESTIMATORS,
    KPrior,
    population_prior,
)
from gaitlog.host.gait.pipeline import StepPipeline, apply_calibration
from gaitlog.host.gait.recipe import RecipeBaseline
from gaitlog.host.studies.compare import match_steps, with_m4_exponent
from gaitlog.host.studies.stats import BOOTSTRAP_LEVEL, BOOTSTRAP_RESAMPLES, subject_bootstrap, subject_resamples
from gaitlog.host.studies.tuning import (
    COUNT_CRITERION,
    CRITERION,
    K_CRITERION,
    K_PRIOR_CRITERION,
    MATCH_TOLERANCE_S,
    SIMPLER_COUNT_CHOICE,
    TIMING_TOLERANCE_S,
    TUNED_PARAMETERS,
    EventScore,
    LosoChoice,
    candidates,
    choose_loso,
    detector_for,
    least_error,
    least_spread,
    score_events,
)
from gaitlog.protocol.steps import StepConfig

#: Reference distance of an IPOL trial: 10 m out + 10 m back (the default of :class:`IpolEvaluation`'s
#: ``distance_m``; a trial JSON's ``WalkedDistance_m`` overrides it for that trial).
IPOL_DISTANCE_M = 20.0
#: A heel strike counts for the trial when it is >= start + SECTION_START_DELAY_S and <= end + SECTION_END_TOLERANCE_S.
SECTION_START_DELAY_S = 0.25
SECTION_END_TOLERANCE_S = 0.2
#: The chains evaluated: the offline float chain and the on-line algorithm in both arithmetics.
ARITHMETICS = ("offline", "online-float", "online-fixed")
#: Where a row's K comes from: ``offline`` (the comparison, one K for every arithmetic) or ``own`` (the
#: on-line algorithm's own K, fitted on its own records: a different K, not a comparison).
K_FROM = ("offline", "own")

#: Weinberg's exponent, M4's simpler choice (the shipped one; the on-line rows ``variant = "m4-quarter"``).
WEINBERG_EXPONENT = 0.25

#: Whether the main rows use K shrunk toward the other subjects' K (the K prior, step 5b). False: its
#: cross-validated gain in IQR over the first trial's K alone has a 95 % subject-bootstrap interval that includes
#: zero for M1, M2 and M4 (``docs/topics/accuracy.md``), so the paper's K stays and the prior is a second row
#: (``variant = "k-prior"``; with True, the rows of the first trial's K alone are ``variant = "no-prior"``).
K_PRIOR_IN_MAIN = False

#: M3's double support of the ``m3-<rule>`` rows (:data:`gaitlog.host.gait.estimators.two_phase.DOUBLE_SUPPORT_RULES`):
#: covered at the single support's mean speed, no constant; not kept, its gain's interval includes zero
#: (:mod:`gaitlog.host.studies.ipol_m3`), so the main rows keep Alvarez's foot length.
M3_DOUBLE_SUPPORT_VARIANT = "single-support-speed"

#: The two U-turn rules (module notes, step 4); both are reported.
UTURN_RULES = ("exclude", "include")

#: The on-line algorithm's own rules against their simpler choices (rows ``arithmetic = "online-fixed"``, K the
#: offline chain's, as the main rows): variant -> the
#: :class:`~gaitlog.firmware_sim.algorithms.parameters.EventParameters` fields it changes from the defaults, the
#: on-line algorithm re-run in fixed point on the stored codes with them. ``stop-v3``: the stop rule of on-line algorithm versions 1-3 (0.2 m/s^2; version 4 has none);
#: ``prominence-fixed``: the fixed foot-flat prominence of versions 1-2 (the cap, 0.5 m/s^2, floor = cap).
ONLINE_EVENT_VARIANTS: dict[str, dict[str, float]] = {
    "stop-v3": dict(stop_prominence_m_s2=0.2),
    "prominence-fixed": dict(min_prominence_m_s2=EventParameters().max_prominence_m_s2),
}
#: The on-line chain's M4 with each exponent (variant -> exponent): ``K range^p`` of the on-line fixed-point
#: records' ranges (host float; the arithmetic's share is ~1e-4), K fitted with ``p`` on the offline chain.
ONLINE_M4_VARIANTS: dict[str, float] = {"m4-quarter": WEINBERG_EXPONENT, "m4-half": 0.5}
#: M4 length rules without a constant, scored as extra rows on the offline chain and, on the host, on the on-line
#: fixed chain's records (variant = the rule; K fitted with it on the first trial's offline chain;
#: :func:`with_m4_rule`): ``m4-range-share``, a step whose range is below the trial's
#: median counts the share of a typical step its range is
#: (:func:`~gaitlog.host.gait.estimators.weinberg.range_share_length_m`); ``m4-duration-share``, each step's
#: Weinberg length times its duration's share of the trial's median, at most 1
#: (:func:`~gaitlog.host.gait.estimators.weinberg.duration_share_length_m`). Neither is kept by the rule for choices
#: (``docs/topics/accuracy.md``): the main rows use Weinberg's length.
M4_STEP_RULES = ("m4-range-share", "m4-duration-share")

CSV_COLUMNS = ("subject", "trial", "estimator", "arithmetic", "k_from", "uturn", "lengths_source", "variant",
               "walked_distance_m", "distance_m", "ratio", "steps", "reference_steps", "steps_outside_k_range",
               "cross_validated")
#: Per trial and chain (offline, online-fixed): steps in the trial, steps with each event found, M3's filled
#: steps (no toe-off or heel strike: the bout median), the events against the foot sensors, and the logger
#: samples missing between the trial boundaries (fraction, longest run, samples the offline chain interpolated:
#: :mod:`gaitlog.host.gait.gaps`).
EVENT_COLUMNS = ("subject", "trial", "calibration_trial", "chain", "steps", "heel_strike_found", "toe_off_found",
                 "m3_filled", "hs_reference", "hs_detected", "hs_matched", "to_reference", "to_detected", "to_matched",
                 "steps_outside", "hs_reference_outside", "missing_fraction", "longest_gap_s", "gap_samples_filled")
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
        The step records the logger stored (:data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`, CRC-good).
    leg_length_m, foot_length_m
        The anatomy the logger's step configuration was given.
    distance_m
        The distance walked between ``TrialBoundaries``, m: the JSON's ``WalkedDistance_m`` when it has one,
        else the evaluation's (:data:`IPOL_DISTANCE_M` by default). K is fitted on it and ratios are over it.
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
    distance_m: float = IPOL_DISTANCE_M

    def seconds(self, packet_index: float) -> float:
        """JSON packet index -> seconds on the logger clock."""
        return float(packet_index) / self.source_rate_hz

    @property
    def height_m(self) -> float | None:
        return height_m_of(self.meta)

    def reference_event_times_s(self) -> tuple[np.ndarray, np.ndarray]:
        """Foot-sensor toe-offs and heel strikes (both feet, sorted) inside ``TrialBoundaries``, s."""
        lo, hi = self.meta["TrialBoundaries"]
        arr = self._foot_events()
        out = []
        for col in (0, 1):
            x = np.sort(arr[:, col])
            out.append(x[(x >= lo) & (x <= hi)] / self.source_rate_hz)
        return out[0], out[1]

    def reference_steps(self) -> int:
        lo, hi = self.meta["TrialBoundaries"]
        hs = self._foot_events()[:, 1]
        return int(np.count_nonzero((hs >= lo) & (hs <= hi)))

    def reference_steps_outside(self) -> int:
        """Foot-sensor heel strikes of the recording outside ``TrialBoundaries`` (standing, shuffling and
        turning before and after the trial: not scored)."""
        return self._foot_events().shape[0] - self.reference_steps()

    def _foot_events(self) -> np.ndarray:
        """``(n, 2)`` foot-sensor (toe-off, heel strike) pairs of both feet, JSON packet indices."""
        pairs = list(self.meta.get("LeftFootEvents") or []) + list(self.meta.get("RightFootEvents") or [])
        return np.asarray(pairs, np.float64).reshape(-1, 2)

    def gaps(self) -> GapFiller:
        """The missing samples between the trial boundaries, as the offline chain treats them
        (:class:`gaitlog.host.gait.gaps.GapFiller`: fraction, longest gap, samples interpolated)."""
        lo, hi = (int(round((self.seconds(b) - self.t0_s) * self.sampling_rate_hz))
                  for b in self.meta["TrialBoundaries"])
        lo, hi = max(lo, 0), min(hi + 1, self.valid.size)
        return GapFiller().fill(self.acc_g[lo:hi], self.valid[lo:hi], sampling_rate_hz=self.sampling_rate_hz)

    def run_starts(self) -> np.ndarray:
        """Rows where a logging run starts (SESSION_START; every sample of a replayed trial is present)."""
        return run_starts(np.ones(self.codes.shape[0], bool), self.flags)

    def check_records(self) -> Any:
        """The device's records against the host's replay (:func:`gaitlog.host.files.replay.check_records`)."""
        return check_records(self.codes, np.ones(self.codes.shape[0], bool), self.flags, self.sample_numbers,
                             self.header, self.device_records)

    def online_table(self, *, arithmetic: str, k_fit: KFit | None = None,
                     events: EventParameters | None = None) -> tuple[StepTable, Any]:
        """The on-line algorithm on the stored codes, the header's device calibration and rate, this trial's
        anatomy and ``k_fit``'s K (:func:`gaitlog.host.files.replay.online_step_table`); ``events``: other
        rules than the defaults (a study's variant, not what the logger ran)."""
        algorithm = (OnlineStepAlgorithm if events is None else functools.partial(OnlineStepAlgorithm, events=events))
        return online_step_table(self.codes, sampling_rate_hz=self.header.sampling_rate_hz,
                                 leg_length_m=self.leg_length_m, foot_length_m=self.foot_length_m,
                                 k_fit=k_fit, adc_calibration=self.header.calibration,
                                 adc_bits=self.adc_bits, arithmetic=arithmetic, run_starts=self.run_starts(),
                                 t0_s=self.t0_s, algorithm=algorithm)

    def device_table(self) -> StepTable:
        """The logger's own records as a table (raw lengths: it ran uncalibrated)."""
        steps = OnlineSteps.from_records(self.device_records, first_sample_number=int(self.sample_numbers[0]),
                                         sampling_rate_hz=self.header.sampling_rate_hz)
        return StepTable.from_online(steps, t0_s=self.t0_s)



def replay_trial(lb_path: str | Path, *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10, leg_length_m: float | None = None,
                 foot_length_m: float | None = None, distance_m: float = IPOL_DISTANCE_M) -> ReplayedTrial:
    """Replay one IPOL trial through the emulated logger with its on-line algorithm on (module notes).

    ``leg_length_m`` / ``foot_length_m`` configure the logger's step algorithm; missing ones come from the
    trial's height (:func:`gaitlog.host.gait.anthropometry.choose_lengths`). ``distance_m``: the distance walked
    between the trial boundaries unless the JSON gives its own ``WalkedDistance_m``
    (:func:`gaitlog.host.files.ipol.walked_distance_m_of`).
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
    except HostError as err:                              # the JSON's Height is in cm, not the metres of --height
        raise HostError(f"{json_path_of(lb_path)}: {str(err).replace(' (give it in metres)', '')} (its 'Height' is "
                        "read in cm)") from None
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
                         header, records[crc_ok], float(leg), float(foot),
                         float(walked_distance_m_of(meta) or distance_m))


def section_mask(rt: ReplayedTrial, table: StepTable) -> np.ndarray:
    """Which rows of ``table`` are the trial section's (heel strike, or foot-flat, within the shifted boundaries)."""
    lo, hi = rt.meta["TrialBoundaries"]
    t = table.event_time_s()
    return (t >= rt.seconds(lo) + SECTION_START_DELAY_S) & (t <= rt.seconds(hi) + SECTION_END_TOLERANCE_S)


def trial_steps(rt: ReplayedTrial, table: StepTable, *, uturn: str = "include") -> tuple[StepTable, np.ndarray]:
    """Steps of the trial section and a mask of those that count for the distance (U-turn rule)."""
    sec = table.select(section_mask(rt, table))
    counts = np.ones(sec.n_steps, bool)
    ub = rt.meta.get("UTurnBoundaries")
    if uturn == "exclude" and ub:
        ts = sec.event_time_s()
        counts = ~((ts >= rt.seconds(ub[0])) & (ts <= rt.seconds(ub[1])))
    elif uturn not in UTURN_RULES:
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
    uturn
        The U-turn rule of the main rows (``variant = "main"``); the offline chain is also scored with the
        other (``variant = "uturn-<rule>"``).
    candidates, event_scores, loso
        The grid of the tuned constants (:func:`gaitlog.host.studies.tuning.candidates`, the defaults first), per
        ``(subject, trial)`` and candidate the offline chain's (heel-strike, toe-off) scores against the
        foot sensors, and the leave-one-subject-out choice per subject.
    count_errors
        Per ``(subject, trial)`` and candidate, the offline chain's detected - reference steps in the trial
        section (U-turn steps included): the step-counting constants' criterion.
    trial_events
        :data:`EVENT_COLUMNS` rows (every trial of a calibrated subject, offline and on-line fixed).
    m4_exponent
        Per held-out subject, M4's exponent chosen on the other subjects (:data:`gaitlog.host.studies.tuning.
        K_CRITERION`).
    calibrations_online
        The K the on-line chains use per subject: ``calibrations``' own unless the subject's fold chose another
        M4 exponent than the logger's, then K refitted on the same trial with the logger's.
    priors
        Per held-out subject, the K prior learned on the other subjects (:func:`choose_prior`; ``"main"``: with
        the fold's M4 exponent, ``"online"``: with the logger's).
    prior_all
        The prior learned on every subject with the shipped constants (what
        :data:`gaitlog.host.gait.k_prior.LOWER_BACK_PRIOR` ships; never used to score).
    calibration_trials
        Per calibrated subject, the trial its K was fitted on: its first readable trial in file order (trial 1
        unless that is absent or unreadable).
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
    uturn: str = "include"
    candidates: list[dict[str, Any]] = field(default_factory=list)
    event_scores: dict[tuple[int, int], list[tuple[EventScore, EventScore]]] = field(default_factory=dict)
    loso: LosoChoice = field(default_factory=lambda: LosoChoice({}, {}))
    trial_events: list[dict] = field(default_factory=list)
    m4_exponent: dict[int, float] = field(default_factory=dict)
    calibrations_online: dict[int, KFit] = field(default_factory=dict)
    count_errors: dict[tuple[int, int], list[int]] = field(default_factory=dict)
    priors: dict[int, dict[str, KPrior]] = field(default_factory=dict)
    prior_all: KPrior | None = None
    calibration_trials: dict[int, int] = field(default_factory=dict)


def _with_m4_lengths(table: StepTable, k: KFit) -> StepTable:
    """A copy of ``table`` whose calibrated M4 lengths are ``k``'s ``K range^p`` (p its exponent) of each step's
    range."""
    out = table.select(np.ones(table.n_steps, bool))
    out.length_m = {**table.length_m, "M4": weinberg_length_m(table.acc_range_m_s2, k=k.k_m4, exponent=k.m4_exponent)}
    return out


def _with_m4_rule_lengths(rt: ReplayedTrial, table: StepTable, rule: str, k: KFit) -> StepTable:
    """A copy of ``table`` whose calibrated M4 lengths are ``rule``'s (:func:`with_m4_rule`, from each step's range
    and duration) with ``k``'s K; the other lengths as they are (the on-line chain's own arithmetic)."""
    out = table.select(np.ones(table.n_steps, bool))
    out.length_m = {**table.length_m, "M4": k.k_m4 * with_m4_rule(rt, table, rule).raw_m["M4"]}
    return out


def with_m4_rule(rt: ReplayedTrial, table: StepTable, rule: str) -> StepTable:
    """``table`` with its raw M4 lengths from one of :data:`M4_STEP_RULES`, the typical step (median range or
    duration) that of the steps of ``rt``'s trial section; ``table`` itself when the section has none."""
    inside = section_mask(rt, table)
    if rule == "m4-range-share":
        r = table.acc_range_m_s2[inside]
        if not np.isfinite(r).any():
            return table
        raw = range_share_length_m(table.acc_range_m_s2, float(np.nanmedian(r)), k=1.0)
    elif rule == "m4-duration-share":
        t = table.duration_s[inside]
        if not np.isfinite(t).any():
            return table
        raw = duration_share_length_m(table.acc_range_m_s2, table.duration_s, float(np.nanmedian(t)), k=1.0)
    else:
        raise ValueError(f"rule must be one of {M4_STEP_RULES}, got {rule!r}")
    out = table.select(np.ones(table.n_steps, bool))
    out.raw_m = {**table.raw_m, "M4": raw}
    return out


def _calibrate_on(rt: ReplayedTrial, table: StepTable, *, uturn: str, leg: float, foot: float,
                  m4_exponent: float = M4_EXPONENT) -> KFit:
    sec, counts = trial_steps(rt, with_m4_exponent(table, m4_exponent), uturn=uturn)
    # one trial at one speed: the M5 walk-ratio fallback is expected (its note stays in the result)
    return calibrate([(_counted(sec, counts), rt.distance_m)], leg_length_m=leg, foot_length_m=foot,
                     subject=str(rt.subject), m4_exponent=m4_exponent)


#: One subject's first-trial K and its other trials' ratios with it (:func:`choose_prior`'s input).
KTransfer = tuple[KFit, dict[str, list[float]]]


def _calibrated(table: StepTable, k: KFit) -> StepTable:
    """A copy of ``table`` with its lengths calibrated with ``k``
    (:func:`gaitlog.host.gait.pipeline.apply_calibration`)."""
    out = table.select(np.ones(table.n_steps, bool))
    out.length_m = apply_calibration(table, k)
    return out


def _transfer(subject: ReplayedSubject, candidate: int, exponent: float, *, uturn: str) -> KTransfer | None:
    """A subject's K fitted on its first trial (the offline chain of one event candidate, M4 computed with
    ``exponent``) and the distance ratios of M1, M2 and M4 on its other trials with that K (the input of
    the ``"k-transfer"`` criterion); None when the calibration fails."""
    offs = subject.offline(candidate)
    try:
        k = _calibrate_on(subject.trials[0], offs[0], uturn=uturn, leg=subject.leg_length_m,
                          foot=subject.foot_length_m, m4_exponent=exponent)
    except HostError:
        return None
    out: dict[str, list[float]] = {e: [] for e in PRIOR_ESTIMATORS}
    for rt, off in zip(subject.trials[1:], offs[1:], strict=True):
        sec, counts = trial_steps(rt, _calibrated(off, k), uturn=uturn)
        for e in PRIOR_ESTIMATORS:
            out[e].append(section_distance(sec, counts, e) / rt.distance_m)
    return k, out


def _shrunk_ratios(fit: KFit, ratios: list[float], estimator: str, prior: KPrior) -> list[float]:
    """``ratios`` (scored with ``fit``'s K) with ``estimator``'s K shrunk toward ``prior`` (distances are linear
    in K: each ratio scales by shrunk K / fitted K)."""
    attr = f"k_{estimator.lower()}"
    scale = getattr(prior.shrink(fit), attr) / getattr(fit, attr)
    return [r * scale for r in ratios]


def _shrunk_pool(transfers: dict[int, KTransfer], estimator: str,
                 distance_m: dict[str, float]) -> list[float]:
    """The ratios of ``estimator`` of every subject of ``transfers``, its K shrunk toward the median K of the
    *others* with the prior weights ``distance_m`` (:func:`choose_prior`'s pooled ratios)."""
    out: list[float] = []
    for o, (fit, ratios) in transfers.items():
        prior = population_prior([transfers[q][0] for q in transfers if q != o], distance_m=distance_m)
        out += _shrunk_ratios(fit, ratios[estimator], estimator, prior)
    return out


def choose_prior(transfers: dict[int, KTransfer], *,
                 source: str) -> tuple[KPrior, dict[str, float]]:
    """The K prior learned on ``transfers`` (subject: its first-trial K and its other trials' ratios with it).

    The population K is the median over the subjects (:func:`gaitlog.host.gait.k_prior.population_prior`); ``d0`` per
    estimator is the candidate (:data:`gaitlog.host.gait.k_prior.PRIOR_DISTANCE_CANDIDATES_M`) whose pooled ratios have
    the smallest mean squared log ratio (:data:`gaitlog.host.studies.tuning.K_PRIOR_CRITERION`: the loss shrinkage
    minimises, smoother than an IQR of a few dozen ratios), each subject's K shrunk toward the median of the
    *others* (so that no subject is pulled toward itself). Returns the prior and that error per estimator.
    """
    subjects = list(transfers)
    zero = dict.fromkeys(PRIOR_ESTIMATORS, 0.0)
    chosen, error = {}, {}
    for e in PRIOR_ESTIMATORS:
        pooled = [_shrunk_pool(transfers, e, {**zero, e: d0}) for d0 in PRIOR_DISTANCE_CANDIDATES_M]
        j, error[e] = least_error(pooled)
        chosen[e] = PRIOR_DISTANCE_CANDIDATES_M[j]
    return population_prior([transfers[o][0] for o in subjects], distance_m=chosen, source=source), error


def _score_rows(rt: ReplayedTrial, table: StepTable, k: KFit, *, arithmetic: str, k_from: str, uturn: str,
                lengths_source: str, variant: str, cross_validated: bool) -> list[dict]:
    """The :data:`CSV_COLUMNS` rows of one scored trial and chain (one per estimator)."""
    sec, counts = trial_steps(rt, table, uturn=uturn)
    outside = k.outside_range(sec)
    out = []
    for name in ESTIMATORS:
        d = section_distance(sec, counts, name)
        out.append(dict(subject=rt.subject, trial=rt.trial, estimator=name, arithmetic=arithmetic, k_from=k_from,
                        uturn=uturn, lengths_source=lengths_source, variant=variant,
                        walked_distance_m=rt.distance_m, distance_m=d, ratio=d / rt.distance_m,
                        steps=sec.n_steps, reference_steps=rt.reference_steps(),
                        steps_outside_k_range=int(np.count_nonzero(outside[name] & counts)) if name in outside
                        else None, cross_validated=int(cross_validated)))
    return out


def _event_row(rt: ReplayedTrial, table: StepTable, chain: str, calibration_trial: bool) -> dict:
    """Per trial and chain: steps in the trial, how many had each event found, M3's filled steps, the
    events against the foot sensors, and the steps and foot-sensor heel strikes of the rest of the recording
    (:data:`EVENT_COLUMNS`)."""
    sec, _ = trial_steps(rt, table, uturn="include")
    hs, to = score_trial_events(rt, table)
    gaps = rt.gaps()
    return dict(subject=rt.subject, trial=rt.trial, calibration_trial=int(calibration_trial), chain=chain,
                steps=sec.n_steps, heel_strike_found=int(np.count_nonzero(sec.heel_strike >= 0)),
                toe_off_found=int(np.count_nonzero(sec.toe_off >= 0)),
                m3_filled=int(np.count_nonzero(~np.isfinite(sec.length_m["M3"]))),
                hs_reference=hs.n_reference, hs_detected=hs.n_detected, hs_matched=hs.n_matched,
                to_reference=to.n_reference, to_detected=to.n_detected, to_matched=to.n_matched,
                steps_outside=table.n_steps - sec.n_steps, hs_reference_outside=rt.reference_steps_outside(),
                missing_fraction=round(gaps.missing_fraction_, 4), longest_gap_s=round(gaps.longest_gap_s_, 3),
                gap_samples_filled=gaps.n_filled_)


def score_trial_events(rt: ReplayedTrial, table: StepTable) -> tuple[EventScore, EventScore]:
    """Heel strikes and toe-offs of a step table (:attr:`StepTable.heel_strike`, ``toe_off``; -1 = not found)
    against the trial's foot-sensor events inside ``TrialBoundaries`` (:func:`gaitlog.host.studies.tuning.score_events`)."""
    to_ref, hs_ref = rt.reference_event_times_s()
    return (score_events(hs_ref, table.time_s(table.heel_strike[table.heel_strike >= 0])),
            score_events(to_ref, table.time_s(table.toe_off[table.toe_off >= 0])))


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


def _offline(rt: ReplayedTrial, leg: float, foot: float, candidate: dict[str, Any],
             m3_double_support: str = "foot") -> StepTable:
    """The offline chain on a replayed trial with one candidate's event detector (:mod:`gaitlog.host.studies.tuning`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return StepPipeline(leg_length_m=leg, foot_length_m=foot, detector=detector_for(candidate),
                            m3_double_support=m3_double_support).run(
            rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s).steps_


# The evaluation as an object (module notes): IpolEvaluation.run is a sequence of numbered stages, each
# returning one of the small dataclasses below.

@dataclass(frozen=True, eq=False)
class ReplayedSubject:
    """One subject's readable trials, replayed (stage 1).

    Attributes
    ----------
    subject
        Identifier.
    trials
        The readable trials in file order; the first is the calibration trial.
    offline_tables
        Per trial, the offline chain with each candidate of the tuned constants (``[trial][candidate]``).
    leg_length_m, foot_length_m, lengths_source
        The anatomy of the first readable trial (it configures every later one) and where it came from.
    """

    subject: int
    trials: list[ReplayedTrial]
    offline_tables: list[list[StepTable]]
    leg_length_m: float
    foot_length_m: float
    lengths_source: str

    def offline(self, candidate: int) -> list[StepTable]:
        """Per trial, the offline chain with one candidate of the tuned constants."""
        return [tables[candidate] for tables in self.offline_tables]


@dataclass(frozen=True, eq=False)
class ReplayStage:
    """Stage 1: every trial replayed through the emulated logger.

    Attributes
    ----------
    n_files
        Per subject (file order), its trial files, readable or not.
    subjects
        The subjects with at least one readable trial.
    candidates
        The grid of the tuned constants each trial's offline chain ran with (the defaults first).
    replay_checks
        Per readable trial, the device records against the host's replay (:attr:`IpolResult.replay_checks`).
    skipped
        The unreadable trials and why.
    """

    n_files: dict[int, int]
    subjects: dict[int, ReplayedSubject]
    candidates: list[dict[str, Any]]
    replay_checks: list[dict]
    skipped: list[str]


@dataclass(frozen=True, eq=False)
class EventConstantsStage:
    """Stage 2: the tuned event constants, chosen leave-one-subject-out (:attr:`IpolResult.event_scores`,
    :attr:`IpolResult.count_errors`, :attr:`IpolResult.loso`); ``skipped``: the trials left out of them (no
    foot-sensor heel strike between their boundaries)."""

    event_scores: dict[tuple[int, int], list[tuple[EventScore, EventScore]]]
    count_errors: dict[tuple[int, int], list[int]]
    loso: LosoChoice
    skipped: list[str] = field(default_factory=list)


@dataclass(frozen=True, eq=False)
class FoldChoice:
    """Stage 3, one held-out subject: M4's exponent and the K priors chosen on the other subjects
    (``"main"`` and ``"online"``: with the shipped exponent, which the main rows use; absent with too few
    others)."""

    m4_exponent: float
    priors: dict[str, KPrior]


@dataclass(frozen=True, eq=False)
class KConstantsStage:
    """Stage 3: the constants chosen on calibrated ratios, per held-out subject, and the prior learned on
    every subject (:attr:`IpolResult.prior_all`)."""

    folds: dict[int, FoldChoice]
    prior_all: KPrior | None


@dataclass(frozen=True, eq=False)
class SubjectFit:
    """Stage 4: one subject's K, fitted on its first trial with the constants of its fold (stage 5 shrinks it).

    Attributes
    ----------
    replayed
        The subject's trials.
    offline, assumed
        Per trial, the offline chain with the fold's event constants, with the subject's lengths and with a
        1.70 m adult's.
    k, k_fitted
        The main rows' K, and the first trial's K alone (equal unless :data:`K_PRIOR_IN_MAIN`).
    k_online
        The on-line chains' K (the logger's M4 exponent).
    k_other, k_assumed, k_fold
        K for the other U-turn rule, for the height unknown, and with M4's exponent chosen in the subject's fold.
    k_by_exponent
        K fitted with each exponent of :data:`ONLINE_M4_VARIANTS` (the on-line chain's M4 rows).
    own
        The on-line algorithm's own K (None without ``online-fixed`` or when its calibration failed).
    cross_validated_online
        Whether the subject's fold chose the on-line chains' defaults.
    k_shrunk
        The K of the ``k-prior`` rows (stage 5; None without a prior).
    m3_variant
        Per trial, the offline chain with M3's double support by :data:`M3_DOUBLE_SUPPORT_VARIANT` (the
        ``m3-<rule>`` rows; M3 has no K, the other estimators are the main rows').
    k_m4_rules
        K fitted with each of :data:`M4_STEP_RULES` (their rows).
    """

    replayed: ReplayedSubject
    offline: list[StepTable]
    assumed: list[StepTable]
    k: KFit
    k_fitted: KFit
    k_online: KFit
    k_other: KFit
    k_assumed: KFit
    k_fold: KFit
    own: KFit | None
    cross_validated_online: bool
    k_by_exponent: dict[float, KFit] = field(default_factory=dict)
    k_shrunk: KFit | None = None
    m3_variant: list[StepTable] = field(default_factory=list)
    k_m4_rules: dict[str, KFit] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class FitStage:
    """Stage 4: the subjects fitted, and the subjects (or own-K calibrations) skipped and why."""

    fits: dict[int, SubjectFit]
    skipped: list[str]


@dataclass(frozen=True, eq=False)
class ShrunkK:
    """Stage 5, one subject: its K shrunk toward the other subjects' (a variant None when it has too few others)."""

    k: KFit
    k_fitted: KFit
    k_online: KFit
    k_other: KFit | None
    k_assumed: KFit | None
    own: KFit | None


@dataclass(frozen=True, eq=False)
class ScoredChain:
    """Stage 6: one chain of one scored trial, as its :data:`CSV_COLUMNS` rows are computed."""

    arithmetic: str
    k_from: str
    table: StepTable
    k: KFit
    uturn: str
    lengths_source: str
    variant: str
    cross_validated: bool

    def rows(self, rt: ReplayedTrial) -> list[dict]:
        """The chain's rows for ``rt`` (one per estimator)."""
        return _score_rows(rt, self.table, self.k, arithmetic=self.arithmetic, k_from=self.k_from, uturn=self.uturn,
                           lengths_source=self.lengths_source, variant=self.variant,
                           cross_validated=self.cross_validated)


@dataclass(frozen=True, eq=False)
class ScoreStage:
    """Stage 6: the rows (:attr:`IpolResult.rows`, ``step_rows``, ``trial_events``), the scored trials and the
    fixed-point saturation reports."""

    rows: list[dict]
    step_rows: list[dict]
    trial_events: list[dict]
    n_trials: int
    saturation: list[str]


@dataclass(eq=False)
class _Transfers:
    """:func:`_transfer` per (subject, event candidate, exponent index), computed once (stage 3)."""

    subjects: dict[int, ReplayedSubject]
    exponents: tuple[float, ...]
    uturn: str
    cache: dict[tuple[int, int, int], KTransfer | None] = field(default_factory=dict)

    def __call__(self, subject: int, candidate: int, j: int) -> KTransfer | None:
        key = (subject, candidate, j)
        if key not in self.cache:
            self.cache[key] = _transfer(self.subjects[subject], candidate, self.exponents[j], uturn=self.uturn)
        return self.cache[key]

    def pool(self, subjects: list[int], candidate: int, j: int) -> dict[int, KTransfer]:
        """The transfers of ``subjects`` whose calibration succeeded (their order)."""
        return {o: t for o in subjects if (t := self(o, candidate, j)) is not None}


class IpolEvaluation:
    """The whole evaluation on an IPOL folder (module notes), in numbered stages. Library code: no printing.

    Parameters
    ----------
    sampling_rate_hz, adc_bits
        The emulated logger's sample rate and ADC width.
    uturn
        The U-turn rule of the main rows (:data:`UTURN_RULES`).
    arithmetic
        Any of :data:`ARITHMETICS`; every one uses the offline chain's K of the subject's calibration trial.
        With ``online-fixed``, the own-K rows are added (``k_from = "own"``).
    distance_m
        The distance walked between each trial's boundaries, m (> 0; :data:`IPOL_DISTANCE_M`, the IPOL
        protocol's, by default): K is fitted on it and every trial is scored against it, except a trial whose
        JSON gives its own ``WalkedDistance_m``.

    Attributes
    ----------
    replay_, event_constants_, k_constants_, fits_, scores_
        Stages 1 to 6 (:class:`ReplayStage`, :class:`EventConstantsStage`, :class:`KConstantsStage`,
        :class:`FitStage` after the shrinking of stage 5, :class:`ScoreStage`).
    result_
        Stage 7: :class:`IpolResult`.

    Notes
    -----
    1. Replay every trial; the offline chain per candidate of the tuned constants (cached per trial).
    2. The tuned event constants, leave-one-subject-out (heel strikes against the foot sensors).
    3. M4's exponent and the K prior, chosen per held-out subject on the other subjects' calibrated ratios:
       for each exponent, the other subjects' first-trial K (the fold's event constants) and ``d0`` chosen on
       them (:func:`choose_prior`, nested); the exponent is then chosen on their M4 ratios with K as it is
       used. The shipped prior is the one learned on every subject with the shipped constants.
    4. Per subject: K on the first trial with the constants chosen without it.
    5. Every K shrunk toward the other subjects' (the variants toward the same variant of the others, with the
       fold's ``d0``): the main K when :data:`K_PRIOR_IN_MAIN`, else the ``k-prior`` rows' K.
    6. The rows: every trial's step and event rows, the other trials scored.
    7. The result.
    """

    def __init__(self, *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10,
                 uturn: str = "include", arithmetic: tuple[str, ...] = ARITHMETICS,
                 distance_m: float = IPOL_DISTANCE_M) -> None:
        self.sampling_rate_hz = sampling_rate_hz
        self.adc_bits = adc_bits
        self.uturn = uturn
        self.arithmetic = arithmetic
        self.distance_m = distance_m

    def run(self, folder: str | Path, *, progress: Callable[[str], object] | None = None) -> Self:
        """Evaluate ``folder``; ``progress`` (optional) is called with each trial name as it starts.

        Raises
        ------
        HostError
            A trial whose device records differ from the host's replay (naming the first record), or nothing
            to evaluate.
        """
        self._check_parameters()
        self.replay_ = self._replay(list_trials(folder), progress)                               # 1.
        self.replay_.skipped[:0] = stray_files(folder)
        self.event_constants_ = self._choose_event_constants(self.replay_)                       # 2.
        self.k_constants_ = self._choose_k_constants(self.replay_, self.event_constants_)        # 3.
        fits = self._fit(self.replay_, self.event_constants_, self.k_constants_)                 # 4.
        self.fits_ = self._shrink(fits, self.k_constants_)                                       # 5.
        self.scores_ = self._score(self.fits_)                                                   # 6.
        self.result_ = self._result()                                                            # 7.
        if not self.result_.rows:
            raise HostError(f"{folder}: nothing to evaluate (" + "; ".join(self.result_.skipped) + ")")
        return self

    @property
    def other_uturn(self) -> str:
        """The U-turn rule the ``uturn-<rule>`` rows are scored with."""
        return next(u for u in UTURN_RULES if u != self.uturn)

    def _check_parameters(self) -> None:
        for a in self.arithmetic:
            if a not in ARITHMETICS:
                raise ValueError(f"arithmetic must be one of {ARITHMETICS}, got {a!r}")
        if self.uturn not in UTURN_RULES:
            raise ValueError(f"uturn must be 'exclude' or 'include', got {self.uturn!r}")
        d = self.distance_m
        if isinstance(d, bool) or not (isinstance(d, int | float) and math.isfinite(d) and d > 0):
            raise ValueError(f"distance_m must be a finite number of metres > 0, got {self.distance_m!r}")

    # 1. replay -----------------------------------------------------------------------------------------------

    def _replay(self, files: list[Path], progress: Callable[[str], object] | None) -> ReplayStage:
        by_subject: dict[int, list[Path]] = {}
        for f in files:
            by_subject.setdefault(trial_key(f)[0], []).append(f)
        stage = ReplayStage({s: len(p) for s, p in by_subject.items()}, {}, candidates(), [], [])
        for subject, paths in by_subject.items():
            replayed = self._replay_subject(subject, paths, stage, progress)
            if replayed is not None:
                stage.subjects[subject] = replayed
        return stage

    def _replay_subject(self, subject: int, paths: list[Path], stage: ReplayStage,
                        progress: Callable[[str], object] | None) -> ReplayedSubject | None:
        """One subject's trials (None when none is readable); checks and skips go to ``stage``."""
        trials: list[ReplayedTrial] = []
        tables: list[list[StepTable]] = []
        leg = foot = None
        for p in paths:
            if progress is not None:
                progress(p.name)
            try:   # the anatomy of the subject's first readable trial configures every later one
                rt = replay_trial(p, sampling_rate_hz=self.sampling_rate_hz, adc_bits=self.adc_bits,
                                  leg_length_m=leg, foot_length_m=foot, distance_m=self.distance_m)
            except HostError as err:   # one unreadable trial must not sink the whole evaluation
                stage.skipped.append(f"{p.name}: {err}")
                continue
            leg, foot = rt.leg_length_m, rt.foot_length_m
            check = rt.check_records()
            stage.replay_checks.append(dict(trial=p.name, n_device=check.n_device, n_compared=check.n_compared,
                                            n_identical=check.n_identical))
            if check.differs:
                raise HostError(check.error_message(p))
            trials.append(rt)
            tables.append([_offline(rt, leg, foot, c) for c in stage.candidates])
        if not trials:
            return None
        first = trials[0]
        return ReplayedSubject(subject, trials, tables, first.leg_length_m, first.foot_length_m,
                               choose_lengths(trial_height_m=first.height_m).source)

    # 2. the tuned event constants ----------------------------------------------------------------------------

    @staticmethod
    def _choose_event_constants(replay: ReplayStage) -> EventConstantsStage:
        scores: dict[tuple[int, int], list[tuple[EventScore, EventScore]]] = {}
        errors: dict[tuple[int, int], list[int]] = {}
        skipped: list[str] = []
        for subject, rs in replay.subjects.items():
            for rt, tables in zip(rs.trials, rs.offline_tables, strict=True):
                if rt.reference_steps() == 0:     # nothing to score against: not a trial of zero steps
                    skipped.append(f"{rt.path.name}: no foot-sensor heel strike between the trial boundaries; left "
                                   "out of the event and step-count scores (its distance is scored)")
                    continue
                scores[(subject, rt.trial)] = [score_trial_events(rt, t) for t in tables]
                errors[(subject, rt.trial)] = [trial_steps(rt, t, uturn="include")[0].n_steps - rt.reference_steps()
                                               for t in tables]
        loso = LosoChoice({}, {})
        if replay.subjects:
            scored = {s: [rt.trial for rt in rs.trials if (s, rt.trial) in scores] for s, rs in replay.subjects.items()}
            loso = choose_loso({s: [[hs for hs, _ in scores[(s, t)]] for t in ts] for s, ts in scored.items()},
                               {s: [errors[(s, t)] for t in ts] for s, ts in scored.items()}, replay.candidates)
        return EventConstantsStage(scores, errors, loso, skipped)

    # 3. M4's exponent and the K prior ------------------------------------------------------------------------

    def _choose_k_constants(self, replay: ReplayStage, events: EventConstantsStage) -> KConstantsStage:
        exponents = next(p.candidates for p in TUNED_PARAMETERS if p.name == "m4_exponent")
        shipped_j = next(j for j, e in enumerate(exponents) if math.isclose(e, M4_EXPONENT))
        scorable = [s for s, rs in replay.subjects.items() if len(rs.trials) >= 2]
        transfers = _Transfers(replay.subjects, tuple(exponents), self.uturn)
        folds = {s: _fold_choice([o for o in scorable if o != s], events.loso.chosen[s], transfers, shipped_j)
                 for s in scorable}
        every = transfers.pool(scorable, 0, shipped_j)
        prior_all = None
        if len(every) >= 3:
            prior_all = choose_prior(every, source=f"IPOL lower back, subjects {', '.join(map(str, every))}, "
                                                   "first trial each")[0]
        return KConstantsStage(folds, prior_all)

    # 4. K per subject ----------------------------------------------------------------------------------------

    def _fit(self, replay: ReplayStage, events: EventConstantsStage, constants: KConstantsStage) -> FitStage:
        stage = FitStage({}, [])
        for subject, n_files in replay.n_files.items():
            rs = replay.subjects.get(subject)
            if n_files < 2:
                stage.skipped.append(f"subject {subject}: only one trial, nothing to evaluate after calibration")
                continue
            if rs is None or len(rs.trials) < 2:
                stage.skipped.append(f"subject {subject}: fewer than two readable trials")
                continue
            fold = constants.folds.get(subject)
            try:
                fit = self._fit_subject(rs, replay.candidates, events.loso.chosen[subject],
                                        fold.m4_exponent if fold is not None else M4_EXPONENT)
            except HostError as err:
                stage.skipped.append(f"subject {subject}: calibration on {rs.trials[0].path.name} failed: {err}")
                continue
            stage.fits[subject] = replace(fit, own=self._own_k(rs, stage.skipped))
        return stage

    def _fit_subject(self, rs: ReplayedSubject, cands: list[dict[str, Any]], c: int, p4: float) -> SubjectFit:
        """The subject's K with event candidate ``c`` and M4 exponent ``p4`` (``own`` left None)."""
        leg, foot, rt0 = rs.leg_length_m, rs.foot_length_m, rs.trials[0]
        offs = rs.offline(c)
        # the main rows and the on-line chains: the shipped M4 exponent (the fold's is not kept by the rule for
        # choices: its gain's interval includes zero); the fold's scores the m4-per-fold rows
        k = _calibrate_on(rt0, offs[0], uturn=self.uturn, leg=leg, foot=foot)
        k_online = k
        k_other = _calibrate_on(rt0, offs[0], uturn=self.other_uturn, leg=leg, foot=foot)
        a_leg, a_foot = anatomical_lengths(height_m=DEFAULT_HEIGHT_M)
        assumed = [_offline(rt, a_leg, a_foot, cands[c]) for rt in rs.trials]
        k_assumed = _calibrate_on(rt0, assumed[0], uturn=self.uturn, leg=a_leg, foot=a_foot)
        k_fold = _calibrate_on(rt0, offs[0], uturn=self.uturn, leg=leg, foot=foot, m4_exponent=p4)
        # the on-line algorithm runs the defaults (event candidate 0)
        cv_online = c == 0
        k_by_exponent = {p: _calibrate_on(rt0, offs[0], uturn=self.uturn, leg=leg, foot=foot, m4_exponent=p)
                         for p in ONLINE_M4_VARIANTS.values()} if "online-fixed" in self.arithmetic else {}
        m3v = [_offline(rt, leg, foot, cands[c], M3_DOUBLE_SUPPORT_VARIANT) for rt in rs.trials]
        k_m4_rules = {rule: _calibrate_on(rt0, with_m4_rule(rt0, offs[0], rule), uturn=self.uturn, leg=leg, foot=foot)
                      for rule in M4_STEP_RULES}
        return SubjectFit(rs, offs, assumed, k=k, k_fitted=k, k_online=k_online, k_other=k_other, k_assumed=k_assumed,
                          k_fold=k_fold, own=None, cross_validated_online=cv_online, k_by_exponent=k_by_exponent,
                          m3_variant=m3v, k_m4_rules=k_m4_rules)

    def _own_k(self, rs: ReplayedSubject, skipped: list[str]) -> KFit | None:
        """The on-line algorithm's own K (only with ``online-fixed``); a failure is skipped, the subject kept."""
        if "online-fixed" not in self.arithmetic:
            return None
        rt0 = rs.trials[0]
        try:
            return _calibrate_on(rt0, rt0.device_table(), uturn=self.uturn, leg=rs.leg_length_m,
                                 foot=rs.foot_length_m)
        except HostError as err:
            skipped.append(f"subject {rs.subject}: own-K calibration of the on-line algorithm failed: {err}")
            return None

    # 5. the K prior ------------------------------------------------------------------------------------------

    @staticmethod
    def _shrink(stage: FitStage, constants: KConstantsStage) -> FitStage:
        shrunk = {s: _shrunk_k(s, stage.fits, fold.priors) for s, fold in constants.folds.items()
                  if s in stage.fits and fold.priors}
        fits = dict(stage.fits)
        for subject, new in shrunk.items():
            if K_PRIOR_IN_MAIN:
                variants = {n: getattr(new, n) for n in ("k_other", "k_assumed", "own") if getattr(new, n) is not None}
                fits[subject] = replace(fits[subject], k=new.k, k_fitted=new.k_fitted, k_online=new.k_online,
                                        **variants)
            else:           # the main rows keep the first trial's K; the shrunk one scores the k-prior rows
                fits[subject] = replace(fits[subject], k_shrunk=new.k)
        return FitStage(fits, stage.skipped)

    # 6. the rows ---------------------------------------------------------------------------------------------

    def _score(self, stage: FitStage) -> ScoreStage:
        rows: list[dict] = []
        step_rows: list[dict] = []
        trial_events: list[dict] = []
        saturation: list[str] = []
        for fit in stage.fits.values():
            trials = fit.replayed.trials
            for i, rt in enumerate(trials):     # every trial's step and event rows; the first is not scored
                tables = self._trial_tables(fit, i, saturation)
                if set(tables) == set(ARITHMETICS):
                    step_rows += _step_rows(rt, tables, i == 0)
                trial_events += [_event_row(rt, tables[a], a, i == 0) for a in ("offline", "online-fixed")
                                 if a in tables]
                if i > 0:
                    rows += [row for chain in self._chains(fit, i, tables, saturation) for row in chain.rows(rt)]
            if "offline" in self.arithmetic:
                rows += baseline_rows(trials, fit.replayed.leg_length_m, fit.replayed.lengths_source)
        n_trials = sum(len(f.replayed.trials) - 1 for f in stage.fits.values())
        return ScoreStage(rows, step_rows, trial_events, n_trials, saturation)

    def _trial_tables(self, fit: SubjectFit, i: int, saturation: list[str]) -> dict[str, StepTable]:
        """Trial ``i``'s step table per arithmetic, with the offline K."""
        return {a: _calibrated(fit.offline[i], fit.k) if a == "offline"
                else _online(fit.replayed.trials[i], a, fit.k_online, saturation) for a in self.arithmetic}

    def _chains(self, fit: SubjectFit, i: int, tables: dict[str, StepTable],
                saturation: list[str]) -> list[ScoredChain]:
        """The chains scored on trial ``i``: each arithmetic, the own K, and the offline variants."""
        src, cv = fit.replayed.lengths_source, fit.cross_validated_online
        runs = [ScoredChain(a, "offline", tables[a], fit.k if a == "offline" else fit.k_online, self.uturn, src, "main",
                            a == "offline" or cv) for a in self.arithmetic]
        if fit.own is not None:
            own = _online(fit.replayed.trials[i], "fixed", fit.own, saturation)
            runs.append(ScoredChain("online-fixed", "own", own, fit.own, self.uturn, src, "main", cv))
        if "offline" in self.arithmetic:
            runs += self._offline_variants(fit, i)
        if "online-fixed" in self.arithmetic:
            runs += self._online_variants(fit, i, tables["online-fixed"], saturation)
        if "offline" in self.arithmetic:       # M4's length rules (their rows differ from the main ones in M4 alone)
            rt = fit.replayed.trials[i]
            runs += [ScoredChain("offline", "offline", _calibrated(with_m4_rule(rt, fit.offline[i], rule), k), k,
                                 self.uturn, fit.replayed.lengths_source, rule, True)
                     for rule, k in fit.k_m4_rules.items()]
        return runs

    def _online_variants(self, fit: SubjectFit, i: int, table: StepTable, saturation: list[str]) -> list[ScoredChain]:
        """The on-line fixed chain on trial ``i`` with each of :data:`ONLINE_EVENT_VARIANTS` and
        :data:`ONLINE_M4_VARIANTS` (the offline K; ``cross_validated`` 0: the on-line rules were chosen on these
        trials), and its records' M4 with each of :data:`M4_STEP_RULES` (K fitted with the rule on the offline chain;
        no constant, so cross-validated as the on-line main rows are)."""
        rt, src = fit.replayed.trials[i], fit.replayed.lengths_source
        runs = [ScoredChain("online-fixed", "offline", _online(rt, "online-fixed", fit.k_online, saturation,
                                                               events=replace(EventParameters(), **fields)),
                            fit.k_online, self.uturn, src, name, False)
                for name, fields in ONLINE_EVENT_VARIANTS.items()]
        runs += [ScoredChain("online-fixed", "offline", _with_m4_lengths(table, fit.k_by_exponent[p]),
                             fit.k_by_exponent[p], self.uturn, src, name, False)
                 for name, p in ONLINE_M4_VARIANTS.items()]
        runs += [ScoredChain("online-fixed", "offline", _with_m4_rule_lengths(rt, table, rule, k), k, self.uturn, src,
                             rule, fit.cross_validated_online) for rule, k in fit.k_m4_rules.items()]
        return runs

    def _offline_variants(self, fit: SubjectFit, i: int) -> list[ScoredChain]:
        """The offline chain on trial ``i`` with the other U-turn rule, the height unknown, M4's exponent chosen in
        the fold and the other K (the first trial's alone, or shrunk)."""
        off, src, u = fit.offline[i], fit.replayed.lengths_source, self.uturn
        runs = [ScoredChain("offline", "offline", _calibrated(off, fit.k_other), fit.k_other, self.other_uturn, src,
                            f"uturn-{self.other_uturn}", True),
                ScoredChain("offline", "offline", _calibrated(fit.assumed[i], fit.k_assumed), fit.k_assumed, u,
                            "assumed-height", "height-unknown", True),
                ScoredChain("offline", "offline", _calibrated(off, fit.k_fold), fit.k_fold, u, src, "m4-per-fold",
                            True),
                ScoredChain("offline", "offline", _calibrated(fit.m3_variant[i], fit.k), fit.k, u, src,
                            f"m3-{M3_DOUBLE_SUPPORT_VARIANT}", True)]
        if K_PRIOR_IN_MAIN:
            runs.append(ScoredChain("offline", "offline", _calibrated(off, fit.k_fitted), fit.k_fitted, u, src,
                                    "no-prior", True))
        elif fit.k_shrunk is not None:
            runs.append(ScoredChain("offline", "offline", _calibrated(off, fit.k_shrunk), fit.k_shrunk, u, src,
                                    "k-prior", True))
        return runs

    # 7. the result -------------------------------------------------------------------------------------------

    def _result(self) -> IpolResult:
        replay, events, constants, fits, scores = (self.replay_, self.event_constants_, self.k_constants_, self.fits_,
                                                   self.scores_)
        priors = {s: fold.priors for s, fold in constants.folds.items() if fold.priors}
        return IpolResult(
            rows=scores.rows, calibrations={s: f.k for s, f in fits.fits.items()}, n_trials=scores.n_trials,
            skipped=replay.skipped + events.skipped + fits.skipped,
            calibrations_own={s: f.own for s, f in fits.fits.items() if f.own is not None},
            saturation=scores.saturation, replay_checks=replay.replay_checks, step_rows=scores.step_rows,
            arithmetics=tuple(self.arithmetic), uturn=self.uturn, candidates=replay.candidates,
            event_scores=events.event_scores, loso=events.loso, trial_events=scores.trial_events,
            m4_exponent={s: fold.m4_exponent for s, fold in constants.folds.items()},
            calibrations_online={s: f.k_online for s, f in fits.fits.items()}, count_errors=events.count_errors,
            priors=priors, prior_all=constants.prior_all,
            calibration_trials={s: f.replayed.trials[0].trial for s, f in fits.fits.items()})


def _fold_choice(others: list[int], candidate: int, transfers: _Transfers, shipped_j: int) -> FoldChoice:
    """Stage 3 for one held-out subject: per exponent, the K prior learned on ``others`` (with the fold's event
    ``candidate``; at least two of them calibrated), then the exponent whose pooled M4 ratios of ``others``, with
    K as it is used, spread least (:func:`gaitlog.host.studies.tuning.least_spread`)."""
    priors: dict[int, KPrior] = {}
    pooled = []
    for j in range(len(transfers.exponents)):
        train = transfers.pool(others, candidate, j)
        if len(train) >= 2:
            priors[j] = choose_prior(train, source=f"subjects {', '.join(map(str, train))} (leave-one-out)")[0]
        if j not in priors or not K_PRIOR_IN_MAIN:   # K as fitted (no one to shrink toward, or no prior)
            pooled.append([r for _, ratios in train.values() for r in ratios["M4"]])
        else:
            pooled.append(_shrunk_pool(train, "M4", priors[j].distance_m))
    j, _ = least_spread(pooled)
    return FoldChoice(float(transfers.exponents[j]),
                      {key: priors[shipped_j] for key in ("main", "online") if shipped_j in priors})


def _shrunk_k(subject: int, fits: dict[int, SubjectFit], priors: dict[str, KPrior]) -> ShrunkK:
    """Stage 5 for one subject: its K shrunk with its fold's priors; each variant toward the same variant of the
    other subjects (at least two, fitted with the same M4 exponent) with the fold's ``d0``."""
    f = fits[subject]
    k = priors["main"].shrink(f.k)
    variants: dict[str, KFit | None] = {}
    for name in ("k_other", "k_assumed", "own"):
        mine = getattr(f, name)
        others = [getattr(g, name) for o, g in fits.items() if o != subject and getattr(g, name) is not None
                  and mine is not None and math.isclose(getattr(g, name).m4_exponent, mine.m4_exponent)]
        variants[name] = None
        if len(others) >= 2:
            variants[name] = population_prior(others, distance_m=priors["main"].distance_m, source=(
                f"the other subjects' {name.removeprefix('k_')} K (leave-one-out)")).shrink(mine)
    return ShrunkK(k=k, k_fitted=f.k, k_online=k if f.k_online is f.k else priors["online"].shrink(f.k_online),
                   **variants)


def evaluate_folder(
    folder: str | Path, *, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10, uturn: str = "include",
    progress: Callable[[str], object] | None = None, arithmetic: tuple[str, ...] = ARITHMETICS,
    distance_m: float = IPOL_DISTANCE_M,
) -> IpolResult:
    """:class:`IpolEvaluation` on ``folder``: its :attr:`~IpolEvaluation.result_` (``progress``: see
    :meth:`IpolEvaluation.run`)."""
    return IpolEvaluation(sampling_rate_hz=sampling_rate_hz, adc_bits=adc_bits, uturn=uturn,
                          arithmetic=arithmetic, distance_m=distance_m).run(folder, progress=progress).result_


def baseline_rows(trials: list[ReplayedTrial], leg_length_m: float, lengths_source: str) -> list[dict]:
    """The recipe (:class:`gaitlog.host.gait.recipe.RecipeBaseline`) scored as the chain is: its steps whose end
    lies in the trial section (step 3's window), summed; K per estimator = the first trial's walked distance
    (:attr:`ReplayedTrial.distance_m`) over its sum; one
    :data:`CSV_COLUMNS` row per other trial and estimator (``variant = "baseline"``). Empty when the first trial
    has no step."""
    sums, steps = [], []
    for rt in trials:
        rec = RecipeBaseline(leg_length_m=leg_length_m).estimate(rt.acc_g, rt.valid,
                                                                 sampling_rate_hz=rt.sampling_rate_hz)
        lo, hi = rt.meta["TrialBoundaries"]
        t = rt.t0_s + rec.step_end_ / rt.sampling_rate_hz
        inside = (t >= rt.seconds(lo) + SECTION_START_DELAY_S) & (t <= rt.seconds(hi) + SECTION_END_TOLERANCE_S)
        sums.append({e: float(np.nansum(v[inside])) for e, v in rec.length_m_.items()})
        steps.append(int(np.count_nonzero(inside)))
    if not all(sums[0][e] > 0 for e in sums[0]):
        return []
    k = {e: trials[0].distance_m / v for e, v in sums[0].items()}
    return [dict(subject=rt.subject, trial=rt.trial, estimator=e, arithmetic="offline", k_from="offline",
                 uturn="include", lengths_source=lengths_source, variant="baseline",
                 walked_distance_m=rt.distance_m, distance_m=k[e] * d[e], ratio=k[e] * d[e] / rt.distance_m,
                 steps=n, reference_steps=rt.reference_steps(),
                 steps_outside_k_range=None, cross_validated=1)
            for rt, d, n in zip(trials[1:], sums[1:], steps[1:], strict=True) for e in d]


def _online(rt: ReplayedTrial, arithmetic: str, k: KFit, saturation: list[str],
            events: EventParameters | None = None) -> StepTable:
    """The on-line chain of ``arithmetic`` on ``rt``'s stored codes with ``k`` (and ``events``' rules instead of the
    defaults); a fixed-point saturation is added to ``saturation``."""
    ar = arithmetic.removeprefix("online-")
    table, alg = rt.online_table(arithmetic=ar, k_fit=k, events=events)
    if ar == "fixed" and alg.arithmetic_context().report():
        saturation.append(f"{rt.path.name}: {alg.arithmetic_context().report()}")
    return table


def main_rows(rows: list[dict]) -> list[dict]:
    """The rows of the main variant (the chosen U-turn rule, each subject's own lengths)."""
    return [r for r in rows if r.get("variant", "main") == "main"]


def summarise(rows: list[dict], *, arithmetic: str | None = None, k_from: str | None = "offline",
              variant: str | None = "main", intervals: bool = False,
              n_resamples: int = BOOTSTRAP_RESAMPLES) -> list[dict]:
    """Per estimator: n, median, quartiles, IQR, min, max of the ratio; the step count's median ``|error|`` (%
    and steps) and median signed error (steps, detected - reference); steps outside K's calibrated range (of
    the steps in the trials).

    ``arithmetic`` / ``k_from`` / ``variant`` keep only the rows of that arithmetic / K source / variant
    (None: every row). ``intervals``: also ``median_ci`` and ``iqr_ci``, 95 % subject-bootstrap intervals
    (:func:`subject_intervals`, ``n_resamples`` resamples; none when it is 0).
    """
    for key, want, default in (("arithmetic", arithmetic, "offline"), ("k_from", k_from, "offline"),
                               ("variant", variant, "main")):
        if want is not None:
            rows = [r for r in rows if r.get(key, default) == want]
    out = []
    for name in ESTIMATORS:
        mine = [row for row in rows if row["estimator"] == name]
        out.append(_estimator_summary(name, mine))
        if intervals and n_resamples > 0 and out[-1]["n"]:
            ci = subject_intervals(mine, name, n_resamples=n_resamples)
            out[-1].update(median_ci=ci["median"][1:], iqr_ci=ci["iqr"][1:])
    return out


def _estimator_summary(name: str, mine: list[dict]) -> dict[str, Any]:
    """:func:`summarise`'s figures of one estimator's rows (``n = 0`` alone when no ratio is finite)."""
    r = np.array([row["ratio"] for row in mine], float)
    st = [(row["steps"], row["reference_steps"]) for row in mine]
    err = np.array([abs(s - ref) / ref * 100 for s, ref in st if ref > 0], float)
    signed = np.array([s - ref for s, ref in st if ref > 0], float)
    outside = [row.get("steps_outside_k_range") for row in mine]
    r = r[np.isfinite(r)]
    if r.size == 0:
        return dict(estimator=name, n=0)
    q1, med, q3 = np.percentile(r, [25, 50, 75])
    return dict(estimator=name, n=int(r.size), median=float(med), q1=float(q1), q3=float(q3),
                iqr=float(q3 - q1), min=float(r.min()), max=float(r.max()),
                step_error_median_pct=float(np.median(err)) if err.size else float("nan"),
                step_error_median_abs=float(np.median(np.abs(signed))) if signed.size else float("nan"),
                step_error_median_signed=float(np.median(signed)) if signed.size else float("nan"),
                steps_outside_k_range=None if any(o is None for o in outside) else int(sum(outside)),
                steps_total=int(sum(s for s, _ in st)))


def subject_groups(rows: list[dict], estimator: str) -> dict[int, np.ndarray]:
    """``estimator``'s finite ratios of ``rows`` per subject (subject order)."""
    out: dict[int, list[float]] = {}
    for r in rows:
        if r["estimator"] == estimator and math.isfinite(r["ratio"]):
            out.setdefault(int(r["subject"]), []).append(float(r["ratio"]))
    return {s: np.asarray(out[s]) for s in sorted(out)}


def _median_iqr(x: np.ndarray) -> np.ndarray:
    q1, med, q3 = np.percentile(x, [25, 50, 75]) if x.size else (math.nan,) * 3
    return np.array([med, q3 - q1])


def subject_intervals(rows: list[dict], estimator: str, *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0,
                      level: float = BOOTSTRAP_LEVEL) -> dict[str, tuple[float, float, float]]:
    """Median and IQR of ``estimator``'s ratios, each with its percentile-bootstrap interval over subjects
    (subjects drawn with replacement, a subject's trials kept together): ``{"median": (value, low, high),
    "iqr": (...)}``."""
    groups = list(subject_groups(rows, estimator).values())
    if not groups:
        return {k: (math.nan,) * 3 for k in ("median", "iqr")}
    counts = subject_resamples(len(groups), n_resamples=n_resamples, seed=seed)
    value, lo, hi = subject_bootstrap(groups, _median_iqr, counts, level=level)
    return {k: (float(value[j]), float(lo[j]), float(hi[j])) for j, k in enumerate(("median", "iqr"))}


def choice_gain(simple: list[dict], rule: list[dict], estimator: str, *, n_resamples: int = BOOTSTRAP_RESAMPLES,
                seed: int = 0, level: float = BOOTSTRAP_LEVEL) -> tuple[float, float, float]:
    """The gain of a rule over the simpler choice: IQR of the ratios with the simple choice minus with the rule
    (positive: the rule narrows), and its percentile-bootstrap interval over subjects (the same subjects drawn
    for both; only subjects with ratios under both). The rule is kept only when the interval excludes zero."""
    a, b = subject_groups(simple, estimator), subject_groups(rule, estimator)
    subjects = [s for s in a if s in b]
    if not subjects:
        return (math.nan,) * 3
    ga, gb = [a[s] for s in subjects], [b[s] for s in subjects]
    counts = subject_resamples(len(subjects), n_resamples=n_resamples, seed=seed)
    gain, lo, hi = subject_bootstrap(ga, lambda a, b: _median_iqr(a)[1] - _median_iqr(b)[1], counts, gb, level=level)
    return float(gain), float(lo), float(hi)


def _median_abs_log(x: np.ndarray) -> float:
    with np.errstate(divide="ignore"):            # a trial with no step scores 0: |log 0| is inf, as it should be
        return float(np.median(np.abs(np.log(x)))) if x.size else math.nan


def log_error_gain(simple: list[dict], rule: list[dict], estimator: str, *, n_resamples: int = BOOTSTRAP_RESAMPLES,
                   seed: int = 0, level: float = BOOTSTRAP_LEVEL) -> tuple[float, float, float]:
    """As :func:`choice_gain`, the gain in the median ``|log ratio|`` (the typical error of a trial, over- and
    underestimation alike) instead of the IQR: simple minus rule (positive: the rule errs less)."""
    a, b = subject_groups(simple, estimator), subject_groups(rule, estimator)
    subjects = [s for s in a if s in b]
    if not subjects:
        return (math.nan,) * 3
    counts = subject_resamples(len(subjects), n_resamples=n_resamples, seed=seed)
    gain, lo, hi = subject_bootstrap([a[s] for s in subjects], lambda x, y: _median_abs_log(x) - _median_abs_log(y),
                                     counts, [b[s] for s in subjects], level=level)
    return float(gain), float(lo), float(hi)


#: The choices scored by the rule (:func:`choice_gains`): name, the simple choice's rows, the rule's rows (offline
#: chain), the estimators it acts on.
CHOICES = (
    ("K prior (K shrunk toward the other subjects' K) against the first trial's K alone", "no-prior", "main",
     ("M1", "M2", "M4")),
    ("K prior (K shrunk toward the other subjects' K) against the first trial's K alone", "main", "k-prior",
     ("M1", "M2", "M4")),
    ("M4's exponent chosen per fold against the shipped one (Weinberg's 1/4)", "main", "m4-per-fold", ("M4",)),
    ("M4: a step below the trial's median range counts its share of a typical step, against Weinberg's length",
     "main", "m4-range-share", ("M4",)),
    ("M4: Weinberg's length times the step's share of the trial's median duration, against Weinberg's length",
     "main", "m4-duration-share", ("M4",)),
    ("the shipped chain against the recipe (the baseline)", "baseline", "main", ("M2", "M4")),
    ("U-turn steps left out of the distance against every step summed", "main", "uturn-exclude", ESTIMATORS),
    ("M3's double support at the single support's speed against the foot length", "main",
     f"m3-{M3_DOUBLE_SUPPORT_VARIANT}", ("M3",)),
)


#: The on-line algorithm's own rules scored by the rule (:func:`choice_gains`, rows ``online-fixed``): name, the
#: simple choice's rows, the rule's rows (:data:`ONLINE_EVENT_VARIANTS`, :data:`ONLINE_M4_VARIANTS`), the
#: estimators whose IQR it is scored on; the step-counting rules also by the step count (:func:`row_count_gain`).
#: In-sample: these rules were chosen on these trials, so each gain is, if anything, optimistic.
ONLINE_CHOICES = (
    ("on-line: the stop rule of versions 1-3 (stop_prominence_m_s2 0.2) against none (version 4)", "main", "stop-v3",
     ("M2", "M4")),
    ("on-line: the adaptive foot-flat prominence as shipped against the fixed 0.5 m/s^2", "prominence-fixed", "main",
     ("M2", "M4")),
    ("on-line: M4's exponent 1/2 against Weinberg's 1/4 (both from the records' ranges)", "m4-quarter", "m4-half",
     ("M4",)),
    ("on-line: M4 with a step below the trial's median range counted as its share of a typical step (from the "
     "records' ranges, no constant) against the logger's Weinberg length", "main", "m4-range-share", ("M4",)),
    ("on-line: M4 times the step's share of the trial's median duration (from the records, no constant) against the "
     "logger's Weinberg length", "main", "m4-duration-share", ("M4",)),
)


def choice_gains(result: IpolResult, *, n_resamples: int = BOOTSTRAP_RESAMPLES) -> list[dict[str, Any]]:
    """Each rule of :data:`CHOICES` (offline chain) and of :data:`ONLINE_CHOICES` (on-line fixed chain) against its
    simpler choice, per estimator: the gain in IQR with its 95 % subject-bootstrap interval (:func:`choice_gain`)
    and whether the rule is kept (the interval excludes zero on the side of a gain); the on-line step-counting
    rules also by the step count (:func:`row_count_gain`). Empty for a choice whose rows are absent (e.g. the
    U-turn rule when the main rows exclude the turn)."""
    out = []
    for arithmetic, choices in (("offline", CHOICES), ("online-fixed", ONLINE_CHOICES)):
        mine = [r for r in result.rows if r["arithmetic"] == arithmetic and r["k_from"] == "offline"]
        for label, simple, rule, estimators in choices:
            a = [r for r in mine if r["variant"] == simple]
            b = [r for r in mine if r["variant"] == rule]
            if not a or not b:
                continue
            for e in estimators:
                gain, lo, hi = choice_gain(a, b, e, n_resamples=n_resamples)
                out.append(dict(choice=label, estimator=e, gain=gain, low=lo, high=hi, kept=bool(lo > 0)))
                if rule in M4_STEP_RULES:
                    gain, lo, hi = log_error_gain(a, b, e, n_resamples=n_resamples)
                    out.append(dict(choice=label, estimator=f"{e} median |log ratio|", gain=gain, low=lo, high=hi,
                                    kept=bool(lo > 0)))
            if ONLINE_EVENT_VARIANTS.keys() & {simple, rule} and arithmetic != "offline":
                gain, lo, hi = row_count_gain(a, b, n_resamples=n_resamples)
                out.append(dict(choice=label, estimator="steps", gain=gain, low=lo, high=hi, kept=bool(lo > 0)))
    return out


def _mean_gain(diffs: list[np.ndarray], *, n_resamples: int, seed: int, level: float) -> tuple[float, float, float]:
    """The mean of per-subject arrays of per-trial differences pooled, and its percentile-bootstrap interval over
    subjects (a subject's trials kept together)."""
    counts = subject_resamples(len(diffs), n_resamples=n_resamples, seed=seed)
    gain, lo, hi = subject_bootstrap(diffs, np.mean, counts, level=level)
    return float(gain), float(lo), float(hi)


def row_count_gain(simple: list[dict], rule: list[dict], *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0,
                   level: float = BOOTSTRAP_LEVEL) -> tuple[float, float, float]:
    """The step-count gain of a rule (rows ``rule``) over the simpler choice (rows ``simple``, the same trials): per
    trial ``|steps - reference| simple - |steps - reference| rule`` (steps; positive: the rule counts better), its
    mean and 95 % subject-bootstrap interval."""
    def errors(rows: list[dict]) -> dict[tuple[int, int], int]:
        return {(int(r["subject"]), int(r["trial"])): abs(int(r["steps"]) - int(r["reference_steps"])) for r in rows}
    a, b = errors(simple), errors(rule)
    per: dict[int, list[int]] = {}
    for key in sorted(k for k in a if k in b):
        per.setdefault(key[0], []).append(a[key] - b[key])
    if not per:
        return (math.nan,) * 3
    return _mean_gain([np.asarray(v, float) for v in per.values()], n_resamples=n_resamples, seed=seed, level=level)


def count_gains(result: IpolResult, *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0,
                level: float = BOOTSTRAP_LEVEL) -> list[dict[str, Any]]:
    """Each step-counting constant (:data:`gaitlog.host.studies.tuning.SIMPLER_COUNT_CHOICE`) against the rule off:
    per subject, its trials' ``|detected - reference steps|`` with its fold's candidate and with the same candidate
    but that constant at its simpler value; the gain is the mean per trial of the difference (steps; positive: the
    rule counts better), with its 95 % subject-bootstrap interval. Kept only when the interval excludes zero."""
    grid, out = result.candidates, []
    for name, simple in SIMPLER_COUNT_CHOICE.items():
        diffs = []
        for s, c in result.loso.chosen.items():
            want = {**grid[c], name: simple}
            twin = next((j for j, g in enumerate(grid) if g == want), None)
            errs = [e for (o, _), e in result.count_errors.items() if o == s]
            if twin is None or not errs:
                continue
            diffs.append(np.array([abs(e[twin]) - abs(e[c]) for e in errs], float))
        if not diffs:
            continue
        gain, lo, hi = _mean_gain(diffs, n_resamples=n_resamples, seed=seed, level=level)
        out.append(dict(choice=f"{name} chosen per fold against {simple!r} (the rule off); gain in mean |step-count "
                        "error| per trial, steps", estimator="steps", gain=gain, low=lo, high=hi, kept=bool(lo > 0)))
    return out


def format_choices(gains: list[dict[str, Any]]) -> str:
    """:func:`choice_gains` as text."""
    lines = ["choices against the simpler one (gain = IQR simple - IQR with the rule, cross-validated, 95 % "
             "subject-bootstrap interval; a rule is kept only when the interval excludes zero):"]
    for label in dict.fromkeys(g["choice"] for g in gains):
        lines.append(f"  {label}: " + ", ".join(
            f"{g['estimator']} {g['gain']:+.3f} [{g['low']:+.3f}, {g['high']:+.3f}] "
            f"{'kept' if g['kept'] else 'not kept'}" for g in gains if g["choice"] == label))
    return "\n".join(lines)


def event_figures(result: IpolResult) -> dict[str, dict[str, Any]]:
    """Heel strikes and toe-offs against the foot sensors, pooled over every replayed trial.

    Returns ``{label: {"hs": EventScore, "to": EventScore, "cross_validated": bool}}`` for: the offline
    chain with each subject's constants chosen on the other subjects (cross-validated), the offline chain
    with the shipped defaults (in-sample: the defaults were chosen on these trials), and the on-line
    algorithm in fixed point (the shipped defaults; cross-validated only when every fold chose them).
    """
    out: dict[str, dict[str, Any]] = {}
    loso = result.loso.chosen
    keys = [k for k in result.event_scores if k[0] in loso]
    if keys:
        out["offline, constants chosen leave-one-subject-out"] = dict(
            hs=EventScore.pooled([result.event_scores[k][loso[k[0]]][0] for k in keys]),
            to=EventScore.pooled([result.event_scores[k][loso[k[0]]][1] for k in keys]), cross_validated=True)
        out["offline, shipped defaults (in-sample)"] = dict(
            hs=EventScore.pooled([result.event_scores[k][0][0] for k in keys]),
            to=EventScore.pooled([result.event_scores[k][0][1] for k in keys]),
            cross_validated=all(c == 0 for c in loso.values()))
    fx = [r for r in result.trial_events if r["chain"] == "online-fixed" and r["hs_reference"] > 0]
    if fx:
        out["on-line fixed, shipped defaults"] = dict(
            hs=EventScore(sum(r["hs_reference"] for r in fx), sum(r["hs_detected"] for r in fx),
                          sum(r["hs_matched"] for r in fx)),
            to=EventScore(sum(r["to_reference"] for r in fx), sum(r["to_detected"] for r in fx),
                          sum(r["to_matched"] for r in fx)),
            cross_validated=all(c == 0 for c in loso.values()))
    return out


def format_tuning(result: IpolResult) -> str:
    """The constants chosen from these recordings, per held-out subject, and what is cross-validated."""
    loso = result.loso.chosen
    if not loso or not result.candidates:
        return ""
    lines = [f"constants tuned on these recordings, chosen leave-one-subject-out ({len(result.candidates)} candidates; "
             f"criterion: {CRITERION}; step-counting constants: {COUNT_CRITERION}):"]
    for p in TUNED_PARAMETERS:
        if p.criterion == "k-transfer":
            if p.name != "m4_exponent" or not result.m4_exponent:
                continue
            values = list(result.m4_exponent.values())
            lines.append(f"  {p.name} (default {p.default!r}; {p.used_in}; criterion: {K_CRITERION}): "
                         + ", ".join(f"{v!r} in {values.count(v)} of {len(values)} folds" for v in dict.fromkeys(values)))
            continue
        if p.criterion == "k-prior":
            if not result.priors:
                continue
            folds = [pr["main"] for pr in result.priors.values()]
            lines.append(f"  {p.name} ({p.used_in}; criterion: {K_PRIOR_CRITERION}): " + "; ".join(
                f"{e} " + ", ".join(f"{v:g} m in {n} of {len(folds)} folds" for v, n in sorted(Counter(
                    f.distance_m[e] for f in folds).items())) for e in PRIOR_ESTIMATORS))
            if result.prior_all is not None:
                a = result.prior_all
                lines.append("    learned on every subject (shipped as LOWER_BACK_PRIOR, never used to score): d0 "
                             + ", ".join(f"{e} {a.distance_m[e]:g} m" for e in PRIOR_ESTIMATORS)
                             + f"; population K: M1 {a.k_m1:.4f}, M2 {a.k_m2:.4f}, M4 {a.k_m4_per_leg:.4f} x leg "
                             f"length (m/(m/s^2)^{a.m4_exponent:g} per m)")
            continue
        values = [result.candidates[c][p.name] for c in loso.values()]
        counts = {v: values.count(v) for v in dict.fromkeys(values)}
        lines.append(f"  {p.name} (default {p.default!r}; {p.used_in}; by {p.criterion}): "
                     + ", ".join(f"{v!r} in {n} of {len(values)} folds" for v, n in counts.items()))
    every_default = all(c == 0 for c in loso.values())
    lines.append("cross-validated: every offline-chain figure (each subject scored with the constants chosen on "
                 "the other subjects; K per subject from its first trial" + (
                     ", shrunk toward the other subjects' K," if K_PRIOR_IN_MAIN else "") + " scored "
                 "on its other trials); the on-line "
                 "chains run the shipped defaults: "
                 + ("every fold chose them, so their figures are cross-validated too" if every_default else
                    "some folds chose otherwise, so their rows of those subjects are NOT cross-validated "
                    "(column cross_validated = 0)"))
    lines += _nothing_to_choose_on(result)
    return "\n".join(lines)


def _nothing_to_choose_on(result: IpolResult) -> list[str]:
    """A line saying why the folds' choices above are the defaults by absence, when they are: one subject (no
    other to choose on), or no trial with foot-sensor events (no criterion)."""
    if len(result.loso.chosen) < 2:
        return ["  (one subject: no other subject to choose on, so the defaults stand and nothing is cross-validated "
                "between subjects)"]
    if not result.event_scores:
        return ["  (no trial has foot-sensor heel strikes between its boundaries: no criterion to choose the event "
                "and step-counting constants by, so the defaults stand)"]
    return []


def format_events(result: IpolResult) -> str:
    """:func:`event_figures` and the per-trial event counts (:attr:`IpolResult.trial_events`) as text."""
    lines = _event_figure_lines(event_figures(result))
    if result.trial_events:
        lines += _trial_event_lines(result.trial_events)
    return "\n".join(lines)


def _timing(e: EventScore) -> str:
    """The median ``|error|`` and median error of matched events, as :func:`format_events` prints them."""
    return (f", median |error| {1e3 * e.median_abs_error_s:.0f} ms ({1e3 * e.median_error_s:+.0f} ms)"
            if e.errors_s.size else "")


def _event_figure_lines(figs: dict[str, dict[str, Any]]) -> list[str]:
    """:func:`event_figures` as text lines."""
    tol = f"{1e3 * MATCH_TOLERANCE_S:.0f} ms"
    lines = [f"events against the foot sensors (F1 within {tol}; median |error| and median error, detected - "
             f"reference, of the events within {1e3 * TIMING_TOLERANCE_S:.0f} ms):"]
    for label, f in figs.items():
        hs, to = f["hs"], f["to"]
        lines.append(f"  {label}{' [cross-validated]' if f['cross_validated'] else ''}: heel strike F1 {hs.f1:.3f} "
                     f"({hs.n_matched} of {hs.n_reference} reference, {hs.n_detected} detected){_timing(hs)}; "
                     f"toe-off F1 {to.f1:.3f} ({to.n_matched} of {to.n_reference}, {to.n_detected} detected)"
                     f"{_timing(to)}")
    return lines


def _trial_event_lines(rows: list[dict]) -> list[str]:
    """The per-trial event counts (:data:`EVENT_COLUMNS` rows) as text lines: a table, totals per chain, the
    missing samples and what lies outside the trial boundaries."""
    by = {(r["subject"], r["trial"], r["chain"]): r for r in rows}
    chains = [c for c in ("offline", "online-fixed") if any(k[2] == c for k in by)]
    lines = _trial_table_lines(by, chains)
    for c in chains:
        mine = [r for r in rows if r["chain"] == c]
        n = sum(r["steps"] for r in mine)
        lines.append(f"  {c}, all trials: {n} steps, heel strike found on {sum(r['heel_strike_found'] for r in mine)}"
                     f", toe-off on {sum(r['toe_off_found'] for r in mine)}, M3 filled on "
                     f"{sum(r['m3_filled'] for r in mine)}")
    first = [r for r in rows if r["chain"] == chains[0]]
    lines += _gap_lines(first)
    broken = [r for r in first if r["calibration_trial"] and r["longest_gap_s"] > MAX_INTERPOLATED_GAP_S]
    if broken:
        lines.append(f"calibration trials with a gap over {MAX_INTERPOLATED_GAP_S:g} s (a walking bout ends there: "
                     "steps can be lost from the distance K is fitted on): " + ", ".join(
                         f"{r['subject']}-{r['trial']} ({100 * r['missing_fraction']:.1f} % missing, longest gap "
                         f"{r['longest_gap_s']:.2f} s)" for r in broken))
    lines.append("outside the trial boundaries (standing, shuffling and turning before and after the trials; not "
                 f"scored): foot-sensor heel strikes {sum(r['hs_reference_outside'] for r in first)}, detected "
                 "steps " + ", ".join(f"{c} {sum(r['steps_outside'] for r in rows if r['chain'] == c)}"
                                      for c in chains))
    return lines


def _trial_table_lines(by: dict[tuple[int, int, str], dict], chains: list[str]) -> list[str]:
    """The table of :func:`_trial_event_lines`: per trial, each chain's steps with each event found and filled."""
    lines = ["steps per trial (between the trial boundaries) with a heel strike found, a toe-off found, and "
             "filled (M3 without both events: the bout median); * = calibration trial; the logger samples missing "
             "between the trial boundaries (% and the longest gap, s)",
             f"{'trial':<10}" + "".join(f"{c + ': steps HS TO filled':>34}" for c in chains)
             + f"{'missing %':>11}{'gap s':>7}"]
    for s, t in dict.fromkeys((k[0], k[1]) for k in by):
        cells = []
        for c in chains:
            r = by.get((s, t, c))
            cells.append(f"{r['steps']:>19}{r['heel_strike_found']:>5}{r['toe_off_found']:>4}{r['m3_filled']:>6}"
                         if r else f"{'':>34}")
        first = next(by[k] for k in by if k[:2] == (s, t))
        star = "*" if first["calibration_trial"] else ""
        lines.append(f"{f'{s}-{t}{star}':<10}" + "".join(cells)
                     + f"{100 * first['missing_fraction']:>11.1f}{first['longest_gap_s']:>7.2f}")
    return lines


def _gap_lines(rows: list[dict]) -> list[str]:
    """The missing logger samples of one chain's per-trial rows, as a text line (none when no sample is missing)."""
    gappy = [r for r in rows if r["missing_fraction"] > 0]
    if not gappy:
        return []
    worst = max(rows, key=lambda r: r["missing_fraction"])
    longest = max(rows, key=lambda r: r["longest_gap_s"])
    return [f"missing logger samples between the trial boundaries: {len(gappy)} of {len(rows)} trials, "
            f"median {100 * float(np.median([r['missing_fraction'] for r in gappy])):.1f} % of those, "
            f"at most {100 * worst['missing_fraction']:.1f} % ({worst['subject']}-{worst['trial']}); "
            f"longest gap {longest['longest_gap_s']:.2f} s ({longest['subject']}-{longest['trial']}); "
            f"gaps up to {MAX_INTERPOLATED_GAP_S:g} s interpolated by the offline chain: "
            f"{sum(r['gap_samples_filled'] for r in rows)} samples"]


def done_figures(result: IpolResult) -> dict[str, Any]:
    """The targets' figures from an evaluation with every arithmetic (see :func:`format_done`).

    Returns
    -------
    dict
        ``identity``: trials and records compared and identical (device vs host replay);
        ``arithmetic_step``: per estimator, over the matched steps with the same events of every trial,
        ``n``, ``median_abs_mm`` and ``max_abs_mm`` of online-fixed - online-float and ``max_rel`` (``|d|`` /
        the float length); ``different_events``: matched steps whose events differ, of ``matched``;
        ``algorithm_ratio`` / ``arithmetic_ratio``: per estimator, the median and max over the scored trials of
        ``|ratio online-float - ratio offline|`` and ``|ratio online-fixed - ratio online-float|``; ``median_ratio``:
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
    out["arithmetic_step"] = _arithmetic_step(st, same)
    out.update(_ratio_differences(result.rows))
    out["median_ratio"] = {a: {s["estimator"]: s.get("median", math.nan) for s in summarise(result.rows, arithmetic=a)}
                           for a in result.arithmetics}
    out["own"] = {s["estimator"]: dict(median=s.get("median", math.nan), iqr=s.get("iqr", math.nan))
                  for s in summarise(result.rows, arithmetic="online-fixed", k_from="own")}
    return out


def _arithmetic_step(st: list[dict], same: np.ndarray) -> dict[str, dict[str, Any]]:
    """:func:`done_figures`' ``arithmetic_step``: per estimator, online-fixed - online-float over the matched steps
    of :data:`STEP_COLUMNS` rows ``st`` with the same events (``same``)."""
    out = {}
    for e in ESTIMATORS:
        k = e.lower()
        x = np.array([r[f"{k}_online_fixed_m"] for r in st], float)
        y = np.array([r[f"{k}_online_float_m"] for r in st], float)
        g = same & np.isfinite(x) & np.isfinite(y)
        d = np.abs(x[g] - y[g])
        out[e] = dict(n=int(d.size), median_abs_mm=1e3 * float(np.median(d)) if d.size else math.nan,
                      max_abs_mm=1e3 * float(d.max()) if d.size else math.nan,
                      max_rel=float(np.max(d / y[g])) if d.size else math.nan)
    return out


def _ratio_differences(rows: list[dict]) -> dict[str, dict[str, dict[str, Any]]]:
    """:func:`done_figures`' ``algorithm_ratio`` and ``arithmetic_ratio`` from the main rows with the offline K."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    by = {(r["subject"], r["trial"], r["estimator"], r["arithmetic"]): r["ratio"] for r in main_rows(rows)
          if r["k_from"] == "offline"}
    for key, (a, b) in (("algorithm_ratio", ("online-float", "offline")),
                        ("arithmetic_ratio", ("online-fixed", "online-float"))):
        out[key] = {}
        for e in ESTIMATORS:
            d = np.abs([by[t[:3] + (a,)] - by[t] for t in by if t[2] == e and t[3] == b and t[:3] + (a,) in by])
            d = d[np.isfinite(d)]
            out[key][e] = dict(n=int(d.size), median=float(np.median(d)) if d.size else math.nan,
                               max=float(d.max()) if d.size else math.nan)
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
