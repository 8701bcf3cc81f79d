"""The simulated walks the studies run on: the emulated world, sensor, ADC and logger at work.

- :func:`record_subject` -> :class:`SimulatedRecording`: a subject walks the paper's protocol with the emulated
  logger (after a pose session that calibrates it), and its memory image is decoded as a dump would be (steps
  1-2 of :mod:`gaitlog.host.studies.evaluation`).
- :class:`AnalogWalk`: the same walk seen by the sensor on its fine analog grid, sampled at any rate into a
  :class:`gaitlog.host.studies.compare.SampledWalk` (the ADC/rate/arithmetic comparison of :mod:`gaitlog.host.studies.compare`
  and the sweep).
- :func:`ipol_trial` / :func:`export_ipol`: the IPOL lower-back trial (stand, walk 10 m, U-turn, walk back,
  stop) walked by simulated subjects and written in the IPOL layout (``gaitlog simulate --ipol-out``), so that
  the walker can be measured with the same tools as the real recordings.

The world model and the sensor (``scipy.signal``, ``scipy.interpolate``) are imported here, at module level,
so that the studies on recordings (``gaitlog compare`` on a file) and the commands on files never load them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any, TypeVar

import numpy as np

from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ, Adc
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import SensorModel, flicker_rng
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.firmware_sim.world.stopwatch import Stopwatch
from gaitlog.firmware_sim.world.subject import Subject, random_subjects
from gaitlog.firmware_sim.world.walk_plan import PAPER_HEIGHTS_M, POPULATION_PLANS, WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.accelerometer.fit import AccCalibrator
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_bytes
from gaitlog.host.files.ipol import IPOL_SAMPLING_RATE_HZ, write_trial
from gaitlog.host.files.replay import run_starts
from gaitlog.host.studies.compare import SampledWalk, WalkComparison, compare_walk
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.image import build_image
from gaitlog.protocol.packing import FLAG_MARK
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["PROTOCOLS", "AnalogWalk", "SimulatedRecording", "at_paper_heights", "export_ipol", "ipol_trial", "ipol_walk_plan",
           "record_subject", "simulated_population"]


#: Missing samples the host puts between two logging runs on its own clock (it does not know how long the
#: logger was stopped; the runs only have to stay apart so that no step or filter bridges them).
RUN_GAP_S = 2.0
#: Who times the 20 m laps: the observer's stopwatch (the paper's) or the logger's MARK button.
LAP_TIMINGS = ("stopwatch", "mark")


@dataclass(frozen=True, eq=False)
class SimulatedRecording:
    """What the logger stored for one simulated subject, in calibrated g, with the world's truth.

    Every time here is on the **host's clock**: the decoded logging runs one after the other, ``RUN_GAP_S``
    of missing samples between them, sample 0 at ``t0_s`` = 0 (the host does not know how long the logger
    was stopped between runs). The truth's times are converted to that clock (NaN where nothing was logged,
    e.g. during a rest the logger was stopped for).

    Attributes
    ----------
    subject
        The :class:`gaitlog.firmware_sim.world.subject.Subject`.
    seed
        Seed of the walk and of the device.
    acc_g, valid
        ``(n, 3)`` calibrated specific force (g) and the validity mask.
    sampling_rate_hz, t0_s
        Logger rate and time of sample 0.
    mark_times_s
        Times of the samples carrying the MARK flag (lap button).
    truth
        The walk's truth (``steps``, ``laps``, ``excursions``, ...; see :mod:`gaitlog.firmware_sim.world.walking`).
    device_calibrated
        True when the codes were converted with a pose-session calibration (else the nominal map).
    run_rows
        ``[start, stop)`` rows of each logging run (from its SESSION_START sample).
    lap_sheet
        The observer's stopwatch sheet (:meth:`gaitlog.firmware_sim.world.stopwatch.Stopwatch.time_laps`; its
        ``start_walk_s`` converted to the host clock as truth) when the laps were timed by stopwatch, else None.
    """

    subject: Any
    seed: int
    acc_g: np.ndarray
    valid: np.ndarray
    sampling_rate_hz: float
    t0_s: float
    mark_times_s: np.ndarray
    truth: dict
    device_calibrated: bool
    run_rows: tuple[tuple[int, int], ...] = ()
    lap_sheet: dict | None = None


_TRUTH_TIMES = {"steps": ("heel_strike_s", "foot_flat_s", "toe_off_s", "next_heel_strike_s", "next_foot_flat_s",
                          "com_min_s"),
                "laps": ("time_s",), "excursions": ("t_start_s", "t_stop_s", "turn_start_s", "turn_end_s"),
                "rests": ("t_start_s", "t_stop_s")}


def _to_host(t_walk: np.ndarray, spans: list[tuple[float, float, float]]) -> np.ndarray:
    """Walk-clock times to the host clock: ``spans`` = (first sample's walk time, last's, its host time)."""
    t = np.asarray(t_walk, np.float64)
    out = np.full(t.shape, np.nan)
    for first, last, host in spans:
        inside = (t >= first - 1e-9) & (t <= last + 1e-9)
        out[inside] = host + t[inside] - first
    return out


def record_subject(subject: Any, *, seed: int, walk_plan: Any = None, sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, adc_bits: int = 10,
                   calibrate_device: bool = True, laps: str = "mark") -> SimulatedRecording:
    """Walk ``subject`` through the protocol with the emulated logger (:mod:`gaitlog.host.studies.evaluation`, steps 1-2).

    The logger is STARTed and STOPped as the plan says (:attr:`~gaitlog.firmware_sim.world.walk_plan.WalkPlan.logger_runs`:
    one run, or one per excursion with the rests unlogged), all runs into one memory (no ERASE between them);
    the host reads the memory image as a dump and splits it into runs at the SESSION_START samples.

    Parameters
    ----------
    subject
        A :class:`gaitlog.firmware_sim.world.subject.Subject`.
    seed
        Seeds the walk's variability, the pose session, the device's sensor errors and the observer.
    walk_plan
        A :class:`gaitlog.firmware_sim.world.walk_plan.WalkPlan` (default: ``WalkPlan()``).
    sampling_rate_hz, adc_bits
        Logger sample rate and ADC resolution.
    calibrate_device
        Fit the device calibration on a pose session first (default) or use the nominal map.
    laps
        ``"mark"``: the MARK button is pressed at every lap (exactly); ``"stopwatch"``: an observer times them
        (:class:`gaitlog.firmware_sim.world.stopwatch.Stopwatch`, no MARK on the device).

    Raises
    ------
    HostError
        The protocol does not fit in the logger's memory.
    """
    if laps not in LAP_TIMINGS:
        raise HostError(f"laps must be one of {LAP_TIMINGS}, got {laps!r}")
    logger = Logger(adc=Adc(adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz), sampling_rate_hz=sampling_rate_hz, device_id=1 + seed % 60000)
    apply = (_pose_calibration(logger, seed=seed, adc_bits=adc_bits, sampling_rate_hz=sampling_rate_hz)
             if calibrate_device else CalibrationSlot.nominal(adc_bits).apply)
    walking = Walking(subject=subject, walk_plan=walk_plan, seed=seed)
    results = _log_runs(logger, walking, subject.subject_id, mark_laps=laps == "mark")
    # What the host gets: the memory image (header + EEPROM), decoded as a dump would be, cut into runs.
    stored = decode_bytes(build_image(logger.header.to_bytes(), logger.memory, step_memory=logger.step_memory),
                          source=f"{subject.subject_id}.sim")
    walk_times_s, bounds = _stored_runs(stored, results, subject.subject_id)
    host = _HostClock.join(stored, apply, walk_times_s, bounds)
    res = results[-1]
    truth = _truth_on_host_clock(res.truth, host.spans)
    sheet = None
    if laps == "stopwatch":
        sheet = Stopwatch().time_laps(res.truth["laps"], res.truth["excursions"], seed=seed)
        sheet["start_walk_s"] = _to_host(sheet["start_walk_s"], host.spans)
    return SimulatedRecording(subject, int(seed), host.acc_g, host.valid, host.sampling_rate_hz, 0.0,
                              host.mark_times_s, truth, bool(calibrate_device), host.run_rows, sheet)


def _pose_calibration(logger: Logger, *, seed: int, adc_bits: int, sampling_rate_hz: float
                      ) -> Callable[[np.ndarray], np.ndarray]:
    """The device calibration fitted on a pose session the logger records (then erased): codes -> g."""
    poses = logger.record(CalibrationPoses(n_poses=12, hold_s=4.0, move_s=1.5, seed=seed))
    full = float(2**adc_bits)
    apply = AccCalibrator().calibrate(poses.codes.astype(np.float64), sampling_rate_hz=sampling_rate_hz,
                                      input_unit="counts", zero=full / 2, unit_per_g=full / 4,
                                      valid_range=(0.0, full - 1)).calibration_.apply
    logger.erase()
    return apply


def _log_runs(logger: Logger, walking: Walking, subject_id: str, *, mark_laps: bool) -> list:
    """The logger's result of each logging run of the walk (the MARK button pressed at every lap only when
    ``mark_laps``); :class:`HostError` when a run does not fit in its memory."""
    results = []
    for motion in walking.render_runs(logger.sensor.internal_rate_hz):
        if not mark_laps:
            motion = replace(motion, marker_times_s=np.zeros(0))
        try:
            results.append(logger.record(motion, start_time_s=1_700_000_000 + int(motion.t0_s)))
        except DeviceError as err:
            raise HostError(f"subject {subject_id}: logging run {len(results) + 1}: {err}; the protocol "
                            "does not fit in the logger's memory (stop the logger during the rests)") from None
        if results[-1].n_taken != results[-1].n_samples:
            raise HostError(f"subject {subject_id}: the logger stored {results[-1].n_samples} of "
                            f"{results[-1].n_taken} samples of run {len(results)} (memory full): the protocol does not "
                            "fit in the logger's memory (stop the logger during the rests)")
    return results


def _stored_runs(stored: Any, results: list, subject_id: str) -> tuple[np.ndarray, list[int]]:
    """The walk-clock time of each decoded sample, and the rows where each run starts (then the end): the
    decoded samples must be the logged ones and hold one SESSION_START per run (:class:`HostError` otherwise)."""
    numbers = np.concatenate([np.asarray(r.sample_numbers) for r in results])
    times = np.concatenate([np.asarray(r.sample_times_s, np.float64) for r in results])
    pos = np.searchsorted(numbers, stored.sample_numbers)
    if np.any(pos >= numbers.size) or np.any(numbers[np.minimum(pos, numbers.size - 1)] != stored.sample_numbers):
        raise HostError(f"subject {subject_id}: decoded sample numbers do not match the recording")
    starts = run_starts(stored.valid, stored.flags)
    if starts.size != len(results) or (starts.size and starts[0] != 0):
        raise HostError(f"subject {subject_id}: {starts.size} logging runs in the dump for {len(results)} "
                        "STARTs")
    return times[pos], [int(x) for x in starts] + [int(stored.sample_numbers.size)]


@dataclass(frozen=True)
class _HostClock:
    """The decoded runs on the host's clock (:class:`SimulatedRecording`): one after the other, ``RUN_GAP_S`` of
    missing rows between them. ``spans``: per run, its first and last sample's walk time and its host time."""

    acc_g: np.ndarray
    valid: np.ndarray
    mark_times_s: np.ndarray
    run_rows: tuple[tuple[int, int], ...]
    spans: list[tuple[float, float, float]]
    sampling_rate_hz: float

    @classmethod
    def join(cls, stored: Any, apply: Callable[[np.ndarray], np.ndarray], walk_times_s: np.ndarray,
             bounds: list[int]) -> _HostClock:
        """The runs of ``stored`` (rows ``bounds[i]`` to ``bounds[i + 1]``, at ``walk_times_s``), calibrated by
        ``apply`` (codes -> g; an invalid or non-finite sample becomes NaN)."""
        rate = float(1.0 / np.median(np.diff(walk_times_s)))
        gap = round(RUN_GAP_S * rate)
        acc_all = np.asarray(apply(stored.codes.astype(np.float64)), np.float64)
        ok_all = np.asarray(stored.valid, bool) & np.isfinite(acc_all).all(axis=1)
        flags_all = np.asarray(stored.flags)
        acc_parts, ok_parts, mark_parts, rows, spans = [], [], [], [], []
        row = 0
        for a, b in pairwise(bounds):
            if rows:
                acc_parts.append(np.full((gap, 3), np.nan))
                ok_parts.append(np.zeros(gap, bool))
                row += gap
            acc_parts.append(acc_all[a:b])
            ok_parts.append(ok_all[a:b])
            mark_parts.append(row + np.flatnonzero(flags_all[a:b] & FLAG_MARK))
            rows.append((row, row + b - a))
            spans.append((float(walk_times_s[a]), float(walk_times_s[b - 1]), row / rate))
            row += b - a
        acc = np.concatenate(acc_parts)
        valid = np.concatenate(ok_parts)
        acc[~valid] = np.nan
        return cls(acc, valid, np.concatenate(mark_parts) / rate, tuple(rows), spans, rate)


