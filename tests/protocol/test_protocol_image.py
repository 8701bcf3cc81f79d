"""Memory-image file (PROTOCOL.md section 6), versions 1 and 2 (the layout before version 3, still read):
layout, round trip, recovery of damaged files. Version 3: ``test_protocol_image_framed.py``."""

from __future__ import annotations

import random
import struct
import warnings
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import encode_frame
from gaitlog.protocol.header import DeviceHeader, HeaderFlag
from gaitlog.protocol.image import build_image as build_current_image
from gaitlog.protocol.image import (
    detect_format,
    image_version_for,
    parse_image,
)
from gaitlog.protocol.steps import STEP_CAPACITY_RECORDS, empty_step_records, pack_step_records

pytestmark = pytest.mark.filterwarnings("ignore:.*are not usable:UserWarning")


def build_image(header, memory, missing_blocks=(), block_size=1024, **kw) -> bytes:
    """The image of version 1 or 2 that a host older than version 3 wrote for this header."""
    h = header if isinstance(header, DeviceHeader) else DeviceHeader.from_bytes(bytes(header))
    return build_current_image(header, memory, missing_blocks, block_size, image_version=image_version_for(h), **kw)


def _header(cap: int = 65536, sw: int | None = None) -> DeviceHeader:
    sw = cap if sw is None else sw
    flags = int(HeaderFlag.WRAPPED | HeaderFlag.OVERWRITE) if sw > cap else 0
    return DeviceHeader(capacity_samples=cap, samples_written=sw, write_index=sw % cap, flags=flags)


