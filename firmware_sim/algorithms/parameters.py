"""The step algorithm's rules and constants, arithmetic-free, in one place.

:class:`EventParameters` holds what defines the gait events and the steps: the same numbers are used by the
firmware's on-line algorithm (:mod:`gaitlog.firmware_sim.algorithms.online`, float or fixed point) and by the
host's offline chain (``gaitlog.host.gait``: the paper's PC processing). :class:`OnlineParameters` adds what only
the on-line algorithm needs (its causal gravity estimate and its running median). :class:`SampleCounts`
turns both into the integer sample counts a firmware works with at a given sampling rate, with the rounding
rule written once (:func:`samples`).

Why each default is what it is (the measured figures behind them are in ``gaitlog.host.gait.events``' notes):

* ``ff_cutoff_hz`` 3 Hz: the first harmonic of trunk vertical acceleration (Alvarez's M4 band); foot-flat is
  its peak, where the centre of mass is lowest and its vertical velocity null.
* ``detail_cutoff_hz`` 10 Hz and ``impact_cutoff_hz`` 5 Hz: the heel-strike impact is the peak of the
  5-10 Hz band, ``hs_delay_s`` (40 ms) after the contact; toe-off is the first minimum of the 10 Hz signal
  after the foot-flat.
* ``min_step_s`` 0.25 s (at most 240 steps/min), ``max_step_s`` 1.5 s (a longer interval ends a walking
  bout), ``max_prominence_m_s2`` 0.5 m/s^2 (a 1 cm excursion of the centre of mass at 1.6 steps/s already
  gives ~1.5 m/s^2 peak to trough; the floor below it: next item), ``min_step_fraction`` 0.6 (a "step" 40 %
  shorter than the typical one is a second bump of the same step: stride-time CV is 2-4 % in healthy adults,
  Hausdorff 2005).
* Prominence (the foot-flat threshold): ``min(max_prominence_m_s2, max(min_prominence_m_s2,
  prominence_fraction · A))``, ``A`` the walk's recent step amplitude (rise of the 3 Hz signal from the
  trough before each accepted foot-flat, an exponential mean over ``amplitude_steps`` (4) accepted peaks; the
  first accepted peak sets it); before any peak is accepted (the run's start, standing) it is the cap:
  :func:`prominence_threshold`. Defaults: floor 0.25 m/s^2, cap 0.5 m/s^2, fraction 0.25 (on-line algorithm
  version 3). Walkers whose amplitude is at least ``cap / fraction`` (2 m/s^2: brisk walking) keep the
  fixed 0.5 m/s^2 of versions 1-2; slow, short steps (0.30-0.35 m at 70-90 /min, whose 3 Hz first harmonic
  rises 0.3-0.8 m/s^2) get down to the floor: the fixed threshold missed 17-25 % of them, this rule
  -3.1..+0.4 % (``tests/host/gait/test_slow_walking_sim.py``, simulated walkers: there is no such recording).
  History: the rule was first uncapped, ``max(0.25, 0.2 A)``, and the floor also its threshold
  before the first step; the fraction and floor were chosen on simulated walkers (``gaitlog.firmware_sim.world``,
  six random subjects, seed 3, three speeds, 20 m out and back: fraction 0.2 gave step count errors -1..+2
  of 188, 0.15: +2..+3, 0.25: -3..0, 0.3: -7..-4; floor 0.15-0.2 added +2..+9, 0.3 missed 2-4 % of the
  slow walkers). On brisk walking (``A`` 2-6 m/s^2) the uncapped rule raised the threshold to 0.4-1.2
  m/s^2, above the 0.3-0.5 m/s^2 bumps of turns and stops (IPOL: the stopping step missed in 31 of 52
  trials instead of 21; on-line M4 and M5 IQRs 0.099 -> 0.115, 0.175 -> 0.205), hence the cap. Its
  threshold before the first step is the cap, not the floor: with the floor the offline chain found
  foot-flats in the standing 4-5 s before walking in 7 of the 52 IPOL trials (subjects 4 and 9) and in the
  0.4 s weight shift before the first step in 16 more. The fraction 0.25 (of 0.2, 0.25, 0.3) is the best on
  the IPOL step count in both chains (sum of ``|errors|`` over the 52 trials, U-turns included, offline 43 / 41 /
  42, on-line float 58 / 52 / 53; fixed threshold 42 and 52): 0.2 let low-amplitude IPOL subject 3
  (``A`` ~1.5 m/s^2) count secondary bumps 0.41-0.50 m/s^2 prominent between steps; a leave-one-subject-out
  choice by ``gaitlog.host.studies.tuning``'s step-count criterion gave 0.25 in 9 of 9 folds (measured then; it is
  a constant chosen on the IPOL recordings; the slow walkers sit at the floor, most IPOL walking at the
  cap). It was first opt-in (``gaitlog estimate --slow-walking``,
  algorithm version 2): as a default it moved the on-line vs offline M2 median ``|ratio difference|`` on IPOL
  from 0.0087 to 0.0106-0.0110, past the 0.01 the two chains are held to. The cause was in the offline chain: its minimum
  distance ran over every local maximum before the prominence rule, so a weak bump could suppress a
  foot-flat the on-line algorithm confirms (``gaitlog.host.gait.events`` notes 1; IPOL trial 8-2's first step).
  With the distance among prominent peaks only, the rule as default costs nothing measurable on IPOL
  against the fixed threshold (``gaitlog evaluate ipol``: in the scored sections only trial 3-4 moves, by
  one step; offline M2 0.998 / IQR 0.048 and M4 IQR 0.058 unchanged, on-line vs offline M2 0.0097 either
  way, step counts' sum of ``|errors|`` 37 -> 36 offline, 41 -> 40 on-line). What it costs: outside the trial
  boundaries (standing, shuffling and turning before and after the IPOL trials) the foot sensors mark 67
  heel strikes and both rules detect about three times that (``evaluate ipol``: offline 189 -> 202, on-line
  fixed 179 -> 195 steps, fixed threshold -> this rule); on simulated walkers
  the walk's amplitude, remembered through a sitting rest, lets the sit-to-stand before the next walk pass
  as a step (4 times in 6 subjects' 18 rests: heel-strike F1 0.9903 -> 0.98997 on 3 subjects, a strict
  xfail in ``tests/host/studies/test_evaluation_sim.py``). Resetting the threshold to the cap when a bout ends
  removes those but misses a slow walker's next bout start (count -6 %, M3 1.154), so it is not done.
* Stop rule (``stop_prominence_m_s2``; default 0: off since on-line algorithm version 4): the step that brings the
  walker to a stop
  raises the 3 Hz signal less than a walking step, and the full prominence missed it in 25 of the 52 IPOL
  trials. After a bout's last full foot-flat, the first peak within about two steps (the minimum distance
  ``DIST`` to three times it, ``DIST`` being 0.6 of the typical step) that stands out
  by ``stop_prominence_m_s2`` is one more step when no full foot-flat follows within ``max_step``. Chosen
  leave-one-subject-out on the IPOL trials by the step count (``gaitlog.host.studies.tuning``; every fold chose
  0.2 of 0, 0.2, 0.3, 0.4 then): the stopping step was then missed in 15 trials offline (16 on-line). It was the
  default (0.2) up to on-line algorithm version 3. Put through the rule for choices (a constant chosen on recordings
  is kept only when its gain's 95 % subject-bootstrap interval excludes zero), it fails: with short gaps interpolated
  and every step of a trial scored, the folds chose 0.2 in 7 of 9 and the cross-validated gain in mean absolute
  step-count error per trial is -0.06 [-0.15, +0.04] steps offline; the shipped 0.2 in the on-line fixed chain, in-sample,
  -0.09 [-0.24, +0.09] steps, M2 IQR -0.004 [-0.014, +0.009] (``gaitlog evaluate ipol``'s choices). The
  simulated slow walkers' counts and M3 are the same with and without it (both chains, three walkers). So the
  simpler choice stays: no stop rule; the rule remains a parameter (``0.2``: versions 1-3's).
* On-line only: gravity is a causal two-stage exponential mean of time constant ``gravity_tau_s``,
  replacing the offline chain's centred 4 s window (which needs 2 s of future samples). Rule: the smallest
  power-of-two number of samples whose second-order attenuation ``(2 pi f tau)^-2`` at a slow step
  (1.5 Hz) is below 1 %: tau > 1.06 s, so 64 samples = 1.28 s at 50 Hz (an update is then a shift by 6).
  Shorter time constants let the step's own acceleration into the gravity estimate (0.32 s: M2 +3 % on the
  IPOL trials against the offline chain), longer ones follow trunk tilt more slowly (2.56 s: within 0.2 %);
  the rule, not those trials, sets it. The typical step duration is the median of the last
  ``median_steps`` (7) peak intervals; before three are known, the prior ``prior_step_s`` (0.55 s, a
  literature cadence; the offline chain has the whole recording's median instead).
* M4's exponent :data:`M4_EXPONENT` 1/4, Weinberg's (Alvarez eq 4; Weinberg, ADI AN-602), the default of the step
  configuration's ``m4_exponent`` (on-line algorithm version 4; versions 2-3 computed 1/2). It was 1/2, argued
  so: with K fitted on one trial, a range^(1/4) follows a subject's later, longer or shorter
  steps too little: IPOL subject 5 walks its first trial with 38 steps of 0.53 m and its others with 33 of
  0.61 m (-13 %); the fourth root of the range of the 3 Hz vertical acceleration per step moves by -2 %, its
  square root by -4 %. The exponent is a constant chosen from the IPOL recordings, chosen
  leave-one-subject-out by :mod:`gaitlog.host.studies.tuning` (criterion: the IQR of the calibrated M4 distance
  ratio, K from each training subject's first trial, scored on its other trials; candidates 1/4, 3/8, 1/2:
  whole eighths, which the firmware computes with square roots, and at most 1/2 so that the uncalibrated
  record's ``range^p``, in (m/s^2)^p, fits its 0-4 m UQ2.14 length up to a range of 16 m/s^2: 5/8 would
  saturate it from 9.2 m/s^2, 0.94 g, which simulated walking reaches). 1/2 in 8 of 9 folds (3/8 when IPOL
  subject 7 is held out). Put through the rule for choices, 1/2 fails: its gain in IQR of the calibrated M4 ratio
  over 1/4 is +0.021 [-0.009, +0.044] offline (the exponent chosen per fold) and +0.028 [-0.011, +0.057] in the
  on-line fixed chain (in-sample), 95 % subject-bootstrap intervals that include zero, so Weinberg's 1/4 is the
  default again; the exponent stays a parameter of the step configuration (a K file stores the one K was fitted
  with, and the logger computes that one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


__all__ = ["prominence_threshold", "M4_EXPONENT", "m4_exponent_eighths", "EventParameters", "OnlineParameters", "SampleCounts", "samples", "minimum_distance", "amplitude_update",
           "gaussian_radius", "FRACTION_SCALE",
           "SIGMA_S_AT_1HZ"]

#: Gaussian sigma (s) whose -3 dB cut-off is 1 Hz: ``|H(f)| = exp(-(2 pi f sigma)^2 / 2) = 1/sqrt(2)``.
SIGMA_S_AT_1HZ = float(math.sqrt(math.log(2.0)) / (2.0 * math.pi))


def m4_exponent_eighths(exponent: float) -> int:
    """M4's exponent as a whole number of eighths (1..7: what the firmware computes with square roots).

    >>> m4_exponent_eighths(0.5), m4_exponent_eighths(0.375)
    (4, 3)
    """
    e = float(exponent) * 8.0
    if not (math.isfinite(e) and abs(e - round(e)) < 1e-9 and 1 <= round(e) <= 7):
        raise ValueError(f"M4's exponent must be a whole number of eighths in 1/8..7/8, got {exponent!r}")
    return round(e)


#: M4's exponent: ``S = K (a_max - a_min)^M4_EXPONENT`` (module notes): Weinberg's 1/4, the default of the step
#: configuration's ``m4_exponent``.
M4_EXPONENT = 1 / 4
#: ``min_step_fraction`` is applied as the integer ``round(fraction · FRACTION_SCALE)`` (a 3-digit constant).
FRACTION_SCALE = 1000


def samples(duration_s: float, sampling_rate_hz: float) -> int:
    """A duration as a whole number of samples, rounded half up (the one rounding rule of both chains).

    >>> samples(0.25, 50.0), samples(0.03, 50.0), samples(0.01, 50.0)
    (13, 2, 1)
    """
    return int(math.floor(duration_s * sampling_rate_hz + 0.5))


def minimum_distance(typical_twice, min_step, fraction_scaled):
    """Peaks closer than this many samples are one step: ``max(min_step, round_half_up(f · typical))``.

    ``typical_twice`` is twice the typical step duration in samples (an integer: the median of an even
    number of intervals is the mean of the middle two) and ``fraction_scaled`` the fraction out of
    :data:`FRACTION_SCALE`, so the rule is exact integer arithmetic: the same in the on-line algorithm (both
    arithmetics; its kernel registers this function with numba) and in the offline chain (which does not
    import numba).

    >>> minimum_distance(50, 13, 600), minimum_distance(57, 13, 600), minimum_distance(30, 13, 600)
    (15, 17, 13)
    """
    d = (fraction_scaled * typical_twice + FRACTION_SCALE) // (2 * FRACTION_SCALE)
    return d if d > min_step else min_step


@dataclass(frozen=True)
class EventParameters:
    """Rules of the gait events and steps, shared by the on-line and the offline chain (see module notes).

    Attributes
    ----------
    ff_cutoff_hz, detail_cutoff_hz, impact_cutoff_hz
        -3 dB frequencies of the Gaussian low-passes: foot-flat (3 Hz), heel-strike/toe-off detail (10 Hz),
        lower edge of the heel-strike impact band (5 Hz).
    min_step_s, max_step_s
        Shortest step (0.25 s) and longest step inside a walking bout (1.5 s).
    min_prominence_m_s2, max_prominence_m_s2
        The foot-flat prominence's floor and cap (0.25 and 0.5 m/s^2; floor = cap: a fixed threshold, as in
        on-line algorithm versions 1-2; the cap is also the threshold before a step amplitude is known): a
        foot-flat's rise and fall of the 3 Hz signal (module notes).
    hs_search_s, hs_after_s, hs_delay_s
        The impact is searched from ``hs_search_s`` before to ``hs_after_s`` after each foot-flat; the
        heel-strike is ``hs_delay_s`` before the impact.
    to_search_s
        Toe-off: first local minimum of the 10 Hz signal within this long after the foot-flat.
    min_step_fraction
        Peaks closer than this fraction of the typical step duration are one step (the higher is kept).
    prominence_fraction, amplitude_steps
        The prominence's share of the recent step amplitude (0.25; an exponential mean over
        ``amplitude_steps`` peaks, a power of two), clamped to ``[min_prominence_m_s2,
        max_prominence_m_s2]`` (:func:`prominence_threshold`; floor = cap: a fixed threshold).
    stop_prominence_m_s2
        The stop rule (module notes): a bout's weak last step stands out by this much (0, the default: off).
    """

    ff_cutoff_hz: float = 3.0
    detail_cutoff_hz: float = 10.0
    impact_cutoff_hz: float = 5.0
    min_step_s: float = 0.25
    max_step_s: float = 1.5
    min_prominence_m_s2: float = 0.25
    max_prominence_m_s2: float = 0.5
    hs_search_s: float = 0.2
    hs_after_s: float = 0.06
    hs_delay_s: float = 0.04
    to_search_s: float = 0.3
    min_step_fraction: float = 0.6
    prominence_fraction: float = 0.25
    amplitude_steps: int = 4
    stop_prominence_m_s2: float = 0.0

    def __post_init__(self) -> None:
        for name in ("ff_cutoff_hz", "detail_cutoff_hz", "impact_cutoff_hz", "min_step_s", "max_step_s",
                     "min_prominence_m_s2", "max_prominence_m_s2", "min_step_fraction"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        for name in ("hs_search_s", "hs_after_s", "hs_delay_s", "to_search_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {v!r}")
        if not (isinstance(self.prominence_fraction, (int, float)) and 0 <= self.prominence_fraction < 1):
            raise ValueError(f"prominence_fraction must be in [0, 1), got {self.prominence_fraction!r}")
        if self.max_prominence_m_s2 < self.min_prominence_m_s2:
            raise ValueError(f"max_prominence_m_s2 ({self.max_prominence_m_s2}) must be at least "
                             f"min_prominence_m_s2 ({self.min_prominence_m_s2})")
        a = self.amplitude_steps
        if not (isinstance(a, int) and 1 <= a <= 64 and a & (a - 1) == 0):
            raise ValueError(f"amplitude_steps must be a power of two in 1..64, got {a!r}")
        if self.max_step_s <= self.min_step_s:
            raise ValueError(f"max_step_s ({self.max_step_s}) must exceed min_step_s ({self.min_step_s})")
        if not self.impact_cutoff_hz < self.detail_cutoff_hz:
            raise ValueError("impact_cutoff_hz must be below detail_cutoff_hz (the impact band is between them)")

    @property
    def min_step_fraction_scaled(self) -> int:
        """``min_step_fraction`` as an integer out of :data:`FRACTION_SCALE`."""
        return int(round(self.min_step_fraction * FRACTION_SCALE))

    @property
    def amplitude_shift(self) -> int:
        """``log2(amplitude_steps)``: the exponential mean's update is a shift."""
        return int(self.amplitude_steps).bit_length() - 1


