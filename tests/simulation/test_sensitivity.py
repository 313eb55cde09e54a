"""Exact forward sensitivities of the term kernels and the output-error Jacobian from them.

- the kernels with sensitivities give the plain kernels' outputs to the last bit;
- the exact Jacobian equals central differences of the residuals, with the sub-step count
  held fixed (the sensitivities are the derivative of the discrete scheme at the sub-step
  count the kernel chose; a finite difference that changes that count measures the jump
  too), for the seed's families on release, forced and driven sets and for the effects,
  at parameters drawn at random around the defaults with a fixed seed;
- a fit with the exact Jacobian lands where the forward-difference fit lands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hystdisc.data import load
from hystdisc.errors import HystdiscError
from hystdisc.fitting import FamilyParametrization, OutputErrorFitter, SystemParametrization
from hystdisc.fitting.jacobian import exact_jacobian
from hystdisc.measurement import FitData
from hystdisc.models import Model
from hystdisc.models.compiled import N_BASE, base_coefficients
from hystdisc.models.wheel import BeamOnCompliantWheel
from hystdisc.simulation import Integration
from hystdisc.simulation.batch import (
    driven_batch,
    driven_sens_batch,
    mech_batch,
    mech_sens_batch,
)
from hystdisc.simulation.sensitivity import DIR_J, DIR_N, DIR_TH0, N_DIR
from hystdisc.simulation.synth import generate

SYNTH = Path(__file__).resolve().parents[2] / "data_synth"
CURRENTS = (0.3, 0.9)
#: Sub-steps per sample interval held fixed in the Jacobian comparisons.
FIXED_SUB = 3
#: Exact and finite-difference columns agree to this share of the column's norm.
JAC_TOL = 1e-5


def _fit_data(family: str, experiment: str, window: int = 0, how=None) -> FitData:
    """Two 1-s runs of ``family`` at its defaults, as the output-error fit takes them (the
    first samples masked; ``window``: a declared output filter; ``how``: the fits'
    :class:`Integration`)."""
    ds = generate(family, experiment, currents=CURRENTS, duration=1.0, fs=500.0, seed=3)
    runs = list(ds.runs)
    driven = experiment == "driven"
    y = [np.asarray(r.torque if driven else r.theta, dtype=float) for r in runs]
    w = [r.theta_dot if driven else np.gradient(r.theta, r.t) for r in runs]
    u = [r.input if experiment == "forced" else np.zeros(r.t.size) for r in runs]
    mask = [np.arange(r.t.size) >= max(window, 10) for r in runs]
    fd = FitData(
        experiment,
        [r.name for r in runs],
        [r.t for r in runs],
        y,
        np.array([r.current for r in runs]),
        [np.asarray(r.theta, dtype=float) for r in runs],
        [np.asarray(a, dtype=float) for a in w],
        [np.asarray(a, dtype=float) for a in u],
        mask,
        1e-3,
        integration=how or Integration(),
    )
    if window:
        fd.filter_windows = [window] * fd.n_runs
    return fd


def _random_point(par, fd: FitData, seed: int) -> np.ndarray:
    """Free parameters at ``U(0.7, 1.3)`` times their defaults (within the bounds) and
    random initial states."""
    rng = np.random.default_rng(seed)
    x = np.clip(par.x0 * rng.uniform(0.7, 1.3, par.x0.size), par.lower, par.upper)
    nu = fd.nuisance_start(par.has_state()).reshape(fd.n_runs, -1)
    if nu.shape[1] == 1:  # a release: its initial angle
        nu = nu * rng.uniform(0.9, 1.1, nu.shape)
    elif nu.shape[1]:  # a forced run starts anywhere (z within the loop)
        nu = rng.uniform(-1.0, 1.0, nu.shape) * np.array([0.05, 0.5, 0.3][: nu.shape[1]])
    return np.concatenate([x, nu.ravel()])


def _central(fitter: OutputErrorFitter, v: np.ndarray, rel: float = 1e-6) -> np.ndarray:
    """Central differences of the residuals."""
    cols = []
    scale = 1e-3 * np.abs(v).max()
    for j in range(v.size):
        h = rel * max(abs(v[j]), scale)
        vp, vm = v.copy(), v.copy()
        vp[j] += h
        vm[j] -= h
        cols.append((fitter.residuals(vp) - fitter.residuals(vm)) / (2 * h))
    return np.column_stack(cols)


@pytest.fixture
def fixed_substeps() -> Integration:
    """Every sample interval of a fit integrated in :data:`FIXED_SUB` sub-steps."""
    return Integration(min_sub=FIXED_SUB, max_sub=FIXED_SUB)


def _check_jacobian(par, fd: FitData, seed: int) -> None:
    fitter = OutputErrorFitter(fd, par, jacobian_mode="exact")
    assert fitter.exact
    v = _random_point(par, fd, seed)
    x, nu = v[: par.x0.size], v[par.x0.size :].reshape(fd.n_runs, -1)
    Je = exact_jacobian(fd, par, x, nu, fitter.state, fitter.masks, fitter.rel_step)
    assert Je is not None  # no run diverged: the sensitivities were used
    np.testing.assert_array_equal(Je, fitter.jacobian(v))
    Jc = _central(fitter, v)
    norms = np.linalg.norm(Jc, axis=0)
    err = np.linalg.norm(Je - Jc, axis=0)
    names = par.names + fd.nuisance_names(fitter.state)
    bad = {n: float(e / m) for n, e, m in zip(names, err, norms, strict=True) if e > JAC_TOL * m}
    assert not bad, bad
    assert np.all(norms > 0)  # every column is seen by the data


# ----------------------------------------------------------------------------- kernels


def _everything():
    """A term model with every term of the kernels."""
    tm = Model("bouc-wen-std").to_terms()
    tm.torque.update({"theta": 150.0, "theta^3": 30.0, "1": 0.1, "sign(theta_dot)": 0.2})
    tm.torque.update({"theta_dot*|theta_dot|": 0.05, "sign(theta_dot)*|theta_dot|^m": 0.3})
    tm.torque.update({"|theta_dot|*z": 0.2, "|theta_dot|": 0.15, "i": 0.05, "|z|": -0.1})
    tm.hysteresis.update({"|theta_dot|*z": -1.0, "|theta_dot|*|z|^n": 0.5})
    tm.n = 1.6
    return tm


def _vectors(tm, currents):
    coef = np.array([base_coefficients(tm, i) for i in currents])
    b = np.tile(tm.hysteresis_vector(), (len(currents), 1))
    return coef, b, np.full(len(currents), tm.n)


@pytest.mark.parametrize("hold", ["cubic", "linear", "zoh"])
def test_mech_kernel_with_sensitivities_gives_the_same_bits(hold):
    tm = _everything()
    coef, b, n = _vectors(tm, CURRENTS)
    t = np.arange(0.0, 1.0, 1e-3)
    tt = np.r_[t, t]
    u = np.r_[20 * np.sin(9 * t), 15 * np.cos(4 * t)]
    off = np.array([0, t.size, 2 * t.size])
    start = (np.array([0.3, -0.1]), np.array([0.0, 2.0]), np.array([0.0, -0.4]))
    J = np.array([1.0, 0.7])
    opts = {"hold": hold, "ratio": 0.4, "min_sub": 1, "max_sub": 8}
    plain = mech_batch(coef, b, n, J, tt, u, off, *start, **opts)
    act = np.arange(N_DIR)
    th, w, z, sens, status = mech_sens_batch(coef, b, n, J, tt, u, off, *start, act, **opts)
    for a, c in zip(plain[:3], (th, w, z), strict=True):
        np.testing.assert_array_equal(a, c)
    np.testing.assert_array_equal(plain[3], status)
    assert np.all(status == 0) and np.all(np.isfinite(sens))
    # the derivative along the initial angle starts at 1, the others at 0
    np.testing.assert_array_equal(sens[0], np.eye(N_DIR)[-3])


@pytest.mark.parametrize(
    "act",
    [[0, 2, 4, 8, 9, 10, 12, 13, 14, 15, 19], [0, 2, 4, 8, 9]],
    ids=["rate directions", "torque directions only"],
)
def test_driven_kernel_with_sensitivities_gives_the_same_bits(act):
    tm = _everything()
    coef, b, n = _vectors(tm, CURRENTS)
    t = np.arange(0.0, 1.0, 2e-3)
    tt = np.r_[t, t]
    th = np.r_[0.3 * np.sin(2 * np.pi * 2 * t), 0.1 * np.sin(2 * np.pi * 3 * t)]
    w = np.r_[0.6 * np.pi * 2 * np.cos(2 * np.pi * 2 * t), 0.6 * np.pi * np.cos(6 * np.pi * t)]
    off = np.array([0, t.size, 2 * t.size])
    z0 = np.array([0.0, 0.2])
    opts = {"ratio": 0.4, "min_sub": 1, "max_sub": 8}
    tq, z, status = driven_batch(coef, b, n, tt, th, w, off, z0, **opts)
    act = np.array(act)
    tq2, z2, sens, status2 = driven_sens_batch(coef, b, n, tt, th, w, off, z0, act, **opts)
    np.testing.assert_array_equal(tq, tq2)
    np.testing.assert_array_equal(z, z2)
    np.testing.assert_array_equal(status, status2)
    # the torque's own coefficients act on it directly: d torque / d c[2] = z
    np.testing.assert_array_equal(sens[:, 1], z)


def test_sensitivities_match_central_differences_of_the_kernel():
    """Along every direction (fixed sub-steps), a kernel-level check of the hand-written
    derivative independent of the fitter's chain rule."""
    tm = _everything()
    coef, b, n = _vectors(tm, CURRENTS)
    t = np.arange(0.0, 0.5, 1e-3)
    tt, u = np.r_[t, t], np.r_[20 * np.sin(9 * t), 15 * np.cos(4 * t)]
    off = np.array([0, t.size, 2 * t.size])
    J = np.array([1.0, 0.7])
    start = np.array([[0.3, -0.1], [0.5, 2.0], [0.1, -0.4]])
    opts = {"hold": "cubic", "ratio": 0.4, "min_sub": 4, "max_sub": 4}
    act = np.arange(N_DIR)
    *_, sens, _ = mech_sens_batch(coef, b, n, J, tt, u, off, *start, act, **opts)
    for d in act:
        cols = []
        for sgn in (1.0, -1.0):
            vec = np.column_stack([coef, b, n, J, start.T])
            h = 1e-6 * max(abs(vec[0, d]), 1.0)
            vec[:, d] += sgn * h
            c, bb, nn, JJ = vec[:, :N_BASE], vec[:, N_BASE:DIR_N], vec[:, DIR_N], vec[:, DIR_J]
            s0 = vec[:, DIR_TH0:]
            s0 = np.ascontiguousarray(s0.T)
            th = mech_batch(c.copy(), bb.copy(), nn.copy(), JJ.copy(), tt, u, off, *s0, **opts)
            cols.append(th[0])
        fd = (cols[0] - cols[1]) / (2 * h)
        assert np.linalg.norm(fd - sens[:, d]) <= JAC_TOL * np.linalg.norm(fd), d


