"""Physical constants and units, defined once, below every package of gaitlog (protocol, simulator, host).

>>> round(STANDARD_GRAVITY_M_S2 * 0.5, 6)
4.903325
"""

__all__ = ["STANDARD_GRAVITY_M_S2"]

#: Standard gravity, m/s^2 per g (CGPM 1901): one g of the accelerometers' specific force.
STANDARD_GRAVITY_M_S2 = 9.80665
