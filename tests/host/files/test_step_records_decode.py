"""gaitlog.host.files.decode + gaitlog.host.files.recording: the device's per-step records from images, raw dumps and wire captures.

Truth is built here by hand: record bytes packed with ``struct`` and ``binascii.crc_hqx`` (PROTOCOL.md 2.3's
layout, not the project's packer), ring slots from the spec's rule, or the emulated device's own step memory.
A record is used only when all its bytes arrived intact and its CRC matches; every other stored record is
reported dropped, never repaired, and a used record is never a wrong one.
"""

from __future__ import annotations

import binascii
import copy
import csv
import dataclasses
import json
import struct
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.host.files.decode import STEP_REASONS, decode_bytes
from gaitlog.host.files.recording import STEP_CSV_COLUMNS, Recording
from gaitlog.host.files.replay import verify_step_records
from gaitlog.protocol.frames import encode_frame
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.header import DeviceHeader as _Header
from gaitlog.protocol.image import build_image as _build_current_image
from gaitlog.protocol.image import image_version_for


def build_image(header, memory, missing_blocks=(), block_size=1024, **kw) -> bytes:
    """The image of version 1 or 2 (the layout these tests damage at known offsets; version 3 is damaged by
    ``tests/protocol/test_corruption_campaign.py``)."""
    h = header if isinstance(header, _Header) else _Header.from_bytes(bytes(header))
    return _build_current_image(header, memory, missing_blocks, block_size, image_version=image_version_for(h), **kw)
from gaitlog.protocol.raw_dump import raw_dump_bytes
from gaitlog.protocol.steps import (
    ONLINE_ALGORITHM_VERSION,
    STEP_ADDRESS_BASE,
    StepConfig,
    StepFormat,
)

CAP = 3276                      # records in the step ring of this device
N_SAMPLES = 400                 # a few samples beside the records (they do not matter here)
T_HEADER, T_DATA = 0x86, 0x87
CONFIG = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)


def record_bytes(end: int, dur: int, toe: int, heel: int, flags: int, lengths) -> bytes:
    """One record from PROTOCOL.md 2.3's table: <IBBbB5H, then CRC-16/XMODEM of bytes 0-17, big-endian."""
    body = struct.pack("<IBBbB5H", end, dur, toe, heel, flags, *lengths)
    return body + binascii.crc_hqx(body, 0).to_bytes(2, "big")


def synthetic(steps_written: int, *, seed: int = 0, capacity: int = CAP, config: StepConfig = CONFIG):
    """Header, sample memory, step memory and the truth: ``{record number: 20 bytes}`` of the stored records."""
    rng = np.random.default_rng(seed)
    step_memory = bytearray(b"\xff" * (20 * capacity))
    truth = {}
    for k in range(steps_written):
        rec = record_bytes(1000 + 27 * k, int(rng.integers(0, 60)), int(rng.integers(0, 30)),
                           int(rng.integers(-128, 3)), int(rng.integers(0, 128)), rng.integers(0, 40000, 5).tolist())
        slot = k % capacity
        step_memory[20 * slot: 20 * slot + 20] = rec
        truth[k] = rec
    n = min(steps_written, capacity)
    truth = {k: truth[k] for k in range(steps_written - n, steps_written)}
    memory = np.full(65536, 0xFFFFFFFF, "<u4")
    memory[:N_SAMPLES] = 512 | (512 << 10) | (768 << 20)
    memory[0] |= 1 << 30
    header = DeviceHeader(device_id=7, samples_written=N_SAMPLES, write_index=N_SAMPLES, start_time_s=1_700_000_000,
                          step_capacity=capacity, steps_written=steps_written,
                          step_write_index=steps_written % capacity if capacity else 0, step_config=config)
    return header, memory.tobytes(), bytes(step_memory), truth


def assert_exact_or_dropped(rec: Recording, truth: dict[int, bytes], dropped: set[int] | None = None) -> None:
    """Every used record is the truth at its number; every stored record is used or in exactly one loss."""
    for number, row in zip(rec.step_record_numbers.tolist(), rec.step_records):
        assert row.tobytes() == truth[number], number
    lost = [k for g in rec.step_losses for k in range(g.first_record_number, g.last_record_number + 1)]
    assert len(lost) == len(set(lost)) == rec.n_steps_dropped
    assert sorted(lost + rec.step_record_numbers.tolist()) == sorted(truth)
    if dropped is not None:
        assert set(lost) == dropped


