"""XMODEM-1K/CRC bulk transfer of a raw dump (``PROTOCOL.md`` section 5), sans-I/O.

:class:`XmodemSender` is the device side as a pure state machine: feed it what the receiver sent, it returns
the bytes to send; the firmware emulator owns the UART and the clock. :func:`build_block` and
:func:`parse_block` are the block layout ``STX blk 255−blk data[1024] CRC-16/XMODEM (BE)``.

Examples
--------
>>> s = XmodemSender(b"hello")
>>> block = s.receive(CRC_REQUEST)
>>> block[:3].hex(" "), block[3:8], block[8:10].hex(), len(block), block[-2:].hex()
('02 01 fe', b'hello', '1a1a', 1029, 'b85a')
>>> s.receive(ACK), s.receive(ACK), s.done
(b'\\x04', b'', True)
"""

from __future__ import annotations

from gaitlog.protocol.crc import crc16_xmodem
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.steps import STEP_RECORD_SIZE

__all__ = [
    "SOH",
    "STX",
    "EOT",
    "ACK",
    "NAK",
    "CAN",
    "CRC_REQUEST",
    "BLOCK_1K",
    "BLOCK_128",
    "PAD",
    "MAX_RETRIES",
    "START_TIMEOUT_S",
    "ACK_TIMEOUT_S",
    "build_block",
    "parse_block",
    "XmodemSender",
]

SOH = b"\x01"
STX = b"\x02"
EOT = b"\x04"
ACK = b"\x06"
NAK = b"\x15"
CAN = b"\x18"
CRC_REQUEST = b"C"
BLOCK_1K = 1024
BLOCK_128 = 128
PAD = 0x1A
#: Retransmissions of one block (or of EOT) before the sender gives up with CAN CAN.
MAX_RETRIES = 10
#: How long the sender waits for the receiver's ``C``.
START_TIMEOUT_S = 60.0
#: Silence after a block (or EOT) that counts as a NAK.
ACK_TIMEOUT_S = 10.0


def build_block(blk: int, data: bytes) -> bytes:
    """One XMODEM-1K block: ``STX, blk mod 256, 255 − that, data padded to 1024 with 0x1A, CRC-16 (BE)``.

    Raises
    ------
    ProtocolError
        More than 1024 data bytes.

    Examples
    --------
    >>> b = build_block(256, b"\\x00" * 1024)
    >>> b[:3].hex(" "), b[-2:].hex(), len(b)
    ('02 00 ff', '0000', 1029)
    """
    if len(data) > BLOCK_1K:
        raise ProtocolError(f"XMODEM block data of {len(data)} bytes exceeds {BLOCK_1K}")
    payload = bytes(data) + bytes([PAD]) * (BLOCK_1K - len(data))
    n = int(blk) & 0xFF
    return b"".join((STX, bytes((n, 255 - n)), payload, crc16_xmodem(payload).to_bytes(2, "big")))


def parse_block(block: bytes, source: str | None = None) -> tuple[int, bytes]:
    """Check one CRC-mode block (``STX`` 1024 or ``SOH`` 128 data bytes); return ``(blk, data)``.

    The data keeps its 0x1A padding (XMODEM cannot tell padding from data).

    Raises
    ------
    ProtocolError
        Unknown start byte, wrong length, block-number complement mismatch or CRC mismatch (with offset).

    Examples
    --------
    >>> parse_block(build_block(3, b"abc"))[0]
    3
    >>> parse_block(build_block(3, b"abc")[:-1] + b"\\x00")
    Traceback (most recent call last):
    ...
    gaitlog.protocol.errors.ProtocolError: offset 1027 (0x403): XMODEM block 3: CRC mismatch (stored 0xd700, computed 0xd7c2)
    """
    if not block:
        raise ProtocolError("empty XMODEM block", offset=0, source=source)
    start = block[:1]
    size = {STX: BLOCK_1K, SOH: BLOCK_128}.get(start)
    if size is None:
        raise ProtocolError(f"XMODEM block starts with 0x{block[0]:02x} (expected STX 0x02 or SOH 0x01)",
                            offset=0, source=source)
    if len(block) != size + 5:
        raise ProtocolError(f"XMODEM block of {len(block)} bytes (expected {size + 5})", offset=len(block),
                            source=source)
    blk, inv = block[1], block[2]
    if blk + inv != 255:
        raise ProtocolError(f"XMODEM block number 0x{blk:02x} and complement 0x{inv:02x} disagree", offset=2,
                            source=source)
    data = bytes(block[3 : 3 + size])
    stored = int.from_bytes(block[3 + size :], "big")
    computed = crc16_xmodem(data)
    if stored != computed:
        raise ProtocolError(f"XMODEM block {blk}: CRC mismatch (stored 0x{stored:04x}, computed "
                            f"0x{computed:04x})", offset=3 + size, source=source)
    return blk, data


