"""``gaitlog demo``: the whole data path on defaults, as a sequence of stages.

record (calibration poses with the emulated logger) -> serve (the image as a live device on a pty) ->
dump (over the pty, as from a real logger) -> decode (CSV + NPZ) -> calibrate (9-parameter fit on the dumped
poses, CAL.json) -> summary (samples, gaps, duration and, per pose, the mean g against the truth and the
error of |a| before and after calibration) -> walk (a simulated subject through the paper's protocol,
recorded by the same emulated device, g from the pose calibration) -> estimate (the float chain, K per
subject, every 20 m section's ratio, CSV and the Figs 5-6 box plots: :mod:`host.evaluation`) -> fixed (the
PIC's fixed-point chain vs the float chain on the same codes: :mod:`host.compare`).

Later issues extend the demo by appending :class:`Stage` objects to :data:`STAGES` (each stage reads and
adds entries of the shared ``context`` dict and returns lines to print).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

HELP = ("run the whole path on defaults: record poses -> serve on a pty -> dump -> decode -> calibrate -> summary "
        "-> walk a simulated subject -> M1-M5 per 20 m and box plots -> fixed vs float")


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


def _walk(ctx: dict[str, Any]) -> list[str]:
    import numpy as np

    from firmware_sim.device import Logger
    from firmware_sim.sensor import SensorModel
    from firmware_sim.world.subject import random_subjects
    from firmware_sim.world.walking import Walking
    from host.evaluation import SimulatedRecording
    from protocol.header import Calibration
    from protocol.packing import FLAG_MARK

    args = ctx["args"]
    subject = random_subjects(1, seed=args.seed)[0]
    logger = Logger(sensor=SensorModel.draw(seed=args.seed), sample_rate_hz=50.0)   # the device calibrated above
    res = logger.record(Walking(subject=subject, seed=args.seed), start_time_s=1_700_000_000)
    acc_cal = ctx.get("calibration")
    cal = (Calibration(acc_cal.offset, acc_cal.matrix, valid=True) if acc_cal is not None
           else Calibration.nominal(10))
    codes = np.asarray(res.codes, np.int64)
    times = np.asarray(res.sample_times_s, np.float64)
    marks = times[(np.asarray(res.flags) & FLAG_MARK) != 0]
    rec = SimulatedRecording(subject, int(args.seed), cal.apply(codes.astype(np.float64)),
                             np.ones(codes.shape[0], bool), 50.0, float(times[0]), marks,
                             {k: res.truth[k] for k in ("steps", "laps", "excursions", "rests")}, acc_cal is not None)
    ctx.update(walk_codes=codes, walk_recording=rec, walk_calibration=cal)
    st = res.truth["steps"]
    return [f"subject {subject.subject_id}: height {subject.height_m:.2f} m, leg {subject.leg_length_m:.3f} m, "
            f"foot {subject.foot_length_m:.3f} m; protocol 4 x 200 m (preferred, fast, slow, medium)",
            f"{res.n_samples} samples ({res.n_samples / 50 / 60:.1f} min at 50 Hz), {len(marks)} lap marks, "
            f"{len(st['length_m'])} true steps; g from the {'pose calibration above' if acc_cal else 'nominal map'}"]


def _estimate(ctx: dict[str, Any]) -> list[str]:
    from host.compare import rows_csv_text
    from host.evaluation import evaluate_recording, format_summary, summarise
    from host.evaluation_plots import plot_boxplots
    from protocol.atomic_write import atomic_write_text

    res = evaluate_recording(ctx["walk_recording"])
    summary = summarise(res.rows)
    rows_path = ctx["dir"] / "walk_sections.csv"
    fig_path = ctx["dir"] / "walk_boxplots.png"
    atomic_write_text(rows_path, rows_csv_text(res.rows))
    plot_boxplots(res.rows, fig_path, title=f"simulated subject {res.subject_id}, 50 Hz, 10 bits (float chain)")
    ctx["walk_result"] = res
    k = res.calibrations["multi-speed"]
    return ([f"float chain, K per mode from the first 40 m; 20 m sections: ratio estimated / real -> {rows_path}, "
             f"{fig_path}"] + format_summary(summary, res.events).splitlines()
            + [f"multi-speed K: M1 {k.k_m1:.3f}, M2 {k.k_m2:.3f}, M4 {k.k_m4:.3f} m/(m/s2)^1/4, "
               f"M5 S = {k.k1_m5_m_s:.3f}/T + {k.k2_m5_m:.3f} m"])


def _fixed(ctx: dict[str, Any]) -> list[str]:
    import numpy as np

    from host.compare import compare_recording, format_step_diffs, rows_csv_text
    from host.evaluation import sections_from_marks
    from protocol.atomic_write import atomic_write_text

    rec = ctx["walk_recording"]
    sub = rec.subject
    secs = [s for s in sections_from_marks(rec.mark_times_s, rec.truth["laps"]) if not s.turn]
    res = compare_recording(ctx["walk_codes"], sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=sub.leg_length_m,
                            foot_length_m=sub.foot_length_m, adc_calibration=ctx["walk_calibration"],
                            calibration=ctx["walk_result"].calibrations["multi-speed"], t0_s=rec.t0_s, sections=secs)
    path = ctx["dir"] / "walk_fixed_vs_float.csv"
    atomic_write_text(path, rows_csv_text(res.segments))
    m = res.match
    lines = [f"the PIC's fixed-point chain vs the float chain on the same 10-bit codes, same K -> {path}",
             f"steps: float {res.float_table.n_steps}, fixed {res.fixed_table.n_steps}, matched {m.n_matched}; "
             f"different events {int(np.count_nonzero(~m.same_events))} (+ {m.only_a.size + m.only_b.size} "
             "found by one chain only)"]
    lines += format_step_diffs(res.step_diffs).splitlines()
    lines.append(f"{'est':<5}{'20 m sections':>14}{'ratio float':>13}{'ratio fixed':>13}{'max |d ratio|':>15}")
    for est in ("M1", "M2", "M3", "M4", "M5"):
        r = [x for x in res.segments if x["estimator"] == est]
        a = np.array([x["ratio_float"] for x in r])
        b = np.array([x["ratio_fixed"] for x in r])
        lines.append(f"{est:<5}{len(r):>14}{np.median(a):>13.4f}{np.median(b):>13.4f}{np.max(np.abs(b - a)):>15.5f}")
    lines.append(f"saturation/wrap: {res.saturation or 'none'}; estimated PIC cycles per sample "
                 f"{res.cycles_per_sample:.0f} of 100,000 at 50 Hz")
    return lines


#: The demo, in order. Later issues append stages here.
STAGES: list[Stage] = [
    Stage("record", _record),
    Stage("serve", _serve),
    Stage("dump", _dump),
    Stage("decode", _decode),
    Stage("calibrate", _calibrate),
    Stage("summary", _summary),
    Stage("walk", _walk),
    Stage("estimate", _estimate),
    Stage("fixed", _fixed),
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
