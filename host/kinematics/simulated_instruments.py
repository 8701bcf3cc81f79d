"""Simulated recordings of Morris' and Hall's instruments, written in the recording format, with their truth.

:func:`simulate_morris` renders :class:`RigidBodyShank` (five accelerometers as Morris mounted them, or six)
and adds white noise per accelerometer at a stated signal-to-noise ratio: Morris gives "better than 40 dB"
within the signal band, so the default is 40 dB, the noise standard deviation of each channel being the RMS
of its varying part divided by ``10^(40/20) = 100`` (about 1-13 mg on the simulated shank). The default record
is Morris' 2.56 s, cut to start in swing so that it holds one cycle from foot-flat to foot-flat.

:func:`simulate_hall` renders :class:`TwoLinkJoint` (Hall: 10 kHz) with a pre-test posture that is not
neutral -- link B starts turned by ``Rx(6°) Ry(12°)`` relative to link A -- so that taking the initial A−B
transformation as identity would be visibly wrong; each link also carries a triaxial accelerometer along its
link axes (gravity channels) from which that posture is found.

Each ``write_*`` writes ``<name>.csv`` (the recording), ``<name>_platform.json`` and ``<name>_truth.csv``
(columns: the true orientation / joint matrix row by row, angular velocity, origin position).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.firmware_sim.world.rigid_body import RigidBodyShank, elementary_rotations
from gaitlog.firmware_sim.world.two_link import HALL_SENSOR_TO_LINK, TwoLinkJoint
from gaitlog.host.kinematics.joints import joint_angles_yxz
from gaitlog.host.kinematics.platform_description import HallLink, HallPlatform, MorrisPlatform
from gaitlog.host.kinematics.sensor_csv import write_sensor_csv

__all__ = [
    "HALL_INITIAL_B_FROM_A",
    "MORRIS_SNR_DB",
    "SimulatedInstrument",
    "noise_sd_for_snr",
    "simulate_hall",
    "simulate_morris",
    "write_instrument",
]

#: Morris: "mean signal-to-noise ratio within the signal frequency band is better than 40 db".
MORRIS_SNR_DB = 40.0
#: Pre-test posture of link B relative to link A in the simulated Hall test.
HALL_INITIAL_B_FROM_A = elementary_rotations("x", np.radians(6.0)) @ elementary_rotations("y", np.radians(12.0))


@dataclass(frozen=True, eq=False)
class SimulatedInstrument:
    """A simulated recording: time, named columns (with units), platform, truth columns."""

    t_s: np.ndarray
    columns: dict[str, np.ndarray]
    platform: MorrisPlatform | HallPlatform
    truth: dict[str, np.ndarray]
    comment: str


def noise_sd_for_snr(signals: np.ndarray, snr_db: float) -> np.ndarray:
    """Per-column noise standard deviation giving ``snr_db``: RMS of the column's varying part / 10^(snr/20)."""
    x = np.asarray(signals, dtype=np.float64)
    return np.sqrt(np.mean((x - x.mean(axis=0)) ** 2, axis=0)) / 10.0 ** (snr_db / 20.0)


def _dcm_columns(prefix: str, m: np.ndarray) -> dict[str, np.ndarray]:
    return {f"{prefix}{i + 1}{j + 1}": m[:, i, j] for i in range(3) for j in range(3)}


def simulate_morris(*, n_accelerometers: int = 5, axial_rotation: bool = True, snr_db: float | None = MORRIS_SNR_DB,
                    duration_s: float = 2.56, start_s: float = 0.6, sampling_rate_hz: float = 100.0,
                    seed: int = 0) -> SimulatedInstrument:
    """Morris' shank platform (module notes). ``snr_db=None``: no noise; ``axial_rotation=False``: ψ ≡ 0."""
    kw: dict[str, Any] = {} if axial_rotation else {"axial_deg": ()}
    src = RigidBodyShank(n_accelerometers=n_accelerometers, **kw)
    src.n_cycles = int(np.ceil((start_s + duration_s) / src.cycle_s)) + 1
    rec = src.render_platform(sampling_rate_hz)
    tr = rec.motion.truth
    first = round(start_s * sampling_rate_hz)
    sel = slice(first, first + round(duration_s * sampling_rate_hz))
    readings = rec.readings_g[sel]
    if snr_db is not None:
        sd = noise_sd_for_snr(readings, snr_db)
        readings = readings + np.random.default_rng(seed).normal(0.0, 1.0, readings.shape) * sd
    names = [f"acc{i + 1}" for i in range(n_accelerometers)]
    platform = MorrisPlatform(names, rec.positions_m, rec.axes, tr["origin_offset_m"],
                              (2,) if n_accelerometers == 5 else ())
    truth = {**_dcm_columns("dcm", tr["dcm"][sel]),
             **{f"omega{k + 1}_rad_s": tr["omega_rad_s"][sel, k] for k in range(3)},
             **{f"position{k + 1}_m": tr["position_m"][sel, k] for k in range(3)}}
    noise = "no noise" if snr_db is None else f"white noise at {snr_db:g} dB SNR per accelerometer, seed {seed}"
    comment = (f"Simulated Morris (1973) shank platform: {n_accelerometers} accelerometers, "
               f"{'with' if axial_rotation else 'without'} axial rotation, {sampling_rate_hz:g} Hz, {noise}")
    return SimulatedInstrument(tr["t_s"][sel], {f"{n}_g": readings[:, i] for i, n in enumerate(names)},
                               platform, truth, comment)


