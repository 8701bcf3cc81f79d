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


@pytest.fixture(scope="session")
def simulated_walk() -> tuple:
    """``(codes, subject)``: a simulated subject walking the paper's protocol, as the emulated logger stored
    it (10-bit codes at 50 Hz; the logger's default sensor unit)."""
    from firmware_sim.device import Logger
    from firmware_sim.world.subject import random_subjects
    from firmware_sim.world.walking import Walking

    subject = random_subjects(1, seed=3)[0]
    res = Logger(device_id=4).record(Walking(subject=subject, seed=3))
    return res.codes.astype("int64"), subject
