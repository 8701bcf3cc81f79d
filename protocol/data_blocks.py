"""DATA_BLOCKS payloads (``PROTOCOL.md`` section 4.1, protocol version 2): data checked per 64-sample block.

A DATA_BLOCKS payload is ``address`` (u32 LE), then the data cut into blocks of :data:`BLOCK_BYTES` (64 P32
samples; the last may be shorter), each followed by its ``check`` (u16 **BE**): CRC-16/UMTS over the
``binding`` (the header's ``header_crc``, u16 BE), the block's own address (u32 LE) and its bytes. A damaged
byte then costs its block only: the frame's CRC-16 fails, but every other block still verifies at its place,
and no block verifies at another address or under another header's memory state.

Examples
--------
>>> payload = blocks_payload(0x13D5, 0, bytes(range(12)))
>>> payload.hex(" ")
'00 00 00 00 00 01 02 03 04 05 06 07 08 09 0a 0b 9a 12'
>>> found = verified_blocks(0x13D5, payload)
>>> found.addresses.tolist(), found.data_bytes
([0], 12)
>>> verified_blocks(0x13D6, payload).addresses.tolist()  # another header: nothing verifies
[]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitlog.protocol.crc import crc16_umts_rows

__all__ = ["BLOCK_BYTES", "CHECK_BYTES", "ADDRESS_BYTES", "MAX_BLOCKS_DATA", "FoundBlocks", "header_binding",
           "block_checks", "blocks_payload", "payload_data_bytes", "verified_blocks", "salvage_blocks"]

#: Data bytes of one checked block: 64 P32 samples, as a chunk of the raw dump's check trailer (section 5.1).
BLOCK_BYTES = 256
#: Bytes of a block's check.
CHECK_BYTES = 2
#: Bytes of the payload's address field.
ADDRESS_BYTES = 4
#: Largest DUMP_BLOCKS ``chunk``: 64 blocks, so that 16 frames carry a full 262,144-byte memory.
MAX_BLOCKS_DATA = 64 * BLOCK_BYTES
_STRIDE = BLOCK_BYTES + CHECK_BYTES


def header_binding(header_bytes: bytes) -> int:
    """The ``binding`` of a header's memory state: its stored ``header_crc`` (bytes 254-255, BE)."""
    return int.from_bytes(bytes(header_bytes[254:256]), "big")


