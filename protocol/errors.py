"""The one exception base of the ``protocol`` package."""

from __future__ import annotations


class ProtocolError(Exception):
    """Bytes that do not follow ``PROTOCOL.md``.

    Parameters
    ----------
    message
        What was expected, what was found and, where useful, what to do.
    offset
        Byte offset of the problem in the stream or file, if known.
    source
        File name, port or other origin of the bytes, if known.
    """

    def __init__(self, message: str, *, offset: int | None = None, source: str | None = None) -> None:
        self.message = message
        self.offset = offset
        self.source = source
        super().__init__(str(self))

    def __str__(self) -> str:
        where = []
        if self.source is not None:
            where.append(str(self.source))
        if self.offset is not None:
            where.append(f"offset {self.offset} (0x{self.offset:x})")
        return (": ".join([", ".join(where), self.message])) if where else self.message

    def at(self, *, source: str | None = None, offset: int | None = None) -> "ProtocolError":
        """Return a copy that names the source and/or shifts the offset by a base."""
        new_offset = self.offset
        if offset is not None:
            new_offset = offset + (self.offset or 0)
        return type(self)(self.message, offset=new_offset, source=source or self.source)
