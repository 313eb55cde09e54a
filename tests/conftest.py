"""Shared test set-up: a non-interactive matplotlib backend, the measured-data folder,
the fuzz tests' scratch folder and counts, and a local Dask cluster."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The measured data folder (``../shared/data``), found through ``HYSTDISC_DATA``."""
    value = os.environ.get("HYSTDISC_DATA")
    if not value:
        pytest.skip("HYSTDISC_DATA is not set; measured-data tests need ../shared/data")
    path = Path(value)
    if not path.is_dir():
        pytest.skip(
            f"HYSTDISC_DATA={value} is not a folder; measured-data tests need ../shared/data"
        )
    return path


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    """A scratch folder shared by a module's tests (the fuzz tests write their inputs here)."""
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module")
def fuzz_counts(request):
    """After a fuzz module, the inputs it tried per reader (``tests/fuzz``)."""
    from .fuzz import report_counts

    yield
    report_counts(request)


@pytest.fixture(scope="module")
def cluster():
    """A real two-worker Dask cluster on local processes, one thread each (tasks are
    pickled to the workers); skipped without dask.distributed."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    yield cluster
    cluster.close()
