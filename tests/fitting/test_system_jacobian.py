"""The Jacobian of state-space families: exact forward sensitivities of the integrator
(issue 17 item 1) and the lockstep (internal numerical differentiation) alternative."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hystdisc.fitting import FamilySystemParametrization, family_parametrization
from hystdisc.fitting import system_jacobian as sj
from hystdisc.fitting.output_error import OutputErrorFitter
from hystdisc.fitting.system_sensitivity import exact_applies, system_exact_jacobian
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import Model
from hystdisc.simulation import Integration
from hystdisc.simulation.ode import simulate_lockstep, simulate_system
from hystdisc.simulation.sensitivity_ode import simulate_system_sensitivities
from hystdisc.simulation.synth import generate

SPENCER = {
    **{"alpha_a": 0.4, "alpha_b": 3.0, "c0_a": 0.3, "c0_b": 0.5, "c1_a": 4.0, "c1_b": 3.0},
    **{"k0": 0.3, "k1": 0.5, "A": 20.0, "beta": 8.0, "n": 2.0},
}
TANH = {"c_a": 0.8, "c_b": 0.6, "alpha_a": 0.5, "alpha_b": 1.5, "beta": 5.0, "delta": 0.5, "k": 0.4}


def _data(family: str, truth: dict, experiment: str, noise: float, seed: int = 1) -> FitData:
    """A short set (2 runs x 0.5 s) of ``family`` at ``truth`` as the output-error fit
    sees it."""
    kw = {"drives": ["0.2@2.0"]} if experiment == "driven" else {}
    ds = generate(
        Model(family, truth),
        experiment,
        currents=(0.2, 0.8),
        duration=0.5,
        fs=1000,
        noise=noise,
        seed=seed,
        **kw,
    )
    runs = list(ds.runs)
    y = [np.asarray(r.torque if experiment == "driven" else r.theta, dtype=float) for r in runs]
    w = [np.asarray(r.theta_dot, dtype=float) if experiment == "driven" else None for r in runs]
    return FitData(
        experiment,
        [r.name for r in runs],
        [r.t for r in runs],
        y,
        np.array([r.current for r in runs]),
        [np.asarray(r.theta, dtype=float) for r in runs],
        [np.gradient(r.theta, r.t) if q is None else q for r, q in zip(runs, w, strict=True)],
        [np.zeros(r.t.size) for r in runs],
        [np.arange(r.t.size) >= 20 for r in runs],  # a masked start, as the estimator's
        noise,
    )


def _at(data: FitData, rtol: float, atol: float) -> FitData:
    """``data`` whose fits integrate at ``rtol``, ``atol``."""
    return dataclasses.replace(data, integration=Integration(rtol=rtol, atol=atol))


def _jacobian(fitter: OutputErrorFitter, v, method: str, rtol: float, atol: float):
    other = OutputErrorFitter(_at(fitter.data, rtol, atol), fitter.par, jacobian_mode=method)
    v = np.asarray(v, dtype=float)
    return other.difference_jacobian(v) if method == "forward" else other.jacobian(v)


def _column_errors(J, ref):
    return np.linalg.norm(J - ref, axis=0) / np.maximum(np.linalg.norm(ref, axis=0), 1e-300)


def _reference(fitter, v):
    """Central differences of separately integrated runs at rtol 1e-12."""
    h = 1e-5 * np.maximum(np.abs(v), 1e-3)
    ref = np.empty((fitter.row_offsets[-1], v.size))
    tight = OutputErrorFitter(_at(fitter.data, 1e-12, 1e-15), fitter.par)
    for j in range(v.size):
        e = np.zeros(v.size)
        e[j] = h[j]
        ref[:, j] = (tight.residuals(v + e) - tight.residuals(v - e)) / (2 * h[j])
    return ref


def _spencer_run():
    """Spencer's driven model at the test values, a 0.5-s sine motion and its packed
    parameters at 0.5 A."""
    par = FamilySystemParametrization("spencer", "driven", SPENCER)
    system, values = par.model(par.x0)
    t = np.arange(0.0, 0.5, 1e-3)
    inputs = {
        "theta": 0.2 * np.sin(4 * np.pi * t),
        "theta_dot": 0.8 * np.pi * np.cos(4 * np.pi * t),
    }
    return system, values, t, inputs, system.run_parameters(values, 0.5)


def test_lockstep_nominal_is_the_integrator_bit_for_bit_and_copies_follow_it():
    system, values, t, inputs, p = _spencer_run()
    x0 = system.initial_state()
    one = simulate_system(system, t, x0, values, 0.5, inputs, rtol=1e-7, atol=1e-10).y
    P = np.array([p, p, p * (1 + 1e-3)])
    Y = simulate_lockstep(system, t, np.array([x0] * 3), P, inputs, rtol=1e-7, atol=1e-10)
    assert np.array_equal(Y[0], one) and np.array_equal(Y[1], one)
    assert 0 < np.max(np.abs(Y[2] - one)) < 1e-2 * np.max(np.abs(one))
    # a nominal that cannot be integrated: None (the fitter falls back)
    P[0, :] = np.nan
    assert simulate_lockstep(system, t, np.array([x0] * 3), P, inputs) is None


@pytest.mark.parametrize(
    ("family", "truth", "experiment"),
    [("spencer", SPENCER, "driven"), ("tanh", TANH, "driven"), ("tanh", TANH, "release")],
)
def test_lockstep_jacobian_matches_a_tight_central_difference(family, truth, experiment):
    """Spencer (driven: states d, z), tanh driven (no states: every method agrees) and
    tanh released (states theta, theta_dot; initial-state columns of each run)."""
    data = _data(family, truth, experiment, noise=0.01)
    rng = np.random.default_rng(7)
    start = {k: v * rng.uniform(0.7, 1.3) for k, v in truth.items()}
    par = FamilySystemParametrization(family, experiment, start)
    fitter = OutputErrorFitter(data, par)
    v = np.concatenate([par.x0, data.nuisance_start(fitter.state)])
    ref = _reference(fitter, v)
    tight = _jacobian(fitter, v, "lockstep", 1e-10, 1e-13)
    loose = _jacobian(fitter, v, "lockstep", sj.LOCKSTEP_RTOL, sj.LOCKSTEP_ATOL)
    assert _column_errors(tight, ref).max() < 1e-3
    # at the fit's own tolerance: the discrete map's derivative, within its integration error
    assert _column_errors(loose, ref).max() < 2e-2


def _fit(par, data, method: str, rtol: float, atol: float):
    return OutputErrorFitter(_at(data, rtol, atol), par, jacobian_mode=method).fit(heldout=False)


def test_a_spencer_fit_with_the_lockstep_jacobian_reaches_the_old_optimum():
    """The fit at the loosened tolerance with the lockstep Jacobian, the fit as it was
    (forward differences of runs integrated at 1e-10) and a reference (lockstep at 1e-12)
    reach one optimum within a small fraction of the standard errors; the new standard
    errors are the reference's (the old ones were off by up to 8 % here: forward
    differences of separately controlled runs)."""
    data = _data("spencer", SPENCER, "driven", noise=0.02, seed=3)
    start = {k: v * (1.25 if i % 2 else 0.8) for i, (k, v) in enumerate(SPENCER.items())}
    par = FamilySystemParametrization("spencer", "driven", start)
    new = _fit(par, data, "lockstep", sj.LOCKSTEP_RTOL, sj.LOCKSTEP_ATOL)
    old = _fit(par, data, "forward", 1e-10, 1e-13)
    ref = _fit(par, data, "lockstep", 1e-12, 1e-15)
    assert new.rms == pytest.approx(ref.rms, rel=1e-6) and old.rms == pytest.approx(
        ref.rms, rel=1e-6
    )
    for k in par.names:
        se = ref.stderr[k]
        assert abs(new.params[k] - ref.params[k]) < 0.03 * se, k
        assert abs(old.params[k] - ref.params[k]) < 0.03 * se, k
        assert new.stderr[k] == pytest.approx(se, rel=0.005), k


def test_a_batch_on_threads_is_the_batch_in_turn_to_the_bit():
    """``hystdisc.simulation.parallel``: the entries of a state-space batch (here a
    forward-difference Jacobian's columns) integrated side by side give the same bits."""
    from hystdisc.simulation.parallel import limit_threads

    data = _data("spencer", SPENCER, "driven", noise=0.01)
    par = FamilySystemParametrization("spencer", "driven", SPENCER)
    fitter = OutputErrorFitter(data, par)
    v = np.concatenate([par.x0, data.nuisance_start(fitter.state)])
    out = {}
    for n in (1, 2, 3):
        with limit_threads(n):
            out[n] = (fitter.residuals(v), _jacobian(fitter, v, "forward", 1e-10, 1e-13))
    for n in (2, 3):
        assert np.array_equal(out[n][0], out[1][0]) and np.array_equal(out[n][1], out[1][1])


def _exact_column_errors(data: FitData, par) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The column errors of the exact Jacobian of ``par`` at its start against
    :func:`_reference`, that point (parameters, then each run's initial states) and the
    reference."""
    fitter = OutputErrorFitter(data, par)
    assert fitter.exact_system
    v = np.concatenate([par.x0, data.nuisance_start(fitter.state)])
    x, nu = v[: par.x0.size], v[par.x0.size :].reshape(data.n_runs, -1)
    J = system_exact_jacobian(data, par, x, nu, fitter.masks, 1e-6)
    ref = _reference(fitter, v)
    assert J.shape == ref.shape
    return _column_errors(J, ref), v, ref


@pytest.mark.parametrize(
    ("family", "truth", "experiment", "effects"),
    [
        ("spencer", SPENCER, "driven", ()),
        ("spencer", SPENCER, "driven", ("shear_thinning",)),
        ("spencer", SPENCER, "driven", ("current_bias",)),
        ("spencer", SPENCER, "driven", ("channel_delay",)),
        ("spencer", SPENCER, "driven", ("series_compliance",)),
        ("spencer", {k: v for k, v in SPENCER.items() if k != "k1"}, "release", ()),
        ("tanh", TANH, "driven", ("coulomb",)),
        # the shares their compiled forces carry (r_y at the node; r_c, r_y on tanh)
        ("spencer", SPENCER, "driven", ("asymmetric_yield",)),
        ("spencer", SPENCER, "driven", ("asymmetric_yield", "series_compliance")),
        ("spencer", {k: v for k, v in SPENCER.items() if k != "k1"}, "release",
         ("asymmetric_yield",)),
        ("tanh", TANH, "driven", ("asymmetric_damping", "asymmetric_yield")),
    ],
)  # fmt: skip
def test_exact_system_jacobian_matches_a_tight_central_difference(
    family, truth, experiment, effects
):
    """Spencer driven (states d, z; with an effect's nonlinear terms; with a channel delay,
    whose column is the forward difference in the delay alone, as for the term models),
    Spencer released (states theta, theta_dot, d, z; each run's initial-state columns) and
    tanh driven (no states), with the asymmetric shares their forces carry, against
    central differences of runs integrated 100 times tighter."""
    data = _data(family, truth, experiment, noise=0.01)
    rng = np.random.default_rng(7)
    start = {k: v * rng.uniform(0.7, 1.3) for k, v in truth.items()}
    start.update({"c_st": 0.3, "m": 0.7, "f_c": 0.2, "tau_d": 0.0023})  # off the sample grid
    start.update({"k_w": 800.0, "c_w": 2.0, "m_w": 0.05})  # a mount at 20 Hz
    start.update({"r_y": 0.35, "r_c": -0.4})
    par = FamilySystemParametrization(family, experiment, start, effects)
    terms = OutputErrorFitter(data, par, jacobian_mode="terms")  # the sensitivities off
    assert not (terms.exact_system or terms.lockstep or terms.exact)
    errors, v, ref = _exact_column_errors(data, par)
    assert errors.max() < 1e-3
    # the forward differences the fit took before, at its own tolerance (1e-10)
    fd = OutputErrorFitter(data, par, jacobian_mode="forward").jacobian(v)
    assert _column_errors(fd, ref).max() > errors.max()


@pytest.mark.parametrize(
    ("family", "experiment", "effects", "wheel"),
    [
        ("bouc-wen-std", "driven", ("series_compliance",), (800.0, 2.0, 0.05)),
        ("bouc-wen-std", "driven", ("series_compliance", "shear_thinning", "coulomb"),
         (800.0, 2.0, 0.05)),
        ("dahl", "release", ("series_compliance",), (900.0, 3.0, 0.3)),
        ("bouc-wen", "release", ("series_compliance", "coulomb", "cubic_stiffness"),
         (900.0, 3.0, 0.3)),
    ],
)  # fmt: skip
def test_a_term_model_on_a_compliant_mount_or_wheel_has_the_exact_jacobian(
    family, experiment, effects, wheel
):
    """The structural effect ``series_compliance`` around a model in term form (the
    damper behind a mount on a driven test; the beam on a wheel on a release one; with
    other effects' terms across the damper and on the beam): the integrator's exact
    sensitivities, against central differences of runs integrated 100 times tighter."""
    truth = dict(Model(family).params)
    data = _data(family, truth, experiment, noise=0.01 if experiment == "driven" else 1e-3)
    start = {k: v * 1.1 for k, v in truth.items()}
    start.update(dict(zip(("k_w", "c_w", "m_w"), wheel, strict=True)))
    start.update({"c_st": 0.3, "m": 0.7, "f_c": 0.2, "k_3": 100.0})
    par = family_parametrization(family, experiment, start, effects)
    assert _exact_column_errors(data, par)[0].max() < 1e-3


def test_the_output_is_the_integrators_to_the_bit():
    system, values, t, inputs, p = _spencer_run()
    one = simulate_system(system, t, system.initial_state(), values, 0.5, inputs).y
    y, dy = simulate_system_sensitivities(
        system, t, system.initial_state(), p, [0, len(p) - 1], [1], inputs=inputs
    )
    assert np.array_equal(y, one) and dy.shape == (t.size, 3)
    # a run that cannot be integrated: None (the fitter falls back to differences)
    x0, bad = system.initial_state(), p * np.nan
    assert simulate_system_sensitivities(system, t, x0, bad, [0], inputs=inputs) is None


def test_tanh_in_a_rig_keeps_differences():
    """The tanh family's rate jumps with sign(theta) in a rig: its sensitivities would need
    a saltation term at every zero crossing, so its Jacobian stays forward differences."""
    par = FamilySystemParametrization("tanh", "release", {})
    assert not exact_applies(par)
    assert exact_applies(FamilySystemParametrization("tanh", "driven", {}))


def test_a_spencer_fit_with_the_exact_jacobian_reaches_the_reference_optimum():
    """The fit with the exact Jacobian and the fit with forward differences (as before)
    reach the optimum of a reference (forward differences of runs at 1e-12) within a
    small fraction of the standard errors; the exact standard errors are the reference's."""
    data = _data("spencer", SPENCER, "driven", noise=0.02, seed=3)
    start = {k: v * (1.25 if i % 2 else 0.8) for i, (k, v) in enumerate(SPENCER.items())}
    par = FamilySystemParametrization("spencer", "driven", start)
    new = OutputErrorFitter(data, par).fit(heldout=False)
    old = OutputErrorFitter(data, par, jacobian_mode="forward").fit(heldout=False)
    ref = _fit(par, data, "forward", 1e-12, 1e-15)
    assert new.rms == pytest.approx(ref.rms, rel=1e-6)
    for k in par.names:
        se = ref.stderr[k]
        assert abs(new.params[k] - ref.params[k]) < 0.03 * se, k
        assert abs(old.params[k] - ref.params[k]) < 0.03 * se, k
        assert new.stderr[k] == pytest.approx(se, rel=0.01), k