class XmodemSender:
    """The device's XMODEM-1K/CRC sender (section 5) as a sans-I/O state machine.

    Parameters
    ----------
    payload
        The bytes to send (normally :func:`raw_dump_bytes`); split into 1024-byte blocks, the last padded.
    max_retries
        Retransmissions of one block or of EOT before giving up (CAN CAN).
    start_timeout_s, ack_timeout_s
        Used only by :meth:`poll`: how long to wait for ``C``, and the silence after a block that counts as a
        NAK.

    Notes
    -----
    States: ``"wait_start"`` (until ``C``; a ``NAK`` start asks for checksum mode, which is refused with
    CAN CAN), ``"wait_ack"`` (a block is out: ACK sends the next block or EOT, NAK or a repeated ``C``
    before the first ACK resends it), ``"wait_eot_ack"`` (NAK resends EOT), then ``"done"`` or
    ``"failed"``. Two consecutive CAN from the receiver cancel. Bytes not meaningful in a state are ignored.
    """

    def __init__(self, payload: bytes, *, max_retries: int = MAX_RETRIES, start_timeout_s: float = START_TIMEOUT_S,
                 ack_timeout_s: float = ACK_TIMEOUT_S) -> None:
        self.payload = bytes(payload)
        self.max_retries = int(max_retries)
        self.start_timeout_s = float(start_timeout_s)
        self.ack_timeout_s = float(ack_timeout_s)
        self.n_blocks = -(-len(self.payload) // BLOCK_1K)
        self.state = "wait_start"
        self.block_index = 0  # 0-based index of the block in flight / next to send
        self.retries = 0
        self.retransmissions = 0  # total, for statistics
        self.failed: str | None = None
        self._last_can = False
        self._since_s: float | None = None  # time of entering the current wait (set by poll)

    @property
    def done(self) -> bool:
        """The receiver acknowledged EOT: the transfer is complete."""
        return self.state == "done"

    @property
    def finished(self) -> bool:
        """Done or failed: nothing more will be sent."""
        return self.state in ("done", "failed")

    @property
    def blocks_acked(self) -> int:
        """Blocks the receiver has acknowledged."""
        return self.n_blocks if self.state in ("wait_eot_ack", "done") else self.block_index

    def block(self, index: int) -> bytes:
        """Wire bytes of block ``index`` (0-based; XMODEM number ``index + 1``)."""
        return build_block(index + 1, self.payload[index * BLOCK_1K : (index + 1) * BLOCK_1K])

    def _next(self) -> bytes:
        self.retries = 0
        self._since_s = None
        if self.block_index < self.n_blocks:
            self.state = "wait_ack"
            return self.block(self.block_index)
        self.state = "wait_eot_ack"
        return EOT

    def _fail(self, reason: str) -> bytes:
        self.state = "failed"
        self.failed = reason
        return CAN + CAN

    def _resend(self) -> bytes:
        self.retries += 1
        self.retransmissions += 1
        self._since_s = None
        if self.retries > self.max_retries:
            what = f"block {self.block_index + 1}" if self.state == "wait_ack" else "EOT"
            return self._fail(f"{what} not acknowledged after {self.max_retries} retransmissions")
        return self.block(self.block_index) if self.state == "wait_ack" else EOT

    def receive(self, data: bytes) -> bytes:
        """Process bytes from the receiver; return the bytes to send (possibly empty)."""
        out: list[bytes] = []
        for byte in bytes(data):
            if self.finished:
                break
            ch = bytes((byte,))
            if ch == CAN:
                if self._last_can:
                    self.state = "failed"
                    self.failed = "cancelled by the receiver (CAN CAN)"
                    break
                self._last_can = True
                continue
            self._last_can = False
            if self.state == "wait_start":
                if ch == CRC_REQUEST:
                    out.append(self._next())
                elif ch == NAK:
                    out.append(self._fail("receiver asked for checksum mode (NAK); only CRC mode is offered"))
            elif self.state == "wait_ack":
                if ch == ACK:
                    self.block_index += 1
                    out.append(self._next())
                elif ch == NAK or (ch == CRC_REQUEST and self.block_index == 0):
                    out.append(self._resend())
            elif self.state == "wait_eot_ack":
                if ch == ACK:
                    self.state = "done"
                elif ch == NAK:
                    out.append(self._resend())
        return b"".join(out)

    def poll(self, now_s: float) -> bytes:
        """Apply the timeouts at time ``now_s`` (any monotonic clock); return bytes to send.

        The first call after a state change starts that state's clock.
        """
        if self.finished:
            return b""
        if self._since_s is None:
            self._since_s = now_s
            return b""
        waited = now_s - self._since_s
        if self.state == "wait_start" and waited > self.start_timeout_s:
            return self._fail(f"no 'C' from a receiver within {self.start_timeout_s:g} s")
        if self.state in ("wait_ack", "wait_eot_ack") and waited > self.ack_timeout_s:
            return self._resend()
        return b""
