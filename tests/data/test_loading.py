"""load(): several files and folders joined into one dataset; the measured rig folder."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from hystdisc.data import (
    distinct_currents,
    load,
    validate,
)
from hystdisc.errors import HystdiscError

from .helpers import (
    check_message,
    csv_with,
    good_rows,
    write_lines,
)


def test_load_concatenates_and_prefixes_colliding_run_names(tmp_path):
    a = write_lines(tmp_path / "a.csv", "run,t,theta,current", good_rows(30, "0", 0.0))
    b = write_lines(tmp_path / "b.csv", "run,t,theta,current", good_rows(30, "0", 1.0))
    ds = load([a, b])
    assert ds.names == ["a:0", "b:0"] and ds.currents.tolist() == [0.0, 1.0]
    c = write_lines(tmp_path / "c.csv", "run,t,theta,current", good_rows(30, "7", 0.5))
    assert load([a, c]).names == ["0", "7"]


def test_load_merges_mat_files_holding_input_and_output(tmp_path):
    rng = np.random.default_rng(4)
    u, y = rng.normal(size=(1, 500)), np.cumsum(rng.normal(size=(1, 500)), axis=1)
    scipy.io.savemat(tmp_path / "u.mat", {"u": u})
    scipy.io.savemat(tmp_path / "y.mat", {"y": y})
    ds = load(
        tmp_path, experiment="forced", columns={"theta": "y", "input": "u"}, fs=750.0, current=0.0
    )
    assert len(ds) == 1 and ds[0].n == 500 and ds[0].fs == pytest.approx(750.0)
    assert np.array_equal(ds[0].input, u[0])


def test_error_mixed_experiments(tmp_path):
    a = csv_with(tmp_path, "rel.csv", "run,t,theta,current", good_rows(30))
    b = csv_with(tmp_path, "drv.csv", "run,t,theta,current,torque", good_rows(30, "1", extra=True))
    with pytest.raises(HystdiscError) as exc:
        load([a, b])
    check_message(exc, "rel.csv: release", "drv.csv: driven", "different experiment types")
    assert load([a, b], experiment="release").names == ["0", "1"]


def test_real_utfsm_mr_damper_folder():
    root = os.environ.get("HYSTDISC_DATA")
    if not root:
        pytest.skip("HYSTDISC_DATA is not set; point it to the shared data folder to run this test")
    folder = Path(root) / "utfsm_mr_damper"
    if not folder.is_dir():
        pytest.skip(f"{folder} does not exist")
    rig = {
        "experiment": "driven",
        "columns": {"t": 0, "theta": 1, "theta_dot": 2, "torque": 3},
        "units": {"theta": "mm", "theta_dot": "mm/s", "torque": "N"},
        "current": {"from_name": r"(\d+(?:x\d+)?)A$", "decimal": "x"},
    }
    ds = load(folder, rig=rig)
    assert len(ds) == 30 and ds.experiment == "driven"
    assert set(distinct_currents(ds.currents).tolist()) == {0.0, 0.25, 0.5, 0.75, 1.0}
    assert sorted({round(r.fs) for r in ds}) == [200, 1000]
    run = ds["10mm1Hz1A"]
    assert np.ptp(run.theta) == pytest.approx(0.0194, rel=0.01)  # 10 mm amplitude, in m
    assert 1400 < np.max(np.abs(run.torque)) < 1600
    validate(ds, need_currents=5)


def test_load_same_file_twice_numbers_the_repeated_names(tmp_path):
    a = write_lines(tmp_path / "a.csv", "run,t,theta,current", good_rows(30, "0", 0.0))
    ds = load([a, a])
    assert ds.names == ["a:0", "a:0#2"] and ds.source == f"{a}, {a}"


def test_load_label_of_many_files_and_folder_without_data(tmp_path):
    files = [
        write_lines(tmp_path / f"f{i}.csv", "run,t,theta,current", good_rows(30, str(i), i))
        for i in range(5)
    ]
    ds = load(files)
    assert ds.source == f"{files[0]} and 4 more files" and ds.names == ["0", "1", "2", "3", "4"]
    with pytest.raises(HystdiscError) as exc:
        load([])
    check_message(exc, "no input files given")
