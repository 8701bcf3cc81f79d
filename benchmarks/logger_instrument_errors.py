"""Morris' and Hall's kinematics through the emulated logger, against the truth, with the sensors' errors on.

For each configuration and seed: simulate the motion, record it with the logger (sensor -> ADC -> memory,
PROTOCOL.md 2.6), write the memory image, decode it, analyse the decoded recording, and compare with the
simulation's truth: Morris' worst orientation error over each cycle found (heading aligned at the cycle
start, as accelerometers cannot sense it), Hall's worst joint-angle error. The same seed is also recorded by
the same parts without noise, offset or drift (``noise-free``: quantisation, filter lag and the method's own
error) and the stated bound is ``noise-free + 3 σ + offset + drift`` from the sensor model
(:mod:`gaitlog.host.kinematics.logger_error_budget`).

Prints one line per configuration (median and worst error over the seeds, the noise-free error, the bound's
parts); exits 1 if a run exceeds its bound.

Run: ``python benchmarks/logger_instrument_errors.py [--seeds N]`` (default 12).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.channel_sensors import ACCELEROMETER, RATE_SENSOR
from gaitlog.host.files.decode import decode_file
from gaitlog.host.kinematics.logger_error_budget import hall_error_budget, morris_error_budget
from gaitlog.host.kinematics.logger_instruments import (
    LoggedInstrument,
    record_instrument,
    sensor_recording,
)
from gaitlog.host.kinematics.morris_analysis import analyse_morris_recording
from gaitlog.host.kinematics.reports import analyse_hall, morris_errors, truth_from_columns

#: (label, instrument, keyword arguments of record_instrument)
CONFIGURATIONS = (
    ("Morris, 5 accelerometers, 100 Hz", "morris", {"n_accelerometers": 5}),
    ("Morris, 6 accelerometers, 100 Hz", "morris", {"n_accelerometers": 6}),
    ("Hall, 6 rate sensors, 1880 Hz", "hall", {"sampling_rate_hz": 1880.0}),
)
HALL_CFC = 180.0


class _Truth:
    def __init__(self, truth: dict[str, np.ndarray]) -> None:
        self.truth = truth


def _decoded(li: LoggedInstrument, folder: Path):
    path = li.logger.save_image(folder / "instrument.glimg")
    return sensor_recording(decode_file(path))


def run_once(instrument: str, kwargs: dict, seed: int, folder: Path) -> tuple[float, float, float]:
    """(error with the sensors' errors, noise-free error, bound), degrees."""
    li = record_instrument(instrument, seed=seed, **kwargs)
    li0 = record_instrument(instrument, seed=seed, sensors=li.sensors.without_errors(), **kwargs)
    adc_bits = int(li.logger.header.adc_bits)
    rate = li.logger.header.sampling_rate_hz
    errs = []
    cycle_s = 0.0
    for x in (li, li0):
        rec = _decoded(x, folder)
        if instrument == "morris":
            cycles = analyse_morris_recording(rec, x.platform)
            truth = truth_from_columns(_Truth(x.truth))
            errs.append(max(morris_errors(c, truth)["orientation_deg"] for c in cycles))
            cycle_s = max(cycle_s, max(c.t_s[-1] - c.t_s[0] for c in cycles))
        else:
            hall = analyse_hall(rec, x.platform, HALL_CFC, "absolute")
            true = np.stack([x.truth[f"{n}_rad"] for n in ("phi", "theta", "psi")], axis=1)
            errs.append(float(np.degrees(np.abs(hall.angles_rad_ - true).max())))
    n = li.sensors.n_channels
    if instrument == "morris":
        budget = morris_error_budget(li.platform, li.sensors, adc_bits=adc_bits, sampling_rate_hz=rate,
                                     cycle_s=cycle_s, offset_g=np.full(n, ACCELEROMETER.offset_tol),
                                     drift_g_per_s=np.full(n, ACCELEROMETER.drift_tol))
    else:
        budget = hall_error_budget(li.platform, li.sensors, adc_bits=adc_bits, sampling_rate_hz=rate,
                                   duration_s=li.t_s[-1], drift_rad_s2=np.full(n, RATE_SENSOR.drift_tol))
    return errs[0], errs[1], budget.bound_deg(errs[1]), budget


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=12)
    args = parser.parse_args(argv)
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for label, instrument, kwargs in CONFIGURATIONS:
            rows = [run_once(instrument, kwargs, seed, Path(tmp)) for seed in range(args.seeds)]
            err = np.array([r[0] for r in rows])
            free = np.array([r[1] for r in rows])
            bound = np.array([r[2] for r in rows])
            b = rows[0][3]
            over = int((err > bound).sum())
            failed |= over > 0
            print(f"{label}: error median {np.median(err):.3g} deg, worst {err.max():.3g} deg over {args.seeds} "
                  f"seeds; noise-free {free.min():.3g}-{free.max():.3g} deg; bound {bound.min():.3g}-{bound.max():.3g} "
                  f"deg (noise σ {b.noise_deg:.3g}, offset {b.offset_deg:.3g}, drift {b.drift_deg:.3g} deg)"
                  + (f"; {over} run(s) OVER THE BOUND" if over else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
