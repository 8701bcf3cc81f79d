"""The firmware's step chain in the PIC16F877's fixed-point arithmetic (``firmware_sim.fixedpoint``).

It mirrors the float chain of ``host.gait`` / ``host.estimators`` class for class, with the same parameters
and event definitions, so that fixed and float differ only by arithmetic. It starts from the 10-bit ADC
codes and returns integers in documented Q formats (``formats``), converted to SI units only at the edge.

Modules
-------
formats
    The Q formats of the chain and the RAM its state takes.
calibration
    ``a = M (codes - offset)`` with the header's calibration quantised to 16-bit words.
axes
    Vertical acceleration from the moving-mean gravity (projection, integer square root and divide).
lowpass
    Centred Gaussian FIR low-pass with integer weights over the measured samples.
events
    Foot-flat, heel-strike and toe-off on the integer signals (:class:`FixedGaitEventDetector`).
integration
    Per-step double integration in saturating 32-bit accumulators (M1 resets, M2 drift correction).
pendulum, two_phase, weinberg, cadence
    M1-M5 in integer arithmetic.
chain
    ADC codes -> per-step table (:class:`FixedStepChain`).
"""