def _truth_on_host_clock(truth: dict, spans: list[tuple[float, float, float]]) -> dict:
    """The walk's truth with its times (:data:`_TRUTH_TIMES`) on the host's clock (:func:`_to_host`)."""
    out = {k: dict(truth[k]) for k in _TRUTH_TIMES if k in truth}
    for part, keys in _TRUTH_TIMES.items():
        for key in keys:
            if part in out and key in out[part]:
                out[part][key] = _to_host(out[part][key], spans)
    if "subject" in truth:
        out["subject"] = truth["subject"]
    return out


class AnalogWalk:
    """A subject walking the protocol, seen by the logger's sensor on its fine analog grid.

    Parameters
    ----------
    subject
        :class:`gaitlog.firmware_sim.world.subject.Subject`.
    seed
        Seed of the walk; the sensor is the unit ``SensorModel.draw(seed=sensor_seed)`` (default: the
        logger's default for ``device_id = 1 + seed % 60000``, as :func:`record_subject`).
    walk_plan
        :class:`gaitlog.firmware_sim.world.walk_plan.WalkPlan` (default: the paper's).

    Attributes
    ----------
    volts_, rate_hz_, truth_, sensor_
        Sensor output (``(n, 3)`` V, noise-free: the noise is drawn at the sample instants), its rate, the
        walk's truth and the sensor.
    """

    def __init__(self, *, subject: Any, seed: int = 0, walk_plan: Any = None, sensor_seed: int | None = None) -> None:
        self.subject = subject
        self.seed = seed
        self.walk_plan = walk_plan
        self.sensor_seed = sensor_seed

    def run(self) -> AnalogWalk:
        """Render the walk and the sensor's response (the expensive part, done once per subject)."""
        sseed = self.sensor_seed if self.sensor_seed is not None else 1 + self.seed % 60000
        self.sensor_ = SensorModel.draw(seed=int(sseed))
        motion = Walking(subject=self.subject, walk_plan=self.walk_plan, seed=self.seed).render(
            self.sensor_.internal_rate_hz)
        self.rate_hz_ = float(motion.sampling_rate_hz)
        self.t0_s_ = float(motion.t0_s)
        self.t_last_s_ = self.t0_s_ + (motion.acc_g.shape[0] - 1) / self.rate_hz_
        self.marker_times_s_ = np.asarray(motion.marker_times_s, np.float64)
        self.volts_ = self.sensor_.respond(motion.acc_g, self.rate_hz_, noise=False)
        self.truth_ = {k: motion.truth[k] for k in ("steps", "laps", "excursions", "rests") if k in motion.truth}
        return self

    def sample(self, sampling_rate_hz: float, *, noise_density_g_rthz: float | None = None,
               sensor_changes: Mapping[str, Any] | None = None, converter: Mapping[str, Any] | None = None
               ) -> SampledWalk:
        """The analog output at the sample instants of a ``sampling_rate_hz`` timer, noise included (as
        :meth:`gaitlog.firmware_sim.device.Logger.record`: same instants, same hold, same noise stream).

        ``noise_density_g_rthz`` replaces the sensor's white-noise density (default: the sensor's, 200 µg/√Hz);
        the noise stream (its seed) is the same, only scaled, so a noise sweep compares like with like.
        ``sensor_changes``: other :class:`SensorModel` fields replaced (1/f corner, temperature coefficients and
        profile: applied at the sample instants, the 1/f noise from its own stream). ``converter``:
        :class:`gaitlog.firmware_sim.adc.Adc` fields of a real converter (sequential sampling, settling, INL/DNL,
        offset, gain error; the device's curve seeded with the sensor's seed unless ``linearity_seed`` is given):
        the codes come from it, the ideal chain keeps the simultaneous, unquantised input."""
        adc = Adc(adc_bits=10, sampling_rate_hz=sampling_rate_hz)
        sen = self.sensor_
        if noise_density_g_rthz is not None:
            sen = replace(sen, noise_density_g_rthz=float(noise_density_g_rthz))
        if sensor_changes:
            sen = replace(sen, **sensor_changes)
        times = adc.sample_times_s(self.t0_s_, self.t_last_s_)
        noise_v = sen.noise_g(times, rng=np.random.default_rng(sen.seed)) * sen.gain_v_per_g
        flicker_v = sen.flicker_g(times, rng=flicker_rng(sen.seed)) * sen.gain_v_per_g if sen.flicker_corner_hz else None

        def analog(conv: Adc) -> np.ndarray:          # the operations of Logger.record, in its order
            held = conv.hold(self.volts_, self.rate_hz_, self.t0_s_, times) + noise_v
            if flicker_v is not None:
                held = held + flicker_v
            return sen.drifted_v(held, times - self.t0_s_)

        held = analog(adc)
        # the converter input in 10-bit code units (Adc.convert without the floor), clipped to the span
        lsb = adc.lsb_v
        v = adc.ref_v + adc.gain * (held - adc.ref_v)
        x = np.clip((v - adc.vref_low_v) / lsb, 0.0, float(adc.n_codes) - 1e-9)
        offset = (adc.ref_v + adc.gain * (sen.zero_g_v + sen.gain_v_per_g * sen.offset_g - adc.ref_v)
                  - adc.vref_low_v) / lsb
        gain = (adc.gain * sen.gain_v_per_g / lsb)[:, None] * sen.axes
        marks = np.zeros(times.size, bool)
        if self.marker_times_s_.size:
            k = np.searchsorted(times, self.marker_times_s_, side="left")
            marks[k[k < times.size]] = True
        real = None if not converter else replace(adc, **({"linearity_seed": int(sen.seed)} | dict(converter)))
        if real is None or real.ideal:
            return SampledWalk(x, times, times[marks], float(sampling_rate_hz), offset, gain, self.truth_)
        adc_input = real.input_lsb(analog(real) if real.sequential else held)
        return SampledWalk(x, times, times[marks], float(sampling_rate_hz), offset, gain, self.truth_,
                           np.minimum(adc_input, float(adc.n_codes) - 1e-9), real.transfer_curve)


