"""The selected family reduced to a smaller one plus effects (issue 16;
``hystdisc.closing.reduction``).

A reduction claims an exact identity (LuGre at ``sigma_1 = 0`` is Dahl with a
current-dependent viscous term; the standard Bouc-Wen at ``n = 1, beta = 0`` too): the
first tests simulate both sides. The last one runs a Dahl damper with a current-dependent
viscous term, written by the package's simulator with values drawn here inside the
physical bounds (not the bundled ``effect_current_viscous.csv``), through the estimator.
"""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.cli import main
from hystdisc.closing.reduction import reduction_held
from hystdisc.data import load
from hystdisc.models import Model, get_family
from hystdisc.simulation.runs import simulate_mech

CURRENTS = [0.0, 0.4, 1.0]


def _release(model: Model) -> list[np.ndarray]:
    t = [np.arange(0.0, 2.0, 1e-3)] * len(CURRENTS)
    runs, _ = simulate_mech(model, t, CURRENTS, [0.3] * len(CURRENTS))
    return [r.theta for r in runs]


def test_lugre_at_sigma_1_zero_is_dahl_with_a_current_viscous_term():
    (values, to, effects) = get_family("lugre").reductions[0]
    assert (values, to, effects) == ({"sigma_1": 0.0}, "dahl", ("current_viscous",))
    p = {"sigma_a": 12.0, "sigma_0": 25.0, "sigma_1": 0.0, "sigma_2": 0.7, "sigma_b": 0.45}
    p |= {"a_0": 0.8, "k_s": 150.0}
    r = p["sigma_0"] * p["a_0"]  # Dahl's w = r z saturates at 1
    dahl = {"k_x": p["sigma_2"], "k_wa": p["sigma_a"] / r, "k_wb": p["sigma_0"] / r}
    dahl |= {"rho": r, "k_s": p["k_s"]}
    lugre = _release(Model("lugre", p))
    small = _release(Model("dahl", dahl, effects={"current_viscous": {"c_i": p["sigma_b"]}}))
    for a, b in zip(lugre, small, strict=True):
        assert np.abs(a - b).max() < 1e-12 * np.abs(a).max()
    # with sigma_1 above 0 they differ: the identity is the reduction's, not a coincidence
    moved = _release(Model("lugre", p | {"sigma_1": 0.3}))
    assert max(np.abs(a - b).max() for a, b in zip(moved, small, strict=True)) > 1e-3


def test_standard_bouc_wen_at_n_1_beta_0_is_dahl_with_a_current_viscous_term():
    (values, to, effects) = get_family("bouc-wen-std").reductions[0]
    assert (values, to, effects) == ({"n": 1.0, "beta": 0.0}, "dahl", ("current_viscous",))
    p = {"alpha_1": 0.6, "alpha_2": 1.2, "c_1": 0.5, "c_2": 0.35, "beta": 0.0, "gamma": 17.0}
    p |= {"delta": 17.0, "n": 1.0, "k_s": 160.0}  # z_sat = 1: delta = beta + gamma
    dahl = {"k_x": p["c_1"], "k_wa": p["alpha_1"], "k_wb": p["alpha_2"], "rho": p["delta"]}
    dahl |= {"k_s": p["k_s"]}
    bw = _release(Model("bouc-wen-std", p))
    small = _release(Model("dahl", dahl, effects={"current_viscous": {"c_i": p["c_2"]}}))
    for a, b in zip(bw, small, strict=True):
        assert np.abs(a - b).max() < 1e-12 * np.abs(a).max()
    # the seed form has no exact reduction (Dahl only in the limit n -> 0)
    assert get_family("bouc-wen").reductions == ()


@pytest.fixture(scope="module")
def dahl_cv(tmp_path_factory):
    """A Dahl damper with a current-dependent viscous term, values drawn inside the
    physical bounds around the family's scale (seeded)."""
    rng = np.random.default_rng(2611)
    truth = {
        "k_x": rng.uniform(0.4, 1.2),
        "k_wa": rng.uniform(0.3, 1.0),
        "k_wb": rng.uniform(0.8, 2.0),
        "rho": rng.uniform(10.0, 40.0),
        "k_s": rng.uniform(120.0, 200.0),
    }
    c_i = rng.uniform(0.3, 0.9)
    out = tmp_path_factory.mktemp("reduction") / "dahl_cv.csv"
    argv = ["simulate", "--model", "dahl", "--set", ",".join(f"{k}={v}" for k, v in truth.items())]
    argv += ["--effect", f"current_viscous:c_i={c_i}", "--currents", "0,0.25,0.5,0.75,1"]
    argv += ["--duration", "3", "--noise", "1e-3", "--seed", "9", "-o", str(out), "--quiet"]
    assert main(argv) == 0
    return truth, c_i, Discovery().fit(load(out))


def test_a_dahl_damper_with_current_viscous_damping_is_not_answered_by_lugre(dahl_cv):
    truth, c_i, disc = dahl_cv
    # the family table, without effects, picks LuGre: it carries the term natively, with
    # sigma_1 at 0 (its interval holds 0)
    red = disc.reduction_
    assert red is not None and red.family == "lugre" and red.at == {"sigma_1": 0.0}
    assert red.switched
    # the answer: Dahl plus the current-viscous term, the truth's structure
    assert disc.family_ == "dahl" and disc.effects_ == ["current_viscous"]
    fit = disc.final_fit_
    for name, v in (truth | {"c_i": c_i}).items():
        lo, hi = fit.ci95[name]
        assert abs(fit.params[name] / v - 1) < 0.02, name
        assert lo - 0.5 * (hi - lo) < v < hi + 0.5 * (hi - lo), name
    # judged on the runs each fold left out: as good as LuGre's, with a parameter fewer
    assert red.final_heldout["dahl"] <= 1.01 * red.final_heldout["lugre"]
    assert red.final_bic["dahl"] < red.final_bic["lugre"]
    assert disc.results_.reduction["switched"] is True


def test_a_significant_sigma_1_is_never_reduced():
    from types import SimpleNamespace as NS

    lugre = get_family("lugre")
    fit = NS(is_system=False, par=NS(family=lugre), ci95={"sigma_1": (0.05, 0.09)})
    assert reduction_held(fit) is None
    std = get_family("bouc-wen-std")
    # both of the standard form's values must lie inside their intervals
    fit = NS(is_system=False, par=NS(family=std), ci95={"n": (0.9, 1.2), "beta": (0.5, 2.0)})
    assert reduction_held(fit) is None
    fit.ci95["beta"] = (-0.3, 0.4)
    assert reduction_held(fit) == ({"n": 1.0, "beta": 0.0}, "dahl", ("current_viscous",))
