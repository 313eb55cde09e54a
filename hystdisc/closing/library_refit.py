"""The open library's terms refitted into the model by output error, judged held out.

On a driven test (the motion imposed, the force measured) a term of the open library is a
force of the imposed motion and the current alone (:func:`~hystdisc.models.term_columns.term_column`):
the model with the terms predicts ``F = F_model(theta, theta_dot, i; p) + sum_j c_j g_j``.
:func:`refit_terms` fits the model's parameters ``p`` (and each run's initial state) with
the coefficients ``c`` by output error, from the fit's optimum: the terms enter linearly,
so ``c`` is projected out (variable projection: each step of ``p`` sees the residual the
best ``c`` leaves, Kaufman's Jacobian).

The verdict is the one every effect gets (:mod:`hystdisc.closing.rounds`): each test
condition is left out in turn, the model **with** the terms and the model **without** them
are each refitted on the other conditions from their joint optima (the same budget), and
the left-out condition is predicted by both. The terms are accepted when

* they lower BIC by more than :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN`;
* they remove at least :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the residual's
  excess over the floor, or lower the held-out error of every condition (at least
  :data:`~hystdisc.closing.rounds.MIN_FOLDS_ALL`);
* the pooled held-out error falls;
* the model with them is physically admissible (its own parameters:
  :func:`~hystdisc.simulation.admissibility.check_admissible`), still absorbs energy in
  every training run (the terms may not make the damper a source), and the terms in the
  position alone do not soften to a negative stiffness within twice the training stroke.

The term set was chosen on all the data (the open library's stability selection); what
the folds hold out is every coefficient and parameter.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from hystdisc.closing.refit import EFFECT_BIC_MARGIN
from hystdisc.closing.rounds import MIN_EXCESS_SHARE, MIN_FOLDS_ALL, excess_over
from hystdisc.closing.scores import effect_z2, significance_params
from hystdisc.data.envelope import Envelope
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OEFit, OutputErrorFitter
from hystdisc.fitting.lm import levenberg_marquardt
from hystdisc.models.term_columns import term_column
from hystdisc.simulation.admissibility import check_admissible
from hystdisc.stats import bic


@dataclass
class TermsRefit:
    """The open library's terms refitted into the model and judged on held-out conditions.

    Attributes
    ----------
    terms : list of str
        The terms' names (their formulas).
    coefficients, stderr : dict of str to float
        Each term's refitted coefficient and its standard error (output units per the
        term's unit).
    params : dict of str to float
        The model's free parameters refitted with the terms.
    rms_before, rms_after : float
        In-sample RMS without and with the terms.
    bic_before, bic_after : float
        BIC without and with them.
    heldout_before, heldout_after : float or None
        Pooled held-out RMS (each condition left out, both models refitted on the others);
        None when a fold diverged.
    fold_before, fold_after : list of float
        Each condition's held-out RMS.
    excess_share : float
        Share of the residual's excess over the floor (``RSS - N floor^2``) they remove.
    admissible : bool
        The model's own parameters are admissible and the whole model absorbs energy in
        every training run.
    accepted : bool
        The verdict (see the module docstring).
    note : str
        Why, in words.
    dropped : list of str
        Terms of the library's set left out: its spring terms, when with them the spring
        softened to a negative stiffness (:func:`refit_admissible`).
    redundant : dict of str to float
        The model's catalogued effects the terms made redundant, each with its Wald
        chi-square (smallest squared z-score of its parameters) in the fit with the terms:
        left out of the refitted model, since its parameter was no longer significant and
        BIC fell without it (an effect accepted as a stand-in for what the terms describe).
    fit : OEFit or None
        The model's fit moved to the refitted parameters (its residual, RMS and intervals
        are the catalogued model's at its own optimum; not in ``results.json``: the
        pipeline records its model).

    Examples
    --------
    >>> r = TermsRefit(["bias[i=1 A]"], {"bias[i=1 A]": 29.5}, {"bias[i=1 A]": 0.4}, {},
    ...                46.1, 15.2, -10.0, -900.0, 46.6, 15.4, [46.6], [15.4], 0.9, True, True)
    >>> print(r.equation())
    F_extra = 29.5*bias[i=1 A]
    """

    terms: list[str]
    coefficients: dict[str, float]
    stderr: dict[str, float]
    params: dict[str, float]
    rms_before: float
    rms_after: float
    bic_before: float
    bic_after: float
    heldout_before: float | None
    heldout_after: float | None
    fold_before: list[float] = field(default_factory=list)
    fold_after: list[float] = field(default_factory=list)
    excess_share: float = 0.0
    admissible: bool = False
    accepted: bool = False
    note: str = ""
    dropped: list[str] = field(default_factory=list)
    redundant: dict[str, float] = field(default_factory=dict)
    fit: OEFit | None = field(default=None, repr=False, compare=False)

    @property
    def lower(self) -> int:
        """The held-out conditions the terms predict better."""
        return sum(a < b for a, b in zip(self.fold_after, self.fold_before, strict=True))

    def equation(self) -> str:
        """The refitted terms as an equation of the extra force."""
        parts = [f"{self.coefficients[n]:+.4g}*{n}" for n in self.terms]
        text = " ".join(parts).lstrip("+")
        return "F_extra = " + text.replace(" +", " + ").replace(" -", " - ")

    def sentence(self) -> str:
        """One line: the verdict with the held-out error before and after."""
        verdict = "accepted" if self.accepted else "not accepted"
        held = (
            f"held out {self.heldout_before:.4g} -> {self.heldout_after:.4g} (lower in "
            f"{self.lower} of {len(self.fold_after)} conditions)"
            if self.heldout_before is not None and self.heldout_after is not None
            else "held out: not available"
        )
        return (
            f"refitted into the model by output error: RMS {self.rms_before:.4g} -> "
            f"{self.rms_after:.4g}, {held}: {verdict} ({self.note})"
        )

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "fit"}
        return out | {"equation": self.equation(), "lower": self.lower}


def columns(data, names: Sequence[str], runs: Sequence[int] | None = None) -> np.ndarray:
    """The terms ``names`` on the masked samples of ``data``'s runs (all, or ``runs``), in
    the fitter's row order."""
    runs = range(data.n_runs) if runs is None else runs
    blocks = []
    for k in runs:
        th, w, t = data.theta[k], data.theta_dot[k], data.t[k]
        i, m = float(data.currents[k]), data.mask[k]
        blocks.append(np.column_stack([term_column(n, th, w, i, t)[m] for n in names]))
    return np.vstack(blocks)


