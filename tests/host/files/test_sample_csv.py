"""The sample CSV of ``gaitlog decode``, formatted by numpy (:func:`int_csv_cells`, :func:`fixed_csv_cells` put
together by :func:`csv_text`), is byte for byte what the former writer gave cell by cell with Python's ``str`` and
``format``: on a real recording replayed through the emulated logger (with its missing samples) and on edge values
(negative and zero g, the largest codes, NaN and infinite g, missing rows, sample numbers past 2^32, exact halves)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.algorithms.steps import csv_text, fixed_csv_cells, int_csv_cells
from gaitlog.host.cli import main
from gaitlog.host.files.decode import decode_file
from gaitlog.host.files.recording import CSV_COLUMNS, Recording


def former_sample_csv(rec: Recording, cal) -> str:
    """The writer :meth:`Recording.to_csv` had before, cell by cell (the oracle): ``str`` of the integers,
    ``{:.4f}`` of the time, ``{:.6f}`` of g, counts, g and flags empty on a missing row."""
    g = np.asarray(cal.apply(rec.codes.astype(np.float64)), dtype=np.float64).reshape(-1, 3)
    lines = [",".join(CSV_COLUMNS)]
    for i in range(rec.n_samples):
        ok = bool(rec.valid[i])
        cells = [str(int(rec.sample_numbers[i])), "{:.4f}".format(float(rec.sample_numbers[i] / rec.sampling_rate_hz))]
        cells += [str(int(c)) if ok else "" for c in rec.codes[i]]
        cells += ["{:.6f}".format(float(v)) if ok else "" for v in g[i]]
        cells += [str(int(rec.flags[i])) if ok else "", "1" if ok else "0"]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


class _Affine:
    """A counts-to-g map given by its outputs: ``apply`` returns ``g`` whatever the codes (edge values of g)."""

    def __init__(self, g: np.ndarray) -> None:
        self.g = g

    def apply(self, codes: np.ndarray) -> np.ndarray:
        assert codes.shape == self.g.shape
        return self.g


def test_real_recording_replayed_through_the_logger(shared_data: Path, tmp_path: Path) -> None:
    trial = shared_data / "ipol-lowerback-dev" / "GaitData" / "1-1_lb.txt"
    image = tmp_path / "t.glimg"
    assert main(["record", "--motion", "replay", str(trial), "--out", str(image), "-q"]) == 0
    damaged = bytearray(image.read_bytes())
    damaged[3000] ^= 0xFF                   # a byte of a used block damaged: its 256 samples are missing rows
    image.write_bytes(bytes(damaged))
    assert main(["decode", str(image), "--out", str(tmp_path / "t"), "-q", "--max-missing", "100"]) == 0
    rec = decode_file(tmp_path / "t.glimg")
    assert 0 < int((~rec.valid).sum()) < rec.n_samples
    written = (tmp_path / "t.csv").read_bytes()
    assert written == former_sample_csv(rec, rec.default_calibration()[0]).encode()


def test_edge_values() -> None:
    n = 12
    codes = np.array([[0, 0, 0], [1023, 1023, 1023], [65535, 0, 65535], [512, 511, 513]] * 3, dtype=np.uint16)
    valid = np.array([True, True, True, False] * 3)
    flags = np.array([0, 3, 255, 7] * 3, dtype=np.uint8)
    g = np.array([[0.0, -0.0, -1e-9], [-2.0, 2.0, 1 / 128], [np.nan, np.inf, -np.inf], [1.0, 1.0, 1.0],
                  [1e17, -1e17, 2.5e-7], [0.0000005, -0.0000015, 0.9999995], [123456.7890125, -3.25, 7.0],
                  [1.0, 2.0, 3.0], [5e-324, -5e-324, 1e-300], [1e300, 4503599627.370496, 4503599627.3704965],
                  [-0.0078125, 0.0234375, 0.1], [0.3, 0.7, -0.2]])
    sample_numbers = np.array([0, 1, 2, 3, 2**32 - 1, 2**32, 2**40 + 5, 10**15, 17, 18, 19, 20], dtype=np.int64)
    for rate_hz in (50.0, 64.0, 3.0, 1000.0):
        rec = Recording(codes=codes, valid=valid, flags=flags, sample_numbers=sample_numbers, sampling_rate_hz=rate_hz)
        cal = _Affine(g)
        assert rec._csv_rows(cal, 0, n) == former_sample_csv(rec, cal)


def test_no_rows_and_all_missing(tmp_path: Path) -> None:
    for n, ok in ((0, True), (5, False)):
        rec = Recording(codes=np.zeros((n, 3), np.uint16), valid=np.full(n, ok), flags=np.zeros(n, np.uint8),
                        sample_numbers=np.arange(n, dtype=np.int64) + 100, sampling_rate_hz=50.0)
        rec.to_csv(tmp_path / "x.csv")
        assert (tmp_path / "x.csv").read_text() == former_sample_csv(rec, rec.default_calibration()[0])


def _texts(chars: np.ndarray) -> list[str]:
    return [bytes(row).replace(b"\0", b"").decode() for row in chars]


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), max_size=30),
       decimals=st.integers(0, 15))
def test_fixed_cells_are_pythons_format(values, decimals) -> None:
    a = np.array(values, dtype=np.float64)
    assert _texts(fixed_csv_cells(a, decimals)) == [format(v, f".{decimals}f") for v in values]


@settings(max_examples=300, deadline=None)
@given(numerators=st.lists(st.integers(-2**40, 2**40), min_size=1, max_size=30), shift=st.integers(0, 30),
       decimals=st.integers(0, 15))
def test_fixed_cells_of_dyadic_values_round_their_halves_as_python(numerators, shift, decimals) -> None:
    """k / 2^s lands on an exact half of the last digit often: half to even of the exact value, as Python."""
    values = [math.ldexp(k, -shift) for k in numerators]
    assert _texts(fixed_csv_cells(np.array(values), decimals)) == [format(v, f".{decimals}f") for v in values]


@settings(max_examples=200, deadline=None)
@given(kind=st.sampled_from([np.int64, np.int32, np.int16, np.int8, np.uint64, np.uint32, np.uint16, np.uint8,
                             np.bool_]), data=st.data())
def test_int_cells_are_str(kind, data) -> None:
    if kind is np.bool_:
        values = data.draw(st.lists(st.booleans(), max_size=20))
    else:
        info = np.iinfo(kind)
        values = data.draw(st.lists(st.integers(int(info.min), int(info.max)), max_size=20))
    a = np.array(values, dtype=kind)
    defined = np.array(data.draw(st.lists(st.booleans(), min_size=len(values), max_size=len(values))), dtype=bool)
    assert _texts(int_csv_cells(a, defined)) == [str(int(v)) if ok else "" for v, ok in zip(values, defined)]


def test_csv_text_of_matrices_and_cells_mixed_or_quoted() -> None:
    """A character matrix beside text cells, or a single column, goes through the general writer: the same text."""
    numbers = int_csv_cells(np.array([1, -2, 30]))
    assert csv_text(["n", "note"], [numbers, ["a", "b, c", ""]]) == 'n,note\n1,a\n-2,"b, c"\n30,\n'
    assert csv_text(["n"], [int_csv_cells(np.array([1, 2]), np.array([True, False]))]) == 'n\n1\n""\n'
    assert csv_text(["n", "m"], [numbers, numbers]) == "n,m\n1,1\n-2,-2\n30,30\n"
    assert csv_text(["n", "m"], [numbers[:0], numbers[:0]]) == "n,m\n"
    text = np.frombuffer(b'\0a,b"c d', np.uint8).reshape(1, -1)             # a comma, a quote, a space
    assert csv_text(["t", "n"], [text, numbers[:1]]) == 't,n\n"a,b""c d",1\n'
