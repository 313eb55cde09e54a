"""Fuzzing of every reader with hypothesis (issue 8).

Every input, however malformed, must end in one of two ways:

* it loads, and the result satisfies its invariants (a :class:`Dataset` of float64 1-D,
  finite, equally long signals with strictly increasing time; a rig or scenario dict of
  checked types; a finite :class:`TermModel`), or
* it raises :class:`HystdiscError` whose message is one line and says ``fix:``.

Any other exception, a NaN that slips through, or a stray ``RuntimeWarning`` (overflow
noise printed at the user) fails the test. The runs are reproducible and bounded
(``derandomize=True``, no example database, a fixed ``max_examples`` per reader); the
number of inputs tried per reader is printed at the end of the module (``-s`` or the
terminal summary) and written to ``$HYSTDISC_FUZZ_COUNTS`` when that is set.

The nasty inputs found are kept in ``tests/fuzz_corpus/`` and replayed by
:func:`test_corpus` with the outcome expected of each (see ``CORPUS``).
"""

from __future__ import annotations

import contextlib
import csv
import datetime as dt
import io
import json
import math
import os
import re
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hystdisc.cli import main
from hystdisc.data import (
    CANONICAL_COLUMNS,
    EXPERIMENTS,
    MIN_SAMPLES,
    Dataset,
    load,
    read_csv,
    read_mat,
    read_rig,
    read_table,
    validate,
    write_csv,
)
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.models import FAMILIES, Model, TermModel
from hystdisc.registry import get_experiment
from hystdisc.results import Results
from hystdisc.simulation.synth import (
    SCENARIO_KEYS,
    generate,
    generate_from_scenario,
    load_scenario,
    scenario_model,
)

CORPUS_DIR = Path(__file__).parent / "end_to_end" / "fuzz_corpus"

#: inputs tried, per reader, and outcomes: COUNTS[reader], COUNTS[reader, "ok" | "error"].
#: Readers named "a>b" are a later stage fed with what reader "a" accepted (not new inputs).
COUNTS: Counter = Counter()
#: error messages seen, per reader (numbers blanked); listed with HYSTDISC_FUZZ_VERBOSE=1
KINDS: Counter = Counter()


def fuzz_settings(n: int) -> settings:
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


# ----------------------------------------------------------------------------- checks


def check_error(exc: BaseException) -> str:
    """A user error: one non-empty line that names the fix."""
    msg = str(exc)
    assert msg.strip(), "empty error message"
    assert msg == " ".join(msg.split()), f"message is not one clean line: {msg!r}"
    assert len(msg.splitlines()) == 1, f"message spans lines: {msg!r}"
    assert "fix:" in msg, f"message without a fix: {msg!r}"
    assert "Traceback" not in msg
    return msg


def check_dataset(ds: Dataset) -> None:
    """The invariants of a loaded Dataset."""
    assert isinstance(ds, Dataset)
    assert ds.experiment in EXPERIMENTS
    assert len(ds.runs) >= 1
    names = [r.name for r in ds.runs]
    assert len(set(names)) == len(names), names
    extra = get_experiment(ds.experiment).extra_column
    for r in ds.runs:
        assert isinstance(r.name, str)
        assert isinstance(r.current, float) and math.isfinite(r.current)
        for key in ("t", "theta", "torque", "input", "theta_dot"):
            a = getattr(r, key)
            if a is None:
                assert key not in ("t", "theta") and key != extra, key
                continue
            assert isinstance(a, np.ndarray), key
            assert a.dtype == np.float64, (key, a.dtype)
            assert a.ndim == 1, (key, a.shape)
            assert a.size == r.t.size, (key, a.size, r.t.size)
            assert np.all(np.isfinite(a)), key
        assert r.n >= MIN_SAMPLES
        dt_ = np.diff(r.t)
        assert np.all(dt_ > 0), "time not strictly increasing"
        assert np.all(np.isfinite(dt_)), "infinite time step"
        assert math.isfinite(r.fs) and r.fs > 0
        assert np.ptp(r.theta) > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HystdiscWarning)  # already checked by attempt()
        validate(ds)  # idempotent: a loaded dataset passes its own check again


def attempt(reader: str, fn, *args, **kwargs):
    """Call ``fn``; return its result, or None after a well-formed HystdiscError.

    Counts the input under ``reader``; any exception other than HystdiscError and any
    warning other than a HystdiscWarning propagate as test failures.
    """
    COUNTS[reader] += 1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = fn(*args, **kwargs)
        except HystdiscError as exc:
            msg = check_error(exc)
            COUNTS[reader, "error"] += 1
            KINDS[reader, re.sub(r"[-+.\w]*\d[-+.\w]*", "#", msg.split(": ", 1)[-1])[:60]] += 1
            out = None
    stray = [w for w in caught if not issubclass(w.category, HystdiscWarning)]
    assert not stray, f"stray warnings: {[f'{w.category.__name__}: {w.message}' for w in stray]}"
    for w in caught:
        check_warning(w.message)
    if out is not None:
        COUNTS[reader, "ok"] += 1
    return out


def check_warning(message) -> None:
    msg = str(message)
    assert msg == " ".join(msg.split()), f"warning is not one clean line: {msg!r}"


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module", autouse=True)
def _report_counts(request):
    yield
    readers = sorted(k for k in COUNTS if isinstance(k, str))
    total = sum(COUNTS[k] for k in readers if ">" not in k)
    lines = [f"fuzz inputs tried: {total}"]
    for k in readers:
        lines.append(
            f"  {k:<22}{COUNTS[k]:>6}  (accepted {COUNTS[k, 'ok']}, "
            f"one-line error {COUNTS[k, 'error']})"
        )
    if os.environ.get("HYSTDISC_FUZZ_VERBOSE"):
        for (reader, kind), n in sorted(KINDS.items()):
            lines.append(f"    {reader}: {n} x {kind}")
    text = "\n".join(lines)
    tr = request.config.pluginmanager.get_plugin("terminalreporter")
    capman = request.config.pluginmanager.get_plugin("capturemanager")
    if tr is not None:
        ctx = capman.global_and_fixture_disabled() if capman else contextlib.nullcontext()
        with ctx:
            tr.write_line("")
            for line in lines:
                tr.write_line(line)
    out = os.environ.get("HYSTDISC_FUZZ_COUNTS")
    if out:
        Path(out).write_text(text + "\n", encoding="utf-8")


# ----------------------------------------------------------------------------- value pools

