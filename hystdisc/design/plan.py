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

from dataclasses import dataclass, field

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
from hystdisc.fitting import Parametrization
from hystdisc.results import Results

#: Candidates listed per family in the separation ranking.
SEPARATION_TOP = 5
#: Rebuilt intervals this far from the fit's (either way) earn a note.
REBUILD_TOLERANCE = 2.0
#: A free parameter this close to a bound (relative) is held by it.
BOUND_TOL = 1e-9


def _sampling(results: Results) -> tuple[float, float]:
    """Sampling rate and median duration of the training runs."""
    env = results.envelope.runs if results.envelope else []
    rates, durations = [], []
    for r, e in zip(results.runs, env, strict=False):
        d = float(e.duration or 0.0)
        if d > 0 and r.samples:
            rates.append((r.samples - 1) / d)
            durations.append(d)
    if not rates:
        return 1000.0, 3.0
    return float(f"{np.median(rates):.6g}"), float(np.median(durations))


def _uses_final(results: Results, family: str) -> bool:
    """The design works on the final model (the family with its accepted effects)."""
    final = results.final
    return final is not None and final.family == family


def _sigma(results: Results, family: str) -> float:
    """The residual RMS the fit's intervals were computed with."""
    if _uses_final(results, family) and results.residual is not None:
        rms = results.residual.rms  # the final model's residual
    else:
        rms = results.families[family].rms
    sigma = rms if rms else results.noise_std
    if not sigma or not np.isfinite(sigma) or sigma <= 0:
        raise HystdiscError(
            "results: no residual RMS or noise level to scale the information; fix: rerun "
            "hystdisc discover"
        )
    return float(sigma)


def _trim(results: Results, sigma: float) -> float:
    """The noise level a release record is trimmed at (the measured noise)."""
    return float(results.noise_std or sigma)


def _stored_widths(results: Results, family: str, final: bool) -> dict[str, float]:
    params = results.families[family].parameters
    if final and results.final.parameters:
        params = results.final.parameters
    out = {}
    for k, p in params.items():
        ci = p.ci95
        if ci and ci[0] is not None and ci[1] is not None:
            out[k] = float(ci[1]) - float(ci[0])
    return out


def _outputs(par: Parametrization, experiment: str, specs: list[RunSpec], sigma: float):
    data = fit_data(experiment, specs, sigma)
    nn = data.n_nuisance(par.has_state())
    nus = list(data.nuisance_start(par.has_state()).reshape(len(specs), nn))
    runs = list(range(len(specs)))
    return par.simulate(data, [par.model(par.x0)] * len(specs), runs, nus), data.mask


@dataclass
class Information:
    """What a design needs of a fit: its model, the information in hand, the scales.

    Built by :func:`information_in_hand`; :meth:`widths` gives the expected 95 % widths
    after any extra information.

    Attributes
    ----------
    results : Results
        The fit.
    par : Parametrization
        Its model (:func:`~hystdisc.design.information.fitted_parametrization`).
    names : list of str
        The reported parameters (free and derived; fixed ones left out).
    values : dict of str to float
        Their fitted values.
    sigma : float
        Residual standard deviation the information is scaled by.
    fs, duration : float
        Sampling rate and (median) duration of the training runs.
    F0 : ndarray
        Information of the runs rebuilt from the training envelope.
    G : ndarray
        ``d p / d x`` of the reported parameters by the free ones.
    rebuilt, before : dict of str to float
        The 95 % widths from ``F0``, and the fit's own (``results.json``).
    judged : list of str
        The parameters whose relative width counts: not zero, and not held by a bound in
        the fit (such an interval says nothing about the value).
    notes : list of str
        Remarks (a rebuild far from the fit's intervals).
    """

    results: Results
    par: Parametrization
    names: list[str]
    values: dict[str, float]
    sigma: float
    fs: float
    duration: float
    F0: np.ndarray
    G: np.ndarray
    rebuilt: dict[str, float]
    before: dict[str, float]
    judged: list[str]
    notes: list[str] = field(default_factory=list)

    def widths(self, F: np.ndarray) -> np.ndarray:
        """Expected 95 % widths for information ``F``: the fit's widths times the shrink
        ``F`` predicts against ``F0`` (what the rebuild misses cancels in the ratio)."""
        scale = np.array(
            [self.before[k] / self.rebuilt[k] if self.rebuilt[k] > 0 else 1.0 for k in self.names]
        )
        return scale * interval_widths(F, self.G)

    def widest(self, F: np.ndarray) -> float:
        """The widest expected 95 % interval relative to its value, for information ``F``."""
        vals = np.array([abs(self.values[k]) for k in self.names])
        judged = np.array([k in self.judged for k in self.names])
        return float(np.max(self.widths(F)[judged] / vals[judged]))

    def of(self, specs: list[RunSpec]) -> np.ndarray:
        """Each run's information, ``(len(specs), k, k)`` (NaN: the model diverges)."""
        trim = _trim(self.results, self.sigma)
        return run_information(self.par, self.results.experiment, specs, self.sigma, trim)


