"""The text parsing the readers share (hystdisc.data.text) and the columns -> runs step."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data.columns import build_dataset, check_column_map, infer_experiment
from hystdisc.data.text import count, data_lines, guess_delimiter, parse_floats, split_rows
from hystdisc.errors import HystdiscError

from .helpers import check_message


def test_data_lines_numbers_lines_and_drops_comments_blanks_and_boms():
    text = "# head\r\n\r\n\ufeff# second comment\r1 2\n\ufeff3 4\n"
    assert data_lines(text) == [(4, "1 2"), (5, "3 4")]
    assert data_lines("x\ny\nz\n", skip_rows=2) == [(3, "z")]


def test_guess_delimiter_and_split_rows():
    assert guess_delimiter("a;b;c,d") == ";"
    assert guess_delimiter("a\tb") == "\t"
    assert guess_delimiter("a b c") is None
    linenos, rows = split_rows([(3, '"x, y", 2'), (4, "z,3")], ",", "f.csv", None, "header")
    assert linenos.tolist() == [3, 4] and rows == [["x, y", "2"], ["z", "3"]]
    with pytest.raises(HystdiscError) as exc:
        split_rows([(1, '"a,b'), (2, 'c",d')], ",", "f.csv", None, "header")
    check_message(exc, "f.csv", "quoted field spans several lines")


def test_parse_floats_names_the_first_bad_cell():
    lines = np.array([5, 6, 7])
    assert parse_floats(["1", " 2.5", "1e3"], lines, "f", "theta").tolist() == [1.0, 2.5, 1000.0]
    with pytest.raises(HystdiscError) as exc:
        parse_floats(["1", "2,5", "x"], lines, "f", "theta")
    msg = check_message(exc, "non-numeric cell '2,5'", "line 6")
    assert msg.endswith("fix: use '.' as the decimal separator")
    with pytest.raises(HystdiscError) as exc:
        parse_floats(["1", "nan", "nan"], lines, "f", "theta")
    check_message(exc, "'theta' holds NaN on line 6 (2 bad values)")
    assert count(1, "run") == "1 run" and count(0, "run") == "0 runs"


def test_infer_experiment_from_the_extra_columns():
    assert infer_experiment(["t", "theta", "current"], "x") == "release"
    assert infer_experiment(["theta", "torque"], "x") == "driven"
    assert infer_experiment(["theta", "input"], "x") == "forced"
    with pytest.raises(HystdiscError) as exc:
        infer_experiment(["theta", "input", "torque"], "x.csv")
    assert str(exc.value) == (
        "x.csv: has both a torque and an input column, so the experiment type is ambiguous; "
        "fix: pass --experiment driven or --experiment forced"
    )


@pytest.mark.parametrize(
    ("columns", "words"),
    [
        ({"angle": "theta"}, ("unknown column key 'angle'",)),
        ({"theta": True}, ("neither a name nor an index",)),
        ({"theta": -1}, ("is negative",)),
        (["theta"], ("must be a mapping",)),
    ],
)
def test_check_column_map_errors(columns, words):
    with pytest.raises(HystdiscError) as exc:
        check_column_map(columns, "x.csv")
    check_message(exc, "x.csv", *words)


def test_build_dataset_groups_runs_and_takes_one_current_each():
    n = 60
    t = np.tile(np.arange(30) * 1e-3, 2)
    cols = {
        "t": t,
        "theta": np.sin(40 * t) + np.repeat([0.0, 0.1], 30),
        "current": np.repeat([1.0, 0.5], 30) + 0.001 * (np.arange(n) % 2),
    }
    ids = ["b"] * 30 + ["a"] * 30
    ds = build_dataset(cols, ids, np.arange(2, n + 2), "f.csv", "release")
    assert ds.names == ["b", "a"] and ds.currents.tolist() == [1.0005, 0.5005]
    assert ds["a"].lines.tolist() == list(range(32, 62))
    cols["current"][40] = 2.0
    with pytest.raises(HystdiscError) as exc:
        build_dataset(cols, ids, np.arange(2, n + 2), "f.csv", "release")
    check_message(exc, "run a", "current varies", "first change on line 42")