_T = TypeVar("_T")


def simulated_population(n_subjects: int, *, seed: int = 0, population: str = "people",
                         walk_plan: WalkPlan | None = None, protocol: str = "compact"
                         ) -> tuple[list[Subject], WalkPlan | None]:
    """The subjects of a simulated study and the protocol they walk.

    ``protocol="compact"``: ``random_subjects(n_subjects, seed, population)`` walking ``walk_plan``, else
    ``WalkPlan`` with the population's walk habits (:data:`~gaitlog.firmware_sim.world.walk_plan.POPULATION_PLANS`;
    None for ``"v1"``: the default plan: 60 s rests, the logger running throughout).
    ``protocol="paper"``: the same draws brought to the paper's heights (:func:`at_paper_heights`) walking
    ``walk_plan``, else :meth:`WalkPlan.paper` with the population's habits (5-minute rests, the logger
    stopped during them)."""
    if protocol not in PROTOCOLS:
        raise HostError(f"protocol must be one of {PROTOCOLS}, got {protocol!r}")
    subjects = random_subjects(n_subjects, seed=seed, population=population)
    if protocol == "paper":
        if walk_plan is None:
            walk_plan = WalkPlan.paper(**POPULATION_PLANS[population])
        return at_paper_heights(subjects, seed=seed), walk_plan
    if walk_plan is None and POPULATION_PLANS[population]:
        walk_plan = WalkPlan(**POPULATION_PLANS[population])
    return subjects, walk_plan


