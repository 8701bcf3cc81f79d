"""The documentation site's own pieces that a build with ``-W`` does not check (CI builds it: ``.ci/run``)."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from gaitlog.host.cli import build_parser

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _cli_parser_module():
    spec = importlib.util.spec_from_file_location("cli_parser", DOCS / "_ext" / "cli_parser.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += [prefix + (name,), *_commands(sub, prefix + (name,))]
    return out


def test_the_cli_reference_renders_every_command() -> None:
    """docs/cli.md renders the parser of docs/_ext/cli_parser.py: the same commands and subcommands as
    ``gaitlog``, with the help texts' ``*`` escaped for reStructuredText."""
    assert ":func: gaitlog_parser" in (DOCS / "cli.md").read_text(encoding="utf-8")
    shown = _cli_parser_module().gaitlog_parser()
    assert _commands(shown) == _commands(build_parser())
    assert len(_commands(shown)) >= 18
    kinematics = next(a for a in shown._actions if isinstance(a, argparse._SubParsersAction)).choices["kinematics"]
    helps = [a.help for a in kinematics._actions if a.help and "*" in a.help]
    assert helps and all("\\*" in h for h in helps)


def test_the_topics_folder_is_globbed() -> None:
    """Pages added under docs/topics/ appear without editing the index."""
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    assert ":glob:" in index and "topics/*" in index
    assert (DOCS / "topics" / "cache.md").is_file()
