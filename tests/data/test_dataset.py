"""The data structures: Run, Dataset, current levels, the experiment's columns."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc import registry
from hystdisc.data import (
    EXPERIMENTS,
    Dataset,
    Run,
    distinct_currents,
)
from hystdisc.data.dataset import extra_column, needed_columns
from hystdisc.errors import HystdiscError
from hystdisc.registry import get_experiment

from .helpers import check_message, make_dataset


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


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_columns_and_output_follow_the_experiment_objects(name):
    exp = get_experiment(name)
    ds = make_dataset(name)
    assert ds.measured() == exp.output
    assert extra_column(name) == exp.extra_column
    needed = needed_columns(name)
    assert needed[:3] == ["t", "theta", "current"]
    assert needed[3:] == ([exp.extra_column] if exp.extra_column else [])
    assert EXPERIMENTS == registry.experiment_names()


def test_subset_errors_name_the_run_and_the_fix():
    ds = make_dataset("release")
    with pytest.raises(HystdiscError) as exc:
        ds.subset([True, False])
    check_message(exc, "mem", "boolean mask has 2 entries for 3 runs")
    with pytest.raises(HystdiscError) as exc:
        ds["nope"]
    check_message(exc, "no run named 'nope'", "use one of 0, 1, 2")
    with pytest.raises(HystdiscError) as exc:
        ds[3]
    check_message(exc, "run index 3 is out of range (3 runs)", "from 0 to 2")