#: ``"paper"``: Alvarez's protocol as run (5-minute rests, logger stopped, subjects 1.68-1.86 m);
#: ``"compact"``: 60 s rests logged, the population's heights (the studies' walk before the paper's).
PROTOCOLS = ("paper", "compact")


def at_paper_heights(subjects: list[Subject], *, seed: int = 0) -> list[Subject]:
    """The subjects rescaled to heights drawn uniformly over the paper's range (:data:`PAPER_HEIGHTS_M`,
    1.68-1.86 m: the paper gives only the range of its four men), subject ``i``'s height independent of how
    many there are. Lengths scale with height (leg, foot, walk ratio), the preferred speed with its square
    root (dynamic similarity, as the populations draw it); every other habit is the subject's own.

    Examples
    --------
    >>> s = at_paper_heights(random_subjects(3, seed=1))
    >>> all(1.68 <= x.height_m <= 1.86 for x in s), round(s[0].leg_length_m / s[0].height_m, 3) == round(
    ...     random_subjects(1, seed=1)[0].leg_length_m / random_subjects(1, seed=1)[0].height_m, 3)
    (True, True)
    """
    lo, hi = PAPER_HEIGHTS_M
    out = []
    for i, sub in enumerate(subjects):
        h = float(np.random.default_rng(np.random.SeedSequence([int(seed), i, 1968])).uniform(lo, hi))
        f = h / sub.height_m
        out.append(replace(sub, height_m=h, leg_length_m=sub.leg_length_m * f, foot_length_m=sub.foot_length_m * f,
                           walk_ratio_m_spm=sub.walk_ratio_m_spm * f,
                           preferred_speed_m_s=sub.preferred_speed_m_s * float(np.sqrt(f))))
    return out


