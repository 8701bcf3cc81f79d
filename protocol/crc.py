"""Checksums of the wire and file formats (``PROTOCOL.md``, conventions and sections 3, 5, 6).

CRC-16/XMODEM protects frames, XMODEM blocks and the device header; CRC-32 (zlib) protects each block of a
memory-image file. Both are thin wrappers over the C implementations of the standard library.
"""

from __future__ import annotations

import binascii
import zlib

__all__ = ["crc16_xmodem", "crc32"]


def crc16_xmodem(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16/XMODEM: poly 0x1021, init 0x0000, not reflected, no final XOR.

    Parameters
    ----------
    data
        Bytes to check.
    crc
        Running value, to continue a CRC over several pieces (0 to start).

    Returns
    -------
    int
        The 16-bit CRC.

    Examples
    --------
    >>> hex(crc16_xmodem(b"123456789"))
    '0x31c3'
    >>> crc16_xmodem(b"6789", crc16_xmodem(b"12345")) == crc16_xmodem(b"123456789")
    True
    """
    return binascii.crc_hqx(data, crc)


def crc32(data: bytes | bytearray | memoryview) -> int:
    """CRC-32 of zlib/PNG (reflected poly 0x04C11DB7, init and final XOR 0xFFFFFFFF), unsigned.

    Examples
    --------
    >>> hex(crc32(b"123456789"))
    '0xcbf43926'
    """
    return zlib.crc32(data) & 0xFFFFFFFF
