"""Orientation of a rigid segment from gravity and angular rate: the direction-cosine part of Morris (1973).

Convention (the whole project uses it)
--------------------------------------
A direction-cosine matrix ``λ`` (``dcm``, shape ``(..., 3, 3)``) maps **body** coordinates to **space**
coordinates, ``v_space = λ @ v_body``. Space axis 3 points **up**, so row 3 of ``λ`` is the unit "up"
direction in body axes, i.e. the direction of the specific force an accelerometer reads at rest (Morris'
``λ31, λ32, λ33 = g1, g2, g3``). Body angular rates ``ω`` (rad/s, body axes) give

.. math:: \\dot λ = λ [ω×],

which is Morris' eq (9) ``[λ̇] = [ω][λ]`` written for ``λᵀ`` with ``[ω] = −[ω×]``.

Contents
--------
- :func:`initial_dcm_from_gravity` -- eqs (12)-(16), corrected (see ``shared/seeds/README.md``), with the
  singular case (gravity along body axis 2) handled explicitly.
- :func:`integrate_dcm` -- strapdown integration of eq (9): incremental rotation (Rodrigues, exact for a
  constant rate), explicit trapezoid (Heun, Morris' "simple trapezoidal integration"), forward Euler; the
  per-step increments are computed vectorised and chained with a blocked prefix product (unit quaternions
  for the incremental rotations, 3x3 matrices for the others).
- :func:`orthonormalize_jordan` -- eq (18) with a divergence guard and an SVD fallback.
- :func:`skew`, :func:`rotation_increments`, :func:`cumulative_matmul`, :func:`orthogonality_error`,
  :func:`geodesic_distance_rad` -- the building blocks, also used by :mod:`gaitlog.host.kinematics.joints`.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np

from gaitlog.host.errors import HostError

__all__ = [
    "JordanResult",
    "cumulative_matmul",
    "geodesic_distance_rad",
    "initial_dcm_from_gravity",
    "integrate_dcm",
    "orthogonality_error",
    "orthonormalize_jordan",
    "rotation_increments",
    "skew",
]


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v×]`` so that ``skew(v) @ u == np.cross(v, u)``.

    Parameters
    ----------
    v
        ``(..., 3)`` vectors.

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)`` antisymmetric matrices.

    Examples
    --------
    >>> skew([1.0, 2.0, 3.0]) @ [4.0, 5.0, 6.0]
    array([-3.,  6., -3.])
    """
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def orthogonality_error(dcm: np.ndarray) -> np.ndarray:
    """Frobenius norm of ``λ λᵀ − I`` (Morris eq 17), per matrix; shape ``dcm.shape[:-2]``."""
    dcm = np.asarray(dcm, dtype=np.float64)
    return np.linalg.norm(dcm @ np.swapaxes(dcm, -1, -2) - np.eye(3), axis=(-2, -1))


def geodesic_distance_rad(dcm_a: np.ndarray, dcm_b: np.ndarray) -> np.ndarray:
    """Angle in rad of the rotation ``λaᵀ λb`` (both assumed orthonormal), per matrix.

    Computed as ``2·atan2(‖vector part‖, scalar part)``-equivalent
    ``atan2(‖skew part‖, (trace − 1)/2)``, accurate for small and large angles.
    """
    rel = np.swapaxes(np.asarray(dcm_a, dtype=np.float64), -1, -2) @ np.asarray(dcm_b, dtype=np.float64)
    cos_part = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    sin_vec = 0.5 * np.stack(
        [rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0], rel[..., 1, 0] - rel[..., 0, 1]],
        axis=-1,
    )
    return np.arctan2(np.linalg.norm(sin_vec, axis=-1), cos_part)


