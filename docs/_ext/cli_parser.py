"""The ``gaitlog`` argument parser as the CLI reference renders it.

sphinx-argparse reads help texts as reStructuredText, where a lone ``*`` (a file pattern such as
``*_truth.csv``) opens an emphasis; the help texts are plain text, so their ``*`` are escaped here, on a copy
built for the documentation only.
"""

from __future__ import annotations

import argparse

from gaitlog.host.cli import build_parser


def _escape(parser: argparse.ArgumentParser) -> None:
    for action in parser._actions:
        if action.help and action.help is not argparse.SUPPRESS:
            action.help = action.help.replace("*", r"\*")
        if isinstance(action.default, str):
            action.default = action.default.replace("*", r"\*")
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.help:
                    choice.help = choice.help.replace("*", r"\*")
            for sub in action.choices.values():
                _escape(sub)


def gaitlog_parser() -> argparse.ArgumentParser:
    """:func:`gaitlog.host.cli.build_parser`, help texts escaped for reStructuredText."""
    parser = build_parser()
    _escape(parser)
    return parser
