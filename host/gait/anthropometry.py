"""Leg and foot length from body height when they were not measured.

Segment lengths as fractions of body height H from Winter, *Biomechanics and Motor Control of Human
Movement* (4th ed., 2009, Fig. 4.1, after Drillis & Contini 1966):

* leg length (greater trochanter to floor, the pendulum length of M1-M3): ``0.530 H``;
* foot length heel to toe: ``0.152 H``.

Alvarez et al. define M3's double-support constant S2 as the foot length "from the first metatarsal head
to the calcaneal tuberosity" (heel to ball of the foot), not heel to toe. That *ball-of-foot length* is
0.73 of the heel-to-toe length in the US Army anthropometric survey (ANSUR, Gordon et al. 1989: means
197/270 mm in men, 179/244 mm in women), so the ``foot_length_m`` used by M3 is estimated as
``0.73 * 0.152 H = 0.111 H``. A measured ``foot_length_m`` must be measured the paper's way (heel to first
metatarsal head).

What this means for M3, the estimator without K: ``S = 2 sqrt(2 l h1 - h1^2) + S2`` (Alvarez eq. 3) with
``l = 0.530 H`` and ``S2 = 0.111 H`` scales roughly as ``sqrt(H)`` for its pendulum part and as ``H`` for its
double-support part, so a height wrong by 10 % moves M3's step lengths by 5-10 %. The height is therefore
never assumed silently: :func:`choose_lengths` says where the lengths came from (``source``, one of
:data:`LENGTH_SOURCES`, written as a column by the commands) and, when nothing about the wearer is known,
that a :data:`DEFAULT_HEIGHT_M` adult was assumed (``assumed``; the commands warn on stderr). ``gaitlog
evaluate ipol`` reports M3 both with each subject's height and with that assumed height for everyone.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

from gaitlog.firmware_sim.world.body_ratios import (
    BALL_OF_FOOT_PER_FOOT_LENGTH,
    FOOT_LENGTH_PER_HEIGHT,
    HEEL_TOE_LENGTH_PER_HEIGHT,
    LEG_LENGTH_PER_HEIGHT,
)
from gaitlog.host.errors import HostError

__all__ = ["ANATOMY_RANGES_M", "BALL_OF_FOOT_PER_FOOT_LENGTH", "DEFAULT_HEIGHT_M", "FOOT_LENGTH_PER_HEIGHT",
           "HEEL_TOE_LENGTH_PER_HEIGHT",
           "LEG_LENGTH_PER_HEIGHT", "LENGTH_MODEL", "LENGTH_SOURCES", "AnatomyChoice", "anatomical_lengths",
           "choose_lengths"]

#: The plausible adult/child values of a given height, leg length and foot length, m (the command line's
#: ``--height``, ``--leg-length`` and ``--foot-length`` take these ranges).
ANATOMY_RANGES_M = {"height": (0.8, 2.5), "leg length": (0.3, 1.3), "foot length": (0.08, 0.4)}

#: Height used when nothing is known (adult population mean, both sexes, ~1.70 m).
DEFAULT_HEIGHT_M = 1.70

#: The model of the lengths estimated from a height, in one line (printed by the commands).
LENGTH_MODEL = (f"leg = {LEG_LENGTH_PER_HEIGHT:.3f} x height (greater trochanter to floor, Winter 2009 after "
                f"Drillis & Contini), foot (M3's double-support length S2, heel to first metatarsal head) = "
                f"{FOOT_LENGTH_PER_HEIGHT:.3f} x height ({BALL_OF_FOOT_PER_FOOT_LENGTH} x Winter's heel-to-toe "
                f"{HEEL_TOE_LENGTH_PER_HEIGHT} H, ANSUR 1988)")

#: Where :func:`choose_lengths` took the lengths from (the ``source`` of :class:`AnatomyChoice`, the
#: ``lengths_source`` column of the commands' tables): both lengths given; from a given height; from the K
#: file; from the recorded subject's height (IPOL JSON); from the logger's step configuration; from an
#: assumed :data:`DEFAULT_HEIGHT_M` adult (the height is unknown).
LENGTH_SOURCES = ("given", "height", "k-file", "subject-height", "logger-config", "assumed-height")


def anatomical_lengths(
    *, leg_length_m: float | None = None, foot_length_m: float | None = None, height_m: float | None = None
) -> tuple[float, float]:
    """Return ``(leg_length_m, foot_length_m)``, estimating what is missing from the height.

    ``foot_length_m`` is heel to first metatarsal head (the paper's definition, see module notes).

    Raises
    ------
    HostError
        A given length is not a plausible adult/child value (:data:`ANATOMY_RANGES_M`).

    Examples
    --------
    >>> anatomical_lengths(height_m=1.80)
    (0.954, 0.1998)
    >>> anatomical_lengths(leg_length_m=0.9, foot_length_m=0.26)
    (0.9, 0.26)
    """
    for what, value in (("height", height_m), ("leg length", leg_length_m), ("foot length", foot_length_m)):
        low, high = ANATOMY_RANGES_M[what]
        if value is not None and not (low <= value <= high):
            raise HostError(f"{what} {value!r} m is outside {low:g}-{high:g} m (give it in metres)")
    if (leg_length_m is None or foot_length_m is None) and height_m is None:
        warnings.warn(f"no height given: anatomical lengths estimated for a {DEFAULT_HEIGHT_M} m adult",
                      stacklevel=2)
        height_m = DEFAULT_HEIGHT_M
    leg = leg_length_m if leg_length_m is not None else round(LEG_LENGTH_PER_HEIGHT * height_m, 6)
    foot = foot_length_m if foot_length_m is not None else round(FOOT_LENGTH_PER_HEIGHT * height_m, 6)
    return float(leg), float(foot)


class AnatomyChoice(NamedTuple):
    """Leg and foot length chosen by :func:`choose_lengths`, and where they came from."""

    leg_length_m: float
    foot_length_m: float
    #: One line saying where the lengths came from ("" when both were given).
    note: str
    #: True when nothing about the wearer was known and a :data:`DEFAULT_HEIGHT_M` adult was assumed.
    assumed: bool
    #: One of :data:`LENGTH_SOURCES`: where the estimated length(s) came from ("given" when both were given).
    source: str = "given"


def choose_lengths(*, leg_length_m: float | None = None, foot_length_m: float | None = None,
                   height_m: float | None = None, k_lengths_m: tuple[float, float] | None = None,
                   k_source: str = "the K file", trial_height_m: float | None = None,
                   trial_source: str = "the trial", logger_lengths_m: tuple[float, float] | None = None,
                   logger_source: str = "the logger's step configuration") -> AnatomyChoice:
    """The one rule for the leg and foot length of a gait command.

    Each length is, in order: given (``leg_length_m`` / ``foot_length_m``); from the given ``height_m``;
    the K file's (``k_lengths_m``: K holds only with the lengths it was fitted with); from the height of the
    recorded subject (``trial_height_m``, e.g. an IPOL trial's JSON); the lengths the logger ran its on-line
    algorithm with (``logger_lengths_m``, the step configuration in a recording's header); from a
    :data:`DEFAULT_HEIGHT_M` adult (``assumed`` is then True, ``source`` is ``"assumed-height"`` and the note
    says so: the caller must warn). ``source`` names the rule used (:data:`LENGTH_SOURCES`).

    Raises
    ------
    HostError
        A length or height outside its plausible range (:func:`anatomical_lengths`).

    Examples
    --------
    >>> choose_lengths(height_m=1.80)[:2]
    (0.954, 0.1998)
    >>> print(choose_lengths(trial_height_m=1.80, trial_source="2-1.json").note)
    leg and foot length from the recorded subject's height, 1.80 m (2-1.json)
    >>> print(choose_lengths(logger_lengths_m=(0.927, 0.194), logger_source="walk.npz's step configuration").note)
    leg and foot length from walk.npz's step configuration (the lengths the logger's on-line algorithm used)
    >>> choose_lengths(foot_length_m=0.2)[3:]
    (True, 'assumed-height')
    >>> choose_lengths(height_m=1.80).source
    'height'
    """
    anatomical_lengths(leg_length_m=leg_length_m, foot_length_m=foot_length_m,
                       height_m=height_m if height_m is not None else DEFAULT_HEIGHT_M)     # range checks
    if height_m is not None or (leg_length_m is not None and foot_length_m is not None):
        leg, foot = anatomical_lengths(leg_length_m=leg_length_m, foot_length_m=foot_length_m,
                                       height_m=height_m if height_m is not None else DEFAULT_HEIGHT_M)
        return AnatomyChoice(leg, foot, "", False, "height" if height_m is not None else "given")
    if k_lengths_m is not None:
        leg = leg_length_m if leg_length_m is not None else float(k_lengths_m[0])
        foot = foot_length_m if foot_length_m is not None else float(k_lengths_m[1])
        return AnatomyChoice(leg, foot, f"leg and foot length from {k_source} (the lengths K was fitted with)"
                             if leg_length_m is None and foot_length_m is None else
                             f"{'leg' if leg_length_m is None else 'foot'} length from {k_source}", False, "k-file")
    if trial_height_m is not None:
        leg, foot = anatomical_lengths(leg_length_m=leg_length_m, foot_length_m=foot_length_m, height_m=trial_height_m)
        return AnatomyChoice(leg, foot, f"{_what(leg_length_m, foot_length_m)} from the recorded subject's height, "
                             f"{trial_height_m:.2f} m ({trial_source})", False, "subject-height")
    if logger_lengths_m is not None:
        leg = leg_length_m if leg_length_m is not None else float(logger_lengths_m[0])
        foot = foot_length_m if foot_length_m is not None else float(logger_lengths_m[1])
        return AnatomyChoice(leg, foot, f"{_what(leg_length_m, foot_length_m)} from {logger_source} (the lengths "
                             "the logger's on-line algorithm used)", False, "logger-config")
    leg, foot = anatomical_lengths(leg_length_m=leg_length_m, foot_length_m=foot_length_m, height_m=DEFAULT_HEIGHT_M)
    return AnatomyChoice(leg, foot, f"no height known: {_what(leg_length_m, foot_length_m)} estimated"
                         f" for a {DEFAULT_HEIGHT_M:.2f} m adult (leg {leg:.3f} m, foot {foot:.3f} m), an assumption "
                         "M3 (no K) scales with: 10 % off in height is 5-10 % off in M3; "
                         "give --height (or --leg-length and --foot-length)", True, "assumed-height")


def _what(leg_length_m: float | None, foot_length_m: float | None) -> str:
    return ("leg and foot length" if leg_length_m is None and foot_length_m is None
            else "leg length" if leg_length_m is None else "foot length")