def initial_dcm_from_gravity(
    up_body: np.ndarray, *, on_singular: Literal["raise", "axis1"] = "raise", singular_tol: float = 1e-9
) -> np.ndarray:
    """Direction-cosine matrix from the gravity ("up") direction in body axes, Morris eqs (12)-(16).

    Row 3 is the unit up vector ``ĝ = (λ31, λ32, λ33)``; the free heading is fixed by ``λ12 = 0`` (space
    axis 1 has no component along body axis 2, i.e. space axis 2 is the horizontal projection of body
    axis 2). The printed eq (15) is wrong; the corrected set is

    .. math::
        λ22 = \\sqrt{1 − λ32^2},\\; λ21 = −λ31 λ32/λ22,\\; λ13 = λ21 λ32 − λ22 λ31,\\;
        λ23 = −λ32 λ33/λ22,\\; λ11 = λ22 λ33 − λ23 λ32.

    Parameters
    ----------
    up_body
        ``(..., 3)`` specific force at rest (any unit, e.g. g), i.e. the up direction in body axes.
        Normalised here.
    on_singular
        When gravity lies along body axis 2 (``λ22 < singular_tol``) the heading is undefined:
        ``"raise"`` raises :class:`HostError` naming the sample; ``"axis1"`` uses the horizontal
        projection of body axis 1 as space axis 1 instead (continuous with ``λ12 = 0`` at the singular
        point itself).
    singular_tol
        Threshold on ``λ22 = sqrt(1 − λ32²)`` (dimensionless).

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)`` rotation matrices with ``λ @ ĝ = (0, 0, 1)``.

    Examples
    --------
    >>> lam = initial_dcm_from_gravity([0.3, 0.5, 0.812404])
    >>> np.round(lam, 6) + 0.0
    array([[ 0.938083,  0.      , -0.34641 ],
           [-0.173205,  0.866025, -0.469042],
           [ 0.3     ,  0.5     ,  0.812404]])
    """
    g = np.asarray(up_body, dtype=np.float64)
    if g.shape[-1:] != (3,):
        raise HostError(f"initial_dcm_from_gravity: expected (..., 3) vectors, got shape {g.shape}")
    norm = np.linalg.norm(g, axis=-1, keepdims=True)
    bad = ~np.isfinite(norm[..., 0]) | (norm[..., 0] <= 0)
    if np.any(bad):
        where = np.argwhere(np.atleast_1d(bad))[0].tolist()
        raise HostError(f"initial_dcm_from_gravity: zero or non-finite gravity vector at index {where}")
    g = g / norm
    l31, l32, l33 = g[..., 0], g[..., 1], g[..., 2]
    l22 = np.sqrt(np.clip(1.0 - l32**2, 0.0, None))  # eq (12)
    singular = l22 < singular_tol
    safe = np.where(singular, 1.0, l22)
    l21 = -l31 * l32 / safe  # eq (13)
    l13 = l21 * l32 - l22 * l31  # eq (14)
    l23 = -l32 * l33 / safe  # eq (15), corrected
    l11 = l22 * l33 - l23 * l32  # eq (16)
    lam = np.empty(g.shape[:-1] + (3, 3))
    lam[..., 0, 0], lam[..., 0, 1], lam[..., 0, 2] = l11, 0.0, l13
    lam[..., 1, 0], lam[..., 1, 1], lam[..., 1, 2] = l21, l22, l23
    lam[..., 2, :] = g
    if np.any(singular):
        if on_singular == "raise":
            where = np.argwhere(np.atleast_1d(singular))[0].tolist()
            raise HostError(
                f"initial_dcm_from_gravity: gravity lies along body axis 2 at index {where} "
                f"(|g2| = {float(np.abs(np.atleast_1d(l32)[tuple(where)])):.12f}); the heading is undefined "
                "with λ12 = 0 -- pass on_singular='axis1' to reference the heading to body axis 1"
            )
        if on_singular != "axis1":
            raise ValueError(f"on_singular must be 'raise' or 'axis1', not {on_singular!r}")
        gs = g[singular]
        row1 = np.zeros_like(gs)
        row1[:, 0] = 1.0
        row1 -= gs[:, :1] * gs  # horizontal projection of body axis 1
        row1 /= np.linalg.norm(row1, axis=-1, keepdims=True)
        sub = np.empty(gs.shape[:-1] + (3, 3))
        sub[:, 0] = row1
        sub[:, 1] = np.cross(gs, row1)
        sub[:, 2] = gs
        lam[singular] = sub
    return lam


