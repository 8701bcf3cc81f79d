"""The column-wise CSV writers give the cells the cell-by-cell writers they replaced gave, written by the
standard library's ``csv`` (read back with it, every row has the header's columns; text with commas, quotes or
line breaks survives)."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gaitlog.firmware_sim.algorithms.steps import columns_csv_text
from gaitlog.host.studies.compare import rows_csv_text


def cell_by_cell_columns(cols: dict[str, np.ndarray]) -> list[list[str]]:
    """The former ``columns_csv_text``, up to the joining: the oracle's rows of cells."""
    names = list(cols)
    arrays_ = [np.asarray(cols[n]) for n in names]
    n = arrays_[0].size if arrays_ else 0
    lines = [names]
    for i in range(n):
        cells = []
        for a in arrays_:
            x = a[i]
            if a.dtype == bool or np.issubdtype(a.dtype, np.integer):
                cells.append(str(int(x)))
            else:
                cells.append("" if not np.isfinite(x) else f"{float(x):.6g}")
        lines.append(cells)
    return lines


def cell_by_cell_rows(rows: list[dict], columns=None) -> list[list[str]]:
    """The former ``rows_csv_text``, up to the joining: the oracle's rows of cells."""
    if not rows:
        return []
    cols = list(columns) if columns is not None else list(rows[0])
    lines = [cols]
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c, "")
            if isinstance(v, float):
                cells.append("" if not math.isfinite(v) else f"{v:.6g}")
            else:
                cells.append(str(v))
        lines.append(cells)
    return lines


def read_back(text: str) -> list[list[str]]:
    """The rows of ``text`` as the ``csv`` module reads them (a row of no columns reads as ``[]``)."""
    assert text == "" or text.endswith("\n")
    return list(csv.reader(io.StringIO(text, newline="")))


FLOAT = st.floats(allow_nan=True, allow_infinity=True, width=64)
DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.uint16, np.uint64, np.bool_])


@st.composite
def column_tables(draw) -> dict[str, np.ndarray]:
    n = draw(st.integers(0, 40))
    k = draw(st.integers(0, 6))
    cols = {}
    for j in range(k):
        dtype = draw(DTYPES)
        if np.issubdtype(dtype, np.floating):
            elements = st.floats(allow_nan=True, allow_infinity=True, width=32 if dtype == np.float32 else 64)
        elif dtype == np.bool_:
            elements = st.booleans()
        else:
            info = np.iinfo(dtype)
            elements = st.integers(int(info.min), int(info.max))
        cols[f"c{j}_{np.dtype(dtype).name}"] = draw(arrays(dtype, n, elements=elements))
    return cols


@settings(max_examples=300, deadline=None)
@given(cols=column_tables())
def test_columns_csv_text_reads_back_as_the_cells(cols) -> None:
    assert read_back(columns_csv_text(cols)) == cell_by_cell_columns(cols)


VALUE = st.one_of(FLOAT, st.integers(-10**20, 10**20), st.booleans(), st.text(max_size=5),
                  FLOAT.map(np.float64), st.integers(-1000, 1000).map(np.int64), st.none())


@settings(max_examples=300, deadline=None)
@given(rows=st.lists(st.dictionaries(st.sampled_from("abcde"), VALUE, max_size=5), max_size=20),
       all_float=st.lists(FLOAT, max_size=20), columns=st.one_of(st.none(), st.lists(st.sampled_from("abcdef"))))
def test_rows_csv_text_reads_back_as_the_cells(rows, all_float, columns) -> None:
    for r, v in zip(rows, all_float, strict=False):
        r["f"] = v  # a column of floats only (the common case) beside mixed ones
    assert read_back(rows_csv_text(rows, columns)) == cell_by_cell_rows(rows, columns)


def test_text_with_commas_quotes_and_line_breaks_is_quoted() -> None:
    rows = [{"file": "a.glimg", "error": "bad header, version 9; expected 1, 2 or 3", "n": 1.5},
            {"file": 'b "x".glimg', "error": "two\nlines", "n": float("nan")}]
    text = rows_csv_text(rows)
    assert text.splitlines()[1] == 'a.glimg,"bad header, version 9; expected 1, 2 or 3",1.5'
    assert read_back(text) == [["file", "error", "n"], ["a.glimg", rows[0]["error"], "1.5"],
                               ['b "x".glimg', "two\nlines", ""]]


def test_known_table() -> None:
    text = columns_csv_text({"step": np.arange(3), "length_m": np.array([0.7123456789, np.nan, -np.inf]),
                             "ok": np.array([True, False, True])})
    assert text == "step,length_m,ok\n0,0.712346,1\n1,,0\n2,,1\n"


@settings(max_examples=300, deadline=None)
@given(names=st.lists(st.text(max_size=3), max_size=4),
       cells=st.lists(st.lists(st.one_of(st.text(max_size=4), st.sampled_from(["", ",", '"', "\r", "\n", "1.5"])),
                               min_size=3, max_size=3), max_size=4))
def test_csv_text_is_what_the_csv_module_writes(names, cells) -> None:
    from gaitlog.firmware_sim.algorithms.steps import csv_text

    cells = cells[:len(names)] + [["x"] * 3] * (len(names) - len(cells))     # one column per name
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    writer.writerows(zip(*cells))
    text = csv_text(names, cells)
    if "\r" not in buf.getvalue():
        assert text == buf.getvalue()                   # the fast path is the csv module's text, byte for byte
    assert read_back(text) == [list(names), *map(list, zip(*cells))] if names else True
