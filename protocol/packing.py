"""P32 sample packing (``PROTOCOL.md`` section 1), vectorised with numpy.

One sample is one little-endian 32-bit word::

    bit  31 30 | 29 ... 20 | 19 ... 10 | 9 ... 0
         M  S  |  z code   |  y code   |  x code

``x``, ``y``, ``z`` are raw 10-bit ADC codes (0-1023); the 2-bit flag field holds ``S`` (bit 30,
:data:`FLAG_SESSION_START`) and ``M`` (bit 31, :data:`FLAG_MARK`).

Examples
--------
>>> import numpy as np
>>> w = pack_words(np.array([[512, 256, 768]]), np.array([FLAG_SESSION_START]))
>>> hex(int(w[0])), words_to_bytes(w).hex()
('0x70040200', '00020470')
>>> codes, flags = unpack_words(bytes.fromhex("00020470"))
>>> codes.tolist(), flags.tolist()
([[512, 256, 768]], [1])
"""

from __future__ import annotations

import numpy as np

from gaitlog.protocol.errors import ProtocolError

__all__ = [
    "FLAG_SESSION_START",
    "FLAG_MARK",
    "CODE_MAX",
    "pack_words",
    "unpack_words",
    "words_to_bytes",
    "bytes_to_words",
]

#: Flag value (word bit 30) of the first sample of each logging run.
FLAG_SESSION_START = 1
#: Flag value (word bit 31) of the first sample at or after a marker-button press.
FLAG_MARK = 2
#: Largest code of a 10-bit field.
CODE_MAX = 1023

_LE_U32 = np.dtype("<u4")


def pack_words(codes: np.ndarray, flags: np.ndarray | None = None) -> np.ndarray:
    """Pack ``(n, 3)`` ADC codes and ``(n,)`` 2-bit flags into P32 words.

    Parameters
    ----------
    codes
        Integer codes in counts, shape ``(n, 3)`` (x, y, z), each 0 ... 1023.
    flags
        Flag values 0 ... 3 (``FLAG_SESSION_START | FLAG_MARK``), shape ``(n,)``; ``None`` means all 0.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` ``uint32`` words (native byte order; :func:`words_to_bytes` gives the wire bytes).

    Raises
    ------
    ProtocolError
        A code outside 0 ... 1023 or a flag outside 0 ... 3 (the message names the first bad sample), a
        non-integer array or a wrong shape.

    Examples
    --------
    >>> pack_words(np.array([[1023, 0, 1]])).tolist()
    [1049599]
    >>> pack_words(np.array([[1024, 0, 0]]))
    Traceback (most recent call last):
    ...
    gaitlog.protocol.errors.ProtocolError: sample 0 axis 0: code 1024 outside 0..1023
    """
    c = np.asarray(codes)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ProtocolError(f"codes must have shape (n, 3), got {c.shape}")
    if c.size and not np.issubdtype(c.dtype, np.integer):
        raise ProtocolError(f"codes must be integers, got dtype {c.dtype}")
    bad = (c < 0) | (c > CODE_MAX)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ProtocolError(f"sample {i} axis {j}: code {c[i, j]} outside 0..{CODE_MAX}")
    c32 = c.astype(np.uint32, copy=False)
    words = c32[:, 0] | (c32[:, 1] << np.uint32(10)) | (c32[:, 2] << np.uint32(20))
    if flags is not None:
        f = np.asarray(flags)
        if f.shape != (c.shape[0],):
            raise ProtocolError(f"flags must have shape ({c.shape[0]},), got {f.shape}")
        if f.size and not np.issubdtype(f.dtype, np.integer):
            raise ProtocolError(f"flags must be integers, got dtype {f.dtype}")
        badf = (f < 0) | (f > 3)
        if badf.any():
            i = int(np.flatnonzero(badf)[0])
            raise ProtocolError(f"sample {i}: flag value {f[i]} outside 0..3")
        words |= f.astype(np.uint32) << np.uint32(30)
    return words.astype(np.uint32, copy=False)


def unpack_words(words: np.ndarray | bytes | bytearray | memoryview) -> tuple[np.ndarray, np.ndarray]:
    """Split P32 words into codes and flags.

    Parameters
    ----------
    words
        ``uint32`` array, or little-endian bytes (length a multiple of 4).

    Returns
    -------
    codes : numpy.ndarray
        ``(n, 3)`` ``uint16`` codes in counts (x, y, z).
    flags : numpy.ndarray
        ``(n,)`` ``uint8`` flag values 0 ... 3.

    Raises
    ------
    ProtocolError
        Byte input whose length is not a multiple of 4.

    Examples
    --------
    >>> c, f = unpack_words(np.array([0xFFFFFFFF], dtype=np.uint32))
    >>> c.tolist(), f.tolist()
    ([[1023, 1023, 1023]], [3])
    """
    if isinstance(words, (bytes, bytearray, memoryview)):
        w = bytes_to_words(words)
    else:
        w = np.asarray(words)
        if w.dtype != np.uint32:
            w = w.astype(np.uint32)
    w = w.astype(np.uint32, copy=False)  # native order for the shifts
    codes = np.empty((w.shape[0], 3), dtype=np.uint16)
    mask = np.uint32(CODE_MAX)
    codes[:, 0] = w & mask
    codes[:, 1] = (w >> np.uint32(10)) & mask
    codes[:, 2] = (w >> np.uint32(20)) & mask
    flags = (w >> np.uint32(30)).astype(np.uint8)
    return codes, flags


def words_to_bytes(words: np.ndarray) -> bytes:
    """Little-endian bytes of P32 words (4 per sample).

    >>> words_to_bytes(np.array([1, 0x80000000], dtype=np.uint32)).hex()
    '0100000000000080'
    """
    return np.asarray(words, dtype=np.uint32).astype(_LE_U32, copy=False).tobytes()


def bytes_to_words(data: bytes | bytearray | memoryview) -> np.ndarray:
    """P32 words from little-endian bytes (no copy for ``bytes`` input: the array is read-only).

    Raises
    ------
    ProtocolError
        A length that is not a multiple of 4.

    >>> bytes_to_words(b"\\x01\\x00\\x00\\x00").tolist()
    [1]
    >>> bytes_to_words(b"\\x01\\x00")
    Traceback (most recent call last):
    ...
    gaitlog.protocol.errors.ProtocolError: sample bytes: length 2 is not a multiple of 4
    """
    n = len(data)
    if n % 4:
        raise ProtocolError(f"sample bytes: length {n} is not a multiple of 4")
    return np.frombuffer(data, dtype=_LE_U32)