def _ref_image(header: bytes, memory: bytes, missing: set[int], bs: int, version: int = 1) -> bytes:
    """The file written field by field from the section-6 table (zlib directly, struct.pack); ``memory`` is
    the whole memory region (sample memory, then in version 2 the step memory)."""
    n = -(-len(memory) // bs)
    mem = bytearray(memory)
    for b in missing:
        mem[b * bs : (b + 1) * bs] = b"\xff" * len(mem[b * bs : (b + 1) * bs])
    crcs = []
    for i in range(n):
        c = zlib.crc32(bytes(mem[i * bs : (i + 1) * bs]))
        crcs.append(c ^ 0xFFFFFFFF if i in missing else c)
    table = struct.pack("<4sBxHII", b"GLIM", version, bs, len(mem), n) + struct.pack(f"<{n}I", *crcs)
    table += bytes(1 if i in missing else 0 for i in range(n))
    return table + struct.pack("<I", zlib.crc32(table)) + header + bytes(mem)


def test_full_image_matches_reference_layout(tmp_path) -> None:
    rng = np.random.default_rng(0)
    memory = rng.integers(0, 256, 262144, dtype=np.uint8).tobytes()
    h = _header()
    img = build_image(h.to_bytes(), memory, missing_blocks=[5, 255])
    assert img == _ref_image(h.to_bytes(), memory, {5, 255}, 1024)
    assert len(img) == 16 + 5 * 256 + 4 + 256 + 262144
    c = parse_image(img)
    assert c.table_ok and c.block_ok.sum() == 254 and c.block_missing[[5, 255]].all()
    ok_bytes = c.byte_ok()
    assert np.array_equal(c.memory[ok_bytes], np.frombuffer(memory, np.uint8)[ok_bytes])
    assert any("5, 255" in n for n in c.notes)
    assert parse_image(build_current_image(h, memory)).block_ok.all()


@st.composite
def images(draw: st.DrawFn) -> tuple[DeviceHeader, bytes, set[int], int]:
    cap = draw(st.integers(16, 3000))
    sw = draw(st.integers(0, 3 * cap))
    bs = draw(st.sampled_from([64, 128, 256, 1024, 1028]))
    mem = draw(st.binary(min_size=4 * cap, max_size=4 * cap))
    n = -(-4 * cap // bs)
    missing = draw(st.sets(st.integers(0, n - 1), max_size=n))
    return _header(cap, sw), mem, missing, bs


@given(images())
@settings(max_examples=60, deadline=None)
def test_image_round_trip_property(img_case: tuple[DeviceHeader, bytes, set[int], int]) -> None:
    h, mem, missing, bs = img_case
    img = build_image(h, mem, missing, bs)
    assert img == _ref_image(h.to_bytes(), mem, missing, bs)
    c = parse_image(img)
    assert c.header.to_bytes() == h.to_bytes() and c.block_size == bs
    assert set(np.flatnonzero(~c.block_ok)) == missing == set(np.flatnonzero(c.block_missing))
    ok = c.byte_ok()
    assert np.array_equal(c.memory[ok], np.frombuffer(mem, np.uint8)[ok])


def _damage(img: bytes, lo: int, rng: random.Random, n_events: int, max_insert: int = 5
            ) -> tuple[bytes, list[int], int | None]:
    """Flip/drop/insert at random positions >= lo; maybe truncate. Returns damaged bytes, positions in the
    original file, and the truncation point in the original file."""
    data = bytearray(img)
    points = sorted(rng.sample(range(lo, len(img)), n_events), reverse=True)
    for p in points:
        kind = rng.choice(["flip", "drop", "insert"])
        if kind == "flip":
            data[p] ^= 1 << rng.randrange(8)
        elif kind == "drop":
            del data[p]
        else:
            data[p:p] = rng.randbytes(rng.randint(1, max_insert))
    cut = None
    if rng.random() < 0.3:
        cut = rng.randrange(lo, len(img))
        del data[cut:]
    return bytes(data), points, cut


@pytest.mark.parametrize("seed", range(30))
def test_damaged_memory_yields_only_exact_blocks(seed: int) -> None:
    rng = random.Random(seed)
    npr = np.random.default_rng(seed)
    cap = 8192
    memory = npr.integers(0, 256, 4 * cap, dtype=np.uint8).tobytes()
    img = build_image(_header(cap), memory)
    mem0 = len(img) - 4 * cap
    damaged, points, cut = _damage(img, mem0, rng, rng.randint(1, 10))
    c = parse_image(damaged)
    truth = np.frombuffer(memory, np.uint8)
    ok = c.byte_ok()
    assert np.array_equal(c.memory[ok], truth[ok])  # nothing invented
    touched = {(p - mem0) // 1024 for p in points}
    for i in range(c.n_blocks):
        end_in_file = mem0 + (i + 1) * 1024
        beyond_cut = cut is not None and end_in_file + 5 * len(points) > cut
        if i not in touched and not beyond_cut:
            assert c.block_ok[i], f"intact block {i} not recovered; notes {c.notes}"
    if cut is not None and not c.block_ok[-1]:
        assert c.block_truncated[-1] or not c.block_ok[-1]
    assert (~c.block_ok).sum() <= len(touched) + (c.n_blocks if cut is not None else 0)


def test_shifted_blocks_are_recovered_and_reported() -> None:
    cap = 2048
    memory = np.random.default_rng(1).integers(0, 256, 4 * cap, dtype=np.uint8).tobytes()
    img = bytearray(build_image(_header(cap), memory))
    mem0 = len(img) - 4 * cap
    del img[mem0 + 1024 + 10]  # one byte dropped in block 1
    img[mem0 + 3 * 1024 + 5 : mem0 + 3 * 1024 + 5] = b"XYZ"  # three bytes inserted into block 3 (orig. offset)
    c = parse_image(bytes(img))
    assert c.block_ok.tolist() == [True, False, True, False, True, True, True, True]
    assert c.block_shift.tolist() == [0, 0, -1, 0, 2, 2, 2, 2]
    assert any("block 2 found shifted by -1" in n for n in c.notes)
    assert any("block 4 found shifted by +2" in n for n in c.notes)


def test_truncated_image_reports_missing_tail() -> None:
    cap = 4096
    memory = bytes(range(256)) * (4 * cap // 256)
    img = build_image(_header(cap), memory)
    mem0 = len(img) - 4 * cap
    c = parse_image(img[: mem0 + 5000])
    assert c.block_ok.tolist() == [True] * 4 + [False] * 12
    assert c.block_truncated.tolist() == [False] * 4 + [True] * 12
    assert any("truncated" in n for n in c.notes)


def test_damaged_table_of_an_old_image_verifies_no_block() -> None:
    cap = 4096
    memory = bytes(range(256)) * 64
    img = bytearray(build_image(_header(cap), memory, missing_blocks=[2]))
    img[16 + 4 * 16 + 2] = 0  # block 2's state byte: "missing" -> "present", table CRC now wrong
    c = parse_image(bytes(img))
    assert not c.table_ok
    assert not c.block_ok.any()  # its entries cannot be tied to indices: nothing is verified
    assert any("no block can be verified" in n for n in c.notes)


def test_old_image_table_and_memory_moved_by_the_same_blocks_is_not_misread() -> None:
    # 64 bytes inserted in the table move entry i onto i + 16; a 1024-byte duplicate in the memory moves block
    # i onto i + 16 too: with blocks of 64 bytes, entry and block agree on the wrong index (3,568 wrong samples
    # in the campaign before this rule)
    cap, bs = 8192, 64
    memory = np.random.default_rng(3).integers(0, 256, 4 * cap, dtype=np.uint8).tobytes()
    img = build_image(_header(cap), memory, block_size=bs)
    mem0 = 16 + 5 * (4 * cap // bs) + 4 + 256
    at = mem0 + 100 * bs
    moved = img[:400] + bytes(64) + img[400:at] + img[at - 1024:at] + img[at:]
    c = parse_image(moved)
    ok = c.byte_ok()
    assert np.array_equal(c.memory[ok], np.frombuffer(memory, np.uint8)[ok])
    assert not ok.any()


def test_header_shifted_by_table_damage_is_found() -> None:
    cap = 1024
    memory = bytes(4 * cap)
    img = bytearray(build_image(_header(cap), memory))
    del img[30]  # inside the CRC table
    c = parse_image(bytes(img))
    assert any("header found shifted by -1" in n for n in c.notes)
    assert c.header.capacity_samples == cap


def _img() -> bytes:
    return build_image(_header(256), bytes(1024))


@pytest.mark.parametrize(
    ("mutate", "offset", "match"),
    [
        (lambda b: b"GLIN" + b[4:], 0, "not a gaitlog memory image"),
        (lambda b: b[:4] + b"\x04" + b[5:], 4, "unknown version 4"),
        (lambda b: b[:4] + b"\x02" + b[5:], 4, "image_version: 2, but the device header has no step memory"),
        (lambda b: b[:6] + struct.pack("<H", 10) + b[8:], 6, "block_size 10"),
        (lambda b: b[:8] + struct.pack("<I", 2**30) + b[12:], 8, "memory_bytes"),
        (lambda b: b[:12] + struct.pack("<I", 2**31) + b[16:], 12, "n_blocks"),
        (lambda b: b[:10], 10, "truncated"),
        (lambda b: b[:18], 18, "truncated inside its block table"),
        (lambda b: b[:25] + b"\x00" * 256 + b[281:], 25, "magic"),
        (lambda b: b[:25 + 100] + b"\x01" + b[25 + 101 :], 25 + 254, "header_crc"),
    ],
)
def test_image_rejections(mutate, offset: int, match: str) -> None:
    with pytest.raises(ProtocolError, match=match) as info:
        parse_image(mutate(_img()), source="f.glimg")
    assert info.value.offset == offset and "f.glimg" in str(info.value)


def test_image_header_capacity_mismatch() -> None:
    with pytest.raises(ProtocolError, match="needs 4096"):
        build_image(_header(1024), bytes(1000))
    img = bytearray(_img())
    hdr = _header(512).to_bytes()
    img[16 + 5 + 4 : 16 + 5 + 4 + 256] = hdr
    with pytest.raises(ProtocolError, match="memory_bytes") as info:
        parse_image(bytes(img))
    assert info.value.offset == 8


def test_absurd_sizes_do_not_allocate() -> None:
    # n_blocks consistent with a huge memory_bytes is refused before any allocation
    bad = struct.pack("<4sBxHII", b"GLIM", 1, 64, 2**32 - 4, 2**32 // 64)
    with pytest.raises(ProtocolError, match="memory_bytes"):
        parse_image(bad)


def test_detect_format() -> None:
    img = _img()
    assert detect_format(img) == "image"
    assert detect_format(_header(256).to_bytes() + bytes(1024)) == "raw"
    assert detect_format(b"\x00" * 100 + encode_frame(0x87, 0, bytes(8))) == "capture"
    with pytest.raises(ProtocolError, match="not a memory image"):
        detect_format(b"hello world")
    with pytest.raises(ProtocolError):
        detect_format(b"")


def test_warning_only_when_stored_samples_are_lost() -> None:
    cap = 4096  # 16 blocks; 500 samples use block 0 and part of block 1
    img = build_image(_header(cap, 500), bytes(4 * cap), missing_blocks=[5, 9])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = parse_image(img)
    assert c.block_missing[[5, 9]].all()
    img = build_image(_header(cap, 500), bytes(4 * cap), missing_blocks=[1])
    with pytest.warns(UserWarning, match=r"1 of the 2 blocks holding stored samples are not usable \(block 1\)"):
        parse_image(img, source="x.glimg")


# ---------------------------------------------------------------------------- image_version 2: step memory
def _step_header(cap: int, step_cap: int, steps: int, sw: int | None = None) -> DeviceHeader:
    h = _header(cap, sw)
    return h.replace(step_capacity=step_cap, steps_written=steps, step_write_index=steps % step_cap)


def _step_memory(step_cap: int, steps: int, seed: int = 0) -> tuple[bytes, np.ndarray]:
    """A step memory as the ring leaves it: record number k in slot k mod step_cap (erased 0xFF where never
    written), and the records by number."""
    rng = np.random.default_rng(seed)
    rec = empty_step_records(steps)
    rec["end_sample"] = np.cumsum(rng.integers(20, 40, steps))
    rec["duration_samples"] = rng.integers(0, 60, steps)
    rec["length_m1_q14"] = rng.integers(0, 20000, steps)
    raw = np.frombuffer(pack_step_records(rec), np.uint8).reshape(-1, 20)
    mem = np.full((step_cap, 20), 0xFF, np.uint8)
    mem[np.arange(steps) % step_cap] = raw  # later records overwrite earlier ones
    return mem.tobytes(), rec


def test_v2_image_matches_reference_layout_and_splits_the_region() -> None:
    cap, step_cap, steps = 1000, STEP_CAPACITY_RECORDS, 3300  # 4000 sample bytes: block 3 straddles
    h = _step_header(cap, step_cap, steps, sw=700)
    memory = np.random.default_rng(2).integers(0, 256, 4 * cap, dtype=np.uint8).tobytes()
    steps_mem, rec = _step_memory(step_cap, steps)
    img = build_image(h, memory, missing_blocks=[60], step_memory=steps_mem)
    assert img == _ref_image(h.to_bytes(), memory + steps_mem, {60}, 1024, version=2)
    assert img == build_image(h, memory + steps_mem, missing_blocks=[60])  # the region in one piece
    assert img[4] == 2 and struct.unpack_from("<I", img, 8)[0] == 4000 + 65520
    c = parse_image(img)  # block 60 holds records of the wrapped ring: a warning
    assert c.image_version == 2 and c.memory.tobytes() == memory and c.memory.size == 4000
    assert c.step_memory.size == 65520 and c.byte_ok().all()
    step_ok = c.step_byte_ok()
    lost = np.zeros(65520, bool)
    lost[60 * 1024 - 4000 : 61 * 1024 - 4000] = True
    assert np.array_equal(step_ok, ~lost)
    assert np.array_equal(c.step_memory[step_ok], np.frombuffer(steps_mem, np.uint8)[step_ok])
    got, usable = c.step_records()  # oldest first: numbers 24 .. 3299
    assert got.size == 3276 and np.array_equal(got["end_sample"][usable], rec["end_sample"][24:][usable])
    slots = (24 + np.arange(3276)) % 3276
    touches = ((20 * slots + 19 >= 60 * 1024 - 4000) & (20 * slots < 61 * 1024 - 4000))
    assert np.array_equal(usable, ~touches)


def test_v2_build_rejects_wrong_sizes() -> None:
    h = _step_header(256, 4, 1)
    with pytest.raises(ProtocolError, match=r"needs 1104 \(with the 80-byte step memory"):
        build_image(h, bytes(1024))
    with pytest.raises(ProtocolError, match="step memory of 60 bytes"):
        build_image(h, bytes(1024), step_memory=bytes(60))
    with pytest.raises(ProtocolError, match="need 1024 and 0"):
        build_image(_header(256), bytes(1024), step_memory=bytes(20))


@st.composite
def step_images(draw: st.DrawFn) -> tuple[DeviceHeader, bytes, bytes, set[int], int]:
    cap = draw(st.integers(1, 600))
    step_cap = draw(st.integers(1, 300))
    steps = draw(st.integers(0, 3 * step_cap))
    bs = draw(st.sampled_from([64, 68, 128, 1024]))
    mem = draw(st.binary(min_size=4 * cap, max_size=4 * cap))
    steps_mem, _ = _step_memory(step_cap, steps, seed=draw(st.integers(0, 1000)))
    n = -(-(4 * cap + 20 * step_cap) // bs)
    missing = draw(st.sets(st.integers(0, n - 1), max_size=n))
    return _step_header(cap, step_cap, steps, sw=draw(st.integers(0, 2 * cap))), mem, steps_mem, missing, bs


@given(step_images())
@settings(max_examples=60, deadline=None)
def test_v2_image_round_trip_property(case: tuple[DeviceHeader, bytes, bytes, set[int], int]) -> None:
    h, mem, steps_mem, missing, bs = case
    img = build_image(h, mem, missing, bs, step_memory=steps_mem)
    assert img == _ref_image(h.to_bytes(), mem + steps_mem, missing, bs, version=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c = parse_image(img)
    assert c.header.to_bytes() == h.to_bytes() and c.image_version == 2
    assert set(np.flatnonzero(~c.block_ok)) == missing
    ok, step_ok = c.byte_ok(), c.step_byte_ok()
    assert ok.size == len(mem) and step_ok.size == len(steps_mem)
    assert np.array_equal(c.memory[ok], np.frombuffer(mem, np.uint8)[ok])
    assert np.array_equal(c.step_memory[step_ok], np.frombuffer(steps_mem, np.uint8)[step_ok])
    region_ok = np.concatenate([ok, step_ok])
    assert np.array_equal(region_ok, ~np.isin(np.arange(region_ok.size) // bs, list(missing)))
    got, usable = c.step_records()
    assert got.size == h.n_steps_stored
    slots = h.step_slots()
    want = np.array([step_ok[20 * k : 20 * k + 20].all() for k in slots], dtype=bool)
    assert np.array_equal(usable, want)


def test_v2_damage_across_the_boundary_is_recovered() -> None:
    cap, step_cap = 1000, 200  # region 4000 + 4000 bytes, 8 blocks; block 3 = samples 3072-3999 + steps 0-95
    h = _step_header(cap, step_cap, 150, sw=1000)
    memory = np.random.default_rng(5).integers(0, 256, 4 * cap, dtype=np.uint8).tobytes()
    steps_mem, rec = _step_memory(step_cap, 150, seed=5)
    img = bytearray(build_image(h, memory, step_memory=steps_mem))
    mem0 = len(img) - 8000
    del img[mem0 + 1024 + 10]  # one byte dropped in block 1 (samples)
    img[mem0 + 3 * 1024 + 2 : mem0 + 3 * 1024 + 2] = b"AB"  # two inserted in the straddling block 3 (orig. offset)
    img[mem0 + 5 * 1024 + 7 : mem0 + 5 * 1024 + 7] = b"C"  # one inserted in block 5 (steps only)
    with pytest.warns(UserWarning) as caught:
        c = parse_image(bytes(img))
    assert c.block_ok.tolist() == [True, False, True, False, True, False, True, True]
    assert c.block_shift.tolist() == [0, 0, -1, 0, 1, 0, 2, 2]
    messages = [str(w.message) for w in caught]
    assert any("2 of the 4 blocks holding stored samples are not usable (blocks 1, 3)" in m for m in messages)
    assert any("2 of the 4 blocks holding stored step records are not usable (blocks 3, 5)" in m for m in messages)
    ok, step_ok = c.byte_ok(), c.step_byte_ok()
    assert np.array_equal(c.memory[ok], np.frombuffer(memory, np.uint8)[ok])
    assert np.array_equal(c.step_memory[step_ok], np.frombuffer(steps_mem, np.uint8)[step_ok])
    got, usable = c.step_records()
    # records 0-4 touch block 3 (step bytes 0-95, record 4 = bytes 80-99), records 56-107 touch block 5
    # (step bytes 1120-2143); every other record is recovered, across the shifts
    expect = np.ones(150, bool)
    expect[:5] = False
    expect[56:108] = False
    assert np.array_equal(usable, expect)
    assert np.array_equal(got["end_sample"][usable], rec["end_sample"][usable])


def test_v2_image_without_step_memory_is_refused() -> None:
    v1 = _img()  # header with step_capacity 0
    with pytest.raises(ProtocolError, match="image_version: 2, but the device header has no step memory") as info:
        parse_image(v1[:4] + b"\x02" + v1[5:])
    assert info.value.offset == 4
    h = _step_header(256, 4, 1)
    bad_size = bytearray(build_image(h, bytes(1024), step_memory=bytes(80)))
    struct.pack_into("<I", bad_size, 8, 1108)  # still 2 blocks of 1024
    with pytest.raises(ProtocolError, match=r"memory_bytes: 1108, .* 256 samples and 4 step records needs 1104"):
        parse_image(bytes(bad_size))


def test_v1_image_of_a_device_with_step_memory_is_read_without_its_records() -> None:
    # what a host older than the step memory writes: version 1, the sample memory only, the new header as is
    h = _step_header(256, STEP_CAPACITY_RECORDS, 30, sw=100)
    memory = bytes(range(256)) * 4
    img = _ref_image(h.to_bytes(), memory, set(), 256)
    with pytest.warns(UserWarning, match="image version 1 holds no step memory: the header's 30 stored step records"):
        c = parse_image(img, source="old.glimg")
    assert c.image_version == 1 and c.memory.tobytes() == memory and c.byte_ok().all()
    assert c.step_memory.size == 65520 and not c.step_byte_ok().any() and (c.step_memory == 0xFF).all()
    got, usable = c.step_records()
    assert got.size == 30 and not usable.any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no records stored: nothing lost, no warning
        c = parse_image(_ref_image(_step_header(256, 4, 0).to_bytes(), memory, set(), 256))
    assert c.step_memory.size == 80 and c.step_records()[0].size == 0


def test_v1_images_are_still_read() -> None:
    # a file written field by field as version 1 (as written before the step memory existed)
    memory = bytes(range(256)) * 4
    img = _ref_image(_header(256, 100).to_bytes(), memory, set(), 64)
    c = parse_image(img)
    assert c.image_version == 1 and c.memory.tobytes() == memory and c.block_ok.all()
    assert c.step_memory.size == 0 and c.step_byte_ok().size == 0
    got, usable = c.step_records()
    assert got.size == 0 and usable.size == 0
    assert build_image(_header(256, 100), memory, block_size=64) == img  # no step memory: still version 1


def test_truncated_v2_image_reports_the_step_blocks() -> None:
    h = _step_header(256, STEP_CAPACITY_RECORDS, 3000, sw=256)
    steps_mem, _ = _step_memory(STEP_CAPACITY_RECORDS, 3000)
    img = build_image(h, bytes(1024), step_memory=steps_mem)
    with pytest.warns(UserWarning, match="blocks holding stored step records are not usable"):
        c = parse_image(img[: len(img) - 30000])
    assert c.block_ok[:35].all() and c.block_truncated[36:].all()