# ----------------------------------------------------------------------------- Jacobian


@pytest.mark.parametrize("experiment", ["release", "forced", "driven"])
@pytest.mark.parametrize("family", ["bingham", "dahl", "lugre", "bouc-wen", "bouc-wen-std"])
def test_exact_jacobian_matches_central_differences(family, experiment, fixed_substeps):
    fd = _fit_data(family, experiment, how=fixed_substeps)
    par = FamilyParametrization(family, experiment, {})
    _check_jacobian(par, fd, seed=sum(map(ord, family + experiment)))


@pytest.mark.parametrize(
    ("effect", "experiment"),
    [
        ("coulomb", "release"),
        ("shear_thinning", "release"),
        ("cubic_stiffness", "release"),
        ("quadratic_damping", "forced"),
        ("offset", "release"),
        ("current_saturation", "driven"),
        ("channel_delay", "driven"),
        ("channel_delay", "forced"),
        ("shear_thinning", "driven"),
        ("asymmetric_damping", "release"),
        ("asymmetric_damping", "driven"),
        ("asymmetric_yield", "release"),
        ("asymmetric_yield", "driven"),
        ("bias", "forced"),
        ("current_bias", "driven"),
    ],
)
def test_exact_jacobian_with_effects(effect, experiment, fixed_substeps):
    fd = _fit_data("bouc-wen", experiment, how=fixed_substeps)
    par = FamilyParametrization("bouc-wen", experiment, {}, effects=(effect,))
    _check_jacobian(par, fd, seed=7)


