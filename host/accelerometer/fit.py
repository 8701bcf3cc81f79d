"""Fitting the accelerometer calibration (:mod:`gaitlog.host.accelerometer.calibration`, whose docstring states the
model, the fit and its error bounds) to static poses: the algebraic ellipsoid start, Levenberg-Marquardt
(``scipy.optimize.least_squares``) on the pose means, the error bounds (9), and :class:`AccCalibrator`, which
finds the static windows of a recording and fits them.

A module of its own so that reading and applying a calibration (every input reader does) does not import
``scipy.optimize``.
"""

from __future__ import annotations

from typing import Self

import numpy as np
from scipy.optimize import least_squares

from gaitlog.host.accelerometer.calibration import (
    ANGLE_PAIRS,
    INPUT_UNITS,
    MODELS,
    AccCalibration,
    CalibrationError,
    calibration_matrix,
    gram_from_angles,
)
from gaitlog.host.accelerometer.static_windows import StaticWindow, StaticWindowDetector

#: Axis names, in column order.
_AXES = "xyz"

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


def _check_valid_range(x: np.ndarray, valid_range: tuple[float, float] | None, row: str) -> None:
    """Refuse an ``(n, 3)`` array with a value outside ``valid_range`` (NaN passes), naming the first ``row``
    (``"pose"``, ``"sample"``), its axis and value, and how many rows are out of range."""
    if valid_range is None:
        return
    lo, hi = valid_range
    with np.errstate(invalid="ignore"):
        out = (x < lo) | (x > hi)
    if out.any():
        r, c = (int(v[0]) for v in np.nonzero(out))
        raise CalibrationError(f"{row} {r}: axis {_AXES[c]} = {x[r, c]:.6g} is outside the valid range "
                               f"[{lo}, {hi}] ({int(out.any(axis=1).sum())} {row}(s) out of range)")


def _check_poses(means: np.ndarray, model: str, valid_range: tuple[float, float] | None) -> None:
    if means.ndim != 2 or means.shape[1] != 3:
        raise CalibrationError(f"pose means must have shape (n, 3), got {means.shape}")
    bad = ~np.isfinite(means)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        raise CalibrationError(f"pose means contain NaN or infinite values at row(s) {rows[:10].tolist()} "
                               f"(axis {_AXES[int(np.flatnonzero(bad[rows[0]])[0])]} of row {rows[0]})")
    _check_valid_range(means, valid_range, "pose")
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
        Rest detection, see :class:`gaitlog.host.accelerometer.static_windows.StaticWindowDetector`.
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
            :class:`~gaitlog.host.accelerometer.static_windows.StaticWindow`) and ``detector_`` (with its rejected holds).
        """
        if input_unit not in INPUT_UNITS:
            raise CalibrationError(f"input_unit must be one of {INPUT_UNITS}, got {input_unit!r}")
        x = np.asarray(acc, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise CalibrationError(f"acceleration must have shape (n, 3), got {x.shape}")
        if np.isinf(x).any():
            r, c = (int(v[0]) for v in np.nonzero(np.isinf(x)))
            raise CalibrationError(f"sample {r}: axis {_AXES[c]} is infinite")
        _check_valid_range(x, valid_range, "sample")
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
