"""End to end with the device's per-step records: record (on-line step algorithm on) -> image -> served on a pty
or over emu:// -> `gaitlog dump` (samples, then the step memory; retries, --resume) -> `gaitlog decode` (records
bit for bit, PREFIX.steps.csv, replay check) -> `gaitlog info`; `gaitlog record`'s step options and bad input.

Truth is the device: the emulated logger's step memory and header (what its firmware stored), record fields
read back with ``struct`` (PROTOCOL.md 2.3's layout), never the host's own output.
"""

from __future__ import annotations

import binascii
import csv
import io
import json
import os
import signal
import struct
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.pty_server import serve_pty
from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.files.recording import STEP_CSV_COLUMNS, Recording
from gaitlog.host.files.replay import verify_step_records
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.host.link.memory_dump import dump_memory
from gaitlog.protocol.frames import FrameType, parse_stream
from gaitlog.protocol.image import parse_image
from gaitlog.protocol.steps import STEP_ADDRESS_BASE, StepConfig


def read_image(path: Path):
    """A ``.glimg`` file parsed (the protocol works on bytes; reading the file is the caller's)."""
    return parse_image(Path(path).read_bytes(), source=str(path))


ROOT = Path(__file__).resolve().parents[1]
START_S = 1_700_000_000
CONFIG = StepConfig(step_format=4, leg_length_m=0.9275, foot_length_m=0.1943, m4_exponent=0.25)


def walking(corridor_m: float = 20.0, seed: int = 1, height_m: float = 1.75):
    from gaitlog.firmware_sim.world.subject import Subject
    from gaitlog.firmware_sim.world.walk_plan import WalkPlan
    from gaitlog.firmware_sim.world.walking import Walking

    walk_plan = WalkPlan(corridor_length_m=corridor_m, speeds=("preferred",), initial_stand_s=3.0,
                               final_stand_s=2.0, lap_marks_m=(0.0, corridor_m, 2 * corridor_m))
    return Walking(subject=Subject.from_height(height_m), walk_plan=walk_plan, seed=seed)


def device_records(logger: Logger) -> bytes:
    """The stored records in ring order, from the device's step memory and counters (PROTOCOL.md 2.3)."""
    h = logger.header
    n = min(h.steps_written, h.step_capacity)
    first = h.step_write_index if h.steps_written >= h.step_capacity else 0
    mem = bytes(logger.step_memory)
    return b"".join(mem[20 * ((first + i) % h.step_capacity): 20 * ((first + i) % h.step_capacity) + 20]
                    for i in range(n))


def fields(record: bytes) -> tuple:
    """end, duration, toe-off, heel strike, flags, five lengths (raw) of one record; its CRC checked."""
    assert binascii.crc_hqx(record[:18], 0) == int.from_bytes(record[18:], "big")
    return struct.unpack("<IBBbB5H", record[:18])


@pytest.fixture(scope="module")
def walk_image(tmp_path_factory):
    """A walk recorded with the step algorithm on: (image path, logger, records in ring order)."""
    logger = Logger(device_id=9, step_config=CONFIG)
    logger.record(walking(), start_time_s=START_S)
    path = tmp_path_factory.mktemp("walk") / "walk.glimg"
    logger.save_image(path)
    records = device_records(logger)
    assert len(records) // 20 > 40
    return path, logger, records


def _files(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()}


