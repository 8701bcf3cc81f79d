"""Progress bars of the long commands (not a command: the underscore keeps it out of ``--help``): tqdm on stderr,
off with ``-q`` or when stderr is not a terminal."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator

from gaitlog.host.commands._options import verbosity

# The one import inside a function is tqdm (it loads importlib.metadata, ~40 ms):
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).


@contextlib.contextmanager
def progress_bar(args: argparse.Namespace, total: int, unit: str) -> Iterator[Callable[..., None] | None]:
    """Yield ``tick(*_)`` (one more ``unit`` done) or None when no bar is shown."""
    if verbosity(args) < 0 or not sys.stderr.isatty():
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=total, unit=unit, file=sys.stderr, leave=False) as bar:
        yield lambda *_: bar.update(1)