def _rodrigues_soa(phi: np.ndarray) -> np.ndarray:
    """``expm([φ×])`` for ``(m, 3)`` rotation vectors, returned component-first as ``(3, 3, m)``."""
    x, y, z = np.ascontiguousarray(phi.T)
    theta2 = x * x + y * y + z * z
    small = theta2 < 1e-8  # θ < 1e-4 rad: Taylor series (error < 1e-20)
    if small.all():
        a = 1.0 - theta2 * (1.0 / 6.0 - theta2 / 120.0)
        b = 0.5 - theta2 * (1.0 / 24.0 - theta2 / 720.0)
    else:
        theta = np.sqrt(np.where(small, 1.0, theta2))
        half_sin = np.sin(0.5 * theta)
        a = np.where(small, 1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0, np.sin(theta) / theta)
        b = np.where(small, 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0, 2.0 * half_sin * half_sin / theta2)
    out = np.empty((3, 3, phi.shape[0]))
    bx, by, bz = b * x, b * y, b * z
    ax, ay, az = a * x, a * y, a * z
    out[0, 0] = 1.0 + bx * x - b * theta2
    out[1, 1] = 1.0 + by * y - b * theta2
    out[2, 2] = 1.0 + bz * z - b * theta2
    out[0, 1], out[1, 0] = bx * y - az, bx * y + az
    out[0, 2], out[2, 0] = bx * z + ay, bx * z - ay
    out[1, 2], out[2, 1] = by * z - ax, by * z + ax
    return out


