"""Joint angles from two triaxial angular-rate sensors on two links, after Hall et al. (1997).

Frames follow Hall: a link matrix ``TA`` maps reference (laboratory) coordinates to link-A coordinates
(its rows are the link's unit vectors in the reference frame, eq 1), so ``TA = λAᵀ`` for the project's
body-to-space direction-cosine matrix ``λA`` (see :mod:`gaitlog.host.kinematics.orientation`). The joint matrix is
``T = TB · TAᵀ`` (eq 2) and for a ``y − x′ − z″`` sequence (flexion ``φ`` about y, version ``θ`` about the
floating x′, axial rotation ``ψ`` about z″) it has the form of eq (3). Angles (eq 4, with the corrected
``φ``; atan2 forms keep the quadrant):

.. math:: θ = \\operatorname{asin}(−T_{21}),\\; φ = \\operatorname{atan2}(T_{20}, T_{22}),\\;
          ψ = \\operatorname{atan2}(T_{01}, T_{11})

(0-based indices), equal to ``Rotation.from_matrix(TA·TBᵀ).as_euler("YXZ")``.

Processing steps of :class:`HallJointKinematics` (numbers used in the code comments):

1. subtract the mean of the pre-test samples from every rate channel (offset removal);
2. optionally low-pass with the SAE J211 CFC filter (Hall: CFC 180 at 10 kHz);
3. transform sensor rates to link axes, ``ω_link = S ω_sensor`` with ``{î_link} = S {î_sensor}`` (eq 5-6);
4. integrate each link's rate with the trapezoidal rule into incremental rotations and chain them into the
   link matrices (Hall composes three small Euler angles per step, "independent of sequence" at 10 kHz;
   here each increment is the exact rotation of the trapezoidal rotation vector, which is
   sequence-independent for any step size);
5. joint matrix ``T = TB·TAᵀ`` and ``y − x′ − z″`` angles, with gimbal lock reported where ``|θ| → 90°``;
6. right-leg sign convention: version (θ, about x) and axial rotation (ψ, about z) are negated, so that
   eversion, dorsiflexion and internal rotation are positive on both legs.

Hall's abstract says the joint angles are the *sum of incremental Eulerian rotations*. Taken literally that
depends on the path (reaching (40, −20, 15)° along a straight line in angle space sums to about
(41.4, −14.7, 21.9)°) and agrees with the absolute angles only for planar motion, so absolute angles from the
integrated matrices are the default; ``angle_mode="incremental_sum"`` reproduces the literal reading.
"""

from __future__ import annotations

import warnings
from typing import Literal, Self

import numpy as np

from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.cfc_filter import cfc_filter
from gaitlog.host.kinematics.orientation import integrate_dcm

__all__ = [
    "JOINT_ANGLES",
    "JOINT_MATRICES",
    "HallJointKinematics",
    "apply_right_leg_convention",
    "joint_angles_xzy",
    "joint_angles_yxz",
    "joint_matrix_xzy",
    "joint_matrix_yxz",
    "remove_pretest_offset",
]


