"""Experiment design from a fit: :func:`design` (``hystdisc design``).

From a ``results.json``: the fitted model is rebuilt as its fit's parametrization, the
runs the fit saw are rebuilt from the training envelope and give the information in hand,
every candidate run its own (:mod:`hystdisc.design.information`); the runs that most
shrink the widest 95 % interval relative to its value are chosen greedily
(:func:`hystdisc.design.select.greedy`), and for every family that fits about as well
(``equal_fits``) the candidates are ranked by how far apart the two fits' outputs would be.

The expected widths after the runs are the fit's own widths times the predicted shrink of
each: what the rebuilt runs miss (the exact signals, the trimmed samples) cancels in the
ratio.
"""

from __future__ import annotations

import numpy as np

from hystdisc.design.base import DesignResult
from hystdisc.design.information import (
    experiment_kind,
    fit_data,
    fitted_parametrization,
    run_information,
)
from hystdisc.design.runs import RunSpec, candidate_runs, recorded_runs
from hystdisc.design.select import greedy, interval_widths, parameter_gradient, separation
from hystdisc.errors import HystdiscError

#: Candidates listed per family in the separation ranking.
SEPARATION_TOP = 5
#: Rebuilt intervals this far from the fit's (either way) earn a note.
REBUILD_TOLERANCE = 2.0


def _sampling(results) -> tuple[float, float]:
    """Sampling rate and median duration of the training runs."""
    env = results.envelope or {}
    rates, durations = [], []
    for r, e in zip(results.runs, env.get("runs") or [], strict=False):
        d = float(e.get("duration") or 0.0)
        if d > 0 and r.samples:
            rates.append((r.samples - 1) / d)
            durations.append(d)
    if not rates:
        return 1000.0, 3.0
    return float(f"{np.median(rates):.6g}"), float(np.median(durations))


def _sigma(results, family: str) -> float:
    rms = results.families[family].rms
    sigma = rms if rms else results.noise_std
    if not sigma or not np.isfinite(sigma) or sigma <= 0:
        raise HystdiscError(
            "results: no residual RMS or noise level to scale the information; fix: rerun "
            "hystdisc discover"
        )
    return float(sigma)


def _stored_widths(results, family: str) -> dict[str, float]:
    params = results.families[family].parameters
    if results.final is not None and results.final.family == family and results.final.parameters:
        params = results.final.parameters
    out = {}
    for k, p in params.items():
        ci = p.ci95
        if ci and ci[0] is not None and ci[1] is not None:
            out[k] = float(ci[1]) - float(ci[0])
    return out


def _outputs(par, experiment: str, specs: list[RunSpec], sigma: float):
    data = fit_data(experiment, specs, sigma)
    nn = data.n_nuisance(par.has_state())
    nus = list(data.nuisance_start(par.has_state()).reshape(len(specs), nn))
    runs = list(range(len(specs)))
    return par.simulate(data, [par.model(par.x0)] * len(specs), runs, nus), data.mask


