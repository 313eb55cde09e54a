"""``hystdisc discover --each`` over several datasets: ``--jobs`` and ``--scheduler`` give
byte-identical ``results.json`` files to the serial run."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from hystdisc.cli import main
from hystdisc.io import write_csv
from hystdisc.models import Model
from hystdisc.synth import generate

# small datasets: 3 currents, 3 s; a reduced family list keeps the test well under a minute
OPTS = ["--families", "dahl,bouc-wen", "--quiet", "--force"]


@pytest.fixture(scope="module")
def datasets(tmp_path_factory) -> list[Path]:
    d = tmp_path_factory.mktemp("batch")
    a = write_csv(
        generate(
            Model("dahl", {"rho": 15.0, "k_wb": 1.2}), currents=(0, 0.5, 1), duration=3, seed=21
        ),
        d / "dahl_rig.csv",
    )
    b = write_csv(
        generate(Model("bouc-wen", {"c_2": 0.4}), currents=(0, 0.5, 1), duration=3, seed=22),
        d / "bw_rig.csv",
    )
    return [Path(a), Path(b)]


@pytest.fixture(scope="module")
def serial(datasets, tmp_path_factory) -> dict[str, bytes]:
    out = tmp_path_factory.mktemp("serial")
    assert main(["discover", *map(str, datasets), "--each", "--out", str(out), *OPTS]) == 0
    return {p.name: p.read_bytes() for p in sorted(out.glob("*.results.json"))}


def test_serial_writes_one_results_file_per_dataset(serial):
    assert sorted(serial) == ["bw_rig.results.json", "dahl_rig.results.json"]
    assert b'"family": "dahl"' in serial["dahl_rig.results.json"]
    assert b'"family": "bouc-wen"' in serial["bw_rig.results.json"]


def test_each_serial_equals_single_dataset_run(datasets, serial, tmp_path):
    out = tmp_path / "one.json"
    assert main(["discover", str(datasets[0]), "--json", str(out), *OPTS]) == 0
    assert out.read_bytes() == serial["dahl_rig.results.json"]


def test_jobs_is_byte_identical_to_serial(datasets, serial, tmp_path):
    assert (
        main(
            [
                "discover",
                *map(str, datasets),
                "--each",
                "--jobs",
                "2",
                "--out",
                str(tmp_path),
                *OPTS,
            ]
        )
        == 0
    )
    got = {p.name: p.read_bytes() for p in sorted(tmp_path.glob("*.results.json"))}
    assert got == serial


def test_scheduler_is_byte_identical_to_serial(datasets, serial, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        rc = main(
            [
                "discover",
                *map(str, datasets),
                "--each",
                "--scheduler",
                cluster.scheduler_address,
                "--out",
                str(tmp_path),
                *OPTS,
            ]
        )
    assert rc == 0
    got = {p.name: p.read_bytes() for p in sorted(tmp_path.glob("*.results.json"))}
    assert got == serial


def test_scheduler_without_dask_is_one_line(datasets, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    rc = main(
        [
            "discover",
            *map(str, datasets),
            "--each",
            "--scheduler",
            "tcp://127.0.0.1:1",
            "--out",
            str(tmp_path),
            *OPTS,
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err == (
        "hystdisc: error: --scheduler needs dask.distributed; fix: pip install hystdisc[dask]"
    )


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--jobs", "2"], "--jobs runs several datasets in parallel"),
        (["--each", "--jobs", "0"], "--jobs 0: not a number of processes"),
        (["--each", "--json", "x.json"], "--json names one results file"),
    ],
)
def test_bad_batch_flags_are_one_line(datasets, tmp_path, capsys, extra, needle):
    rc = main(["discover", *map(str, datasets), "--out", str(tmp_path), *extra, *OPTS])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert needle in err and "fix:" in err and "\n" not in err
    assert not list(tmp_path.glob("*.results.json"))


def test_existing_output_is_kept_without_force(datasets, tmp_path, capsys):
    (tmp_path / "bw_rig.results.json").write_text("mine\n")
    opts = [o for o in OPTS if o != "--force"]
    rc = main(["discover", *map(str, datasets), "--each", "--out", str(tmp_path), *opts])
    assert rc == 2
    assert "exists; fix: pass --force" in capsys.readouterr().err
    assert (tmp_path / "bw_rig.results.json").read_text() == "mine\n"


def test_a_bad_dataset_does_not_stop_the_others(datasets, tmp_path, capsys):
    bad = tmp_path / "broken.csv"
    bad.write_text("run,t,angle\n0,0,0.1\n")
    rc = main(
        [
            "discover",
            str(bad),
            str(datasets[0]),
            "--each",
            "--jobs",
            "2",
            "--out",
            str(tmp_path),
            *OPTS,
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2
    assert "broken.csv" in err and "1 of 2 datasets failed" in err
    assert (tmp_path / "dahl_rig.results.json").exists()
    assert not (tmp_path / "broken.results.json").exists()
