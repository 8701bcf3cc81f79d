"""Two ADXL202E biaxial accelerometers assembled into the logger's three axes.

Assembly (the paper says only "two ADXL202, 3 axes"; this is the layout assumed here):

- **Part A** lies flat on the main board: its X and Y channels give the device's ``x`` and ``y`` axes.
- **Part B** stands on a small daughter board at right angles to the main board: its X channel gives the
  device's ``z`` axis; its Y channel is nominally parallel to ``x`` (redundant) and is **not wired** to the
  ADC (the logger stores three axes), so it is not modelled.

Each axis reads ``v = V0 + S (1 + e) [b + LPF(clip(u . a, ±range)) + LPF(n)]`` volts, where ``a`` is the true
specific force in g (device axes), ``u`` the axis's actual sensitive direction (a row of ``axes``: the
misalignment matrix), ``clip`` the ±2 g full scale of the sensing element, ``n`` white noise of density
``noise_density_g_rthz``, ``LPF`` the single-pole filter formed by the part's internal 32 kΩ and the external
filter capacitor (``f_-3dB = 5 µF / C``), ``b`` the 0 g offset in g, ``e`` the sensitivity error, ``S`` the
nominal sensitivity and ``V0 = supply_v / 2`` the 0 g level (the analog outputs XFILT/YFILT are
ratiometric). The output is the analog voltage at XFILT/YFILT (buffered); the ADC front end of
:mod:`gaitlog.firmware_sim.adc` turns it into codes. ``LPF(n)``, white noise through the RC, is an
Ornstein-Uhlenbeck process, drawn exactly at the instants where it is observed (:meth:`SensorModel.noise_g`).

Tolerances used by :meth:`SensorModel.draw` (uniform draws; ``*`` = an assumption, not a datasheet limit;
HARDWARE.md lists the ADXL202E tolerance table as unverified):

=========================  =====================  ==============================================================
parameter                  default draw           basis
=========================  =====================  ==============================================================
0 g offset ``b``           ±0.10 g  *             typical parts; the datasheet's worst-case 0 g duty-cycle span
                                                  is far wider (±2 g at 25-75 % duty)
sensitivity error ``e``    ±5 %  *                datasheet limits 10-15 %/g around 12.5 %/g (±20 %)
package alignment          ±1° per part           ADXL202E "alignment error ±1°"
X-to-Y non-orthogonality   ±0.01°                 ADXL202E "X-to-Y alignment error ±0.01°" (same die)
part B mounting            ±2°  *                 a hand-soldered daughter board
filter bandwidth           ±15 %                  internal filter resistor 32 kΩ ±15 %
noise density              200 µg/√Hz (fixed)     ADXL202E typical
full scale                 ±2 g (fixed)           ADXL202 measurement range
sensitivity at 5 V         312 mV/g  *            ratiometric; HARDWARE.md marks 312 mV/g unverified
=========================  =====================  ==============================================================

**Beyond white noise** (each a parameter, **off by default**: the defaults give today's sensor, sample for
sample):

- *1/f noise* (``flicker_corner_hz``): the noise density is ``d² (1 + f_c / f)`` (one-sided, g²/Hz): 1/f below
  the corner ``f_c``, white above. The 1/f part is a sum of Ornstein-Uhlenbeck processes (Lorentzians) with
  corners spaced :data:`FLICKER_POLES_PER_DECADE` per decade from ``flicker_low_hz`` (the longest correlation
  time kept, default 1 mHz) to the output filter's cut-off, each of variance ``d² f_c ln r`` (``r`` the
  corners' ratio): their sum's density is ``d² f_c / f`` between them (:func:`flicker_noise`), drawn exactly at
  the sample instants from its own seeded stream (the white noise's stream is unchanged). Above the cut-off
  it falls as 1/f² instead of through the RC filter as the white part does: there the white part dominates.
- *Temperature drift* (``offset_tempco_g_per_c``, ``sensitivity_tempco_per_c``, ``temperature``): at the
  temperature ``T(t)`` of a :class:`TemperatureProfile` the offset is ``b + α_b (T − T_ref)`` and the sensitivity
  ``S (1 + e) (1 + α_s (T − T_ref))``, ``T_ref`` = 25 °C (where the device is calibrated). ADXL202E typicals
  (:data:`ADXL202_OFFSET_TEMPCO_G_PER_C` 2 mg/°C, :data:`ADXL202_SENSITIVITY_TEMPCO_PER_C` ±0.5 % from 25 to
  70 °C; ADI ADXL202E data sheet, *unverified* as HARDWARE.md says of its tolerance table) with seeded signs:
  :func:`datasheet_tempcos`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.errors import DeviceError

__all__ = ["ADXL202_OFFSET_TEMPCO_G_PER_C", "ADXL202_SENSITIVITY_TEMPCO_PER_C", "AXIS_PARTS",
           "REFERENCE_TEMPERATURE_C", "SensorModel", "TemperatureProfile", "datasheet_tempcos", "filter_cutoff_hz",
           "flicker_noise", "flicker_rng", "ou_noise"]

#: Temperature at which the sensor's offset and sensitivity are what they are (the calibration's), °C.
REFERENCE_TEMPERATURE_C = 25.0
#: ADXL202E typical 0 g offset drift, g/°C (data sheet "0 g offset vs. temperature", 2.0 mg/°C; *unverified*).
ADXL202_OFFSET_TEMPCO_G_PER_C = 2.0e-3
#: ADXL202E typical sensitivity drift, 1/°C (data sheet ±0.5 % from 25 °C to 70 °C; *unverified*).
ADXL202_SENSITIVITY_TEMPCO_PER_C = 0.005 / 45.0
#: Corners of the 1/f synthesis per decade (:func:`flicker_noise`).
FLICKER_POLES_PER_DECADE = 3
#: Lowest corner of the 1/f synthesis unless told otherwise, Hz (a 160 s correlation time scale).
FLICKER_LOW_HZ = 1e-3
#: Substreams of a sensor's seed: the 1/f noise and the temperature coefficients' signs.
_FLICKER_STREAM, _TEMPCO_STREAM = 1, 2


def flicker_rng(seed: int) -> np.random.Generator:
    """A fresh generator of the 1/f noise of the sensor seeded ``seed`` (independent of its white noise)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), _FLICKER_STREAM]))


