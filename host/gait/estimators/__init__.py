"""Step-length estimators M1-M5 of Alvarez et al. (2006) in the offline float chain (K: :mod:`gaitlog.host.gait.k_calibration`).

The names (``ESTIMATORS``) and the per-step table are defined once in ``gaitlog.firmware_sim.algorithms.steps``.

========  =========================================  =====================================
name      class                                      model
========  =========================================  =====================================
M1        :class:`~.pendulum.PendulumM1`             ``K * 2 sqrt(2 l h - h^2)``, integrals reset at foot-flat
M2        :class:`~.pendulum.PendulumDriftM2`        M1 with the c1/c2 drift correction (eqs 2-3)
M3        :class:`~.two_phase.TwoPhasePendulumM3`    ``2 sqrt(2 l h1 - h1^2) + foot length``, no K
M4        :class:`~.weinberg.WeinbergM4`             ``K (a_max - a_min)^p`` (p = 1/2), 3 Hz low-passed
M5        :class:`~.cadence.CadenceM5`               ``K1 / T_step + K2``
========  =========================================  =====================================
"""
