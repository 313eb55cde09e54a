"""Fuzzing the CSV reader (``read_csv`` and ``load``): mutated valid files, random bytes,
random cells. See ``tests/fuzz`` for the rules every input must follow."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from hystdisc.data import CANONICAL_COLUMNS, EXPERIMENTS, MIN_SAMPLES, Dataset, load, read_csv
from hystdisc.registry import get_experiment

from ..fuzz import BAD_CELLS, attempt, check_dataset, fmt, fuzz_settings
from ..fuzz.text import CSV_OPS, TEXT_OPS, apply_row_ops, apply_text_ops

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


#: operations that leave the meaning of the file unchanged
BENIGN = {
    "bom",
    "crlf",
    "cr",
    "blank_lines",
    "comment",
    "no_final_newline",
    "upper_header",
    "spaces",
}


_RUN_IDS = st.lists(
    st.text(st.characters(categories=["L", "N"], codec="utf-8"), min_size=1, max_size=4),
    min_size=3,
    max_size=3,
    unique=True,
)


@st.composite
def csv_documents(draw):
    """A valid long CSV (with its expected content) and a list of mutations."""
    experiment = draw(st.sampled_from(EXPERIMENTS))
    n_runs = draw(st.integers(1, 3))
    n = draw(st.integers(MIN_SAMPLES, 40))
    fs = draw(st.sampled_from([100.0, 1000.0, 2048.0, 3.0]))
    with_dot = draw(st.booleans())
    with_run = n_runs > 1 or draw(st.booleans())
    run_ids = draw(_RUN_IDS)[:n_runs]
    assume(len(run_ids) == n_runs)
    if not with_run:
        run_ids = ["0"]
    cols = ["run"] if with_run else []
    cols += ["t", "theta", "current"]
    extra = get_experiment(experiment).extra_column
    if extra:
        cols.append(extra)
    if with_dot:
        cols.append("theta_dot")
    order = draw(st.permutations(cols))
    delim = draw(st.sampled_from([",", ";", "\t", " "]))
    expected = []
    rows = []
    for r, rid in enumerate(run_ids):
        k = np.arange(n)
        t = k / fs
        theta = 0.3 * np.cos(0.7 * k + r) * np.exp(-0.01 * k) + 1e-3 * np.sin(3.1 * k)
        cur = 0.5 * r
        sig = {
            "run": [rid] * n,
            "t": [fmt(v) for v in t],
            "theta": [fmt(v) for v in theta],
            "current": [fmt(cur)] * n,
            "torque": [fmt(v) for v in np.sin(0.3 * k + r)],
            "input": [fmt(v) for v in np.cos(0.2 * k - r)],
            "theta_dot": [fmt(v) for v in np.sin(0.5 * k)],
        }
        expected.append((rid.strip(), cur, [float(x) for x in sig["theta"]]))
        rows += [[sig[c][i] for c in order] for i in range(n)]
    ops = draw(st.lists(CSV_OPS, max_size=3))
    text_ops = draw(st.lists(TEXT_OPS, max_size=3))
    return {
        "experiment": experiment,
        "header": list(order),
        "rows": rows,
        "delim": delim,
        "ops": ops,
        "text_ops": text_ops,
        "expected": expected,
    }


def _serialize(header, rows, delim: str, quote_all: bool = False) -> str:
    if delim == " ":
        return "\n".join(" ".join(r) for r in [header, *rows]) + "\n"
    buf = io.StringIO()
    w = csv.writer(
        buf,
        delimiter=delim,
        lineterminator="\n",
        quoting=csv.QUOTE_ALL if quote_all else csv.QUOTE_MINIMAL,
    )
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def _check_same(ds: Dataset, doc) -> None:
    """A benign mutation must load to exactly the file's content."""
    assert ds.experiment == doc["experiment"]
    assert len(ds.runs) == len(doc["expected"])
    for r, (name, cur, theta) in zip(ds.runs, doc["expected"], strict=True):
        assert r.name == name
        assert r.current == cur
        assert r.theta.tolist() == theta


@fuzz_settings(500)
@given(doc=csv_documents())
def test_fuzz_csv_mutations(work, doc):
    header, rows = list(doc["header"]), [list(r) for r in doc["rows"]]
    apply_row_ops(header, rows, doc["ops"])
    # csv quoting of every cell is harmless, except for whitespace tables (no quoting there)
    quote_cells = any(op[0] == "quote_cells" for op in doc["text_ops"])
    text = _serialize(header, rows, doc["delim"], quote_all=quote_cells and doc["delim"] != " ")
    data = apply_text_ops(text, doc["delim"], doc["text_ops"])
    path = work / "fuzz.csv"
    path.write_bytes(data)
    via_load = len(data) % 2 == 0
    ds = attempt("csv", load if via_load else read_csv, path)
    if ds is not None:
        check_dataset(ds)
    kinds = {op[0] for op in doc["ops"]} | {op[0] for op in doc["text_ops"]}
    if kinds <= BENIGN | {"quote_cells"} and not (quote_cells and doc["delim"] == " "):
        assert ds is not None, f"harmless changes {doc['text_ops']} must load: {data[:80]!r}"
        _check_same(ds, doc)
    extra = get_experiment(doc["experiment"]).extra_column
    needed = {"t", "theta", "current"} | ({extra} if extra else set())
    untouched = not doc["text_ops"] and not any(op[0] == "drop_rows" for op in doc["ops"])
    for op in doc["ops"]:
        if op[0] == "ragged" and untouched:
            assert ds is None, "a ragged row must be an error"
        if op[0] == "cell" and op[3] in ("", "nan", "inf", "abc", "1e400", "None"):
            col = doc["header"][op[2] % len(doc["header"])]
            if col in needed and len(doc["ops"]) == 1 and not doc["text_ops"]:
                assert ds is None, f"a bad cell {op[3]!r} in column {col!r} must be an error"


@fuzz_settings(300)
@given(data=st.binary(max_size=600))
def test_fuzz_csv_random_bytes(work, data):
    path = work / "bytes.csv"
    path.write_bytes(data)
    ds = attempt("csv", read_csv, path)
    if ds is not None:
        check_dataset(ds)


_HEADERS = st.lists(
    st.sampled_from([*CANONICAL_COLUMNS, "Theta", "T", "time", "x", ""]), min_size=1, max_size=6
)
_CELLS = st.one_of(
    st.sampled_from(BAD_CELLS),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.text(max_size=4),
)


@fuzz_settings(250)
@given(
    header=_HEADERS,
    cells=st.lists(st.lists(_CELLS, min_size=0, max_size=7), min_size=0, max_size=30),
    delim=st.sampled_from([",", ";", "\t", " ", "|"]),
    columns=st.none()
    | st.dictionaries(
        st.sampled_from(CANONICAL_COLUMNS),
        st.integers(0, 7) | st.sampled_from(["x", "T", "theta"]),
        max_size=2,
    ),
    units=st.none()
    | st.dictionaries(
        st.sampled_from(["t", "theta", "torque", "current", "z"]),
        st.sampled_from(["deg", "mm", "ms", "kN", "mA", "parsec", ""]),
        max_size=2,
    ),
    experiment=st.none() | st.sampled_from([*EXPERIMENTS, "bogus"]),
)
def test_fuzz_csv_random_cells(work, header, cells, delim, columns, units, experiment):
    text = delim.join(header) + "\n" + "\n".join(delim.join(r) for r in cells)
    path = work / "cells.csv"
    path.write_text(text, encoding="utf-8")
    ds = attempt("csv", read_csv, path, experiment, columns, units)
    if ds is not None:
        check_dataset(ds)
