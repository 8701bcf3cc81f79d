"""The PIC16 assembly kernels (``firmware_sim/pic``) executed in gpsim: bit for bit ``fixedpoint.py``, and the
cycle table ``fixedpoint.CYCLES`` reads is the one these runs measure.

Needs gputils (``gpasm``) and gpsim (Debian packages, installed by ``.ci/run``); skipped with the reason
otherwise.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gaitlog.firmware_sim.fixedpoint import CYCLES, MEASURED_CYCLES
from gaitlog.firmware_sim.pic.gpsim_bench import (
    DEFAULT_RANDOM,
    KERNELS,
    TABLE_RULES,
    assemble,
    cycle_table,
    gpsim_version,
    markdown_table,
    measure,
    missing_tools,
    run_kernel,
    vectors,
)

needs_gpsim = pytest.mark.skipif(missing_tools() is not None, reason=f"gpsim kernels: {missing_tools()}")
DOC = Path(__file__).resolve().parents[2] / "docs" / "FIXED_POINT.md"


@pytest.fixture(scope="module")
def measured() -> tuple[dict, int]:
    return measure(DEFAULT_RANDOM)


@pytest.fixture(scope="module")
def runs(measured: tuple[dict, int]) -> dict:
    return measured[0]


@needs_gpsim
@pytest.mark.parametrize("name", list(KERNELS))
def test_kernel_is_bit_exact_with_fixedpoint(runs: dict, name: str) -> None:
    run = runs[name]
    assert len(run.operands) == len(vectors(name, 0)) + DEFAULT_RANDOM >= 10_000 + 25   # edge cases + random
    assert run.mismatches == []                             # results and the saturation / div-by-zero flags
    assert run.cycles.min() > 0 and run.cycles.size == len(run.operands)


def test_the_edge_cases_are_in_the_vectors() -> None:
    div_s = set(vectors("div32s", 0))
    assert {(-(1 << 31), -1), ((1 << 31) - 1, 0), (-(1 << 31), 0), (-5, 2), (-3, -2)} <= div_s
    assert {(-(1 << 31), -1), (-3, 2), (3, -2), (-1, -2)} <= set(vectors("divr32s", 0))      # ties both ways
    assert {(-1, 1), (-3, 1), ((1 << 31) - 1, 1), (-(1 << 31), 31)} <= set(vectors("shr32r", 0))
    assert {(65535 * 65535 + 65535,), ((1 << 32) - 1,)} <= set(vectors("isqrt32n", 0))
    assert {(-32768, -32768), (32767, -32768)} <= set(vectors("mul16s", 0))


@needs_gpsim
def test_the_flags_are_exercised(runs: dict) -> None:
    """Saturations and divisions by zero happen in the vectors, and the PIC flags them as fixedpoint counts."""
    for name, flag in (("div32s", 2), ("div32s", 1), ("divr32u", 2), ("sat16", 1)):
        assert sum(1 for o in runs[name].outputs if o[-1] & flag) >= 5


@needs_gpsim
def test_a_wrong_kernel_is_caught(tmp_path: Path) -> None:
    """The floor shift's code checked against the half-up definition: the comparison must fail."""
    cod = assemble(tmp_path)
    wrong = dataclasses.replace(KERNELS["shr32r"], select=KERNELS["shr32"].select, name="shr32")
    run = run_kernel(wrong, vectors("shr32r", 200), cod)
    assert len(run.mismatches) > 100


@needs_gpsim
def test_the_cycle_table_is_the_measured_one(runs: dict, measured: tuple[dict, int]) -> None:
    table = cycle_table(runs, gpsim_version(), measured[1])
    for key in ("cycles", "cycles_mean", "kernels", "kernel_program_words"):    # regenerate:
        assert table[key] == MEASURED_CYCLES[key]                                # gaitlog budget --measure-kernels
    for key in TABLE_RULES:
        assert CYCLES[key] == table["cycles"][key]
    # the cost model: a shift of s bits costs s per-bit figures (plus the rounding add) as the kernel does
    by_s = {}
    for ops, c in zip(runs["shr32"].operands, runs["shr32"].cycles.tolist()):
        by_s[ops[1]] = c
    assert by_s[31] - by_s[1] == 30 * CYCLES["shift32_per_bit"]


def test_the_doc_shows_the_measured_table_beside_the_cited_one() -> None:
    """docs/FIXED_POINT.md carries the table ``gaitlog budget --measure-kernels`` prints (no gpsim needed)."""
    assert markdown_table(MEASURED_CYCLES) in DOC.read_text(encoding="utf-8")
