"""The interface every motion source implements.

Axis and sign convention (one convention for the whole project)
----------------------------------------------------------------
Accelerations are *specific force* in g along the device's nominal axes ``x, y, z`` (columns 0, 1, 2):
what an ideal accelerometer reads. A device at rest with its ``+z`` axis pointing up reads ``(0, 0, +1)``;
in free fall it reads ``(0, 0, 0)``. One g is 9.80665 m/s^2 (:data:`gaitlog.units.STANDARD_GRAVITY_M_S2`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

@dataclass(frozen=True, eq=False)
class Motion:
    """True acceleration of the device on a regular grid, with ground truth.

    Attributes
    ----------
    acc_g
        ``(n, 3)`` float64 specific force in g along the nominal device axes, gravity included.
    sampling_rate_hz
        Sampling rate of ``acc_g`` in Hz.
    t0_s
        Time of the first sample in seconds (the source's own clock; 0 unless a source says otherwise).
    truth
        Source-specific ground truth (pose orientations, step events, lap marks, ...), keyed by name; every
        time in it is in seconds on the same clock as ``t0_s`` and every length in metres.
    marker_times_s
        Times at which the logger's marker input fires (a push button: lap marks, pose changes); the
        firmware sets the MARK flag on the first sample it takes at or after each time.
    """

    acc_g: np.ndarray
    sampling_rate_hz: float
    t0_s: float = 0.0
    truth: Mapping[str, Any] = field(default_factory=dict)
    marker_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        acc = np.asarray(self.acc_g, dtype=np.float64)
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise ValueError(f"Motion.acc_g must have shape (n, 3), got {acc.shape}")
        if not np.isfinite(acc).all():
            raise ValueError("Motion.acc_g contains NaN or infinite values")
        if not (np.isfinite(self.sampling_rate_hz) and self.sampling_rate_hz > 0):
            raise ValueError(f"Motion.sampling_rate_hz must be a positive number, got {self.sampling_rate_hz!r}")
        object.__setattr__(self, "acc_g", acc)
        object.__setattr__(self, "marker_times_s", np.asarray(self.marker_times_s, dtype=np.float64))

    @property
    def n_samples(self) -> int:
        """Number of samples in ``acc_g``."""
        return int(self.acc_g.shape[0])

    @property
    def duration_s(self) -> float:
        """Duration covered by the samples, ``n / sampling_rate_hz``, in seconds."""
        return self.n_samples / self.sampling_rate_hz

    @property
    def t_s(self) -> np.ndarray:
        """Sample times in seconds, shape ``(n,)``."""
        return self.t0_s + np.arange(self.n_samples) / self.sampling_rate_hz


@runtime_checkable
class MotionSource(Protocol):
    """Anything that can produce the physical input of the logger.

    Implementations store their parameters in ``__init__`` (seeded: the same parameters give the same
    motion) and do the work in :meth:`render`.
    """

    def render(self, sampling_rate_hz: float) -> Motion:
        """Return the motion sampled at ``sampling_rate_hz`` (the sensor model's internal rate)."""
        ...
