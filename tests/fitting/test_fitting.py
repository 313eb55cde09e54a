"""The fitting layer alone: the Levenberg-Marquardt, the data, the output-error fitter.

No discovery runs here: the fits are started near a known truth on sets simulated by
:func:`hystdisc.simulation.synth.generate`, and the fitter is built from :class:`FitData`
directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.errors import HystdiscError
from hystdisc.fitting import FamilyParametrization, OutputErrorFitter, levenberg_marquardt
from hystdisc.measurement import FitData
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

CURRENTS = (0.0, 0.5, 1.0)
#: The true Dahl parameters of the sets below (the rig spring included).
TRUTH = {"k_x": 0.8, "k_wa": 0.5, "k_wb": 1.5, "rho": 20.0, "k_s": 158.0}


def _release_data(noise: float, seed: int = 0, duration: float = 2.0, currents=CURRENTS) -> FitData:
    """A release set of the Dahl truth as the output-error fit sees it (all samples used)."""
    data = generate(
        Model("dahl", TRUTH), currents=currents, duration=duration, noise=noise, seed=seed
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


def test_a_fold_whose_linear_step_is_exact_skips_the_iterations(monkeypatch):
    import dataclasses

    from hystdisc.fitting import heldout

    fd = _release_data(noise=1e-3, seed=11)
    par = FamilyParametrization("dahl", "release", _start(1.1))
    fitter = OutputErrorFitter(fd, par, max_nfev=60)
    fit = fitter.fit(heldout=False)
    calls = []
    lm = heldout.levenberg_marquardt

    def counted(*args, **kwargs):
        calls.append(1)
        return lm(*args, **kwargs)

    monkeypatch.setattr(heldout, "levenberg_marquardt", counted)
    # at the noise floor each fold's Gauss-Newton step is where its iterations end
    fast = fitter.heldout_at(fit).heldout_rms
    assert not calls
    monkeypatch.setattr(heldout, "HELDOUT_GN_TRUST", 0.0)
    slow = OutputErrorFitter(fd, par, max_nfev=60).heldout_at(fit).heldout_rms
    assert len(calls) == fd.n_runs  # one fold per run, each iterated
    assert fast == pytest.approx(slow, rel=1e-4)
    # a fit far from its optimum: the step misses its linear prediction and is iterated
    monkeypatch.setattr(heldout, "HELDOUT_GN_TRUST", 0.1)
    calls.clear()
    off = dataclasses.replace(fit, x=fit.x * 1.3)
    OutputErrorFitter(fd, par, max_nfev=60).heldout_at(off)
    assert calls


def test_a_direction_the_data_leave_flat_has_no_finite_interval():
    """Two runs at one current: k_wa and k_wb enter only as k_wa + 0.5 k_wb, a direction
    the data leave exactly flat. Neither gets an interval (not a zero-width one from the
    pseudo-inverse), both are not identifiable and say why; the other parameters keep
    finite intervals that hold the truth."""
    fd = _release_data(noise=1e-3, seed=3, currents=(0.5, 0.5))
    fit = OutputErrorFitter(fd, FamilyParametrization("dahl", "release", _start(1.1))).fit(
        heldout=False
    )
    for k in ("k_wa", "k_wb"):
        assert fit.stderr[k] == np.inf and not fit.identifiable[k]
        assert f"{k} is not identifiable (the data leave a direction of the fit flat" in " ".join(
            fit.notes
        )
    for k in ("k_x", "rho", "k_s"):
        lo, hi = fit.ci95[k]
        assert np.isfinite(fit.stderr[k]) and lo <= TRUTH[k] <= hi, k
    combined = fit.params["k_wa"] + 0.5 * fit.params["k_wb"]
    assert combined == pytest.approx(TRUTH["k_wa"] + 0.5 * TRUTH["k_wb"], rel=0.01)


def test_a_diverging_fold_says_why_its_heldout_error_is_missing(monkeypatch):
    """A held-out prediction that diverges gives no held-out RMS, and the fit's notes say
    why, whether the folds ran inside fit() or later through heldout_at()."""
    fd = _release_data(noise=1e-3, seed=11)
    par = FamilyParametrization("dahl", "release", _start(1.1))
    fit = OutputErrorFitter(fd, par, max_nfev=60).fit(heldout=False)
    names = list(par.names)

    def unstable(self, fold, v_gn, rss_gn, full=False, rss_joint=np.inf):
        x = np.array(v_gn[: self.npar])  # negative damping, quick or full
        x[names.index("k_x")] = -500.0
        return x

    monkeypatch.setattr(OutputErrorFitter, "_fold_refit", unstable)
    late = OutputErrorFitter(fd, par, max_nfev=60).heldout_at(fit)
    assert late.heldout_rms is None
    why = [n for n in late.notes if "held-out RMS not reported" in n]
    assert len(why) == 1 and why[0].startswith("the held-out prediction of run ")
    assert not any("held-out RMS not reported" in n for n in fit.notes)  # not shared
    early = OutputErrorFitter(fd, par, max_nfev=60).fit(heldout=True)
    assert early.heldout_rms is None and why[0] in early.notes


def test_a_state_space_model_is_fitted_like_a_family():
    """The output-error fit takes any state-space model: the SAS beam on a compliant wheel
    (two extra states), started at the truth, stays there with the noise as its residual
    and intervals that cover the truth (finding the basin from far is the job of the
    starts, not of this layer)."""
    from hystdisc.fitting import SystemParametrization
    from hystdisc.models.wheel import BeamOnCompliantWheel
    from hystdisc.simulation import simulate_system

    truth = {"k_x": 0.6, "k_wa": 0.4, "k_wb": 1.2, "rho": 25.0, "k_s": 150.0}
    truth |= {"m_w": 0.3, "k_w": 900.0, "c_w": 3.0}
    model = BeamOnCompliantWheel("dahl")
    t = np.arange(0.0, 3.0, 1e-3)
    rng = np.random.default_rng(4)
    cur = np.array([0.0, 0.5, 1.0])
    x0 = model.initial_state(theta=0.3)
    ys = [simulate_system(model, t, x0, truth, current=c).y for c in cur]
    ys = [y + 1e-4 * rng.standard_normal(t.size) for y in ys]
    n = len(cur)
    zeros, ones = [np.zeros(t.size)] * n, [np.ones(t.size, dtype=bool)] * n
    fd = FitData("release", ["0", "1", "2"], [t] * n, ys, cur, ys, zeros, zeros, ones, 1e-4)
    par = SystemParametrization(model, truth, fixed={"m_w": 0.3})
    fit = OutputErrorFitter(fd, par, max_nfev=20).fit(heldout=False)
    assert abs(fit.rms / 1e-4 - 1.0) < 0.03
    for k, v in truth.items():
        lo, hi = fit.ci95[k]
        assert lo <= v <= hi, (k, fit.params[k], fit.ci95[k])
    # the wheel matters: the seed's rig model (no wheel) cannot reach the noise
    assert (
        fit.rms
        < 0.7
        * OutputErrorFitter(fd, FamilyParametrization("dahl", "release", truth))
        .fit(heldout=False)
        .rms
    )
    with pytest.raises(HystdiscError, match="is a state-space model, not a term model"):
        par.terms(par.x0)


def test_full_heldout_is_the_refit_of_each_fold_from_the_joint_optimum():
    """``heldout_at(full=True)``: every fold fitted completely on the other runs from the
    joint optimum, then predicted: the same as doing that by hand with a fitter of the
    other runs; and it recomputes a fit that already has a (quick) held-out error."""
    fd = _release_data(noise=1e-3, seed=11)
    par = FamilyParametrization("dahl", "release", _start(1.1))
    fitter = OutputErrorFitter(fd, par, max_nfev=60)
    fit = fitter.fit(heldout=True)
    full = OutputErrorFitter(fd, par, max_nfev=60).heldout_at(fit, full=True)
    assert full.heldout_rms is not None and full.heldout_rms != fit.heldout_rms
    sq = n = 0.0
    for fold in fd.folds():
        train = [r for r in range(fd.n_runs) if r not in fold]
        sub = fd.subset(train)
        start = np.concatenate([fit.x, np.asarray(fit.nuisance)[train].ravel()])
        vs, *_ = levenberg_marquardt(
            OutputErrorFitter(sub, par, max_nfev=60).residuals,
            OutputErrorFitter(sub, par, max_nfev=60).jacobian,
            start,
            np.concatenate([par.lower, np.full(start.size - len(par.names), -np.inf)]),
            np.concatenate([par.upper, np.full(start.size - len(par.names), np.inf)]),
            max_iter=60,
        )
        tm = par.model(vs[: len(par.names)])
        preds = par.simulate(fd, [tm] * len(fold), fold, [fit.nuisance[r] for r in fold], [])
        for r, p in zip(fold, preds, strict=True):
            e = (p - fd.y[r])[fd.mask[r]]
            sq, n = sq + float(e @ e), n + e.size
    assert full.heldout_rms == pytest.approx(np.sqrt(sq / n), rel=1e-6)
    # at the noise floor the quick estimate is the refit, to a fraction of the noise
    assert full.heldout_rms == pytest.approx(fit.heldout_rms, rel=0.05)


def test_a_fold_the_quick_estimate_misses_by_far_is_refitted_fully(monkeypatch):
    """A quick estimate that leaves its basin (here: damping 20 times the truth, stable but
    wrong) predicts its fold far worse than the joint fit fits it; that fold is refitted
    fully from the joint optimum, so the held-out error is the full refits' (a state-space
    family's step did this on a driven set: 9.27 quick, 0.146 refitted)."""
    from hystdisc.fitting.heldout import FOLD_RECHECK, HeldOutFolds

    fd = _release_data(noise=1e-3, seed=11)
    par = FamilyParametrization("dahl", "release", _start(1.1))
    fit = OutputErrorFitter(fd, par, max_nfev=60).fit(heldout=False)
    full = OutputErrorFitter(fd, par, max_nfev=60).heldout_at(fit, full=True)
    names = list(par.names)
    refit = HeldOutFolds._fold_refit

    def astray(self, fold, v_gn, rss_gn, full=False, rss_joint=np.inf):
        if full:
            return refit(self, fold, v_gn, rss_gn, True)
        x = np.array(v_gn[: self.npar])
        x[names.index("k_x")] *= 20.0
        return x

    monkeypatch.setattr(OutputErrorFitter, "_fold_refit", astray)
    quick = OutputErrorFitter(fd, par, max_nfev=60).heldout_at(fit)
    assert quick.heldout_rms == pytest.approx(full.heldout_rms, rel=1e-9)
    assert quick.heldout_rms < FOLD_RECHECK * fit.rms


