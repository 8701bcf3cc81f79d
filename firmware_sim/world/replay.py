"""Replay of a real recording as the physical motion the logger experiences.

A recording (acceleration in g, gravity included, on a regular grid at its own rate, with missing samples) is
taken as the true specific force along the device's nominal axes and resampled to whatever rate the sensor
model asks for, with an anti-aliasing polyphase filter (:func:`gaitlog.firmware_sim.world.resampling.resample_g`; never
by picking samples).

Files are read by the host (:func:`gaitlog.host.files.inputs.read_acceleration`: logger files, IPOL, CSV), which hands
the samples to :meth:`Replay.from_samples`. The physical input over a missing sample (a lost packet, a gap)
was continuous, so the holes are *interpolated* linearly between their neighbours, and every filled range is
reported in the truth (``filled``, ``filled_ranges_s``, ``filled_packets``, ``n_filled``): those stretches are
not measured motion.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.firmware_sim.world.resampling import resample_g

__all__ = ["Replay", "regular_grid"]


def regular_grid(index: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Place ``values`` at integer grid positions ``index`` (sorted, unique) and interpolate the holes.

    Returns the ``(m, k)`` filled array, ``m = index[-1] - index[0] + 1``, and a bool mask ``filled``
    (True where a value was interpolated).

    >>> v, f = regular_grid(np.array([0, 1, 4]), np.array([[0.0], [1.0], [4.0]]))
    >>> v[:, 0].tolist(), f.tolist()
    ([0.0, 1.0, 2.0, 3.0, 4.0], [False, False, True, True, False])
    """
    rel = index - index[0]
    m = int(rel[-1]) + 1
    grid = np.arange(m)
    out = np.empty((m, values.shape[1]), dtype=np.float64)
    for j in range(values.shape[1]):  # 3 columns: one np.interp each
        out[:, j] = np.interp(grid, rel, values[:, j])
    filled = np.ones(m, dtype=bool)
    filled[rel] = False
    return out, filled


def _ranges(mask: np.ndarray) -> np.ndarray:
    """``(k, 2)`` [first, last] index pairs of the True runs of ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return np.c_[np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1]


class Replay:
    """A recorded acceleration replayed as the logger's physical input.

    Parameters
    ----------
    acc_g
        ``(n, 3)`` specific force in g on a regular grid, gravity included, device axes.
    sampling_rate_hz
        Rate of ``acc_g`` in Hz.
    t0_s
        Time of the first sample, seconds.
    truth
        Ground truth and provenance passed through to :class:`Motion` (``filled_ranges_s`` etc.).
    marker_times_s
        Marker-button times, seconds.

    Examples
    --------
    >>> t = np.arange(1000) / 100.0
    >>> acc = np.c_[0.1 * np.sin(2 * np.pi * t), np.zeros_like(t), np.ones_like(t)]
    >>> m = Replay(acc, sampling_rate_hz=100.0).render(500.0)
    >>> m.n_samples, m.sampling_rate_hz
    (5000, 500.0)
    """

    def __init__(
        self,
        acc_g: np.ndarray,
        *,
        sampling_rate_hz: float,
        t0_s: float = 0.0,
        truth: Mapping[str, Any] | None = None,
        marker_times_s: np.ndarray | Sequence[float] = (),
    ) -> None:
        self.acc_g = np.asarray(acc_g, dtype=np.float64)
        self.sampling_rate_hz = float(sampling_rate_hz)
        self.t0_s = float(t0_s)
        self.truth = dict(truth or {})
        self.marker_times_s = np.asarray(marker_times_s, dtype=np.float64)

    def render(self, sampling_rate_hz: float) -> Motion:
        """The recording resampled to ``sampling_rate_hz`` (anti-aliased; the exact achieved rate is in the Motion)."""
        if self.acc_g.ndim != 2 or self.acc_g.shape[1] != 3 or self.acc_g.shape[0] < 2:
            raise DeviceError(f"replay needs an (n >= 2, 3) acceleration array, got {self.acc_g.shape}")
        acc, rate = resample_g(self.acc_g, self.sampling_rate_hz, sampling_rate_hz)
        truth = dict(self.truth)
        truth.setdefault("source_rate_hz", self.sampling_rate_hz)
        return Motion(acc_g=acc, sampling_rate_hz=rate, t0_s=self.t0_s, truth=truth, marker_times_s=self.marker_times_s)

    @property
    def n_interpolated(self) -> int:
        """Samples of :attr:`acc_g` interpolated over lost packets or gaps (not measured motion)."""
        return int(self.truth.get("n_filled", 0))

    @classmethod
    def from_samples(cls, acc_g: np.ndarray, valid: np.ndarray, *, sampling_rate_hz: float, source: str = "recording",
                     marker_times_s: np.ndarray | Sequence[float] = ()) -> Replay:
        """A recording on a regular grid with missing samples (``valid`` False): the holes are interpolated
        linearly, as the physical input was continuous, and reported (``truth["n_filled"]``,
        :attr:`n_interpolated`, ``filled_ranges_s``).

        >>> r = Replay.from_samples(np.ones((5, 3)), np.array([1, 0, 0, 1, 1], bool), sampling_rate_hz=10.0)
        >>> r.n_interpolated, r.truth["filled_packets"].tolist()
        (2, [[1, 2]])
        """
        ok = np.asarray(valid, bool) & np.all(np.isfinite(acc_g), axis=1)
        idx = np.flatnonzero(ok)
        if idx.size < 2:
            raise DeviceError(f"{source}: fewer than 2 measured samples to replay")
        grid, filled = regular_grid(idx, np.asarray(acc_g, np.float64)[idx])
        truth = _fill_truth(filled, float(sampling_rate_hz))
        truth.update(source=source, first_sample=int(idx[0]))
        return cls(grid, sampling_rate_hz=float(sampling_rate_hz), t0_s=idx[0] / float(sampling_rate_hz), truth=truth,
                   marker_times_s=marker_times_s)


def _fill_truth(filled: np.ndarray, sampling_rate_hz: float) -> dict[str, Any]:
    r = _ranges(filled)
    return {
        "filled": filled,
        "filled_packets": r,
        "filled_ranges_s": r / sampling_rate_hz + np.array([0.0, 1.0 / sampling_rate_hz]) * (r.size > 0),
        "n_filled": int(filled.sum()),
    }
