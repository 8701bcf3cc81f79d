"""Checksums of the wire and file formats (``PROTOCOL.md``, conventions and sections 2, 2.3, 3, 5, 6).

CRC-16/XMODEM protects frames, XMODEM blocks, the device header and each per-step record; CRC-32 (zlib)
protects each block of a memory-image file; CRC-16/UMTS (another polynomial, so that it fails where the frame's
CRC-16/XMODEM does not) checks each 64-sample block of a DATA_BLOCKS frame (protocol version 2, section 4.1). Both are thin wrappers over the C implementations of the
standard library; :func:`crc16_xmodem_rows` computes the CRC-16 of many short records at once with numpy.
"""

from __future__ import annotations

import binascii
import zlib

import numpy as np

__all__ = ["crc16_xmodem", "crc16_xmodem_rows", "crc16_umts_rows", "crc32"]


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


#: CRC-16/XMODEM of each single byte from a zero register: the table of the byte-wise algorithm.
_CRC16_TABLE = np.array([binascii.crc_hqx(bytes((i,)), 0) for i in range(256)], dtype=np.uint16)


def crc16_xmodem_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/XMODEM of every row of a ``(n, k)`` ``uint8`` array, vectorised over the rows.

    The byte-wise table algorithm ``crc = (crc << 8) ^ T[(crc >> 8) ^ byte]`` run on all rows at once: k
    numpy steps instead of n calls of :func:`crc16_xmodem` (same values; checked by the tests).

    Parameters
    ----------
    rows
        ``(n, k)`` bytes, one message per row.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` ``uint16`` CRCs.

    Examples
    --------
    >>> rows = np.frombuffer(b"123456789" * 2, dtype=np.uint8).reshape(2, 9)
    >>> [hex(c) for c in crc16_xmodem_rows(rows)]
    ['0x31c3', '0x31c3']
    """
    return _rows_crc16(rows, _CRC16_TABLE)


def _rows_crc16(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """The byte-wise algorithm of a non-reflected 16-bit CRC with a zero register and no final XOR, over every
    row of ``rows`` at once (``table``: the CRC of each single byte)."""
    r = np.asarray(rows, dtype=np.uint8)
    if r.ndim != 2:
        raise ValueError(f"rows must be a 2-D uint8 array, got shape {r.shape}")
    crc = np.zeros(r.shape[0], dtype=np.uint16)
    for j in range(r.shape[1]):
        crc = (crc << 8) ^ table[(crc >> 8) ^ r[:, j]]
    return crc


def _msb_first_table(poly: int) -> np.ndarray:
    """The byte-wise table of a 16-bit CRC, most significant bit first."""
    table = np.zeros(256, dtype=np.uint16)
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
        table[i] = crc
    return table


_CRC16_UMTS_TABLE = _msb_first_table(0x8005)


def crc16_umts_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/UMTS (poly 0x8005, init 0x0000, not reflected, no final XOR; check value 0xFEE8) of every row of a
    ``(n, k)`` ``uint8`` array, vectorised over the rows as :func:`crc16_xmodem_rows`.

    Its register starts at 0, so zero bytes in front of a message leave its CRC unchanged: rows of different
    lengths can be left-padded with zeros to one width.

    >>> [hex(c) for c in crc16_umts_rows(np.frombuffer(b"123456789", dtype=np.uint8).reshape(1, 9))]
    ['0xfee8']
    >>> int(crc16_umts_rows(np.frombuffer(b"\\x00\\x00123456789", dtype=np.uint8).reshape(1, 11))[0])
    65256
    """
    return _rows_crc16(rows, _CRC16_UMTS_TABLE)


def crc32(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-32 of zlib/PNG (reflected poly 0x04C11DB7, init and final XOR 0xFFFFFFFF), unsigned.

    ``crc`` is the running value, to continue a CRC over several pieces (0 to start).

    Examples
    --------
    >>> hex(crc32(b"123456789"))
    '0xcbf43926'
    >>> crc32(b"6789", crc32(b"12345")) == crc32(b"123456789")
    True
    """
    return zlib.crc32(data, crc) & 0xFFFFFFFF
