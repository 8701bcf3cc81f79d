"""The stages of ``gaitlog demo``: the whole data path on defaults (the command's notes list them).

Each :class:`Stage` reads and adds entries of one shared ``context`` dict and returns the lines to print. The
command fills in ``args`` (its parsed options: ``poses``, ``seed``), ``dir`` (the output folder), ``progress``
(show the dump's progress bar) and ``cleanup`` (callables run at the end, last first), and prints the lines.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text
from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.firmware_sim.algorithms.online import OnlineSteps
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.fixedpoint import cycles_per_sample_available
from gaitlog.firmware_sim.pty_server import serve_pty
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.world.poses import CalibrationPoses
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.accelerometer.fit import AccCalibrator
from gaitlog.host.files.decode import decode_file, save_decoded, save_outputs
from gaitlog.host.files.replay import verify_step_records
from gaitlog.host.gait.sections import sections_from_marks
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.host.link.memory_dump import dump_memory
from gaitlog.host.studies.compare import (
    compare_recording,
    format_step_diffs,
    match_steps,
    offline_step_table,
    rows_csv_text,
    segment_distances,
    step_differences,
)
from gaitlog.host.studies.evaluation import evaluate_recording, format_summary, summarise
from gaitlog.host.studies.overview import recording_overview
from gaitlog.host.studies.plots import plot_boxplots, render_overview_png
from gaitlog.host.studies.simulation import SimulatedRecording
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.packing import FLAG_MARK
from gaitlog.protocol.steps import StepConfig


@dataclass(frozen=True)
class Stage:
    """One step of the demo: ``run(context) -> lines to print``."""

    name: str
    run: Callable[[dict[str, Any]], list[str]]


def _record(ctx: dict[str, Any]) -> list[str]:
    args = ctx["args"]
    source = CalibrationPoses(n_poses=args.poses, hold_s=5.0, move_s=2.0, seed=args.seed)
    motion = source.render(DEFAULT_SAMPLING_RATE_HZ)
    logger = Logger(sensor=SensorModel.draw(seed=args.seed))
    result = logger.record(motion, start_time_s=1_700_000_000)
    image = ctx["dir"] / "recorded.glimg"
    logger.save_image(image)
    ctx.update(motion=motion, record_result=result, recorded_image=image)
    return [f"{len(result.codes)} samples of {args.poses} poses ({motion.duration_s:.0f} s) -> {image}"]


def _serve(ctx: dict[str, Any]) -> list[str]:
    server = serve_pty(Logger.from_image(ctx["recorded_image"]), baud=115200)
    server.start()
    ctx["cleanup"].append(server.stop)
    ctx["port"] = server.path
    return [f"device on pty {server.path}"]


def _dump(ctx: dict[str, Any]) -> list[str]:
    out = ctx["dir"] / "dumped.glimg"
    with LoggerLink(ctx["port"], baud=115200) as link:
        result = dump_memory(link, out, progress=ctx["progress"])
    meta = result.metadata_
    ctx["dumped_image"] = out
    return [f"{meta['stored_bytes']} bytes in {meta['duration_s']:.2f} s, {meta['frames_damaged']} damaged "
            f"frames -> {out} (+ {result.metadata_path_.name})"]


def _decode(ctx: dict[str, Any]) -> list[str]:
    rec = decode_file(ctx["dumped_image"])
    npz, csv = save_outputs(rec, ctx["dir"] / "decoded")
    ctx["recording"] = rec
    return [f"-> {csv}, {npz}"]


def _calibrate(ctx: dict[str, Any]) -> list[str]:
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


def _walk_logger(ctx: dict[str, Any], step_config: Any) -> Any:
    """The demo's device (the sensor of the poses), its header holding the pose calibration and
    ``step_config`` (as SET_CALIBRATION and SET_STEP_CONFIG would leave it)."""
    logger = Logger(sensor=SensorModel.draw(seed=ctx["args"].seed), step_config=step_config)
    logger.ring.set_calibration(ctx["walk_calibration"])
    return logger


def _walk(ctx: dict[str, Any]) -> list[str]:
    args = ctx["args"]
    subject = random_subjects(1, seed=args.seed)[0]
    acc_cal = ctx.get("calibration")
    cal = acc_cal.to_header_calibration() if acc_cal is not None else CalibrationSlot.nominal(10)
    ctx.update(walk_calibration=cal, subject=subject)
    logger = _walk_logger(ctx, StepConfig(step_format=1, leg_length_m=subject.leg_length_m,
                                          foot_length_m=subject.foot_length_m))
    res = logger.record(Walking(subject=subject, seed=args.seed), start_time_s=1_700_000_000)
    image = ctx["dir"] / "walk.glimg"
    logger.save_image(image)
    codes = np.asarray(res.codes, np.int64)
    times = np.asarray(res.sample_times_s, np.float64)
    marks = times[(np.asarray(res.flags) & FLAG_MARK) != 0]
    rec = SimulatedRecording(subject, int(args.seed), cal.apply(codes.astype(np.float64)),
                             np.ones(codes.shape[0], bool), logger.adc.sampling_rate_hz, float(times[0]), marks,
                             {k: res.truth[k] for k in ("steps", "laps", "excursions", "rests")}, acc_cal is not None)
    ctx.update(walk_codes=codes, walk_recording=rec, walk_times_s=times)
    st = res.truth["steps"]
    return [f"subject {subject.subject_id}: height {subject.height_m:.2f} m, leg {subject.leg_length_m:.3f} m, "
            f"foot {subject.foot_length_m:.3f} m; protocol 4 x 200 m (preferred, fast, slow, medium)",
            f"{res.n_samples} samples ({res.n_samples / 50 / 60:.1f} min at 50 Hz), {len(marks)} lap marks, "
            f"{len(st['length_m'])} true steps; g from the {'pose calibration above' if acc_cal else 'nominal map'}",
            f"the logger ran its on-line step algorithm while recording (leg and foot set, no K yet): "
            f"{logger.header.steps_written} step records in its step memory -> {image}"]


def _estimate(ctx: dict[str, Any]) -> list[str]:
    res = evaluate_recording(ctx["walk_recording"])
    summary = summarise(res.rows)
    rows_path = ctx["dir"] / "walk_sections.csv"
    fig_path = ctx["dir"] / "walk_boxplots.png"
    atomic_write_text(rows_path, rows_csv_text(res.rows))
    plot_boxplots(res.rows, fig_path, title=f"simulated subject {res.subject_id}, 50 Hz, 10 bits (float chain)")
    ctx["walk_result"] = res
    k = res.calibrations["multi-speed"]
    k_path = ctx["dir"] / "k.json"
    k.save(k_path)
    ctx["k_path"] = k_path
    return ([f"float chain, K per mode from the first 40 m; 20 m sections: ratio estimated / real -> {rows_path}, "
             f"{fig_path}"] + format_summary(summary, res.events).splitlines()
            + [f"multi-speed K: M1 {k.k_m1:.3f}, M2 {k.k_m2:.3f}, M4 {k.k_m4:.3f} m/(m/s2)^{k.m4_exponent:g}, "
               f"M5 S = {k.k1_m5_m_s:.3f}/T + {k.k2_m5_m:.3f} m -> {k_path}"])


def _device(ctx: dict[str, Any]) -> list[str]:
    sub = ctx["subject"]
    k = ctx["walk_result"].calibrations["multi-speed"]
    cfg = StepConfig(step_format=1, leg_length_m=sub.leg_length_m, foot_length_m=sub.foot_length_m,
                     **k.step_constants())
    logger = _walk_logger(ctx, cfg)                          # SET_STEP_CONFIG with the subject's K
    logger.record(Walking(subject=sub, seed=ctx["args"].seed), start_time_s=1_700_000_000)
    image = ctx["dir"] / "walk_k.glimg"
    logger.save_image(image)
    rec = decode_file(image)
    ctx["walk_k_image"] = image
    check = verify_step_records(rec)
    t0 = float(ctx["walk_times_s"][0])
    device = StepTable.from_online(OnlineSteps.from_records(rec.step_records, first_sample_number=int(
        rec.sample_numbers[0]), sampling_rate_hz=rec.sampling_rate_hz), t0_s=t0)
    walk = ctx["walk_recording"]
    offline = offline_step_table(walk.acc_g, sampling_rate_hz=walk.sampling_rate_hz, leg_length_m=sub.leg_length_m,
                                 foot_length_m=sub.foot_length_m, k_fit=k, t0_s=t0)
    secs = [s for s in sections_from_marks(walk.mark_times_s, walk.truth["laps"]) if not s.turn]
    real = np.array([s.real_m for s in secs])
    d_dev, d_off = segment_distances(device, secs), segment_distances(offline, secs)
    diffs = step_differences(device, offline, match_steps(device, offline), pair="device - offline")
    lines = [f"multi-speed K sent to the device (SET_STEP_CONFIG), the walk recorded again -> {image}: "
             f"{rec.n_step_records} step records decoded; {check.summary() if check else 'nothing to check'}",
             "the device's own lengths (on-line algorithm, PIC fixed point) beside the host's offline float chain, "
             "same K:",
             f"{'est':<5}{'20 m sections':>14}{'device ratio':>14}{'offline ratio':>15}{'max |d ratio|':>15}"
             f"{'per step med |d| mm':>21}"]
    for j, est in enumerate(ESTIMATORS):
        a, b = d_dev[:, j] / real, d_off[:, j] / real
        med = next(r["median_abs_mm"] for r in diffs if r["estimator"] == est)
        lines.append(f"{est:<5}{len(secs):>14}{np.nanmedian(a):>14.4f}{np.nanmedian(b):>15.4f}"
                     f"{np.nanmax(np.abs(a - b)):>15.4f}{med:>21.2f}")
    return lines


def _split(ctx: dict[str, Any]) -> list[str]:
    rec = ctx["walk_recording"]
    sub = rec.subject
    secs = [s for s in sections_from_marks(rec.mark_times_s, rec.truth["laps"]) if not s.turn]
    res = compare_recording(ctx["walk_codes"], sampling_rate_hz=rec.sampling_rate_hz, leg_length_m=sub.leg_length_m,
                            foot_length_m=sub.foot_length_m, adc_calibration=ctx["walk_calibration"],
                            k_fit=ctx["walk_result"].calibrations["multi-speed"], t0_s=rec.t0_s, sections=secs)
    path = ctx["dir"] / "walk_split.csv"
    atomic_write_text(path, rows_csv_text(res.segments))
    tb = res.tables
    lines = [f"the same codes, the same K: offline (host) vs on-line float vs on-line fixed (the device's) -> {path}",
             "steps: " + ", ".join(f"{c} {tb[c].n_steps}" for c in tb) + "; " + "; ".join(
                 f"{s}: different events {int(np.count_nonzero(~m.same_events))} (+ {m.only_a.size + m.only_b.size} "
                 "found by one chain only)" for s, m in res.matches.items())]
    lines += format_step_diffs(res.step_diffs).splitlines()
    lines.append(f"{'est':<5}{'20 m sections':>14}{'offline':>10}{'on-line float':>15}{'on-line fixed':>15}"
                 f"{'max |alg|':>11}{'max |arith|':>13}")
    for est in ESTIMATORS:
        r = [x for x in res.segments if x["estimator"] == est]
        off = np.array([x["ratio_offline"] for x in r])
        fl = np.array([x["ratio_online_float"] for x in r])
        fx = np.array([x["ratio_online_fixed"] for x in r])
        lines.append(f"{est:<5}{len(r):>14}{np.median(off):>10.4f}{np.median(fl):>15.4f}{np.median(fx):>15.4f}"
                     f"{np.max(np.abs(fl - off)):>11.4f}{np.max(np.abs(fx - fl)):>13.5f}")
    lines.append(f"saturation/wrap: {res.saturation or 'none'}; PIC cycles per sample {res.cycles_per_sample:,.0f} "
                 f"(gaitlog budget: against the {cycles_per_sample_available(rec.sampling_rate_hz):,.0f} of a "
                 f"{rec.sampling_rate_hz:g} Hz period)")
    return lines


def _plot(ctx: dict[str, Any]) -> list[str]:
    rec = decode_file(ctx["walk_k_image"])
    written = save_decoded(rec, ctx["dir"] / "walk_k")
    sub = ctx["subject"]
    start_s = 60.0
    overview = recording_overview(rec, leg_length_m=sub.leg_length_m, foot_length_m=sub.foot_length_m,
                                  k_fit=ctx["walk_result"].calibrations["multi-speed"], start_s=start_s,
                                  duration_s=30.0)
    png = ctx["dir"] / "walk_k.png"
    atomic_write_bytes(png, render_overview_png(overview))
    ctx.update(walk_k_npz=written[0], overview_png=png, overview_start_s=start_s)
    return [f"the device's walk decoded -> {', '.join(str(p) for p in written)}",
            f"acceleration, gaps, lap marks, events and step lengths of {start_s:g}-{start_s + 30:g} s -> {png}"]


def _next(ctx: dict[str, Any]) -> list[str]:
    d = ctx["dir"]
    sub = ctx["subject"]
    npz, k = ctx["walk_k_npz"], ctx["k_path"]
    start = ctx["overview_start_s"]
    lines = [f"everything is in {d}/; open first:",
             f"  {ctx['overview_png']}   the walk as the device recorded it: acceleration, events, step lengths",
             f"  {d / 'walk_boxplots.png'}   estimated / real distance per estimator (Alvarez et al. Figs 5-6)",
             f"  {d / 'walk_sections.csv'}, {d / 'walk_split.csv'}   the per-section tables behind them",
             "then try:"]
    commands = [f"gaitlog info {ctx['walk_k_image']}",
                f"gaitlog estimate {npz} --k-file {k} --out {d / 'steps.csv'} --arithmetic both",
                f"gaitlog plot {npz} --k-file {k} --start {start + 30:g} --duration 20 --out {d / 'next.png'}",
                *([f"gaitlog calibrate {d / 'decoded.npz'} --out {d / 'calibration_again.json'}"]
                  if ctx.get("calibration") is not None else []),
                (f"gaitlog compare {npz} --leg-length {sub.leg_length_m:.3f} --foot-length {sub.foot_length_m:.3f} "
                 f"--k-file {k} --out {d / 'compare.csv'}")]
    ctx["next_commands"] = commands
    return lines + [f"  {c}" for c in commands]


#: The demo, in order (``gaitlog demo`` runs them). Later issues append stages here.
STAGES: list[Stage] = [
    Stage("record", _record),
    Stage("serve", _serve),
    Stage("dump", _dump),
    Stage("decode", _decode),
    Stage("calibrate", _calibrate),
    Stage("summary", _summary),
    Stage("walk", _walk),
    Stage("estimate", _estimate),
    Stage("device", _device),
    Stage("split", _split),
    Stage("plot", _plot),
    Stage("next", _next),
]
