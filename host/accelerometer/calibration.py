r"""Accelerometer calibration from static poses: offsets, scales and axis non-orthogonality.

The model is the non-orthogonal one of Krohn et al. (2005) [1]_, the calibration the logger paper
(Alvarez et al. 2006) cites, with its orthogonal special case.

Sensor model
------------
Sensor axis ``j`` has offset ``b_j`` and gain ``k_j`` (input unit per g) along a unit sensitive direction
``s_j``; at rest, with specific force ``a`` (|a| = 1 g),

.. math:: r_j = b_j + k_j \, s_j \cdot a \qquad (1)

The three non-orthogonality angles are the deviations from 90 deg of the angles between the sensitive axes,
``theta_xy, theta_xz, theta_yz`` with :math:`s_i \cdot s_j = \sin\theta_{ij}`. They fix the Gram matrix

.. math:: G = S S^\mathsf{T}, \qquad G_{ii} = 1, \; G_{ij} = \sin\theta_{ij} \qquad (2)

(rows of ``S`` are the ``s_j``), which is all a gravity-only calibration can see: the mounting rotation of the
whole triad is not observable from |a| = 1 g (see ``shared/notes/CALIBRATION-KINEMATICS.md``). Inverting (1)
with ``u = K^{-1}(r - b)``, ``K = diag(k)``:

.. math:: a = S^{-1} u, \qquad |a|^2 = u^\mathsf{T} G^{-1} u \qquad (3)

**Frame.** We state ``S`` in the orthogonal frame whose z axis is the sensor's z axis and whose y-z plane
holds the sensor's y axis, i.e. ``S`` is the upper-triangular factor of ``G = S S^T`` with positive diagonal.
The calibrated output is then

.. math:: \text{calibrated\_g} = M (r - b), \qquad M = S^{-1} K^{-1} \qquad (4)

with ``M`` upper-triangular; with ``S^{-1} = T D`` (``T`` unit upper-triangular, ``D`` diagonal) this is the
notes' ``f = T K' (r - b)`` with ``K' = D K^{-1}``.

Krohn's two variants: the **orthogonal model** ("6-param": 3 offsets, 3 gains, ``G = I``) and the
**non-orthogonal model** ("9-param": plus the 3 angles, the default). Both fit

.. math:: \rho_i(p) = \sqrt{u_i^\mathsf{T} G^{-1} u_i} - 1 \quad [\mathrm{g}], \qquad
          \min_p \sum_i \rho_i^2 \qquad (5)

over the static pose means ``r_i`` by Levenberg-Marquardt (``scipy.optimize.least_squares(method="lm")``)
with the analytic Jacobian (``v = G^{-1} u``, ``n = |a|``):

.. math:: \partial\rho/\partial b_j = -v_j/(n k_j), \quad \partial\rho/\partial k_j = -v_j u_j/(n k_j),
          \quad \partial\rho/\partial\theta_{ij} = -v_i v_j \cos\theta_{ij} / n \qquad (6)

The start is an algebraic ellipsoid fit (quadric ``x^T A x + 2 d^T x = 1``; centre ``c = -A^{-1} d``,
``M^T M = A' = A / (1 + c^T A c)``; then ``k_j = sqrt((A'^{-1})_{jj})`` and ``G = K^{-1} A'^{-1} K^{-1}``, since
``M^T M = K^{-1} G^{-1} K^{-1}``; axis-aligned quadric for the orthogonal model).

Precision through the 10-bit logger
-----------------------------------
Each pose mean averages ``N`` samples (150 for a 3 s hold at 50 Hz, fewer after trimming). With sensor noise
``sigma_s`` and the ADC step ``q = 4 g / 1024 = 3.906 mg``, the quantisation error of a dithered Gaussian
input is close to uniform and independent of the signal, so each axis of a pose mean carries

.. math:: \sigma_p = \sqrt{(\sigma_s^2 + q^2/12)/N} \qquad (7)

(1.13 mg rms for quantisation alone, 0.19 mg per pose mean with ``sigma_s`` = 2 mg and ``N`` = 140), plus a
deterministic bias: the mean of a quantised Gaussian differs from its input by at most

.. math:: \beta = \frac{q}{\pi} e^{-2\pi^2 \sigma_s^2 / q^2} \qquad (8)

(first Fourier term of the quantiser's error, valid for ``sigma_s`` above ~``q/4``; 3e-3 mg at ``sigma_s`` =
2 mg, 0.34 mg at 1 mg). With a noiseless sensor the quantisation is deterministic, the error does not average
out at all and reaches ``q/2`` = 1.95 mg per axis; such holds also read one constant code and are rejected as
stuck by the rest detection. The emulated ADXL202 (200 ug/sqrt(Hz), 20 Hz filter: ``sigma_s`` = 1.1 mg) gives
``sigma_p`` = 0.12 mg and ``beta`` = 0.32 mg for 5 s holds. A parameter
``p_m`` of the linearised least-squares fit (``J`` the Jacobian (6) at the solution, ``P = (J^T J)^{-1} J^T``)
is then off by at most

.. math:: |\Delta p_m| \le 4 \sigma_p \sqrt{\textstyle\sum_i P_{mi}^2} \;+\; \sqrt{3}\,\beta \sum_i |P_{mi}|
          \qquad (9)

(four standard deviations of the noise term, plus the worst case of the bias term). :func:`parameter_bounds`
evaluates (9) for a given pose set; the emulator test checks the recovered parameters against it.

References
----------
.. [1] A. Krohn, M. Beigl, C. Decker, U. Kochendörfer, P. Robinson, T. Zimmer, "Inexpensive and automatic
   calibration for acceleration sensors", Ubiquitous Computing Systems (UCS 2004), LNCS 3598, Springer 2005,
   pp. 245-258.
.. [2] B. Widrow, I. Kollár, M.-C. Liu, "Statistical theory of quantization", IEEE Trans. Instrum. Meas. 45(2),
   1996 (the bias term (8)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Self

import numpy as np

from host.accelerometer.static_windows import StaticWindow, StaticWindowDetector
from host.errors import HostError
from host.files.versioned_json import VersionedJson

#: Number of parameters of each model.
MODELS: dict[str, int] = {"9-param": 9, "6-param": 6}
#: Units an :class:`AccCalibration` can take as input.
INPUT_UNITS = ("counts", "g")
#: Axis pairs of the three non-orthogonality angles, in the order of ``angles_deg``.
ANGLE_PAIRS = ((0, 1), (0, 2), (1, 2))
ANGLE_NAMES = ("xy", "xz", "yz")
_AXES = "xyz"


class CalibrationError(HostError, ValueError):
    """A calibration cannot be fitted, loaded or applied; the message says why and where."""


# --------------------------------------------------------------------------------------------------------------
# Geometry of the model, eqs (2)-(4)


def gram_from_angles(angles_rad: np.ndarray) -> np.ndarray:
    """Gram matrix ``G`` of the sensitive axes from the non-orthogonality angles, eq (2).

    Parameters
    ----------
    angles_rad
        ``(3,)`` ``theta_xy, theta_xz, theta_yz`` in radians.

    Returns
    -------
    ``(3, 3)`` symmetric, unit diagonal, ``G_ij = sin(theta_ij)``.

    Examples
    --------
    >>> gram_from_angles(np.radians([30.0, 0.0, 0.0])).round(3)
    array([[1. , 0.5, 0. ],
           [0.5, 1. , 0. ],
           [0. , 0. , 1. ]])
    """
    s = np.sin(np.asarray(angles_rad, dtype=np.float64))
    return np.array([[1.0, s[0], s[1]], [s[0], 1.0, s[2]], [s[1], s[2], 1.0]])


def axes_matrix(angles_rad: np.ndarray) -> np.ndarray:
    """Sensitive directions ``S`` (rows, unit vectors) in the upper-triangular frame of eq (4).

    ``S`` is upper-triangular with positive diagonal and ``S @ S.T = G``: sensor z is the frame's z axis and
    sensor y lies in the frame's y-z plane.

    Examples
    --------
    >>> S = axes_matrix(np.radians([1.0, -0.5, 0.8]))
    >>> bool(np.allclose(np.linalg.norm(S, axis=1), 1.0)), bool(np.allclose(np.tril(S, -1), 0.0))
    (True, True)
    >>> round(float(np.degrees(np.arcsin(S[0] @ S[1]))), 12)
    1.0
    """
    g = gram_from_angles(angles_rad)
    flip = g[::-1, ::-1]
    try:
        low = np.linalg.cholesky(flip)
    except np.linalg.LinAlgError as err:
        raise CalibrationError(f"angles {np.degrees(angles_rad)} deg do not describe three independent axes") \
            from err
    return low[::-1, ::-1]


def calibration_matrix(scale_per_g: np.ndarray, angles_rad: np.ndarray) -> np.ndarray:
    """``M = S^{-1} K^{-1}`` of eq (4): g per input unit, upper-triangular.

    Examples
    --------
    >>> calibration_matrix(np.array([2.0, 4.0, 5.0]), np.zeros(3))
    array([[0.5 , 0.  , 0.  ],
           [0.  , 0.25, 0.  ],
           [0.  , 0.  , 0.2 ]])
    """
    s = axes_matrix(angles_rad)
    return np.linalg.inv(s) / np.asarray(scale_per_g, dtype=np.float64)[None, :]


# --------------------------------------------------------------------------------------------------------------
# The result


def _vector(value: Any, n: int, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (n,):
        raise CalibrationError(f"{what} must have shape ({n},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise CalibrationError(f"{what} contains NaN or infinite values: {arr}")
    return arr


@dataclass(frozen=True, eq=False)
class AccCalibration(VersionedJson):
    """A fitted accelerometer calibration: ``calibrated_g = matrix @ (raw - offset)``, eq (4).

    Attributes
    ----------
    model
        ``"9-param"`` (non-orthogonal, Krohn et al. 2005) or ``"6-param"`` (orthogonal).
    input_unit
        ``"counts"`` (ADC codes) or ``"g"`` (nominally scaled data); :meth:`apply` checks it.
    offset
        ``(3,)`` ``b``, input unit: the reading at 0 g.
    scale_per_g
        ``(3,)`` ``k``, input unit per g along each sensitive axis.
    angles_deg
        ``(3,)`` non-orthogonality ``theta_xy, theta_xz, theta_yz``, degrees (0 for the orthogonal model).
    matrix
        ``(3, 3)`` ``M = S^{-1} K^{-1}``, g per input unit. With ``offset``, the whole map.
    residual_rms_g, residual_max_g
        RMS and largest ``| |a_i| - 1 g |`` over the poses used, g.
    n_poses
        Number of static poses fitted.
    pose_residuals_g
        ``(n_poses,)`` ``|a_i| - 1`` per pose, g.
    chi2_per_dof
        Goodness of fit: ``sum (rho_i / sigma_i)^2 / (n_poses - n_params)`` with ``sigma_i`` the standard error
        of pose ``i``'s ``|a|`` from the spread of its samples (eq (7)); about 1 when the model explains the
        poses down to their noise, much larger when it does not. ``None`` when unknown (no per-pose spread
        given, or no degrees of freedom).
    min_direction_sv
        Smallest singular value of the ``(n_poses, 3)`` matrix of unit pose directions divided by
        ``sqrt(n_poses)``: 0.577 for perfectly spread poses, 0 when a direction is never observed.
    """

    SCHEMA: ClassVar[str] = "gaitlog.AccCalibration"
    FORMAT_VERSION: ClassVar[str] = "1.0"
    KIND: ClassVar[str] = "accelerometer calibration"
    ERROR: ClassVar[type[HostError]] = CalibrationError
    REDO: ClassVar[str] = "re-run 'gaitlog calibrate'"

    model: str
    input_unit: str
    offset: np.ndarray
    scale_per_g: np.ndarray
    angles_deg: np.ndarray
    matrix: np.ndarray
    residual_rms_g: float
    residual_max_g: float
    n_poses: int
    pose_residuals_g: np.ndarray = field(default_factory=lambda: np.zeros(0))
    chi2_per_dof: float | None = None
    min_direction_sv: float = float("nan")

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise CalibrationError(f"model must be one of {sorted(MODELS)}, got {self.model!r}")
        if self.input_unit not in INPUT_UNITS:
            raise CalibrationError(f"input_unit must be one of {INPUT_UNITS}, got {self.input_unit!r}")
        object.__setattr__(self, "offset", _vector(self.offset, 3, "offset"))
        object.__setattr__(self, "scale_per_g", _vector(self.scale_per_g, 3, "scale_per_g"))
        object.__setattr__(self, "angles_deg", _vector(self.angles_deg, 3, "angles_deg"))
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape != (3, 3) or not np.isfinite(m).all():
            raise CalibrationError(f"matrix must be a finite (3, 3) array, got shape {m.shape}")
        object.__setattr__(self, "matrix", m)
        if (self.scale_per_g <= 0).any():
            raise CalibrationError(f"scale_per_g must be positive, got {self.scale_per_g}")
        if (np.abs(self.angles_deg) >= 45).any():
            raise CalibrationError(f"angles_deg must be within +-45 deg, got {self.angles_deg}")
        if self.model == "6-param" and (self.angles_deg != 0).any():
            raise CalibrationError(f"the 6-param model has no angles, got {self.angles_deg}")
        expect = calibration_matrix(self.scale_per_g, np.radians(self.angles_deg))
        if not np.allclose(m, expect, rtol=1e-9, atol=1e-12 * float(np.abs(expect).max())):
            raise CalibrationError("matrix does not equal S^-1 K^-1 of scale_per_g and angles_deg "
                                   f"(largest difference {float(np.abs(m - expect).max()):.3g})")
        object.__setattr__(self, "pose_residuals_g", np.asarray(self.pose_residuals_g, dtype=np.float64))
        if self.pose_residuals_g.ndim != 1:
            raise CalibrationError("pose_residuals_g must be one-dimensional")
        if not isinstance(self.n_poses, int | np.integer) or self.n_poses < 0:
            raise CalibrationError(f"n_poses must be a non-negative integer, got {self.n_poses!r}")
        object.__setattr__(self, "n_poses", int(self.n_poses))

    @property
    def n_params(self) -> int:
        """Number of fitted parameters of the model (9 or 6)."""
        return MODELS[self.model]

    # ---------------------------------------------------------------------------------------------- apply
    def apply(self, x: np.ndarray, unit: str | None = None) -> np.ndarray:
        """Calibrated specific force in g: ``(x - offset) @ matrix.T`` (eq (4) row-wise).

        Parameters
        ----------
        x
            ``(..., 3)`` readings in :attr:`input_unit`; NaN passes through (missing samples stay missing).
        unit
            The unit of ``x``; checked against :attr:`input_unit` when given.

        Examples
        --------
        >>> cal = AccCalibration.from_parameters(offset=[512, 512, 512], scale_per_g=[256, 256, 256],
        ...                                      input_unit="counts")
        >>> cal.apply(np.array([[512, 768, 256]]), unit="counts")
        array([[ 0.,  1., -1.]])
        """
        if unit is not None and unit != self.input_unit:
            raise CalibrationError(f"this calibration takes {self.input_unit}, but the data are in {unit}")
        arr = np.asarray(x, dtype=np.float64)
        if arr.shape[-1:] != (3,):
            raise CalibrationError(f"readings must have shape (..., 3), got {arr.shape}")
        return (arr - self.offset) @ self.matrix.T

    def inverse(self, acc_g: np.ndarray) -> np.ndarray:
        """Readings in :attr:`input_unit` that :meth:`apply` maps to ``acc_g`` (``(..., 3)``, g)."""
        arr = np.asarray(acc_g, dtype=np.float64)
        if arr.shape[-1:] != (3,):
            raise CalibrationError(f"accelerations must have shape (..., 3), got {arr.shape}")
        return arr @ np.linalg.inv(self.matrix).T + self.offset

    def to_header_calibration(self) -> Any:
        """The device header's calibration slot (``protocol.header.Calibration``, PROTOCOL.md 2.1).

        Only a calibration of ADC counts fits the slot (``a_g = M (codes - offset)``).
        """
        if self.input_unit != "counts":
            raise CalibrationError("only a calibration of ADC counts can go in the device header, "
                                   f"this one takes {self.input_unit}")
        from protocol.header import Calibration

        return Calibration(offset_counts=self.offset.copy(), matrix_g_per_count=self.matrix.copy(), valid=True)

    # ---------------------------------------------------------------------------------------------- build
    @classmethod
    def from_parameters(cls, *, offset: Any, scale_per_g: Any, angles_deg: Any = (0.0, 0.0, 0.0),
                        input_unit: str = "g", model: str | None = None) -> "AccCalibration":
        """A calibration with given parameters and no fit statistics (e.g. a data-sheet nominal map)."""
        angles = _vector(angles_deg, 3, "angles_deg")
        if model is None:
            model = "6-param" if (angles == 0).all() else "9-param"
        scale = _vector(scale_per_g, 3, "scale_per_g")
        return cls(model=model, input_unit=input_unit, offset=_vector(offset, 3, "offset"), scale_per_g=scale,
                   angles_deg=angles, matrix=calibration_matrix(scale, np.radians(angles)),
                   residual_rms_g=float("nan"), residual_max_g=float("nan"), n_poses=0)

    # ---------------------------------------------------------------------------------------------- files
    def fields_to_dict(self) -> dict[str, Any]:
        """The fields, JSON-ready (NaN as null); :meth:`to_dict` adds the type and version tags."""

        def num(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "map": "calibrated_g = matrix @ (raw - offset)",
            "model": self.model,
            "input_unit": self.input_unit,
            "offset": self.offset.tolist(),
            "matrix": self.matrix.tolist(),
            "scale_per_g": self.scale_per_g.tolist(),
            "angles_deg": self.angles_deg.tolist(),
            "residual_rms_g": num(self.residual_rms_g),
            "residual_max_g": num(self.residual_max_g),
            "n_poses": self.n_poses,
            "pose_residuals_g": self.pose_residuals_g.tolist(),
            "chi2_per_dof": num(self.chi2_per_dof),
            "min_direction_sv": num(self.min_direction_sv),
        }

    @classmethod
    def fields_from_dict(cls, data: dict[str, Any], *, source: str) -> Self:
        """Rebuild from the file's keys (:meth:`from_dict` checked the tags); errors name ``source`` and the key."""

        def fail(msg: str) -> CalibrationError:
            return CalibrationError(f"{source}: {msg}")

        def get(key: str, kind: str, shape: tuple[int, ...] | None = None, optional: bool = False) -> Any:
            if key not in data:
                raise fail(f"missing key {key!r}")
            value = data[key]
            if value is None and optional:
                return None
            if kind == "str":
                if not isinstance(value, str):
                    raise fail(f"key {key!r}: expected a string, found {type(value).__name__}")
                return value
            if kind == "int":
                if isinstance(value, bool) or not isinstance(value, int):
                    raise fail(f"key {key!r}: expected an integer, found {value!r}")
                return value
            if kind == "num":
                if isinstance(value, bool) or not isinstance(value, int | float):
                    raise fail(f"key {key!r}: expected a number, found {value!r}")
                return float(value)
            # array of numbers
            if not isinstance(value, list):
                raise fail(f"key {key!r}: expected a list of numbers, found {type(value).__name__}")

            def flat(v: Any) -> list[Any]:
                return [y for x in v for y in flat(x)] if isinstance(v, list) else [v]

            if any(isinstance(v, bool) or not isinstance(v, int | float) for v in flat(value)):
                raise fail(f"key {key!r}: expected numbers only")
            arr = np.asarray(value, dtype=np.float64)
            if shape is not None and arr.shape != shape:
                raise fail(f"key {key!r}: expected shape {shape}, found {arr.shape}")
            return arr

        fields = dict(
            model=get("model", "str"), input_unit=get("input_unit", "str"),
            offset=get("offset", "array", (3,)), matrix=get("matrix", "array", (3, 3)),
            scale_per_g=get("scale_per_g", "array", (3,)), angles_deg=get("angles_deg", "array", (3,)),
            residual_rms_g=get("residual_rms_g", "num", optional=True),
            residual_max_g=get("residual_max_g", "num", optional=True),
            n_poses=get("n_poses", "int"),
            pose_residuals_g=get("pose_residuals_g", "array"),
            chi2_per_dof=get("chi2_per_dof", "num", optional=True),
            min_direction_sv=get("min_direction_sv", "num", optional=True),
        )
        for key in ("residual_rms_g", "residual_max_g", "min_direction_sv"):
            if fields[key] is None:
                fields[key] = float("nan")
        try:
            return cls(**fields)
        except CalibrationError as err:
            raise fail(str(err)) from err


