"""The physical world the logger sits in: motion sources with ground truth.

Every source implements :class:`gaitlog.firmware_sim.world.base.MotionSource`: ``render(sampling_rate_hz)`` returns a
:class:`~gaitlog.firmware_sim.world.base.Motion`, the true specific force along the device's nominal axes in g
(gravity included) on a regular time grid, with the source's ground truth beside it.
"""