def amplitude_update(amplitude, rise, first: bool, shift: int):
    """The step amplitude after an accepted peak that rose by ``rise``: ``rise`` for the first, else the
    exponential mean ``A + (rise - A) / 2**shift`` (the offline chain's float form of the firmware's shift).

    >>> amplitude_update(0.0, 2.0, True, 2), amplitude_update(2.0, 1.0, False, 2)
    (2.0, 1.75)
    """
    return rise if first else amplitude + (rise - amplitude) / float(1 << shift)


def prominence_threshold(amplitude, known: bool, floor, cap, fraction):
    """The foot-flat prominence in force (module notes): ``min(cap, max(floor, fraction · amplitude))``
    once a step amplitude is ``known``, the cap before (the offline chain's float form; the on-line
    kernel's ``_prominence`` computes the same in its arithmetic).

    >>> prominence_threshold(0.0, False, 0.25, 0.5, 0.2), prominence_threshold(1.0, True, 0.25, 0.5, 0.2)
    (0.5, 0.25)
    >>> prominence_threshold(2.0, True, 0.25, 0.5, 0.2), prominence_threshold(4.0, True, 0.25, 0.5, 0.2)
    (0.4, 0.5)
    """
    if not known:
        return cap
    return min(cap, max(floor, fraction * amplitude))