def image_step_offset(data: bytes, header: DeviceHeader) -> int:
    """File offset of the step memory in an image (PROTOCOL.md 6): table, header, sample memory."""
    n_blocks = int.from_bytes(data[12:16], "little")
    return 16 + 5 * n_blocks + 4 + 256 + 4 * header.capacity_samples


def capture(header: DeviceHeader, memory: bytes, step_memory: bytes, *, chunk: int, skip=(), corrupt=()) -> bytes:
    """READ_HEADER + DUMP of the samples + DUMP of the stored step bytes, DATA frames by the spec's layout.
    Step frames in ``skip`` are left out; in ``corrupt`` one payload byte is changed (the frame CRC fails)."""
    out = [encode_frame(T_HEADER, 1, header.to_bytes())]
    for a in range(0, 4 * N_SAMPLES, 2048):
        out.append(encode_frame(T_DATA, 0, a.to_bytes(4, "little") + memory[a: min(a + 2048, 4 * N_SAMPLES)]))
    for k, a in enumerate(range(0, header.step_used_bytes, chunk)):
        if k in skip:
            continue
        frame = bytearray(encode_frame(T_DATA, k & 0xFF, (STEP_ADDRESS_BASE + a).to_bytes(4, "little")
                                       + step_memory[a: min(a + chunk, header.step_used_bytes)]))
        if k in corrupt:
            frame[12] ^= 0x40
        out.append(bytes(frame))
    return b"".join(out)


# ------------------------------------------------------------------------------------------ clean inputs
@pytest.mark.parametrize("steps_written", [0, 1, 57, CAP, CAP + 24, 3 * CAP + 5])
@pytest.mark.parametrize("kind", ["image", "raw", "capture"])
def test_every_input_gives_the_stored_records_in_ring_order(kind, steps_written):
    header, memory, step_memory, truth = synthetic(steps_written, seed=steps_written)
    if kind == "image":
        data = build_image(header, memory, step_memory=step_memory)
    elif kind == "raw":
        data = raw_dump_bytes(header.to_bytes(), memory[: 4 * N_SAMPLES], step_memory[: header.step_used_bytes])
    else:
        data = capture(header, memory, step_memory, chunk=2040)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rec = decode_bytes(data, source=f"x.{kind}")
    assert rec.n_step_records == len(truth) and rec.step_losses == []
    assert rec.step_records.tobytes() == b"".join(truth[k] for k in sorted(truth))
    np.testing.assert_array_equal(rec.step_record_numbers, sorted(truth))
    assert rec.step_config == CONFIG.quantised() and rec.valid.all()


def test_a_device_without_step_memory_has_no_records():
    header, memory, _, _ = synthetic(0, capacity=0, config=StepConfig.off())
    for data in (build_image(header, memory), raw_dump_bytes(header.to_bytes(), memory[: 4 * N_SAMPLES])):
        rec = decode_bytes(data)
        assert rec.n_step_records == 0 and rec.step_losses == [] and "step record" not in rec.summary()
        assert verify_step_records(rec) is None


# ------------------------------------------------------------------------------------------ damaged inputs
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n_damaged=st.integers(1, 12))
def test_raw_dump_drops_exactly_the_damaged_records(seed, n_damaged):
    header, memory, step_memory, truth = synthetic(CAP + 100, seed=seed)
    # a dump without the check trailer (older firmware), accepted unverified: the records' own CRC-16 must catch
    # the damage
    raw = bytearray(header.to_bytes() + memory[: 4 * N_SAMPLES] + step_memory)
    rng = np.random.default_rng(seed)
    slots = rng.choice(CAP, n_damaged, replace=False)
    for slot in slots:  # one changed byte per record: CRC-16 detects every such error
        raw[256 + 4 * N_SAMPLES + 20 * int(slot) + int(rng.integers(0, 20))] ^= int(rng.integers(1, 256))
    with pytest.warns(UserWarning, match=f"{n_damaged} of the {CAP} stored step records dropped"):
        rec = decode_bytes(bytes(raw), source="rx.bin", accept_unverified=True)
    first = header.first_step_slot
    dropped = {header.first_step_number + (int(s) - first) % CAP for s in slots}
    assert_exact_or_dropped(rec, truth, dropped)
    assert {g.reason for g in rec.step_losses} == {STEP_REASONS[4]}  # record CRC mismatch


