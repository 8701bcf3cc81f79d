"""The walking protocol of Alvarez et al. (2006), section II-C, as data.

Subjects walk a 100 m corridor out and back (one *excursion*, 200 m) four times: at preferred, fast, slow
and medium speed (medium = halfway between preferred and fast), resting (sitting or standing) between
excursions; laps are timed every 20 m. The first 10 m of each excursion are gait initiation and
acceleration and are discarded by the paper, so the default lap marks sit at 10, 30, ..., 190 m along the
corridor, plus a mark when the walker sets off (0 m) and when they stop (200 m): nine full 20 m sections
per excursion, the fifth containing the turn.

The paper's rests last five minutes. Its logger holds 64K samples (21.8 min at 50 Hz), and four excursions
(≈ 12-14 min of walking) plus three 5-minute rests (15 min) do not fit in it with the logger running, so the
paper's logger cannot have been logging through the rests: :meth:`WalkPlan.paper` (``gaitlog evaluate sim``'s
default) STOPs the logger at the end of each excursion and STARTs it again before the next
(``logger_runs="per-excursion"``: four logging runs in one memory, each opened by a SESSION_START sample), the
rests five minutes. The dataclass default (used by the comparisons and sweeps, which render the walk on the
sensor's fine grid) keeps 60 s rests and one continuous run (≈ 16 min, which fits).
"""

from __future__ import annotations

from dataclasses import dataclass

SPEED_LABELS = ("preferred", "fast", "slow", "medium")

#: Alvarez et al. II-C: "to walk freely or to rest on a chair between different excursions for a lapse of five
#: minutes".
PAPER_REST_S = 300.0
#: Alvarez et al. II-A: "four adult men, ages 32 to 38. Height of subjects varied from 168 to 186 cm".
PAPER_HEIGHTS_M = (1.68, 1.86)
#: How the logger runs over the protocol: one run through the rests, or STOP/START around each excursion.
LOGGER_RUNS = ("continuous", "per-excursion")

#: Walk habits of each population of :func:`gaitlog.firmware_sim.world.subject.random_subjects` (WalkPlan fields).
#: ``"people"``: tuned to the IPOL lower-back trials' U-turn duration (1.6 s median), step-time variability
#: and the little forward acceleration left after the first toe-off: 1.2 s from set-off to the first heel
#: strike, the centre of mass close to its speed by then and steady within ~2 m, i.e. 2-3 steps (Brenière &
#: Do 1986: close to steady speed at the end of the first step; Jian et al. 1993), a tight turn (centre-of-mass
#: path radius 0.3 m) slowing to ~0.45 of the speed from ~1.6 m before its apex.
POPULATION_PLANS: dict[str, dict[str, float]] = {
    "v1": {},
    "people": dict(initiation_distance_m=2.0, initiation_speed_deficit=0.15, initiation_time_s=1.2,
                   termination_distance_m=2.0, turn_radius_m=0.3, turn_speed_factor=0.45, turn_slowdown_m=1.6),
}