BAD_CELLS = [
    "",
    " ",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-Infinity",
    "abc",
    "1,5",
    "1e400",
    "-1e400",
    "1e-400",
    "0x10",
    "１２",
    "٣",
    "∞",
    "1_0",
    '"1"',
    "None",
    "null",
    "TRUE",
    "9" * 400,
    "1e308",
    "-1.7976931348623157e308",
    "5e-324",
    "\u00a0",
    "1.0.0",
    "--1",
    "+-1",
    "1e",
    "e5",
    ".",
    "#",
]

UNICODE_TEXT = st.text(
    alphabet=st.characters(codec="utf-8", exclude_characters="\x00"), min_size=0, max_size=12
)


def _fmt(x: float) -> str:
    return f"{x:.10g}"


# ----------------------------------------------------------------------------- CSV

_CSV_OPS = st.one_of(
    st.tuples(
        st.just("cell"), st.integers(0, 10_000), st.integers(0, 20), st.sampled_from(BAD_CELLS)
    ),
    st.tuples(st.just("unicode_cell"), st.integers(0, 10_000), st.integers(0, 20), UNICODE_TEXT),
    st.tuples(st.just("drop_col"), st.integers(0, 20)),
    st.tuples(
        st.just("extra_col"),
        st.sampled_from(["note", "Theta", "x y", "t", "é", ""]),
        st.sampled_from(["1", "", "nan", "abc"]),
    ),
    st.tuples(st.just("ragged"), st.integers(0, 10_000), st.booleans()),
    st.tuples(st.just("dup_row"), st.integers(0, 10_000)),
    st.tuples(st.just("swap_rows"), st.integers(0, 10_000), st.integers(0, 10_000)),
    st.tuples(st.just("reverse")),
    st.tuples(
        st.just("scale_col"), st.integers(0, 20), st.sampled_from([1e300, 1e-300, -1.0, 0.0, 1e15])
    ),
    st.tuples(st.just("jitter_t"), st.integers(0, 10_000), st.floats(-0.9, 0.9)),
    st.tuples(st.just("rename_header"), st.integers(0, 20), UNICODE_TEXT),
    st.tuples(st.just("upper_header")),
    st.tuples(st.just("dup_header"), st.integers(0, 20), st.integers(0, 20)),
    st.tuples(st.just("drop_rows"), st.integers(0, 60)),
    st.tuples(st.just("const_col"), st.integers(0, 20), st.sampled_from(["0", "0.5", "1e-20"])),
)
_TEXT_OPS = st.one_of(
    st.tuples(st.just("bom")),
    st.tuples(st.just("crlf")),
    st.tuples(st.just("cr")),
    st.tuples(st.just("blank_lines"), st.integers(0, 10_000)),
    st.tuples(st.just("comment"), st.integers(0, 10_000), UNICODE_TEXT),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0)),
    st.tuples(st.just("nul"), st.floats(0.0, 1.0)),
    st.tuples(
        st.just("latin1"),
    ),
    st.tuples(st.just("flip_byte"), st.floats(0.0, 1.0), st.integers(0, 255)),
    st.tuples(st.just("no_final_newline")),
    st.tuples(st.just("trailing_delim")),
    st.tuples(st.just("quote_all")),
    st.tuples(st.just("quote_cells")),
    st.tuples(st.just("spaces")),
)

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
            "t": [_fmt(v) for v in t],
            "theta": [_fmt(v) for v in theta],
            "current": [_fmt(cur)] * n,
            "torque": [_fmt(v) for v in np.sin(0.3 * k + r)],
            "input": [_fmt(v) for v in np.cos(0.2 * k - r)],
            "theta_dot": [_fmt(v) for v in np.sin(0.5 * k)],
        }
        expected.append((rid.strip(), cur, [float(x) for x in sig["theta"]]))
        rows += [[sig[c][i] for c in order] for i in range(n)]
    ops = draw(st.lists(_CSV_OPS, max_size=3))
    text_ops = draw(st.lists(_TEXT_OPS, max_size=3))
    return {
        "experiment": experiment,
        "header": list(order),
        "rows": rows,
        "delim": delim,
        "ops": ops,
        "text_ops": text_ops,
        "expected": expected,
    }


def _apply_row_ops(header: list[str], rows: list[list[str]], ops) -> None:
    for op in ops:
        kind = op[0]
        if kind in ("cell", "unicode_cell") and rows:
            r = op[1] % len(rows)
            if rows[r]:
                rows[r][op[2] % len(rows[r])] = op[3]
        elif kind == "drop_col" and header:
            c = op[1] % len(header)
            del header[c]
            for row in rows:
                if c < len(row):
                    del row[c]
        elif kind == "extra_col":
            header.append(op[1])
            for row in rows:
                row.append(op[2])
        elif kind == "ragged" and rows:
            row = rows[op[1] % len(rows)]
            if op[2]:
                row.append("0")
            elif row:
                row.pop()
        elif kind == "dup_row" and rows:
            r = op[1] % len(rows)
            rows.insert(r, list(rows[r]))
        elif kind == "swap_rows" and rows:
            a, b = op[1] % len(rows), op[2] % len(rows)
            rows[a], rows[b] = rows[b], rows[a]
        elif kind == "reverse":
            rows.reverse()
        elif kind == "scale_col" and header:
            c = op[1] % len(header)
            for row in rows:
                with contextlib.suppress(ValueError, IndexError):
                    row[c] = repr(float(row[c]) * op[2])
        elif kind == "jitter_t" and "t" in header and rows:
            c = header.index("t")
            row = rows[op[1] % len(rows)]
            with contextlib.suppress(ValueError, IndexError):
                row[c] = repr(float(row[c]) + op[2] * 0.01)
        elif kind == "rename_header" and header:
            header[op[1] % len(header)] = op[2]
        elif kind == "upper_header":
            header[:] = [h.upper() if h != "run" else h for h in header]
        elif kind == "dup_header" and header:
            header[op[2] % len(header)] = header[op[1] % len(header)]
        elif kind == "drop_rows":
            del rows[op[1] :]
        elif kind == "const_col" and header:
            c = op[1] % len(header)
            for row in rows:
                if c < len(row):
                    row[c] = op[2]


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


