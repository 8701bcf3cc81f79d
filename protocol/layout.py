"""Byte layout of the construct declarations: where each named field lies, and when a declaration is compiled.

The structs of :mod:`gaitlog.protocol.header`, :mod:`gaitlog.protocol.steps` and :mod:`gaitlog.protocol.frames` *are* the formats;
the offsets the spec's tables print, error messages name and the numpy paths index are read from them here,
never typed again. :class:`CompiledOnReuse` runs a declaration interpreted until it is used often enough to be
worth compiling.
"""

from __future__ import annotations

import construct as cs

__all__ = ["COMPILE_AFTER_USES", "CompiledOnReuse", "named_fields", "field_offsets"]

#: Calls of a :class:`CompiledOnReuse` declaration run by construct's interpreter before it is compiled.
COMPILE_AFTER_USES = 32


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


class CompiledOnReuse:
    """The ``parse`` and ``build`` of a construct declaration, run by construct's interpreter for its first
    :data:`COMPILE_AFTER_USES` calls and by its compiled code (``Struct.compile()``) from then on.

    Compiling one of the protocol's blocks costs about 1 ms, some 20-30 interpreted parses of it (and the
    interpreted parse of a header takes as long as the compiled one, 0.05 ms): a process that reads one header
    (``gaitlog estimate`` of a decoded file) never pays it, one that builds thousands (the emulated device) soon
    runs the compiled code. Both give the same values and bytes (``tests/protocol/test_layout.py``).

    >>> block = CompiledOnReuse(cs.Struct("a" / cs.Int16ul, "b" / cs.Int8ul))
    >>> [block.parse(b"\\x01\\x02\\x03").b for _ in range(COMPILE_AFTER_USES + 1)][-1], block.compiled
    (3, True)
    """

    def __init__(self, struct: cs.Construct) -> None:
        self.struct = struct
        self._compiled: cs.Construct | None = None
        self._uses = 0

    @property
    def compiled(self) -> bool:
        """Whether the calls now run the compiled code."""
        return self._compiled is not None

    def _runner(self) -> cs.Construct:
        if self._compiled is None:
            self._uses += 1
            if self._uses <= COMPILE_AFTER_USES:
                return self.struct
            self._compiled = self.struct.compile()
        return self._compiled

    def parse(self, data: bytes, **context: object) -> cs.Container:
        """``struct.parse(data)``."""
        return self._runner().parse(data, **context)

    def build(self, obj: object, **context: object) -> bytes:
        """``struct.build(obj)``."""
        return self._runner().build(obj, **context)
