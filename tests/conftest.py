"""Shared test fixtures: paths to the real recordings in ``../shared/data`` (tests skip when absent)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: Root of the real recordings; override with GAITLOG_DATA_DIR.
DATA_DIR = Path(os.environ.get("GAITLOG_DATA_DIR", Path(__file__).resolve().parents[1].parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The ``shared/data`` folder; the test is skipped with a reason when it is absent."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real recordings not found at {DATA_DIR} (set GAITLOG_DATA_DIR)")
    return DATA_DIR
