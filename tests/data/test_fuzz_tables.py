"""Fuzzing the whitespace-table reader (``read_table``), rig files (``read_rig``) and the
readers' arguments. See ``tests/fuzz``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import given
from hypothesis import strategies as st

from hystdisc.data import CANONICAL_COLUMNS, EXPERIMENTS, load, read_mat, read_rig, read_table
from hystdisc.errors import HystdiscError

from ..fuzz import attempt, check_dataset, check_error, fmt, fuzz_settings
from ..fuzz.text import CSV_OPS, TEXT_OPS, apply_row_ops, apply_text_ops
from ..fuzz.toml import TOML_ANY, maybe, often, to_toml

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


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
    ops=st.lists(CSV_OPS, max_size=2),
    text_ops=st.lists(TEXT_OPS, max_size=2),
)
def test_fuzz_table(work, nrows, ncols, kw, stem, ops, text_ops):
    k = np.arange(nrows)
    signals = [k / 1000.0, 0.2 * np.cos(0.5 * k), np.sin(0.3 * k), 0.5 + 0 * k, np.cos(0.1 * k)]
    signals.append(np.cos(0.7 * k))
    width = max(ncols, 5) if nrows % 3 else ncols
    rows = [[fmt(signals[c][i]) for c in range(width)] for i in range(nrows)]
    header = [f"c{c}" for c in range(width)]
    apply_row_ops(header, rows, ops)
    text = "\n".join(" ".join(r) for r in rows) + "\n"
    data = apply_text_ops(text, " ", text_ops)
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


_RIG_JUNK = {
    "experiment": maybe(st.sampled_from([*EXPERIMENTS, "Driven ", "none"])),
    "columns": maybe(
        st.dictionaries(
            st.sampled_from([*CANONICAL_COLUMNS, "z"]),
            st.integers(-1, 5) | st.sampled_from(["t", "angle"]),
            max_size=5,
        )
    ),
    "units": maybe(
        st.dictionaries(
            st.sampled_from(["t", "theta", "torque", "current", "speed"]),
            st.sampled_from(["mm", "deg", "ms", "kN", "N*m", "lbf*ft", "mA", "cubit"]),
            max_size=3,
        )
    ),
    "current": maybe(
        st.fixed_dictionaries(
            {},
            optional={
                "value": maybe(st.floats(-2, 2)),
                "from_name": maybe(
                    st.sampled_from([r"(\d+(?:x\d+)?)A$", r"(\d+)", "(", r"(x)?", r"(\d+)(A)"])
                ),
                "decimal": maybe(st.sampled_from(["x", "", "p", "."])),
                "bogus": st.integers(),
            },
        )
        | st.floats(-1, 1)
    ),
    "skip_rows": maybe(st.integers(-2, 3)),
    "fs": maybe(st.sampled_from([1000.0, 1000, 0, -1.0, float("inf"), float("nan")])),
    "name": TOML_ANY,
    "description": TOML_ANY,
    "path": TOML_ANY,
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


def _theta_mat(p: Path) -> Path:
    out = p.with_suffix(".mat")
    scipy.io.savemat(str(out), {"theta": np.cos(0.5 * np.arange(30))})
    return out


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
