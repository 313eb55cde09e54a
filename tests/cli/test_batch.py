"""``hystdisc discover --each`` over several datasets: ``--jobs`` and ``--scheduler`` give
byte-identical ``results.json`` files to the serial run."""

from __future__ import annotations

import gc
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hystdisc.cli import batch, build_parser, main
from hystdisc.cli.batch import discover_many
from hystdisc.cli.common import discovery_options
from hystdisc.data import write_csv
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

# small datasets: 3 currents, 3 s; a reduced family list keeps the test well under a minute
OPTS = ["--families", "dahl,bouc-wen", "--quiet", "--force"]
#: Dask's own connection timeout in s (``distributed.comm.timeouts.connect``), which
#: ``--scheduler`` replaces by :data:`hystdisc.cluster.CONNECT_TIMEOUT`.
DASK_DEFAULT = 30.0


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


def _tasks_done(cluster) -> int:
    """How many ``discover_one`` tasks the cluster's scheduler has completed."""
    prefix = cluster.scheduler.task_prefixes.get("discover_one")
    return prefix.state_counts["memory"] if prefix is not None else 0


def test_scheduler_is_byte_identical_to_serial(datasets, serial, cluster, tmp_path):
    before = _tasks_done(cluster)
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
    assert _tasks_done(cluster) - before == len(datasets)  # the cluster did the work
    got = {p.name: p.read_bytes() for p in sorted(tmp_path.glob("*.results.json"))}
    assert got == serial  # results.json has no timing field: byte-identical


def test_scheduler_accepts_a_client_and_reports_progress(datasets, serial, cluster):
    from distributed import Client, get_task_stream

    # the estimator options of the CLI run that wrote ``serial``
    options = discovery_options(build_parser().parse_args(["discover", "x.csv", *OPTS]))
    messages: list[str] = []
    with Client(cluster, set_as_default=False) as client:
        with get_task_stream(client) as stream:
            items = discover_many(
                datasets[:1],
                discovery_options=options,
                scheduler=client,
                progress=messages.append,
            )
        assert client.status == "running"  # a client passed in is not closed
        workers = set(client.scheduler_info()["workers"])
    assert [t["worker"] for t in stream.data] and {t["worker"] for t in stream.data} <= workers
    assert items[0].error is None and items[0].family == "dahl"
    assert items[0].results_json.encode() == serial["dahl_rig.results.json"]
    assert messages == [f"dataset 1/1 done: {datasets[0]} -> family dahl"]


def test_unreachable_scheduler_is_one_line_within_the_timeout(datasets, tmp_path):
    # a separate interpreter, so that a traceback printed by a finaliser at exit is seen too;
    # it prints how long main() took after the imports, to tell the wait from the start-up
    argv = ["discover", *map(str, datasets), "--each", "--scheduler", "tcp://127.0.0.1:1"]
    argv += ["--out", str(tmp_path), *OPTS]
    code = (
        "import sys, time\nimport distributed, hystdisc.cli.batch, hystdisc.cli.discover\n"
        "from hystdisc.cli import main\n"
        f"t = time.monotonic()\nrc = main({argv!r})\n"
        "print(f'{time.monotonic() - t:.3f}')\nsys.exit(rc)\n"
    )
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    total = time.monotonic() - t0
    assert proc.returncode == 2
    assert proc.stderr == (
        "hystdisc: error: --scheduler tcp://127.0.0.1:1: cannot connect: no Dask scheduler "
        "answered within 5 s; fix: start one with 'dask scheduler' (and workers with "
        "'dask worker ADDRESS'), or check the address\n"
    )
    waited = float(proc.stdout)
    # the 5 s connection timeout, not dask's 30 s default: the bound is halfway between
    # the two, so that a loaded machine (8.9 s with three benchmark jobs beside the
    # suite) does not fail a wait that is ours
    assert batch.CONNECT_TIMEOUT - 0.5 < waited < (batch.CONNECT_TIMEOUT + DASK_DEFAULT) / 2
    # and no half-closed client that holds the exit for 40 s (start-up takes a few seconds)
    assert total - waited < 30
    assert not list(tmp_path.glob("*.results.json"))


@pytest.mark.parametrize(
    "address, reason",
    [
        ("foo://x", "unknown address scheme 'foo'"),
        ("tcp://127.0.0.1", "missing port number"),
        ("tcp://127.0.0.1:99999", "port 99999 is not between 1 and 65535"),
    ],
)
def test_malformed_scheduler_address_is_one_line_at_once(
    datasets, tmp_path, capsys, monkeypatch, address, reason
):
    pytest.importorskip("distributed")
    unraisable: list[object] = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    t0 = time.process_time()
    rc = main(["discover", *map(str, datasets), "--each", "--scheduler", address, *OPTS])
    gc.collect()  # a half-made Client would complain from its finaliser here
    err = capsys.readouterr().err
    assert rc == 2 and not unraisable
    assert err.startswith(f"hystdisc: error: --scheduler {address}: not a Dask scheduler address (")
    assert reason in err
    assert err.endswith("; fix: give the address the scheduler prints, e.g. tcp://10.0.0.5:8786\n")
    assert err.count("\n") == 1
    assert time.process_time() - t0 < 2.0  # no connection attempt


# run on the workers with exec (a builtin, so nothing of this module needs pickling)
_HIDE_HYSTDISC = """
import sys
for name in [m for m in sys.modules if m == "hystdisc" or m.startswith("hystdisc.")]:
    del sys.modules[name]
sys.modules["hystdisc"] = None
"""
_SHOW_HYSTDISC = "import sys; sys.modules.pop('hystdisc', None)"
_OLD_VERSION = "import hystdisc; hystdisc.__version__ = '0.0.1'"
_OWN_VERSION = "import importlib, hystdisc; importlib.reload(hystdisc)"


@pytest.mark.parametrize(
    "break_code, fix_code, needle",
    [
        (_OLD_VERSION, _OWN_VERSION, "has hystdisc 0.0.1, this machine "),
        (
            _HIDE_HYSTDISC,
            _SHOW_HYSTDISC,
            "cannot import hystdisc (ModuleNotFoundError: No module named",
        ),
    ],
    ids=["other-version", "not-installed"],
)
def test_workers_without_this_hystdisc_are_one_line(
    datasets, cluster, tmp_path, capsys, break_code, fix_code, needle
):
    from distributed import Client

    before = _tasks_done(cluster)
    with Client(cluster, set_as_default=False) as client:
        client.run(exec, break_code, {})
        try:
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
        finally:
            client.run(exec, fix_code, {})
    err = capsys.readouterr().err
    assert rc == 2
    assert err.startswith(f"hystdisc: error: --scheduler {cluster.scheduler_address}: the Dask ")
    assert needle in err
    assert "fix: pip install hystdisc==" in err and err.count("\n") == 1
    assert _tasks_done(cluster) == before  # refused before any dataset was sent
    assert not list(tmp_path.glob("*.results.json"))


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