def simulate_comparisons(n_subjects: int, *, seed: int = 0, adc_bits: int = 10,
                         sampling_rate_hz: float = DEFAULT_SAMPLING_RATE_HZ, workers: int = 1,
                         progress: Callable[[], object] | None = None,
                         population: str = "people") -> list[WalkComparison]:
    """One :class:`gaitlog.host.studies.compare.WalkComparison` per simulated subject (``gaitlog compare --simulate``),
    in parallel over subjects; ``progress()`` is called after each subject."""
    subjects, plan = simulated_population(n_subjects, seed=seed, population=population)
    jobs = [(s, seed * 1000 + i, adc_bits, sampling_rate_hz, plan) for i, s in enumerate(subjects)]
    return map_subjects(_compared_subject, jobs, workers=workers, progress=progress)


def map_subjects(job: Callable[[Any], _T], jobs: list, *, workers: int = 1,
                 progress: Callable[[], object] | None = None) -> list[_T]:
    """``[job(j) for j in jobs]``, on up to ``workers`` processes when there are several jobs (``job`` and the
    jobs must pickle), in order; ``progress()`` is called as each result arrives (one tick per subject)."""
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
            return [_ticked(r, progress) for r in pool.map(job, jobs)]
    return [_ticked(job(j), progress) for j in jobs]