def test_a_fold_whose_step_goes_the_wrong_way_is_refitted_fully():
    """A misspecified model with directions the data leave flat (bouc-wen on a Spencer
    damper with a bias per level and a backlash, as another lab's records are): a fold's
    Gauss-Newton step fitted the other runs worse than the joint optimum, and two
    iterations from there predicted the fold at 2.2 times its refit (held-out 162.8 N
    quick, 98.2 N refitted; on the 18-test stand-in bouc-wen 206 N against bouc-wen-std's
    121 N for the same fit, which decided the selection). Such a step is no estimate of
    the refit: the fold is refitted fully, and the quick held-out error is the refit's."""
    from hystdisc import Discovery
    from hystdisc.closing.rounds import fold_rms

    spencer = dict(
        alpha_a=90, alpha_b=448, c0_a=2100, c0_b=350, c1_a=28300, c1_b=295, k0=4690, k1=500,
        A=46700, beta=23350, n=2,
    )  # fmt: skip
    effects = {"current_bias": {"f_0a": 30.0, "f_0i": -20.0}, "backlash": {"r_b": 0.0005}}
    data = generate(
        Model("spencer", spencer, effects), "driven", currents=(0, 1, 2), duration=1.0,
        fs=500, drives=["0.01@1", "0.005@2", "0.0025@4"], noise=15.0, seed=1,
    )  # fmt: skip
    d = Discovery(families=["bouc-wen"], close_loop=False, n_jobs=1).fit(data)
    fit = d.family_fits_["bouc-wen"]
    full = OutputErrorFitter(d.fit_data_, fit.par, max_nfev=40).heldout_at(fit, full=True)
    quick, refit = fold_rms(d.fit_data_, fit), fold_rms(d.fit_data_, full)
    # measured: within 1.6 % in every fold (before: 228.7 against 104.5 in the third)
    assert np.allclose(quick, refit, rtol=0.05), (quick, refit)
