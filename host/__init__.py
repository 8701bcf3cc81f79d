"""The PC side of the gait logger: link, dump, decode, calibration, kinematics, estimators, evaluation.

This package may import ``protocol`` and ``firmware_sim``; nothing imports it.
"""