def rotation_increments(rotvec_rad: np.ndarray) -> np.ndarray:
    """Rotation matrices ``expm([φ×])`` of rotation vectors, by Rodrigues' formula (vectorised).

    Parameters
    ----------
    rotvec_rad
        ``(..., 3)`` rotation vectors in rad.

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)`` rotation matrices ``I + a[φ×] + b[φ×]²`` with ``a = sin θ/θ``,
        ``b = (1 − cos θ)/θ²`` (Taylor series below 1e-4 rad).

    Examples
    --------
    >>> np.round(rotation_increments([0.0, 0.0, np.pi / 2]), 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    phi = np.asarray(rotvec_rad, dtype=np.float64)
    flat = phi.reshape(-1, 3)
    return np.moveaxis(_rodrigues_soa(flat), -1, 0).reshape(phi.shape[:-1] + (3, 3))


def _mm_soa(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """3x3 products of component-first arrays ``(3, 3, ...)`` (broadcasting over the trailing axes)."""
    if out is None:
        out = np.empty((3, 3) + np.broadcast_shapes(a.shape[2:], b.shape[2:]))
    for i in range(3):
        a0, a1, a2 = a[i, 0], a[i, 1], a[i, 2]
        for k in range(3):
            o = out[i, k]
            np.multiply(a0, b[0, k], out=o)
            o += a1 * b[1, k]
            o += a2 * b[2, k]
    return out


def _scan_soa(s: np.ndarray, block: int) -> np.ndarray:
    """Inclusive prefix products ``s0 s1 … sk`` of component-first ``(3, 3, m)`` matrices (blocked scan)."""
    m = s.shape[2]
    if m <= 2 * block:
        out = np.empty_like(s)
        if m:
            out[:, :, 0] = s[:, :, 0]
        for k in range(1, m):
            out[:, :, k] = out[:, :, k - 1] @ s[:, :, k]
        return out
    nb = -(-m // block)
    pad = nb * block - m
    if pad:
        s = np.concatenate([s, np.broadcast_to(np.eye(3)[:, :, None], (3, 3, pad))], axis=2)
    blk = np.ascontiguousarray(s.reshape(3, 3, nb, block).transpose(0, 1, 3, 2))  # (3, 3, block, nb)
    inner = np.empty_like(blk)  # inner[..., i, j]: product of the first i+1 steps of block j
    inner[:, :, 0] = blk[:, :, 0]
    for i in range(1, block):
        _mm_soa(inner[:, :, i - 1], blk[:, :, i], out=inner[:, :, i])
    totals = _scan_soa(np.ascontiguousarray(inner[:, :, -1]), block)  # inclusive over blocks
    out = np.empty_like(inner)
    out[:, :, :, 0] = inner[:, :, :, 0]
    _mm_soa(totals[:, :, None, :-1], inner[:, :, :, 1:], out=out[:, :, :, 1:])
    return out.transpose(0, 1, 3, 2).reshape(3, 3, nb * block)[:, :, :m]


def _chain_soa(initial: np.ndarray, steps_soa: np.ndarray, block: int = 16) -> np.ndarray:
    m = steps_soa.shape[2]
    out = np.empty((m + 1, 3, 3))
    out[0] = initial
    if m:
        steps_soa = np.array(steps_soa, dtype=np.float64, order="C")
        steps_soa[:, :, 0] = initial @ steps_soa[:, :, 0]  # fold the start into the first step
        out[1:] = np.moveaxis(_scan_soa(steps_soa, block), -1, 0)
    return out


def _qmul_soa(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Hamilton products of component-first quaternions ``(4, ...)`` (scalar first), broadcasting."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    if out is None:
        out = np.empty((4,) + np.broadcast_shapes(a0.shape, b0.shape))
    out[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3
    out[1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2
    out[2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1
    out[3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0
    return out


def _scan_quat(s: np.ndarray, block: int = 16) -> np.ndarray:
    """Inclusive prefix products of component-first ``(4, m)`` quaternions (blocked scan, as :func:`_scan_soa`)."""
    m = s.shape[1]
    if m <= 2 * block:
        out = np.empty_like(s)
        if m:
            out[:, 0] = s[:, 0]
        for k in range(1, m):
            out[:, k] = _qmul_soa(out[:, k - 1], s[:, k])
        return out
    nb = -(-m // block)
    pad = nb * block - m
    if pad:
        unit = np.zeros((4, pad))
        unit[0] = 1.0
        s = np.concatenate([s, unit], axis=1)
    blk = np.ascontiguousarray(s.reshape(4, nb, block).transpose(0, 2, 1))  # (4, block, nb)
    inner = np.empty_like(blk)
    inner[:, 0] = blk[:, 0]
    for i in range(1, block):
        _qmul_soa(inner[:, i - 1], blk[:, i], out=inner[:, i])
    totals = _scan_quat(np.ascontiguousarray(inner[:, -1]), block)
    out = np.empty_like(inner)
    out[:, :, 0] = inner[:, :, 0]
    _qmul_soa(totals[:, None, :-1], inner[:, :, 1:], out=out[:, :, 1:])
    return out.transpose(0, 2, 1).reshape(4, nb * block)[:, :m]


def _rotvec_to_quat_soa(phi: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(cos(θ/2), sin(θ/2)·φ/θ)`` of ``(m, 3)`` rotation vectors, as ``(4, m)``."""
    x, y, z = np.ascontiguousarray(phi.T)
    theta = np.sqrt(x * x + y * y + z * z)
    small = theta < 1e-4
    half = 0.5 * theta
    scale = np.where(small, 0.5 - theta * theta / 48.0, np.sin(half) / np.where(small, 1.0, theta))
    q = np.empty((4, phi.shape[0]))
    q[0] = np.cos(half)
    q[1], q[2], q[3] = scale * x, scale * y, scale * z
    return q


