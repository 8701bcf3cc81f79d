"""Sphinx configuration of the gaitlog documentation (MyST Markdown pages, the CLI from the argument parser,
the API from the docstrings). Build: ``python -m sphinx -W -b html docs docs/_build/html``."""

from __future__ import annotations

import sys
from pathlib import Path

import gaitlog

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "gaitlog"
author = "the gaitlog developers"
copyright = "2026, the gaitlog developers"
release = gaitlog.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", ".venv"]
myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 3
# An attribute name (``valid``, ``sampling_rate_hz``) that several classes share is an ambiguous reference in
# the API pages; each page documents its own class's.
suppress_warnings = ["ref.python"]

autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
# "Attributes" sections as :ivar: fields: a documented property of the same name is then not a duplicate
napoleon_use_ivar = True

html_theme = "alabaster"
html_static_path = ["_static"]
html_title = f"gaitlog {release}"


def setup(app):
    """PROTOCOL.md labels its worked examples' fences (``example``, ``header-slot-example``,
    ``journal-ring-example``) for its tests: they are plain text to Sphinx."""
    from pygments.lexers.special import TextLexer

    for name in ("example", "header-slot-example", "journal-ring-example"):
        app.add_lexer(name, TextLexer)
