"""One discovery's tasks on a Dask cluster (issue 36): the same results as its threads.

A real two-worker ``LocalCluster`` on processes (the tasks are pickled to the workers); the
dataset is the bundled ``data_synth/dahl.csv`` with two term families and no closing loop
(first fits, more starts for Bingham, held-out folds), a few seconds a fit.
"""

from __future__ import annotations

import pickle
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import clone

pytest.importorskip(
    "distributed", reason="dask.distributed is not installed (pip install hystdisc[dask])"
)

from hystdisc import Discovery  # noqa: E402
from hystdisc.cli import main  # noqa: E402
from hystdisc.cluster import CONNECT_TIMEOUT, DASK_MISSING  # noqa: E402
from hystdisc.data import load  # noqa: E402
from hystdisc.errors import HystdiscError  # noqa: E402
from hystdisc.faults import Failures  # noqa: E402
from hystdisc.pipeline.tasks import ClusterTasks, Say  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "data_synth" / "dahl.csv"
OPTIONS = {"families": ["dahl", "bingham"], "close_loop": False}
CLI = ["--families", "dahl,bingham", "--no-effects", "--quiet", "--force"]


@pytest.fixture(scope="module")
def data():
    return load(str(DATA))


@pytest.fixture(scope="module")
def threaded(data) -> Discovery:
    return Discovery(**OPTIONS, n_jobs=2).fit(data)


def _tasks_done(cluster) -> int:
    """How many tasks of a discovery the cluster's scheduler has completed."""
    prefix = cluster.scheduler.task_prefixes.get("discovery_task")
    return prefix.state_counts["memory"] if prefix is not None else 0


def test_a_discovery_on_the_cluster_equals_the_threaded_one(cluster, data, threaded):
    before = _tasks_done(cluster)
    disc = Discovery(**OPTIONS, n_jobs=1, scheduler=cluster.scheduler_address).fit(data)
    assert _tasks_done(cluster) - before > 10  # the cluster fitted the families
    assert disc.family_ == threaded.family_ == "dahl"
    assert disc.failed_ == threaded.failed_
    assert list(disc.family_fits_) == list(threaded.family_fits_)
    for name, fit in threaded.family_fits_.items():
        got = disc.family_fits_[name]
        assert list(got.params) == list(fit.params)
        np.testing.assert_allclose(list(got.params.values()), list(fit.params.values()),
                                   rtol=1e-10, atol=0)  # fmt: skip
        assert got.heldout_rms == pytest.approx(fit.heldout_rms, rel=1e-10)
    # each task computes as in turn: the whole record is the same, bit for bit
    assert disc.results_.to_json() == threaded.results_.to_json()
    # an address keeps the estimator clonable and picklable
    assert clone(disc).get_params()["scheduler"] == cluster.scheduler_address
    assert pickle.loads(pickle.dumps(disc)).family_ == "dahl"


def test_the_cli_runs_one_discovery_on_the_cluster(cluster, threaded, tmp_path):
    out = tmp_path / "results.json"
    before = _tasks_done(cluster)
    argv = ["discover", str(DATA), "--scheduler", cluster.scheduler_address, "--json", str(out)]
    assert main(argv + CLI) == 0
    assert _tasks_done(cluster) > before
    assert out.read_text(encoding="utf-8") == threaded.results_.to_json()


def test_tasks_send_back_their_failures_messages_and_errors(cluster):
    from distributed import Client

    failures, said = Failures(), []
    failures.record("earlier", "kept")

    def task(k: int) -> int:
        say(f"task {k}")
        failures.guard(f"task {k}", lambda: 1 / (k - 2))  # task 2 fails, recorded
        if k == 3:
            raise ValueError("task 3 broke")
        return k * k

    say = Say(said.append)
    with Client(cluster, set_as_default=False) as client:
        tasks = ClusterTasks(client, 1, failures, say)
        assert tasks.map(task, [0, 1, 2]) == [0, 1, 4]
        assert said == ["task 0", "task 1", "task 2"]  # replayed in task order
        assert failures.items() == {
            "earlier": "kept",
            "task 2": "the computation failed (ZeroDivisionError: division by zero)",
        }
        with pytest.raises(ValueError, match="task 3 broke"):
            tasks.map(task, [3, 4])
    # as on threads: the error is raised once every task has ended, with their records
    assert said[-2:] == ["task 3", "task 4"]
    # a pickled engine is the threads of the worker it lands on
    assert type(pickle.loads(pickle.dumps(tasks))).__name__ == "ThreadTasks"


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys):
    argv = ["discover", str(DATA), "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path)]
    t0 = time.monotonic()
    assert main(argv + CLI) == 2
    assert time.monotonic() - t0 < CONNECT_TIMEOUT + 10  # before any work: no fit
    err = capsys.readouterr().err
    assert err == (
        "hystdisc: error: --scheduler tcp://127.0.0.1:1: cannot connect: no Dask scheduler "
        f"answered within {CONNECT_TIMEOUT:g} s; fix: start one with 'dask scheduler' (and "
        "workers with 'dask worker ADDRESS'), or check the address\n"
    )
    assert not list(tmp_path.iterdir())


def test_a_malformed_address_or_no_dask_is_one_line(data, monkeypatch):
    with pytest.raises(HystdiscError, match=r"^--scheduler tcp://127\.0\.0\.1: not a Dask "):
        Discovery(**OPTIONS, scheduler="tcp://127.0.0.1").fit(data)
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    with pytest.raises(HystdiscError) as exc:
        Discovery(**OPTIONS, scheduler="tcp://127.0.0.1:8786").fit(data)
    assert str(exc.value) == DASK_MISSING
