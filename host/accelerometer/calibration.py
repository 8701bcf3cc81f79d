r"""Accelerometer calibration from static poses: offsets, scales and axis non-orthogonality.

The model is the non-orthogonal one of Krohn et al. (2005) [1]_, the calibration the logger paper
(Alvarez et al. 2006) cites, with its orthogonal special case.

Sensor model
------------
Sensor axis ``j`` has offset ``b_j`` and gain ``k_j`` (input unit per g) along a unit sensitive direction
``s_j``; at rest, with specific force ``a`` (``|a|`` = 1 g),

.. math:: r_j = b_j + k_j \, s_j \cdot a \qquad (1)

The three non-orthogonality angles are the deviations from 90 deg of the angles between the sensitive axes,
``theta_xy, theta_xz, theta_yz`` with :math:`s_i \cdot s_j = \sin\theta_{ij}`. They fix the Gram matrix

.. math:: G = S S^\mathsf{T}, \qquad G_{ii} = 1, \; G_{ij} = \sin\theta_{ij} \qquad (2)

(rows of ``S`` are the ``s_j``), which is all a gravity-only calibration can see: the mounting rotation of the
whole triad is not observable from ``|a|`` = 1 g (see ``shared/notes/CALIBRATION-KINEMATICS.md``). Inverting (1)
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
deterministic bias [2]_: the mean of a quantised Gaussian differs from its input by at most

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

(four standard deviations of the noise term, plus the worst case of the bias term). :func:`gaitlog.host.accelerometer.fit.parameter_bounds`
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

from gaitlog.host.errors import HostError
from gaitlog.host.storage.versioned_json import VersionedJson
from gaitlog.protocol.header import CalibrationSlot

#: Number of parameters of each model.
MODELS: dict[str, int] = {"9-param": 9, "6-param": 6}
#: Units an :class:`AccCalibration` can take as input.
INPUT_UNITS = ("counts", "g")
#: Axis pairs of the three non-orthogonality angles, in the order of ``angles_deg``.
ANGLE_PAIRS = ((0, 1), (0, 2), (1, 2))
ANGLE_NAMES = ("xy", "xz", "yz")


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

    def to_header_calibration(self) -> CalibrationSlot:
        """The device header's calibration slot (``gaitlog.protocol.header.CalibrationSlot``, PROTOCOL.md 2.1).

        Only a calibration of ADC counts fits the slot (``a_g = M (codes - offset)``).
        """
        if self.input_unit != "counts":
            raise CalibrationError("only a calibration of ADC counts can go in the device header, "
                                   f"this one takes {self.input_unit}")
        return CalibrationSlot(offset_counts=self.offset.copy(), matrix_g_per_count=self.matrix.copy(), valid=True)

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