def joint_matrix_yxz(angles_rad: np.ndarray) -> np.ndarray:
    """Hall eq (3): the matrix ``T`` with ``{î_B} = T {î_A}`` for a ``y − x′ − z″`` rotation sequence.

    Parameters
    ----------
    angles_rad
        ``(..., 3)`` angles ``(φ, θ, ψ)`` in rad: φ about y, θ about x′, ψ about z″.

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)``; equals ``Rotation.from_euler("YXZ", angles).as_matrix().T``.

    Examples
    --------
    >>> T = joint_matrix_yxz(np.radians([40.0, -25.0, 10.0]))
    >>> np.round(np.degrees(joint_angles_yxz(T)[0]), 12) + 0.0
    array([ 40., -25.,  10.])
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    sf, cf = np.sin(a[..., 0]), np.cos(a[..., 0])
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    sp, cp = np.sin(a[..., 2]), np.cos(a[..., 2])
    t = np.empty(a.shape[:-1] + (3, 3))
    t[..., 0, 0] = cf * cp + sf * st * sp
    t[..., 0, 1] = ct * sp
    t[..., 0, 2] = -sf * cp + cf * st * sp
    t[..., 1, 0] = -cf * sp + sf * st * cp
    t[..., 1, 1] = ct * cp
    t[..., 1, 2] = sf * sp + cf * st * cp
    t[..., 2, 0] = sf * ct
    t[..., 2, 1] = -st
    t[..., 2, 2] = cf * ct
    return t


def joint_angles_yxz(t: np.ndarray, *, gimbal_tol_rad: float = np.radians(1.0)) -> tuple[np.ndarray, np.ndarray]:
    """``y − x′ − z″`` angles of joint matrices (Hall eq 4, corrected, in atan2 form).

    Parameters
    ----------
    t
        ``(..., 3, 3)`` joint matrices ``T = TB·TAᵀ``.
    gimbal_tol_rad
        Gimbal lock is reported where ``90° − |θ| < gimbal_tol_rad``; there φ and ψ are not separable
        (only ``φ ± ψ`` is) and the returned split is arbitrary.

    Returns
    -------
    angles_rad : numpy.ndarray
        ``(..., 3)`` ``(φ, θ, ψ)`` in rad, ``θ ∈ [−π/2, π/2]``, φ and ψ in ``(−π, π]``.
    gimbal_lock : numpy.ndarray
        ``(...)`` boolean.
    """
    t = np.asarray(t, dtype=np.float64)
    theta = np.arctan2(-t[..., 2, 1], np.hypot(t[..., 2, 0], t[..., 2, 2]))  # asin(−k_B·j_A)
    phi = np.arctan2(t[..., 2, 0], t[..., 2, 2])  # asin((k_B·i_A)/cos θ), quadrant kept
    psi = np.arctan2(t[..., 0, 1], t[..., 1, 1])  # asin((i_B·j_A)/cos θ), quadrant kept
    lock = (np.pi / 2 - np.abs(theta)) < gimbal_tol_rad
    return np.stack([phi, theta, psi], axis=-1), lock


def joint_matrix_xzy(angles_rad: np.ndarray) -> np.ndarray:
    """The joint matrix ``T`` (``{î_B} = T {î_A}``) of Hall's spine sequence ``x − z′ − y″``.

    Parameters
    ----------
    angles_rad
        ``(..., 3)`` ``(tilt about x, rotation about z′, flexion about y″)`` in rad.

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)`` ``(Rx Rz Ry)ᵀ``; equals ``Rotation.from_euler("XZY", angles).as_matrix().T``.

    Examples
    --------
    >>> T = joint_matrix_xzy(np.radians([15.0, -10.0, 30.0]))
    >>> np.round(np.degrees(joint_angles_xzy(T)[0]), 12) + 0.0
    array([ 15., -10.,  30.])
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    sa, ca = np.sin(a[..., 0]), np.cos(a[..., 0])
    sb, cb = np.sin(a[..., 1]), np.cos(a[..., 1])
    sc, cc = np.sin(a[..., 2]), np.cos(a[..., 2])
    m = np.empty(a.shape[:-1] + (3, 3))  # M = Rx(a) Rz(b) Ry(c), body A -> body B axes in A
    m[..., 0, 0], m[..., 0, 1], m[..., 0, 2] = cb * cc, -sb, cb * sc
    m[..., 1, 0] = ca * sb * cc + sa * sc
    m[..., 1, 1] = ca * cb
    m[..., 1, 2] = ca * sb * sc - sa * cc
    m[..., 2, 0] = sa * sb * cc - ca * sc
    m[..., 2, 1] = sa * cb
    m[..., 2, 2] = sa * sb * sc + ca * cc
    return np.swapaxes(m, -1, -2)


def joint_angles_xzy(t: np.ndarray, *, gimbal_tol_rad: float = np.radians(1.0)) -> tuple[np.ndarray, np.ndarray]:
    """``x − z′ − y″`` angles (tilt, rotation, flexion) of joint matrices ``T = TB·TAᵀ`` (Hall's spine).

    With ``M = Tᵀ = Rx(a) Rz(b) Ry(c)``: ``b = asin(−M01)``, ``a = atan2(M21, M11)``, ``c = atan2(M02, M00)``;
    gimbal lock where ``|b| → 90°``. Returns ``(angles_rad (..., 3), gimbal_lock (...))``.
    """
    m = np.swapaxes(np.asarray(t, dtype=np.float64), -1, -2)
    b = np.arctan2(-m[..., 0, 1], np.hypot(m[..., 0, 0], m[..., 0, 2]))
    a = np.arctan2(m[..., 2, 1], m[..., 1, 1])
    c = np.arctan2(m[..., 0, 2], m[..., 0, 0])
    lock = (np.pi / 2 - np.abs(b)) < gimbal_tol_rad
    return np.stack([a, b, c], axis=-1), lock