def datasheet_tempcos(seed: int) -> dict[str, np.ndarray]:
    """ADXL202E typical temperature coefficients with seeded signs per axis: ``offset_tempco_g_per_c`` and
    ``sensitivity_tempco_per_c``, ``(3,)`` each (keyword arguments of :class:`SensorModel`).

    >>> t = datasheet_tempcos(1)
    >>> np.abs(t["offset_tempco_g_per_c"]).tolist()
    [0.002, 0.002, 0.002]
    """
    signs = np.random.default_rng(np.random.SeedSequence([int(seed), _TEMPCO_STREAM])).choice([-1.0, 1.0], (2, 3))
    return {"offset_tempco_g_per_c": signs[0] * ADXL202_OFFSET_TEMPCO_G_PER_C,
            "sensitivity_tempco_per_c": signs[1] * ADXL202_SENSITIVITY_TEMPCO_PER_C}


def flicker_noise(times_s: np.ndarray, density: np.ndarray, corner_hz: np.ndarray, low_hz: float,
                  high_hz: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """1/f noise ``(n, N)`` of one-sided density ``density² · corner_hz / f`` between ``low_hz`` and ``high_hz``,
    drawn exactly at the increasing instants ``times_s`` (module notes: Lorentzians, each an Ornstein-Uhlenbeck
    process of :func:`ou_noise`, :data:`FLICKER_POLES_PER_DECADE` per decade, variance ``density² corner ln r``).
    Channels with a zero corner or density get zeros."""
    t = np.asarray(times_s, dtype=np.float64)
    d = np.asarray(density, dtype=np.float64).reshape(-1)
    fc = np.broadcast_to(np.asarray(corner_hz, dtype=np.float64), d.shape)
    hi = np.broadcast_to(np.asarray(high_hz, dtype=np.float64), d.shape)
    if not (low_hz > 0 and np.all(hi > low_hz) and np.all(fc >= 0)):
        raise DeviceError(f"1/f noise needs 0 < low ({low_hz!r} Hz) < high ({hi.tolist()} Hz) and corners >= 0")
    ratio = 10.0 ** (1.0 / FLICKER_POLES_PER_DECADE)
    out = np.zeros((t.size, d.size))
    for j in np.flatnonzero((d > 0) & (fc > 0)):
        poles_hz = low_hz * ratio ** np.arange(int(np.ceil(np.log(hi[j] / low_hz) / np.log(ratio))) + 1)
        sigma = np.full(poles_hz.size, d[j] * np.sqrt(fc[j] * np.log(ratio)))
        out[:, j] = ou_noise(t, sigma, poles_hz, rng).sum(axis=1)
    return out


@dataclass(frozen=True)
class TemperatureProfile:
    """The sensor's temperature vs time since the recording started: piecewise linear through the points
    ``(times_s[i], temperatures_c[i])``, held beyond the first and the last. Default: 25 °C throughout.

    >>> TemperatureProfile.ramp(25.0, 50.0, 100.0).at(np.array([-1.0, 50.0, 200.0])).tolist()
    [25.0, 37.5, 50.0]
    """

    times_s: tuple[float, ...] = (0.0,)
    temperatures_c: tuple[float, ...] = (REFERENCE_TEMPERATURE_C,)

    def __post_init__(self) -> None:
        t = np.asarray(self.times_s, dtype=np.float64)
        c = np.asarray(self.temperatures_c, dtype=np.float64)
        if t.ndim != 1 or t.shape != c.shape or t.size == 0 or not (np.isfinite(t).all() and np.isfinite(c).all()):
            raise DeviceError("a temperature profile needs as many finite times as temperatures, at least one")
        if np.any(np.diff(t) <= 0) or np.any(c < -60.0) or np.any(c > 150.0):
            raise DeviceError("temperature profile: times must increase, temperatures lie in -60 .. 150 °C")
        object.__setattr__(self, "times_s", tuple(float(x) for x in t))
        object.__setattr__(self, "temperatures_c", tuple(float(x) for x in c))

    @classmethod
    def ramp(cls, start_c: float, end_c: float, duration_s: float) -> TemperatureProfile:
        """A linear ramp from ``start_c`` at 0 s to ``end_c`` at ``duration_s``."""
        if start_c == end_c:
            return cls((0.0,), (float(start_c),))
        return cls((0.0, float(duration_s)), (float(start_c), float(end_c)))

    def at(self, elapsed_s: np.ndarray) -> np.ndarray:
        """Temperatures, °C, at the times ``elapsed_s`` since the start."""
        return np.interp(np.asarray(elapsed_s, dtype=np.float64), self.times_s, self.temperatures_c)


def _ou_regular(drive: np.ndarray, a: float, x0: float) -> np.ndarray:
    """``x_0 = x0``, ``x_k = a x_(k-1) + drive[k]`` for k >= 1 (one IIR pass)."""
    d = drive.copy()
    d[0] = x0
    return signal.lfilter([1.0], [1.0, -a], d)


def ou_noise(times_s: np.ndarray, noise_rms: np.ndarray, cutoff_hz: np.ndarray,
             rng: np.random.Generator) -> np.ndarray:
    """White noise through one-pole filters, ``(n, N)``, drawn exactly at the increasing instants ``times_s``.

    An Ornstein-Uhlenbeck process per channel ``j``: ``x_k = a_k x_(k-1) + σ_j sqrt(1 - a_k²) ξ_k`` with
    ``a_k = exp(-(t_k - t_(k-1)) / τ_j)``, ``τ_j = 1 / (2π cutoff_hz[j])``, ``σ_j = noise_rms[j]`` (the filtered
    output's rms) and ``x_0`` drawn from the stationary law: no discretisation error, one random number per
    channel and sample observed (``(N, n)`` standard normals drawn at once).
    """
    t = np.asarray(times_s, dtype=np.float64)
    sigma = np.asarray(noise_rms, dtype=np.float64).reshape(-1)
    cutoff = np.broadcast_to(np.asarray(cutoff_hz, dtype=np.float64), sigma.shape)
    n = t.size
    out = np.zeros((n, sigma.size))
    if n == 0:
        return out
    xi = rng.standard_normal((sigma.size, n))
    dt = np.diff(t)
    regular = n < 2 or np.allclose(dt, dt[0], rtol=1e-9, atol=0.0)
    for j in range(sigma.size):
        tau = 1.0 / (2.0 * np.pi * cutoff[j])
        if regular:  # constant coefficient: one IIR pass (the process is genuinely recursive)
            a = np.exp(-(dt[0] if n > 1 else 1.0) / tau)
            drive = sigma[j] * np.sqrt(1.0 - a * a) * xi[j]
            out[:, j] = _ou_regular(drive, a, sigma[j] * xi[j, 0])
        else:
            a_k = np.exp(-dt / tau)
            x = np.empty(n)
            x[0] = sigma[j] * xi[j, 0]
            drive = sigma[j] * np.sqrt(1.0 - a_k * a_k) * xi[j, 1:]
            for k in range(1, n):  # irregular instants: per-sample recursion
                x[k] = a_k[k - 1] * x[k - 1] + drive[k - 1]
            out[:, j] = x
    return out

#: Which part and channel gives each device axis.
AXIS_PARTS = ("A.X", "A.Y", "B.X")

#: ADXL202 filter constant: ``f_-3dB = 5 µF / C``.
FILTER_CONSTANT_F_HZ = 5e-6


def filter_cutoff_hz(capacitance_f: np.ndarray | float) -> np.ndarray:
    """-3 dB frequency of the ADXL202 output filter, ``5 µF / C`` (C in farads).

    >>> round(filter_cutoff_hz(0.25e-6).item(), 9)
    20.0
    """
    c = np.asarray(capacitance_f, dtype=np.float64)
    if np.any(c <= 0):
        raise DeviceError(f"filter capacitance must be > 0 F, got {c}")
    return FILTER_CONSTANT_F_HZ / c


@dataclass(frozen=True, eq=False)
class SensorModel:
    """Parameters of the three-axis ADXL202E assembly, all explicit.

    Parameters
    ----------
    offset_g
        ``(3,)`` 0 g offset of each axis, in g.
    sensitivity_error
        ``(3,)`` relative sensitivity error (0.02 = 2 % high).
    axes
        ``(3, 3)`` misalignment matrix: row ``i`` is the unit sensitive direction of axis ``i`` in device
        axes (identity = perfectly orthogonal and aligned).
    filter_capacitance_f
        ``(3,)`` filter capacitor of each axis in farads (Cx, Cy of part A; Cx of part B); the bandwidth
        is ``5 µF / C`` times ``bandwidth_factor``.
    bandwidth_factor
        ``(3,)`` spread of the internal 32 kΩ filter resistor, as a factor on the bandwidth (1 = nominal).
    noise_density_g_rthz
        White-noise density referred to the input, g/√Hz (ADXL202E: 200 µg/√Hz).
    range_g
        Full scale of the sensing element; the element output clips at ±``range_g``.
    supply_v
        Supply voltage; the 0 g output is ``supply_v / 2`` (ratiometric).
    sensitivity_v_per_g
        Nominal sensitivity at the analog output, V/g.
    internal_rate_hz
        Rate of the fine time grid the analog behaviour (filter, noise) is simulated on.
    seed
        Seed of the noise generator (each call of :meth:`respond` without ``rng`` continues one stream).
    flicker_corner_hz
        1/f corner of the noise, Hz (module notes); 0 (default): white noise only.
    flicker_low_hz
        Lowest frequency of the 1/f synthesis, Hz.
    offset_tempco_g_per_c, sensitivity_tempco_per_c
        ``(3,)`` temperature coefficients of the offset (g/°C) and of the sensitivity (1/°C); 0 by default.
    temperature
        The sensor's :class:`TemperatureProfile` over the recording (default 25 °C throughout).
    reference_temperature_c
        Temperature at which ``offset_g`` and ``sensitivity_error`` hold, °C.

    Examples
    --------
    >>> s = SensorModel.ideal(noise_density_g_rthz=0.0)
    >>> v = s.respond(np.tile([0.0, 0.0, 1.0], (1000, 1)), 500.0)
    >>> np.round(v[-1], 6).tolist()
    [2.5, 2.5, 2.812]
    """

    offset_g: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sensitivity_error: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    filter_capacitance_f: np.ndarray = field(default_factory=lambda: np.full(3, 0.25e-6))
    bandwidth_factor: np.ndarray = field(default_factory=lambda: np.ones(3))
    noise_density_g_rthz: float = 200e-6
    range_g: float = 2.0
    supply_v: float = 5.0
    sensitivity_v_per_g: float = 0.312
    internal_rate_hz: float = 500.0
    seed: int = 0
    flicker_corner_hz: float = 0.0
    flicker_low_hz: float = FLICKER_LOW_HZ
    offset_tempco_g_per_c: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sensitivity_tempco_per_c: np.ndarray = field(default_factory=lambda: np.zeros(3))
    temperature: TemperatureProfile = field(default_factory=TemperatureProfile)
    reference_temperature_c: float = REFERENCE_TEMPERATURE_C
    _rng: np.random.Generator = field(init=False, repr=False)
    _flicker_rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for name, shape in (("offset_g", (3,)), ("sensitivity_error", (3,)), ("axes", (3, 3)),
                            ("filter_capacitance_f", (3,)), ("bandwidth_factor", (3,)),
                            ("offset_tempco_g_per_c", (3,)), ("sensitivity_tempco_per_c", (3,))):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.shape == () and shape == (3,):
                arr = np.full(3, float(arr))
            if arr.shape != shape or not np.isfinite(arr).all():
                raise DeviceError(f"SensorModel.{name} must be a finite array of shape {shape}, got {arr!r}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if np.any(self.filter_capacitance_f <= 0) or np.any(self.bandwidth_factor <= 0):
            raise DeviceError("filter capacitances and bandwidth factors must be > 0")
        if not np.allclose(np.linalg.norm(self.axes, axis=1), 1.0, atol=1e-9):
            raise DeviceError("SensorModel.axes rows must be unit vectors (sensitive directions)")
        if self.noise_density_g_rthz < 0 or self.range_g <= 0 or self.internal_rate_hz <= 0:
            raise DeviceError("noise density must be >= 0, range and internal rate > 0")
        if np.any(self.cutoff_hz >= self.internal_rate_hz / 2):
            raise DeviceError(
                f"filter cut-off {self.cutoff_hz.max():.1f} Hz is not below the Nyquist frequency of the "
                f"internal rate {self.internal_rate_hz} Hz: raise internal_rate_hz or the capacitance"
            )
        if not (0.0 <= self.flicker_corner_hz <= 1e3 and 0.0 < self.flicker_low_hz < self.cutoff_hz.min()):
            raise DeviceError(f"1/f corner must be 0 .. 1000 Hz and its lowest frequency between 0 and the filter "
                              f"cut-off, got {self.flicker_corner_hz!r} and {self.flicker_low_hz!r} Hz")
        if not isinstance(self.temperature, TemperatureProfile):
            raise DeviceError(f"SensorModel.temperature must be a TemperatureProfile, got {self.temperature!r}")
        object.__setattr__(self, "_rng", np.random.default_rng(self.seed))
        object.__setattr__(self, "_flicker_rng", flicker_rng(self.seed))

    # ------------------------------------------------------------------ construction
    @classmethod
    def ideal(cls, **overrides: object) -> SensorModel:
        """A perfect assembly (no offset, gain error or misalignment; noise and filter still there)."""
        return cls(**overrides)  # type: ignore[arg-type]

    @classmethod
    def draw(
        cls,
        *,
        seed: int = 0,
        offset_tol_g: float = 0.10,
        sensitivity_tol: float = 0.05,
        package_alignment_tol_deg: float = 1.0,
        xy_orthogonality_tol_deg: float = 0.01,
        mounting_tol_deg: float = 2.0,
        bandwidth_tol: float = 0.15,
        temperature_drift: bool = False,
        **overrides: object,
    ) -> SensorModel:
        """A seeded assembly with every error drawn uniformly within the tolerances (module docstring);
        ``temperature_drift``: the ADXL202E's typical temperature coefficients with seeded signs
        (:func:`datasheet_tempcos`, from a stream of their own: the other draws are the same either way).

        Examples
        --------
        >>> s = SensorModel.draw(seed=3)
        >>> bool(np.all(np.abs(s.offset_g) <= 0.1)), bool(np.all(np.abs(s.sensitivity_error) <= 0.05))
        (True, True)
        >>> ang = np.degrees(np.arccos(np.clip(np.abs(np.diag(s.axes)), 0, 1)))
        >>> bool(np.all(ang < 4.0)), bool(np.all(ang > 0.0))
        (True, True)
        """
        rng = np.random.default_rng(seed)
        offset = rng.uniform(-offset_tol_g, offset_tol_g, 3)
        sens = rng.uniform(-sensitivity_tol, sensitivity_tol, 3)
        rot_a = Rotation.from_rotvec(np.radians(rng.uniform(-package_alignment_tol_deg, package_alignment_tol_deg, 3)))
        skew = Rotation.from_rotvec([0.0, 0.0, np.radians(rng.uniform(-xy_orthogonality_tol_deg, xy_orthogonality_tol_deg))])
        mount_deg = rng.uniform(-mounting_tol_deg, mounting_tol_deg, 3) + rng.uniform(
            -package_alignment_tol_deg, package_alignment_tol_deg, 3
        )
        rot_b = Rotation.from_rotvec(np.radians(mount_deg))
        axes = np.vstack([
            rot_a.apply([1.0, 0.0, 0.0]),
            (rot_a * skew).apply([0.0, 1.0, 0.0]),
            rot_b.apply([0.0, 0.0, 1.0]),
        ])
        bw = 1.0 + rng.uniform(-bandwidth_tol, bandwidth_tol, 3)
        params: dict[str, object] = dict(
            offset_g=offset, sensitivity_error=sens, axes=axes, bandwidth_factor=bw, seed=seed + 1
        )
        if temperature_drift:
            params.update(datasheet_tempcos(seed + 1))
        params.update(overrides)
        return cls(**params)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ derived
    @property
    def cutoff_hz(self) -> np.ndarray:
        """``(3,)`` -3 dB frequency of each axis, Hz."""
        return filter_cutoff_hz(self.filter_capacitance_f) * self.bandwidth_factor

    @property
    def zero_g_v(self) -> float:
        """Nominal 0 g output voltage, ``supply_v / 2``."""
        return self.supply_v / 2.0

    @property
    def gain_v_per_g(self) -> np.ndarray:
        """``(3,)`` actual sensitivity of each axis, V/g."""
        return self.sensitivity_v_per_g * (1.0 + self.sensitivity_error)

    def static_v(self, acc_g: np.ndarray) -> np.ndarray:
        """Noise-free settled output ``(n, 3)`` in V for a constant input ``acc_g`` ``(n, 3)`` (DC gain 1)."""
        r = np.clip(np.atleast_2d(acc_g) @ self.axes.T, -self.range_g, self.range_g)
        return self.zero_g_v + self.gain_v_per_g * (self.offset_g + r)

    # ------------------------------------------------------------------ action
    @property
    def noise_rms_g(self) -> np.ndarray:
        """``(3,)`` rms of the output noise in g: white noise of density ``d`` through a one-pole RC,
        ``d · sqrt(π/2 · f_-3dB)`` (1.1 mg at 200 µg/√Hz and 20 Hz)."""
        return self.noise_density_g_rthz * np.sqrt(np.pi / 2.0 * self.cutoff_hz)

    def noise_g(self, times_s: np.ndarray, *, rng: np.random.Generator | None = None) -> np.ndarray:
        """The output noise in g, ``(n, 3)``, observed at the increasing instants ``times_s``.

        White noise through the RC filter is an Ornstein-Uhlenbeck process; it is drawn exactly at the
        instants where it is observed: ``x_k = a_k x_(k-1) + σ sqrt(1 - a_k²) ξ_k`` with
        ``a_k = exp(-(t_k - t_(k-1)) / τ)``, ``τ = 1 / (2π f_-3dB)``, ``σ`` = :attr:`noise_rms_g` and
        ``x_0`` drawn from the stationary law. No discretisation error, and one random number per sample
        actually observed.
        """
        t = np.asarray(times_s, dtype=np.float64)
        if t.size == 0 or self.noise_density_g_rthz == 0:
            return np.zeros((t.size, 3))
        return ou_noise(t, self.noise_rms_g, self.cutoff_hz, self._rng if rng is None else rng)

    def flicker_g(self, times_s: np.ndarray, *, rng: np.random.Generator | None = None) -> np.ndarray:
        """The 1/f part of the noise in g, ``(n, 3)``, at the increasing instants ``times_s`` (module notes;
        zeros without a corner). ``rng``: default the model's own 1/f stream (:func:`flicker_rng`)."""
        t = np.asarray(times_s, dtype=np.float64)
        if t.size == 0 or self.flicker_corner_hz == 0 or self.noise_density_g_rthz == 0:
            return np.zeros((t.size, 3))
        return flicker_noise(t, np.full(3, self.noise_density_g_rthz), self.flicker_corner_hz, self.flicker_low_hz,
                             self.cutoff_hz, self._flicker_rng if rng is None else rng)

    @property
    def drifts(self) -> bool:
        """Whether the offset or the sensitivity changes with temperature over the profile."""
        hot = np.any(np.asarray(self.temperature.temperatures_c) != self.reference_temperature_c)
        return bool(hot and (np.any(self.offset_tempco_g_per_c) or np.any(self.sensitivity_tempco_per_c)))

    def drifted_v(self, volts: np.ndarray, elapsed_s: np.ndarray) -> np.ndarray:
        """Output voltages ``(n, 3)`` of the sensor at the reference temperature moved to its temperature at
        ``elapsed_s`` since the start (module notes): ``V0 + (v − V0)(1 + α_s ΔT) + S (1 + e)(1 + α_s ΔT) α_b ΔT``.
        ``volts`` itself when nothing drifts."""
        if not self.drifts:
            return volts
        dt_c = (self.temperature.at(elapsed_s) - self.reference_temperature_c)[:, None]
        scale = 1.0 + self.sensitivity_tempco_per_c * dt_c
        return self.zero_g_v + (np.asarray(volts, np.float64) - self.zero_g_v) * scale \
            + self.gain_v_per_g * scale * self.offset_tempco_g_per_c * dt_c

    # ------------------------------------------------------------------ action
    def respond(self, acc_g: np.ndarray, sampling_rate_hz: float, *, rng: np.random.Generator | None = None,
                noise: bool = True, zi_settled: bool = True) -> np.ndarray:
        """Analog output voltages ``(n, 3)`` for a true specific force ``acc_g`` ``(n, 3)`` sampled at ``sampling_rate_hz``.

        Parameters
        ----------
        acc_g
            True specific force along the device's nominal axes, g, on a regular grid.
        sampling_rate_hz
            Rate of ``acc_g``; should be well above the filter cut-off (``internal_rate_hz`` is the
            design value). The signal path's RC filter is discretised by the bilinear transform with
            pre-warping (exact at the cut-off frequency, within 3 % of the analog RC up to twice the
            cut-off when the rate is ten times it).
        rng
            Noise generator; default the model's own seeded stream.
        noise
            Add the output noise (:meth:`noise_g`, exact at the grid instants). :meth:`Logger.record
            <gaitlog.firmware_sim.device.Logger.record>` passes False and adds the noise at the ADC's sample
            instants instead (the filter is linear, so the two are the same process).
        zi_settled
            Start the filter settled on the first input sample (a device powered on long before logging);
            False starts it at 0 g.
        """
        a = np.asarray(acc_g, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 3:
            raise DeviceError(f"acc_g must have shape (n, 3), got {a.shape}")
        if np.any(self.cutoff_hz >= sampling_rate_hz / 2):
            raise DeviceError(f"input rate {sampling_rate_hz} Hz too low for a {self.cutoff_hz.max():.1f} Hz filter")
        # work axis-major (3, n): each axis is one contiguous row for the projection and the filter
        if np.array_equal(self.axes, np.eye(3)):
            r = np.ascontiguousarray(a.T)  # element input, g along each sensitive axis
        else:
            r = self.axes @ a.T
        if r.size and (r.max() > self.range_g or r.min() < -self.range_g):
            np.clip(r, -self.range_g, self.range_g, out=r)
        # one first-order IIR per axis (the RC filter is genuinely recursive)
        designs = [signal.butter(1, fc, btype="low", fs=sampling_rate_hz) for fc in self.cutoff_hz]
        if all(np.array_equal(designs[0][0], d[0]) and np.array_equal(designs[0][1], d[1]) for d in designs):
            b, den = designs[0]
            zi = signal.lfilter_zi(b, den)[None, :] * (r[:, :1] if (zi_settled and r.shape[1]) else 0.0)
            out, _ = signal.lfilter(b, den, r, axis=1, zi=zi)
        else:
            out = np.empty_like(r)
            for j, (b, den) in enumerate(designs):
                zi = signal.lfilter_zi(b, den) * (r[j, 0] if (zi_settled and r.shape[1]) else 0.0)
                out[j], _ = signal.lfilter(b, den, r[j], zi=zi)
        if noise and a.shape[0]:
            out += self.noise_g(np.arange(a.shape[0]) / sampling_rate_hz, rng=rng).T
        out *= self.gain_v_per_g[:, None]
        out += (self.zero_g_v + self.gain_v_per_g * self.offset_g)[:, None]
        return out.T

    def truth(self) -> dict[str, object]:
        """Every parameter as plain arrays and numbers (for ground truth and reports)."""
        return {
            "axis_parts": AXIS_PARTS,
            "offset_g": self.offset_g.copy(),
            "sensitivity_error": self.sensitivity_error.copy(),
            "axes": self.axes.copy(),
            "cutoff_hz": self.cutoff_hz.copy(),
            "filter_capacitance_f": self.filter_capacitance_f.copy(),
            "noise_density_g_rthz": self.noise_density_g_rthz,
            "range_g": self.range_g,
            "supply_v": self.supply_v,
            "sensitivity_v_per_g": self.sensitivity_v_per_g,
            "gain_v_per_g": self.gain_v_per_g.copy(),
            "seed": self.seed,
            "flicker_corner_hz": self.flicker_corner_hz,
            "flicker_low_hz": self.flicker_low_hz,
            "offset_tempco_g_per_c": self.offset_tempco_g_per_c.copy(),
            "sensitivity_tempco_per_c": self.sensitivity_tempco_per_c.copy(),
            "temperature_profile": {"times_s": list(self.temperature.times_s),
                                    "temperatures_c": list(self.temperature.temperatures_c)},
            "reference_temperature_c": self.reference_temperature_c,
        }
