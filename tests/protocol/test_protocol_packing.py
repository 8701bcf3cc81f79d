"""P32 packing (PROTOCOL.md section 1) against a per-sample bit-twiddling reference."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.packing import (
    FLAG_MARK,
    FLAG_SESSION_START,
    bytes_to_words,
    pack_words,
    unpack_words,
    words_to_bytes,
)


def _ref_pack(x: int, y: int, z: int, f: int) -> bytes:
    return struct.pack("<I", x | (y << 10) | (z << 20) | (f << 30))


codes_st = st.integers(0, 200).flatmap(
    lambda n: st.tuples(
        hnp.arrays(np.int64, (n, 3), elements=st.integers(0, 1023)),
        hnp.arrays(np.uint8, (n,), elements=st.integers(0, 3)),
    )
)


@settings(deadline=None)
@given(codes_st)
def test_pack_matches_reference_and_round_trips(cf: tuple[np.ndarray, np.ndarray]) -> None:
    codes, flags = cf
    data = words_to_bytes(pack_words(codes, flags))
    assert data == b"".join(_ref_pack(*map(int, c), int(f)) for c, f in zip(codes, flags))
    c2, f2 = unpack_words(data)
    assert c2.dtype == np.uint16 and f2.dtype == np.uint8
    np.testing.assert_array_equal(c2, codes)
    np.testing.assert_array_equal(f2, flags)
    np.testing.assert_array_equal(bytes_to_words(data), pack_words(codes, flags))


@settings(deadline=None)
@given(st.binary(max_size=400).map(lambda b: b[: len(b) // 4 * 4]))
def test_unpack_then_pack_is_identity_on_any_word(data: bytes) -> None:
    codes, flags = unpack_words(data)
    assert words_to_bytes(pack_words(codes, flags)) == data


def test_flag_bits_positions() -> None:
    assert FLAG_SESSION_START == 1 and FLAG_MARK == 2
    w = pack_words(np.zeros((2, 3), int), np.array([FLAG_SESSION_START, FLAG_MARK]))
    assert w.tolist() == [1 << 30, 1 << 31]
    assert pack_words(np.zeros((1, 3), int)).tolist() == [0]


@pytest.mark.parametrize(
    ("codes", "flags", "match"),
    [
        (np.array([[0, -1, 0]]), None, "sample 0 axis 1: code -1"),
        (np.array([[0, 0, 0], [0, 0, 1024]]), None, "sample 1 axis 2: code 1024"),
        (np.zeros((3,), int), None, "shape"),
        (np.zeros((1, 3)), None, "integers"),
        (np.zeros((2, 3), int), np.array([0, 4]), "sample 1: flag value 4"),
        (np.zeros((2, 3), int), np.array([0]), "flags must have shape"),
    ],
)
def test_pack_rejects(codes: np.ndarray, flags: np.ndarray | None, match: str) -> None:
    with pytest.raises(ProtocolError, match=match):
        pack_words(codes, flags)


def test_unpack_rejects_partial_word() -> None:
    with pytest.raises(ProtocolError, match="multiple of 4"):
        unpack_words(b"\x00" * 7)


def test_empty() -> None:
    c, f = unpack_words(b"")
    assert c.shape == (0, 3) and f.shape == (0,)
    assert words_to_bytes(pack_words(np.zeros((0, 3), np.uint16))) == b""
