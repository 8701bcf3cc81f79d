"""``gaitlog demo``: the whole data path on defaults, as a sequence of stages.

record (calibration poses with the emulated logger) -> serve (the image as a live device on a pty) ->
dump (over the pty, as from a real logger) -> decode (CSV + NPZ) -> summary (samples, gaps, duration and the
per-axis mean g of each pose against the truth).

Later issues extend the demo by appending :class:`Stage` objects to :data:`STAGES` (each stage reads and
adds entries of the shared ``context`` dict and returns lines to print).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

HELP = "run the whole path on defaults: record poses -> serve on a pty -> dump -> decode -> summary"


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


def _summary(ctx: dict[str, Any]) -> list[str]:
    import numpy as np

    rec = ctx["recording"]
    truth = ctx["record_result"]
    exact = bool(rec.valid.all() and np.array_equal(rec.codes, np.asarray(truth.codes)))
    lines = [f"{rec.n_samples} samples, {rec.n_valid} valid, {len(rec.gaps)} gap(s), {rec.duration_s:.1f} s "
             f"at {rec.sampling_rate_hz:g} Hz; bit-identical to what the device recorded: {exact}",
             rec.default_calibration()[1]]
    acc = rec.acc_g()
    t = rec.time_s - rec.time_s[0] if rec.n_samples else rec.time_s
    holds = np.asarray(ctx["motion"].truth["hold_windows_s"])
    up = np.asarray(ctx["motion"].truth["specific_force_g"])
    lines.append("pose   mean x_g  mean y_g  mean z_g   (truth x, y, z)")
    for i, (t0, t1) in enumerate(holds):
        sel = (t >= t0 + 0.5) & (t < t1 - 0.5) & rec.valid
        m = acc[sel].mean(axis=0) if sel.any() else np.full(3, np.nan)
        lines.append(f"{i + 1:4d}  {m[0]:+8.3f}  {m[1]:+8.3f}  {m[2]:+8.3f}   "
                     f"({up[i, 0]:+.3f}, {up[i, 1]:+.3f}, {up[i, 2]:+.3f})")
    return lines


#: The demo, in order. Later issues append stages here.
STAGES: list[Stage] = [
    Stage("record", _record),
    Stage("serve", _serve),
    Stage("dump", _dump),
    Stage("decode", _decode),
    Stage("summary", _summary),
]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", help="keep the files in DIR (default: a temporary directory)")
    parser.add_argument("--poses", type=int, default=12, help="number of calibration poses (default 12)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor and the poses (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    import tempfile
    from pathlib import Path

    from host.errors import HostError

    tmp = None
    if args.out:
        out = Path(args.out)
        if not out.is_dir():
            raise HostError(f"--out {out}: not a directory")
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
