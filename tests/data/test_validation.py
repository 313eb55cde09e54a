"""validate(): every problem of a dataset is a one-line error naming the run and the fix."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hystdisc.data import (
    Dataset,
    ImplausibleUnitsWarning,
    Run,
    read_csv,
    validate,
)
from hystdisc.data.plausibility import MAX_FORCE, MAX_MOTION
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


#: the exact warnings for the bundled Dahl set recorded in other units ({} is the file)
DAHL_IN_OTHER_UNITS = {
    "t": (
        1000.0,
        "{}: t gives a sampling rate of 1 Hz, a 5999 s record and motion at 0.0021 Hz, "
        "implausible for a damper test (sampled below 10 Hz or moving slower than 0.005 Hz): "
        "is the time in milliseconds? (fix: --units t=ms)",
        "t=ms",
    ),
    "theta": (
        180.0 / math.pi,
        "{}: theta reaches 17.29 rad, a release of more than half a turn: is it in degrees? "
        "(fix: --units theta=deg)",
        "theta=deg",
    ),
    "current": (
        1000.0,
        "{}: the coil current reaches 1000 A, implausible for an MR damper: is it in "
        "milliamperes? (fix: --units current=mA)",
        "current=mA",
    ),
}


def _unit_warnings(ds_or_call) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds_or_call() if callable(ds_or_call) else validate(ds_or_call)
    return [str(w.message) for w in caught if issubclass(w.category, ImplausibleUnitsWarning)]


@pytest.mark.parametrize("column", list(DAHL_IN_OTHER_UNITS))
def test_implausible_units_are_warned_with_the_fix(dahl_csv_text, tmp_path, capsys, column):
    """The bundled Dahl set with time in ms, the angle in degrees or the current in mA:
    one exact warning naming the --units fix (API: a Python warning; CLI: one line)."""
    from hystdisc.cli import main

    factor, message, unit = DAHL_IN_OTHER_UNITS[column]
    path = tmp_path / f"dahl_{column}.csv"
    path.write_text(_with_column(dahl_csv_text, column, factor))
    expected = message.format(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = read_csv(path)
    (w,) = [w for w in caught if issubclass(w.category, HystdiscWarning)]
    assert str(w.message) == expected and w.category is ImplausibleUnitsWarning
    assert _unit_warnings(ds) == [expected]
    # through the command line: that one line on stderr, and the --units fix removes it
    argv = ["discover", str(path), "--families", "dahl", "--no-heldout", "--no-effects", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert [ln for ln in err if "implausible" in ln or "(fix: --units" in ln] == [
        f"hystdisc: warning: {expected}"
    ]
    assert main([*argv, "--out", str(tmp_path / "b"), "--units", unit]) == 0
    assert "--units" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "experiment, column, value, message",
    [
        (
            "driven",
            "theta",
            25.0,
            "x.csv: theta reaches 25, more than 6 m as a damper's displacement and more than "
            "a turn as an angle: is it in millimetres or degrees? (fix: --units theta=mm or "
            "--units theta=deg)",
        ),
        (
            "driven",
            "torque",
            1.46e6,
            "x.csv: torque reaches 1.46e+06, more than 1 MN (or MN·m), beyond any damper: is "
            "it in N·mm? (fix: --units torque=N*mm)",
        ),
        (
            "forced",
            "input",
            5e7,
            "x.csv: input reaches 5e+07, more than 1 MN (or MN·m), beyond any damper: is it "
            "in N·mm? (fix: --units input=N*mm)",
        ),
    ],
)
def test_implausible_displacement_and_force(experiment, column, value, message):
    t = np.arange(2000) / 1000.0
    s = np.sin(2 * np.pi * 2 * t)
    sig = {"theta": 0.02 * s, "torque": 100.0 * np.cos(2 * np.pi * 2 * t)}
    if experiment == "forced":
        sig = {"theta": 0.002 * s, "input": 50.0 * np.cos(2 * np.pi * 2 * t)}
    sig[column] = value * sig[column] / np.max(np.abs(sig[column]))
    ds = Dataset([Run("0", t, current=0.5, **sig)], experiment, "x.csv")
    assert _unit_warnings(ds) == [message]
    # at the bound itself nothing is said (the bounds are in hystdisc.data.plausibility)
    bound = {"theta": MAX_MOTION, "torque": MAX_FORCE, "input": MAX_FORCE}[column]
    sig[column] = bound * sig[column] / np.max(np.abs(sig[column]))
    assert _unit_warnings(Dataset([Run("0", t, current=0.5, **sig)], experiment, "x.csv")) == []


def test_slow_motion_is_warned_even_when_finely_sampled():
    """A 2 Hz test sampled at 20 kHz with time in ms: 20 samples per 'second', but motion at
    0.002 'Hz' (a 500 s period)."""
    t = np.arange(40000) / 20.0  # ms read as s
    ds = Dataset([Run("0", t, 0.01 * np.sin(2 * np.pi * 0.002 * t), 0.0)], "release", "x.csv")
    (text,) = _unit_warnings(ds)
    assert text.startswith("x.csv: t gives a sampling rate of 20 Hz, a 2000 s record and ")
    assert "motion at 0.002 Hz" in text and text.endswith("(fix: --units t=ms)")


BUNDLED = sorted((Path(__file__).resolve().parents[2] / "data_synth").glob("*.csv"))


@pytest.mark.parametrize("path", BUNDLED, ids=[p.stem for p in BUNDLED])
def test_bundled_sets_have_plausible_units(path):
    assert _unit_warnings(lambda: read_csv(path)) == []


@pytest.mark.parametrize("name", ["utfsm_mr_damper", "boucwen_benchmark"])
def test_real_data_have_plausible_units(data_dir, name):
    from hystdisc.data import load

    rig = Path(__file__).resolve().parents[2] / "data_synth" / "rigs" / f"{name}.toml"
    assert _unit_warnings(lambda: load(data_dir / name, rig=rig)) == []


def test_a_folder_in_other_units_is_warned_once(data_dir):
    """30 MR damper files read without the rig's units (mm taken as m): one warning for
    the dataset, not one per file."""
    from hystdisc.data import load, read_rig

    rig = read_rig(Path(__file__).resolve().parents[2] / "data_synth/rigs/utfsm_mr_damper.toml")
    rig = {k: v for k, v in rig.items() if k not in ("units", "path")}
    texts = _unit_warnings(lambda: load(data_dir / "utfsm_mr_damper", rig=rig))
    assert texts == [
        f"{data_dir / 'utfsm_mr_damper'}: theta reaches 25.63, more than 6 m as a damper's "
        "displacement and more than a turn as an angle: is it in millimetres or degrees? "
        "(fix: --units theta=mm or --units theta=deg)"
    ]
