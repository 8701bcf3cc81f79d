"""Static calibration poses: the device held still in known orientations, with smooth moves between.

This is the world of the multi-position calibration (Alvarez et al. 2006, section II: offset, scale and
orthogonality from static poses). The device sits in pose ``i`` for ``hold_s`` seconds, then turns to pose
``i + 1`` in ``move_s`` seconds along the shortest rotation with a minimum-jerk profile
``s(u) = 10u^3 - 15u^4 + 6u^5`` (zero angular velocity and acceleration at both ends), and so on.

The device turns about its own sensing point (an ideal calibration jig), so the specific force it feels
is gravity alone, rotated into the device axes: ``f(t) = R(t)^-1 (0, 0, 1)`` in g, where ``R(t)`` maps
device axes to world axes (world ``z`` up). During a hold this is exactly the pose's 1 g vector.

Default orientations: 24 "up" directions spread evenly over the sphere (a Fibonacci lattice, turned by a
seeded random rotation so the poses are not aligned with the axes), each with a seeded random yaw about the
vertical (yaw does not change what an accelerometer reads, but it makes the orientations complete).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.world.base import Motion

__all__ = ["CalibrationPoses", "fibonacci_directions", "minimum_jerk"]

_UP = np.array([0.0, 0.0, 1.0])


def fibonacci_directions(n: int) -> np.ndarray:
    """``(n, 3)`` unit vectors spread evenly over the sphere (golden-angle spiral).

    Examples
    --------
    >>> d = fibonacci_directions(24)
    >>> d.shape, bool(np.allclose(np.linalg.norm(d, axis=1), 1.0)), bool(abs(d.mean(axis=0)).max() < 0.05)
    ((24, 3), True, True)
    """
    if n < 1:
        raise DeviceError(f"need at least one direction, got n={n}")
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.c_[r * np.cos(phi), r * np.sin(phi), z]


def minimum_jerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile ``10u^3 - 15u^4 + 6u^5`` on ``u`` in [0, 1] (clipped outside).

    >>> minimum_jerk(np.array([0.0, 0.5, 1.0])).tolist()
    [0.0, 0.5, 1.0]
    """
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def _rotation_taking_to_up(v: np.ndarray) -> Rotation:
    """Shortest rotations ``A`` with ``A v = (0, 0, 1)`` for unit vectors ``v`` of shape ``(n, 3)``."""
    axis = np.cross(v, _UP)
    s = np.linalg.norm(axis, axis=1)
    c = v @ _UP
    angle = np.arctan2(s, c)
    unit = np.where(s[:, None] > 1e-12, axis / np.maximum(s, 1e-300)[:, None], np.array([1.0, 0.0, 0.0]))
    return Rotation.from_rotvec(unit * angle[:, None])


