"""Fuzzing ``hystdisc predict`` with edited ``results.json`` files. See ``tests/fuzz``."""

from __future__ import annotations

import contextlib
import io
import json
import warnings
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hystdisc.cli import main
from hystdisc.data import write_csv
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

from ..fuzz import COUNTS, check_error, fuzz_settings
from ..fuzz.results import BASE_RESULTS, JSON_PATHS, JSON_VALUES, mutate_json

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


@pytest.fixture(scope="module")
def predict_data(work) -> Path:
    ds = generate(Model("dahl"), currents=(0.0, 1.0), duration=0.3, noise=1e-3, seed=2)
    return write_csv(ds, work / "predict_data.csv")


@fuzz_settings(60)
@given(
    edits=st.lists(st.tuples(JSON_PATHS, JSON_VALUES, st.booleans()), max_size=2),
    family=st.none() | st.sampled_from(["dahl", "bingham", "lugre", ""]),
)
def test_fuzz_predict_cli(work, predict_data, edits, family):
    doc = json.loads(json.dumps(BASE_RESULTS))
    for path, value, delete in edits:
        mutate_json(doc, path, value, delete)
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


def test_predict_family_with_families_not_a_table(tmp_path, capsys):
    data = write_csv(
        generate("dahl", currents=(0.0, 1.0), duration=0.3, seed=1), tmp_path / "d.csv"
    )
    res = tmp_path / "results.json"
    res.write_text(json.dumps({**BASE_RESULTS, "families": None}))
    argv = ["predict", str(res), str(data), "-o", str(tmp_path / "o.csv"), "--family", "dahl"]
    assert main(argv) == 2
    check_error(capsys.readouterr().err.strip().removeprefix("hystdisc: error: "))