def _apply_text_ops(text: str, delim: str, ops) -> bytes:
    data: bytes | None = None
    for op in ops:
        kind = op[0]
        if (
            kind
            in (
                "bom",
                "crlf",
                "cr",
                "blank_lines",
                "comment",
                "no_final_newline",
                "trailing_delim",
                "spaces",
            )
            and data is None
        ):
            lines = text.split("\n")
            if kind == "bom":
                text = "\ufeff" + text
            elif kind == "crlf":
                text = text.replace("\n", "\r\n")
            elif kind == "cr":
                text = text.replace("\n", "\r")
            elif kind == "blank_lines":
                i = op[1] % len(lines)
                lines.insert(i, "   ")
                text = "\n".join(lines)
            elif kind == "comment":
                i = op[1] % len(lines)
                lines.insert(i, "# " + " ".join(op[2].split()))
                text = "\n".join(lines)
            elif kind == "no_final_newline":
                text = text.rstrip("\n")
            elif kind == "trailing_delim":
                d = "," if delim == " " else delim
                text = "\n".join(line + d if line else line for line in lines)
            elif kind == "spaces" and delim != " ":
                text = "\n".join(
                    (delim + " ").join(line.split(delim)) if line else line for line in lines
                )
        elif kind == "quote_all" and data is None:
            text = "\n".join('"' + line + '"' if line else line for line in text.split("\n"))
        else:
            if data is None:
                data = text.encode("utf-8")
            if kind == "truncate":
                data = data[: int(op[1] * len(data))]
            elif kind == "nul" and data:
                i = int(op[1] * (len(data) - 1))
                data = data[:i] + b"\x00" + data[i:]
            elif kind == "latin1":
                data = text.encode("latin-1", errors="replace") + "é".encode("latin-1")
            elif kind == "flip_byte" and data:
                i = int(op[1] * (len(data) - 1))
                data = data[:i] + bytes([op[2]]) + data[i + 1 :]
    return data if data is not None else text.encode("utf-8")


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
    _apply_row_ops(header, rows, doc["ops"])
    # csv quoting of every cell is harmless, except for whitespace tables (no quoting there)
    quote_cells = any(op[0] == "quote_cells" for op in doc["text_ops"])
    text = _serialize(header, rows, doc["delim"], quote_all=quote_cells and doc["delim"] != " ")
    data = _apply_text_ops(text, doc["delim"], doc["text_ops"])
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


# ----------------------------------------------------------------------------- MAT

_MAT_NAMES = st.one_of(
    st.sampled_from([*CANONICAL_COLUMNS, "Theta", "T", "time", "angle", "y", "u", "data"]),
    st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,7}", fullmatch=True),
)
_DTYPES = st.sampled_from(
    [
        np.float64,
        np.float32,
        np.int8,
        np.int16,
        np.int32,
        np.int64,
        np.uint8,
        np.uint16,
        np.uint64,
        np.bool_,
        np.complex128,
    ]
)


@st.composite
def mat_arrays(draw):
    kind = draw(
        st.sampled_from(
            ["vector", "vector", "matrix", "scalar", "string", "cell", "struct", "empty"]
        )
    )
    if kind == "string":
        return draw(
            st.text(alphabet=st.characters(codec="ascii", exclude_characters="\x00"), max_size=10)
        )
    if kind == "cell":
        arr = np.empty((1, 2), dtype=object)
        arr[0, 0] = np.arange(3.0)
        arr[0, 1] = "x"
        return arr
    if kind == "struct":
        return {"a": np.arange(draw(st.integers(0, 30)), dtype=float), "b": "text"}
    if kind == "empty":
        return np.zeros(draw(st.sampled_from([(0,), (0, 0), (0, 3), (1, 0)])))
    dtype = draw(_DTYPES)
    n = draw(st.sampled_from([1, 2, 19, 20, 25, 40]))
    if kind == "scalar":
        shape = ()
    elif kind == "vector":
        shape = draw(st.sampled_from([(n,), (1, n), (n, 1), (1, 1, n)]))
    else:
        shape = draw(st.sampled_from([(n, 2), (2, n), (n, 4), (3, 3)]))
    if draw(st.booleans()):
        elements = None  # structured: a ramp, which often makes a valid time or signal
        arr = np.arange(int(np.prod(shape)) or 1)[: int(np.prod(shape))].reshape(shape)
        arr = (
            (arr * draw(st.sampled_from([1, -1, 2]))).astype(dtype)
            if dtype != np.bool_
            else (arr % 2).astype(bool)
        )
        return arr
    elements = (
        hnp.from_dtype(np.dtype(dtype), allow_nan=True, allow_infinity=True)
        if np.dtype(dtype).kind in "fc"
        else None
    )
    return draw(hnp.arrays(dtype, shape, elements=elements))