@dataclass(frozen=True)
class OnlineParameters:
    """What the on-line algorithm adds to the shared rules.

    Attributes
    ----------
    gravity_tau_s
        Time constant of each of the two exponential stages of the gravity estimate; rounded to a power of
        two of samples (the update is a shift).
    median_steps
        Number of recent peak intervals whose median is the typical step duration (odd).
    min_gravity_g
        Below this gravity magnitude the vertical direction is not defined (free fall): ``a_v = 0``.
    prior_step_s
        The typical step duration assumed until ``3`` peak intervals are known (a run's first steps): the
        minimum foot-flat distance is then ``min_step_fraction · prior_step_s`` (17 samples, 0.34 s, at
        50 Hz), not ``min_step_s``.
        0.55 s is a cadence of 109 steps/min, the middle of the laboratory normal-walking cadences of adults
        (96-138 steps/min for women, 81-135 for men: Tudor-Locke & Rowe, Sports Med 42, 2012, 381-398; the
        same review's pedestrians walk at 115 steps/min); a literature value, not chosen on IPOL. The offline
        chain needs no prior: it has the whole recording's median.
    """

    gravity_tau_s: float = 1.28
    median_steps: int = 7
    min_gravity_g: float = 0.2
    prior_step_s: float = 0.55

    def __post_init__(self) -> None:
        if not (math.isfinite(self.gravity_tau_s) and self.gravity_tau_s > 0):
            raise ValueError(f"gravity_tau_s must be positive, got {self.gravity_tau_s!r}")
        if not (isinstance(self.median_steps, int) and 3 <= self.median_steps <= 15 and self.median_steps % 2):
            raise ValueError(f"median_steps must be an odd integer in 3..15, got {self.median_steps!r}")
        if not 0 < self.min_gravity_g < 1:
            raise ValueError(f"min_gravity_g must be in (0, 1) g, got {self.min_gravity_g!r}")
        if not (isinstance(self.prior_step_s, (int, float)) and math.isfinite(self.prior_step_s)
                and 0 < self.prior_step_s <= 2.0):
            raise ValueError(f"prior_step_s must be in (0, 2] s, got {self.prior_step_s!r}")