@pytest.mark.parametrize("experiment", ["release", "driven"])
def test_exact_jacobian_with_a_saturating_law_and_a_filter(experiment, fixed_substeps):
    """A current law ``i0 tanh(i / i0)`` (a nonlinear map to the term vectors) and a
    declared moving-average filter of the output."""
    fd = _fit_data("dahl", experiment, window=7, how=fixed_substeps)
    par = FamilyParametrization("dahl", experiment, {"k_w_i0": 0.6}, laws={"k_w": "saturating"})
    assert "k_w_i0" in par.names
    _check_jacobian(par, fd, seed=11)


def test_exact_jacobian_on_decimated_data():
    """The bulk of a long fit: every other sample, the sub-step cap doubled (fixed at
    twice :data:`FIXED_SUB` here), a filter averaged on the measured grid."""
    how = Integration(min_sub=2 * FIXED_SUB, max_sub=FIXED_SUB)
    fd = _fit_data("lugre", "release", window=5, how=how).decimated([2, 2])
    assert fd.integration == how  # the decimated copy integrates as its original
    _check_jacobian(FamilyParametrization("lugre", "release", {}), fd, seed=5)


def test_a_diverging_start_falls_back_to_forward_differences():
    fd = _fit_data("dahl", "release")
    par = FamilyParametrization("dahl", "release", {"k_s": 1e9, "J": 1e-9})
    fitter = OutputErrorFitter(fd, par)
    v = np.concatenate([par.x0, fd.nuisance_start()])
    x, nu = v[: par.x0.size], v[par.x0.size :].reshape(fd.n_runs, -1)
    with np.errstate(all="ignore"):
        assert exact_jacobian(fd, par, x, nu, True, fitter.masks, fitter.rel_step) is None
        np.testing.assert_array_equal(fitter.jacobian(v), fitter.difference_jacobian(v))