def test_truncated_raw_dump_drops_the_records_beyond_its_end():
    header, memory, step_memory, truth = synthetic(300, seed=4)
    raw = raw_dump_bytes(header.to_bytes(), memory[: 4 * N_SAMPLES], step_memory[: header.step_used_bytes])
    cut = 256 + 4 * N_SAMPLES + 20 * 123 + 7  # inside record 123
    with pytest.warns(UserWarning, match="300 of the 300"):  # cut before its trailer: nothing verified
        refused = decode_bytes(raw[:cut], source="rx.bin")
    assert refused.n_step_records == 0 and not refused.valid.any()
    assert "without its check trailer" in refused.step_losses[0].reason
    with pytest.warns(UserWarning, match="177 of the 300"):
        rec = decode_bytes(raw[:cut], source="rx.bin", accept_unverified=True)
    assert_exact_or_dropped(rec, truth, set(range(123, 300)))
    assert [(g.first_record_number, g.last_record_number) for g in rec.step_losses] == [(123, 299)]
    assert "truncated" in rec.step_losses[0].reason


@pytest.mark.parametrize("seed", range(6))
def test_damaged_image_blocks_drop_exactly_their_records(seed):
    header, memory, step_memory, truth = synthetic(CAP + 700, seed=seed)
    data = bytearray(build_image(header, memory, step_memory=step_memory))
    base = image_step_offset(bytes(data), header)
    rng = np.random.default_rng(seed)
    flipped = rng.choice(20 * CAP, 4, replace=False)
    for off in flipped:
        data[base + int(off)] ^= 0x01
    with pytest.warns(UserWarning):
        rec = decode_bytes(bytes(data), source="d.glimg")
    # the image's blocks of 1024 bytes cover the sample memory (262,144 bytes = 256 blocks), then the steps
    bad_blocks = {(4 * 65536 + int(off)) // 1024 for off in flipped}
    bad_slots = {s for s in range(CAP) if {(4 * 65536 + 20 * s) // 1024, (4 * 65536 + 20 * s + 19) // 1024}
                 & bad_blocks}
    dropped = {header.first_step_number + (s - header.first_step_slot) % CAP for s in bad_slots}
    assert_exact_or_dropped(rec, truth, dropped)
    assert all("damaged" in g.reason for g in rec.step_losses)


def test_image_with_a_cut_page_write_drops_that_record_by_its_crc():
    """Blocks intact (the image checks what the EEPROM held) but one record half written: CRC mismatch."""
    header, memory, step_memory, truth = synthetic(40, seed=2)
    torn = bytearray(step_memory)
    torn[20 * 17 + 8: 20 * 17 + 20] = b"\xff" * 12  # the page write of its second half never happened
    with pytest.warns(UserWarning, match="1 of the 40 stored step records dropped"):
        rec = decode_bytes(build_image(header, memory, step_memory=bytes(torn)), source="t.glimg")
    assert_exact_or_dropped(rec, truth, {17})
    assert rec.step_losses[0].reason == STEP_REASONS[4]
    assert any("1 of the 40 stored step records dropped" in n for n in rec.notes)


def test_missing_blocks_and_a_version_1_file():
    header, memory, step_memory, truth = synthetic(200, seed=3)
    first_step_block = 4 * 65536 // 1024
    with pytest.warns(UserWarning):
        rec = decode_bytes(build_image(header, memory, [first_step_block + 1], step_memory=step_memory))
    # block 257 holds step bytes 1024-2047: records 51 (bytes 1020-1039) to 102 (bytes 2040-2059)
    assert_exact_or_dropped(rec, truth, set(range(51, 103)))
    assert "never received" in rec.step_losses[0].reason
    # an image of version 1 (written by a host older than the step memory) holds none of them
    from gaitlog.protocol.image import IMAGE_PREFIX_STRUCT

    v1 = bytearray(build_image(header.replace(step_capacity=0, steps_written=0, step_write_index=0), memory))
    table_end = 16 + 5 * 256
    hdr = header.to_bytes()
    v1[table_end + 4: table_end + 260] = hdr  # the header says step memory; the file has none
    assert IMAGE_PREFIX_STRUCT.parse(bytes(v1[:16])).image_version == 1
    with pytest.warns(UserWarning, match="not in the file"):
        old = decode_bytes(bytes(v1))
    assert old.n_step_records == 0 and old.n_steps_dropped == 200
    assert old.step_losses[0].reason == STEP_REASONS[5]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), chunk=st.integers(20, 4096), skip=st.sets(st.integers(0, 60), max_size=4),
       corrupt=st.sets(st.integers(0, 60), max_size=4))
