"""CRC-16/XMODEM and CRC-32 against their published check values and a bitwise reference."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.protocol.crc import crc16_xmodem, crc32


def _crc16_bitwise(data: bytes) -> int:
    """Textbook MSB-first CRC-16, poly 0x1021, init 0 (independent of binascii)."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def test_crc_check_values() -> None:
    # catalogue of parametrised CRC algorithms (reveng): CRC-16/XMODEM check 0x31C3, CRC-32 check 0xCBF43926
    assert crc16_xmodem(b"123456789") == 0x31C3
    assert crc32(b"123456789") == 0xCBF43926
    assert crc16_xmodem(b"") == 0 and crc32(b"") == 0


@settings(deadline=None)
@given(st.binary(max_size=300), st.binary(max_size=50))
def test_crc16_matches_bitwise_and_chains(a: bytes, b: bytes) -> None:
    assert crc16_xmodem(a + b) == _crc16_bitwise(a + b)
    assert crc16_xmodem(b, crc16_xmodem(a)) == crc16_xmodem(a + b)