def _ticked(result: _T, progress: Callable[[], object] | None) -> _T:
    if progress is not None:
        progress()
    return result


def _compared_subject(job: tuple) -> WalkComparison:
    subject, seed, adc_bits, sampling_rate_hz, walk_plan = job
    wc = compare_walk(AnalogWalk(subject=subject, seed=seed, walk_plan=walk_plan).run().sample(sampling_rate_hz), subject,
                      adc_bits=adc_bits)
    wc.runs = {}            # the tables are not needed any more (keeps the pickled result small)
    wc.matches = {}
    return wc


def ipol_walk_plan(population: str = "people") -> WalkPlan:
    """The IPOL lower-back trial as a :class:`WalkPlan`: quiet standing (2 s: the tools take gravity from the
    first second), 10 m out, the U-turn, 10 m back, stop, stand 1.5 s; one excursion at the preferred speed.
    Gait initiation, turn and termination: the population's (:data:`gaitlog.firmware_sim.world.walk_plan.POPULATION_PLANS`)."""
    extra = POPULATION_PLANS[population]
    return WalkPlan(corridor_length_m=10.0, speeds=("preferred",), initial_stand_s=2.0, final_stand_s=1.5,
                    lap_marks_m=(0.0, 20.0), **extra)


def ipol_trial(subject: Subject, *, seed: int, population: str = "people") -> tuple[np.ndarray, dict]:
    """One simulated IPOL trial: ``(acc_m_s2, meta)`` for :func:`gaitlog.host.files.ipol.write_trial`.

    ``acc_m_s2`` is the world's specific force at the sensor, in the device axes (x up, y left, z backward, as
    the Xsens of the IPOL recordings; the subject's mounting tilt included), sampled at 100 Hz without noise.
    The JSON fields come from the world's truth, rounded to the nearest packet:
    ``Left/RightFootEvents`` one [toe-off, heel-strike] pair per swing (the trailing foot of each step; the
    first swing starts one swing time before the first heel strike), ``TrialBoundaries`` = [first toe-off,
    last heel strike] (as in the IPOL files), ``UTurnBoundaries`` = when the centre of mass enters and leaves
    the curved part of its path, ``Height`` in cm; ``Simulated`` holds the seed and the subject's parameters.
    """
    motion = Walking(subject=subject, walk_plan=ipol_walk_plan(population), seed=seed).render(IPOL_SAMPLING_RATE_HZ)
    st, exc = motion.truth["steps"], motion.truth["excursions"]

    def packet(t_s: np.ndarray | float) -> np.ndarray:
        return np.rint(np.asarray(t_s, dtype=np.float64) * IPOL_SAMPLING_RATE_HZ).astype(np.int64)

    other = {"L": "R", "R": "L"}
    swing_feet = [other[s] for s in st["side"]]                     # the trailing foot swings in each step
    swing_to, swing_hs = list(st["toe_off_s"]), list(st["next_heel_strike_s"])
    first_swing_s = float(st["next_heel_strike_s"][0] - st["toe_off_s"][0])
    swing_feet.insert(0, str(st["side"][0]))
    swing_to.insert(0, max(float(exc["t_start_s"][0]), float(st["heel_strike_s"][0]) - first_swing_s))
    swing_hs.insert(0, float(st["heel_strike_s"][0]))
    to_p, hs_p = packet(swing_to), packet(swing_hs)
    events = {foot: [[int(a), int(b)] for a, b, f in zip(to_p, hs_p, swing_feet) if f == foot] for foot in "LR"}
    meta = {
        "Height": round(100.0 * subject.height_m, 1),
        "TrialBoundaries": [int(to_p.min()), int(hs_p.max())],
        "UTurnBoundaries": [int(packet(exc["turn_start_s"][0])), int(packet(exc["turn_end_s"][0]))],
        "LeftFootEvents": events["L"],
        "RightFootEvents": events["R"],
        "Simulated": {"seed": int(seed), "population": population, "subject": _jsonable(subject.as_dict())},
    }
    return motion.acc_g * STANDARD_GRAVITY_M_S2, meta


