"""The PC side of the gait logger, one subpackage per concept, in the order the data flows.

This package may import ``protocol`` and ``firmware_sim``; nothing imports it.

Subpackages
-----------
storage
    Below the others: typed versioned JSON results, input size limits, PNG figures.
link
    The serial side: :class:`~gaitlog.host.link.logger_link.LoggerLink` over pyserial, the memory dump, ``emu://``.
files
    Files and decoding: memory image / dump / capture -> :class:`~gaitlog.host.files.recording.Recording`, every
    input format a command reads, the IPOL reader, and the bit-for-bit check of the device's step records.
accelerometer
    Accelerometer calibration: static windows of a calibration session, the fit of offsets, scales and axes.
gait
    Gait of lower-back acceleration: axes, events, the per-step float chain, estimators M1-M5, K calibration.
kinematics
    Segment kinematics after Morris (1973) and Hall et al. (1997): orientation, translation, joints, CFC.
studies
    The paper's evaluation (simulated and IPOL), chain comparisons, ADC x rate sweeps, and their plots.
commands
    One module per ``gaitlog`` subcommand, on top of everything else (:mod:`gaitlog.host.cli` is the entry point).
"""