def _quat_to_dcm_into(q: np.ndarray, out: np.ndarray) -> None:
    """Write the rotation matrices of component-first unit quaternions ``(4, m)`` into ``out`` ``(m, 3, 3)``."""
    a, b, c, d = q
    aa, bb, cc, dd = a * a, b * b, c * c, d * d
    ab, ac, ad, bc, bd, cd = a * b, a * c, a * d, b * c, b * d, c * d
    out[:, 0, 0] = aa + bb - cc - dd
    out[:, 0, 1] = 2.0 * (bc - ad)
    out[:, 0, 2] = 2.0 * (bd + ac)
    out[:, 1, 0] = 2.0 * (bc + ad)
    out[:, 1, 1] = aa - bb + cc - dd
    out[:, 1, 2] = 2.0 * (cd - ab)
    out[:, 2, 0] = 2.0 * (bd - ac)
    out[:, 2, 1] = 2.0 * (cd + ab)
    out[:, 2, 2] = aa - bb - cc + dd


def _dcm_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar first) of one rotation matrix (Shepperd's method)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    cands = (tr, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(cands))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif k == 1:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif k == 2:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def _rodrigues_chain(lam0: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """``λ0 · expm([φ1×]) ⋯ expm([φk×])`` for every k, composed as unit quaternions (fewer operations than
    3x3 products, same rotations) and returned as ``(m + 1, 3, 3)`` matrices."""
    m = phi.shape[0]
    out = np.empty((m + 1, 3, 3))
    out[0] = lam0
    if m == 0:
        return out
    q = _rotvec_to_quat_soa(phi)
    proper = orthogonality_error(lam0) < 1e-12 and np.linalg.det(lam0) > 0
    if proper:
        q[:, 0] = _qmul_soa(_dcm_to_quat(lam0), q[:, 0])
    _quat_to_dcm_into(_scan_quat(q), out[1:])
    if not proper:  # a start matrix that is not a rotation is carried along as given
        out[1:] = lam0 @ out[1:]
    return out


def cumulative_matmul(initial: np.ndarray, steps: np.ndarray, *, block: int = 16) -> np.ndarray:
    """Prefix products ``P[0] = initial``, ``P[k] = P[k−1] @ steps[k−1]``.

    The recursion is evaluated as a blocked scan: the steps are cut into blocks of ``block``, the products
    inside every block are formed for all blocks at once (component-wise, one vector operation per matrix
    element and position in the block), the block totals are scanned the same way (recursively), and each
    block is finally premultiplied by the product of everything before it. About three matrix products per
    step, all vectorised; the Python overhead is ``O(block · log m)`` instead of ``O(m)``. Rounding differs
    from the sequential order only by re-association (~1e-15 per product).

    Parameters
    ----------
    initial
        ``(3, 3)`` start matrix.
    steps
        ``(m, 3, 3)`` per-step matrices.
    block
        Block length.

    Returns
    -------
    numpy.ndarray
        ``(m + 1, 3, 3)``.

    Examples
    --------
    >>> steps = rotation_increments(np.tile([0.0, 0.0, np.pi / 8], (4, 1)))
    >>> np.round(cumulative_matmul(np.eye(3), steps)[-1], 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    steps = np.asarray(steps, dtype=np.float64)
    return _chain_soa(np.asarray(initial, dtype=np.float64), np.moveaxis(steps, 0, -1), block)


def integrate_dcm(
    omega_rad_s: np.ndarray,
    sampling_rate_hz: float,
    dcm0: np.ndarray | None = None,
    *,
    method: Literal["rodrigues", "heun", "euler"] = "rodrigues",
    coning_correction: bool = False,
    jordan_each_step: bool = False,
) -> np.ndarray:
    """Strapdown integration of ``λ̇ = λ[ω×]`` (Morris eqs 9-10) over regularly sampled body rates.

    Parameters
    ----------
    omega_rad_s
        ``(n, 3)`` body angular velocity in rad/s at the sample times.
    sampling_rate_hz
        Sampling rate in Hz.
    dcm0
        ``(3, 3)`` orientation at the first sample (default identity).
    method
        ``"rodrigues"`` (incremental rotation): step ``k`` applies ``expm([φk×])`` with the trapezoidal
        angle ``φk = (ωk + ωk+1)·Δt/2``; exact for a constant rate and orthonormal to round-off (the
        increments are composed as unit quaternions and converted to matrices once).
        ``"heun"``: explicit trapezoid (predictor-corrector) on the matrix ODE,
        ``λk+1 = λk (I + Δt/2 ([ωk×] + [ωk+1×]) + Δt²/2 [ωk×][ωk+1×])``; second order, drifts from
        orthogonality. ``"euler"``: ``λk+1 = λk (I + Δt[ωk×])``, first order, for comparison.
    coning_correction
        Rodrigues only: add the two-sample coning term ``Δt²/12 · ωk × ωk+1`` (Bortz 1970) to ``φk``.
    jordan_each_step
        Apply one Jordan step (eq 18) after every step. This makes the recursion non-linear, so it runs as
        a per-sample loop (slow, but it is the method that keeps ``‖λλᵀ − I‖`` near 1e-10 over minutes).

    Returns
    -------
    numpy.ndarray
        ``(n, 3, 3)`` direction-cosine matrices, ``dcm[0] = dcm0``.
    """
    w = np.asarray(omega_rad_s, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != 3:
        raise HostError(f"integrate_dcm: omega_rad_s must have shape (n, 3), got {w.shape}")
    if not np.isfinite(w).all():
        raise HostError(f"integrate_dcm: omega_rad_s has non-finite values at row {int(np.argwhere(~np.isfinite(w))[0, 0])}")
    if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise HostError(f"integrate_dcm: sampling_rate_hz must be positive, got {sampling_rate_hz!r}")
    lam0 = np.eye(3) if dcm0 is None else np.asarray(dcm0, dtype=np.float64)
    if lam0.shape != (3, 3):
        raise HostError(f"integrate_dcm: dcm0 must be 3x3, got {lam0.shape}")
    if w.shape[0] == 0:
        return np.zeros((0, 3, 3))
    dt = 1.0 / sampling_rate_hz
    if method == "rodrigues":
        phi = 0.5 * dt * (w[:-1] + w[1:])
        if coning_correction:
            phi = phi + dt * dt / 12.0 * np.cross(w[:-1], w[1:])
        if not jordan_each_step:
            return _rodrigues_chain(lam0, phi)
        steps = _rodrigues_soa(phi)
    elif method == "heun":
        k0, k1 = np.moveaxis(skew(w[:-1]), 0, -1), np.moveaxis(skew(w[1:]), 0, -1)
        steps = 0.5 * dt * (k0 + k1) + 0.5 * dt * dt * _mm_soa(k0, k1)
        steps += np.eye(3)[:, :, None]
    elif method == "euler":
        steps = np.eye(3)[:, :, None] + dt * np.moveaxis(skew(w[:-1]), 0, -1)
    else:
        raise ValueError(f"method must be 'rodrigues', 'heun' or 'euler', not {method!r}")
    if not jordan_each_step:
        return _chain_soa(lam0, steps)
    steps = np.moveaxis(steps, -1, 0)
    out = np.empty((w.shape[0], 3, 3))
    out[0] = lam = lam0
    eye = np.eye(3)
    for k in range(steps.shape[0]):  # genuinely recursive: orthonormalise the running matrix
        lam = lam @ steps[k]
        lam = lam @ (eye - 0.5 * (lam.T @ lam - eye))
        out[k + 1] = lam
    return out


class JordanResult(NamedTuple):
    """Result of :func:`orthonormalize_jordan` with ``return_info=True``."""

    dcm: np.ndarray  #: ``(..., 3, 3)`` orthonormal matrices
    iterations: int  #: Jordan iterations used (maximum over the batch)
    fallback: np.ndarray  #: boolean ``(...)``: True where the SVD fallback was used


def orthonormalize_jordan(
    dcm: np.ndarray,
    *,
    tol: float = 1e-12,
    max_iter: int = 8,
    fallback: Literal["svd", "raise"] = "svd",
    return_info: bool = False,
) -> np.ndarray | JordanResult:
    """Nearest rotation by Jordan's iteration (Morris eq 18), with a divergence guard.

    .. math:: λ_{n+1} = λ_n \\left(I − \\tfrac12 (λ_n^T λ_n − I)\\right)

    iterated until ``‖λλᵀ − I‖_F < tol``. Each singular value ``σ`` maps to ``σ(3 − σ²)/2``, which converges
    (quadratically) to 1, i.e. to the polar factor, for ``0 < σ < √3``; above ``√3`` it changes sign and
    the determinant can flip. Guard: the iteration is only used where ``det λ > 0`` and
    ``‖λᵀλ − I‖_F < 1`` (then every ``σ² ∈ (0, 2)`` and the iterates stay there); other matrices, and any
    that fail to converge in ``max_iter`` steps, get the nearest rotation from an SVD
    (``U diag(1, 1, det(UVᵀ)) Vᵀ``), or raise :class:`HostError` when ``fallback="raise"``.

    Parameters
    ----------
    dcm
        ``(..., 3, 3)`` nearly orthogonal matrices.
    tol
        Target Frobenius norm of ``λλᵀ − I``.
    max_iter
        Iteration limit.
    fallback
        ``"svd"`` or ``"raise"``.
    return_info
        Return a :class:`JordanResult` instead of the matrices only.

    Examples
    --------
    >>> out = orthonormalize_jordan(np.eye(3) + 1e-2 * np.arange(9.0).reshape(3, 3) / 8, return_info=True)
    >>> bool(orthogonality_error(out.dcm) < 1e-12), out.iterations <= 4
    (True, True)
    """
    lam = np.array(dcm, dtype=np.float64)
    if lam.shape[-2:] != (3, 3):
        raise HostError(f"orthonormalize_jordan: expected (..., 3, 3) matrices, got {lam.shape}")
    batch = lam.shape[:-2]
    lam = lam.reshape(-1, 3, 3)
    eye = np.eye(3)
    finite = np.isfinite(lam).all(axis=(1, 2))
    gram_err = np.full(lam.shape[0], np.inf)
    gram_err[finite] = np.linalg.norm(np.swapaxes(lam[finite], 1, 2) @ lam[finite] - eye, axis=(1, 2))
    det = np.where(finite, np.linalg.det(np.where(finite[:, None, None], lam, 0.0)), -1.0)
    use_jordan = finite & (det > 0) & (gram_err < 1.0)
    iterations = 0
    active = use_jordan & (orthogonality_error(np.where(finite[:, None, None], lam, 0.0)) >= tol)
    while np.any(active) and iterations < max_iter:
        x = lam[active]
        lam[active] = x @ (eye - 0.5 * (np.swapaxes(x, 1, 2) @ x - eye))  # eq (18)
        iterations += 1
        active &= orthogonality_error(lam) >= tol
    need = ~use_jordan | active
    if np.any(need):
        if fallback == "raise":
            idx = np.argwhere(need.reshape(batch) if batch else need)[0].tolist()
            raise HostError(
                f"orthonormalize_jordan: matrix at index {idx} is outside the Jordan convergence region "
                "(det <= 0, ‖λᵀλ − I‖ >= 1, non-finite, or not converged); use fallback='svd'"
            )
        if not np.isfinite(lam[need]).all():
            raise HostError("orthonormalize_jordan: non-finite matrix cannot be orthonormalised")
        u, _, vt = np.linalg.svd(np.array(dcm, dtype=np.float64).reshape(-1, 3, 3)[need])
        d = np.sign(np.linalg.det(u @ vt))
        d = np.where(d == 0, 1.0, d)
        u[:, :, 2] *= d[:, None]
        lam[need] = u @ vt
    out = lam.reshape(batch + (3, 3))
    if return_info:
        return JordanResult(out, iterations, need.reshape(batch))
    return out
