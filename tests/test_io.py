"""Tests for hystdisc.data.io: readers, writers, checks, noise estimate, trimming."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from hystdisc.data.io import (
    EXPERIMENTS,
    Dataset,
    Run,
    atomic_write_text,
    current_from_name,
    distinct_currents,
    estimate_noise,
    load,
    read_csv,
    read_mat,
    read_rig,
    read_table,
    trim_release,
    validate,
    write_csv,
)
from hystdisc.errors import HystdiscError

RIG_TOML = """\
experiment = "driven"
[columns]        # 0-based indices for whitespace tables
t = 0
theta = 1
theta_dot = 2
torque = 3
[units]
theta = "mm"
theta_dot = "mm/s"
torque = "N"
[current]
from_name = '(\\d+(?:x\\d+)?)A$'
decimal = "x"
"""


# ----------------------------------------------------------------------------- helpers


def make_run(
    name: str, current: float, n: int = 200, fs: float = 1000.0, seed: int = 0, **kw
) -> Run:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    theta = 0.3 * np.exp(-t) * np.cos(2 * np.pi * 3 * t) + rng.normal(0, 1e-4, n)
    return Run(name, t, theta, current, **kw)


def make_dataset(experiment: str, currents=(0.0, 0.5, 1.0), with_dot: bool = False) -> Dataset:
    runs = []
    for i, cur in enumerate(currents):
        r = make_run(str(i), cur, seed=i)
        rng = np.random.default_rng(100 + i)
        extra = rng.normal(size=r.n) * 12.345678901
        if experiment == "driven":
            r.torque = extra
        elif experiment == "forced":
            r.input = extra
        if with_dot:
            r.theta_dot = np.gradient(r.theta, r.t)
        runs.append(r)
    return Dataset(runs, experiment, "mem")


def write_lines(path: Path, header: str | None, rows: list[str]) -> Path:
    text = ((header + "\n") if header else "") + "\n".join(rows) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


def good_rows(
    n: int = 40, run: str | None = "0", current: float = 0.5, extra: bool = False
) -> list[str]:
    rows = []
    for k in range(n):
        cells = [] if run is None else [run]
        cells += [f"{k * 0.001:.3f}", f"{math.sin(0.3 * k):.6f}", f"{current}"]
        if extra:
            cells.append(f"{math.cos(0.3 * k):.6f}")
        rows.append(",".join(cells))
    return rows


def check_message(exc: pytest.ExceptionInfo, *words: str) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    assert "fix:" in msg
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    return msg


def assert_close(a, b, rtol: float = 1e-9) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    scale = np.maximum(np.abs(b), np.max(np.abs(b)) * 1e-12 + 1e-300)
    assert np.all(np.abs(a - b) <= rtol * scale + 1e-15)


# ----------------------------------------------------------------------------- data model


def test_run_converts_arrays_and_properties():
    r = Run(
        3, [[0.0, 0.01, 0.02, 0.03]], np.array([1, 2, 3, 4])[:, None], "0.5", torque=[1, 2, 3, 4]
    )
    assert r.name == "3" and r.current == 0.5
    assert r.t.dtype == np.float64 and r.t.ndim == 1 and r.theta.shape == (4,)
    assert r.torque.dtype == np.float64
    assert r.n == 4 and r.fs == pytest.approx(100.0) and r.duration == pytest.approx(0.03)
    with pytest.raises(HystdiscError, match="shape"):
        Run("x", np.zeros((3, 2)), np.zeros(6), 0.0)


def test_dataset_api():
    ds = make_dataset("driven")
    assert len(ds) == 3 and [r.name for r in ds] == ["0", "1", "2"]
    assert ds.measured() == "torque" and make_dataset("forced").measured() == "theta"
    assert make_dataset("release").measured() == "theta"
    assert ds.currents.tolist() == [0.0, 0.5, 1.0]
    assert ds.subset([2, 0]).names == ["2", "0"]
    assert ds.subset(["1"]).currents.tolist() == [0.5]
    assert ds.subset([True, False, True]).names == ["0", "2"]
    assert ds.subset(slice(1, None)).names == ["1", "2"]
    text = repr(ds)
    assert "driven" in text and "3 runs" in text and "0, 0.5, 1" in text and "600 samples" in text
    assert set(EXPERIMENTS) == {"release", "driven", "forced"}
    with pytest.raises(HystdiscError, match="unknown experiment"):
        Dataset([], "shaken", "x.csv")


def test_distinct_currents_tolerance():
    assert distinct_currents([0, 0.01, 0.5, 0.51, 1.0]).size == 3
    assert distinct_currents([0.0, 0.25, 0.5, 0.75, 1.0]).size == 5


# ----------------------------------------------------------------------------- CSV


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


# ----------------------------------------------------------------------------- writing


def test_overwrite_refused_then_forced(tmp_path):
    ds = make_dataset("release")
    p = write_csv(ds, tmp_path / "out.csv")
    before = p.read_text()
    with pytest.raises(HystdiscError) as exc:
        write_csv(make_dataset("release", currents=(2.0,)), p)
    check_message(exc, "out.csv", "exists", "--force")
    assert p.read_text() == before
    write_csv(make_dataset("release", currents=(2.0,)), p, force=True)
    assert read_csv(p).currents.tolist() == [2.0]
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]  # no temp files left behind


def test_atomic_write_leaves_no_temp_file_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "results.json"
    atomic_write_text(target, "old\n")

    def boom(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(HystdiscError) as exc:
        atomic_write_text(target, "new\n", force=True)
    check_message(exc, "results.json", "No space left")
    monkeypatch.undo()
    assert target.read_text() == "old\n"
    assert os.listdir(tmp_path) == ["results.json"]


def test_atomic_write_creates_parent_and_keeps_umask_mode(tmp_path):
    p = atomic_write_text(tmp_path / "sub" / "report.html", "<html></html>")
    assert p.read_text() == "<html></html>"
    umask = os.umask(0)
    os.umask(umask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~umask)
    with pytest.raises(HystdiscError, match="is a directory"):
        atomic_write_text(tmp_path / "sub", "x", force=True)


# ----------------------------------------------------------------------------- tables, rigs


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


def write_table_dir(folder: Path, currents=("0", "0x5", "1"), rig: bool = True) -> Path:
    folder.mkdir(exist_ok=True)
    rng = np.random.default_rng(7)
    for cur in currents:
        t = np.arange(300) * 0.005
        x = 10.0 * np.sin(2 * np.pi * t)
        v = np.gradient(x, t)
        f = (100 + 300 * float(cur.replace("x", "."))) * np.tanh(v / 5) + rng.normal(0, 1, t.size)
        np.savetxt(folder / f"10mm1Hz{cur}A.txt", np.column_stack([t, x, v, f]), fmt="%.7e")
    (folder / "README.md").write_text("not data")
    if rig:
        (folder / "rig.toml").write_text(RIG_TOML)
    return folder


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


def test_load_concatenates_and_prefixes_colliding_run_names(tmp_path):
    a = write_lines(tmp_path / "a.csv", "run,t,theta,current", good_rows(30, "0", 0.0))
    b = write_lines(tmp_path / "b.csv", "run,t,theta,current", good_rows(30, "0", 1.0))
    ds = load([a, b])
    assert ds.names == ["a:0", "b:0"] and ds.currents.tolist() == [0.0, 1.0]
    c = write_lines(tmp_path / "c.csv", "run,t,theta,current", good_rows(30, "7", 0.5))
    assert load([a, c]).names == ["0", "7"]


# ----------------------------------------------------------------------------- MATLAB


def test_mat_round_trip_vectors(tmp_path):
    ds = make_dataset("driven", currents=(0.75,))
    r = ds[0]
    p = tmp_path / "run.mat"
    scipy.io.savemat(
        p, {"t": r.t[None, :], "theta": r.theta[:, None], "torque": r.torque, "current": 0.75}
    )
    back = read_mat(p)
    assert back.experiment == "driven" and back[0].current == 0.75
    assert np.array_equal(back[0].t, r.t) and np.array_equal(back[0].theta, r.theta)
    assert np.array_equal(back[0].torque, r.torque)
    assert np.array_equal(load(p)[0].theta, r.theta)


def test_mat_names_matrix_and_fs(tmp_path):
    rng = np.random.default_rng(3)
    n = 120
    angle = np.sin(np.arange(n) / 7.0) * 30.0
    p = tmp_path / "sas.mat"
    scipy.io.savemat(p, {"Angle": angle, "I": 0.5})
    ds = read_mat(p, columns={"theta": "angle", "current": "I"}, units={"theta": "deg"}, fs=1000.0)
    assert ds.experiment == "release" and ds[0].current == 0.5
    assert ds[0].theta == pytest.approx(np.radians(angle)) and ds[0].fs == pytest.approx(1000.0)
    m = np.column_stack([np.arange(n) * 1e-3, angle, rng.normal(size=n)])
    q = tmp_path / "matrix.mat"
    scipy.io.savemat(q, {"data": m.T})  # channels as rows: transposed automatically
    ds2 = read_mat(q, "forced", columns={"t": 0, "theta": 1, "input": 2}, current=0.0)
    assert np.array_equal(ds2[0].input, m[:, 2]) and ds2[0].n == n


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


# ----------------------------------------------------------------------------- bad input


def csv_with(tmp_path: Path, name: str, header: str, rows: list[str]) -> Path:
    return write_lines(tmp_path / name, header, rows)


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


def test_error_current_varies_within_run(tmp_path):
    rows = [f"r5,{k * 0.001:.3f},{math.sin(k)},{0.0 if k < 20 else 1.0}" for k in range(40)]
    with pytest.raises(HystdiscError) as exc:
        read_csv(csv_with(tmp_path, "cur.csv", "run,t,theta,current", rows))
    check_message(exc, "cur.csv", "run r5", "current varies", "line 22", "split")


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


def test_error_mixed_experiments(tmp_path):
    a = csv_with(tmp_path, "rel.csv", "run,t,theta,current", good_rows(30))
    b = csv_with(tmp_path, "drv.csv", "run,t,theta,current,torque", good_rows(30, "1", extra=True))
    with pytest.raises(HystdiscError) as exc:
        load([a, b])
    check_message(exc, "rel.csv: release", "drv.csv: driven", "different experiment types")
    assert load([a, b], experiment="release").names == ["0", "1"]


def test_error_units_and_experiment_names(tmp_path):
    p = csv_with(tmp_path, "u.csv", "run,t,theta,current", good_rows(30))
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, units={"theta": "furlong"})
    check_message(exc, "u.csv", "unknown unit 'furlong'", "deg")
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, units={"angle": "deg"})
    check_message(exc, "u.csv", "unknown column 'angle'")
    with pytest.raises(HystdiscError) as exc:
        read_csv(p, experiment="dropped")
    check_message(exc, "u.csv", "unknown experiment type 'dropped'", "release, driven, forced")


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


def test_error_bad_mat_files(tmp_path):
    p = tmp_path / "junk.mat"
    p.write_bytes(b"this is not a mat file at all" * 10)
    with pytest.raises(HystdiscError) as exc:
        read_mat(p)
    check_message(exc, "junk.mat", "not a readable MATLAB")
    q = tmp_path / "novar.mat"
    scipy.io.savemat(q, {"angle": np.arange(50.0), "current": 0.1})
    with pytest.raises(HystdiscError) as exc:
        read_mat(q)
    check_message(exc, "novar.mat", "'theta' is missing", "angle")
    with pytest.raises(HystdiscError) as exc:
        read_mat(q, columns={"theta": "angle"})
    check_message(exc, "novar.mat", "no time variable", "fs")
    r = tmp_path / "nocur.mat"
    scipy.io.savemat(r, {"theta": np.sin(np.arange(50.0)), "t": np.arange(50.0)})
    with pytest.raises(HystdiscError) as exc:
        read_mat(r)
    check_message(exc, "nocur.mat", "run 0", "no coil current")


# ----------------------------------------------------------------------------- noise, trimming


def test_estimate_noise_gaussian_within_10_percent():
    t = np.arange(6000) / 1000.0
    signal = 0.2 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        est = estimate_noise(signal + rng.normal(0, 1e-3, t.size), 1000.0)
        assert est == pytest.approx(1e-3, rel=0.10)


def test_estimate_noise_quantized_signal():
    t = np.arange(6000) / 1000.0
    q = 1e-3
    theta = np.round(np.exp(-0.3 * t) * np.cos(2 * np.pi * 1.5 * t) / q) * q
    assert estimate_noise(theta, 1000.0) == pytest.approx(q / math.sqrt(12), rel=0.15)


def test_estimate_noise_ignores_spikes_and_noiseless_is_zero():
    rng = np.random.default_rng(5)
    t = np.arange(5000) / 1000.0
    x = np.sin(2 * np.pi * t) + rng.normal(0, 1e-3, t.size)
    x[rng.integers(0, t.size, 5)] += 0.5
    assert estimate_noise(x, 1000.0) == pytest.approx(1e-3, rel=0.10)
    assert estimate_noise(1 + 2 * t + 0.5 * t**2) < 1e-12
    with pytest.raises(HystdiscError, match="too few"):
        estimate_noise(np.zeros(5))


def test_trim_release_cuts_dead_tail():
    rng = np.random.default_rng(1)
    t = np.arange(10000) / 1000.0
    theta = np.exp(-2.0 * t) * np.cos(2 * np.pi * 2 * t) + rng.normal(0, 1e-3, t.size)
    run = Run("0", t, theta, 0.0, theta_dot=np.zeros(t.size))
    short = trim_release(run, 1e-3)
    dies = math.log(1 / 3e-3) / 2.0  # amplitude reaches 3 noise std
    assert dies - 0.3 < short.duration < dies + 1.0
    assert short.theta_dot.size == short.n and run.n == 10000  # input untouched
    # a record that never settles is kept whole; a dead one keeps min_samples
    assert trim_release(Run("1", t, np.sin(t * 6) + theta, 0.0), 1e-3).n == 10000
    assert trim_release(Run("2", t, rng.normal(0, 1e-3, t.size), 0.0), 1e-3).n == 200


# ----------------------------------------------------------------------------- real data


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
