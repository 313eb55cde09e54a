"""The fitting layer alone: the Levenberg-Marquardt, the data, the output-error fitter.

No discovery runs here: the fits are started near a known truth on sets simulated by
:func:`hystdisc.simulation.synth.generate`, and the fitter is built from :class:`FitData`
directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.fitting import FamilyParametrization, FitData, OutputErrorFitter, levenberg_marquardt
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

CURRENTS = (0.0, 0.5, 1.0)
#: The true Dahl parameters of the sets below (the rig spring included).
TRUTH = {"k_x": 0.8, "k_wa": 0.5, "k_wb": 1.5, "rho": 20.0, "k_s": 158.0}


def _release_data(noise: float, seed: int = 0, duration: float = 2.0) -> FitData:
    """A release set of the Dahl truth as the output-error fit sees it (all samples used)."""
    data = generate(
        Model("dahl", TRUTH), currents=CURRENTS, duration=duration, noise=noise, seed=seed
    )
    runs = list(data.runs)
    return FitData(
        "release",
        [r.name for r in runs],
        [r.t for r in runs],
        [np.asarray(r.theta, dtype=float) for r in runs],
        np.array([r.current for r in runs]),
        [np.asarray(r.theta, dtype=float) for r in runs],
        [np.gradient(r.theta, r.t) for r in runs],
        [np.zeros(r.t.size) for r in runs],
        [np.ones(r.t.size, dtype=bool) for r in runs],
        noise,
    )


def _start(scale: float = 1.2) -> dict[str, float]:
    return {k: v * scale for k, v in TRUTH.items()}


# ----------------------------------------------------------------------------- LM


def test_lm_reaches_the_optimum_of_a_nonlinear_problem():
    t = np.linspace(0.0, 2.0, 80)
    y = 1.5 * np.exp(-2.0 * t) + 0.3

    def fun(p):
        return p[0] * np.exp(-p[1] * t) + p[2] - y

    def jac(p):
        e = np.exp(-p[1] * t)
        return np.column_stack([e, -p[0] * t * e, np.ones_like(t)])

    lo, hi = np.full(3, -10.0), np.full(3, 10.0)
    x, njev, ok = levenberg_marquardt(fun, jac, np.array([1.0, 1.0, 0.0]), lo, hi, tol=1e-12)
    assert ok and njev > 0
    np.testing.assert_allclose(x, [1.5, 2.0, 0.3], rtol=1e-7, atol=1e-9)


def test_lm_solves_linear_least_squares_and_respects_bounds():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(50, 3))
    b = rng.normal(size=50)
    free, *_ = np.linalg.lstsq(A, b, rcond=None)
    big = np.full(3, 1e3)
    x, _, ok = levenberg_marquardt(
        lambda p: A @ p - b, lambda p: A, np.zeros(3), -big, big, tol=1e-14
    )
    assert ok
    # it stops on the relative cost change: the cost is at the optimum, the parameters
    # as close as that cost tolerance makes them
    cost = lambda p: float(np.sum((A @ p - b) ** 2))  # noqa: E731
    assert cost(x) <= cost(free) * (1 + 1e-12)
    np.testing.assert_allclose(x, free, atol=1e-6)
    # an upper bound below the free optimum of the first coordinate holds it there
    hi = big.copy()
    hi[0] = free[0] - 0.5
    xb, _, _ = levenberg_marquardt(
        lambda p: A @ p - b, lambda p: A, np.zeros(3), -big, hi, max_iter=200, tol=1e-14
    )
    assert xb[0] == pytest.approx(hi[0])
    assert np.all(xb <= hi)


# ----------------------------------------------------------------------------- data


def test_fit_data_nuisance_follows_the_experiment():
    fd = _release_data(noise=0.0, duration=0.5)
    assert fd.n_nuisance() == 1 and fd.nuisance_names()[0] == f"theta0[{fd.names[0]}]"
    np.testing.assert_array_equal(fd.nuisance_start(), [th[0] for th in fd.theta])
    assert fd.subset([2, 0]).names == [fd.names[2], fd.names[0]]


# ----------------------------------------------------------------------------- output error


def test_output_error_recovers_dahl_from_noise_free_data():
    fd = _release_data(noise=0.0)
    par = FamilyParametrization("dahl", "release", _start(1.2))
    fit = OutputErrorFitter(fd, par, max_nfev=60).fit(heldout=False)
    assert fit.success
    for k, v in TRUTH.items():
        # noise-free: the simulator's own accuracy (~1e-6 of the signal) bounds the error
        assert fit.params[k] == pytest.approx(v, rel=1e-3), k
    assert fit.rms < 1e-5
    assert fit.n_params == len(par.names) + fd.n_runs  # one initial angle per run


def test_intervals_contain_the_truth_on_noisy_data():
    fd = _release_data(noise=1e-3, seed=7)
    par = FamilyParametrization("dahl", "release", _start(1.1))
    fit = OutputErrorFitter(fd, par, max_nfev=60).fit(heldout=True)
    for k, v in TRUTH.items():
        lo, hi = fit.ci95[k]
        assert lo <= v <= hi, (k, lo, v, hi)
        assert fit.identifiable[k], k
    # the residual is the noise, and leaving a run out costs little
    assert fit.rms == pytest.approx(1e-3, rel=0.1)
    assert fit.heldout_rms is not None and fit.heldout_rms < 2e-3