# ------------------------------------------------------------------------------------------ round trips
def test_pty_dump_and_decode_reproduce_the_device_records(walk_image, tmp_path, capsys):
    image, logger, records = walk_image
    with serve_pty(Logger.from_image(image)) as server:
        assert main(["dump", "--port", server.path, "--out", str(tmp_path / "d.glimg")]) == 0
    out = capsys.readouterr().out
    n = len(records) // 20
    assert f"{n} of {n} step records" in out
    assert read_image(tmp_path / "d.glimg").image_version == 3
    meta = json.loads((tmp_path / "d.glimg.json").read_text())
    assert meta["step_stored_bytes"] == len(records) and meta["complete"] and meta["n_step_records"] == n
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "dec")]) == 0
    out = capsys.readouterr().out
    assert f"device step records vs host replay: {n} of {n} identical byte for byte" in out
    assert "dec.steps.csv" in out
    rec = Recording.load(tmp_path / "dec.npz")
    assert rec.step_records.tobytes() == records
    np.testing.assert_array_equal(rec.step_record_numbers, np.arange(n))
    # the CSV, against the device's record fields
    with open(tmp_path / "dec.steps.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == STEP_CSV_COLUMNS and len(rows) == n
    for i, row in enumerate(rows):
        end, dur, toe, heel, flags, *lengths = fields(records[20 * i: 20 * i + 20])
        assert int(row["end_sample"]) == end and float(row["time_s"]) == pytest.approx(end / 50.0, abs=1e-12)
        assert row["duration_s"] == ("" if dur == 0 else repr(dur / 50.0))
        raw = {4: "raw_m4_range_pow_p", 5: "raw_m5_cadence_hz"} if flags & 0x40 else {}   # not lengths
        for k, q in enumerate(lengths, start=1):
            assert row[raw.get(k, f"length_m{k}_m")] == ("" if q == 0 else repr(q / 16384))
            assert k not in raw or row[f"length_m{k}_m"] == ""
        assert row["lengths"] == ("raw" if flags & 0x40 else "K")
    # the foot-flat's time is on the sample CSV's clock: the sample row with that number has the same time
    samples = Recording.read_csv(tmp_path / "dec.csv")
    k = int(rows[5]["end_sample"])
    assert samples["time_s"][samples["sample_number"] == k][0] == pytest.approx(float(rows[5]["time_s"]), abs=1e-4)


def test_served_cli_logs_steps_when_a_host_starts_a_run(walk_image, tmp_path, capsys):
    """`gaitlog serve` runs what the image's header says: a run started over the port runs the step algorithm
    (the device lies still: no foot-flat) and `gaitlog dump` fetches every stored record."""
    image, logger, records = walk_image
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "gaitlog", "serve", str(image), "--pty"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        port = proc.stdout.readline().strip()
        with LoggerLink(port, timeout_s=2.0) as link:
            _, before = link.read_header()
            assert before.step_config == CONFIG.quantised()
            link.start(START_S + 600, overwrite=True)
            time.sleep(1.0)
            link.stop()
        assert main(["dump", "--port", port, "--out", str(tmp_path / "d.glimg"), "--quiet"]) == 0
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
    rec = decode_file(tmp_path / "d.glimg")
    assert rec.header.samples_written > logger.header.samples_written + 25  # the second run's samples
    assert rec.step_records.tobytes()[: len(records)] == records
    check = verify_step_records(rec)
    assert len(check.runs) == 2 and all(r.complete for r in check.runs) and check.identical


class WalkingLogger(Logger):
    """A served logger whose timer ISR takes a prerecorded walk, fast-forwarded 500 samples per tick."""

    walk_codes = np.zeros((0, 3), np.int64)

    def advance(self, now_s: float) -> int:
        if not self.ring.logging:
            self._taken = 0
            return 0
        chunk = self.walk_codes[getattr(self, "_taken", 0): getattr(self, "_taken", 0) + 500]
        self._taken = getattr(self, "_taken", 0) + len(chunk)
        return self.firmware.log_samples(chunk) if len(chunk) else 0


def test_records_logged_over_the_port_reach_the_host(tmp_path):
    codes = np.asarray(Logger(device_id=2).record(walking(seed=4), start_time_s=START_S).codes)
    device = WalkingLogger(device_id=2, step_config=CONFIG)
    device.walk_codes = codes
    with serve_pty(device) as server:
        with LoggerLink(server.path, timeout_s=1.0) as link:
            link.set_step_config(CONFIG)
            link.start(START_S)
            while link.status()["samples_written"] < len(codes):
                time.sleep(0.05)
            link.stop()
        assert main(["dump", "--port", server.path, "--out", str(tmp_path / "w.glimg"), "--quiet"]) == 0
        stored = device_records(device)
    assert len(stored) // 20 > 40
    rec = decode_file(tmp_path / "w.glimg")
    assert rec.step_records.tobytes() == stored
    np.testing.assert_array_equal(rec.codes, codes)
    assert verify_step_records(rec).identical


def test_wrapped_sample_memory_with_records_dumps_both(tmp_path, capsys):
    """The step ring outlasts the sample ring: a walk, then more than a full memory of other motion. The dump
    reads the whole sample memory and the step memory after it (two ranges on the wire, one per memory); the
    walk's records end at samples already overwritten, so the replay cannot verify them, which is no error."""
    from gaitlog.firmware_sim.world.base import Motion

    logger = Logger(device_id=8, step_config=CONFIG, overwrite=True)
    logger.record(walking(), start_time_s=START_S)
    n = 65536 + 700
    t = np.arange(n) / 50.0
    acc = np.c_[0.1 * np.sin(0.05 * t), 0.1 * np.cos(0.031 * t), 1.0 + 0.02 * np.sin(0.7 * t)]
    logger.record(Motion(acc_g=acc, sampling_rate_hz=50.0), start_time_s=START_S + 3600)
    assert logger.header.wrapped and logger.header.steps_written > 40
    records = device_records(logger)
    logger.save_image(tmp_path / "wrapped.glimg")
    assert main(["dump", "--port", f"emu://{tmp_path / 'wrapped.glimg'}", "--out", str(tmp_path / "d.glimg"),
                 "--quiet"]) == 0
    meta = json.loads((tmp_path / "d.glimg.json").read_text())
    assert meta["stored_bytes"] == 4 * 65536 and meta["step_stored_bytes"] == len(records) and meta["complete"]
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "dec")]) == 0
    assert "device step records: none verifiable" in capsys.readouterr().out
    rec = Recording.load(tmp_path / "dec.npz")
    assert rec.step_records.tobytes() == records and rec.valid.all()
    assert rec.step_records["end_sample"][0] < rec.sample_numbers[0]  # ends at an overwritten sample


