"""Platform descriptions: where each sensor of a recording sits and points (versioned JSON files).

:class:`MorrisPlatform` (``"cal_type": "gaitlog.MorrisPlatform"``) -- single-axis accelerometers on one
segment::

    {"accelerometers": [{"sensor": "acc1", "position_m": [0, 0, 0], "axis": [1, 0, 0]}, ...],
     "origin_from_pivot_m": [0, 0, 0.2],
     "assume_zero_rate_axes": [2]}

``position_m`` is relative to the platform origin and ``axis`` the sensing direction, both in the segment
frame (1 anterior, 2 left, 3 along the shank up); ``origin_from_pivot_m`` places the origin relative to the
foot-flat pivot (Morris: a point in the talus); ``assume_zero_rate_axes`` lists the segment axes whose
angular velocity is taken as zero (Morris, five accelerometers: ``[2]``, no transverse rotation).

:class:`HallPlatform` (``"gaitlog.HallPlatform"``) -- a triaxial angular-rate sensor on each of two links::

    {"links": {"A": {"rate_sensors": ["A_x", "A_y", "A_z"], "sensor_to_link": [[0,1,0],[0,0,1],[1,0,0]],
                     "gravity_sensors": ["A_gx", "A_gy", "A_gz"]},
               "B": {...}},
     "sequence": "yxz", "side": "left", "pretest_s": 0.02, "initial_joint_deg": null}

``sensor_to_link`` is Hall's ``S`` of eqs (5)-(6), ``{î_link} = S {î_sensor}``; it must be a proper
rotation. The matrix printed in the paper, ``[[0,1,0],[0,0,1],[-1,0,0]]``, has determinant −1: it is a
reflection (a mirror image), which no mounting of a right-handed sensor on a right-handed link can produce,
so it is refused with that explanation (flip the sign of the row whose axis really points the other way;
the project's simulation uses ``k_link = +i_sensor``). ``sequence`` is ``"yxz"`` (lower limb, neck:
y − x′ − z″) or ``"xzy"`` (spine: x − z′ − y″). The initial A−B transformation comes from the pre-test
posture: from ``initial_joint_deg`` when given (a goniometer reading), else from each link's gravity
channels averaged over the pre-test samples (tilts measured, headings taken equal, as Hall's neck test
zeroes the laboratory-z rotation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from gaitlog.host.errors import HostError
from gaitlog.host.storage.versioned_json import VersionedJson

__all__ = ["HALL_SEQUENCES", "HallLink", "HallPlatform", "MorrisPlatform", "check_rotation"]

#: Joint-angle sequences offered (Hall: lower limb and neck ``yxz``, spine ``xzy``).
HALL_SEQUENCES = ("yxz", "xzy")


def _vec3(value: object, where: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64) if isinstance(value, list) else None
    if a is None or a.shape != (3,) or not np.isfinite(a).all():
        raise HostError(f"{where}: expected a list of 3 numbers, found {value!r}")
    return a


def check_rotation(value: object, where: str) -> np.ndarray:
    """A 3x3 proper rotation from a nested list; refuses reflections with Hall's eqs (5)-(6) explained."""
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        m = np.zeros(0)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise HostError(f"{where}: expected a 3x3 matrix (list of 3 rows), found {value!r}")
    if not np.allclose(m @ m.T, np.eye(3), atol=1e-6):
        raise HostError(f"{where}: not orthonormal (rows must be unit vectors at right angles): {m.tolist()}")
    if np.linalg.det(m) < 0:
        raise HostError(
            f"{where}: determinant -1: {m.tolist()} is a reflection, not a rotation -- no mounting of a "
            "right-handed sensor on a right-handed link gives it (Hall's printed eqs (5)-(6) have this error); "
            "negate the row of the axis that really points the other way, e.g. [[0,1,0],[0,0,1],[1,0,0]]"
        )
    return m


def _names(value: object, n: int, where: str) -> list[str]:
    if not (isinstance(value, list) and len(value) == n and all(isinstance(s, str) and s for s in value)):
        raise HostError(f"{where}: expected a list of {n} sensor names, found {value!r}")
    return list(value)


