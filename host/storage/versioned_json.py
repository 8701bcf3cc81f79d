"""The one file format of calibration-type results: a JSON object tagged with its kind and format version.

Every such file holds ``"cal_type"`` (the schema name, e.g. ``"gaitlog.KCalibration"``) and
``"format_version"`` (``"major.minor"``) beside the result's own keys. :class:`VersionedJson` writes it
atomically (whole file or nothing, :func:`gaitlog.atomic_write.atomic_write_text`) and reads it back with
one-line errors naming the file and the key: not JSON, another kind of file, a version this gaitlog does
not read (newer: update gaitlog; older: redo the calibration), a bad field (the subclass's
:meth:`VersionedJson.fields_from_dict`).

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Offset(VersionedJson):
...     SCHEMA = "example.Offset"; FORMAT_VERSION = "1.0"; KIND = "offset"
...     offset_g: float
...     def fields_to_dict(self): return {"offset_g": self.offset_g}
...     @classmethod
...     def fields_from_dict(cls, data, *, source): return cls(float(data["offset_g"]))
>>> Offset.from_json(Offset(0.5).to_json())
Offset(offset_g=0.5)
>>> Offset.from_json('{"cal_type": "example.Offset", "format_version": "2.0", "offset_g": 1}', source="o.json")
Traceback (most recent call last):
...
gaitlog.host.errors.HostError: o.json: key 'format_version': this gaitlog reads version '1.0', the file has '2.0' (written by a newer gaitlog: update gaitlog)
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, ClassVar, Self

from gaitlog.atomic_write import atomic_write_text
from gaitlog.host.errors import HostError
from gaitlog.host.storage.limits import MAX_JSON_BYTES, check_file_size

__all__ = ["VersionedJson"]

#: The keys every versioned JSON file carries (the schema key keeps its historic name).
SCHEMA_KEY = "cal_type"
VERSION_KEY = "format_version"


def _version_tuple(version: object) -> tuple[int, ...] | None:
    """``"1.10"`` -> ``(1, 10)``; None when ``version`` is not dotted whole numbers."""
    if not isinstance(version, str):
        return None
    try:
        return tuple(int(part) for part in version.split("."))
    except ValueError:
        return None


class VersionedJson:
    """Base of results saved as versioned JSON (module notes).

    Subclasses set :attr:`SCHEMA`, :attr:`FORMAT_VERSION`, :attr:`KIND` (and :attr:`ERROR`, :attr:`REDO`
    when they differ) and implement :meth:`fields_to_dict` and :meth:`fields_from_dict`.
    """

    #: Schema name written as ``"cal_type"``.
    SCHEMA: ClassVar[str]
    #: Format version written and the only one read.
    FORMAT_VERSION: ClassVar[str]
    #: What the file holds, for messages ("K calibration").
    KIND: ClassVar[str]
    #: Error raised on a bad file (a :class:`HostError`).
    ERROR: ClassVar[type[HostError]] = HostError
    #: What to do about a file of an older version.
    REDO: ClassVar[str] = "redo the calibration with this gaitlog"

    # -- the subclass's part
    def fields_to_dict(self) -> dict[str, Any]:
        """The result's own keys (JSON-ready)."""
        raise NotImplementedError

    @classmethod
    def fields_from_dict(cls, data: dict[str, Any], *, source: str) -> Self:
        """Rebuild from the file's keys (the two tags removed); raise :attr:`ERROR` naming ``source`` and the key."""
        raise NotImplementedError

    # -- the shared part
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary: the two tags, then :meth:`fields_to_dict`."""
        return {SCHEMA_KEY: self.SCHEMA, VERSION_KEY: self.FORMAT_VERSION, **self.fields_to_dict()}

    def to_json(self) -> str:
        """The JSON text (indented, newline-terminated)."""
        return json.dumps(self.to_dict(), indent=2, allow_nan=True) + "\n"

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the JSON file atomically (whole file or nothing)."""
        atomic_write_text(path, self.to_json())

    @classmethod
    def from_dict(cls, data: object, *, source: str | None = None) -> Self:
        """Check the tags of ``data`` (a parsed file), then :meth:`fields_from_dict`."""
        where = source or f"<{cls.KIND}>"
        if not isinstance(data, dict):
            raise cls.ERROR(f"{where}: not a gaitlog {cls.KIND}: expected a JSON object, found {type(data).__name__}")
        if data.get(SCHEMA_KEY) != cls.SCHEMA:
            raise cls.ERROR(f"{where}: not a gaitlog {cls.KIND} (key {SCHEMA_KEY!r}: expected {cls.SCHEMA!r}, "
                            f"found {data.get(SCHEMA_KEY)!r})")
        version = data.get(VERSION_KEY)
        if version != cls.FORMAT_VERSION:
            found, reads = _version_tuple(version), _version_tuple(cls.FORMAT_VERSION)
            what = ("written by a newer gaitlog: update gaitlog" if found is not None and reads is not None
                    and found > reads else cls.REDO)
            raise cls.ERROR(f"{where}: key {VERSION_KEY!r}: this gaitlog reads version {cls.FORMAT_VERSION!r}, "
                            f"the file has {version!r} ({what})")
        fields = {k: v for k, v in data.items() if k not in (SCHEMA_KEY, VERSION_KEY)}
        try:
            return cls.fields_from_dict(fields, source=where)
        except HostError:
            raise
        except (TypeError, ValueError, KeyError, IndexError, OverflowError, RecursionError) as err:
            # a field of the right name but a shape or type the subclass did not foresee (ragged, nested)
            raise cls.ERROR(f"{where}: not a valid gaitlog {cls.KIND}: {type(err).__name__}: {err}") from None

    @classmethod
    def from_json(cls, text: str, *, source: str | None = None) -> Self:
        """Parse :meth:`to_json` text."""
        where = source or f"<{cls.KIND}>"
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise cls.ERROR(f"{where}: not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})") from err
        except RecursionError:
            raise cls.ERROR(f"{where}: not a gaitlog {cls.KIND}: JSON nested too deeply") from None
        return cls.from_dict(data, source=source)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a file written by :meth:`save`."""
        p = Path(path)
        if p.is_dir():
            raise cls.ERROR(f"{p}: is a folder, not a {cls.KIND} file")
        check_file_size(p, MAX_JSON_BYTES, f"a {cls.KIND} file")
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError as err:
            raise cls.ERROR(f"{p}: not a UTF-8 text file (a {cls.KIND} is JSON)") from err
        except OSError as err:
            raise cls.ERROR(f"{p}: cannot read {cls.KIND}: {err.strerror or err}") from err
        return cls.from_json(text, source=str(p))
