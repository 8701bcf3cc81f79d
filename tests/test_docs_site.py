"""The documentation site's own pieces that a build with ``-W`` does not check (CI builds it: ``.ci/run``)."""

from __future__ import annotations

import argparse
import importlib.util
import re
from pathlib import Path

from gaitlog.host.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: The folders at the repository's top and the packages they install as (pyproject's package-dir).
PACKAGE_FOLDERS = {"gaitlog": "gaitlog", "protocol": "gaitlog.protocol", "firmware_sim": "gaitlog.firmware_sim",
                   "host": "gaitlog.host"}


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


def _public_modules() -> set[str]:
    """Every module of the packages by its installed name, read from the folders (nothing imported), but the
    commands (documented as the CLI reference), ``__main__`` and private ``_name`` modules."""
    out = set()
    for folder, package in PACKAGE_FOLDERS.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            name = ".".join((package, *parts))
            if any(p.startswith("_") for p in parts) or name.startswith("gaitlog.host.commands."):
                continue
            out.add(name)
    return out


def test_the_api_reference_lists_every_public_module() -> None:
    """docs/api.md's autosummary names every module of gaitlog, gaitlog.protocol, gaitlog.firmware_sim and
    gaitlog.host (not gaitlog.host.commands.*, nor __main__), and nothing else: a new module needs its entry."""
    listed = re.findall(r"^ {3}(gaitlog[\w.]*)$", (DOCS / "api.md").read_text(encoding="utf-8"), re.M)
    assert len(listed) == len(set(listed)), "a module listed twice"
    modules = _public_modules()
    assert {"gaitlog", "gaitlog.units", "gaitlog.host.commands", "gaitlog.host.storage.versioned_json"} <= modules
    assert not any(m.startswith("gaitlog.host.commands.") or m.endswith("__main__") for m in modules)
    assert sorted(modules - set(listed)) == [], "modules missing from docs/api.md"
    assert sorted(set(listed) - modules) == [], "docs/api.md lists modules that do not exist"