def _projector(G: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``x -> x - P_G x``: what is left of ``x`` (vector or matrix) beside the span of
    ``G``'s columns that are not zero on these rows."""
    G = G[:, np.any(G != 0.0, axis=0)]
    q, _ = np.linalg.qr(G / np.sqrt(np.mean(G**2, axis=0)))
    return lambda x: x - q @ (q.T @ x)


def _fit(fitter: OutputErrorFitter, v0: np.ndarray, G: np.ndarray | None, iters: int):
    """Output-error fit from ``v0`` (parameters, then the runs' initial states), with the
    linear terms ``G`` projected out when given. Returns the vector, the residual
    (simulated minus measured, the terms' best contribution included) and the terms'
    coefficients."""
    npar = len(fitter.par.names)
    lo = np.concatenate([fitter.par.lower, np.full(v0.size - npar, -np.inf)])
    hi = np.concatenate([fitter.par.upper, np.full(v0.size - npar, np.inf)])
    if G is None:
        fun, jac = fitter.residuals, fitter.jacobian
    else:
        proj = _projector(G)
        fun = lambda v: proj(fitter.residuals(v))  # noqa: E731
        jac = lambda v: proj(fitter.jacobian(v))  # noqa: E731
    with np.errstate(all="ignore"):
        v, *_ = levenberg_marquardt(fun, jac, v0, lo, hi, max_iter=iters)
        r = fitter.residuals(v)
    if G is None:
        return v, r, np.zeros(0)
    # a term that is zero on these rows (a bias of a level a fold leaves out) gets 0
    c = -np.linalg.lstsq(G, r, rcond=None)[0]
    return v, r + G @ c, c


def _absorbs(data, resid: np.ndarray, offsets: np.ndarray) -> bool:
    """The predicted force (measured plus the residual) times the velocity, summed over
    each training run, is positive: the model absorbs energy in every run."""
    for k in range(data.n_runs):
        m = data.mask[k]
        f = data.y[k][m] + resid[offsets[k] : offsets[k + 1]]
        if not float(np.sum(f * data.theta_dot[k][m])) > 0.0:
            return False
    return True


def in_position(name: str) -> bool:
    """The term is a force of the position alone (a spring: ``theta``, ``theta^3``,
    ``theta*[theta>0]``).

    Examples
    --------
    >>> in_position("theta^3"), in_position("i*theta_dot"), in_position("play(theta,0.1)-theta")
    (True, False, False)
    """
    return "theta" in name and "theta_dot" not in name and "play" not in name


def _softens(data, names: Sequence[str], coefs: np.ndarray) -> str | None:
    """Where the terms in the position alone (``theta``, ``theta^3``, ...) make a spring of
    negative stiffness within twice the training stroke, at any training current, in
    words; None when they stiffen (or hold no such term). The model's own spring is
    admissible on its own (it is refitted beside them)."""
    own = [(n, c) for n, c in zip(names, coefs, strict=True) if in_position(n)]
    if not own:
        return None
    reach = 2.0 * max(float(np.max(np.abs(th))) for th in data.theta)
    th = np.linspace(-reach, reach, 401)
    zero, t = np.zeros_like(th), np.arange(th.size, dtype=float)
    for i in sorted({float(c) for c in data.currents}):
        f = sum(c * term_column(n, th, zero, i, t) for n, c in own)
        k = np.diff(f) / np.diff(th)
        if np.any(k < -1e-9 * max(float(np.max(np.abs(k))), 1e-300)):
            at = float(th[int(np.argmin(k))])
            return f"the terms' spring has a negative stiffness at {at:.3g} ({i:g} A)"
    return None


def refit_terms(
    data,
    fit: OEFit,
    names: Sequence[str],
    floor: float,
    max_nfev: int = 60,
    envelope=None,
    before: tuple[float | None, list[float]] | None = None,
) -> TermsRefit:
    """Refit the model of ``fit`` with the terms ``names`` by output error and judge them
    on held-out conditions (see the module docstring).

    Parameters
    ----------
    data : FitData
        The fit's data, a driven test (the force is the output).
    fit : OEFit
        The model's fit at its optimum.
    names : sequence of str
        The terms (names :func:`~hystdisc.models.term_columns.term_column` knows).
    floor : float
        The measurement's floor (repeatability or noise), the output's units.
    max_nfev : int
        Iterations of each fit (the joint one and each fold's, with and without the terms).
    envelope : Envelope, optional
        The training envelope of the admissibility check.
    before : tuple, optional
        The held-out errors of ``fit``'s model without terms (pooled, per condition), when
        an earlier refit of the same fit computed them.

    Returns
    -------
    TermsRefit

    Raises
    ------
    ValueError
        For a test whose output is not the force, or no term.
    """
    if data.exp.output != "torque":
        raise ValueError("the open library's terms are refitted on a force output (driven)")
    names = list(names)
    if not names:
        raise ValueError("no term to refit")
    par = fit.par.like(dict(fit.params), fit.par.effects)
    fitter = OutputErrorFitter(data, par, max_nfev=max_nfev)
    v_fit = np.concatenate([par.x0, np.asarray(fit.nuisance, dtype=float).ravel()])
    G = columns(data, names)
    v, resid, c = _fit(fitter, v_fit, G, max_nfev)
    n, p = resid.size, len(names)
    n_eff = float(data.n_eff()) if any(data.run_filters()) else float(n)
    joint = _Joint(fitter, v, resid, c, fit.n_params + p, G, n_eff)
    joint, redundant = _without_redundant(data, fit, joint, max_nfev)
    fitter, v, resid, c = joint.fitter, joint.v, joint.resid, joint.c
    npar = len(fitter.par.names)
    rss = joint.rss
    bic_after = joint.bic
    se = np.sqrt(np.clip(np.diag(joint.cov)[-p:], 0.0, None))
    excess = excess_over(fit, floor)
    share = (fit.rss - rss) / excess if excess > 0 else 0.0
    moved = dataclasses.replace(
        fit, par=fitter.par, x=v[:npar], nuisance=v[npar:].reshape(fit.nuisance.shape)
    )
    if envelope is None:
        envelope = Envelope.from_runs(data.names, data.t, data.theta, data.theta_dot, data.currents)
    adm = check_admissible(moved.model if moved.is_system else moved.term_part, envelope)
    absorbs = _absorbs(data, resid, fitter.row_offsets)
    soft = _softens(data, names, c)
    out = TermsRefit(
        terms=names,
        coefficients=dict(zip(names, map(float, c), strict=True)),
        stderr=dict(zip(names, map(float, se), strict=True)),
        params=dict(zip(fitter.par.names, map(float, v[:npar]), strict=True)),
        rms_before=float(fit.rms),
        rms_after=float(np.sqrt(rss / n)),
        bic_before=float(fit.bic),
        bic_after=float(bic_after),
        heldout_before=None,
        heldout_after=None,
        excess_share=float(share),
        admissible=bool(adm.ok and absorbs and soft is None),
        redundant=redundant,
        fit=moved,
    )
    # the model without the terms is held out once for every term set of one fit
    without = before if before is not None else _heldout(data, par, v_fit, None, max_nfev)
    with_terms = _heldout(data, fitter.par, v, names, max_nfev)
    if without[0] is not None and with_terms[0] is not None:  # else: a fold diverged
        out.heldout_before, out.fold_before = without
        out.heldout_after, out.fold_after = with_terms
    violation = adm.violations[0] if not adm.ok else soft
    out.accepted, out.note = _verdict(out, violation, absorbs)
    return out


@dataclass
class _Joint:
    """The model fitted with the terms ``G`` (columns) on ``n`` residuals worth ``n_eff``
    independent samples: its fitter, the vector (parameters, then the runs' initial
    states), the residual, the terms' coefficients, and the free parameters counted with
    the terms (BIC's ``k``)."""

    fitter: OutputErrorFitter
    v: np.ndarray
    resid: np.ndarray
    c: np.ndarray
    k: int
    G: np.ndarray
    n_eff: float

    @property
    def rss(self) -> float:
        return float(self.resid @ self.resid)

    @property
    def bic(self) -> float:
        return bic(self.rss, self.resid.size, self.k, n_eff=self.n_eff)

    @cached_property
    def cov(self) -> np.ndarray:
        """The covariance of the vector and the coefficients (last), from the whole
        Jacobian at the optimum."""
        with np.errstate(all="ignore"):
            J = np.column_stack([self.fitter.jacobian(self.v), self.G])
        sc = np.sqrt(np.mean(J**2, axis=0))
        sc[sc == 0] = 1.0
        n = self.resid.size
        scaled = np.linalg.pinv((J / sc).T @ (J / sc)) / np.outer(sc, sc)
        return scaled * self.rss / max(n - J.shape[1], 1) * n / self.n_eff

    def weak_effects(self) -> list[tuple[float, str]]:
        """The model's catalogued effects whose parameters are free and not significant
        beside the terms (:func:`~hystdisc.closing.scores.effect_z2` at most ``log n``, the
        loop's rule for a redundant effect), weakest first, with that chi-square."""
        names = self.fitter.par.names
        se = np.sqrt(np.clip(np.diag(self.cov)[: len(names)], 0.0, None))
        values = dict(zip(names, map(float, self.v), strict=False))
        stderr = dict(zip(names, map(float, se), strict=True))
        out = []
        for name in self.fitter.par.effects:
            if not set(significance_params(name)) <= values.keys():
                continue  # judged by a derived parameter (a compliance's stiffness)
            z2 = effect_z2(name, values, stderr)
            if z2 <= np.log(self.resid.size):
                out.append((z2, name))
        return sorted(out)


def _without_redundant(
    data, fit: OEFit, joint: _Joint, iters: int
) -> tuple[_Joint, dict[str, float]]:
    """The model with the terms, without the catalogued effects the terms made
    redundant: the weakest effect whose parameter is no longer significant is left out
    and the model refitted with the terms from there, kept when BIC falls; until none is.

    The loop accepts an effect by what it removes of a residual that the catalogue cannot
    describe; an effect that only stood in for the terms (a constant bias for the mean of
    a stiffness in tension alone) has nothing left to explain once they are in. Returns
    the kept joint fit and each dropped effect's chi-square beside the terms."""
    dropped: dict[str, float] = {}
    skip: set[str] = set()
    while True:
        weak = [(z2, e) for z2, e in joint.weak_effects() if e not in skip]
        if not weak:
            return joint, dropped
        z2, name = weak[0]
        par = joint.fitter.par
        npar = len(par.names)
        start = {**fit.params, **dict(zip(par.names, map(float, joint.v[:npar]), strict=True))}
        smaller = par.like(start, tuple(e for e in par.effects if e != name))
        sub = OutputErrorFitter(data, smaller, max_nfev=iters)
        if sub.nnu != joint.fitter.nnu:  # the effect has states of its own: kept
            skip.add(name)
            continue
        v, resid, c = _fit(sub, np.concatenate([smaller.x0, joint.v[npar:]]), joint.G, iters)
        k = joint.k - (npar - len(smaller.names))
        new = _Joint(sub, v, resid, c, k, joint.G, joint.n_eff)
        if not (np.isfinite(new.rss) and new.bic < joint.bic):
            skip.add(name)
            continue
        joint, dropped[name] = new, float(z2)


def _heldout(data, par, v0, names, iters) -> tuple[float | None, list[float]]:
    """Each condition left out: the model (with the terms ``names``, or without any for
    None) refitted on the others from ``v0``, its joint optimum, and the condition
    predicted. Returns the pooled RMS (None when a prediction diverged) and each fold's."""
    npar = len(par.names)
    nu = v0[npar:].reshape(data.n_runs, (v0.size - npar) // data.n_runs)
    sq, folds, count = 0.0, [], 0
    for fold in data.folds():
        train = [k for k in range(data.n_runs) if k not in fold]
        sub = OutputErrorFitter(data.subset(train), par, max_nfev=iters)
        test = OutputErrorFitter(data.subset(fold), par, max_nfev=iters)
        G = None if names is None else columns(data, names, train)
        try:
            vf, _, c = _fit(sub, np.concatenate([v0[:npar], nu[train].ravel()]), G, iters)
        except (HystdiscError, np.linalg.LinAlgError, ValueError):
            return None, []
        with np.errstate(all="ignore"):
            e = test.residuals(np.concatenate([vf[:npar], nu[fold].ravel()]))
        if G is not None:
            e = e + columns(data, names, fold) @ c
        if not np.all(np.isfinite(e)):
            return None, []
        sq, count = sq + float(e @ e), count + e.size
        folds.append(float(np.sqrt(np.mean(e**2))))
    return float(np.sqrt(sq / max(count, 1))), folds


def _verdict(r: TermsRefit, violation: str | None, absorbs: bool) -> tuple[bool, str]:
    """The acceptance rule of the module docstring, and why in words."""
    if violation is not None:
        return False, f"the model with them is not physical: {violation}"
    if not absorbs:
        return False, "the model with them gives energy in a training run"
    if not r.bic_after < r.bic_before - EFFECT_BIC_MARGIN:
        return False, "BIC does not fall by the margin"
    if r.heldout_before is None or r.heldout_after is None:
        return False, "a held-out prediction diverged"
    if not r.heldout_after < r.heldout_before:
        return False, "they do not lower the held-out error"
    folds = len(r.fold_after)
    every = r.lower == folds and folds >= MIN_FOLDS_ALL
    if r.excess_share < MIN_EXCESS_SHARE and not every:
        return False, (
            f"they remove only {r.excess_share:.0%} of the residual's excess over the floor"
        )
    return True, (
        f"they remove {r.excess_share:.0%} of the excess over the floor and predict "
        f"{r.lower} of {folds} held-out conditions better"
    )


def refit_admissible(data, fit: OEFit, names: Sequence[str], floor: float, **kw) -> TermsRefit:
    """:func:`refit_terms`, and when the terms' spring softens to a negative stiffness
    (an inadmissible spring: no such damper exists), once more without the terms in the
    position alone (:func:`in_position`); the second refit is the verdict, its
    ``dropped`` says which terms were left out and its note why."""
    first = refit_terms(data, fit, names, floor, **kw)
    rest = [n for n in names if not in_position(n)]
    coefs = np.array([first.coefficients[n] for n in first.terms])
    if first.accepted or not rest or _softens(data, first.terms, coefs) is None:
        return first
    held = first.heldout_before  # the model without terms, held out (None: not computed)
    before = None if held is None else (held, first.fold_before)
    out = refit_terms(data, fit, rest, floor, before=before, **kw)
    out.dropped = [n for n in names if in_position(n)]
    out.note += f"; without {', '.join(out.dropped)} ({first.note})"
    return out