def information_in_hand(results: Results, parameters: list[str] | None = None) -> Information:
    """The fit's model and the information of the runs it saw (rebuilt from its envelope).

    ``parameters`` names the parameters whose relative width counts (default: every
    parameter not held by a bound in the fit and not indistinguishable from an admissible
    zero).

    Raises
    ------
    HystdiscError
        For a file without a training envelope, a forced experiment, or a model that
        diverges on a rebuilt run.
    """
    if not results.envelope or not results.envelope.runs:
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
    F0 = run_information(par, results.experiment, recorded, sigma, _trim(results, sigma))
    if not np.all(np.isfinite(F0)):
        raise HystdiscError(
            "results: the fitted model diverges on a run it was fitted to; fix: rerun "
            "hystdisc discover"
        )
    F0 = F0.sum(axis=0)
    fixed = getattr(par, "fixed", {}) or {}
    p = par.params(par.x0)
    names = [k for k in p if k not in fixed]
    G = parameter_gradient(par, par.x0, names)
    rebuilt = dict(zip(names, map(float, interval_widths(F0, G)), strict=True))
    stored = _stored_widths(results, family, _uses_final(results, family))
    before = {k: stored.get(k, rebuilt[k]) for k in names}
    notes = [
        f"{k}: the runs rebuilt from the training envelope give an interval "
        f"{rebuilt[k] / before[k]:.2g} times the fit's (the expected widths are scaled back)"
        for k in names
        if before[k] > 0
        and not 1 / REBUILD_TOLERANCE <= rebuilt[k] / before[k] <= REBUILD_TOLERANCE
    ]
    vals = {k: float(p[k]) for k in names}
    pinned = [
        n
        for n, x, lo, hi in zip(par.names, par.x0, par.lower, par.upper, strict=True)
        if min(x - lo, hi - x) <= BOUND_TOL * (1.0 + abs(x))
    ]
    notes += [f"{k} is held by a bound in the fit: its interval is not judged" for k in pinned]
    bounds = dict(zip(par.names, zip(par.lower, par.upper, strict=True), strict=True))
    # a relative width means nothing for a value that cannot be told from an admissible 0
    unsure = [
        k
        for k in names
        if k not in pinned
        and abs(vals[k]) <= before[k] / 2
        and bounds.get(k, (-np.inf, np.inf))[0] <= 0 <= bounds.get(k, (-np.inf, np.inf))[1]
    ]
    notes += [
        f"{k}: its 95 % interval reaches 0, an admissible value: its width relative to the "
        "value is not judged (name it with parameters= / --parameters to target it)"
        for k in unsure
    ]
    if parameters is not None:
        unknown = [k for k in parameters if k not in names]
        if unknown:
            raise HystdiscError(
                f"results: no fitted parameter '{unknown[0]}' in {family}; fix: use some of "
                f"{', '.join(names)}"
            )
        judged = [k for k in names if k in parameters and vals[k] != 0]
    else:
        judged = [k for k in names if vals[k] != 0 and k not in pinned and k not in unsure]
    if not judged:
        raise HystdiscError(
            "results: no parameter to judge (each is zero, at a bound or not told from 0); "
            "fix: name the parameters to target"
        )
    return Information(
        results, par, names, vals, sigma, fs, duration, F0, G, rebuilt, before, judged, notes
    )


def expected_widths(results: Results, runs: list[RunSpec]) -> dict[str, float]:
    """The 95 % interval widths expected after recording ``runs`` too.

    Examples
    --------
    >>> from hystdisc import Discovery
    >>> from hystdisc.simulation.synth import generate
    >>> data = generate("dahl", currents=(0, 0.5), theta0=0.05, duration=2.0, fs=500, seed=1)
    >>> res = Discovery(model="dahl", heldout=False, close_loop=False).fit(data).results_
    >>> now = expected_widths(res, [])
    >>> now["rho"] == res.selected.parameters["rho"].ci95[1] - res.selected.parameters["rho"].ci95[0]
    True
    >>> more = expected_widths(res, [RunSpec("release", 1.0, 0.2, duration=2.0, fs=500.0)])
    >>> all(more[k] < now[k] for k in now)
    True
    """
    info = information_in_hand(results)
    F = info.F0 + info.of(list(runs)).sum(axis=0)
    if not np.all(np.isfinite(F)):
        raise HystdiscError("the fitted model diverges on one of the runs; fix: change the runs")
    return dict(zip(info.names, map(float, info.widths(F)), strict=True))