def test_capture_drops_exactly_the_records_no_intact_frame_covered(seed, chunk, skip, corrupt):
    header, memory, step_memory, truth = synthetic(CAP + 10, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = decode_bytes(capture(header, memory, step_memory, chunk=chunk, skip=skip, corrupt=corrupt))
    covered = np.zeros(20 * CAP, bool)
    for k, a in enumerate(range(0, header.step_used_bytes, chunk)):
        if k not in skip and k not in corrupt:
            covered[a: a + chunk] = True
    bad_slots = np.flatnonzero(~covered.reshape(CAP, 20).all(axis=1))
    dropped = {header.first_step_number + (int(s) - header.first_step_slot) % CAP for s in bad_slots}
    assert_exact_or_dropped(rec, truth, dropped)
    assert all("not received" in g.reason for g in rec.step_losses)


def test_a_record_not_received_is_dropped_even_when_its_crc_happens_to_match():
    """All-zero bytes carry a matching CRC-16/XMODEM (0x0000): a decoder that trusted the CRC alone would invent
    an all-zero record wherever a buffer of zeros was never filled. Every input path hands the step bytes with
    their received mask to one assembler; drive it with such a buffer."""
    from gaitlog.host.files.decode import _assemble_steps

    header, _, step_memory, truth = synthetic(6, seed=1)
    buffer = bytearray(step_memory)
    buffer[40:60] = bytes(20)                      # record 2: never received, zeros in the buffer
    assert binascii.crc_hqx(bytes(18), 0) == 0     # ... which pass the CRC check
    received = np.ones(20 * CAP, bool)
    received[40:60] = False
    notes: list[str] = []
    with pytest.warns(UserWarning, match="1 of the 6"):
        records, numbers, losses = _assemble_steps(header, np.frombuffer(bytes(buffer), np.uint8), received,
                                                   np.full(20 * CAP, 3, np.int8), "t", notes)
    assert numbers.tolist() == [0, 1, 3, 4, 5] and records.tobytes() == b"".join(truth[k] for k in (0, 1, 3, 4, 5))
    assert [(g.first_record_number, g.reason) for g in losses] == [(2, STEP_REASONS[3])]


# ------------------------------------------------------------------------------------------ Recording files
def test_npz_round_trip_keeps_records_and_losses(tmp_path):
    header, memory, step_memory, truth = synthetic(CAP + 30, seed=8)
    step_memory = bytearray(step_memory)
    step_memory[20 * 5 + 3] ^= 0x10
    with pytest.warns(UserWarning):
        rec = decode_bytes(build_image(header, memory, step_memory=bytes(step_memory)), source="s.glimg")
    rec.save_npz(tmp_path / "s.npz")
    back = Recording.load(tmp_path / "s.npz")
    assert back.step_records.tobytes() == rec.step_records.tobytes()
    np.testing.assert_array_equal(back.step_record_numbers, rec.step_record_numbers)
    assert back.step_losses == rec.step_losses and back.n_steps_dropped == 1
    assert back.step_config == rec.step_config
    meta = json.loads(str(np.load(tmp_path / "s.npz")["metadata_json"]))
    assert meta["step_records"]["n_decoded"] == CAP - 1 and meta["header"]["steps_written"] == CAP + 30


def test_npz_saved_before_the_step_records_still_loads(tmp_path):
    header, memory, step_memory, truth = synthetic(25, seed=9)
    rec = decode_bytes(build_image(header, memory, step_memory=step_memory))
    rec.save_npz(tmp_path / "new.npz")
    arrays = dict(np.load(tmp_path / "new.npz"))
    meta = json.loads(str(arrays.pop("metadata_json")))
    for name in ("step_record_bytes", "step_record_numbers"):
        arrays.pop(name)
    meta.pop("step_records")  # exactly the arrays and metadata an older gaitlog wrote
    np.savez_compressed(tmp_path / "old.npz", metadata_json=np.array(json.dumps(meta)), **arrays)
    old = Recording.load(tmp_path / "old.npz")
    np.testing.assert_array_equal(old.codes, rec.codes)
    assert old.n_step_records == 0 and old.n_steps_dropped == 25
    assert "not in this NPZ" in old.step_losses[0].reason
    # and a recording without header or steps, as the old layout
    plain = Recording.from_arrays(np.full((3, 3), 512))
    plain.save_npz(tmp_path / "plain.npz")
    assert Recording.load(tmp_path / "plain.npz").step_losses == []


def test_steps_csv_columns_and_values(tmp_path):
    rows = [record_bytes(1000, 0, 0, -3, 0x01 | 0x40, [0] * 5),                        # bout start, raw
            record_bytes(1027, 27, 5, -2, 0x40, [11264, 11520, 11776, 11392, 32768]),  # raw: M5 = 2 Hz
            record_bytes(1060, 33, 0, -128, 0x02 | 0x04 | 0x08, [9000, 0, 0, 8000, 7000])]  # K, M2/M3 not computed
    step_memory = b"".join(rows) + b"\xff" * (20 * (CAP - 3))
    header, memory, _, _ = synthetic(0)
    header = header.replace(steps_written=3, step_write_index=3)
    rec = decode_bytes(build_image(header, memory, step_memory=step_memory))
    rec.to_steps_csv(tmp_path / "s.steps.csv")
    with open(tmp_path / "s.steps.csv", newline="") as fh:
        got = list(csv.DictReader(fh))
    assert tuple(got[0]) == STEP_CSV_COLUMNS
    assert [r["record_number"] for r in got] == ["0", "1", "2"]
    assert [r["end_sample"] for r in got] == ["1000", "1027", "1060"]
    assert [float(r["time_s"]) for r in got] == [20.0, 20.54, 21.2]  # end_sample / 50 Hz, the sample CSV's clock
    assert [r["duration_s"] for r in got][0] == "" and float(got[1]["duration_s"]) == 0.54
    assert float(got[2]["duration_s"]) == 0.66
    # toe-off: window start (previous foot-flat) + 5 samples; heel strike: foot-flat - 2 samples
    assert got[0]["toe_off_s"] == "" and float(got[1]["toe_off_s"]) == 1005 / 50 and got[2]["toe_off_s"] == ""
    assert float(got[0]["heel_strike_s"]) == 997 / 50 and float(got[1]["heel_strike_s"]) == 1025 / 50
    assert got[2]["heel_strike_s"] == ""
    assert [r["flags"] for r in got] == ["NO_WINDOW|UNCALIBRATED", "UNCALIBRATED",
                                         "NO_TOE_OFF|NO_HEEL_STRIKE|M3_UNDEFINED"]
    assert [got[0][f"length_m{k}_m"] for k in range(1, 6)] == [""] * 5  # 0: not computed
    # a raw record: M1-M3 are lengths (K = 1); M4 (range^p) and M5 (the cadence, Hz) are not: their own columns
    assert [float(got[1][f"length_m{k}_m"]) for k in range(1, 4)] == [0.6875, 0.703125, 0.71875]
    assert [got[1][f"length_m{k}_m"] for k in (4, 5)] == ["", ""]
    assert (float(got[1]["raw_m4_range_pow_p"]), float(got[1]["raw_m5_cadence_hz"])) == (0.6953125, 2.0)
    assert [got[2][c] for c in ("raw_m4_range_pow_p", "raw_m5_cadence_hz")] == ["", ""]    # calibrated: none
    assert (float(got[2]["length_m4_m"]), float(got[2]["length_m5_m"])) == (8000 / 16384, 7000 / 16384)
    assert [got[2][f"length_m{k}_m"] for k in (2, 3)] == ["", ""]
    assert float(got[2]["length_m1_m"]) == 9000 / 16384
    assert [r["lengths"] for r in got] == ["raw", "raw", "K"]


# ------------------------------------------------------------------------------------------ with the device
@pytest.fixture(scope="module")
def walk():
    """A simulated walk recorded by the emulated logger with its on-line step algorithm on."""
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import Subject
    from gaitlog.firmware_sim.world.walk_plan import WalkPlan
    from gaitlog.firmware_sim.world.walking import Walking

    walk_plan = WalkPlan(corridor_length_m=20.0, speeds=("preferred",), initial_stand_s=3.0,
                               final_stand_s=2.0, lap_marks_m=(0.0, 20.0, 40.0))
    logger = Logger(device_id=5, step_config=StepConfig(step_format=1, leg_length_m=0.93, foot_length_m=0.194))
    logger.record(Walking(subject=Subject.from_height(1.75), walk_plan=walk_plan, seed=1), start_time_s=1_700_000_000)
    h = logger.header
    stored = bytes(logger.step_memory)[: h.step_used_bytes]  # not wrapped: slot k = record k
    assert h.steps_written > 40 and not h.steps_wrapped
    return logger, stored


def test_device_records_decode_bit_for_bit_and_match_the_replay(walk):
    logger, stored = walk
    image = build_image(logger.header, logger.memory, step_memory=logger.step_memory)
    rec = decode_bytes(image)
    assert rec.step_records.tobytes() == stored
    check = verify_step_records(rec)
    assert check.identical and check.n_compared == rec.n_step_records == len(stored) // 20
    assert check.summary() == (f"device step records vs host replay: {check.n_compared} of {check.n_compared} "
                               "identical byte for byte")


def test_dropped_records_are_not_compared_and_a_changed_one_is_found(walk):
    logger, stored = walk
    step_memory = bytearray(logger.step_memory)
    step_memory[20 * 10 + 4] ^= 0x01           # damaged: dropped by its CRC
    with pytest.warns(UserWarning, match="1 of the"):
        rec = decode_bytes(build_image(logger.header, logger.memory, step_memory=bytes(step_memory)))
    check = verify_step_records(rec)
    n = len(stored) // 20
    assert check.identical and check.n_compared == n - 1 and check.n_replay_unknown == 1
    # a record changed *with* a valid CRC (a device computing something else) is found, field named
    body = bytearray(stored[20 * 12: 20 * 12 + 18])
    body[4] += 1                                # duration_samples
    step_memory = bytearray(logger.step_memory)
    step_memory[20 * 12: 20 * 13] = bytes(body) + binascii.crc_hqx(bytes(body), 0).to_bytes(2, "big")
    rec = decode_bytes(build_image(logger.header, logger.memory, step_memory=bytes(step_memory)))
    check = verify_step_records(rec)
    assert not check.identical and check.n_identical == check.n_compared - 1
    end_sample, what = check.mismatches[0]
    assert end_sample == int.from_bytes(stored[20 * 12: 20 * 12 + 4], "little")
    assert what.startswith("duration_samples: device")


def test_the_device_stores_the_algorithm_version_it_runs(walk):
    """PROTOCOL.md 2.2 (versions): configured with step_format 1, firmware 1.3 stores 4, the version it runs, and
    M4's exponent not given as its default 1/4; SET_STEP_CONFIG does the same; off stays off."""
    from gaitlog.firmware_sim.device import Logger

    logger, _ = walk
    assert logger.header.step_config.step_format == StepFormat.V4 == ONLINE_ALGORITHM_VERSION
    assert logger.header.firmware_version == 0x0103
    other = Logger(device_id=6)
    other.step_config = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)
    assert other.header.step_config.step_format == 4 and other.header.step_config.leg_length_m == 0.9
    assert other.header.step_config.m4_exponent == 0.25
    other.step_config = StepConfig()
    assert other.header.step_config.step_format == 0