@dataclass(frozen=True)
class WalkPlan:
    """Parameters of the corridor protocol (lengths in m, times in s).

    Attributes
    ----------
    corridor_length_m
        One-way corridor length; an excursion is out and back (``2 · corridor_length_m``).
    speeds
        Speed label of each excursion, in order (see :meth:`Subject.speed_m_s`).
    rest_s
        Duration of each rest between excursions (including the sit-down/stand-up transitions).
    rest_postures
        ``"sitting"`` or ``"standing"`` for each rest (cycled when shorter than the number of rests).
    initial_stand_s, final_stand_s
        Quiet standing before the first and after the last excursion.
    lap_marks_m
        Corridor distances (from the excursion's start line) at which the lap button is pressed.
    initiation_distance_m, initiation_speed_deficit
        Gait initiation: speed rises as ``1 - initiation_speed_deficit·exp(-d / (initiation_distance_m / 4.6))``
        over the first metres, reaching 99 % of the excursion's speed at this distance.
    initiation_time_s
        From setting off (the centre of mass starts moving) to the first heel strike.
    termination_distance_m
        Over this last stretch the walker slows down before stopping at the line.
    turn_radius_m
        Radius of the 180° turn at the far end (the centre-of-mass path is a smooth turn of length
        ``pi · turn_radius_m``, its apex at ``corridor_length_m``).
    turn_speed_factor
        Speed in the turn relative to the excursion's speed; the slow-down spans ±``turn_slowdown_m``.
    sit_transition_s
        Duration of a sit-down or a stand-up.
    logger_runs
        ``"continuous"``: the logger is started before the first excursion and stopped after the last (one
        run, the rests included); ``"per-excursion"``: it is STARTed ``run_lead_s`` before each set-off and
        STOPped ``run_tail_s`` after each stop (one run per excursion; the rests are not logged).
    run_lead_s, run_tail_s
        Quiet standing logged before each set-off and after each stop (``"per-excursion"``; at most the
        standing or rest time there is). The walker is on their feet at the start line for the last
        ``run_lead_s`` of each rest (the logger is STARTed there, then the walker is told to go).
    """

    corridor_length_m: float = 100.0
    speeds: tuple[str, ...] = SPEED_LABELS
    rest_s: float = 60.0
    rest_postures: tuple[str, ...] = ("sitting", "standing", "sitting")
    initial_stand_s: float = 10.0
    final_stand_s: float = 5.0
    lap_marks_m: tuple[float, ...] = (0.0, 10.0, 30.0, 50.0, 70.0, 90.0, 110.0, 130.0, 150.0, 170.0, 190.0,
                                      200.0)
    initiation_distance_m: float = 10.0
    initiation_speed_deficit: float = 0.6
    initiation_time_s: float = 0.8
    termination_distance_m: float = 3.0
    turn_radius_m: float = 0.5
    turn_speed_factor: float = 0.45
    turn_slowdown_m: float = 2.5
    sit_transition_s: float = 2.5
    logger_runs: str = "continuous"
    run_lead_s: float = 5.0
    run_tail_s: float = 3.0

    @classmethod
    def paper(cls, **overrides: float | str | tuple) -> WalkPlan:
        """The protocol as Alvarez et al. ran it: 5-minute rests (:data:`PAPER_REST_S`) with the logger
        stopped (one logging run per excursion); ``overrides`` (e.g. a population's walk habits,
        :data:`POPULATION_PLANS`) replace any field.

        Examples
        --------
        >>> p = WalkPlan.paper(turn_radius_m=0.3)
        >>> p.rest_s, p.logger_runs, p.speeds
        (300.0, 'per-excursion', ('preferred', 'fast', 'slow', 'medium'))
        """
        kw: dict = {"rest_s": PAPER_REST_S, "logger_runs": "per-excursion"}
        kw.update(overrides)
        return cls(**kw)

    def __post_init__(self) -> None:
        if self.corridor_length_m < 10.0:
            raise ValueError(f"corridor_length_m must be >= 10 m, got {self.corridor_length_m}")
        if not self.speeds:
            raise ValueError("WalkPlan.speeds is empty")
        for label in self.speeds:
            if label not in SPEED_LABELS:
                raise ValueError(f"unknown speed label {label!r}; expected one of {SPEED_LABELS}")
        for p in self.rest_postures:
            if p not in ("sitting", "standing"):
                raise ValueError(f"rest posture must be 'sitting' or 'standing', got {p!r}")
        if len(self.speeds) > 1 and not self.rest_postures:
            raise ValueError("rest_postures is empty but the protocol has rests")
        if self.rest_s - (self.run_lead_s if self.logger_runs == "per-excursion" else 0.0) < (
                2.0 * self.sit_transition_s + 1.0):
            raise ValueError(f"rest_s = {self.rest_s} s is too short for two {self.sit_transition_s} s "
                             "posture transitions")
        marks = self.lap_marks_m
        total = self.excursion_distance_m
        if any(b <= a for a, b in zip(marks, marks[1:])) or (marks and (marks[0] < 0 or marks[-1] > total)):
            raise ValueError(f"lap_marks_m must increase within [0, {total}] m, got {marks}")
        if self.turn_radius_m <= 0.05 or self.turn_radius_m > 0.2 * self.corridor_length_m:
            raise ValueError(f"turn_radius_m = {self.turn_radius_m} is implausible")
        if self.logger_runs not in LOGGER_RUNS:
            raise ValueError(f"logger_runs must be one of {LOGGER_RUNS}, got {self.logger_runs!r}")
        if self.run_lead_s < 0 or self.run_tail_s < 0:
            raise ValueError(f"run_lead_s and run_tail_s must be >= 0, got {self.run_lead_s}, {self.run_tail_s}")
        if not 0.2 <= self.turn_speed_factor <= 1.0:
            raise ValueError(f"turn_speed_factor must be in [0.2, 1], got {self.turn_speed_factor}")

    @property
    def excursion_distance_m(self) -> float:
        """Corridor distance of one excursion (out and back)."""
        return 2.0 * self.corridor_length_m

    def rest_posture(self, index: int) -> str:
        """Posture of rest ``index`` (0-based), cycling through ``rest_postures``."""
        return self.rest_postures[index % len(self.rest_postures)]
