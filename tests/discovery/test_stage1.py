"""Stage 1 on its own: equation-error data, shape search, term selection, starts."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data import estimate_noise
from hystdisc.discovery import (
    DEFAULT_TORQUE_TERMS,
    SHAPES,
    EqData,
    describe_structure,
    differentiate,
    family_start,
    fit_shape,
)
from hystdisc.discovery.selection import EQ_RSS_FLOOR
from hystdisc.models import Model
from hystdisc.simulation.synth import generate
from hystdisc.stats import bic


def release_eq(data) -> EqData:
    """Equation-error data of a release dataset (as the estimator prepares it, in short)."""
    runs = list(data.runs)
    noise = float(np.median([estimate_noise(r.theta, r.fs) for r in runs]))
    ds = [differentiate(r.t, r.theta, noise) for r in runs]
    window = int(np.median([d.window for d in ds]))
    q = max(1, window // 16)
    rows = []
    for r, d in zip(runs, ds, strict=True):
        m = np.ones(r.t.size, dtype=bool)
        m[: d.window // 2] = False
        m[-(d.window // 2) or None :] = False
        rows.append(m[::q])
    return EqData(
        "release",
        [r.t[::q] for r in runs],
        [d.theta[::q] for d in ds],
        [d.theta_dot[::q] for d in ds],
        [d.theta_ddot[::q] for d in ds],
        [-d.theta_ddot[::q] for d in ds],
        np.array([r.current for r in runs]),
        rows,
        max(1, window // q),
        float(np.median([np.ptp(d.theta) / 2 for d in ds])),
    )


@pytest.fixture(scope="module")
def dahl_eq():
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3, noise=1e-3, seed=1)
    return release_eq(data)


@pytest.fixture(scope="module")
def dahl_fits(dahl_eq):
    return {s: fit_shape(dahl_eq, s, DEFAULT_TORQUE_TERMS) for s in SHAPES}


def test_stage1_finds_the_dahl_structure(dahl_fits):
    best = min(dahl_fits.values(), key=lambda f: f.bic)
    assert best.shape == "dahl"
    assert set(best.terms) == {"theta", "theta_dot", "z", "i*z"}
    assert describe_structure(best.terms, best.shape) == "Dahl"
    truth = Model("dahl").to_terms()
    for t in best.terms:
        assert best.coefs[t] == pytest.approx(truth.torque[t], rel=0.1), t
    assert SHAPES["dahl"].shape_dict(best.s)["rho"] == pytest.approx(20.0, rel=0.1)
    assert best.term_model().hysteresis == pytest.approx(
        {"theta_dot": 20.0, "|theta_dot|*z": -20.0}, rel=0.1
    )


def test_shape_fit_bic_is_the_one_bic(dahl_eq, dahl_fits):
    n = int(sum(m.sum() for m in dahl_eq.rows))
    for f in dahl_fits.values():
        k = len(f.terms) + len(SHAPES[f.shape].shape_names)
        expected = bic(f.rss, n, k, n_eff=dahl_eq.n_eff(n), floor=EQ_RSS_FLOOR * dahl_eq.yy)
        assert f.bic == expected
        # the path starts at plain least squares and the selection is its lowest BIC
        assert f.path[0]["threshold"] == 0.0
        assert min(p["bic"] for p in f.path) <= f.path[0]["bic"]
    # no state: no z terms, no shape constants
    assert not set(dahl_fits["none"].terms) & {"z", "i*z", "|theta_dot|*z"}
    assert dahl_fits["none"].s.size == 0


def test_bingham_terms_without_state():
    data = generate(Model("bingham"), currents=(0, 0.5, 1), duration=3, noise=1e-3, seed=2)
    f = fit_shape(release_eq(data), "none", DEFAULT_TORQUE_TERMS)
    assert set(f.terms) == {
        "theta",
        "theta_dot",
        "i*theta_dot",
        "sign(theta_dot)",
        "i*sign(theta_dot)",
    }
    assert describe_structure(f.terms, f.shape) == "Bingham"
    assert f.coefs["theta"] == pytest.approx(158.0, rel=0.01)
    assert f.term_model().hysteresis == {}


def test_family_start_maps_stage1_onto_the_family(dahl_eq):
    p, coefs = family_start(dahl_eq, "dahl")
    truth = Model("dahl").params
    assert set(p) == set(truth)
    for k in ("k_wa", "k_wb", "rho", "k_s"):
        assert p[k] == pytest.approx(truth[k], rel=0.1), k
    assert p["J"] == 1.0
    assert "1" in coefs  # the constant column of a release (motion not imposed)
    p1, coefs1 = family_start(dahl_eq, "dahl", ["theta^3"], one_level=True, constant=False)
    assert "1" not in coefs1 and "theta^3" in coefs1 and "i*z" not in coefs1
    assert p1["k_wb"] == 0.0


def test_n_eff_counts_a_measured_torque_fully(dahl_eq):
    assert dahl_eq.n_eff(1000) == pytest.approx(2000.0 / max(dahl_eq.window, 2))
    t = np.linspace(0, 1, 5)
    driven = EqData("driven", [t], [t], [t], [t], [t], np.zeros(1), [t > 0], window=9)
    assert driven.n_eff(1000) == 1000.0


def test_the_ensemble_leaves_numpys_global_generator_as_it_found_it():
    """pysindy's EnsembleOptimizer draws its resamples from numpy's global generator: the
    inclusion probabilities are those of ``seed`` whatever the generator's state, and a
    caller's own stream from ``np.random`` continues as if they had not been computed."""
    from hystdisc.discovery.selection import inclusion

    rng = np.random.default_rng(5)
    F = rng.normal(size=(300, 4))
    y = F @ np.array([1.0, 0.0, 0.28, 2.0]) + rng.normal(0, 0.3, 300)  # c at the threshold
    names = ["a", "b", "c", "d"]
    np.random.seed(123)  # noqa: NPY002 - the caller's stream, as a user's script has it
    first = inclusion(F, y, names, 0.1, seed=7, n_models=10)
    after = np.random.random(3)  # noqa: NPY002
    np.random.seed(123)  # noqa: NPY002
    expected = np.random.random(3)  # noqa: NPY002
    np.testing.assert_array_equal(after, expected)
    np.random.seed(999)  # noqa: NPY002 - another state: the same probabilities
    assert inclusion(F, y, names, 0.1, seed=7, n_models=10) == first
    assert first["a"] == 1.0 and first["d"] == 1.0 and 0.0 < first["c"] < 1.0
    assert inclusion(F, y, names, 0.1, seed=10, n_models=10)["c"] != first["c"]  # seeded