@pytest.mark.parametrize("version", [1, 2, 3])
def test_an_image_of_an_older_algorithm_version_decodes_and_says_so(walk, version):
    """An image firmware 1.0, 1.1 or 1.2 wrote (step_format 1-3) decodes with its records as stored; the host
    replays only version 4, so they are reported as the older version's, not verified (and not a mismatch)."""
    logger, stored = walk
    firmware = f"firmware 1.{version - 1}"
    old = copy.deepcopy(logger.header)
    old.step_config = dataclasses.replace(old.step_config, step_format=StepFormat(version), m4_exponent=0.0)
    old.firmware_version = 0x0100 + version - 1
    rec = decode_bytes(build_image(old, logger.memory, step_memory=logger.step_memory))
    assert rec.header.step_config.step_format == version and rec.step_records.tobytes() == stored
    assert any(f"written by on-line algorithm version {version} ({firmware})" in n for n in rec.notes)
    check = verify_step_records(rec)
    assert check.algorithm_version == version and check.n_compared == 0 and not check.differs
    assert check.n_device == len(stored) // 20
    assert f"on-line algorithm version {version} ({firmware})" in check.summary()
    assert "this host replays version 4, so they are not verified" in check.summary()
    current = decode_bytes(build_image(logger.header, logger.memory, step_memory=logger.step_memory))
    assert not any("algorithm version" in n for n in current.notes)
    from gaitlog.host.files.info_report import step_lines  # `gaitlog info` says it too

    assert (f"on-line version {version}, leg 0.9300 m, foot 0.1940 m, records by on-line algorithm version "
            f"{version} ({firmware})") in step_lines(rec.header)[1]
    assert "records by" not in step_lines(current.header)[1]