def design(
    results: Results,
    budget: int = 3,
    candidates: list[RunSpec] | None = None,
    currents: list[float] | None = None,
    parameters: list[str] | None = None,
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
        Currents of the default grid (default: 0 to the largest trained current).
    parameters : list of str, optional
        The parameters whose widest relative interval is shrunk (default: see
        :func:`information_in_hand`).

    Returns
    -------
    DesignResult

    Raises
    ------
    HystdiscError
        For a budget below 1, a file without a training envelope, a forced experiment,
        or a model that diverges on every candidate.

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
    info = information_in_hand(results, parameters)
    family, par, sigma = results.family, info.par, info.sigma
    driven = experiment_kind(results.experiment)
    cands = candidates or candidate_runs(results.envelope, driven, info.fs, info.duration, currents)
    Fc = info.of(cands)
    ok = [c for c in range(len(cands)) if np.all(np.isfinite(Fc[c]))]
    notes = list(info.notes)
    if len(ok) < len(cands):
        dropped = [cands[c].label() for c in range(len(cands)) if c not in ok]
        notes.append(f"the fitted model diverges on {len(dropped)} candidates ({dropped[0]}, ...)")
    if not ok:
        raise HystdiscError(
            "results: the fitted model diverges on every candidate run; fix: give other currents"
        )
    cands, Fc = [cands[c] for c in ok], Fc[ok]
    picks, steps = greedy(info.F0, Fc, info.widest, int(budget))
    notes += edge_notes([cands[c] for c in picks], cands)
    F = info.F0 + Fc[picks].sum(axis=0)
    after = dict(zip(info.names, map(float, info.widths(F)), strict=True))
    alone = sorted((info.widest(info.F0 + Fc[c]), c) for c in range(len(cands)))
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
        names=info.names,
        judged=info.judged,
        values=info.values,
        widths_before=info.before,
        predicted_before=info.rebuilt,
        widths_after=after,
        runs=[cands[c] for c in picks],
        widest_steps=steps,
        ranking=[(cands[c], v) for v, c in alone],
        separation=sep,
        notes=notes,
    )


#: What each candidate dimension is called in :func:`edge_notes`, by kind of run.
_DIMENSIONS = (
    (
        "amplitude",
        {"release": ("release angle", "rad"), "sine": ("amplitude", ""), "multisine": ("peak", "")},
    ),
    ("frequency", {"sine": ("frequency", "Hz")}),
    (
        "current",
        {"release": ("current", "A"), "sine": ("current", "A"), "multisine": ("current", "A")},
    ),
)


def edge_notes(picks: list[RunSpec], candidates: list[RunSpec]) -> list[str]:
    """Notes on suggested runs that sit at the top of their candidate range.

    A run chosen at the largest angle, amplitude, frequency or current the candidates
    offer may be chosen only because the grid stops there: the information could keep
    growing beyond it (if the rig allows it), and it is further from what the model was
    identified on.

    Parameters
    ----------
    picks : list of RunSpec
        The suggested runs.
    candidates : list of RunSpec
        The runs they were chosen from.

    Returns
    -------
    list of str
        One note per suggested run and dimension at the top of its range.

    Examples
    --------
    >>> cands = [RunSpec("release", i, a) for i in (0.0, 1.0) for a in (0.15, 0.3, 1.0)]
    >>> edge_notes([RunSpec("release", 0.0, 1.0)], cands)
    ['release from 1 rad at 0 A: 1 rad is the top of the candidate release angles (0.15 to 1 rad): the grid stops there, and a larger release angle, if the rig allows it, may inform more']
    """
    notes = []
    for run in picks:
        same = [c for c in candidates if c.kind == run.kind]
        for attr, names in _DIMENSIONS:
            if run.kind not in names:
                continue
            values = sorted({round(float(getattr(c, attr)), 12) for c in same})
            v = round(float(getattr(run, attr)), 12)
            if len(values) < 2 or v < values[-1]:
                continue
            name, unit = names[run.kind]
            u = f" {unit}" if unit else ""
            notes.append(
                f"{run.label()}: {v:.3g}{u} is the top of the candidate {name}s "
                f"({values[0]:.3g} to {values[-1]:.3g}{u}): the grid stops there, and a "
                f"larger {name}, if the rig allows it, may inform more"
            )
    return notes
