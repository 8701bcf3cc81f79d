"""Simulated walkers: anthropometry, gait habits and how the logger sits on their back.

A :class:`Subject` holds everything that makes one person's lower-back acceleration differ from another's
at the same speed. The anthropometric ratios are Winter's (*Biomechanics and Motor Control of Human
Movement*, 4th ed., 2009, Fig. 4.1): greater-trochanter height (the pendulum length ``l`` of Alvarez
eq. 1) 0.530·H, foot length heel to toe 0.152·H; M3's ``S2`` (heel to first metatarsal head, Alvarez's
"foot length") is 0.73 of that (ANSUR, Gordon et al. 1989), 0.111·H. In the ``"v1"`` population step length
and cadence follow the walk ratio (step length / cadence,
nearly constant over ordinary speeds, Sekiya & Nagasaki 1998; equivalently Grieve's step length ∝ v^0.5):
``S = sqrt(60 · WR · v)``, WR ≈ 0.00375·H m per step/min (≈ 0.0066 for H = 1.77 m), drifting per subject
with speed (``walk_ratio_speed_exponent``); the ``"people"`` population (:func:`random_subjects`) draws a
linear cadence-speed law instead, and the trunk motion of real lower-back walking (``_people_overrides``).

Contact timing and shape follow the IPOL lower-back recordings (Voisard et al. 2023: 9 subjects, 52 trials,
1298 straight steps with foot-sensor heel-strike and toe-off, 100 Hz) and the gait literature:

- double support 0.14 s median (IQR 0.11-0.16), 24 % of the step (IQR 21-27 %; per subject 18-29 %), i.e.
  ~12 % of the gait cycle per side (Perry: 10-12 % at preferred speed, longer when slower; the world scales
  it as ``(v / v_pref) ** -0.6``);
- the centre of mass is lowest 40 ms after heel strike (IQR 20-60 ms; 0.27 of double support; peak of the
  3 Hz low-passed vertical acceleration and minimum of its double integral agree) and 100 ms before the
  trailing toe-off (IQR 80-110 ms);
- vertical acceleration (ensemble over all steps): it rises from the single-stance level (-0.17 g) ~100 ms
  *before* heel strike (the trailing leg's push-off), peaks at +0.35 g ~30 ms after heel strike (impact and
  loading), dips to ~0 g ~30 ms before the trailing toe-off (the trailing foot unloads), peaks again at
  +0.17 g ~30 ms after it (the leading leg's loading-response force peak) and falls back to -0.17 g by
  ~120 ms after toe-off; SD 0.19 g per step.

The defaults reproduce these (centre-of-mass valley at ``com_min_fraction`` of double support with a skewed
trough, impact ``heel_strike_delay_s`` after heel strike, unloading dip ``toe_off_lead_s`` before toe-off,
loading-response peak ``loading_response_delay_s`` after it). Anatomical foot-flat (forefoot down) comes
from the literature (~8 % of the gait cycle: 0.65 of double support), after the centre of mass's low point.

The fields that break the estimators' assumptions (so that a per-subject K is genuinely needed):

- ``pendulum_ratio``: the single-stance centre-of-mass arc has radius ``pendulum_ratio · leg_length_m``
  rather than the leg length (stance-knee flexion, foot rocker and pelvic obliquity flatten it — the
  determinants of gait), and that ratio changes with speed (``pendulum_speed_exponent``,
  ``pendulum_speed_curvature``), so a K calibrated at one speed is biased at the others;
- ``double_support_fraction`` and ``com_min_fraction``: how long double support lasts and when the centre
  of mass bottoms out (early in double support, not at foot-flat, where M1 resets its integrals);
- ``sensor_offset_m``: the sensor sits on the skin over L3, behind and above the centre of mass, so trunk
  pitch and roll move it vertically and tangential/centripetal accelerations add to the centre of mass's;
- ``mounting_rotation_deg``: the corset holds the device tilted.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from gaitlog.firmware_sim.world.body_ratios import FOOT_LENGTH_PER_HEIGHT, LEG_LENGTH_PER_HEIGHT
from gaitlog.units import STANDARD_GRAVITY_M_S2


#: Walk ratio per metre of height, m per (steps/min) per m (Sekiya & Nagasaki 1998: WR ≈ 0.0064 in men).
WALK_RATIO_PER_HEIGHT = 0.00375


@dataclass(frozen=True)
class Subject:
    """One simulated walker (all lengths in metres, angles in degrees, times in seconds).

    Attributes
    ----------
    subject_id
        Free label, carried into the truth.
    height_m, leg_length_m, foot_length_m
        Body height, leg length (greater trochanter to floor: the pendulum length ``l``) and foot length
        (heel to first metatarsal head, Alvarez's ``S2``).
    preferred_speed_m_s
        Self-selected walking speed.
    fast_speed_factor, slow_speed_factor
        "Fast" and "slow" excursions walk at these multiples of the preferred speed.
    walk_ratio_m_spm
        Step length / cadence in m per (steps/min); sets the speed -> step length, cadence relation.
    walk_ratio_speed_exponent
        The walk ratio changes with speed as ``(v / v_pref) ** exponent`` (0: Sekiya's invariance; real
        subjects drift a little at the slow and fast ends).
    step_length_cv, step_time_cv
        Step-to-step coefficients of variation of length and duration (independent draws).
    asymmetry
        Relative left/right step-length difference (left steps longer by ``+asymmetry / 2``).
    pendulum_ratio, pendulum_speed_exponent, pendulum_speed_curvature
        Radius of the single-stance centre-of-mass arc over leg length at preferred speed, and how it
        changes with speed: radius ∝ ``(v / v_pref) ** exponent · (1 + curvature · ln(v / v_pref)²)``.
        The curvature term makes the walk most pendulum-like at the preferred speed (Cavagna's pendular
        energy recovery peaks near it) and flatter both slower and faster. The ratio (1.2, SD 0.12) comes
        from the IPOL recordings: there M3 with the paper's inputs (leg 0.530·H, S2 0.111·H) and the
        single-support excursion of the lower back gives 1.02-1.05 times the step length (1047 steps, 9
        subjects; single-support excursion 32 mm, IQR 27-38 mm, at 0.63 m steps); the same measurement
        on the world at preferred speed gives 1.01 with 1.2 (0.91 with the former 1.8).
    double_support_fraction
        Double-support time per step as a fraction of the step time, at preferred speed (it shrinks with
        speed as ``(v / v_pref) ** -0.6``).
    foot_flat_fraction
        Foot-flat of the leading foot, as a fraction of the double support after heel strike.
    com_min_fraction
        When the centre of mass is lowest, in units of the double-support time after heel strike (1 = at
        the trailing foot's toe-off). Real people: ~0.3 (the 3 Hz first harmonic peaks ~40 ms after heel
        strike, ~100 ms before toe-off); the phase skew (``vertical_skew``) moves the measured low point a
        little earlier than this nominal valley.
    peak_fraction
        Where in single stance the centre of mass is highest (fraction of single stance).
    vertical_warp
        Phase warp of the vertical centre-of-mass oscillation (0: a cosine; > 0: a broad crest in single
        stance and a sharp trough in double support, i.e. a sharp positive acceleration peak).
    vertical_skew
        Skew of the vertical phase around the valley (:class:`~gaitlog.firmware_sim.world.gait_cycle.WarpedPhase`):
        the centre of mass decelerates its fall quickly and rises slowly, so the vertical acceleration stays
        above 1 g into early single stance (~80 ms after toe-off in the IPOL recordings).
    double_support_radius_m
        Radius of the concave-up centre-of-mass arc over the double-support travel (Alvarez Fig. 3's
        second pendulum): adds ``d_ds² / (8 r)`` to the step's vertical excursion.
    peak_drop_m
        How much lower than in quiet standing the centre of mass peaks while walking, at preferred speed.
    ap_speed_fluctuation
        Relative forward-speed fluctuation within a step (fastest in double support, slowest at mid-stance).
    ml_sway_m
        Medio-lateral centre-of-mass sway amplitude at stride frequency, at preferred speed.
    trunk_lean_deg, stand_lean_deg
        Mean forward trunk pitch while walking (at preferred speed) and standing.
    pitch_amp_deg, roll_amp_deg, yaw_amp_deg
        Trunk pitch oscillation (step frequency), pelvic obliquity / trunk roll and pelvic rotation (stride
        frequency) amplitudes.
    pitch_phase_rad, roll_phase_rad, yaw_phase_rad, sway_phase_rad
        Phases of those oscillations relative to the gait phase (0 at a left heel strike).
    sensor_offset_m
        Sensor position relative to the centre of mass in trunk axes (forward, left, up).
    mounting_rotation_deg
        Rotation vector (degrees) of the device relative to its nominal mounting on the trunk (see
        :mod:`gaitlog.firmware_sim.world.walking` for the nominal device axes).
    heel_strike_acc_g, heel_strike_ap_acc_g, heel_strike_width_s, heel_strike_delay_s
        Heel-strike transient at the sensor: vertical peak, antero-posterior (braking) peak, in g at
        preferred speed (∝ speed), the Gaussian width, and its delay after heel strike (the lower back
        peaks ~30 ms after initial contact in the IPOL recordings).
    toe_off_acc_g, toe_off_ap_acc_g, toe_off_width_s, toe_off_lead_s
        Unloading of the trailing foot at the end of push-off: drop of the vertical and forward
        accelerations (g, at preferred speed, ∝ speed), Gaussian width, and how long before the trailing
        toe-off it peaks.
    loading_response_acc_g, loading_response_delay_s, loading_response_width_s
        The leading leg's loading-response force peak: vertical rise (g, at preferred speed, ∝ speed), its
        delay after the trailing toe-off and its Gaussian width.
    sit_drop_m
        How far the centre of mass drops when sitting down.
    cadence_law_spm
        ``(c0, c1)``: when set, step length comes from a linear cadence-speed law instead of the walk ratio:
        cadence = ``(c0 + c1 · v) · sqrt(1.72 m / height_m)`` steps/min, step length = ``60 · v / cadence``
        (the linear form of Kirtley, Whittle & Jefferson 1985; the height factor is dynamic similarity at equal
        Froude number, Alexander 1984). Step length is then linear in step *duration* (``60/c1 - c0/c1 · T``
        for H = 1.72 m), which is neither M5's model (linear in step frequency) nor the pendulum's.
    ml_harmonics_m_s2
        Medio-lateral acceleration amplitudes (m/s^2, at preferred speed, ∝ ``sqrt(v / v_pref)``) of the
        trunk's lateral motion at stride harmonics 2, 3, 4, ... (one per entry), on top of the
        stride-frequency sway ``ml_sway_m``. Real lower-back ML acceleration is not a sway: its per-stride
        spectrum is broad (harmonics 1-10 of similar size), the 3rd harmonic is strongest in half the IPOL
        trials (median strongest harmonic 5, odd/even ratio 1.9, RMS 1.3 m/s^2): a lateral push toward the new
        stance foot just after each heel strike, alternating in sign (the odd harmonics).
    ml_even_phases_rad
        Phases of the even ML harmonics (the part repeated every step: the trunk's own asymmetry) relative to
        quadrature with the forward braking (0 or pi: uncorrelated with the antero-posterior acceleration),
        cycled over the even harmonics.
    ap_harmonics_m_s2
        Antero-posterior acceleration amplitudes (m/s^2, at preferred speed, ∝ ``sqrt(v / v_pref)``) at stride
        harmonics 4, 6, 8, ... (step harmonics 2, 3, 4, ...): the braking after each heel strike is sharper
        than the speed fluctuation ``ap_speed_fluctuation`` (real AP spectra keep 0.4-0.8 m/s^2 up to the
        8th stride harmonic).
    ml_step_variability
        Step-to-step variability of the lateral harmonics: their gain is ``exp(N(0, ml_step_variability))``
        at each heel strike (smoothly interpolated), so the lateral acceleration is not strictly periodic.
    envelope_full_at_step
        The periodic trunk motions (sway, harmonics, pitch, roll, yaw) grow from nothing at set-off to full
        amplitude at this heel strike (0: the first; real gait initiation shifts the weight laterally before
        the first step, so the lateral motion is full from the first step, Jian et al. 1993).
    harmonic_lag_s
        The odd ML harmonics peak (toward the new stance foot) and the AP harmonics brake this long after each
        heel strike.
    vertical_asymmetry
        Relative left/right difference of the centre of mass's vertical excursion and of the contact
        transients (left steps deeper and left contacts stronger by ``+vertical_asymmetry / 2``): odd stride
        harmonics in the vertical (and antero-posterior) acceleration.
    step_length_follows_time
        How much of a step's relative duration error its length shares (0: independent; 1: the step's mean
        speed unchanged). People hold their speed from step to step and let step length and step time vary
        together (Dingwell, John & Cusumano 2010, PLoS Comput Biol 6: e1000856); independent errors make every
        step's mean speed jump by several %, a forward acceleration at the odd stride harmonics.
    ap_contact_asymmetry_share, ap_contact_jitter_share
        Shares of the contacts' left/right asymmetry (``vertical_asymmetry``) and of the heel-strike impact's
        contact-to-contact variability (log-SD) that the forward transients keep (1: as the vertical).
    """

    subject_id: str = "S00"
    height_m: float = 1.77
    leg_length_m: float = LEG_LENGTH_PER_HEIGHT * 1.77
    foot_length_m: float = FOOT_LENGTH_PER_HEIGHT * 1.77
    preferred_speed_m_s: float = 1.35
    fast_speed_factor: float = 1.32
    slow_speed_factor: float = 0.70
    walk_ratio_m_spm: float = WALK_RATIO_PER_HEIGHT * 1.77
    walk_ratio_speed_exponent: float = 0.0
    step_length_cv: float = 0.025
    step_time_cv: float = 0.02
    asymmetry: float = 0.01
    pendulum_ratio: float = 1.2
    pendulum_speed_exponent: float = 0.0
    pendulum_speed_curvature: float = 0.6
    double_support_fraction: float = 0.24
    foot_flat_fraction: float = 0.65
    com_min_fraction: float = 0.40
    peak_fraction: float = 0.5
    vertical_warp: float = 0.15
    vertical_skew: float = 0.4
    double_support_radius_m: float = 0.5
    peak_drop_m: float = 0.01
    ap_speed_fluctuation: float = 0.09
    ml_sway_m: float = 0.022
    trunk_lean_deg: float = 4.0
    stand_lean_deg: float = 2.0
    pitch_amp_deg: float = 1.5
    roll_amp_deg: float = 3.0
    yaw_amp_deg: float = 4.0
    pitch_phase_rad: float = 0.8
    roll_phase_rad: float = 0.3
    yaw_phase_rad: float = -1.2
    sway_phase_rad: float = -1.6
    sensor_offset_m: tuple[float, float, float] = (-0.11, 0.0, 0.03)
    mounting_rotation_deg: tuple[float, float, float] = (0.0, 6.0, 2.0)
    heel_strike_acc_g: float = 0.35
    heel_strike_ap_acc_g: float = 0.25
    heel_strike_width_s: float = 0.018
    heel_strike_delay_s: float = 0.03
    toe_off_acc_g: float = 0.25
    toe_off_ap_acc_g: float = 0.10
    toe_off_width_s: float = 0.015
    toe_off_lead_s: float = 0.025
    loading_response_acc_g: float = 0.20
    loading_response_delay_s: float = 0.04
    loading_response_width_s: float = 0.03
    sit_drop_m: float = 0.40
    cadence_law_spm: tuple[float, float] | None = None
    ml_harmonics_m_s2: tuple[float, ...] = ()
    ml_even_phases_rad: tuple[float, ...] = (0.0,)
    ap_harmonics_m_s2: tuple[float, ...] = ()
    harmonic_lag_s: float = 0.05
    ml_step_variability: float = 0.0
    envelope_full_at_step: int = 2
    vertical_asymmetry: float = 0.0
    step_length_follows_time: float = 0.0
    ap_contact_asymmetry_share: float = 1.0
    ap_contact_jitter_share: float = 1.0

    def __post_init__(self) -> None:
        checks = {
            "height_m": (1.0, 2.5),
            "leg_length_m": (0.4, 1.3),
            "foot_length_m": (0.12, 0.40),
            "preferred_speed_m_s": (0.4, 2.2),
            "pendulum_ratio": (0.8, 4.0),
            "double_support_fraction": (0.05, 0.45),
            "foot_flat_fraction": (0.1, 0.95),
            "com_min_fraction": (-0.2, 1.6),
            "peak_fraction": (0.2, 0.8),
        }
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not (lo <= value <= hi):
                raise ValueError(f"Subject.{name} = {value!r} is outside the plausible range [{lo}, {hi}]")
        if not self.slow_speed_factor < 1.0 < self.fast_speed_factor:
            raise ValueError("Subject needs slow_speed_factor < 1 < fast_speed_factor")

    @property
    def com_height_m(self) -> float:
        """Height of the centre of mass in quiet standing (0.56·H, near S2; Winter)."""
        return 0.56 * self.height_m

    def speed_m_s(self, label: str) -> float:
        """Walking speed for an excursion label: ``preferred``, ``fast``, ``slow`` or ``medium``.

        ``medium`` lies halfway between preferred and fast (Alvarez II-C).

        Examples
        --------
        >>> s = Subject(preferred_speed_m_s=1.4, fast_speed_factor=1.3)
        >>> round(s.speed_m_s("medium"), 3)
        1.61
        """
        factors = {
            "preferred": 1.0,
            "fast": self.fast_speed_factor,
            "slow": self.slow_speed_factor,
            "medium": 0.5 * (1.0 + self.fast_speed_factor),
        }
        if label not in factors:
            raise ValueError(f"unknown speed label {label!r}; expected one of {sorted(factors)}")
        return self.preferred_speed_m_s * factors[label]

    def step_length_m(self, speed_m_s: float | np.ndarray) -> float | np.ndarray:
        """Nominal step length at a speed: ``60 · v / cadence(v)`` with :attr:`cadence_law_spm` when set, else
        from the walk ratio: ``S = sqrt(60 · WR · v)``.

        Examples
        --------
        >>> round(float(Subject().step_length_m(1.35)), 3)
        0.733
        >>> round(float(Subject(height_m=1.72, cadence_law_spm=(72.0, 33.0)).step_length_m(1.1)), 3)
        0.609
        """
        v = np.asarray(speed_m_s, dtype=np.float64)
        if self.cadence_law_spm is not None:
            c0, c1 = self.cadence_law_spm
            return 60.0 * v / ((c0 + c1 * v) * np.sqrt(1.72 / self.height_m))
        ratio = self.walk_ratio_m_spm * (v / self.preferred_speed_m_s) ** self.walk_ratio_speed_exponent
        return np.sqrt(60.0 * ratio * v)

    @classmethod
    def from_height(cls, height_m: float, **overrides: object) -> Subject:
        """A subject of the given height with Winter's proportions and population-mean habits.

        Examples
        --------
        >>> s = Subject.from_height(1.80)
        >>> round(s.leg_length_m, 3), round(s.foot_length_m, 3)
        (0.954, 0.2)
        """
        base = dict(
            height_m=height_m,
            leg_length_m=LEG_LENGTH_PER_HEIGHT * height_m,
            foot_length_m=FOOT_LENGTH_PER_HEIGHT * height_m,
            walk_ratio_m_spm=WALK_RATIO_PER_HEIGHT * height_m,
        )
        base.update(overrides)
        return cls(**base)  # type: ignore[arg-type]

    @classmethod
    def random(cls, rng: np.random.Generator, *, subject_id: str = "S00", population: str = "v1",
               ml_push_quantile: float | None = None) -> Subject:
        """Draw one adult from a population.

        ``"v1"`` (default): heights 1.60–1.92 m (cf. Alvarez: 1.68–1.86 m); every habit listed in the class
        docstring is drawn independently around its default, so no two subjects share a step-length
        calibration constant; step length from the walk ratio.

        ``"people"``: the same draws, then (further draws from ``rng``) the trunk motion and gait timing of real
        lower-back walking, see :func:`_people_overrides`; walk it with
        ``WalkPlan(**POPULATION_PLANS["people"])`` (:mod:`gaitlog.firmware_sim.world.walk_plan`).
        ``ml_push_quantile`` (``"people"`` only): the subject's quantile, in (0, 1), of the between-subject
        trait that decides where its lateral spectrum peaks (:func:`ml_peak_pattern`); drawn from ``rng`` when
        None (:func:`random_subjects` stratifies it over the cohort).
        """
        if population not in POPULATIONS:
            raise ValueError(f"unknown population {population!r}; expected one of {POPULATIONS}")
        height = float(np.clip(rng.normal(1.76, 0.07), 1.60, 1.92))

        def around(mean: float, sd: float, lo: float, hi: float) -> float:
            return float(np.clip(rng.normal(mean, sd), lo, hi))

        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(3.0, 15.0)
        kw = dict(
            subject_id=subject_id,
            leg_length_m=height * around(LEG_LENGTH_PER_HEIGHT, 0.012, 0.49, 0.57),
            foot_length_m=height * around(FOOT_LENGTH_PER_HEIGHT, 0.0037, 0.101, 0.121),
            preferred_speed_m_s=float(around(1.35, 0.10, 1.10, 1.60) * np.sqrt(height / 1.76)),
            fast_speed_factor=around(1.32, 0.06, 1.18, 1.45),
            slow_speed_factor=around(0.70, 0.05, 0.58, 0.82),
            walk_ratio_m_spm=height * around(WALK_RATIO_PER_HEIGHT, 0.00025, 0.0031, 0.0044),
            walk_ratio_speed_exponent=around(0.0, 0.12, -0.3, 0.3),
            step_length_cv=around(0.025, 0.006, 0.012, 0.045),
            step_time_cv=around(0.020, 0.005, 0.010, 0.035),
            asymmetry=around(0.0, 0.015, -0.04, 0.04),
            pendulum_ratio=around(1.2, 0.12, 0.95, 1.55),
            pendulum_speed_exponent=around(0.0, 0.2, -0.4, 0.4),
            pendulum_speed_curvature=around(0.6, 0.3, 0.0, 1.5),
            double_support_fraction=around(0.24, 0.035, 0.17, 0.32),
            foot_flat_fraction=around(0.65, 0.08, 0.45, 0.85),
            com_min_fraction=around(0.40, 0.10, 0.0, 0.7),
            peak_fraction=around(0.5, 0.05, 0.38, 0.62),
            vertical_warp=around(0.15, 0.06, 0.0, 0.3),
            vertical_skew=around(0.4, 0.1, 0.15, 0.6),
            double_support_radius_m=around(0.5, 0.12, 0.25, 0.9),
            peak_drop_m=around(0.01, 0.004, 0.0, 0.025),
            ap_speed_fluctuation=around(0.09, 0.02, 0.04, 0.15),
            ml_sway_m=around(0.022, 0.005, 0.010, 0.035),
            trunk_lean_deg=around(4.0, 2.0, -1.0, 10.0),
            stand_lean_deg=around(2.0, 1.5, -2.0, 6.0),
            pitch_amp_deg=around(1.5, 0.5, 0.5, 3.0),
            roll_amp_deg=around(3.0, 1.0, 1.0, 6.0),
            yaw_amp_deg=around(4.0, 1.5, 1.5, 8.0),
            pitch_phase_rad=float(rng.uniform(0.0, 2.0 * np.pi)),
            roll_phase_rad=float(rng.uniform(-0.5, 0.8)),
            yaw_phase_rad=float(rng.uniform(-1.8, -0.6)),
            sway_phase_rad=float(rng.uniform(-2.0, -1.2)),
            sensor_offset_m=(around(-0.11, 0.02, -0.16, -0.07), around(0.0, 0.01, -0.02, 0.02),
                             around(0.03, 0.03, -0.05, 0.10)),
            mounting_rotation_deg=tuple(float(a) for a in axis * angle),
            heel_strike_acc_g=around(0.35, 0.1, 0.15, 0.6),
            heel_strike_ap_acc_g=around(0.25, 0.08, 0.1, 0.45),
            heel_strike_width_s=around(0.018, 0.003, 0.012, 0.025),
            heel_strike_delay_s=around(0.03, 0.008, 0.015, 0.045),
            toe_off_acc_g=around(0.25, 0.08, 0.08, 0.45),
            toe_off_ap_acc_g=around(0.10, 0.04, 0.03, 0.2),
            toe_off_width_s=around(0.015, 0.003, 0.01, 0.022),
            toe_off_lead_s=around(0.025, 0.008, 0.010, 0.040),
            loading_response_acc_g=around(0.20, 0.07, 0.05, 0.4),
            loading_response_delay_s=around(0.04, 0.01, 0.02, 0.06),
            loading_response_width_s=around(0.03, 0.005, 0.02, 0.04),
        )
        if population == "people":
            height, over = _people_overrides(rng, height, kw, ml_push_quantile)
            kw.update(over)
        return cls.from_height(height, **kw)

    @property
    def preferred_stride_rate_rad_s(self) -> float:
        """Angular frequency of the stride (rad/s) at the preferred speed: ``pi / step duration``."""
        v = self.preferred_speed_m_s
        return float(np.pi * v / self.step_length_m(v))

    def as_dict(self) -> dict:
        """Plain-Python dictionary of the parameters (for truth and CSV metadata)."""
        return dataclasses.asdict(self)


#: Populations of :meth:`Subject.random` and :func:`random_subjects` (with their walk habits in
#: :data:`gaitlog.firmware_sim.world.walk_plan.POPULATION_PLANS`).
POPULATIONS = ("v1", "people")


#: Lateral acceleration of the ``"people"`` population's trunk at stride harmonics: the step-related lateral
#: push at harmonics 3, 5, 7, 9 relative to the 3rd, and the part repeated every step (harmonics 2, 4, ..., 10,
#: m/s^2 at preferred speed, median subject). With the sway these give the IPOL trials' RMS ML 1.3 m/s^2 and
#: odd/even ratio 1.9, and the per-stride strongest harmonic 5 (median; 3-7).
ML_PUSH_HARMONICS = (1.0, 0.9, 1.0, 0.8)
ML_EVEN_HARMONICS_M_S2 = (0.3, 0.24, 0.33, 0.29, 0.29)
#: Where the medio-lateral spectrum of the lower back peaks: at the stride frequency (the sway: the centre of
#: mass moving over each stance foot, with the trunk's roll bringing gravity in), at the step frequency (the part
#: repeated every step) or at the 3rd stride harmonic (the push toward the new stance foot just after each heel
#: strike, a sharp lateral peak of the lower-trunk acceleration, Zijlstra & Hof 2003). Shares of the IPOL trials
#: (23, 3 and 26 of 52 trials; a trait with within-subject scatter: of 9 subjects 2 always at 1x, 2 always at 3x,
#: 5 mixed, faster trials nearer 3x as the lateral sway shrinks with speed, Orendurff et al. 2004). A subject's
#: quantile ``u`` of this trait (:func:`_stratified_quantiles`) picks the pattern: sway-led below the first
#: share, step-led below the first two, push-led above.
ML_PEAK_SHARES = (23 / 52, 3 / 52, 26 / 52)
#: Per pattern: the 3rd stride harmonic over the 1st (h3/h1; median, log-SD, lowest, highest), drawn per subject.
#: The spectrum (summed over a trial, stride-to-stride jitter widening the higher harmonics) peaked at the
#: stride frequency for every simulated sway-led subject (h3/h1 <= 0.85) and at the 3rd harmonic for most
#: push-led ones (h3/h1 >= 1.3; 1 or 2 of 20 peak at the step frequency instead, as the IPOL trials' few do,
#: seeds 0-7); the bounds keep each pattern clear of the threshold between.
ML_PUSH_RATIO = ((0.6, 0.2, 0.35, 0.85), (0.7, 0.1, 0.5, 0.85), (1.6, 0.25, 1.3, 2.6))
#: Step-led pattern: the 2nd stride harmonic (step frequency) over the 1st. The IPOL trials that peak at the step
#: frequency keep an odd/even ratio above 1 (1.4): one even harmonic stands out, not all.
ML_STEP_RATIO = 1.25
#: Other patterns: the 2nd stride harmonic at most this fraction of the pattern's peak harmonic (the trunk's
#: other step-periodic motions add to it at the sensor).
ML_STEP_CAP = 0.25
#: Median and between-subject log-SD of the ``"people"`` population's lateral acceleration amplitude (its RMS
#: over the stride harmonics at preferred speed, m/s^2): the IPOL trials' RMS ML 1.28 m/s^2 [0.92, 1.71]
#: (median [5, 95 %], step-to-step gain and transients included), the same whichever harmonic peaks.
ML_RMS_M_S2 = 1.38
ML_RMS_LOG_SD = 0.12


def ml_peak_pattern(quantile: float) -> int:
    """The lateral pattern (0 sway-led, 1 step-led, 2 push-led: where the ML spectrum peaks, 1x, 2x or 3x the
    stride frequency) of the subject at ``quantile`` of the trait (:data:`ML_PEAK_SHARES`).

    Examples
    --------
    >>> [ml_peak_pattern(u) for u in (0.05, 0.45, 0.55)]
    [0, 1, 2]
    """
    if not 0.0 < quantile < 1.0:
        raise ValueError(f"ml_push_quantile must lie in (0, 1), got {quantile!r}")
    return int(np.searchsorted(np.cumsum(ML_PEAK_SHARES)[:-1], quantile, side="right"))


def stride_lateral_acc_m_s2(subject: Subject) -> float:
    """Amplitude of the medio-lateral acceleration at the sensor at the stride frequency (m/s^2, preferred speed,
    small angles): the centre of mass's sway, gravity brought in by the trunk's roll, and the lever arm of the
    sensor behind (yaw) and above (roll) the centre of mass, added as phasors of the gait phase.

    Examples
    --------
    >>> round(stride_lateral_acc_m_s2(Subject(ml_sway_m=0.01, roll_amp_deg=0.0, yaw_amp_deg=0.0)), 3)
    0.335
    """
    w = subject.preferred_stride_rate_rad_s
    fwd, _, up = subject.sensor_offset_m
    roll = np.deg2rad(subject.roll_amp_deg) * np.exp(1j * subject.roll_phase_rad)
    phasor = (w**2 * (subject.ml_sway_m * np.exp(1j * subject.sway_phase_rad)
                      + fwd * np.deg2rad(subject.yaw_amp_deg) * np.exp(1j * subject.yaw_phase_rad) - up * roll)
              - STANDARD_GRAVITY_M_S2 * roll)
    return float(abs(phasor))


def _sway_gain(subject: Subject, stride_acc_m_s2: float) -> float:
    """Factor on ``subject``'s centre-of-mass sway and roll (its yaw kept) that makes its stride-frequency lateral
    acceleration (:func:`stride_lateral_acc_m_s2`) ``stride_acc_m_s2``, or the nearest to it (>= 0).

    Examples
    --------
    >>> s = Subject(ml_sway_m=0.01, roll_amp_deg=2.0, yaw_amp_deg=3.0)
    >>> g = _sway_gain(s, 1.0)
    >>> round(stride_lateral_acc_m_s2(dataclasses.replace(s, ml_sway_m=0.01 * g, roll_amp_deg=2.0 * g)), 6)
    1.0
    """
    full = stride_lateral_acc_m_s2(subject)
    yaw = stride_lateral_acc_m_s2(dataclasses.replace(subject, ml_sway_m=0.0, roll_amp_deg=0.0))
    rest = stride_lateral_acc_m_s2(dataclasses.replace(subject, yaw_amp_deg=0.0))
    if rest == 0.0:
        return 1.0
    cross = 0.5 * (full**2 - rest**2 - yaw**2)   # Re(conj(P) Y): |c P + Y|^2 = c^2 |P|^2 + 2 c cross + |Y|^2
    disc = cross**2 - rest**2 * (yaw**2 - stride_acc_m_s2**2)
    c = (-cross + np.sqrt(disc)) / rest**2 if disc >= 0.0 else -cross / rest**2
    return float(max(c, 0.0))


def _people_overrides(rng: np.random.Generator, height_v1: float, kw: dict,
                      ml_push_quantile: float | None = None) -> tuple[float, dict]:
    """Height and habits of the ``"people"`` population (drawn from ``rng`` after the ``"v1"`` draws).

    Sources, and what was tuned to the real IPOL lower-back trials (Voisard et al. 2023, 52 trials of 9
    subjects, statistics of ``../shared/tools/walking_stats.py``; never to any estimator's results):

    - height: mixed-sex adults, N(1.71 m, 0.09 m) (European adult means ~1.77 m men, ~1.64 m women,
      NCD-RisC 2016); leg and foot keep their drawn fractions of height;
    - preferred speed: N(1.20, 0.12) m/s x sqrt(H / 1.72 m) (dynamic similarity): below Bohannon 1997's
      comfortable speeds (1.3-1.46 m/s, adults 20-79, on a walkway with a rolling start) and chosen so that
      10 m trials from standstill average ~1.0 m/s as the IPOL trials do;
    - cadence: linear in speed (Kirtley et al. 1985), ``(c0 + c1 v) sqrt(1.72/H)``, c0 ~ N(72, 5),
      c1 ~ N(33, 4) steps/min per m/s (IPOL: 108 steps/min at ~1.1 m/s steady; ~115 at 1.35 m/s as in
      the literature's preferred-speed cadences); step length = speed / cadence, so it is not the walk ratio
      law (M5's model) and each subject has its own slope;
    - step-time CV ~ N(0.036, 0.008): above the ~2 % stride-time CV of healthy adults on long walks
      (Hausdorff et al. 1996) as the IPOL 10 m trials' step-duration CV (0.038) is; step length follows
      step time (:attr:`Subject.step_length_follows_time`, Dingwell et al. 2010);
    - trunk harmonics tuned to IPOL (RMS ML 1.3 m/s^2 with the 3rd stride harmonic strongest in half the
      trials; RMS AP 1.65 m/s^2; harmonic ratios V 4.2, AP 3.4, ML 1.9 (Moe-Nilssen & Helbostad 2004 report
      the same order for healthy adults at L3): the lateral pattern and total (:data:`ML_PEAK_SHARES`,
      :data:`ML_RMS_M_S2`), ML stride harmonics 2-10, a larger forward speed fluctuation and a left/right
      vertical asymmetry, each drawn per subject.
    """
    def around(mean: float, sd: float, lo: float, hi: float) -> float:
        return float(np.clip(rng.normal(mean, sd), lo, hi))

    height = around(1.71, 0.09, 1.50, 1.95)
    speed = around(1.20, 0.12, 0.9, 1.55) * float(np.sqrt(height / 1.72))
    # trunk accelerations rise with walking speed in every direction (Menz, Lord & Fitzpatrick 2003) and a
    # subject's AP and ML accelerations go together (IPOL: log RMS AP and ML correlate 0.6 over trials; their
    # ratio's log-SD is 0.19): a shared vigour factor, then the lateral total's own scatter
    vigour = float(np.exp(rng.normal(0.0, 0.12)))
    ml_rms = ML_RMS_M_S2 * vigour * speed / 1.2 * float(np.exp(rng.normal(0.0, ML_RMS_LOG_SD)))
    pattern = ml_peak_pattern(float(rng.uniform(0.0005, 0.9995)) if ml_push_quantile is None
                              else float(ml_push_quantile))
    median, log_sd, lo, hi = ML_PUSH_RATIO[pattern]
    push = float(np.clip(median * np.exp(rng.normal(0.0, log_sd)), lo, hi))
    push_shape = (1.0,) + tuple(a * float(np.exp(rng.normal(0.0, 0.15))) for a in ML_PUSH_HARMONICS[1:])
    even_shape = [a * ml_rms / ML_RMS_M_S2 * float(np.exp(rng.normal(0.0, 0.3))) for a in ML_EVEN_HARMONICS_M_S2]
    scale = height / height_v1
    over = dict(
        leg_length_m=kw["leg_length_m"] * scale,
        foot_length_m=kw["foot_length_m"] * scale,
        preferred_speed_m_s=speed,
        cadence_law_spm=(around(72.0, 5.0, 58.0, 86.0), around(33.0, 4.0, 22.0, 44.0)),
        step_time_cv=around(0.036, 0.008, 0.015, 0.055),
        ap_speed_fluctuation=around(0.105, 0.025, 0.05, 0.17),
        ml_sway_m=around(0.012, 0.003, 0.005, 0.02),
        ml_step_variability=around(0.3, 0.08, 0.1, 0.5),
        envelope_full_at_step=0,
        # walking lean close to standing lean: the IPOL first seconds of walking show no large
        # gravity leak into AP (trunk ~1 deg more forward when walking)
        trunk_lean_deg=kw["stand_lean_deg"] + around(1.0, 1.0, -1.0, 3.0),
        # heel-strike impact 0.8 x the v1 draw: the IPOL per-step vertical peak-to-peak (8.3 m/s^2 median)
        heel_strike_acc_g=0.8 * kw["heel_strike_acc_g"],
        # even lateral harmonics near quadrature with the forward ones (the IPOL principal axes lie within ~6 deg
        # of the periodicity axes: AP and ML nearly uncorrelated)
        ml_even_phases_rad=tuple(float(np.pi * rng.integers(2) + rng.normal(0.0, 0.05)) for _ in range(4)),
        ap_harmonics_m_s2=tuple(a * vigour * float(np.exp(rng.normal(0.0, 0.3))) for a in (0.7, 0.9, 0.45)),
        harmonic_lag_s=around(0.05, 0.02, 0.0, 0.1),
        vertical_asymmetry=around(0.0, 0.4, -0.7, 0.7),
        # tuned to the IPOL forward even/odd ratio 3.4 (a fully varying or asymmetric braking peak and steps
        # of independent length and time leave it near 2.5): see the fields' descriptions
        step_length_follows_time=0.8,
        ap_contact_asymmetry_share=0.4,
        ap_contact_jitter_share=0.5,
    )
    # The lateral total is the subject's own (ml_rms): a stronger push comes with less sway, not more lateral
    # motion (in the IPOL trials RMS ML is the same whichever harmonic peaks), so the sway's three sources
    # that grow with it (centre of mass, roll; not the pelvic yaw, which turns forward acceleration into
    # lateral) are scaled together to the stride-harmonic amplitude h1 that leaves the total
    # at ml_rms; stride harmonics 2, 3, ..., 10 follow, even and odd (the push) interleaved.
    odd = [push * a for a in push_shape]
    step = ML_STEP_RATIO if pattern == 1 else 0.0
    rest = sum(a * a for a in even_shape[1:]) + (0.0 if step else even_shape[0] ** 2)
    h1 = float(np.sqrt(max(2.0 * ml_rms**2 - rest, 0.1 * ml_rms**2) / (1.0 + sum(a * a for a in odd) + step**2)))
    # the step-frequency harmonic kept below the pattern's peak (half of it) unless it is the peak
    even_shape[0] = step * h1 if step else min(even_shape[0], ML_STEP_CAP * h1 * max(1.0, push))
    gain = _sway_gain(Subject.from_height(height, **{**kw, **over}), h1)
    over.update(ml_sway_m=over["ml_sway_m"] * gain, roll_amp_deg=kw["roll_amp_deg"] * gain)
    over["ml_harmonics_m_s2"] = tuple(even_shape[i // 2] if i % 2 == 0 else h1 * odd[i // 2]
                                      for i in range(len(even_shape) + len(push_shape)))
    return height, over


def random_subjects(n: int, *, seed: int = 0, population: str = "v1") -> list[Subject]:
    """``n`` subjects drawn from ``population`` (:meth:`Subject.random`) with a seeded generator.

    The same ``(n, seed)`` always gives the same subjects; subject ``i`` does not depend on ``n``.

    Examples
    --------
    >>> a = random_subjects(3, seed=7)
    >>> [s.subject_id for s in a]
    ['S00', 'S01', 'S02']
    >>> random_subjects(2, seed=7)[1] == a[1]
    True
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    seeds = np.random.SeedSequence(seed).spawn(n)
    push = _stratified_quantiles(n, seed) if population == "people" else [None] * n
    return [Subject.random(np.random.default_rng(s), subject_id=f"S{i:02d}", population=population,
                           ml_push_quantile=u)
            for i, (s, u) in enumerate(zip(seeds, push))]


#: Cohort block of :func:`_stratified_quantiles`.
STRATUM_BLOCK = 10


def _stratified_quantiles(n: int, seed: int) -> list[float]:
    """Quantiles of a between-subject trait for a cohort of ``n``, stratified: each block of
    :data:`STRATUM_BLOCK` consecutive subjects holds one subject per decile (at its centre, in a seeded random
    order), so subject ``i`` depends only on ``(seed, i)`` and a cohort of 10, 20, ... spans the
    distribution as a designed sample does rather than as a lucky draw.

    Used for the lateral pattern of the ``"people"`` population (:func:`ml_peak_pattern`): the medio-lateral
    spectral peak is bimodal (1x or 3x stride frequency, rarely 2x), so the share of a small independent cohort
    at each mode, and hence its median, is a coin toss (20 trials resampled from the 52 real ones put their
    median within ±20 % of the real median only 30 % of the time); stratifying the trait that decides it gives
    each block of 10 the real shares to the nearest subject (4 at 1x, 1 at 2x, 5 at 3x) and removes that
    sampling luck, not the subject-to-subject variability within each pattern.

    Examples
    --------
    >>> u = _stratified_quantiles(20, seed=3)
    >>> sorted(int(10 * x) for x in u[:10]) == list(range(10)), _stratified_quantiles(12, 3) == u[:12]
    (True, True)
    >>> sorted(ml_peak_pattern(x) for x in u[:10])
    [0, 0, 0, 0, 1, 2, 2, 2, 2, 2]
    """
    out: list[float] = []
    for block in range(-(-n // STRATUM_BLOCK)):
        rng = np.random.default_rng(np.random.SeedSequence([seed, block, 14]))
        u = (rng.permutation(STRATUM_BLOCK) + 0.5) / STRATUM_BLOCK
        out.extend(float(x) for x in u)
    return out[:n]