def test_sensitivities_too_large_for_the_gram_fall_back_to_forward_differences():
    # where a LuGre fit wandered on a noise-free encoder record (stress suite, dahl/0):
    # sigma_0 -> 0 and a_0 at its bound; the output stays bounded, its sensitivities reach
    # 1e200 and their Gram matrix overflowed (a crash at the intervals)
    ds = generate("dahl", "release", currents=(0.0,), duration=2.0, fs=1000.0, seed=3)
    run = ds.runs[0]
    theta = np.asarray(run.theta, dtype=float)
    fd = FitData(
        "release", [run.name], [run.t], [theta], np.array([0.0]), [theta],
        [np.gradient(theta, run.t)], [np.zeros(theta.size)], [np.ones(theta.size, bool)],
        1e-3,
    )  # fmt: skip
    wild = {"sigma_a": 54.9, "sigma_0": 2.17e-6, "sigma_1": 1.207e4, "sigma_2": 56.05}
    wild.update({"sigma_b": 0.0, "a_0": 1e9, "k_s": 1455.8})
    par = FamilyParametrization("lugre", "release", wild)
    fitter = OutputErrorFitter(fd, par)
    v = np.concatenate([par.x0, fd.nuisance_start(True)])
    x, nu = v[: par.x0.size], v[par.x0.size :].reshape(fd.n_runs, -1)
    with np.errstate(all="ignore"):
        assert exact_jacobian(fd, par, x, nu, True, fitter.masks, fitter.rel_step) is None
        J = fitter.jacobian(v)
    assert np.all(np.isfinite(fitter.gram(J)))


