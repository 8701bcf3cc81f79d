"""The centre-of-mass path of one corridor excursion: out, a smooth 180° turn, and back.

Coordinates are the corridor's: ``x`` along the corridor from the start line, ``y`` to the walker's left
on the way out, in metres. The path is parametrised by its arc length ``s``; the heading turns from 0 to
pi over ``turn_length_m = pi · turn_radius_m`` with a raised-cosine curvature profile (no curvature jump,
so the lateral acceleration of the turn builds up smoothly), the apex of the turn sits exactly at
``x = corridor_length_m`` and the path returns to ``x = 0``.
"""

from __future__ import annotations

import numpy as np


class CorridorPath:
    """Out-turn-back path (lengths in m, angles in rad).

    Parameters
    ----------
    corridor_length_m
        Distance from the start line to the apex of the turn.
    turn_radius_m
        Equivalent radius of the turn (``turn_length_m = pi · turn_radius_m``).

    Examples
    --------
    >>> p = CorridorPath(corridor_length_m=100.0, turn_radius_m=0.5)
    >>> round(float(p.corridor_distance_m(p.s_apex_m)), 9), round(float(p.corridor_distance_m(p.length_m)), 9)
    (100.0, 200.0)
    >>> p.length_m > 200.0
    True
    """

    def __init__(self, *, corridor_length_m: float, turn_radius_m: float) -> None:
        self.corridor_length_m = float(corridor_length_m)
        self.turn_radius_m = float(turn_radius_m)
        self.turn_length_m = np.pi * self.turn_radius_m
        # Turn shape on a fine grid of the normalised turn parameter u in [0, 1] (Simpson-exact enough:
        # the integrands are smooth; 4096 intervals give ~1e-12 m).
        u = np.linspace(0.0, 1.0, 4097)
        psi = self._heading_u(u)
        ds = self.turn_length_m / (u.size - 1)
        cx = np.concatenate(([0.0], np.cumsum(0.5 * (np.cos(psi[1:]) + np.cos(psi[:-1])) * ds)))
        cy = np.concatenate(([0.0], np.cumsum(0.5 * (np.sin(psi[1:]) + np.sin(psi[:-1])) * ds)))
        self._ugrid, self._cx, self._cy = u, cx, cy
        half = u.size // 2
        self.turn_start_m = self.corridor_length_m - float(cx[half])  # apex (u = 0.5) at the far end
        self.s_apex_m = self.turn_start_m + 0.5 * self.turn_length_m
        self.turn_end_m = self.turn_start_m + self.turn_length_m
        self.lateral_offset_m = float(cy[-1])
        self.length_m = self.turn_end_m + (self.turn_start_m + float(cx[-1]))

    @staticmethod
    def _heading_u(u: np.ndarray) -> np.ndarray:
        return np.pi * (u - np.sin(2.0 * np.pi * u) / (2.0 * np.pi))

    def _u(self, s_m: np.ndarray) -> np.ndarray:
        return np.clip((np.asarray(s_m, dtype=np.float64) - self.turn_start_m) / self.turn_length_m, 0.0, 1.0)

    def heading_rad(self, s_m: np.ndarray) -> np.ndarray:
        """Heading of the path tangent (0 = +x, pi on the way back)."""
        return self._heading_u(self._u(s_m))

    def curvature_per_m(self, s_m: np.ndarray) -> np.ndarray:
        """Curvature d(heading)/ds in rad/m (0 on the straights)."""
        u = self._u(s_m)
        k = (np.pi / self.turn_length_m) * (1.0 - np.cos(2.0 * np.pi * u))
        return np.where((u > 0.0) & (u < 1.0), k, 0.0)

    def curvature_slope_per_m2(self, s_m: np.ndarray) -> np.ndarray:
        """d(curvature)/ds in rad/m^2."""
        u = self._u(s_m)
        k = (np.pi / self.turn_length_m) * (2.0 * np.pi / self.turn_length_m) * np.sin(2.0 * np.pi * u)
        return np.where((u > 0.0) & (u < 1.0), k, 0.0)

    def position_m(self, s_m: np.ndarray) -> np.ndarray:
        """``(n, 2)`` position ``(x, y)`` on the path; straight extrapolation beyond both ends."""
        s = np.asarray(s_m, dtype=np.float64)
        u = self._u(s)
        x = np.where(s <= self.turn_start_m, s, self.turn_start_m + np.interp(u, self._ugrid, self._cx))
        y = np.where(s <= self.turn_start_m, 0.0, np.interp(u, self._ugrid, self._cy))
        after = s > self.turn_end_m
        x = np.where(after, self.turn_start_m + self._cx[-1] - (s - self.turn_end_m), x)
        y = np.where(after, self.lateral_offset_m, y)
        return np.stack([x, y], axis=-1)

    def corridor_distance_m(self, s_m: np.ndarray) -> np.ndarray:
        """Distance walked along the corridor: ``x`` on the way out, ``2·C - x`` after the apex."""
        s = np.asarray(s_m, dtype=np.float64)
        x = self.position_m(s)[..., 0]
        return np.where(s <= self.s_apex_m, x, 2.0 * self.corridor_length_m - x)

    def s_at_corridor_distance(self, d_m: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`corridor_distance_m` (monotonic on ``[0, length_m]``)."""
        d = np.asarray(d_m, dtype=np.float64)
        grid = np.linspace(self.turn_start_m, self.turn_end_m, 4097)
        dist = self.corridor_distance_m(grid)
        out = np.interp(d, dist, grid)
        out = np.where(d <= dist[0], d, out)
        return np.where(d >= dist[-1], self.length_m - (2.0 * self.corridor_length_m - d), out)
