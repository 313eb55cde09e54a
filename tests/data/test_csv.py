"""The long-format CSV reader (and the text parsing it shares with the others)."""

from __future__ import annotations

import math

import pytest

from hystdisc.data import (
    EXPERIMENTS,
    Dataset,
    load,
    read_csv,
    validate,
    write_csv,
)
from hystdisc.errors import HystdiscError

from .helpers import (
    assert_close,
    check_message,
    csv_with,
    good_rows,
    make_dataset,
    make_run,
    write_lines,
)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_csv_round_trip(tmp_path, experiment):
    ds = make_dataset(experiment, with_dot=experiment == "driven")
    path = write_csv(ds, tmp_path / "out.csv")
    back = read_csv(path)
    assert back.experiment == experiment
    assert back.names == ds.names
    for a, b in zip(back, ds, strict=True):
        assert a.current == b.current
        for key in ("t", "theta", "torque", "input", "theta_dot"):
            va, vb = getattr(a, key), getattr(b, key)
            assert (va is None) == (vb is None), key
            if vb is not None:
                assert_close(va, vb)
    header = path.read_text().splitlines()[0]
    expected = {"release": "run,t,theta,current", "driven": "run,t,theta,current,torque,theta_dot"}
    assert header == expected.get(experiment, "run,t,theta,current,input")


def test_csv_predictions_and_odd_run_names(tmp_path):
    ds = make_dataset("release", currents=(0.0, 1.0))
    ds.runs[0].name = "a,b"
    preds = [r.theta * 2 for r in ds]
    p = write_csv(ds, tmp_path / "p.csv", predictions=preds)
    lines = p.read_text().splitlines()
    assert lines[0] == "run,t,theta,current,theta_model"
    assert lines[1].startswith('"a,b",')
    back = read_csv(p)  # extra column ignored, quoted name kept
    assert back.names == ["a,b", "1"]
    p2 = write_csv(ds, tmp_path / "q.csv", predictions={"sim": preds})
    assert p2.read_text().splitlines()[0].endswith(",sim")
    with pytest.raises(HystdiscError, match="one prediction array per run"):
        write_csv(ds, tmp_path / "r.csv", predictions=preds[:1])


def test_csv_column_mapping_and_units(tmp_path):
    rows = [f"{k % 2},{k * 0.01},{10.0 * math.sin(k)},{(k % 2) * 0.5},{k}" for k in range(60)]
    p = write_lines(
        tmp_path / "m.csv", "trial;time;angle deg;amps;force kN".replace(";", ","), rows
    )
    ds = read_csv(
        p,
        columns={
            "run": "trial",
            "t": "time",
            "theta": "angle deg",
            "current": "amps",
            "torque": "force kN",
        },
        units={"theta": "deg", "torque": "kN"},
    )
    assert ds.experiment == "driven" and ds.names == ["0", "1"]
    r1 = ds[1]
    assert r1.current == 0.5 and r1.n == 30
    assert r1.theta[0] == pytest.approx(math.radians(10.0 * math.sin(1)), rel=1e-12)
    assert r1.torque[0] == pytest.approx(1000.0)
    # column positions work too
    ds2 = read_csv(p, columns={"run": 0, "t": 1, "theta": 2, "current": 3}, experiment="release")
    assert ds2.experiment == "release" and ds2[0].torque is None


def test_csv_mm_units_and_no_run_column(tmp_path):
    rows = [
        f"{k * 0.002},{5.0 * math.sin(0.2 * k)},{50 * math.cos(0.2 * k)},1.0" for k in range(50)
    ]
    p = write_lines(tmp_path / "lin.csv", "t,theta,theta_dot,current", rows)
    ds = read_csv(p, units={"theta": "mm", "theta_dot": "mm/s"})
    assert ds.names == ["0"] and ds.experiment == "release"
    assert ds[0].theta[1] == pytest.approx(5e-3 * math.sin(0.2))
    assert ds[0].theta_dot[0] == pytest.approx(0.05)
    assert ds[0].fs == pytest.approx(500.0)


def test_csv_semicolon_crlf_comments_bom(tmp_path):
    p = tmp_path / "eu.csv"
    body = "# exported by rig software\r\nrun;t;theta;current\r\n" + "\r\n".join(
        r.replace(",", ";") for r in good_rows(30)
    )
    p.write_bytes(("\ufeff" + body).encode("utf-8"))
    ds = read_csv(p)
    assert ds[0].n == 30


def test_runs_grouped_in_order_of_first_appearance(tmp_path):
    rows = good_rows(30, run="b", current=1.0) + good_rows(30, run="a", current=0.0)
    ds = read_csv(write_lines(tmp_path / "g.csv", "run,t,theta,current", rows))
    assert ds.names == ["b", "a"] and ds.currents.tolist() == [1.0, 0.0]


