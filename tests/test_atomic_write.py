"""gaitlog.atomic_write: files appear whole or not at all, with the permissions a plain open() would give."""

from __future__ import annotations

import os
import stat
import sys

import pytest

from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permission bits")
@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_new_file_keeps_the_users_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        atomic_write_bytes(tmp_path / "a.bin", b"x")
        atomic_write_text(tmp_path / "b.txt", "x")
        with open(tmp_path / "plain.bin", "wb") as fh:  # the independent truth: what open() gives
            fh.write(b"x")
    finally:
        os.umask(old)
    expected = stat.S_IMODE((tmp_path / "plain.bin").stat().st_mode)
    assert expected == 0o666 & ~umask
    assert stat.S_IMODE((tmp_path / "a.bin").stat().st_mode) == expected
    assert stat.S_IMODE((tmp_path / "b.txt").stat().st_mode) == expected


def test_failed_write_leaves_nothing(tmp_path):
    from gaitlog.atomic_write import atomic_write

    with pytest.raises(RuntimeError), atomic_write(tmp_path / "y.bin") as fh:
        fh.write(b"partial")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
