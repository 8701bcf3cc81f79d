"""The walking protocol of Alvarez et al. (2006), section II-C, as data.

Subjects walk a 100 m corridor out and back (one *excursion*, 200 m) four times: at preferred, fast, slow
and medium speed (medium = halfway between preferred and fast), resting (sitting or standing) between
excursions; laps are timed every 20 m. The first 10 m of each excursion are gait initiation and
acceleration and are discarded by the paper, so the default lap marks sit at 10, 30, ..., 190 m along the
corridor, plus a mark when the walker sets off (0 m) and when they stop (200 m): nine full 20 m sections
per excursion, the fifth containing the turn.

The paper's rests last five minutes; the default here is 60 s so that the whole protocol (≈ 16 min)
fits in the logger's 64K samples (21.8 min at 50 Hz). Set ``rest_s=300`` for the paper's.
"""

from __future__ import annotations

from dataclasses import dataclass

SPEED_LABELS = ("preferred", "fast", "slow", "medium")

#: Walk habits of each population of :func:`firmware_sim.world.subject.random_subjects` (WalkPlan fields).
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
        if self.rest_s < 2.0 * self.sit_transition_s + 1.0:
            raise ValueError(f"rest_s = {self.rest_s} s is too short for two {self.sit_transition_s} s "
                             "posture transitions")
        marks = self.lap_marks_m
        total = self.excursion_distance_m
        if any(b <= a for a, b in zip(marks, marks[1:])) or (marks and (marks[0] < 0 or marks[-1] > total)):
            raise ValueError(f"lap_marks_m must increase within [0, {total}] m, got {marks}")
        if self.turn_radius_m <= 0.05 or self.turn_radius_m > 0.2 * self.corridor_length_m:
            raise ValueError(f"turn_radius_m = {self.turn_radius_m} is implausible")
        if not 0.2 <= self.turn_speed_factor <= 1.0:
            raise ValueError(f"turn_speed_factor must be in [0.2, 1], got {self.turn_speed_factor}")

    @property
    def excursion_distance_m(self) -> float:
        """Corridor distance of one excursion (out and back)."""
        return 2.0 * self.corridor_length_m

    def rest_posture(self, index: int) -> str:
        """Posture of rest ``index`` (0-based), cycling through ``rest_postures``."""
        return self.rest_postures[index % len(self.rest_postures)]