def test_the_jacobian_mode_chooses_the_method():
    fd = _fit_data("dahl", "release")
    par = FamilyParametrization("dahl", "release", {})
    v = np.concatenate([par.x0, fd.nuisance_start()])
    forward = OutputErrorFitter(fd, par, jacobian_mode="forward")
    assert not forward.exact and OutputErrorFitter(fd, par, jacobian_mode="exact").exact
    np.testing.assert_array_equal(forward.jacobian(v), forward.difference_jacobian(v))
    with pytest.raises(HystdiscError, match="unknown Jacobian mode"):
        OutputErrorFitter(fd, par, jacobian_mode="central")
    # a state-space model has no term kernels: forward differences
    system = SystemParametrization(BeamOnCompliantWheel("dahl"), {}, {"m_w": 0.3})
    assert not OutputErrorFitter(fd, system, jacobian_mode="exact").exact
    assert OutputErrorFitter(fd, system, jacobian_mode="lockstep").lockstep
    assert not OutputErrorFitter(fd, par, jacobian_mode="lockstep").lockstep
    # "lockstep" and "terms" keep a term model's exact Jacobian
    assert OutputErrorFitter(fd, par, jacobian_mode="lockstep").exact
    assert OutputErrorFitter(fd, par, jacobian_mode="terms").exact
    # without an argument the fitter takes the data's mode (the pipeline's option), and
    # the fits inside it (the bulk, the held-out folds) take it from the fitter
    fd.jacobian = "forward"
    assert OutputErrorFitter(fd, par).jacobian_mode == "forward"
    assert OutputErrorFitter(fd.subset([1]), par).jacobian_mode == "forward"
    assert OutputErrorFitter(fd, par, jacobian_mode="exact").exact


@pytest.mark.parametrize("experiment", ["release", "forced", "driven"])
@pytest.mark.parametrize("family", ["bingham", "lugre", "bouc-wen"])
def test_forward_differences_reuse_the_residuals_base_to_the_last_bit(family, experiment):
    """The forward-difference Jacobian at the vector of the last residual takes that
    residual's outputs as its base instead of simulating them again (issue 17): the same
    Jacobian, bit for bit, as one that simulates its base; a residual elsewhere is not
    reused."""
    fd = _fit_data(family, experiment)
    par = FamilyParametrization(family, experiment, {})
    entries: list[int] = []
    simulate = par.simulate

    def counted(data, models, *args, **kwargs):
        entries.append(len(models))
        return simulate(data, models, *args, **kwargs)

    par.simulate = counted
    v = _random_point(par, fd, seed=7)
    fresh = OutputErrorFitter(fd, par, jacobian_mode="forward").difference_jacobian(v)
    n_fresh = sum(entries)
    fitter = OutputErrorFitter(fd, par, jacobian_mode="forward")
    fitter.residuals(v)
    entries.clear()
    np.testing.assert_array_equal(fitter.difference_jacobian(v), fresh)
    assert sum(entries) == n_fresh - fd.n_runs  # one base simulation per run saved
    fitter.residuals(1.01 * v)  # the last residual is elsewhere: not the base at v
    np.testing.assert_array_equal(fitter.difference_jacobian(v), fresh)
    system = SystemParametrization(BeamOnCompliantWheel("dahl"), {}, {"m_w": 0.3})
    if experiment == "release" and family == "lugre":
        fs = OutputErrorFitter(fd, system)
        w = np.concatenate([system.x0, fd.nuisance_start(system.has_state())])
        fresh = OutputErrorFitter(fd, system).difference_jacobian(w)
        fs.residuals(w)
        np.testing.assert_array_equal(fs.difference_jacobian(w), fresh)


