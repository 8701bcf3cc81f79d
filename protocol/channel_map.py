"""Channel map (``cal_format`` 2, ``PROTOCOL.md`` section 2.6): which analog input holds which instrument sensor.

A logger recording an instrument of single-axis sensors (Morris' accelerometer platform, Hall's angular-rate
sensors) samples up to the PIC16F877's 8 analog inputs AN0-AN7 each timer tick. The header's ``axes`` byte
then counts the channels sampled per tick (1-8) and the 64-byte calibration slot holds this map instead of
the three-axis affine calibration: per channel its analog input, its quantity, a sensor name of up to 4
ASCII characters and its full scale (the value at which the conditioned signal reaches the ADC's ends).
One tick is one *frame* of :func:`frame_words` consecutive P32 words (three 10-bit fields each, section 1):
channel ``i`` is field ``i mod 3`` of word ``i // 3``; unused fields are 0. ``sampling_rate_millihz`` is the
frame rate and the sample counters count words (slots), as for the three-axis logger.

Examples
--------
>>> m = ChannelMap((Channel(0, SPECIFIC_FORCE, "acc1", 5.0), Channel(1, ANGULAR_RATE, "A_x", 30.0)))
>>> raw = m.to_bytes()
>>> raw[:4].hex(), raw[4:11].hex(), raw[11:18].hex()
('02020000', '10616363318813', '21415f78003075')
>>> ChannelMap.from_bytes(raw).channels == m.channels
True
>>> m.values(np.array([[512, 1023], [0, 512]]), adc_bits=10).round(4).tolist()
[[0.0049, 29.9707], [-4.9951, 0.0293]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gaitlog.protocol.errors import ProtocolError

__all__ = [
    "CAL_FORMAT_CHANNEL_MAP",
    "MAX_CHANNELS",
    "CHANNEL_ENTRY_SIZE",
    "SPECIFIC_FORCE",
    "ANGULAR_RATE",
    "QUANTITY_UNITS",
    "Channel",
    "ChannelMap",
    "frame_words",
]

#: ``cal_format`` of a calibration slot holding a channel map.
CAL_FORMAT_CHANNEL_MAP = 2
#: Analog inputs of the PIC16F877 (AN0-AN7).
MAX_CHANNELS = 8
#: Bytes of one channel entry: input and quantity (1), name (4), full scale (2).
CHANNEL_ENTRY_SIZE = 7
_PREFIX = 4  # cal_format, n_channels, 2 reserved
_SLOT_SIZE = 64
#: Quantity codes of a channel.
SPECIFIC_FORCE, ANGULAR_RATE = 1, 2
#: quantity code -> (CSV unit suffix of ``gaitlog.host.kinematics.sensor_csv``, stored full-scale unit per count of
#: ``full_scale_milli``: the full scale is stored in thousandths of the unit: mg, mrad/s).
QUANTITY_UNITS: dict[int, str] = {SPECIFIC_FORCE: "g", ANGULAR_RATE: "rad_s"}


def frame_words(n_channels: int) -> int:
    """P32 words a frame of ``n_channels`` occupies: ``ceil(n / 3)`` (three 10-bit fields a word).

    >>> [frame_words(n) for n in (1, 3, 5, 6, 8)]
    [1, 1, 2, 2, 3]
    """
    return math.ceil(int(n_channels) / 3)


@dataclass(frozen=True)
class Channel:
    """One analog channel: input ``AN<analog_input>``, quantity (:data:`SPECIFIC_FORCE` in g,
    :data:`ANGULAR_RATE` in rad/s), sensor name (1-4 printable ASCII characters, the recording CSV's column
    ``<name>_<unit>``) and full scale in the quantity's unit (stored to 0.001, at most 65.535)."""

    analog_input: int
    quantity: int
    name: str
    full_scale: float

    @property
    def unit(self) -> str:
        """The column unit suffix (``g`` or ``rad_s``)."""
        return QUANTITY_UNITS[self.quantity]

    @property
    def column(self) -> str:
        """The recording CSV column name, ``<name>_<unit>``."""
        return f"{self.name}_{self.unit}"