#: Joint-angle functions by sequence: lower limb and neck ``y − x′ − z″``, spine ``x − z′ − y″``.
JOINT_ANGLES = {"yxz": joint_angles_yxz, "xzy": joint_angles_xzy}
#: Joint matrices by sequence.
JOINT_MATRICES = {"yxz": joint_matrix_yxz, "xzy": joint_matrix_xzy}


def remove_pretest_offset(rate: np.ndarray, n_pretest: int) -> np.ndarray:
    """Subtract the mean of the first ``n_pretest`` samples from every channel (Hall: offset removal).

    Parameters
    ----------
    rate
        ``(n, k)`` angular rates (any unit; returned in the same unit).
    n_pretest
        Number of leading samples recorded before the test (sensor at rest). 0 leaves the data unchanged.
    """
    r = np.asarray(rate, dtype=np.float64)
    if n_pretest < 0 or n_pretest > r.shape[0]:
        raise HostError(f"pre-test window of {n_pretest} samples does not fit a recording of {r.shape[0]}")
    if n_pretest == 0:
        return r.copy()
    return r - r[:n_pretest].mean(axis=0)


def apply_right_leg_convention(angles: np.ndarray) -> np.ndarray:
    """Negate version (θ) and axial rotation (ψ) of ``(..., 3)`` ``(φ, θ, ψ)`` angles for a right leg."""
    out = np.array(angles, dtype=np.float64)
    out[..., 1:] *= -1.0
    return out


def _as_rate(name: str, x: np.ndarray) -> np.ndarray:
    r = np.asarray(x, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] != 3:
        raise HostError(f"{name} must have shape (n, 3) (rad/s), got {r.shape}")
    bad = ~np.isfinite(r).all(axis=1)
    if bad.any():
        raise HostError(f"{name} has non-finite values at sample {int(np.argmax(bad))}")
    return r


def _as_rotation(name: str, m: np.ndarray | None) -> np.ndarray:
    if m is None:
        return np.eye(3)
    a = np.asarray(m, dtype=np.float64)
    if a.shape != (3, 3) or not np.allclose(a @ a.T, np.eye(3), atol=1e-6) or np.linalg.det(a) < 0:
        raise HostError(
            f"{name} must be a 3x3 proper rotation matrix (orthonormal, det +1), got {a.tolist()}; note that "
            "Hall's printed eqs (5)-(6) have det -1: flip the sign of one row"
        )
    return a


