"""``gaitlog demo``: the whole data path on defaults, as a sequence of stages.

record (calibration poses with the emulated logger) -> serve (the image as a live device on a pty) ->
dump (over the pty, as from a real logger) -> decode (CSV + NPZ) -> calibrate (9-parameter fit on the dumped
poses, CAL.json) -> summary (samples, gaps, duration and, per pose, the mean g against the truth and the
error of |a| before and after calibration).

Later issues extend the demo by appending :class:`Stage` objects to :data:`STAGES` (each stage reads and
adds entries of the shared ``context`` dict and returns lines to print).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

HELP = "run the whole path on defaults: record poses -> serve on a pty -> dump -> decode -> calibrate -> summary"


@dataclass(frozen=True)
class Stage:
    """One step of the demo: ``run(context) -> lines to print``."""

    name: str
    run: Callable[[dict[str, Any]], list[str]]


def _record(ctx: dict[str, Any]) -> list[str]:
    from firmware_sim.device import Logger
    from firmware_sim.sensor import SensorModel
    from firmware_sim.world.poses import CalibrationPoses

    args = ctx["args"]
    source = CalibrationPoses(n_poses=args.poses, hold_s=5.0, move_s=2.0, seed=args.seed)
    motion = source.render(50.0)
    logger = Logger(sensor=SensorModel.draw(seed=args.seed), sample_rate_hz=50.0)
    result = logger.record(motion, start_time_s=1_700_000_000)
    image = ctx["dir"] / "recorded.glimg"
    logger.save_image(image)
    ctx.update(motion=motion, record_result=result, recorded_image=image)
    return [f"{len(result.codes)} samples of {args.poses} poses ({motion.duration_s:.0f} s) -> {image}"]


def _serve(ctx: dict[str, Any]) -> list[str]:
    from firmware_sim.device import Logger
    from firmware_sim.transport import serve_pty

    server = serve_pty(Logger.from_image(ctx["recorded_image"]), baud=115200)
    server.start()
    ctx["cleanup"].append(server.stop)
    ctx["port"] = server.path
    return [f"device on pty {server.path}"]


def _dump(ctx: dict[str, Any]) -> list[str]:
    from host.link import LoggerLink

    out = ctx["dir"] / "dumped.glimg"
    with LoggerLink(ctx["port"], baud=115200) as link:
        result = link.dump(out, progress=not ctx["args"].quiet)
    meta = result.metadata_
    ctx["dumped_image"] = out
    return [f"{meta['stored_bytes']} bytes in {meta['duration_s']:.2f} s, {meta['frames_damaged']} damaged "
            f"frames -> {out} (+ {result.metadata_path_.name})"]


def _decode(ctx: dict[str, Any]) -> list[str]:
    from host.decode import decode_file, save_outputs

    rec = decode_file(ctx["dumped_image"])
    npz, csv = save_outputs(rec, ctx["dir"] / "decoded")
    ctx["recording"] = rec
    return [f"-> {csv}, {npz}"]


def _calibrate(ctx: dict[str, Any]) -> list[str]:
    import numpy as np

    from host.calibration import AccCalibrator

    rec = ctx["recording"]
    n_poses = len(ctx["motion"].truth["hold_windows_s"])
    if n_poses < 9:
        return [f"skipped: {n_poses} poses, the 9-parameter model needs at least 9 (use --poses 24)"]
    counts = rec.codes.astype(np.float64)
    counts[~rec.valid] = np.nan
    span = 2 ** int(rec.adc_bits)
    fit = AccCalibrator(model="9-param").calibrate(
        counts, sampling_rate_hz=rec.sampling_rate_hz, input_unit="counts", zero=span / 2,
        unit_per_g=span / 4, valid_range=(0.0, float(span - 1)))
    cal = fit.calibration_
    path = ctx["dir"] / "calibration.json"
    cal.save(path)
    ctx["calibration"] = cal
    return [f"{cal.n_poses} static poses found, 9-parameter fit: |a| - 1 g rms {cal.residual_rms_g * 1e3:.2f} mg, "
            f"max {cal.residual_max_g * 1e3:.2f} mg -> {path}",
            "offset (counts) " + " ".join(f"{v:.2f}" for v in cal.offset)
            + "; scale (counts/g) " + " ".join(f"{v:.2f}" for v in cal.scale_per_g)
            + "; axis angles (deg) " + " ".join(f"{v:+.3f}" for v in cal.angles_deg)]


def _summary(ctx: dict[str, Any]) -> list[str]:
    import numpy as np

    rec = ctx["recording"]
    truth = ctx["record_result"]
    exact = bool(rec.valid.all() and np.array_equal(rec.codes, np.asarray(truth.codes)))
    lines = [f"{rec.n_samples} samples, {rec.n_valid} valid, {len(rec.gaps)} gap(s), {rec.duration_s:.1f} s "
             f"at {rec.sampling_rate_hz:g} Hz; bit-identical to what the device recorded: {exact}",
             rec.default_calibration()[1]]
    acc = rec.acc_g()
    counts = rec.codes.astype(np.float64)
    counts[~rec.valid] = np.nan
    cal = ctx.get("calibration")
    acc_cal = cal.apply(counts) if cal is not None else np.full_like(acc, np.nan)
    t = rec.time_s - rec.time_s[0] if rec.n_samples else rec.time_s
    holds = np.asarray(ctx["motion"].truth["hold_windows_s"])
    up = np.asarray(ctx["motion"].truth["specific_force_g"])
    lines.append("pose   mean x_g  mean y_g  mean z_g   (truth x, y, z)            |a|-1 g (mg): nominal  calibrated")
    worst = [0.0, 0.0]
    for i, (t0, t1) in enumerate(holds):
        sel = (t >= t0 + 0.5) & (t < t1 - 0.5) & rec.valid
        m = acc[sel].mean(axis=0) if sel.any() else np.full(3, np.nan)
        mc = acc_cal[sel].mean(axis=0) if sel.any() else np.full(3, np.nan)
        err = [(np.linalg.norm(m) - 1.0) * 1e3, (np.linalg.norm(mc) - 1.0) * 1e3]
        worst = [max(w, abs(e)) for w, e in zip(worst, err, strict=True)]
        lines.append(f"{i + 1:4d}  {m[0]:+8.3f}  {m[1]:+8.3f}  {m[2]:+8.3f}   "
                     f"({up[i, 0]:+.3f}, {up[i, 1]:+.3f}, {up[i, 2]:+.3f})   {err[0]:+8.1f}  {err[1]:+8.2f}")
    lines.append(f"worst | |a| - 1 g | over the poses: {worst[0]:.1f} mg with the nominal map, "
                 f"{worst[1]:.2f} mg calibrated (one LSB is {4000 / 2 ** rec.adc_bits:.1f} mg)")
    return lines


#: The demo, in order. Later issues append stages here.
STAGES: list[Stage] = [
    Stage("record", _record),
    Stage("serve", _serve),
    Stage("dump", _dump),
    Stage("decode", _decode),
    Stage("calibrate", _calibrate),
    Stage("summary", _summary),
]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", help="keep the files in DIR (default: a temporary directory)")
    parser.add_argument("--poses", type=int, default=24, help="number of calibration poses (default 24)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor and the poses (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    import tempfile
    from pathlib import Path

    from host.errors import HostError

    tmp = None
    if args.out:
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise HostError(f"--out {out}: exists and is not a directory")
        out.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="gaitlog-demo-")
        out = Path(tmp.name)
    ctx: dict[str, Any] = {"args": args, "dir": out, "cleanup": []}
    try:
        for stage in STAGES:
            lines = stage.run(ctx)
            print(f"[{stage.name}] " + (lines[0] if lines else ""), flush=True)
            for line in lines[1:]:
                print(f"    {line}", flush=True)
    finally:
        for fn in reversed(ctx["cleanup"]):
            fn()
        if tmp is not None:
            tmp.cleanup()
    return 0