def test_xdump_raw_dump_received_by_rx_carries_the_records(walk_image, tmp_path, lrzsz_rx):
    from test_end_to_end_dump import xdump_with_rx

    image, logger, records = walk_image
    with serve_pty(Logger.from_image(image)) as server:
        rx_file = xdump_with_rx(server.path, tmp_path / "rx.bin", lrzsz_rx)
    raw = rx_file.read_bytes()
    used = 4 * logger.header.samples_written
    assert raw[256 + used: 256 + used + len(records)] == records  # header, samples, records, 0x1A padding
    assert main(["decode", str(rx_file), "--out", str(tmp_path / "r"), "--quiet"]) == 0
    assert Recording.load(tmp_path / "r.npz").step_records.tobytes() == records


def test_noisy_line_capture_decodes_to_the_same_records(walk_image, tmp_path):
    image, _, records = walk_image
    assert main(["dump", "--port", f"emu://{image}?corrupt=0.002&seed=3", "--out", str(tmp_path / "n.glimg"),
                 "--capture", str(tmp_path / "wire.bin"), "--timeout", "0.2", "--quiet"]) == 0
    meta = json.loads((tmp_path / "n.glimg.json").read_text())
    assert meta["frames_damaged"] > 0 and meta["complete"]
    # a completed dump's capture holds a good copy of every block (with this seed a retried stream lies between two
    # damaged header copies): both decode to every sample, exactly the device's, and to its step records
    truth = decode_file(image).codes
    for source in ("n.glimg", "wire.bin"):
        assert main(["decode", str(tmp_path / source), "--out", str(tmp_path / source[0]), "--quiet",
                     "--max-missing", "0"]) == 0
        rec = Recording.load(tmp_path / f"{source[0]}.npz")
        assert rec.valid.all() and np.array_equal(rec.codes, truth), source
        assert rec.step_records.tobytes() == records



@pytest.mark.slow  # ~30 s: ten noisy dumps of the walk through the emulator
def test_noisy_line_captures_of_completed_dumps_lose_nothing(walk_image, tmp_path):
    """Whenever a dump over a noisy line completes, its wire capture holds a good copy of every block: decoded, it
    gives every sample, equal to the device's (seeds 3, 6, 7 and 8 lost 12-258 samples before a retried stream
    between two damaged header copies was used)."""
    image, _, records = walk_image
    truth = decode_file(image).codes
    completed = 0
    for seed in range(1, 11):
        out, wire = tmp_path / f"n{seed}.glimg", tmp_path / f"wire{seed}.bin"
        assert main(["dump", "--port", f"emu://{image}?corrupt=0.002&seed={seed}", "--out", str(out),
                     "--capture", str(wire), "--timeout", "0.2", "--quiet"]) == 0, seed
        meta = json.loads(out.with_name(out.name + ".json").read_text())
        assert meta["frames_damaged"] > 0, seed
        if not meta["complete"]:
            continue
        completed += 1
        assert main(["decode", str(wire), "--out", str(tmp_path / f"w{seed}"), "--quiet", "--max-missing", "0"]) == 0
        rec = Recording.load(tmp_path / f"w{seed}.npz")
        assert rec.valid.all() and np.array_equal(rec.codes, truth), seed
        assert rec.step_records.tobytes() == records, seed
    assert completed >= 8