@dataclass(frozen=True, eq=False)
class MorrisPlatform(VersionedJson):
    """Single-axis accelerometers on one segment (module notes)."""

    SCHEMA = "gaitlog.MorrisPlatform"
    FORMAT_VERSION = "1.0"
    KIND = "Morris platform description"
    REDO = "write it again for this gaitlog"

    sensors: list[str]
    positions_m: np.ndarray
    axes: np.ndarray
    origin_from_pivot_m: np.ndarray
    assume_zero_rate_axes: tuple[int, ...]

    def fields_to_dict(self) -> dict[str, Any]:
        return {
            "accelerometers": [{"sensor": s, "position_m": p.tolist(), "axis": a.tolist()}
                               for s, p, a in zip(self.sensors, self.positions_m, self.axes)],
            "origin_from_pivot_m": self.origin_from_pivot_m.tolist(),
            "assume_zero_rate_axes": list(self.assume_zero_rate_axes),
        }

    @classmethod
    def fields_from_dict(cls, data: dict[str, Any], *, source: str) -> Self:
        accs = data.get("accelerometers")
        if not isinstance(accs, list) or len(accs) < 5:
            raise HostError(f"{source}: key 'accelerometers': expected a list of at least 5 accelerometers "
                            f"(Morris used 5 with one rate assumed zero), found {accs!r}")
        sensors, pos, axes = [], [], []
        for i, a in enumerate(accs):
            where = f"{source}: accelerometers[{i}]"
            if not isinstance(a, dict) or not isinstance(a.get("sensor"), str):
                raise HostError(f"{where}: expected an object with 'sensor', 'position_m', 'axis'")
            sensors.append(a["sensor"])
            pos.append(_vec3(a.get("position_m"), f"{where}.position_m"))
            ax = _vec3(a.get("axis"), f"{where}.axis")
            if np.linalg.norm(ax) == 0:
                raise HostError(f"{where}.axis: the sensing axis is the zero vector")
            axes.append(ax / np.linalg.norm(ax))
        if len(set(sensors)) != len(sensors):
            raise HostError(f"{source}: key 'accelerometers': a sensor is listed twice: {sensors}")
        zero = data.get("assume_zero_rate_axes", [])
        if not (isinstance(zero, list) and all(z in (0, 1, 2) for z in zero) and len(set(zero)) == len(zero)):
            raise HostError(f"{source}: key 'assume_zero_rate_axes': expected a list of distinct axes 0, 1, 2, "
                            f"found {zero!r}")
        return cls(sensors, np.array(pos), np.array(axes), _vec3(data.get("origin_from_pivot_m"),
                   f"{source}: key 'origin_from_pivot_m'"), tuple(int(z) for z in zero))


@dataclass(frozen=True, eq=False)
class HallLink:
    """One link: its rate sensor's three channels, mounting matrix and optional gravity channels."""

    rate_sensors: list[str]
    sensor_to_link: np.ndarray
    gravity_sensors: list[str] | None


@dataclass(frozen=True, eq=False)
class HallPlatform(VersionedJson):
    """Two triaxial angular-rate sensors on two links (module notes)."""

    SCHEMA = "gaitlog.HallPlatform"
    FORMAT_VERSION = "1.0"
    KIND = "Hall platform description"
    REDO = "write it again for this gaitlog"

    link_a: HallLink
    link_b: HallLink
    sequence: str
    side: str
    pretest_s: float
    initial_joint_deg: np.ndarray | None

    def fields_to_dict(self) -> dict[str, Any]:
        def link(k: HallLink) -> dict[str, Any]:
            out: dict[str, Any] = {"rate_sensors": k.rate_sensors, "sensor_to_link": k.sensor_to_link.tolist()}
            if k.gravity_sensors:
                out["gravity_sensors"] = k.gravity_sensors
            return out

        return {
            "links": {"A": link(self.link_a), "B": link(self.link_b)},
            "sequence": self.sequence,
            "side": self.side,
            "pretest_s": self.pretest_s,
            "initial_joint_deg": None if self.initial_joint_deg is None else self.initial_joint_deg.tolist(),
        }

    @classmethod
    def fields_from_dict(cls, data: dict[str, Any], *, source: str) -> Self:
        links = data.get("links")
        if not isinstance(links, dict) or set(links) != {"A", "B"}:
            raise HostError(f"{source}: key 'links': expected an object with links 'A' and 'B'")
        parsed = []
        for name in ("A", "B"):
            k = links[name]
            where = f"{source}: links.{name}"
            if not isinstance(k, dict):
                raise HostError(f"{where}: expected an object")
            grav = k.get("gravity_sensors")
            parsed.append(HallLink(_names(k.get("rate_sensors"), 3, f"{where}.rate_sensors"),
                                   check_rotation(k.get("sensor_to_link"), f"{where}.sensor_to_link"),
                                   None if grav is None else _names(grav, 3, f"{where}.gravity_sensors")))
        seq = data.get("sequence", "yxz")
        if seq not in HALL_SEQUENCES:
            raise HostError(f"{source}: key 'sequence': expected one of {HALL_SEQUENCES}, found {seq!r}")
        side = data.get("side", "left")
        if side not in ("left", "right"):
            raise HostError(f"{source}: key 'side': expected 'left' or 'right', found {side!r}")
        pre = data.get("pretest_s", 0.0)
        if not (isinstance(pre, (int, float)) and pre >= 0 and np.isfinite(pre)):
            raise HostError(f"{source}: key 'pretest_s': expected a duration >= 0 in s, found {pre!r}")
        init = data.get("initial_joint_deg")
        init_arr = None if init is None else _vec3(init, f"{source}: key 'initial_joint_deg'")
        if init_arr is None and not (parsed[0].gravity_sensors and parsed[1].gravity_sensors):
            raise HostError(f"{source}: the initial A-B transformation is not given: state 'initial_joint_deg' "
                            "(the pre-test posture, e.g. from a goniometer; [0, 0, 0] for neutral) or give both "
                            "links 'gravity_sensors' to take it from the pre-test samples")
        if init_arr is None and pre <= 0:
            raise HostError(f"{source}: key 'pretest_s': the posture from gravity needs a pre-test window > 0 s")
        return cls(parsed[0], parsed[1], seq, side, float(pre), init_arr)
