"""Units: conversion to SI, and the one-line errors for unknown units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hystdisc.data import read_csv, unit_factor
from hystdisc.data.units import apply_units
from hystdisc.errors import HystdiscError

from .helpers import (
    check_message,
    csv_with,
    good_rows,
)


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


@pytest.mark.parametrize(
    ("column", "unit", "factor"),
    [
        ("t", "ms", 1e-3),
        ("theta", "Degrees", math.pi / 180.0),
        ("theta", "µm", 1e-6),
        ("theta_dot", "rpm", 2.0 * math.pi / 60.0),
        ("theta_dot", "mm/s", 1e-3),
        ("torque", "N·m", 1.0),
        ("torque", "kN-m", 1e3),
        ("input", "lbf*in", 0.1129848290276167),
        ("current", "mA", 1e-3),
    ],
)
def test_unit_factor_spellings(column, unit, factor):
    assert unit_factor(column, unit) == factor


def test_unit_factor_names_the_column_and_the_choices():
    with pytest.raises(HystdiscError) as exc:
        unit_factor("current", "volt", "x.csv")
    msg = check_message(exc, "x.csv", "unknown unit 'volt' for column 'current'")
    assert msg.endswith("fix: use one of a, ma")


def test_apply_units_scales_only_the_given_columns_in_place():
    theta, t = np.array([1.0, 2.0]), np.array([0.0, 1.0])
    cols = {"theta": theta, "t": t}
    apply_units(cols, {"theta": "mm", "t": "s", "torque": "kN"}, "x")  # no torque column: skipped
    assert cols["theta"].tolist() == [1e-3, 2e-3] and cols["t"] is t
    apply_units(cols, None, "x")
    assert cols["theta"].tolist() == [1e-3, 2e-3]
    with pytest.raises(HystdiscError, match="units must be a mapping"):
        apply_units(cols, ["mm"], "x")  # type: ignore[arg-type]