# --------------------------------------------------------------------------------------------------------------
# Fitting


def ellipsoid_fit(x: np.ndarray, *, axis_aligned: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Algebraic ellipsoid through points ``x`` (``(n, 3)``): centre ``c`` and ``A'`` with ``(x-c)^T A' (x-c) = 1``.

    Least squares on the quadric ``x^T A x + 2 d^T x = 1`` (9 coefficients, or 6 with ``axis_aligned``);
    ``c = -A^{-1} d``, ``A' = A / (1 + c^T A c)``. ``A'`` is not guaranteed positive definite for noisy or
    badly spread points: check it.

    Examples
    --------
    >>> u = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    >>> c, a = ellipsoid_fit(u * [2, 3, 4] + [1, 2, 3], axis_aligned=True)
    >>> c.round(9) + 0.0, np.diag(a).round(6)
    (array([1., 2., 3.]), array([0.25    , 0.111111, 0.0625  ]))
    """
    x = np.asarray(x, dtype=np.float64)
    sq = x * x
    if axis_aligned:
        design = np.hstack([sq, 2 * x])
    else:
        cross = 2 * np.stack([x[:, 0] * x[:, 1], x[:, 0] * x[:, 2], x[:, 1] * x[:, 2]], axis=1)
        design = np.hstack([sq, cross, 2 * x])
    coef, *_ = np.linalg.lstsq(design, np.ones(len(x)), rcond=None)
    if axis_aligned:
        a = np.diag(coef[:3])
        d = coef[3:]
    else:
        a = np.array([[coef[0], coef[3], coef[4]], [coef[3], coef[1], coef[5]], [coef[4], coef[5], coef[2]]])
        d = coef[6:]
    centre = -np.linalg.solve(a, d)
    return centre, a / (1.0 + centre @ a @ centre)


def _unpack(p: np.ndarray, model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return p[0:3], p[3:6], (p[6:9] if model == "9-param" else np.zeros(3))


def _residuals(p: np.ndarray, y: np.ndarray, model: str) -> np.ndarray:
    """Eq (5): ``|a_i| - 1`` for pose means ``y`` (``(n, 3)``)."""
    b, k, th = _unpack(p, model)
    u = (y - b) / k
    v = np.linalg.solve(gram_from_angles(th), u.T).T
    return np.sqrt(np.maximum(np.einsum("ij,ij->i", u, v), 0.0)) - 1.0


def _jacobian(p: np.ndarray, y: np.ndarray, model: str) -> np.ndarray:
    """Eq (6): analytic Jacobian of :func:`_residuals`, ``(n, n_params)``."""
    b, k, th = _unpack(p, model)
    u = (y - b) / k
    v = np.linalg.solve(gram_from_angles(th), u.T).T
    n = np.sqrt(np.maximum(np.einsum("ij,ij->i", u, v), 1e-300))[:, None]
    cols = [-v / (n * k), -v * u / (n * k)]
    if model == "9-param":
        c = np.cos(th)
        cols.append(np.stack([-v[:, i] * v[:, j] * c[m] for m, (i, j) in enumerate(ANGLE_PAIRS)], axis=1) / n)
    return np.hstack(cols)


def _start(y: np.ndarray, model: str) -> np.ndarray:
    """Ellipsoid-fit start in normalised coordinates; the unit sphere when the quadric is not an ellipsoid."""
    fallback = np.concatenate([np.zeros(3), np.ones(3), np.zeros(MODELS[model] - 6)])
    try:
        c, a = ellipsoid_fit(y, axis_aligned=(model == "6-param"))
        if not np.isfinite(a).all() or np.linalg.eigvalsh(a).min() <= 0:
            return fallback
        ainv = np.linalg.inv(a)
        k = np.sqrt(np.diag(ainv))
        if model == "6-param":
            return np.concatenate([c, k])
        g = ainv / np.outer(k, k)
        th = np.arcsin(np.clip([g[i, j] for i, j in ANGLE_PAIRS], -0.7, 0.7))
        return np.concatenate([c, k, th])
    except np.linalg.LinAlgError:
        return fallback


def _describe_direction(v: np.ndarray) -> str:
    j = int(np.argmax(np.abs(v)))
    v = v if v[j] > 0 else -v
    comp = ", ".join(f"{c:+.2f}" for c in v)
    return f"direction ({comp}), mostly the {_AXES[j]} axis"


def _check_poses(means: np.ndarray, model: str, valid_range: tuple[float, float] | None) -> None:
    if means.ndim != 2 or means.shape[1] != 3:
        raise CalibrationError(f"pose means must have shape (n, 3), got {means.shape}")
    bad = ~np.isfinite(means)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        raise CalibrationError(f"pose means contain NaN or infinite values at row(s) {rows[:10].tolist()} "
                               f"(axis {_AXES[int(np.flatnonzero(bad[rows[0]])[0])]} of row {rows[0]})")
    if valid_range is not None:
        lo, hi = valid_range
        out = (means < lo) | (means > hi)
        if out.any():
            r, c = (int(v[0]) for v in np.nonzero(out))
            raise CalibrationError(f"pose {r}: axis {_AXES[c]} = {means[r, c]:.6g} is outside the valid range "
                                   f"[{lo}, {hi}] ({int(out.any(axis=1).sum())} pose(s) out of range)")
    need = MODELS[model]
    if len(means) < need:
        raise CalibrationError(f"the {model} model needs at least {need} static poses, found {len(means)}; "
                               "record more holds in different orientations (18-24 well spread is best)")


def direction_coverage(means: np.ndarray, centre: np.ndarray) -> tuple[float, np.ndarray]:
    """How well the poses observe every direction.

    Returns the smallest singular value of the ``(n, 3)`` matrix of unit pose directions ``(r_i - centre) /
    |r_i - centre|`` divided by ``sqrt(n)`` (0.577 for isotropic poses, 0 when some direction is never seen) and
    that least-observed direction (unit ``(3,)``).

    Examples
    --------
    >>> flat = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0.7, 0.7, 0]])
    >>> sv, v = direction_coverage(flat, np.zeros(3))
    >>> round(sv, 6), np.abs(v).round(6)
    (0.0, array([0., 0., 1.]))
    """
    d = np.asarray(means, dtype=np.float64) - centre
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    _, s, vt = np.linalg.svd(d, full_matrices=False)
    return float(s[-1] / np.sqrt(len(d))), vt[-1]


def fit_calibration(pose_means: np.ndarray, *, model: str = "9-param", input_unit: str = "g",
                    pose_sd: np.ndarray | None = None, pose_n: np.ndarray | None = None,
                    code_step: float | np.ndarray = 0.0, valid_range: tuple[float, float] | None = None,
                    min_direction_sv: float = 0.1) -> AccCalibration:
    """Fit offsets, scales (and angles) to static pose means so that every pose reads 1 g, eqs (5)-(6).

    Parameters
    ----------
    pose_means
        ``(n, 3)`` mean reading of each static pose, in ``input_unit``.
    model
        ``"9-param"`` (non-orthogonal, default) or ``"6-param"`` (orthogonal).
    input_unit
        ``"counts"`` or ``"g"``: the unit of ``pose_means`` and of the readings the result will calibrate.
    pose_sd, pose_n
        ``(n, 3)`` per-axis SD of each pose's samples (input unit) and ``(n,)`` sample counts; with them the
        result carries ``chi2_per_dof``.
    code_step
        Quantisation step of the readings (input unit; 1 for counts), floors each pose's noise at
        ``code_step / sqrt(12 N)`` in ``chi2_per_dof``.
    valid_range
        ``(low, high)`` allowed values of every pose mean (e.g. ``(0, 1023)`` for 10-bit codes).
    min_direction_sv
        Refuse poses whose :func:`direction_coverage` is below this.

    Raises
    ------
    CalibrationError
        Too few poses for the model, NaN or out-of-range pose means (row and axis named), poses leaving a
        direction unobserved (direction named), a fit that does not converge to a physical sensor.

    Examples
    --------
    >>> dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0],
    ...                  [0.6, 0.8, 0], [0, -0.6, 0.8], [0.8, 0, -0.6]])
    >>> raw = dirs * [1.02, 0.98, 1.01] + [0.05, -0.03, 0.02]
    >>> cal = fit_calibration(raw, model="6-param")
    >>> cal.offset.round(9), cal.scale_per_g.round(9), cal.residual_max_g < 1e-12
    (array([ 0.05, -0.03,  0.02]), array([1.02, 0.98, 1.01]), True)
    """
    from scipy.optimize import least_squares

    if model not in MODELS:
        raise CalibrationError(f"model must be one of {sorted(MODELS)}, got {model!r}")
    if input_unit not in INPUT_UNITS:
        raise CalibrationError(f"input_unit must be one of {INPUT_UNITS}, got {input_unit!r}")
    means = np.asarray(pose_means, dtype=np.float64)
    _check_poses(means, model, valid_range)
    # normalise: centre of the extremes, median radius (keeps LM well scaled for counts and g alike)
    c0 = 0.5 * (means.max(axis=0) + means.min(axis=0))
    s0 = float(np.median(np.linalg.norm(means - c0, axis=1)))
    if not s0 > 0:
        raise CalibrationError("all pose means are equal: the poses must differ in orientation")
    y = (means - c0) / s0
    p0 = _start(y, model)
    sv, weak = direction_coverage(means, c0 + s0 * p0[:3])
    if not sv >= min_direction_sv:
        raise CalibrationError(
            f"the {len(means)} poses leave the {_describe_direction(weak)} unobserved (smallest singular value "
            f"of the pose directions {sv:.3f} < {min_direction_sv}); add holds with that axis tilted up and down")
    sol = least_squares(_residuals, p0, jac=_jacobian, method="lm", args=(y, model),
                        xtol=1e-14, ftol=1e-14, gtol=1e-14)
    b_n, k_n, th = _unpack(sol.x, model)
    if not (np.isfinite(sol.x).all() and (k_n > 0).all() and (np.abs(th) < np.radians(45)).all()):
        raise CalibrationError(f"the fit did not converge to a physical sensor ({sol.message}); check that the "
                               "poses are static and well spread")
    jac = _jacobian(sol.x, y, model)
    js = np.linalg.svd(jac, compute_uv=False)
    if js[-1] < 1e-8 * js[0]:
        raise CalibrationError("the poses do not determine all parameters (Jacobian condition number "
                               f"{js[0] / max(js[-1], 1e-300):.2g}); add holds in new orientations")
    offset = c0 + s0 * b_n
    scale = s0 * k_n
    angles = np.degrees(th)
    res = _residuals(sol.x, y, model)
    chi2 = None
    dof = len(means) - MODELS[model]
    if pose_sd is not None and pose_n is not None and dof > 0:
        matrix = calibration_matrix(scale, th)
        f = (means - offset) @ matrix.T
        grad = (f / np.linalg.norm(f, axis=1, keepdims=True)) @ matrix  # d|a|/dr, (n, 3), g per unit
        n_s = np.asarray(pose_n, dtype=np.float64).reshape(-1, 1)
        var_axis = np.maximum(np.asarray(pose_sd, dtype=np.float64) ** 2,
                              np.broadcast_to(np.asarray(code_step, dtype=np.float64) ** 2 / 12, (3,)))
        sigma = np.sqrt(np.sum(grad**2 * var_axis / n_s, axis=1))
        chi2 = float(np.sum((res / sigma) ** 2) / dof)
    return AccCalibration(
        model=model, input_unit=input_unit, offset=offset, scale_per_g=scale, angles_deg=angles,
        matrix=calibration_matrix(scale, th), residual_rms_g=float(np.sqrt(np.mean(res**2))),
        residual_max_g=float(np.abs(res).max()), n_poses=len(means), pose_residuals_g=res, chi2_per_dof=chi2,
        min_direction_sv=sv)


def parameter_bounds(pose_g: np.ndarray, *, noise_g: float, bias_g: float = 0.0,
                     model: str = "9-param", n_sigma: float = 4.0) -> dict[str, np.ndarray]:
    """Eq (9): how far noise and quantisation bias can move each fitted parameter, for a set of poses.

    Parameters
    ----------
    pose_g
        ``(n, 3)`` true pose means expressed in g relative to the offset (i.e. ``K^{-1}(r - b)`` of the true
        sensor, close to the unit pose directions).
    noise_g
        ``sigma_p`` of eq (7): standard deviation of each axis of each pose mean, in g of reading.
    bias_g
        ``beta`` of eq (8): worst-case quantisation bias of each axis of each pose mean, in g of reading.
    model, n_sigma
        Model whose Jacobian is used; number of standard deviations of the noise term.

    Returns
    -------
    dict
        ``offset_g`` and ``scale`` (relative, dimensionless) ``(3,)``, and ``angles_deg`` ``(3,)`` (zeros for the
        orthogonal model): the bounds on ``|offset error| / k``, ``|scale error| / k`` and the angle errors.

    Examples
    --------
    >>> d = np.vstack([np.eye(3), -np.eye(3)] * 4)
    >>> b = parameter_bounds(d, noise_g=0.001, model="6-param")
    >>> b["offset_g"].round(6)  # 4 sigma / sqrt(8) per axis: 4 poses on each end of each axis
    array([0.001414, 0.001414, 0.001414])
    """
    y = np.asarray(pose_g, dtype=np.float64)
    n_par = MODELS[model]
    p = np.concatenate([np.zeros(3), np.ones(3), np.zeros(n_par - 6)])
    jac = _jacobian(p, y, model)  # in units of k: offsets in g, scales relative
    # a per-axis perturbation e of a pose mean moves that pose's residual by d rho / d r = v / n (= unit pose)
    pinv = np.linalg.pinv(jac)  # (n_par, n)
    noise = n_sigma * noise_g * np.sqrt(np.sum(pinv**2, axis=1))
    grad_l1 = np.abs(y / np.linalg.norm(y, axis=1, keepdims=True)).sum(axis=1)  # <= sqrt(3)
    bias = bias_g * (np.abs(pinv) @ grad_l1)
    total = noise + bias
    return {"offset_g": total[0:3], "scale": total[3:6],
            "angles_deg": np.degrees(total[6:9]) if n_par == 9 else np.zeros(3)}


# --------------------------------------------------------------------------------------------------------------
# Detection + fit


class AccCalibrator:
    """Calibrate an accelerometer from a recording of static holds: rest detection, then eqs (5)-(6).

    Parameters
    ----------
    model
        ``"9-param"`` (default) or ``"6-param"``.
    hold_s, sd_factor, max_norm_g, min_angle_deg, trim_s
        Rest detection, see :class:`host.accelerometer.static_windows.StaticWindowDetector`.
    min_direction_sv
        See :func:`fit_calibration`.
    """

    def __init__(self, *, model: str = "9-param", hold_s: float = 3.0, sd_factor: float = 1.3,
                 max_norm_g: float = 2.0, min_angle_deg: float = 10.0, trim_s: float = 0.25,
                 min_direction_sv: float = 0.1) -> None:
        self.model = model
        self.hold_s = hold_s
        self.sd_factor = sd_factor
        self.max_norm_g = max_norm_g
        self.min_angle_deg = min_angle_deg
        self.trim_s = trim_s
        self.min_direction_sv = min_direction_sv

    def calibrate(self, acc: np.ndarray, *, sampling_rate_hz: float, input_unit: str,
                  zero: np.ndarray | None = None, unit_per_g: float | np.ndarray | None = None,
                  valid_range: tuple[float, float] | None = None) -> Self:
        """Find the static holds of ``acc`` and fit the model to their means.

        Parameters
        ----------
        acc
            ``(n, 3)`` readings in ``input_unit``; NaN marks missing samples (never part of a hold).
        sampling_rate_hz
            Sampling rate, Hz.
        input_unit
            ``"counts"`` or ``"g"``.
        zero, unit_per_g
            Nominal map used by the rest detection (norm and angle tests). Defaults: 0 and 1 for g; estimated
            from the holds for counts.
        valid_range
            ``(low, high)`` allowed values of every sample (e.g. ``(0, 1023)``); a finite sample outside it is
            refused, naming the sample.

        Returns
        -------
        self
            With ``calibration_`` (:class:`AccCalibration`), ``windows_`` (the holds used, list of
            :class:`~host.accelerometer.static_windows.StaticWindow`) and ``detector_`` (with its rejected holds).
        """
        if input_unit not in INPUT_UNITS:
            raise CalibrationError(f"input_unit must be one of {INPUT_UNITS}, got {input_unit!r}")
        x = np.asarray(acc, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise CalibrationError(f"acceleration must have shape (n, 3), got {x.shape}")
        if np.isinf(x).any():
            r, c = (int(v[0]) for v in np.nonzero(np.isinf(x)))
            raise CalibrationError(f"sample {r}: axis {_AXES[c]} is infinite")
        if valid_range is not None:
            lo, hi = valid_range
            with np.errstate(invalid="ignore"):
                out = (x < lo) | (x > hi)
            if out.any():
                r, c = (int(v[0]) for v in np.nonzero(out))
                raise CalibrationError(f"sample {r}: axis {_AXES[c]} = {x[r, c]:.6g} is outside the valid range "
                                       f"[{lo}, {hi}] ({int(out.any(axis=1).sum())} sample(s) out of range)")
        if input_unit == "g" and unit_per_g is None:
            unit_per_g = 1.0
        det = StaticWindowDetector(hold_s=self.hold_s, sd_factor=self.sd_factor, max_norm_g=self.max_norm_g,
                                   min_angle_deg=self.min_angle_deg, trim_s=self.trim_s)
        det.detect(x, sampling_rate_hz=sampling_rate_hz, zero=zero, unit_per_g=unit_per_g)
        self.detector_ = det
        self.windows_: list[StaticWindow] = det.windows_
        need = MODELS.get(self.model, 0)
        if len(det.windows_) < need:
            raise CalibrationError(
                f"found {len(det.windows_)} static poses (holds of >= {self.hold_s} s in distinct orientations; "
                f"{len(det.rejected_)} rejected), the {self.model} model needs at least {need}")
        means = np.array([w.mean for w in det.windows_])
        self.calibration_ = fit_calibration(
            means, model=self.model, input_unit=input_unit, pose_sd=np.array([w.sd for w in det.windows_]),
            pose_n=np.array([w.n_samples for w in det.windows_]), code_step=det.code_step_,
            valid_range=valid_range, min_direction_sv=self.min_direction_sv)
        return self