class CalibrationPoses:
    """A sequence of static orientations held still, with smooth moves between them.

    Parameters
    ----------
    n_poses
        Number of poses of the default set (ignored when ``orientations`` is given). Default 24.
    hold_s
        Time each pose is held still, seconds (>= 3 s, as a calibration procedure needs).
    move_s
        Duration of each move between poses, seconds (> 0).
    orientations
        Explicit orientations (device axes -> world axes, world ``z`` up), one per pose; default: the
        seeded spread set described in the module docstring.
    markers
        If True, the marker button fires at the start of every hold after the first (pose changes), so the
        firmware sets the MARK flag there.
    seed
        Seed of the random turn of the lattice and of the yaws.

    Examples
    --------
    >>> m = CalibrationPoses(n_poses=6, hold_s=3.0, move_s=1.0, seed=1).render(100.0)
    >>> m.n_samples, m.truth["hold_windows_s"].shape, round(float(np.linalg.norm(m.acc_g, axis=1).max()), 12)
    (2300, (6, 2), 1.0)
    """

    def __init__(
        self,
        *,
        n_poses: int = 24,
        hold_s: float = 5.0,
        move_s: float = 2.0,
        orientations: Rotation | None = None,
        markers: bool = True,
        seed: int = 0,
    ) -> None:
        self.n_poses = n_poses
        self.hold_s = hold_s
        self.move_s = move_s
        self.orientations = orientations
        self.markers = markers
        self.seed = seed

    # -- the parts of the truth that do not depend on the rendering rate --------------------------------
    def pose_rotations(self) -> Rotation:
        """Orientations of the poses (device axes -> world axes), one per pose."""
        if self.orientations is not None:
            rot = self.orientations
            if rot.single or len(rot) < 1:
                raise DeviceError("orientations must be a Rotation holding at least one orientation")
            return rot
        if self.n_poses < 1:
            raise DeviceError(f"n_poses must be >= 1, got {self.n_poses}")
        rng = np.random.default_rng(self.seed)
        turn = Rotation.random(random_state=rng)
        up_dev = turn.apply(fibonacci_directions(self.n_poses))  # 1 g "up" vector in device axes
        yaw = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi, (self.n_poses, 1)))
        return yaw * _rotation_taking_to_up(up_dev)

    def windows_s(self) -> tuple[np.ndarray, np.ndarray]:
        """Hold windows ``(n, 2)`` and move windows ``(n - 1, 2)`` as [start, end) in seconds."""
        if not self.hold_s >= 3.0:
            raise DeviceError(f"hold_s must be >= 3 s for a static pose, got {self.hold_s}")
        if not self.move_s > 0.0:
            raise DeviceError(f"move_s must be > 0, got {self.move_s}")
        n = len(self.pose_rotations())
        start = np.arange(n) * (self.hold_s + self.move_s)
        holds = np.c_[start, start + self.hold_s]
        moves = np.c_[holds[:-1, 1], holds[1:, 0]]
        return holds, moves

    def render(self, sampling_rate_hz: float) -> Motion:
        """Sample the pose sequence at ``sampling_rate_hz``.

        Returns
        -------
        Motion
            ``acc_g`` is gravity's specific force in device axes. ``truth`` holds ``orientations_xyzw``
            (scalar-last quaternions, device -> world), ``specific_force_g`` (per pose, what an ideal sensor
            reads: the unit "up" vector), ``gravity_g`` (its negative: gravity in device axes),
            ``hold_windows_s``, ``move_windows_s`` and ``moving`` (per-sample bool).
        """
        if not (sampling_rate_hz > 0 and np.isfinite(sampling_rate_hz)):
            raise DeviceError(f"sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
        rots = self.pose_rotations()
        holds, moves = self.windows_s()
        n = len(rots)
        up_dev = rots.inv().apply(_UP).reshape(n, 3)
        duration_s = float(holds[-1, 1])
        n_samples = int(np.floor(duration_s * sampling_rate_hz + 1e-9))
        # sample index where each hold and each move begins (first sample at or after the time)
        hold_first = np.minimum(np.ceil(holds[:, 0] * sampling_rate_hz - 1e-9).astype(np.int64), n_samples)
        move_first = np.minimum(np.ceil(moves[:, 0] * sampling_rate_hz - 1e-9).astype(np.int64), n_samples)
        counts = np.diff(np.r_[hold_first, n_samples])
        acc = np.repeat(up_dev, counts, axis=0)  # every sample at its pose's vector ...
        moving = np.zeros(n_samples, dtype=bool)
        if n > 1:
            # ... then the moves (a few percent of the samples), one vectorised block per move:
            # body-frame rotation vector r from pose i to i + 1, R(s) = R_i exp(s r), f(s) = exp(-s r) f_i
            rel = (rots[:-1].inv() * rots[1:]).as_rotvec().reshape(n - 1, 3)
            for i in range(n - 1):
                a, b = move_first[i], hold_first[i + 1]
                if b <= a:
                    continue
                moving[a:b] = True
                u = (np.arange(a, b) / sampling_rate_hz - moves[i, 0]) / self.move_s
                s = minimum_jerk(u)
                theta = float(np.linalg.norm(rel[i]))
                k = rel[i] / theta if theta > 0 else np.zeros(3)
                v = up_dev[i]
                phi = -s * theta
                cos, sin = np.cos(phi)[:, None], np.sin(phi)[:, None]
                acc[a:b] = v * cos + np.cross(k, v) * sin + k * (k @ v) * (1.0 - cos)
        markers = holds[1:, 0] if self.markers else np.zeros(0)
        truth = {
            "source": "calibration_poses",
            "orientations_xyzw": rots.as_quat().reshape(n, 4),
            "specific_force_g": up_dev,
            "gravity_g": -up_dev,
            "hold_windows_s": holds,
            "move_windows_s": moves,
            "moving": moving,
            "seed": self.seed,
        }
        return Motion(acc_g=acc, sampling_rate_hz=float(sampling_rate_hz), t0_s=0.0, truth=truth, marker_times_s=markers)