class HallJointKinematics:
    """Joint angles of two links from two triaxial angular-rate sensors (Hall et al. 1997).

    Parameters
    ----------
    sensor_to_link_a, sensor_to_link_b
        ``S`` with ``{î_link} = S {î_sensor}`` (Hall eqs 5-6); default identity.
    initial_ta, initial_tb
        Link matrices (reference -> link) at the first sample; Hall sets ``TA = I`` and ``TB`` to the initial
        A-B matrix. Default identity (both links in the neutral position).
    pretest_samples
        Leading samples recorded at rest, whose mean is subtracted from each rate channel (step 1).
    cfc
        SAE J211 channel class for a zero-phase low-pass of the rates (step 2), or None for none.
    side
        ``"left"`` or ``"right"`` (step 6).
    angle_mode
        ``"absolute"`` (angles of ``TB·TAᵀ`` at each sample) or ``"incremental_sum"`` (Hall's abstract
        taken literally: the sum of the angles of the per-step increments ``T_k T_{k−1}ᵀ``).
    gimbal_tol_deg
        Gimbal lock is flagged where ``90° − |θ|`` is below this.
    sequence
        ``"yxz"`` (lower limb, neck: y − x′ − z″, angles (φ, θ, ψ)) or ``"xzy"`` (spine: tilt about x,
        rotation about z′, flexion about y″). The right-leg convention applies to ``"yxz"`` only.

    Attributes
    ----------
    rate_a_link_rad_s_, rate_b_link_rad_s_ : ``(n, 3)`` rates in link axes after steps 1-3.
    ta_, tb_ : ``(n, 3, 3)`` link matrices (reference -> link).
    joint_matrix_ : ``(n, 3, 3)`` ``T = TB·TAᵀ``.
    angles_rad_ : ``(n, 3)`` ``(φ, θ, ψ)`` after the side convention.
    gimbal_lock_ : ``(n,)`` boolean.
    """

    def __init__(
        self,
        *,
        sensor_to_link_a: np.ndarray | None = None,
        sensor_to_link_b: np.ndarray | None = None,
        initial_ta: np.ndarray | None = None,
        initial_tb: np.ndarray | None = None,
        pretest_samples: int = 0,
        cfc: float | None = None,
        side: Literal["left", "right"] = "left",
        angle_mode: Literal["absolute", "incremental_sum"] = "absolute",
        gimbal_tol_deg: float = 1.0,
        sequence: Literal["yxz", "xzy"] = "yxz",
    ) -> None:
        self.sequence = sequence
        self.sensor_to_link_a = sensor_to_link_a
        self.sensor_to_link_b = sensor_to_link_b
        self.initial_ta = initial_ta
        self.initial_tb = initial_tb
        self.pretest_samples = pretest_samples
        self.cfc = cfc
        self.side = side
        self.angle_mode = angle_mode
        self.gimbal_tol_deg = gimbal_tol_deg

    def compute(self, rate_a_rad_s: np.ndarray, rate_b_rad_s: np.ndarray, *, sampling_rate_hz: float) -> Self:
        """Process sensor rates (rad/s, sensor axes, ``(n, 3)`` each) sampled at ``sampling_rate_hz``."""
        if self.side not in ("left", "right"):
            raise HostError(f"side must be 'left' or 'right', not {self.side!r}")
        if self.sequence not in JOINT_ANGLES:
            raise HostError(f"sequence must be one of {sorted(JOINT_ANGLES)}, not {self.sequence!r}")
        if self.angle_mode not in ("absolute", "incremental_sum"):
            raise HostError(f"angle_mode must be 'absolute' or 'incremental_sum', not {self.angle_mode!r}")
        ra = _as_rate("rate_a_rad_s", rate_a_rad_s)
        rb = _as_rate("rate_b_rad_s", rate_b_rad_s)
        if ra.shape != rb.shape:
            raise HostError(f"the two sensors have different lengths: {ra.shape[0]} and {rb.shape[0]} samples")
        if ra.shape[0] < 2:
            raise HostError("need at least 2 samples of angular rate")
        sa = _as_rotation("sensor_to_link_a", self.sensor_to_link_a)
        sb = _as_rotation("sensor_to_link_b", self.sensor_to_link_b)
        ta0 = _as_rotation("initial_ta", self.initial_ta)
        tb0 = _as_rotation("initial_tb", self.initial_tb)
        # 1. pre-test offset
        ra = remove_pretest_offset(ra, self.pretest_samples)
        rb = remove_pretest_offset(rb, self.pretest_samples)
        # 2. SAE J211 filter
        if self.cfc is not None:
            ra, rb = cfc_filter(ra, self.cfc, sampling_rate_hz), cfc_filter(rb, self.cfc, sampling_rate_hz)
        # 3. sensor -> link axes
        self.rate_a_link_rad_s_ = ra @ sa.T
        self.rate_b_link_rad_s_ = rb @ sb.T
        # 4. trapezoidal incremental rotations, chained (λ = Tᵀ is body -> reference)
        lam_a = integrate_dcm(self.rate_a_link_rad_s_, sampling_rate_hz, ta0.T)
        lam_b = integrate_dcm(self.rate_b_link_rad_s_, sampling_rate_hz, tb0.T)
        self.ta_ = np.swapaxes(lam_a, 1, 2)
        self.tb_ = np.swapaxes(lam_b, 1, 2)
        # 5. joint matrix and angles
        self.joint_matrix_ = self.tb_ @ lam_a  # TB · TAᵀ
        tol = np.radians(self.gimbal_tol_deg)
        angles_of = JOINT_ANGLES[self.sequence]
        angles, lock = angles_of(self.joint_matrix_, gimbal_tol_rad=tol)
        if self.angle_mode == "incremental_sum":
            inc = self.joint_matrix_[1:] @ np.swapaxes(self.joint_matrix_[:-1], 1, 2)
            inc_angles, _ = angles_of(inc, gimbal_tol_rad=tol)
            angles = np.concatenate([angles[:1], angles[:1] + np.cumsum(inc_angles, axis=0)])
        if lock.any():
            warnings.warn(
                f"joint angles: gimbal lock (|θ| within {self.gimbal_tol_deg:g}° of 90°) at "
                f"{int(lock.sum())} samples, first at sample {int(np.argmax(lock))}; φ and ψ are not "
                "separable there",
                stacklevel=2,
            )
        # 6. side convention
        right = self.side == "right" and self.sequence == "yxz"
        self.angles_rad_ = apply_right_leg_convention(angles) if right else angles
        self.gimbal_lock_ = lock
        return self
