"""Write a file completely or not at all.

Every output file of the project (memory images, decoded CSV/NPZ, calibration JSON, reports) is written to a
temporary file in the destination directory and renamed over the destination only when writing succeeded, so
a crash or a bad input never leaves a partial or corrupted file behind.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb", **open_kwargs: object) -> Iterator[IO]:
    """Open a temporary file next to ``path``; rename it onto ``path`` when the block exits cleanly.

    Parameters
    ----------
    path
        Destination file.
    mode
        ``"wb"`` or ``"w"`` (text; pass ``encoding``/``newline`` in ``open_kwargs``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_write(d / "x.bin") as f:
    ...     _ = f.write(b"abc")
    >>> (d / "x.bin").read_bytes()
    b'abc'
    >>> try:
    ...     with atomic_write(d / "y.bin") as f:
    ...         _ = f.write(b"partial")
    ...         raise RuntimeError("boom")
    ... except RuntimeError:
    ...     pass
    >>> (d / "y.bin").exists(), sorted(p.name for p in d.iterdir())
    (False, ['x.bin'])
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_write mode must be 'wb' or 'w', not {mode!r}")
    dest = Path(path)
    require_folder(dest)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent or Path("."))
    try:
        os.chmod(tmp_name, _CREATE_MODE & ~_current_umask())  # mkstemp makes 0600; a plain open() honours umask
        with os.fdopen(fd, mode, **open_kwargs) as handle:  # type: ignore[call-overload]
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp_name, dest)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


#: Permissions a new file gets from ``open()`` before the umask is applied.
_CREATE_MODE = 0o666


def _current_umask() -> int:
    """The process umask (read by setting it and putting it back: the only portable way)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def require_folder(path: str | os.PathLike[str]) -> None:
    """Raise ``FileNotFoundError`` naming the folder when the folder that would hold ``path`` does not exist.

    Commands call it before long work so that a mistyped ``--out`` fails at once, not after the work.

    >>> require_folder("/no/such/folder/out.csv")
    Traceback (most recent call last):
    ...
    FileNotFoundError: cannot write /no/such/folder/out.csv: folder /no/such/folder does not exist
    """
    dest = Path(path)
    folder = dest.parent                                  # Path("x.csv").parent is Path(".")
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise FileNotFoundError(f"cannot write {dest}: folder {folder} {what}")


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_write(path, "wb") as handle:
        handle.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically (UTF-8, newlines as given)."""
    with atomic_write(path, "w", encoding=encoding, newline="") as handle:
        handle.write(text)