def test_small_current_ripple_is_accepted_as_median(tmp_path):
    rows = good_rows(30, current=0.5)
    rows = [r.rsplit(",", 1)[0] + f",{0.5 + 0.005 * (-1) ** k}" for k, r in enumerate(rows)]
    ds = read_csv(write_lines(tmp_path / "rip.csv", "run,t,theta,current", rows))
    assert ds[0].current == pytest.approx(0.5, abs=0.005)


def test_error_missing_column(tmp_path):
    p = csv_with(tmp_path, "nocol.csv", "run,t,angle,current", good_rows(30))
    with pytest.raises(HystdiscError) as exc:
        read_csv(p)
    check_message(exc, "nocol.csv", "'theta' is missing", "angle", "--column theta=NAME")


def test_error_mapped_column_absent(tmp_path):
    p = csv_with(tmp_path, "map.csv", "run,t,theta,current", good_rows(30))
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, columns={"theta": "angle"})
    check_message(exc, "map.csv", "'angle'", "not in the header")


def test_error_nan_names_column_and_line(tmp_path):
    rows = good_rows(30)
    rows[9] = "0,0.009,nan,0.5"
    p = csv_with(tmp_path, "nan.csv", "run,t,theta,current", rows)
    with pytest.raises(HystdiscError) as exc:
        read_csv(p)
    check_message(exc, "nan.csv", "'theta'", "NaN", "line 11")


def test_error_inf(tmp_path):
    rows = good_rows(30)
    rows[4] = "0,0.004,0.1,inf"
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "inf.csv", "run,t,theta,current", rows))
    check_message(exc, "inf.csv", "'current'", "inf", "line 6")


def test_error_current_varies_within_run(tmp_path):
    rows = [f"r5,{k * 0.001:.3f},{math.sin(k)},{0.0 if k < 20 else 1.0}" for k in range(40)]
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "cur.csv", "run,t,theta,current", rows))
    check_message(exc, "cur.csv", "run r5", "current varies", "line 22", "split")


def test_error_torque_missing_for_driven(tmp_path):
    p = csv_with(tmp_path, "drv.csv", "run,t,theta,current", good_rows(30))
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, experiment="driven")
    check_message(exc, "drv.csv", "'torque' is missing", "driven")
    r = make_run("9", 0.0)
    with pytest.raises(HystdiscError) as exc:
        validate(Dataset([r], "driven", "api"))
    check_message(exc, "api", "run 9", "torque")


def test_error_input_missing_for_forced(tmp_path):
    p = csv_with(tmp_path, "frc.csv", "run,t,theta,current", good_rows(30))
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, experiment="forced")
    check_message(exc, "frc.csv", "'input' is missing", "forced")


def test_error_ambiguous_torque_and_input(tmp_path):
    p = csv_with(
        tmp_path,
        "both.csv",
        "run,t,theta,current,torque,input",
        [r + ",1,2" for r in good_rows(30)],
    )
    with pytest.raises(HystdiscError) as exc:
        read_csv(p)
    check_message(exc, "both.csv", "ambiguous", "--experiment")


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (b"", ("empty",)),
        (b"   \n\n", ("empty",)),
        (b"run,t,theta,current\n", ("no data rows",)),
        (b"run,t,theta,current\n0,0,1\x00\x00,0\n", ("not a text file",)),
        (b"run,t,theta,current\n0,0,\xe9,0\n", ("UTF-8", "line 2")),
    ],
    ids=["empty", "blank", "header-only", "binary", "encoding"],
)
def test_error_unreadable_content(tmp_path, content, words):
    p = tmp_path / "bad.csv"
    p.write_bytes(content)
    with pytest.raises(HystdiscError) as exc:
        read_csv(p)
    check_message(exc, "bad.csv", *words)


def test_error_missing_file_and_directory(tmp_path):
    with pytest.raises(HystdiscError) as exc:
        read_csv(tmp_path / "nothere.csv")
    check_message(exc, "nothere.csv", "does not exist")
    with pytest.raises(HystdiscError) as exc:
        load(tmp_path / "nothere.csv")
    check_message(exc, "nothere.csv", "does not exist")
    with pytest.raises(HystdiscError) as exc:
        read_csv(tmp_path)
    check_message(exc, str(tmp_path), "is a directory")
    with pytest.raises(HystdiscError) as exc:
        load(tmp_path)  # empty folder
    check_message(exc, str(tmp_path), "no data files")


def test_error_ragged_row(tmp_path):
    rows = good_rows(30)
    rows[5] = "0,0.005,0.2"
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "ragged.csv", "run,t,theta,current", rows))
    check_message(exc, "ragged.csv", "line 7", "3 fields, expected 4")


def test_error_non_numeric_cell(tmp_path):
    rows = good_rows(30)
    rows[2] = "0,0.002,abc,0.5"
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "text.csv", "run,t,theta,current", rows))
    check_message(exc, "text.csv", "non-numeric cell 'abc'", "'theta'", "line 4")
    rows[2] = "0,0.002,,0.5"
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "gap.csv", "run,t,theta,current", rows))
    check_message(exc, "gap.csv", "empty cell", "line 4")