def _fill_in_blocks(block: int, path: Path) -> Logger:
    """A stop-when-full run of a synthetic 1.75 Hz gait fed to the firmware in blocks until the 65,536-sample
    memory is full (its last foot-flat is then still pending)."""
    t = np.arange(66_000) / 50.0
    a_v = 0.25 * np.sin(2 * np.pi * 1.75 * t) + 0.08 * np.sin(2 * np.pi * 3.5 * t + 1.0)
    codes = np.round(np.column_stack([512 + 10 * np.sin(2 * np.pi * 0.9 * t), np.full(t.size, 512.0),
                                      512 + 256 * (1 + a_v)])).astype(np.int64)
    logger = Logger(device_id=9, step_config=CONFIG, overwrite=False)
    logger.firmware.start_logging(start_time_s=START_S, overwrite=False)
    for i in range(0, t.size, block):
        logger.firmware.log_samples(codes[i:i + block])
    assert logger.header.full_stopped and logger.header.samples_written == 65_536
    logger.save_image(path)
    return logger


def test_memory_filled_by_a_whole_block_still_stores_the_last_step(tmp_path):
    """Stop-when-full ends the run whether the last block fills the memory exactly or is cut: the pending
    foot-flat is stored either way, and the records are the host's replay of the stored samples."""
    exact = _fill_in_blocks(512, tmp_path / "exact.glimg")      # 65,536 = 128 x 512: no block is cut
    cut = _fill_in_blocks(500, tmp_path / "cut.glimg")          # the 132nd block is cut at 36 samples
    assert device_records(exact) == device_records(cut) and len(device_records(exact)) // 20 > 2000
    last_end = struct.unpack_from("<I", device_records(exact), len(device_records(exact)) - 20)[0]
    assert last_end > 65_536 - 50   # the pending foot-flat, finalised by the end of the run (< 1 s before)
    for name in ("exact", "cut"):
        check = verify_step_records(decode_file(tmp_path / f"{name}.glimg"))
        assert check.identical and check.n_compared == len(device_records(exact)) // 20, (name, check.summary())


# ------------------------------------------------------------------------------------------ resume
def test_cli_resume_of_a_dump_cut_in_the_step_memory(walk_image, tmp_path, capsys):
    image, _, records = walk_image
    assert main(["dump", "--port", f"emu://{image}", "--out", str(tmp_path / "full.glimg"), "--quiet"]) == 0
    total = json.loads((tmp_path / "full.glimg.json").read_text())["bytes_received"]
    # the step DUMP comes last: one DATA frame of the records, then DUMP_END (18 bytes); cut inside the frame
    cut = total - 18 - len(records) // 2
    out = tmp_path / "d.glimg"
    rc = main(["dump", "--port", f"emu://{image}?cut_after={cut}", "--out", str(out), "--timeout", "0.1",
               "--retries", "1", "--quiet"])
    assert rc == 1 and "--resume" in capsys.readouterr().err
    assert not out.exists()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = read_image(tmp_path / "d.glimg.part")
    header = part.header
    assert part.byte_ok()[: header.used_bytes].all() and not part.step_byte_ok()[: len(records)].any()
    assert main(["dump", "--port", f"emu://{image}", "--out", str(out), "--resume", "--quiet"]) == 0
    meta = json.loads((tmp_path / "d.glimg.json").read_text())
    assert meta["resumed"] and meta["complete"] and meta["bytes_from_partial_state"] >= header.used_bytes
    assert not (tmp_path / "d.glimg.part").exists()
    assert decode_file(out).step_records.tobytes() == records


