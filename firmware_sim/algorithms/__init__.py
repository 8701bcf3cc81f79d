"""The firmware's step algorithm: on-line (causal, sample by sample, bounded state), one text, two arithmetics.

The logger runs it while logging (``gaitlog.firmware_sim.firmware``) in the PIC's fixed point; the host runs the
same definition to replay a dump bit for bit, or in floating point to see what the arithmetic costs. The
rules it shares with the host's offline chain (``gaitlog.host.gait``: the paper's PC processing) are defined here,
below the host, once.

Modules
-------
parameters
    The rules and constants (cut-offs, step limits, prominence, search windows, the rounding of durations
    to samples, the minimum-distance rule), shared with the offline chain.
arithmetic
    The operations the algorithm uses; the type of the values selects float or the PIC's fixed point.
formats
    The Q formats of every value in fixed point.
kernel
    The per-sample program (compiled by numba, once per arithmetic).
aot_kernel
    The same program compiled ahead of time: loaded without numba (fast start-up), JIT as the fallback.
state
    The RAM it keeps: the declared state slots and the kernel's declared temporaries.
online
    :class:`~.online.OnlineStepAlgorithm`: configure, feed samples, get one record per foot-flat.
calibration
    The device calibration as the PIC keeps it (offsets, block-floating-point matrix).
steps
    The per-step table both chains fill (:class:`~.steps.StepTable`) and the estimator names.
"""