def gaussian_radius(cutoff_hz: float, sampling_rate_hz: float, *, truncate: float = 4.0) -> int:
    """Half-width in samples of the Gaussian whose -3 dB frequency is ``cutoff_hz`` (scipy's
    ``int(truncate · sigma + 0.5)``).

    >>> gaussian_radius(3.0, 50.0), gaussian_radius(10.0, 50.0), gaussian_radius(5.0, 50.0)
    (9, 3, 5)
    """
    sigma = SIGMA_S_AT_1HZ / cutoff_hz * sampling_rate_hz
    return int(truncate * sigma + 0.5)


@dataclass(frozen=True)
class SampleCounts:
    """The parameters as whole numbers of samples at one sampling rate (what the firmware stores).

    Build with :meth:`at`.

    Examples
    --------
    >>> c = SampleCounts.at(EventParameters(), OnlineParameters(), 50.0)
    >>> c.r3, c.r10, c.r5, c.min_step, c.max_step, c.hs_before, c.hs_after, c.hs_delay, c.to_span, c.gravity_shift
    (9, 3, 5, 13, 75, 10, 3, 2, 15, 6)
    >>> c.prior_step_twice, minimum_distance(c.prior_step_twice, c.min_step, c.fraction_scaled)
    (55, 17)
    """

    sampling_rate_hz: float
    r3: int
    r10: int
    r5: int
    min_step: int
    max_step: int
    hs_before: int
    hs_after: int
    hs_delay: int
    to_span: int
    gravity_shift: int
    median_steps: int
    fraction_scaled: int
    prior_step_twice: int

    @classmethod
    def at(cls, events: EventParameters, online: OnlineParameters, sampling_rate_hz: float) -> SampleCounts:
        """The counts at ``sampling_rate_hz``."""
        sampling_rate_hz = float(sampling_rate_hz)
        if not (math.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
            raise ValueError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        return cls(
            sampling_rate_hz,
            gaussian_radius(events.ff_cutoff_hz, sampling_rate_hz),
            gaussian_radius(events.detail_cutoff_hz, sampling_rate_hz),
            gaussian_radius(events.impact_cutoff_hz, sampling_rate_hz),
            max(1, samples(events.min_step_s, sampling_rate_hz)),
            samples(events.max_step_s, sampling_rate_hz),
            samples(events.hs_search_s, sampling_rate_hz),
            samples(events.hs_after_s, sampling_rate_hz),
            samples(events.hs_delay_s, sampling_rate_hz),
            samples(events.to_search_s, sampling_rate_hz),
            max(0, int(round(math.log2(max(online.gravity_tau_s * sampling_rate_hz, 1.0))))),
            online.median_steps,
            events.min_step_fraction_scaled,
            max(1, math.floor(2.0 * online.prior_step_s * sampling_rate_hz + 0.5)),
        )