@dataclass(frozen=True)
class ChannelMap:
    """The channels sampled each tick, in frame order (module notes)."""

    channels: tuple[Channel, ...]
    valid = False  # not an affine accelerometer calibration: the header's CAL_VALID flag stays clear

    def __post_init__(self) -> None:
        object.__setattr__(self, "channels", tuple(self.channels))
        self.check()

    @property
    def n_channels(self) -> int:
        """Channels per frame."""
        return len(self.channels)

    @property
    def frame_words(self) -> int:
        """P32 words per frame (:func:`frame_words`)."""
        return frame_words(self.n_channels)

    def check(self, source: str | None = None, base_offset: int = 0) -> None:
        """Every rule of section 2.6; :class:`ProtocolError` naming the channel and the byte offset."""
        n = len(self.channels)
        if not 1 <= n <= MAX_CHANNELS:
            raise ProtocolError(f"channel map: {n} channels (the PIC16F877 has {MAX_CHANNELS} analog inputs: 1..8)",
                                offset=base_offset + 1, source=source)
        seen_in, seen_name = set(), set()
        for i, c in enumerate(self.channels):
            at = base_offset + _PREFIX + CHANNEL_ENTRY_SIZE * i
            if not (isinstance(c.analog_input, int) and 0 <= c.analog_input < MAX_CHANNELS):
                raise ProtocolError(f"channel map: channel {i}: analog input {c.analog_input!r} is not AN0..AN7",
                                    offset=at, source=source)
            if c.analog_input in seen_in:
                raise ProtocolError(f"channel map: channel {i}: AN{c.analog_input} is sampled twice",
                                    offset=at, source=source)
            if c.quantity not in QUANTITY_UNITS:
                raise ProtocolError(f"channel map: channel {i}: unknown quantity {c.quantity!r} (1 specific force "
                                    "in g, 2 angular rate in rad/s)", offset=at, source=source)
            if not (isinstance(c.name, str) and 1 <= len(c.name) <= 4 and c.name.isascii() and c.name.isprintable()
                    and "," not in c.name and c.name.strip() == c.name):
                raise ProtocolError(f"channel map: channel {i}: name {c.name!r} is not 1-4 printable ASCII "
                                    "characters (no comma, no surrounding space)", offset=at + 1, source=source)
            if c.name in seen_name:
                raise ProtocolError(f"channel map: channel {i}: name {c.name!r} is used twice", offset=at + 1,
                                    source=source)
            if not (math.isfinite(c.full_scale) and 0.001 <= round(c.full_scale * 1000) / 1000 <= 65.535):
                raise ProtocolError(f"channel map: channel {i}: full scale {c.full_scale!r} outside 0.001..65.535",
                                    offset=at + 5, source=source)
            seen_in.add(c.analog_input)
            seen_name.add(c.name)

    def to_bytes(self) -> bytes:
        """The 64-byte calibration slot holding this map."""
        out = bytearray(_SLOT_SIZE)
        out[0], out[1] = CAL_FORMAT_CHANNEL_MAP, self.n_channels
        for i, c in enumerate(self.channels):
            at = _PREFIX + CHANNEL_ENTRY_SIZE * i
            out[at] = c.analog_input | (c.quantity << 4)
            out[at + 1: at + 5] = c.name.encode("ascii").ljust(4, b"\0")
            out[at + 5: at + 7] = int(round(c.full_scale * 1000)).to_bytes(2, "little")
        return bytes(out)

    @classmethod
    def from_bytes(cls, data: bytes, *, source: str | None = None, base_offset: int = 0) -> ChannelMap:
        """Parse a 64-byte slot of ``cal_format`` 2; :class:`ProtocolError` naming the byte."""
        if len(data) != _SLOT_SIZE or data[0] != CAL_FORMAT_CHANNEL_MAP:
            raise ProtocolError(f"channel map: expected a {_SLOT_SIZE}-byte slot of cal_format "
                                f"{CAL_FORMAT_CHANNEL_MAP}", offset=base_offset, source=source)
        n = data[1]
        if not 1 <= n <= MAX_CHANNELS:
            raise ProtocolError(f"channel map: {n} channels (the PIC16F877 has {MAX_CHANNELS} analog inputs: 1..8)",
                                offset=base_offset + 1, source=source)
        chans = []
        for i in range(n):
            at = _PREFIX + CHANNEL_ENTRY_SIZE * i
            e = data[at: at + CHANNEL_ENTRY_SIZE]
            name = e[1:5].rstrip(b"\0")
            try:
                text = name.decode("ascii")
            except UnicodeDecodeError:
                raise ProtocolError(f"channel map: channel {i}: name bytes {name.hex()} are not ASCII",
                                    offset=base_offset + at + 1, source=source) from None
            chans.append(Channel(e[0] & 0x0F, e[0] >> 4, text, int.from_bytes(e[5:7], "little") / 1000))
        m = cls.__new__(cls)
        object.__setattr__(m, "channels", tuple(chans))
        m.check(source, base_offset)
        return m

    def values(self, codes: np.ndarray, adc_bits: int) -> np.ndarray:
        """Physical values ``(n, n_channels)`` of codes ``(n, n_channels)``: ``(code + ½ − 2^(b−1)) · FS / 2^(b−1)``
        (the front end maps ±full scale onto the converter's span, zero at mid-scale; ``+ ½``: the middle of the
        code's interval, as the PIC's converter truncates)."""
        half = float(1 << (int(adc_bits) - 1))
        fs = np.array([c.full_scale for c in self.channels])
        return (np.asarray(codes, dtype=np.float64) + 0.5 - half) * (fs / half)

    def frames(self, codes: np.ndarray) -> np.ndarray:
        """Channel codes ``(m, n_channels)`` of ``(m · frame_words, 3)`` word fields (section 2.6)."""
        c = np.asarray(codes)
        w = self.frame_words
        if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] % w:
            raise ProtocolError(f"channel map: {c.shape[0]} words are not whole frames of {w}")
        return c.reshape(-1, 3 * w)[:, : self.n_channels]

    def words(self, channel_codes: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`frames`: ``(m, n_channels)`` codes as ``(m · frame_words, 3)`` word fields."""
        c = np.asarray(channel_codes)
        if c.ndim != 2 or c.shape[1] != self.n_channels:
            raise ProtocolError(f"channel map: codes of shape {c.shape}, expected (m, {self.n_channels})")
        out = np.zeros((c.shape[0], 3 * self.frame_words), dtype=c.dtype)
        out[:, : self.n_channels] = c
        return out.reshape(-1, 3)