@st.composite
def mat_documents(draw):
    """Either a random dict of variables or a valid record with mutations."""
    if draw(st.booleans()):
        return draw(st.dictionaries(_MAT_NAMES, mat_arrays(), max_size=6))
    n = draw(st.integers(MIN_SAMPLES, 40))
    fs = draw(st.sampled_from([100.0, 1000.0]))
    k = np.arange(n)
    d = {
        "t": k / fs,
        "theta": 0.3 * np.cos(0.6 * k) + 1e-3 * np.sin(2.9 * k),
        "current": np.array([[0.5]]),
    }
    if draw(st.booleans()):
        d["torque"] = np.sin(0.4 * k)
    if draw(st.booleans()):
        d["run"] = (k >= n // 2).astype(float)
        d["current"] = np.where(k >= n // 2, 1.0, 0.0)
    for _ in range(draw(st.integers(0, 3))):
        op = draw(
            st.sampled_from(
                [
                    "drop",
                    "nan",
                    "inf",
                    "row",
                    "col",
                    "short",
                    "int",
                    "complex",
                    "rename",
                    "dup_t",
                    "bool",
                    "matrix",
                    "string",
                ]
            )
        )
        keys = sorted(d)
        if not keys:
            break
        key = draw(st.sampled_from(keys))
        v = np.asarray(d[key])
        if op == "drop":
            del d[key]
        elif op in ("nan", "inf") and v.size and v.dtype.kind == "f":
            v = v.astype(float).copy()
            v.flat[draw(st.integers(0, v.size - 1))] = np.nan if op == "nan" else -np.inf
            d[key] = v
        elif op == "row":
            d[key] = v.reshape(1, -1)
        elif op == "col":
            d[key] = v.reshape(-1, 1)
        elif op == "short" and v.size > 1:
            d[key] = v.reshape(-1)[:-1]
        elif op == "int" and v.dtype.kind in "biuf":
            with np.errstate(all="ignore"):
                d[key] = (
                    np.nan_to_num(np.round(v.astype(float))).clip(-30000, 30000).astype(np.int16)
                )
        elif op == "complex":
            d[key] = v.astype(complex) + 1j
        elif op == "rename":
            d[key.upper()] = d.pop(key)
        elif op == "dup_t" and "t" in d and np.size(d["t"]) > 3:
            t = np.asarray(d["t"], dtype=float).reshape(-1).copy()
            t[2] = t[1]
            d["t"] = t
        elif op == "bool":
            d[key] = v != 0
        elif op == "matrix":
            d["data"] = np.column_stack(
                [np.asarray(x).reshape(-1)[:n] for x in d.values() if np.asarray(x).size == n]
                or [np.zeros(n)]
            )
        elif op == "string":
            d[key] = "x" * 3
    return d


_MAT_KW = st.fixed_dictionaries(
    {},
    optional={
        "experiment": st.sampled_from([*EXPERIMENTS, "bogus"]),
        "columns": st.dictionaries(
            st.sampled_from(CANONICAL_COLUMNS),
            st.integers(0, 4) | st.sampled_from(["t", "theta", "data", "y", "nope"]),
            max_size=3,
        ),
        "units": st.dictionaries(
            st.sampled_from(["t", "theta", "torque"]),
            st.sampled_from(["ms", "deg", "kN", "furlong"]),
            max_size=2,
        ),
        "current": st.floats(-2, 2) | st.sampled_from([float("nan"), "0.5", "x", [1.0], True]),
        "fs": st.sampled_from([1000.0, 0.0, -5.0, float("nan"), float("inf"), 1e-300, "1", True]),
    },
)


def _savemat(path: Path, d: dict, fmt: str) -> bool:
    """savemat; ``fmt`` "5z" is v5 compressed (the MATLAB -v7 default)."""
    kw = {"format": fmt[0], "do_compression": fmt == "5z"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scipy.io.savemat(str(path), d, oned_as="row" if len(d) % 2 else "column", **kw)
    except Exception:  # scipy cannot write every random dict: not our reader's business
        return False
    return True


@fuzz_settings(250)
@given(
    d=mat_documents(),
    kw=_MAT_KW,
    fmt=st.sampled_from(["5", "5z", "5z", "5z", "4", "4"]),
    cut=st.none() | st.floats(0, 1),
)
def test_fuzz_mat(work, d, kw, fmt, cut):
    path = work / "fuzz.mat"
    if not _savemat(path, d, fmt):
        assume(False)
    if cut is not None:
        data = path.read_bytes()
        path.write_bytes(data[: int(cut * len(data))])
    ds = attempt("mat", read_mat, path, **kw)
    if ds is not None:
        check_dataset(ds)


@fuzz_settings(200)
@given(
    data=st.binary(max_size=400),
    header=st.sampled_from(
        [b"", b"MATLAB 5.0 MAT-file", b"MATLAB 7.3 MAT-file", b"\x00\x00\x00\x00"]
    ),
    flip=st.none() | st.tuples(st.floats(0, 1), st.integers(0, 255)),
)
def test_fuzz_mat_random_bytes(work, data, header, flip):
    path = work / "bytes.mat"
    if flip is not None:
        # a valid file with one byte changed
        k = np.arange(30)
        _savemat(path, {"t": k / 100.0, "theta": np.cos(0.5 * k), "current": 0.5}, "5")
        raw = bytearray(path.read_bytes())
        i = int(flip[0] * (len(raw) - 1))
        raw[i] = flip[1]
        path.write_bytes(bytes(raw))
    else:
        path.write_bytes(header.ljust(116 if header else 0, b" ") + data)
    ds = attempt("mat", load, path)
    if ds is not None:
        check_dataset(ds)


# ----------------------------------------------------------------------------- tables


def often(valid, junk):
    """``valid`` most of the time, else ``junk``."""
    return st.one_of(valid, valid, valid, junk)


_TABLE_COLUMNS = {
    "release": {"t": 0, "theta": 1},
    "driven": {"t": 0, "theta": 1, "torque": 2},
    "forced": {"t": 0, "theta": 1, "input": 4},
}
_TABLE_JUNK_MAP = st.dictionaries(
    st.sampled_from(CANONICAL_COLUMNS),
    st.integers(0, 5) | st.sampled_from([-1, True, "theta", 2.5, None]),
    max_size=5,
)


_TABLE_JUNK = {
    "columns": _TABLE_JUNK_MAP,
    "experiment": st.sampled_from(["Driven", "x", "release", ""]),
    "units": st.dictionaries(
        st.sampled_from(["t", "theta", "torque", "input", "current"]),
        st.sampled_from(["mm", "ms", "deg", "N", "kN", "mA", "?"]),
        max_size=2,
    ),
    "current": st.sampled_from([None, float("nan"), float("inf"), 1e308, "0.5", "abc", [0.5], True])
    | st.floats(allow_nan=True, allow_infinity=True),
    "current_from_name": st.sampled_from(
        [r"(\d+(?:x\d+)?)A$", r"(\d+)", "A", "(", r"(x)?A$", "()", "(.*)"]
    ),
    "skip_rows": st.integers(-1, 3) | st.just(True),
    "fs": st.sampled_from([1000.0, 0.0, -1.0, float("nan"), float("inf"), "1000", True]),
}


@st.composite
def table_settings(draw):
    """Valid settings of read_table, with none, one or two of them replaced by junk."""
    experiment = draw(st.sampled_from(EXPERIMENTS))
    columns = dict(_TABLE_COLUMNS[experiment])
    if draw(st.booleans()):
        columns["theta_dot"] = 3
    if draw(st.booleans()):
        columns["current"] = 3
    kw = {
        "columns": columns,
        "experiment": experiment,
        "units": None,
        "current": 0.5,
        "current_from_name": None,
        "skip_rows": 0,
        "fs": None,
    }
    for key in draw(st.lists(st.sampled_from(sorted(_TABLE_JUNK)), max_size=2, unique=True)):
        kw[key] = draw(_TABLE_JUNK[key])
    return kw


@fuzz_settings(300)
@given(
    nrows=st.integers(20, 45) | st.integers(0, 45),
    ncols=st.integers(1, 6),
    kw=table_settings(),
    stem=st.sampled_from(["10mm1Hz0x5A", "run", "1x2x3A", "xA", "0A", "9" * 240 + "A"]),
    ops=st.lists(_CSV_OPS, max_size=2),
    text_ops=st.lists(_TEXT_OPS, max_size=2),
)
def test_fuzz_table(work, nrows, ncols, kw, stem, ops, text_ops):
    k = np.arange(nrows)
    signals = [k / 1000.0, 0.2 * np.cos(0.5 * k), np.sin(0.3 * k), 0.5 + 0 * k, np.cos(0.1 * k)]
    signals.append(np.cos(0.7 * k))
    width = max(ncols, 5) if nrows % 3 else ncols
    rows = [[_fmt(signals[c][i]) for c in range(width)] for i in range(nrows)]
    header = [f"c{c}" for c in range(width)]
    _apply_row_ops(header, rows, ops)
    text = "\n".join(" ".join(r) for r in rows) + "\n"
    data = _apply_text_ops(text, " ", text_ops)
    path = work / f"{stem}.txt"
    path.write_bytes(data)
    ds = attempt("table", read_table, path, **kw)
    if ds is not None:
        check_dataset(ds)
    if not ops and not text_ops and kw["columns"] in _TABLE_COLUMNS.values() and nrows >= 20:
        if kw["skip_rows"] == 0 and kw["current"] == 0.5 and kw["units"] is None and width >= 5:
            if kw["experiment"] in EXPERIMENTS and kw["fs"] is None:
                assert ds is not None, "a valid table must load"
    path.unlink()


# ----------------------------------------------------------------------------- TOML helpers


def _toml_key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _toml_str(k)


def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in '"\\' or ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, (dt.datetime, dt.date, dt.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict) -> str:
    """Top-level scalars as ``key = value``, tables as ``[section]`` (inline below)."""
    lines = []
    tables = {k: v for k, v in doc.items() if isinstance(v, dict)}
    for k, v in doc.items():
        if k not in tables:
            lines.append(f"{_toml_key(k)} = {toml_value(v)}")
    for k, v in tables.items():
        lines.append(f"[{_toml_key(k)}]")
        for kk, vv in v.items():
            lines.append(f"{_toml_key(kk)} = {toml_value(vv)}")
    return "\n".join(lines) + "\n"


_TOML_SCALARS = st.one_of(
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=10),
    st.dates(),
    st.datetimes(),
    st.times(),
)
_TOML_ANY = st.recursive(
    _TOML_SCALARS,
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=6,
)


def _maybe(valid, junk=_TOML_ANY):
    return st.one_of(valid, valid, junk)


# ----------------------------------------------------------------------------- rig descriptions

_RIG_JUNK = {
    "experiment": _maybe(st.sampled_from([*EXPERIMENTS, "Driven ", "none"])),
    "columns": _maybe(
        st.dictionaries(
            st.sampled_from([*CANONICAL_COLUMNS, "z"]),
            st.integers(-1, 5) | st.sampled_from(["t", "angle"]),
            max_size=5,
        )
    ),
    "units": _maybe(
        st.dictionaries(
            st.sampled_from(["t", "theta", "torque", "current", "speed"]),
            st.sampled_from(["mm", "deg", "ms", "kN", "N*m", "lbf*ft", "mA", "cubit"]),
            max_size=3,
        )
    ),
    "current": _maybe(
        st.fixed_dictionaries(
            {},
            optional={
                "value": _maybe(st.floats(-2, 2)),
                "from_name": _maybe(
                    st.sampled_from([r"(\d+(?:x\d+)?)A$", r"(\d+)", "(", r"(x)?", r"(\d+)(A)"])
                ),
                "decimal": _maybe(st.sampled_from(["x", "", "p", "."])),
                "bogus": st.integers(),
            },
        )
        | st.floats(-1, 1)
    ),
    "skip_rows": _maybe(st.integers(-2, 3)),
    "fs": _maybe(st.sampled_from([1000.0, 1000, 0, -1.0, float("inf"), float("nan")])),
    "name": _TOML_ANY,
    "description": _TOML_ANY,
    "path": _TOML_ANY,
    "sample_rate": st.integers(),
}


@st.composite
def rig_documents(draw):
    """The rig of the test tables, with up to three settings dropped, changed or added."""
    doc = {
        "experiment": "driven",
        "columns": {"t": 0, "theta": 1, "theta_dot": 2, "torque": 3},
        "units": {"theta": "mm", "theta_dot": "mm/s", "torque": "N"},
        "current": {"from_name": r"(\d+(?:x\d+)?)A$", "decimal": "x"},
    }
    for key in draw(st.lists(st.sampled_from(sorted(_RIG_JUNK)), max_size=3, unique=True)):
        if key in doc and draw(st.booleans()):
            del doc[key]
        else:
            doc[key] = draw(_RIG_JUNK[key])
    return doc


@pytest.fixture(scope="module")
def table_folder(work) -> Path:
    folder = work / "tables"
    folder.mkdir()
    k = np.arange(60)
    for name, cur in (("10mm1Hz0x5A.txt", 0.5), ("10mm1Hz1A.txt", 1.0)):
        decay = np.exp(-0.05 * k)
        cols = np.column_stack(
            [
                k / 1000.0,
                0.2 * decay * np.cos(0.5 * k + cur),
                0.5 * np.sin(0.4 * k),
                np.cos(0.2 * k),
            ]
        )
        np.savetxt(folder / name, cols, fmt="%.10g")
    return folder


@fuzz_settings(300)
@given(
    doc=rig_documents(),
    raw=often(st.none(), st.text(max_size=80)),
    garbage=often(st.none(), st.binary(max_size=40)),
)
def test_fuzz_rig(work, table_folder, doc, raw, garbage):
    path = work / "rig.toml"
    text = to_toml(doc) if raw is None else raw
    data = text.encode("utf-8") + (garbage or b"")
    path.write_bytes(data)
    rig = attempt("rig", read_rig, path)
    if rig is None:
        return
    assert set(rig) >= {"experiment", "columns", "units", "current", "skip_rows", "fs", "path"}
    assert rig["experiment"] in (None, *EXPERIMENTS)
    assert all(
        isinstance(v, (int, str)) and not isinstance(v, bool) for v in rig["columns"].values()
    )
    assert rig["fs"] is None or (math.isfinite(rig["fs"]) and rig["fs"] > 0)
    cur = rig["current"]["value"]
    assert cur is None or math.isfinite(cur)
    assert isinstance(rig["skip_rows"], int) and rig["skip_rows"] >= 0
    # the settings must be usable: loading tables with them is a Dataset or a one-line error
    ds = attempt("rig>load tables", load, table_folder, rig=path)
    if ds is not None:
        check_dataset(ds)
    ds = attempt("rig>load tables", load, table_folder / "10mm1Hz1A.txt", rig=rig)
    if ds is not None:
        check_dataset(ds)


# ----------------------------------------------------------------------------- scenarios

_PARAM_NAMES = sorted({p.name for f in FAMILIES.values() for p in f.params} | {"k_s", "J", "bogus"})

_SCENARIO_JUNK = {
    "model": _maybe(st.sampled_from([*FAMILIES, "Dahl", "bouc_wen", "spring"])),
    "declared": _maybe(st.sampled_from(list(FAMILIES))),
    "description": _TOML_ANY,
    "params": _maybe(
        st.dictionaries(
            st.sampled_from(_PARAM_NAMES),
            _maybe(st.floats(-5, 200) | st.sampled_from([0, 1e9, 1e12, -1e-9, 1e-300, 1e300])),
            max_size=3,
        )
    ),
    "effects": _maybe(
        st.dictionaries(
            st.sampled_from(["coulomb", "current_viscous", "offset", "cubic_stiffness", "warp"]),
            st.dictionaries(
                st.sampled_from(["f_c", "c_i", "theta_off", "k_3", "zz"]),
                _maybe(st.floats(-2, 2) | st.sampled_from([1e300, -1e300])),
                max_size=2,
            ),
            max_size=2,
        )
        | st.lists(st.sampled_from(["coulomb", "offset", "nope"]), max_size=2)
    ),
    "currents": _maybe(st.lists(st.floats(-0.5, 2), max_size=3) | st.floats(0, 1)),
    "experiment": _maybe(st.sampled_from([*EXPERIMENTS, "free"])),
    "theta0": _maybe(st.floats(-1, 1) | st.lists(st.floats(-1, 1), max_size=3) | st.just(1e300)),
    "duration": _maybe(st.sampled_from([0.05, 0.2, 0.0, -1.0, 1e-6, 1e300])),
    "fs": _maybe(st.sampled_from([200.0, 1000.0, 1.0, 0.0, 1e300])),
    "noise": _maybe(st.sampled_from([0.0, 1e-3, -1.0, 1e3, 1e300])),
    "theta_noise": _maybe(st.sampled_from([0.0, 1e-3, -1.0])),
    "seed": _maybe(st.integers(-3, 2**63 - 1)),
    "encoder_counts": _maybe(st.integers(-2, 5000) | st.just(2**63 - 1)),
    "drives": _maybe(
        st.lists(
            st.sampled_from(["0.3@1", "x@1", "1", "-1@2", "0.1@0", "1e300@1e300"])
            | st.fixed_dictionaries(
                {"amplitude": _maybe(st.floats(-1, 1)), "frequency": _maybe(st.floats(0, 5))}
            ),
            max_size=2,
        )
    ),
    "input": _maybe(
        st.fixed_dictionaries(
            {"kind": st.sampled_from(["multisine", "sine", "chirp"])},
            optional={
                "rms": _maybe(st.floats(0, 20)),
                "f_min": _maybe(st.floats(0, 10)),
                "f_max": _maybe(st.floats(0, 10)),
                "amplitude": st.floats(0, 5),
                "frequency": st.floats(0, 5),
            },
        )
    ),
    "output": _maybe(
        st.sampled_from(["out.csv", "sub/out.csv", "", " ", "a\x00b.csv", "../x.csv", "é.csv"])
    ),
    "colour": st.text(max_size=3),
}


@st.composite
def scenario_documents(draw):
    """A small valid scenario, with up to three settings dropped, changed or added."""
    doc = {
        "model": draw(st.sampled_from(list(FAMILIES))),
        "currents": [0.0, 1.0],
        "duration": 0.2,
        "fs": 500.0,
        "noise": 1e-3,
        "output": "out.csv",
    }
    experiment = draw(st.sampled_from(EXPERIMENTS))
    if experiment != "release":
        doc["experiment"] = experiment
    for key in draw(st.lists(st.sampled_from(sorted(_SCENARIO_JUNK)), max_size=3, unique=True)):
        if key in doc and draw(st.booleans()):
            del doc[key]
        else:
            doc[key] = draw(_SCENARIO_JUNK[key])
    return doc


@fuzz_settings(300)
@given(
    doc=scenario_documents(),
    raw=often(st.none(), st.text(max_size=60)),
    garbage=often(st.none(), st.binary(max_size=30)),
)
def test_fuzz_scenario(work, doc, raw, garbage):
    path = work / "scenario.toml"
    text = to_toml(doc) if raw is None else raw
    path.write_bytes(text.encode("utf-8") + (garbage or b""))
    sc = attempt("scenario", load_scenario, path)
    if sc is None:
        return
    assert isinstance(sc, dict) and set(sc) <= set(SCENARIO_KEYS) | {"path"}
    for key in ("duration", "fs", "noise", "theta_noise"):
        if key in sc:
            assert math.isfinite(sc[key])
    if "output" in sc:
        assert "\x00" not in sc["output"] and Path(sc["output"]).name
    model = attempt("scenario>model", scenario_model, sc)
    if model is None:
        return
    assert isinstance(model, Model)
    samples = (
        sc.get("duration", 6.0) * sc.get("fs", 1000.0) * max(len(sc.get("currents") or [0] * 5), 1)
    )
    if samples <= 3000:  # keep the simulation bounded
        ds = attempt("scenario>generate", generate_from_scenario, sc)
        if ds is not None:
            assert isinstance(ds, Dataset)
            for r in ds.runs:
                for key in ("t", "theta", "torque", "input", "theta_dot"):
                    a = getattr(r, key)
                    assert a is None or np.all(np.isfinite(a)), f"NaN in generated {key}"


# ----------------------------------------------------------------------------- results.json

BASE_RESULTS = {
    "version": "0.1.0",
    "input": "data.csv",
    "experiment": "release",
    "noise_std": 0.001,
    "terms": {"torque": ["theta_dot", "z", "i*z"], "hysteresis": ["theta_dot", "|theta_dot|*z"]},
    "family": "dahl",
    "families": {
        "dahl": {
            "parameters": {"k_x": {"value": 0.8, "ci95": [0.79, 0.81]}},
            "rms": 0.001,
            "bic": -1000.0,
            "n_params": 5,
            "term_model": {
                "torque": {"theta": 158.0, "theta_dot": 0.8, "z": 0.5, "i*z": 1.5},
                "hysteresis": {"theta_dot": 20.0, "|theta_dot|*z": -20.0},
                "n": 1.0,
                "J": 1.0,
            },
        },
        "bingham": {
            "parameters": {},
            "rms": 0.002,
            "bic": -900.0,
            "n_params": 5,
            "term_model": {
                "torque": {
                    "theta": 158.0,
                    "theta_dot": 0.8,
                    "i*theta_dot": 0.6,
                    "sign(theta_dot)": 0.3,
                },
                "hysteresis": {},
                "n": 1.0,
                "J": 1.0,
            },
        },
    },
    "model": {
        "torque": {"theta": 158.0, "theta_dot": 0.8, "z": 0.5, "i*z": 1.5},
        "hysteresis": {"theta_dot": 20.0, "|theta_dot|*z": -20.0},
        "n": 1.0,
        "J": 1.0,
    },
    "effects": [],
    "unexplained": False,
    "residual": {"rms": 0.001},
}

_JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**30), 10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from(
        ["nan", "inf", "-1e999", "1e5", "", "z", "theta_dot", "|theta_dot|*z", "release", "driven"]
    )
    | st.text(max_size=6),
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(
            st.sampled_from(["torque", "hysteresis", "n", "J", "z", "theta", "x"]),
            inner,
            max_size=3,
        )
    ),
    max_leaves=5,
)
_PATHS = st.lists(
    st.sampled_from(
        [
            "families",
            "dahl",
            "bingham",
            "term_model",
            "model",
            "torque",
            "hysteresis",
            "n",
            "J",
            "z",
            "theta",
            "experiment",
            "|theta_dot|*z",
            "family",
        ]
    ),
    min_size=1,
    max_size=4,
)


