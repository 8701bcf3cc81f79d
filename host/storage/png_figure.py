"""A matplotlib figure as PNG: rendered to bytes, or written atomically (whole file or nothing).

The one place both figure modules (:mod:`gaitlog.host.studies.plots`, :mod:`gaitlog.host.kinematics.plots`) turn a
:class:`matplotlib.figure.Figure` into a file: no pyplot, no global backend.
"""

from __future__ import annotations

import io
import os

from matplotlib.figure import Figure

from gaitlog.atomic_write import atomic_write_bytes

__all__ = ["figure_png_bytes", "write_figure_png"]


def figure_png_bytes(fig: Figure, *, dpi: int) -> bytes:
    """``fig`` laid out (``tight_layout``) and rendered to PNG bytes at ``dpi``."""
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def write_figure_png(fig: Figure, path: str | os.PathLike[str], *, dpi: int) -> None:
    """Write ``fig`` to ``path`` as PNG, atomically (:func:`gaitlog.atomic_write.atomic_write_bytes`)."""
    atomic_write_bytes(path, figure_png_bytes(fig, dpi=dpi))
