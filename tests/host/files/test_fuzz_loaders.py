"""Fuzzing the frame, header, image, raw-dump, NPZ and JSON loaders under hypothesis: on any input they return or
raise a documented error (ProtocolError, HostError), nothing else. A few thousand examples here; the long job
(>= 10^6 inputs) is ``benchmarks/fuzz_loaders.py``, whose seeds, mutations and targets these tests share."""

from __future__ import annotations

import importlib.util
import random
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_SPEC = importlib.util.spec_from_file_location(
    "fuzz_loaders", Path(__file__).resolve().parents[3] / "benchmarks" / "fuzz_loaders.py")
fuzz = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(fuzz)

SEEDS = fuzz.seeds()
TARGETS = fuzz.targets()
_FAST = settings(max_examples=400, deadline=None, derandomize=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def test_every_seed_loads():
    """The seeds are valid: a mutation that is refused is refused because of the mutation."""
    for name, corpus in SEEDS.items():
        for data in corpus:
            assert fuzz.run_one(TARGETS[name], data) is None
            if name in ("header", "image", "raw", "capture", "npz"):
                TARGETS[name](data)  # no documented error either


@pytest.mark.parametrize("name", sorted(SEEDS))
@_FAST
@given(seed=st.integers(0, 2**32 - 1))
def test_mutated_inputs_raise_only_documented_errors(name, seed):
    data = fuzz.fuzz_input(name, SEEDS[name], random.Random(seed))
    exc = fuzz.run_one(TARGETS[name], data)
    assert exc is None, f"{type(exc).__name__}: {exc}; input {data[:64].hex()}"


@pytest.mark.parametrize("name", sorted(SEEDS))
@settings(max_examples=100, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.binary(max_size=2048))
def test_arbitrary_bytes_raise_only_documented_errors(name, data):
    exc = fuzz.run_one(TARGETS[name], data)
    assert exc is None, f"{type(exc).__name__}: {exc}"


def test_an_encrypted_zip_member_is_a_documented_error():
    """Found by the long job (3 in 10^6): zipfile raised RuntimeError for a member flagged as encrypted."""
    data = bytearray(SEEDS["npz"][0])
    central = data.find(b"PK\x01\x02")
    data[central + 8] |= 0x1                  # general purpose flag: encrypted
    assert fuzz.run_one(TARGETS["npz"], bytes(data)) is None
    with pytest.raises(fuzz.HostError, match="encrypted"):
        TARGETS["npz"](bytes(data))


def test_a_crash_is_caught_by_the_harness():
    """The harness can fail: an undocumented exception is reported."""
    def broken(data: bytes) -> None:
        raise IndexError("boom")

    assert isinstance(fuzz.run_one(broken, b""), IndexError)