def _mutate_json(doc, path, value, delete):
    cur = doc
    for key in path[:-1]:
        if not isinstance(cur, dict) or key not in cur:
            return
        cur = cur[key]
    if not isinstance(cur, dict):
        return
    if delete:
        cur.pop(path[-1], None)
    else:
        cur[path[-1]] = value


def _results_outcome(path: Path):
    """Load a results.json and ask for every model it holds.

    Any exception but a well-formed HystdiscError (a RecursionError on deep nesting, a
    TypeError on a value of the wrong type) fails the test.
    """
    res = attempt("results", Results.load, path)
    if res is None:
        return None
    exp = res.experiment
    assert exp is None or isinstance(exp, (str, int, float, list, dict, bool))
    models = [attempt("results>term_model", res.term_model)]
    fams = res.families
    if isinstance(fams, dict):
        for name in list(fams)[:3]:
            models.append(attempt("results>term_model", res.term_model, name))
    for tm in models:
        if tm is None:
            continue
        assert isinstance(tm, TermModel)
        coefs = [*tm.torque.values(), *tm.hysteresis.values(), tm.n, tm.J]
        assert all(math.isfinite(c) for c in coefs), "non-finite coefficient accepted"
    return res


@fuzz_settings(350)
@given(
    edits=st.lists(st.tuples(_PATHS, _JSON_VALUES, st.booleans()), max_size=3),
    text_op=st.none()
    | st.sampled_from(
        ["truncate", "bytes", "nest", "nest_object", "bigint", "bom", "utf16", "list", "empty"]
    ),
    cut=st.floats(0, 1),
    junk=st.binary(max_size=40),
    depth=st.sampled_from([100, 400, 700, 1000, 3000]),
)
def test_fuzz_results_json(work, edits, text_op, cut, junk, depth):
    doc = json.loads(json.dumps(BASE_RESULTS))
    for path, value, delete in edits:
        _mutate_json(doc, path, value, delete)
    text = json.dumps(doc)
    data = text.encode("utf-8")
    if text_op == "truncate":
        data = data[: int(cut * len(data))]
    elif text_op == "bytes":
        data = junk
    elif text_op == "nest":
        data = b'{"families": {}, "model": ' + b"[" * 5000 + b"]" * 5000 + b"}"
    elif text_op == "nest_object":
        data = (
            b'{"experiment": "release", "families": {}, "model": {}, "x": '
            + b'{"a": ' * depth
            + b"0"
            + b"}" * depth
            + b"}"
        )
    elif text_op == "bigint":
        data = text.replace("158.0", "1" + "0" * (5 + int(cut * 5000))).encode()
    elif text_op == "bom":
        data = b"\xef\xbb\xbf" + data
    elif text_op == "utf16":
        data = text.encode("utf-16")
    elif text_op == "list":
        data = b"[" + data + b"]"
    elif text_op == "empty":
        data = b""
    path = work / "results.json"
    path.write_bytes(data)
    _results_outcome(path)


