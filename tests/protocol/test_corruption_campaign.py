"""The corruption campaign of ``benchmarks/bench_corruption.py``, small (seeds fixed), and the cases of issue 13.

Truth is the device's memory the files were built from: a sample marked valid must equal it.
"""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from gaitlog.host.files.decode import decode_bytes
from gaitlog.protocol.header import DeviceHeader
from gaitlog.protocol.image import build_image, image_version_for
from gaitlog.protocol.packing import pack_words
from gaitlog.protocol.raw_dump import raw_dump_bytes

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_corruption.py"
_spec = importlib.util.spec_from_file_location("bench_corruption", _PATH)
bench = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("bench_corruption", bench)
_spec.loader.exec_module(bench)


@pytest.mark.parametrize("kind", bench.KINDS)
def test_small_campaign_has_no_wrong_sample_and_no_crash(kind: str) -> None:
    totals = bench.campaign(150, seed=13, kinds=(kind,))[kind]
    assert totals.files == 150 and totals.single > 100
    assert totals.wrong == 0, totals.wrong_examples
    assert totals.crashes == 0, totals.crash_examples
    # one damaged region loses only the blocks it touches, unless it hit what places or verifies the others
    assert totals.excess == 0, totals.excess_examples
    assert totals.unverified == 0  # by default nothing unverified is marked valid


def test_campaign_with_accept_unverified_labels_what_it_keeps() -> None:
    totals = bench.campaign(150, seed=13, kinds=("raw",), accept_unverified=True)["raw"]
    assert totals.wrong == 0 and totals.crashes == 0
    assert totals.unverified > 0  # cut dumps kept, labelled UNVERIFIED (and counted apart from ``wrong``)


def test_the_campaign_can_fail() -> None:
    """A decoder that marks a missing sample valid is caught as wrong; one that refuses all as excess."""
    real = bench.decode_bytes

    def lenient(data, **kw):
        rec = real(data, **kw)
        rec.valid[:] = True
        return rec

    def refusing(data, **kw):
        raise bench.ProtocolError("refused")

    try:
        bench.decode_bytes = lenient
        assert bench.campaign(40, seed=1, kinds=("image",))["image"].wrong > 0
        bench.decode_bytes = refusing
        assert bench.campaign(40, seed=1, kinds=("image",))["image"].excess > 0
    finally:
        bench.decode_bytes = real


def _memory(cap: int, seed: int = 1) -> bytes:
    rng = np.random.default_rng(seed)
    return pack_words(rng.integers(0, 1024, (cap, 3)), np.zeros(cap, int)).astype("<u4").tobytes()


def _score(data: bytes, memory: bytes) -> tuple[int, int]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = decode_bytes(data)
    got = pack_words(rec.codes, rec.flags).astype("<u4")
    truth = np.frombuffer(memory, "<u4")
    return int(rec.valid.sum()), int((rec.valid & (got != truth)).sum())


@pytest.mark.parametrize("version", ["old", 3])
def test_block_size_64_with_4_table_bytes_lost_or_gained_is_never_wrong(version) -> None:
    cap = 8300
    memory = _memory(cap)
    h = DeviceHeader(capacity_samples=cap, samples_written=cap, write_index=0)
    img = build_image(h, memory, block_size=64, image_version=image_version_for(h) if version == "old" else 3)
    for damaged in (img[:100] + img[104:], img[:100] + bytes(4) + img[100:]):
        valid, wrong = _score(damaged, memory)
        assert wrong == 0
        assert valid == (cap if version == 3 else valid)  # version 3: the preamble's copy, nothing lost


@pytest.mark.parametrize(("version", "inserted"), [(1, 64), (1, 65), (3, 64), (3, 65), (3, 5000)])
def test_inserted_bytes_lose_only_the_block_they_hit(version: int, inserted: int) -> None:
    cap = 65536
    memory = _memory(cap, 2)
    h = DeviceHeader(capacity_samples=cap, samples_written=cap, write_index=0)
    img = build_image(h, memory, image_version=version)
    mem0, frame = (16 + 5 * 256 + 4 + 256, 1024) if version == 1 else (276, 1040)
    at = mem0 + 10 * frame + 500
    valid, wrong = _score(img[:at] + bytes(inserted) + img[at:], memory)
    assert wrong == 0 and cap - valid == 256  # block 10 only (was 62,976 lost for 65 bytes)


