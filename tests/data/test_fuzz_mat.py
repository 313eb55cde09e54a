"""Fuzzing the MATLAB reader (``read_mat`` and ``load``): random and mutated variables,
formats v4 and v5, cut files, random and flipped bytes. See ``tests/fuzz``."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hystdisc.data import CANONICAL_COLUMNS, EXPERIMENTS, MIN_SAMPLES, load, read_mat

from ..fuzz import attempt, check_dataset, fuzz_settings

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


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
