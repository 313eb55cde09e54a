"""The Fisher information of a run, from the fitted model's output sensitivities.

The model of a ``results.json`` is rebuilt as the parametrization its fit used
(:func:`fitted_parametrization`: the same free parameters, bounds, fixed parameters and
normalization), each run is simulated by the fitter's own simulator and the sensitivities
``d y / d theta`` are the fitter's own Jacobian
(:meth:`hystdisc.fitting.OutputErrorFitter.jacobian`: exact sensitivities of the compiled
kernels, or lockstep differences for a state-space model), so the
information of a run is the one its intervals would come from. A run's initial state
(a release's angle) is a nuisance parameter of that run only: its information on the
model's parameters is the Schur complement ``A - B C^+ B^T`` of the run's block of
``J^T J / sigma^2`` (:func:`run_information`), and the information of runs adds up.

Examples
--------
>>> import numpy as np
>>> J = np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
>>> schur(J.T @ J, 1).round(6).tolist()
[[1.5]]
"""

from __future__ import annotations

import numpy as np

from hystdisc.data import Run, trim_release
from hystdisc.design.runs import RunSpec
from hystdisc.errors import HystdiscError
from hystdisc.fitting import (
    FamilySystemParametrization,
    OutputErrorFitter,
    Parametrization,
    family_parametrization,
)
from hystdisc.measurement import FitData
from hystdisc.models import get_family
from hystdisc.registry import get_experiment
from hystdisc.results import Results

#: Relative step of the forward differences (the fitter's).
REL_STEP = 1e-6
#: Two-sided 95 % quantile of the normal distribution (the fitter's).
Z95 = 1.959963984540054


def schur(F: np.ndarray, k: int) -> np.ndarray:
    """The information on the first ``k`` parameters with the others unknown (the Schur
    complement ``A - B C^+ B^T`` of ``F = [[A, B], [B^T, C]]``)."""
    A, B, C = F[:k, :k], F[:k, k:], F[k:, k:]
    if C.size == 0:
        return A.copy()
    return A - B @ np.linalg.pinv(C, rcond=1e-12, hermitian=True) @ B.T


def fitted_parametrization(
    results: Results, family: str | None = None
) -> tuple[Parametrization, dict[str, float]]:
    """The parametrization of a fit of ``results`` at its fitted values, and its source.

    Parameters
    ----------
    results : Results
        The record of a discovery.
    family : str, optional
        A family's fit; default the final model (the selected family with its accepted
        effects).

    Returns
    -------
    par : Parametrization
        Its start ``par.x0`` is the fit.
    values : dict of str to float
        The reported parameter values of the fit.

    Raises
    ------
    HystdiscError
        When the file holds no such fit.
    """
    name = family or results.family
    if name not in results.families:
        raise HystdiscError(
            f"results: no fit of family '{name}'; fix: use one of {', '.join(results.families)}"
        )
    fam = results.families[name]
    effects: tuple[str, ...] = ()
    params = fam.parameters
    if family is None and results.final is not None and results.final.family == name:
        effects = tuple(results.final.effects)
        params = results.final.parameters or params
    values = {k: float(p.value) for k, p in params.items() if p.value is not None}
    cd = results.current_dependence
    fixed = {p: 0.0 for p in cd.fixed} if cd is not None and cd.identifiable is False else {}
    fixed = {k: v for k, v in fixed.items() if k not in values or values[k] == 0.0}
    laws = get_family(name).laws_of(values)
    exp = results.experiment
    if fam.system:
        start = {k: float(v) for k, v in fam.system.get("values", {}).items()}
        par = FamilySystemParametrization(name, exp, start or values, effects, fixed, laws)
    else:
        norm = "alpha_1" if fam.normalization.startswith("alpha_1") else "z_sat"
        for k in ("alpha_1",) if norm == "alpha_1" else ():
            fixed[k] = values.get(k, 1.0)
        par = family_parametrization(name, exp, values, effects, fixed, norm, laws)
    return par, values