def _jsonable(d: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


def _ipol_job(job: tuple) -> tuple[int, int, np.ndarray, dict]:
    number, trial, subject, seed, population = job
    acc, meta = ipol_trial(subject, seed=seed, population=population)
    return number, trial, acc, meta


def export_ipol(folder: Any, n_subjects: int, *, seed: int = 0, trials: int = 1, population: str = "people",
                workers: int = 1, progress: Callable[[], object] | None = None) -> list[str]:
    """Write ``n_subjects`` simulated subjects x ``trials`` IPOL trials into ``folder`` (``<i>-<t>_lb.txt`` and
    ``<i>-<t>.json``, subject ``i`` = 1-based index into ``random_subjects(n_subjects, seed=seed,
    population=population)``); returns the trial names. Each trial of a subject is a different walk (its own seed)."""
    if n_subjects < 1 or trials < 1:
        raise HostError(f"need at least one subject and one trial, got {n_subjects} x {trials}")
    subjects = random_subjects(n_subjects, seed=seed, population=population)
    jobs = [(i + 1, t + 1, sub, int(np.random.SeedSequence([seed, i, t]).generate_state(1)[0] % 2**31), population)
            for i, sub in enumerate(subjects) for t in range(trials)]
    names = []
    for number, trial, acc, meta in map_subjects(_ipol_job, jobs, workers=workers, progress=progress):
        write_trial(folder, number, trial, acc, meta, sampling_rate_hz=IPOL_SAMPLING_RATE_HZ)
        names.append(f"{number}-{trial}")
    return names