@pytest.fixture(scope="module")
def predict_data(work) -> Path:
    ds = generate(Model("dahl"), currents=(0.0, 1.0), duration=0.3, noise=1e-3, seed=2)
    return write_csv(ds, work / "predict_data.csv")


@fuzz_settings(60)
@given(
    edits=st.lists(st.tuples(_PATHS, _JSON_VALUES, st.booleans()), max_size=2),
    family=st.none() | st.sampled_from(["dahl", "bingham", "lugre", ""]),
)
def test_fuzz_predict_cli(work, predict_data, edits, family):
    doc = json.loads(json.dumps(BASE_RESULTS))
    for path, value, delete in edits:
        _mutate_json(doc, path, value, delete)
    res = work / "predict_results.json"
    res.write_text(json.dumps(doc), encoding="utf-8")
    out = work / "predicted.csv"
    out.unlink(missing_ok=True)
    argv = ["predict", str(res), str(predict_data), "-o", str(out), "--quiet"]
    if family is not None:
        argv += ["--family", family]
    COUNTS["predict-cli"] += 1
    err = io.StringIO()
    # any exception (RecursionError, TypeError...) propagates and fails the test
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            code = main(argv)
    lines = err.getvalue().splitlines()
    if code == 0:
        COUNTS["predict-cli", "ok"] += 1
        body = out.read_text().splitlines()
        assert body[0].startswith("run,t,current,theta,theta_pred")
        assert not any("nan" in line or "inf" in line for line in body[1:]), (
            "NaN prediction written"
        )
    else:
        COUNTS["predict-cli", "error"] += 1
        assert code == 2, (code, lines)
        errors = [line for line in lines if line.startswith("hystdisc: error:")]
        assert len(errors) == 1, lines
        check_error(errors[0])
        assert not out.exists()
    assert not [p for p in work.iterdir() if p.name.endswith(".tmp")]