# ----------------------------------------------------------------------------- fits


def test_exact_and_forward_fits_land_on_the_same_optimum():
    ds = load(SYNTH / "dahl.csv")
    runs = list(ds.runs)
    fd = FitData(
        "release",
        [r.name for r in runs],
        [r.t for r in runs],
        [r.theta for r in runs],
        np.array([r.current for r in runs]),
        [r.theta for r in runs],
        [np.gradient(r.theta, r.t) for r in runs],
        [np.zeros(r.t.size) for r in runs],
        [np.ones(r.t.size, dtype=bool) for r in runs],
        1e-3,
    )
    start = {"k_x": 1.0, "k_wa": 0.6, "k_wb": 1.2, "rho": 25.0, "k_s": 150.0}
    par = FamilyParametrization("dahl", "release", start)
    fits = {
        mode: OutputErrorFitter(fd, par, jacobian_mode=mode).fit(heldout=False)
        for mode in ("exact", "forward")
    }
    assert all(f.success for f in fits.values())
    for k, v in fits["forward"].params.items():
        assert fits["exact"].params[k] == pytest.approx(v, rel=1e-5), k
    assert fits["exact"].rss == pytest.approx(fits["forward"].rss, rel=1e-8)


def test_a_batch_cut_into_chunks_on_threads_gives_the_same_bits(monkeypatch):
    """``hystdisc.simulation.parallel``: a batch of four entries of different lengths cut
    into chunks integrated side by side equals the batch in one call, outputs, statuses,
    work and sensitivities alike (a diverging entry included)."""
    import hystdisc.simulation.batch as batch
    from hystdisc.simulation.parallel import limit_threads

    tm = _everything()
    currents = [0.0, 0.3, 0.7, 1.0]
    coef, b, n = _vectors(tm, currents)
    coef[2] *= -50.0  # every torque term generating energy: this entry diverges
    lens = [900, 400, 700, 1000]
    tt = np.concatenate([np.arange(k) * 1e-3 for k in lens])
    off = np.concatenate([[0], np.cumsum(lens)])
    u = 10 * np.sin(7 * tt)
    start = (np.full(4, 0.3), np.zeros(4), np.zeros(4))
    J = np.ones(4)
    act = np.arange(N_DIR)
    w = np.cos(5 * tt)

    def every():
        work = [np.zeros(4, dtype=np.int64) for _ in range(4)]
        return (
            mech_batch(coef, b, n, J, tt, u, off, *start, work=work[0]),
            mech_sens_batch(coef, b, n, J, tt, u, off, *start, act, work=work[1]),
            driven_batch(coef, b, n, tt, 0.2 * np.sin(tt), w, off, np.zeros(4), work=work[2]),
            driven_sens_batch(
                coef, b, n, tt, 0.2 * np.sin(tt), w, off, np.zeros(4), act, work=work[3]
            ),  # fmt: skip
            work,
        )

    with limit_threads(1):
        one = every()
    monkeypatch.setattr(batch, "CHUNK_SAMPLES", 500)
    for k in (2, 3):
        with limit_threads(k):
            many = every()
        for a, c in zip(one, many, strict=True):
            for x, y in zip(a, c, strict=True):
                np.testing.assert_array_equal(x, y)
    assert one[0][3].tolist() == [0, 0, 1, 0]  # the diverging entry is flagged in both