def test_resume_keeps_the_step_bytes_already_received(walk_image, tmp_path):
    """The partial state keeps whole 1024-byte image blocks: cut the step DUMP (DATA_BLOCKS frames of 256 bytes) inside
    its last frame, after the first 1024 step bytes arrived; the resumed dump reads only the rest."""
    image, _, records = walk_image
    assert 1024 < len(records) <= 1280
    capture = io.BytesIO()
    with LoggerLink(f"emu://{image}", timeout_s=0.5, capture=capture) as link:
        dump_memory(link, tmp_path / "full.glimg", progress=False, chunk_bytes=256)
    out = tmp_path / "d.glimg"
    frames, _ = parse_stream(capture.getvalue())
    last = [f for f in frames if f.type == FrameType.DATA_BLOCKS][-1]  # the step memory's last frame
    assert int.from_bytes(last.payload[:4], "little") == STEP_ADDRESS_BASE + 1024
    with LoggerLink(f"emu://{image}?cut_after={last.offset + len(last.payload) // 2}", timeout_s=0.1,
                    retries=0) as link:
        with pytest.raises(HostError, match="no answer to IDENTIFY"):
            dump_memory(link, out, progress=False, chunk_bytes=256, retries=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = read_image(tmp_path / "d.glimg.part")
    have = part.step_byte_ok()[: len(records)]
    assert have[:1024].all() and not have[1024:].any()
    with LoggerLink(f"emu://{image}", timeout_s=0.5) as link:
        done = dump_memory(link, out, progress=False, resume=True, chunk_bytes=256)
    meta = done.metadata_
    assert done.complete_ and meta["bytes_from_partial_state"] >= done.header_.used_bytes + 1024
    assert meta["data_frames_used"] == 1  # the 156 step bytes still missing, nothing else
    assert decode_file(out).step_records.tobytes() == records


# ------------------------------------------------------------------------------------------ record
def test_record_steps_off_stores_no_records_and_dumps_fine(tmp_path, capsys):
    assert main(["record", "--motion", "walk", "--steps", "off", "--start-time", str(START_S), "--out",
                 str(tmp_path / "off.glimg")]) == 0
    captured = capsys.readouterr()
    assert "on-line step algorithm off: no step records stored" in captured.out and captured.err == ""
    h = read_image(tmp_path / "off.glimg").header
    assert not h.step_config.enabled and h.steps_written == 0 and h.samples_written > 1500
    assert main(["dump", "--port", f"emu://{tmp_path / 'off.glimg'}", "--out", str(tmp_path / "d.glimg"),
                 "--quiet"]) == 0
    assert main(["decode", str(tmp_path / "d.glimg"), "--out", str(tmp_path / "dec")]) == 0
    out = capsys.readouterr().out
    assert "no step records in" in out and "dec.steps.csv not written" in out
    assert _files(tmp_path) == {"off.glimg", "d.glimg", "d.glimg.json", "dec.npz", "dec.csv"}
    assert main(["info", str(tmp_path / "d.glimg")]) == 0
    out = capsys.readouterr().out
    assert "step algorithm   off (plain logging)" in out and "step records     0 of 0" in out


def test_a_device_without_step_memory_dumps_fine(tmp_path):
    """An older logger (step_capacity 0): the dump reads the samples only and writes an image of version 1."""
    from gaitlog.firmware_sim.eeprom import Eeprom24LC1025
    from gaitlog.firmware_sim.firmware import Firmware
    from gaitlog.firmware_sim.step_store import StepStore
    from gaitlog.firmware_sim.world.poses import CalibrationPoses

    logger = Logger(device_id=6)
    logger.header.step_capacity = 0
    logger.steps = StepStore(Eeprom24LC1025(), logger.header)
    logger.firmware = Firmware(logger.ring, steps=logger.steps)
    res = logger.record(CalibrationPoses(n_poses=4, hold_s=3.0, move_s=1.0), start_time_s=START_S)
    with serve_pty(logger) as server:
        assert main(["dump", "--port", server.path, "--out", str(tmp_path / "old.glimg"), "--quiet"]) == 0
    assert read_image(tmp_path / "old.glimg").image_version == 3  # every device: framed blocks
    rec = decode_file(tmp_path / "old.glimg")
    np.testing.assert_array_equal(rec.codes, res.codes)
    assert rec.n_step_records == 0 and rec.step_losses == [] and verify_step_records(rec) is None


def test_record_default_is_on_and_warns_about_the_assumed_adult(tmp_path, capsys):
    assert main(["record", "--motion", "walk", "--start-time", str(START_S), "--out", str(tmp_path / "a.glimg")]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "a 1.70 m adult (leg 0.901 m, foot 0.189 m)" in captured.err
    h = read_image(tmp_path / "a.glimg").header
    q = h.step_config
    assert q.enabled and not q.calibrated
    assert abs(q.leg_length_m - 0.901) < 1e-4 and abs(q.foot_length_m - 0.1887) < 1e-4
    assert f"{h.steps_written} step records stored by the on-line algorithm" in captured.out and h.steps_written > 40
    # given a height, no warning; the lengths follow it
    assert main(["record", "--motion", "walk", "--height", "1.8", "--start-time", str(START_S), "--quiet", "--out",
                 str(tmp_path / "b.glimg")]) == 0
    assert capsys.readouterr().err == ""
    assert abs(read_image(tmp_path / "b.glimg").header.step_config.leg_length_m - 0.954) < 1e-4


def test_record_with_a_k_file_stores_calibrated_lengths(tmp_path, capsys):
    common = ["--motion", "walk", "--height", "1.75", "--corridor-length", "20", "--start-time", str(START_S)]
    assert main(["record", *common, "--out", str(tmp_path / "raw.glimg"), "--quiet"]) == 0
    assert main(["decode", str(tmp_path / "raw.glimg"), "--out", str(tmp_path / "raw"), "--quiet"]) == 0
    assert main(["calibrate-k", str(tmp_path / "raw.npz"), "--distance", "40", "--height", "1.75", "--out",
                 str(tmp_path / "k.json")]) == 0
    capsys.readouterr()
    k = json.loads((tmp_path / "k.json").read_text())
    # the same walker (--height also gives the lengths K was fitted with: accepted)
    assert main(["record", *common, "--k-file", str(tmp_path / "k.json"), "--out", str(tmp_path / "cal.glimg")]) == 0
    captured = capsys.readouterr()
    assert "calibrated K" in captured.out and captured.err == ""
    cfg = read_image(tmp_path / "cal.glimg").header.step_config
    assert cfg.calibrated and abs(cfg.k_m1 - k["k_m1"]) < 2 ** -15 and abs(cfg.k2_m5_m - k["k2_m5_m"]) < 2 ** -16
    assert main(["decode", str(tmp_path / "cal.glimg"), "--out", str(tmp_path / "cal")]) == 0
    assert "identical byte for byte" in capsys.readouterr().out
    raw, cal = Recording.load(tmp_path / "raw.npz"), Recording.load(tmp_path / "cal.npz")
    # the same walk, the same codes: the same foot-flats; the device applied K in its arithmetic
    np.testing.assert_array_equal(raw.step_records["end_sample"], cal.step_records["end_sample"])
    assert not (cal.step_records["flags"] & 0x40).any() and (raw.step_records["flags"] & 0x40).all()
    m1_raw = raw.step_records["length_m1_q14"] / 16384
    m1_cal = cal.step_records["length_m1_q14"] / 16384
    ok = m1_raw > 0
    np.testing.assert_allclose(m1_cal[ok], cfg.k_m1 * m1_raw[ok], atol=3 / 16384)
    m5 = cal.step_records["length_m5_q14"][raw.step_records["duration_samples"] > 0] / 16384
    cadence = raw.step_records["length_m5_q14"][raw.step_records["duration_samples"] > 0] / 16384
    np.testing.assert_allclose(m5, cfg.k1_m5_m_s * cadence + cfg.k2_m5_m, atol=2e-3)
    with open(tmp_path / "cal.steps.csv", newline="") as fh:
        assert {r["lengths"] for r in csv.DictReader(fh)} == {"K"}


@pytest.mark.parametrize("args, code, message", [
    (["--k-file", "{d}/missing.json"], 1, "missing.json: cannot read K calibration"),
    (["--k-file", "{d}/acc.json"], 1, "acc.json: not a gaitlog K calibration"),
    (["--k-file", "{d}/big.json"], 1, "k_m1_q15: k_m1 3.5 outside the stored range"),
    (["--k-file", "{d}/k.json", "--height", "1.9"], 1, "K was fitted with a leg length of 0.9275 m"),
    (["--height", "5"], 2, "argument --height: must be a height of 0.8 to 2.5 m (give it in metres), got '5'"),
    (["--leg-length", "0.1"], 2, "argument --leg-length: must be a leg length of 0.3 to 1.3 m"),
    (["--corridor-length", "5"], 2, "argument --corridor-length: must be a finite number >= 10 and <= 1000 m, got '5'"),
    (["--height", "tall"], 2, "argument --height: must be a finite number > 0 and <= 100000 m, got 'tall'"),
    (["--steps", "maybe"], 2, "invalid choice: 'maybe'"),
    (["--steps", "off", "--height", "1.8"], 2, "--steps off runs no step algorithm: --height would be ignored"),
])
def test_record_bad_inputs(tmp_path, capsys, args, code, message):
    from gaitlog.host.gait.k_calibration import KFit

    base = dict(k_m1=1.05, k_m2=1.1, k_m4=0.45, k1_m5_m_s=0.35, k2_m5_m=0.1, mode="single-speed", m5_fallback=False,
                leg_length_m=0.9275, foot_length_m=0.1943, n_sections=1, n_steps=50, distance_m=40.0)
    KFit(**base).save(tmp_path / "k.json")
    KFit(**{**base, "k_m1": 3.5}).save(tmp_path / "big.json")
    (tmp_path / "acc.json").write_text(json.dumps({"cal_type": "gaitlog.AccCalibration", "format_version": "1.0"}))
    before = _files(tmp_path)
    argv = ["record", "--motion", "walk", "--out", str(tmp_path / "x.glimg")] + [a.format(d=tmp_path) for a in args]
    if code == 2:
        with pytest.raises(SystemExit) as info:
            rc = main(argv)
            raise SystemExit(rc)
        rc = info.value.code
    else:
        rc = main(argv)
    err = capsys.readouterr().err
    assert rc == code and message in err, err
    if code == 1:
        assert err.count("\n") == 1 and err.startswith("gaitlog record: error: ")
    assert _files(tmp_path) == before  # no image, no partial output


# ------------------------------------------------------------------------------------------ decode / info
def test_decode_refuses_records_that_differ_from_the_replay(walk_image, tmp_path, capsys, monkeypatch):
    image, logger, records = walk_image
    from gaitlog.protocol.image import build_image

    body = bytearray(records[20 * 12: 20 * 12 + 18])
    body[4] += 1  # duration_samples, with a valid CRC: what a device computing something else would store
    step_memory = bytearray(logger.step_memory)
    step_memory[20 * 12: 20 * 13] = bytes(body) + binascii.crc_hqx(bytes(body), 0).to_bytes(2, "big")
    bad = tmp_path / "bad.glimg"
    bad.write_bytes(build_image(logger.header, logger.memory, step_memory=bytes(step_memory)))
    before = _files(tmp_path)
    assert main(["decode", str(bad), "--out", str(tmp_path / "x")]) == 1
    err = capsys.readouterr().err
    end = fields(records[240:260])[0]
    assert f"the first is record 12 (foot-flat at sample {end}): duration_samples: device" in err
    assert err.count("\n") == 1 and _files(tmp_path) == before
    import gaitlog.host.files.replay as replay

    def no_replay(*_args, **_kwargs):
        raise AssertionError("decode --no-verify replayed the algorithm")

    monkeypatch.setattr(replay, "verify_step_records", no_replay)
    assert main(["decode", str(bad), "--out", str(tmp_path / "x"), "--no-verify"]) == 0
    assert "device step records written unchecked (--no-verify: not replayed)" in capsys.readouterr().out
    assert {"x.npz", "x.csv", "x.steps.csv"} <= _files(tmp_path)


def test_info_shows_the_step_configuration_and_counts(walk_image, capsys):
    image, logger, records = walk_image
    n = len(records) // 20
    assert main(["info", str(image)]) == 0
    out = capsys.readouterr().out
    assert f"step memory      2662 records; {n} written (stored {n}, oldest is record 0 in slot 0)" in out
    assert "step algorithm   on-line version 4, leg 0.9275 m, foot 0.1943 m, raw" in out
    assert f"step records     {n} of {n} stored records decode (0 dropped)" in out
    assert main(["info", "--port", f"emu://{image}"]) == 0
    out = capsys.readouterr().out
    assert f"{n} written" in out and "leg 0.9275 m" in out