def test_raw_dump_bit_flip_and_dropped_byte_are_detected() -> None:
    cap = 4096
    memory = _memory(cap, 3)
    h = DeviceHeader(capacity_samples=cap, samples_written=cap, write_index=0)
    raw = bytearray(raw_dump_bytes(h.to_bytes(), memory))
    assert _score(bytes(raw), memory) == (cap, 0)
    raw[256 + 4 * 1000] ^= 0x04
    valid, wrong = _score(bytes(raw), memory)
    assert wrong == 0 and valid == cap - 64  # the 256-byte chunk holding sample 1000
    dropped = bytes(raw[: 256 + 4 * 2000]) + bytes(raw[256 + 4 * 2000 + 1:])
    valid, wrong = _score(dropped, memory)
    assert wrong == 0 and valid == cap - 128


def test_raw_dump_without_trailer_is_reported_missing_unless_accepted() -> None:
    cap = 512
    memory = _memory(cap, 4)
    h = DeviceHeader(capacity_samples=cap, samples_written=cap, write_index=0)
    body = h.to_bytes() + memory
    legacy = body + b"\x1a" * (-len(body) % 1024)
    cut = raw_dump_bytes(h.to_bytes(), memory)[: len(body) - 100]  # an XDUMP file cut before its trailer
    for data, present in ((legacy, cap), (cut, cap - 25)):
        with pytest.warns(UserWarning, match=f"its {present} samples present cannot be verified"):
            rec = decode_bytes(data)
        assert not rec.valid.any() and any("verified: NO" in n for n in rec.metadata()["notes"])
        assert "without its check trailer" in rec.gaps[0].reason
        with pytest.warns(UserWarning, match="UNVERIFIED"):
            accepted = decode_bytes(data, accept_unverified=True)
        assert accepted.n_valid == present and any("UNVERIFIED" in n for n in accepted.metadata()["notes"])
        assert _score(data, memory) == (0, 0)


def test_old_image_whose_table_and_memory_moved_together_is_never_wrong() -> None:
    """The damage that gave the campaign's 3,568 wrong samples in one old image: the block table lost bytes
    and the memory region as many blocks' worth, so entry i + k and block i + k met at index i. Built by
    hand: 4 bytes (one entry) dropped in the table of a 64-byte-block image and 64 bytes (one block) in its
    memory (1,392 wrong samples before the rule)."""
    cap, bs = 2048, 64
    memory = _memory(cap, 9)
    h = DeviceHeader(capacity_samples=cap, samples_written=cap, write_index=0)
    img = build_image(h, memory, block_size=bs, image_version=image_version_for(h))
    mem0 = 16 + 5 * (4 * cap // bs) + 4 + 256
    at = mem0 + 40 * bs
    damaged = img[:40] + img[44:at] + img[at + bs:]
    assert _score(damaged, memory) == (0, 0)  # nothing can be tied to its index: all reported missing
    intact_table = img[:at] + img[at + bs:]  # the same memory damage with the table intact loses one block
    assert _score(intact_table, memory) == (cap - bs // 4, 0)


# ------------------------------------------------------------------ flip campaign (protocol version 2 captures)
def test_flip_campaign_slice_loses_only_the_blocks_touched_and_says_so() -> None:
    """Captures with 1-10 flipped bits, 1-10 flipped bytes or a burst: the DUMP_BLOCKS capture never gives a wrong
    sample, loses nothing beyond the 64-sample blocks touched (and the frames whose framing was hit), and its
    stderr line counts every lost sample; the same devices and damages in today's DUMP_CHECKED capture lose
    whole 4096-byte frames (the baseline)."""
    results = bench.flip_campaign(60, seed=21)
    v1, v2 = results["capture-v1"], results["capture-v2"]
    assert v2.files == 60 and v2.damaged_bytes == v1.damaged_bytes > 60
    assert v2.wrong == 0 and v2.crashes == 0 and v2.refused == 0, v2.examples
    assert v2.excess == 0 and v2.unsaid == 0, v2.examples
    assert v2.max_lost_per_byte <= 64
    assert v1.wrong == 0 and v1.lost > 4 * v2.lost  # the baseline loses whole frames


def test_the_flip_campaign_can_fail() -> None:
    real = bench.decode_bytes

    def lenient(data, **kw):
        rec = real(data, **kw)
        rec.valid[:] = True
        return rec

    def dropping(data, **kw):
        rec = real(data, **kw)
        rec.valid[:] = False
        return rec

    try:
        bench.decode_bytes = lenient
        assert bench.flip_campaign(20, seed=2, kinds=("capture-v2",))["capture-v2"].wrong > 0
        bench.decode_bytes = dropping
        assert bench.flip_campaign(20, seed=2, kinds=("capture-v2",))["capture-v2"].excess > 0
    finally:
        bench.decode_bytes = real