def _rows(binding: int, addresses: np.ndarray, blocks: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """``(n, 6 + 256)`` rows: binding, address, block bytes, left-padded with zeros (a CRC from 0 ignores them)."""
    n = addresses.size
    rows = np.zeros((n, 6 + BLOCK_BYTES), dtype=np.uint8)
    pad = BLOCK_BYTES - sizes
    head = np.zeros((n, 6), dtype=np.uint8)
    head[:, 0], head[:, 1] = binding >> 8, binding & 0xFF
    head[:, 2:] = addresses.astype("<u4").view(np.uint8).reshape(n, 4)
    full = pad == 0
    rows[full, :6] = head[full]
    rows[full, 6:] = blocks[full]
    for i in np.flatnonzero(~full).tolist():  # at most one short block per frame
        rows[i, pad[i]: pad[i] + 6] = head[i]
        rows[i, pad[i] + 6:] = blocks[i, : sizes[i]]
    return rows


def block_checks(binding: int, address: int, data: bytes) -> np.ndarray:
    """The ``check`` of each block of ``data`` sent at ``address`` (``uint16``, one per block).

    >>> [hex(c) for c in block_checks(0x13D5, 0, bytes(range(12)))]
    ['0x9a12']
    """
    raw = np.frombuffer(bytes(data), dtype=np.uint8)
    n = -(-raw.size // BLOCK_BYTES)
    padded = np.zeros(n * BLOCK_BYTES, dtype=np.uint8)
    padded[: raw.size] = raw
    sizes = np.full(n, BLOCK_BYTES, dtype=np.int64)
    if n and raw.size % BLOCK_BYTES:
        sizes[-1] = raw.size % BLOCK_BYTES
    addresses = int(address) + BLOCK_BYTES * np.arange(n, dtype=np.int64)
    return crc16_umts_rows(_rows(int(binding), addresses, padded.reshape(n, BLOCK_BYTES), sizes))


def blocks_payload(binding: int, address: int, data: bytes) -> bytes:
    """A DATA_BLOCKS payload: ``address``, then each block of ``data`` followed by its check (BE)."""
    data = bytes(data)
    checks = block_checks(binding, address, data).astype(">u2").tobytes()
    parts = [int(address).to_bytes(4, "little")]
    for k in range(len(checks) // CHECK_BYTES):
        parts += [data[k * BLOCK_BYTES: (k + 1) * BLOCK_BYTES], checks[2 * k: 2 * k + 2]]
    return b"".join(parts)


def payload_data_bytes(payload_bytes: int) -> int | None:
    """Data bytes a DATA_BLOCKS payload of ``payload_bytes`` carries (None: no payload has that length).

    >>> payload_data_bytes(4 + 258), payload_data_bytes(4 + 258 + 14), payload_data_bytes(4 + 258 + 2)
    (256, 268, None)
    """
    body = int(payload_bytes) - ADDRESS_BYTES
    if body < 0:
        return None
    full, rest = divmod(body, _STRIDE)
    if 0 < rest <= CHECK_BYTES:
        return None
    return full * BLOCK_BYTES + max(rest - CHECK_BYTES, 0)


@dataclass(frozen=True)
class FoundBlocks:
    """Blocks that verified: their memory addresses, sizes and bytes (concatenated in that order)."""

    addresses: np.ndarray
    sizes: np.ndarray
    data: bytes
    first_address: int = 0  #: the frame's address (of its block 0) the blocks verified under

    @property
    def data_bytes(self) -> int:
        return int(self.sizes.sum())

    def leading(self) -> FoundBlocks:
        """The blocks from the frame's block 0 up to the first that did not verify (alignment certain)."""
        expected = self.first_address + BLOCK_BYTES * np.arange(self.addresses.size)
        m = int(np.argmin(np.append(self.addresses == expected, False)))
        return FoundBlocks(self.addresses[:m], self.sizes[:m], self.data[: int(self.sizes[:m].sum())],
                           self.first_address)

    def pieces(self):
        """``(address, bytes)`` of each block."""
        ends = np.cumsum(self.sizes)
        return [(int(a), self.data[e - s: e]) for a, s, e in zip(self.addresses.tolist(), self.sizes.tolist(),
                                                                  ends.tolist())]


_NONE = FoundBlocks(np.zeros(0, np.int64), np.zeros(0, np.int64), b"")


def salvage_blocks(binding: int, body: bytes, addresses: list[int]) -> FoundBlocks:
    """The blocks of a (possibly damaged) DATA_BLOCKS payload body that verify under any candidate frame address.

    Parameters
    ----------
    binding
        The ``header_crc`` of the header the blocks must belong to.
    body
        The payload bytes after the address field, as received: blocks at ``258·k`` (the last block is what is
        left before the end, less its check).
    addresses
        Candidate memory addresses of the frame's first block (its address field, and what the frames around
        it imply). The frame's address is the one candidate under which most blocks verify (none when two
        tie); only the blocks that verify under it are kept, so a damaged block is never tried at another
        address. (Block addresses of one memory differ in their bits 8-23 only, a burst the CRC-16 always
        tells apart: an intact block verifies under its own address only.)
    """
    raw = np.frombuffer(bytes(body), dtype=np.uint8)
    full, rest = divmod(raw.size, _STRIDE)
    n = full + (rest > CHECK_BYTES)
    if n == 0 or not addresses:
        return _NONE
    sizes = np.full(n, BLOCK_BYTES, dtype=np.int64)
    if n > full:
        sizes[-1] = rest - CHECK_BYTES
    padded = np.zeros(n * _STRIDE, dtype=np.uint8)
    padded[: min(raw.size, padded.size)] = raw[: padded.size]  # 1 or 2 bytes after the last block: no block
    grid = padded.reshape(n, _STRIDE)
    blocks = grid[:, :BLOCK_BYTES]
    end = sizes.copy()
    stored = (grid[np.arange(n), end].astype(np.uint16) << 8) | grid[np.arange(n), end + 1]
    best, best_hits, tie = None, 0, False
    for base in dict.fromkeys(int(a) for a in addresses):
        if not 0 <= base <= 0xFFFFFFFF - n * BLOCK_BYTES:
            continue
        addr = base + BLOCK_BYTES * np.arange(n, dtype=np.int64)
        hit = crc16_umts_rows(_rows(int(binding), addr, blocks, sizes)) == stored
        if int(hit.sum()) > best_hits:
            best, best_hits, tie = (addr, hit), int(hit.sum()), False
        elif best_hits and int(hit.sum()) == best_hits:
            tie = True
    if best is None or tie:  # no candidate, or two that explain as many blocks: place nothing
        return _NONE
    where, ok = best
    if not ok.any():
        return _NONE
    data = b"".join(blocks[i, : sizes[i]].tobytes() for i in np.flatnonzero(ok).tolist())
    return FoundBlocks(where[ok], sizes[ok], data, int(where[0]))


def verified_blocks(binding: int, payload: bytes, address: int | None = None) -> FoundBlocks:
    """The blocks of a DATA_BLOCKS payload that verify at its address field (or at ``address``)."""
    payload = bytes(payload)
    if len(payload) < ADDRESS_BYTES:
        return _NONE
    base = int.from_bytes(payload[:ADDRESS_BYTES], "little") if address is None else int(address)
    return salvage_blocks(binding, payload[ADDRESS_BYTES:], [base])