def simulate_hall(*, sampling_rate_hz: float = 10_000.0, noise_rad_s: float = 0.01, gravity_noise_g: float = 0.002,
                  seed: int = 0, rate_offsets: bool = True) -> SimulatedInstrument:
    """Hall's two links with angular-rate sensors and gravity channels, pre-test posture not neutral.
    ``rate_offsets=False``: the rate channels without the world's sensor offsets (for a sensor model that
    adds its own, :mod:`gaitlog.host.kinematics.logger_instruments`)."""
    src = TwoLinkJoint(noise_rad_s=0.0)
    r = src.render_rates(sampling_rate_hz)
    tr = r.truth
    lam_a = np.swapaxes(tr["ta"], 1, 2)
    lam_b = np.swapaxes(tr["tb"], 1, 2) @ HALL_INITIAL_B_FROM_A
    w_a = tr["omega_a_link_rad_s"]
    w_b = tr["omega_b_link_rad_s"] @ HALL_INITIAL_B_FROM_A  # body rate of λB·R: Rᵀω
    rng = np.random.default_rng(seed)
    n = w_a.shape[0]
    s = HALL_SENSOR_TO_LINK
    on = 1.0 if rate_offsets else 0.0
    rate_a = w_a @ s + on * np.asarray(src.offset_a_rad_s) + rng.normal(0.0, noise_rad_s, (n, 3))
    rate_b = w_b @ s + on * np.asarray(src.offset_b_rad_s) + rng.normal(0.0, noise_rad_s, (n, 3))
    up_a = lam_a[:, 2, :] + rng.normal(0.0, gravity_noise_g, (n, 3))  # λᵀ e3: up in link axes
    up_b = lam_b[:, 2, :] + rng.normal(0.0, gravity_noise_g, (n, 3))
    cols: dict[str, np.ndarray] = {}
    for link, rate, up in (("A", rate_a, up_a), ("B", rate_b, up_b)):
        for k, ax in enumerate("xyz"):
            cols[f"{link}_{ax}_rad_s"] = rate[:, k]
        for k, ax in enumerate("xyz"):
            cols[f"{link}_g{ax}_g"] = up[:, k]
    links = [HallLink([f"{k}_x", f"{k}_y", f"{k}_z"], s, [f"{k}_gx", f"{k}_gy", f"{k}_gz"]) for k in "AB"]
    platform = HallPlatform(links[0], links[1], "yxz", "left", float(src.pretest_s), None)
    joint = np.swapaxes(lam_b, 1, 2) @ lam_a  # T = TB·TAᵀ
    angles, _ = joint_angles_yxz(joint)
    truth = {**_dcm_columns("T", joint), **{f"{n}_rad": angles[:, k] for k, n in enumerate(("phi", "theta", "psi"))}}
    comment = (f"Simulated Hall (1997) two-link test: {sampling_rate_hz:g} Hz, rate noise {noise_rad_s:g} rad/s, "
               f"gravity noise {gravity_noise_g:g} g, seed {seed}; pre-test posture B = A·Rx(6°)Ry(12°)")
    return SimulatedInstrument(tr["t_s"], cols, platform, truth, comment)


def write_instrument(sim: SimulatedInstrument, folder: str | Path, name: str) -> list[Path]:
    """Write ``name.csv``, ``name_platform.json`` and ``name_truth.csv`` into ``folder`` (created)."""
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    paths = [d / f"{name}.csv", d / f"{name}_platform.json", d / f"{name}_truth.csv"]
    write_sensor_csv(paths[0], sim.t_s, sim.columns, comment=sim.comment)
    sim.platform.save(paths[1])
    write_sensor_csv(paths[2], sim.t_s, sim.truth, comment=f"truth of {name}.csv", check_units=False)
    return paths
