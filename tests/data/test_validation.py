"""validate(): every problem of a dataset is a one-line error naming the run and the fix."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hystdisc.data import (
    Dataset,
    Run,
    read_csv,
    validate,
)
from hystdisc.errors import HystdiscError, HystdiscWarning

from .helpers import check_message, csv_with, good_rows, make_dataset, make_run


def test_error_nan_in_programmatic_run():
    r = make_run("r1", 0.0)
    r.theta[17] = np.nan
    with pytest.raises(HystdiscError) as exc:
        validate(Dataset([r], "release", "sim"))
    check_message(exc, "sim", "run r1", "NaN", "sample 17")


def test_error_non_increasing_time(tmp_path):
    rows = good_rows(30, run="7")
    rows[20] = "7,0.019,0.1,0.5"  # duplicate of the previous time stamp
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "time.csv", "run,t,theta,current", rows))
    check_message(exc, "time.csv", "run 7", "time does not increase", "line 22", "sort")


def test_error_irregular_sampling(tmp_path):
    rows = [f"2,{k * 0.001 + (0.0003 if k == 15 else 0):.4f},{math.sin(k)},0.5" for k in range(40)]
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "jitter.csv", "run,t,theta,current", rows))
    check_message(exc, "jitter.csv", "run 2", "irregular sampling", "resample")


def test_tiny_time_jitter_is_accepted(tmp_path):
    rng = np.random.default_rng(11)
    t = np.arange(100) * 1e-3 + rng.uniform(-2e-6, 2e-6, 100)  # 0.4 % of dt at most
    ds = Dataset([Run("0", t, np.sin(30 * t), 0.0)], "release", "x")
    assert validate(ds) is ds


def test_error_single_current_where_several_needed(tmp_path):
    rows = good_rows(30, "0", 0.5) + good_rows(30, "1", 0.5)
    ds = read_csv(csv_with(tmp_path, "one.csv", "run,t,theta,current", rows))
    with pytest.raises(HystdiscError) as exc:
        validate(ds, need_currents=2)
    check_message(
        exc, "one.csv", "a single current", "0.5 A", "add runs at other currents", "--model"
    )


def test_error_run_too_short(tmp_path):
    rows = good_rows(30, "long") + good_rows(12, "tiny", 1.0)
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "short.csv", "run,t,theta,current", rows))
    check_message(exc, "short.csv", "run tiny", "too short", "12 samples")


def test_error_never_moves(tmp_path):
    rows = [f"3,{k * 0.001:.3f},0.25,0.5" for k in range(40)]
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "flat.csv", "run,t,theta,current", rows))
    check_message(exc, "flat.csv", "run 3", "never moves")


def test_error_duplicate_run_names():
    ds = Dataset([make_run("a", 0.0), make_run("a", 1.0, seed=1)], "release", "dup")
    with pytest.raises(HystdiscError) as exc:
        validate(ds)
    check_message(exc, "dup", "run a", "two runs are named 'a'")


def test_error_constant_torque_of_a_driven_run():
    r = make_run("d", 0.5, torque=np.full(200, 3.0))
    with pytest.raises(HystdiscError) as exc:
        validate(Dataset([r], "driven", "drv"))
    msg = check_message(exc, "drv", "run d")
    assert "the measured torque never changes (it is constant)" in msg
    # the same constant signal as the input of a forced run is allowed
    forced = make_run("f", 0.5, input=np.full(200, 3.0))
    assert validate(Dataset([forced], "forced", "frc")).runs == [forced]


def test_error_all_zero_currents_and_too_few_levels():
    zero = Dataset([make_run("0", 0.0), make_run("1", 0.0, seed=1)], "release", "z.csv")
    with pytest.raises(HystdiscError) as exc:
        validate(zero, need_currents=2)
    check_message(exc, "z.csv", "every run has current 0 A", "--units current=mA")
    two = make_dataset("release", currents=(0.0, 1.0))
    with pytest.raises(HystdiscError) as exc:
        validate(two, need_currents=3)
    check_message(exc, "only 2 distinct currents (0, 1 A) where 3 are needed")


def _warnings_of(ds: Dataset) -> list[warnings.WarningMessage]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        validate(ds)
    return [w for w in caught if issubclass(w.category, HystdiscWarning)]


def test_clipped_sensor_warning_points_at_the_caller():
    t = np.arange(2000) / 1000.0
    theta = np.clip(np.exp(-0.5 * t) * np.sin(2 * np.pi * 3 * t), -0.6, 0.6)
    caught = _warnings_of(Dataset([Run("c", t, theta, 0.0)], "release", "clip.csv"))
    assert len(caught) == 1
    text = str(caught[0].message)
    assert text.startswith("clip.csv, run c: theta stays at its maximum 0.6 for ")
    assert caught[0].filename == __file__  # stacklevel: the caller of validate()


def test_release_that_does_not_decay_is_warned_but_forced_is_not():
    t = np.arange(3000) / 1000.0
    theta = 0.2 * np.sin(2 * np.pi * 2 * t)
    texts = [str(w.message) for w in _warnings_of(Dataset([Run("0", t, theta, 0.0)], "release"))]
    assert len(texts) == 1 and "the motion does not decay" in texts[0]
    forced = Run("0", t, theta, 0.0, input=np.cos(t))
    assert _warnings_of(Dataset([forced], "forced")) == []


# ----------------------------------------------------------------------------- units


@pytest.fixture(scope="module")
def dahl_csv_text():
    """The bundled Dahl set, as a user would hold it."""
    from pathlib import Path

    return (Path(__file__).resolve().parents[2] / "data_synth" / "dahl.csv").read_text()


def _with_column(text: str, column: str, factor: float) -> str:
    """The CSV text with one column multiplied (a file recorded in other units)."""
    lines = text.splitlines()
    header = lines[0].split(",")
    k = header.index(column)
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[k] = f"{float(cells[k]) * factor:.9g}"
        out.append(",".join(cells))
    return "\n".join(out) + "\n"


@pytest.mark.parametrize(
    "column, factor, words, fix",
    [
        ("t", 1000.0, "is the time column in milliseconds?", "--units t=ms"),
        ("theta", 180.0 / math.pi, "is it in degrees?", "--units theta=deg"),
        ("current", 1000.0, "is it in milliamperes?", "--units current=mA"),
    ],
)
def test_implausible_units_are_warned_with_the_fix(
    dahl_csv_text, tmp_path, capsys, column, factor, words, fix
):
    from hystdisc.cli import main

    path = tmp_path / f"dahl_{column}.csv"
    path.write_text(_with_column(dahl_csv_text, column, factor))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HystdiscWarning)  # the reader validates too
        ds = read_csv(path)
    caught = [w for w in _warnings_of(ds) if words in str(w.message)]
    (w,) = caught
    assert words in str(w.message) and fix in str(w.message) and str(path) in str(w.message)
    # through the command line: one line on stderr, and the --units fix makes it go away
    argv = ["discover", str(path), "--families", "dahl", "--no-heldout", "--no-effects", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if words in ln]
    assert len(err) == 1 and err[0].startswith("hystdisc: warning:")
    unit = fix.split()[-1].split("=")
    assert main([*argv, "--out", str(tmp_path / "b"), "--units", "=".join(unit)]) == 0
    assert words not in capsys.readouterr().err


def test_plausible_units_are_not_warned(dahl_csv_text, tmp_path):
    path = tmp_path / "dahl.csv"
    path.write_text(dahl_csv_text)
    assert not [w for w in _warnings_of(read_csv(path)) if "--units" in str(w.message)]
