"""Byte layout of the construct declarations: where each named field lies.

The structs of :mod:`gaitlog.protocol.header`, :mod:`gaitlog.protocol.steps` and :mod:`gaitlog.protocol.frames` *are* the formats;
the offsets the spec's tables print, error messages name and the numpy paths index are read from them here,
never typed again.
"""

from __future__ import annotations

import construct as cs

__all__ = ["named_fields", "field_offsets"]


def named_fields(struct: cs.Struct) -> list[tuple[str, int, cs.Construct]]:
    """``(name, offset, subcon)`` of the named fields of ``struct``, in order, up to and including the first
    field of variable size (whose offset is known, not what follows it).

    >>> named_fields(cs.Struct("a" / cs.Int16ul, cs.Padding(1), "b" / cs.Int8ul))[1][:2]
    ('b', 3)
    """
    out, pos = [], 0
    for sc in struct.subcons:
        if sc.name is not None:
            out.append((sc.name, pos, sc.subcon if isinstance(sc, cs.Renamed) else sc))
        try:
            pos += sc.sizeof()
        except cs.SizeofError:
            break
    return out


def field_offsets(struct: cs.Struct) -> dict[str, tuple[int, int]]:
    """Field name -> ``(offset, size)`` in bytes of a fixed-size ``struct``.

    >>> field_offsets(cs.Struct("a" / cs.Int16ul, cs.Padding(1), "b" / cs.Int32ub))
    {'a': (0, 2), 'b': (3, 4)}
    """
    return {name: (off, sc.sizeof()) for name, off, sc in named_fields(struct)}
