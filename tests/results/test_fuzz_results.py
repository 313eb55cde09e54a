"""Fuzzing the ``results.json`` reader (``Results.load``, ``term_model``). See ``tests/fuzz``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hystdisc.data import EXPERIMENTS
from hystdisc.errors import HystdiscError
from hystdisc.models import TermModel
from hystdisc.results import Results

from ..fuzz import attempt, check_error, fuzz_settings
from ..fuzz.results import BASE_RESULTS, JSON_PATHS, JSON_VALUES, mutate_json

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


def _results_outcome(path: Path):
    """Load a results.json and ask for every model it holds.

    Any exception but a well-formed HystdiscError (a RecursionError on deep nesting, a
    TypeError on a value of the wrong type) fails the test.
    """
    res = attempt("results", Results.load, path)
    if res is None:
        return None
    exp = res.experiment
    assert exp is None or exp in EXPERIMENTS, exp  # a name the registry knows
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
    edits=st.lists(st.tuples(JSON_PATHS, JSON_VALUES, st.booleans()), max_size=3),
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
        mutate_json(doc, path, value, delete)
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
