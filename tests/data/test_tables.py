"""Header-less tables, rig descriptions and currents in file names."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hystdisc.data import (
    current_from_name,
    load,
    read_rig,
    read_table,
    validate,
)
from hystdisc.data.rigs import normalize_rig
from hystdisc.errors import HystdiscError

from .helpers import (
    RIG_TOML,
    check_message,
    write_lines,
    write_table_dir,
)


@pytest.mark.parametrize(
    ("stem", "current"),
    [("25mm0x25Hz0x75A", 0.75), ("10mm1Hz1A", 1.0), ("2mm5Hz0A", 0.0), ("10mm1Hz0x5A.txt", 0.5)],
)
def test_current_from_name(stem, current):
    assert current_from_name(stem) == current


def test_current_from_name_no_match():
    with pytest.raises(HystdiscError) as exc:
        current_from_name("sine_test_3.txt")
    check_message(exc, "sine_test_3", "does not match", "[current] value")


def test_rig_toml_directory_load(tmp_path):
    folder = write_table_dir(tmp_path / "rig_data")
    ds = load(folder)  # rig.toml in the folder is used automatically
    assert ds.experiment == "driven" and len(ds) == 3
    assert ds.names == ["10mm1Hz0A", "10mm1Hz0x5A", "10mm1Hz1A"]
    assert ds.currents.tolist() == [0.0, 0.5, 1.0]
    r = ds[0]
    assert np.ptp(r.theta) == pytest.approx(0.02, rel=1e-3)  # mm -> m
    assert r.theta_dot is not None and r.torque is not None
    assert r.fs == pytest.approx(200.0)
    validate(ds, need_currents=2)


def test_rig_as_path_and_dict_and_overrides(tmp_path):
    folder = write_table_dir(tmp_path / "d", rig=False)
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML)
    rig = read_rig(rig_path)
    assert rig["experiment"] == "driven" and rig["columns"]["torque"] == 3
    assert rig["current"] == {"value": None, "from_name": r"(\d+(?:x\d+)?)A$", "decimal": "x"}
    a = load(folder, rig=rig_path)
    b = load(sorted(folder.glob("*.txt")), rig=rig)
    assert a.names == b.names and np.array_equal(a[2].torque, b[2].torque)
    c = load(folder / "10mm1Hz1A.txt", rig=rig, units={"theta": "m"})
    assert np.ptp(c[0].theta) == pytest.approx(20.0, rel=1e-3)
    d = load(
        folder / "10mm1Hz1A.txt", rig={"columns": {"t": 0, "theta": 1, "torque": 3}, "current": 0.3}
    )
    assert d.experiment == "driven" and d[0].current == 0.3 and d[0].theta_dot is None


def test_read_table_direct_with_skip_rows_and_fs(tmp_path):
    p = tmp_path / "release_5.dat"
    rows = [f"{math.cos(0.1 * k) * math.exp(-0.01 * k):.8f}" for k in range(100)]
    write_lines(p, "angle_deg", rows)
    ds = read_table(
        p, {"theta": 0}, "release", units={"theta": "deg"}, current=0.25, skip_rows=1, fs=50.0
    )
    assert ds[0].name == "release_5" and ds[0].current == 0.25
    assert ds[0].fs == pytest.approx(50.0) and ds[0].theta[0] == pytest.approx(math.radians(1.0))


def test_error_table_header_and_ragged(tmp_path):
    p = write_lines(tmp_path / "hdr.txt", "time x v F", ["0 1 2 3"] * 30)
    with pytest.raises(HystdiscError) as exc:
        read_table(p, {"t": 0, "theta": 1, "torque": 3}, "driven", current=0.0)
    check_message(exc, "hdr.txt", "'time'", "line 1", "skip_rows")
    q = write_lines(
        tmp_path / "rag.txt", None, [f"{k} {k} {k} {k}" for k in range(30)] + ["30 1 2"]
    )
    with pytest.raises(HystdiscError) as exc:
        read_table(q, {"t": 0, "theta": 1, "torque": 3}, "driven", current=0.0)
    check_message(exc, "rag.txt", "line 31", "3 fields, expected 4")


def test_error_table_without_rig(tmp_path):
    folder = write_table_dir(tmp_path / "norig", rig=False)
    with pytest.raises(HystdiscError) as exc:
        load(folder)
    check_message(exc, "10mm1Hz0A.txt", "without header", "rig.toml")


def test_error_table_name_without_current(tmp_path):
    folder = write_table_dir(tmp_path / "d", currents=("0",))
    (folder / "10mm1Hz0A.txt").rename(folder / "sine.txt")
    with pytest.raises(HystdiscError) as exc:
        load(folder)
    check_message(exc, "sine.txt", "does not match the current pattern")


def test_error_bad_rig_files(tmp_path):
    bad = tmp_path / "rig.toml"
    bad.write_text('experiment = "driven"\n[columns\nt = 0\n')
    with pytest.raises(HystdiscError) as exc:
        read_rig(bad)
    check_message(exc, "rig.toml", "not valid TOML", "line 2")
    bad.write_text('experiment = "driven"\ncolums = {t = 0}\n')
    with pytest.raises(HystdiscError) as exc:
        read_rig(bad)
    check_message(exc, "rig.toml", "unknown rig setting", "'colums'")


@pytest.mark.parametrize(
    ("rig", "words"),
    [
        ({"current": "0.5 A"}, ("[current] must be a table or a number",)),
        ({"current": {"amps": 1}}, ("unknown [current] setting(s) 'amps'",)),
        ({"current": {"value": float("nan")}}, ("[current] value nan is not a number",)),
        ({"current": {"from_name": "("}}, ("is not a valid regex",)),
        ({"skip_rows": -1}, ("skip_rows = -1 is invalid",)),
        ({"skip_rows": True}, ("skip_rows = True is invalid",)),
        ({"fs": 0}, ("fs = 0 is invalid",)),
        ({"units": "mm"}, ("[units] must be a table",)),
        ({"units": {"theta": "parsec"}}, ("unknown unit 'parsec'",)),
        ({"experiment": "shaken"}, ("unknown experiment type 'shaken'",)),
    ],
)
def test_rig_settings_are_checked(rig, words):
    with pytest.raises(HystdiscError) as exc:
        normalize_rig(rig, "rig.toml")
    check_message(exc, "rig.toml", *words)


def test_rig_defaults_and_a_bare_current():
    rig = normalize_rig({"current": 0.5, "fs": 100, "name": 7}, "r")
    assert rig == {
        "experiment": None,
        "columns": {},
        "units": {},
        "current": {"value": 0.5, "from_name": None, "decimal": "x"},
        "skip_rows": 0,
        "fs": 100.0,
        "path": "r",
        "name": "7",
        "filter": None,
    }