def fit_data(experiment: str, specs: list[RunSpec], noise_std: float) -> FitData:
    """The runs ``specs`` as the output-error fit takes them (the outputs left at zero:
    only the sensitivities are asked for). A driven run's samples before the motion has swept its
    range once are left out of the residual, as the fit does (the unknown initial z)."""
    t, y, th, w, u, m = [], [], [], [], [], []
    for s in specs:
        ts, x, v = s.motion()
        # as the fit: skip until the motion has swept its range once
        travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(x)))])
        mask = travel >= np.ptp(x)
        if mask.sum() < 20:
            mask[:] = True
        if s.kind == "release":
            x = np.full_like(ts, s.amplitude)  # the initial angle is read from theta[0]
        t.append(ts)
        y.append(np.zeros_like(ts))
        th.append(x)
        w.append(v)
        u.append(np.zeros_like(ts))
        m.append(mask)
    names = [str(k) for k in range(len(specs))]
    currents = np.array([s.current for s in specs], dtype=float)
    return FitData(experiment, names, t, y, currents, th, w, u, m, noise_std)


def run_information(
    par: Parametrization,
    experiment: str,
    specs: list[RunSpec],
    sigma: float,
    trim_noise: float | None = None,
) -> np.ndarray:
    """Each run's Fisher information on the free parameters of ``par`` at ``par.x0``.

    Parameters
    ----------
    par : Parametrization
        The model (:func:`fitted_parametrization`).
    experiment : str
        The experiment type of the runs.
    specs : list of RunSpec
        The runs.
    sigma : float
        Noise standard deviation of the measured output, data units.
    trim_noise : float, optional
        Release runs only: the tail where the simulated motion has died below 3 times
        this noise is left out, as the fit cuts it (:func:`~hystdisc.data.trim_release`);
        None keeps every sample.

    Returns
    -------
    ndarray
        Shape ``(len(specs), k, k)`` with ``k = len(par.names)``; a run's initial state
        is a nuisance of that run (the Schur complement). A run the model diverges on
        gets NaN.
    """
    if not specs:
        return np.zeros((0, len(par.names), len(par.names)))
    data = fit_data(experiment, specs, sigma)
    state = par.has_state()
    nu = data.nuisance_start(state)
    status: list[bool] = []
    runs = list(range(data.n_runs))
    nus = list(nu.reshape(len(runs), data.n_nuisance(state)))
    with np.errstate(all="ignore"):
        base = par.simulate(data, [par.model(par.x0)] * len(runs), runs, nus, status_out=status)
    if trim_noise and get_experiment(experiment).starts_at_rest:
        for r in runs:
            if not status[r]:
                run = Run(str(r), data.t[r], base[r], float(data.currents[r]))
                data.mask[r][trim_release(run, trim_noise).n :] = False
    fitter = OutputErrorFitter(data, par, rel_step=REL_STEP)
    with np.errstate(all="ignore"):
        J = fitter.jacobian(np.concatenate([par.x0, nu])) / sigma
    k, nn = fitter.npar, fitter.nnu
    out = np.empty((len(specs), k, k))
    for r in runs:
        rows = slice(fitter.row_offsets[r], fitter.row_offsets[r + 1])
        cols = list(range(k)) + list(range(k + r * nn, k + (r + 1) * nn))
        Jr = J[rows][:, cols]
        if status[r] or not np.all(np.isfinite(Jr)):
            out[r] = np.nan
            continue
        out[r] = schur(Jr.T @ Jr, k)
    return out


def experiment_kind(name: str) -> bool:
    """True for an experiment that imposes the motion (driven), False for a release.

    Raises
    ------
    HystdiscError
        For an experiment whose runs this module cannot lay out (forced).
    """
    exp = get_experiment(name)
    if exp.motion_imposed:
        return True
    if exp.starts_at_rest and not exp.has_input:
        return False
    raise HystdiscError(
        f"results: experiment design covers release and driven experiments, not {name}; "
        "fix: design a release or driven test"
    )