# ----------------------------------------------------------------------------- corpus

#: Open results.json problems (in hystdisc/results/ or hystdisc/cli/predict.py), each
#: pinned by a strict xfail that turns into a failure once fixed, so that the mark is removed.
RESULTS_XFAIL: dict[str, str] = {}  # every reported results.py problem is fixed

#: corpus file -> words its one-line error must contain ("ok": it must load)
CORPUS: dict[str, tuple[str, ...] | str] = {
    "csv_ok_double_bom.csv": "ok",  # a BOM written twice: was "column 't' is missing (found: t,...)"
    "csv_ok_cr_only_semicolons.csv": "ok",
    "csv_ok_huge_theta.csv": "ok",  # std() overflowed with a RuntimeWarning
    "csv_err_time_overflow.csv": ("run 0", "time steps overflow", "line 3"),
    "csv_err_nul_byte.csv": ("not a text file",),
    "csv_err_latin1.csv": ("UTF-8", "line 2"),
    "csv_err_ragged.csv": ("line 10", "4 fields"),
    "csv_err_overflow_cell.csv": ("'theta'", "inf", "line 7"),
    "csv_err_decimal_comma.csv": ("'0,5'", "decimal separator"),
    # one byte changed in an uncompressed v5 file: scipy's reader segfaulted (killed pytest)
    "mat_err_segfault_sparse_class.mat": ("damaged MATLAB", "crashed"),
    "mat_err_segfault_complex_flag.mat": ("damaged MATLAB", "crashed"),
    "mat_err_segfault_data_type.mat": ("damaged MATLAB", "crashed"),
    "mat_err_truncated.mat": ("not a readable MATLAB",),
    "mat_overflow_flip.mat": "ok",  # huge value: overflow RuntimeWarning in validate()
    "table_ok_10mm1Hz0x5A.txt": "ok",
    "rig_err_fs_inf.toml": ("fs = inf",),  # was accepted, then "time does not increase"
    "rig_err_current_text.toml": ("'0.5 A'", "not a number"),
    "rig_err_not_utf8.toml": ("UTF-8",),
    "scenario_err_not_utf8.toml": ("UTF-8",),  # was UnicodeDecodeError
    "scenario_err_output_nul.toml": ("output",),  # was ValueError: embedded null byte
    "scenario_err_huge_duration.toml": ("samples",),  # was MemoryError / OverflowError
    "scenario_err_diverges.toml": ("diverged", "sigma_0=1e+09"),
    "results_err_truncated.json": ("not a readable results.json",),
    "results_err_no_model.json": ("not a hystdisc results.json",),
    "results_err_unknown_term.json": ("theta^7",),
    # fixed, each is a one-line error (any wording)
    **{name: () for name in RESULTS_XFAIL},
    # reported problems of results.py, now one-line errors
    "results_xfail_deep_nesting.json": (),
    "results_xfail_huge_int.json": (),
    "results_xfail_nan_string.json": (),
    "results_xfail_no_experiment.json": (),
    "results_xfail_deep_object.json": (),
}


