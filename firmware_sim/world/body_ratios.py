"""Winter's anthropometric ratios (fraction of body height): the one home of these numbers.

Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., 2009, Fig. 4.1: greater-trochanter height
(the pendulum length ``l`` of Alvarez eq. 1) 0.530·H, foot length heel to toe 0.152·H; M3's ``S2`` (heel to first
metatarsal head, Alvarez's "foot length") is 0.73 of that (ANSUR, Gordon et al. 1989), 0.111·H.

The simulated walkers (:mod:`gaitlog.firmware_sim.world.subject`) and the host's lengths from a height
(:mod:`gaitlog.host.gait.anthropometry`) import them from here: a module of constants only, so that the host's
commands (``gaitlog estimate``) do not load the walkers' model to read four numbers.
"""

from __future__ import annotations

__all__ = ["BALL_OF_FOOT_PER_FOOT_LENGTH", "FOOT_LENGTH_PER_HEIGHT", "HEEL_TOE_LENGTH_PER_HEIGHT",
           "LEG_LENGTH_PER_HEIGHT"]

#: Greater-trochanter height (leg length, the pendulum length) per height.
LEG_LENGTH_PER_HEIGHT = 0.530
#: Foot length heel to toe per height.
HEEL_TOE_LENGTH_PER_HEIGHT = 0.152
#: Ball-of-foot length (heel to first metatarsal head) per heel-to-toe length (ANSUR means 197/270 mm in men,
#: 179/244 mm in women).
BALL_OF_FOOT_PER_FOOT_LENGTH = 0.73
#: Heel (calcaneal tuberosity) to first metatarsal head per height: Alvarez's foot length ``S2``.
FOOT_LENGTH_PER_HEIGHT = round(BALL_OF_FOOT_PER_FOOT_LENGTH * HEEL_TOE_LENGTH_PER_HEIGHT, 4)