def design(
    results,
    budget: int = 3,
    candidates: list[RunSpec] | None = None,
    currents: list[float] | None = None,
) -> DesignResult:
    """The next ``budget`` runs that most shrink the widest 95 % interval of a fit.

    Parameters
    ----------
    results : Results
        The record of a discovery (``Results.load("results.json")``).
    budget : int
        Runs to choose.
    candidates : list of RunSpec, optional
        The runs to choose from; default the grid of
        :func:`~hystdisc.design.runs.candidate_runs` around the training envelope.
    currents : list of float, optional
        Currents of the default grid (default: 0 to twice the largest trained current).

    Returns
    -------
    DesignResult

    Raises
    ------
    HystdiscError
        For a budget below 1, a file without a training envelope, a forced experiment,
        or a model that diverges on a candidate.

    Examples
    --------
    >>> from hystdisc import Discovery
    >>> from hystdisc.simulation.synth import generate
    >>> data = generate("dahl", currents=(0, 0.5), theta0=0.05, duration=2.0, fs=500, seed=1)
    >>> res = Discovery(model="dahl", heldout=False, close_loop=False).fit(data).results_
    >>> d = design(res, budget=2)
    >>> len(d.runs), d.predicted_factor < 1
    (2, True)
    """
    if isinstance(budget, bool) or not isinstance(budget, (int, np.integer)) or budget < 1:
        raise HystdiscError(f"budget {budget!r} is not a whole number >= 1; fix: give 1 or more")
    if not results.envelope or not results.envelope.get("runs"):
        raise HystdiscError(
            "results: no training envelope (a file written before schema 3); fix: rerun "
            "hystdisc discover"
        )
    family = results.family
    if family not in results.families:
        raise HystdiscError("results: no selected family; fix: rerun hystdisc discover")
    driven = experiment_kind(results.experiment)
    par, values = fitted_parametrization(results)
    sigma = _sigma(results, family)
    fs, duration = _sampling(results)
    recorded = recorded_runs(results.envelope, driven, fs)
    cands = candidates or candidate_runs(results.envelope, driven, fs, duration, currents)
    F0 = run_information(par, results.experiment, recorded, sigma).sum(axis=0)
    Fc = run_information(par, results.experiment, cands, sigma)
    fixed = getattr(par, "fixed", {}) or {}
    names = [k for k in par.params(par.x0) if k not in fixed]
    G = parameter_gradient(par, par.x0, names)
    rebuilt = dict(zip(names, map(float, interval_widths(F0, G)), strict=True))
    stored = _stored_widths(results, family)
    before = {k: stored.get(k, rebuilt[k]) for k in names}
    scale = np.array([before[k] / rebuilt[k] if rebuilt[k] > 0 else 1.0 for k in names])
    vals = np.array([abs(values.get(k, par.params(par.x0)[k])) for k in names])
    judged = vals > 0

    def widest(F: np.ndarray) -> float:
        rel = scale * interval_widths(F, G) / np.where(judged, vals, 1.0)
        return float(np.max(rel[judged]))

    picks, steps = greedy(F0, Fc, widest, int(budget))
    F = F0 + Fc[picks].sum(axis=0)
    after = dict(zip(names, map(float, scale * interval_widths(F, G)), strict=True))
    alone = sorted(((widest(F0 + Fc[c]), c) for c in range(len(cands))), key=lambda x: x[0])
    notes = [
        f"{k}: the runs rebuilt from the training envelope give an interval "
        f"{rebuilt[k] / before[k]:.2g} times the fit's (the expected widths are scaled back)"
        for k in names
        if before[k] > 0
        and not 1 / REBUILD_TOLERANCE <= rebuilt[k] / before[k] <= REBUILD_TOLERANCE
    ]
    sep = {}
    others = [f for f in results.equal_fits if f != family and f in results.families]
    if others:
        y_sel, masks = _outputs(par, results.experiment, cands, sigma)
        for other in others:
            try:
                par_o, _ = fitted_parametrization(results, other)
                y_o, _ = _outputs(par_o, results.experiment, cands, sigma)
            except HystdiscError as exc:
                notes.append(f"{other}: not compared ({exc})")
                continue
            dist = separation(y_sel, y_o, masks, sigma)
            order = np.argsort(-dist)[:SEPARATION_TOP]
            sep[other] = [(cands[c], float(dist[c])) for c in order]
    return DesignResult(
        family=family,
        experiment=results.experiment,
        sigma=sigma,
        names=names,
        values={k: float(par.params(par.x0)[k]) for k in names},
        widths_before=before,
        predicted_before=rebuilt,
        widths_after=after,
        runs=[cands[c] for c in picks],
        widest_steps=steps,
        ranking=[(cands[c], v) for v, c in alone],
        separation=sep,
        notes=notes,
    )