def _corpus_files() -> list[str]:
    return sorted(p.name for p in CORPUS_DIR.iterdir() if p.is_file() and p.suffix != ".rig")


def _read_corpus(path: Path):
    kind = path.name.split("_", 1)[0]
    if kind in ("csv", "mat"):
        return load(path)
    if kind == "table":
        return load(path, rig=path.with_suffix(".rig"))
    if kind == "rig":
        return load(CORPUS_DIR / "table_ok_10mm1Hz0x5A.txt", rig=read_rig(path))
    if kind == "scenario":
        return generate_from_scenario(load_scenario(path))
    if kind == "results":
        res = Results.load(path)
        assert res.experiment in EXPERIMENTS
        tm = res.term_model()
        coefs = [*tm.torque.values(), *tm.hysteresis.values(), tm.n, tm.J]
        assert all(math.isfinite(c) for c in coefs), "non-finite model accepted"
        return res
    raise AssertionError(f"unknown corpus file kind {kind!r}")


def test_corpus_manifest_lists_every_file():
    assert sorted(CORPUS) == _corpus_files()
    size = sum(p.stat().st_size for p in CORPUS_DIR.iterdir())
    assert size < 16_000, f"the corpus should stay small ({size} bytes)"


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=RESULTS_XFAIL[n]))
        if n in RESULTS_XFAIL
        else n
        for n in sorted(CORPUS)
    ],
)
def test_corpus(name):
    path = CORPUS_DIR / name
    expected = CORPUS[name]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = _read_corpus(path)
        except HystdiscError as exc:
            msg = check_error(exc)
            assert expected != "ok", f"{name} must load, got: {msg}"
            for word in expected:
                assert word in msg, f"{word!r} not in {msg!r}"
            out = None
    assert not [w for w in caught if not issubclass(w.category, HystdiscWarning)]
    if expected == "ok":
        assert out is not None
        if isinstance(out, Dataset):
            check_dataset(out)


def _long_int_results(tmp: Path) -> Path:
    p = tmp / "results.json"
    p.write_text(
        '{"experiment": "release", "families": {}, "model": {"torque": {"z": ' + "1" * 4301 + "}}}"
    )
    return p


def test_results_long_integer_literal(tmp_path):
    with pytest.raises(HystdiscError) as exc:
        Results.load(_long_int_results(tmp_path)).term_model()
    check_error(exc.value)


def _theta_mat(p: Path) -> Path:
    out = p.with_suffix(".mat")
    scipy.io.savemat(str(out), {"theta": np.cos(0.5 * np.arange(30))})
    return out


def test_predict_family_with_families_not_a_table(tmp_path, capsys):
    data = write_csv(
        generate("dahl", currents=(0.0, 1.0), duration=0.3, seed=1), tmp_path / "d.csv"
    )
    res = tmp_path / "results.json"
    res.write_text(json.dumps({**BASE_RESULTS, "families": None}))
    argv = ["predict", str(res), str(data), "-o", str(tmp_path / "o.csv"), "--family", "dahl"]
    assert main(argv) == 2
    check_error(capsys.readouterr().err.strip().removeprefix("hystdisc: error: "))


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda p: read_table(p, {"t": 0, "theta": 1}, "release", current="abc"), ("'abc'",)),
        (lambda p: read_table(p, {"t": 0, "theta": 1}, "release", current=[0.5]), ("[0.5]",)),
        (lambda p: read_table(p, {"theta": 1}, "release", current=0.5, fs="1000"), ("fs",)),
        (lambda p: read_table(p, {"theta": 1}, "release", current=0.5, fs=float("inf")), ("fs",)),
        (lambda p: read_mat(_theta_mat(p), current="x", fs=100.0), ("'x'",)),
        (lambda p: read_mat(_theta_mat(p), current=0.5, fs=True), ("fs",)),
    ],
)
def test_api_argument_regressions(tmp_path, call, words):
    """Bad arguments found by fuzzing, which used to raise ValueError/TypeError."""
    p = tmp_path / "tab.txt"
    k = np.arange(30)
    np.savetxt(p, np.column_stack([k / 100.0, np.cos(0.5 * k)]))
    with pytest.raises(HystdiscError) as exc:
        call(p)
    msg = check_error(exc.value)
    for w in words:
        assert w in msg


def test_generate_refuses_absurd_sizes():
    from hystdisc.simulation.synth import generate

    for kw in ({"duration": 1e200, "fs": 1e200}, {"duration": 1e12}):
        with pytest.raises(HystdiscError) as exc:
            generate("dahl", **kw)
        assert "samples" in check_error(exc.value)
