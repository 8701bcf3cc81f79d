"""The logger's sample-timer rate, in a module of its own: the host's readers need the number without the converter
model (:mod:`gaitlog.firmware_sim.adc` loads ``scipy.linalg`` for its settling model, 0.3 s of every command that
reads a recording)."""

#: The logger's sample-timer rate unless told otherwise (Alvarez et al. 2006: 50 Hz), Hz.
DEFAULT_SAMPLING_RATE_HZ = 50.0
