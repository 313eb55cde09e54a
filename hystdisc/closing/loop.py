"""Closing the loop: residual -> the catalogued effect the model lacks -> refit -> whiteness.

DESIGN.md section 6, issue 4. After the output-error fit of the selected (or declared)
family:

1. **Candidates.** The effect catalogue (:data:`hystdisc.models.EFFECTS`) minus the effects
   whose torque terms the model already has (Bouc-Wen and LuGre carry ``i*theta_dot``,
   Bingham ``sign(theta_dot)``), the effects that need a hysteretic state the model lacks
   (``i^2*z`` in Bingham), the current effects the currents cannot identify (one current
   level; ``i^2`` needs three levels) and the spring effects (``offset``, ``cubic_stiffness``)
   when the rig has no spring (``k_s`` not significantly above 0, a characterization
   machine).
2. **Diagnosis** (:func:`score_effects`): the score (Lagrange-multiplier) test in
   output-error space. All candidates are appended to the model at value 0, and one
   batched forward-difference Jacobian at the current optimum gives each effect's
   signature ``g`` (how the simulated output moves when the effect is switched on) beside
   the model's own columns ``A`` (parameters and initial angles). ``g`` is projected out of
   the span of ``A``; what the projected column explains of the residual is the
   Gauss-Newton predicted RSS reduction of adding the effect and refitting everything.
   Its share of the RSS is the effect's *evidence* (pooled, and each run's part), and it
   predicts the BIC change ``N log(1 - share) + q log N``. Two more views guard against
   the local view's blind spots (a fast hysteretic state mimics Coulomb friction to first
   order; a model stuck in a wrong optimum has a misleading Jacobian): the
   *equation-error evidence* (the same share for the equation residual
   ``target - T(theta, theta_dot, z, i)`` and the effect's torque term, the model's terms
   projected out) and, while the residual is clearly above the noise, the *stage-1 start*
   of each augmented structure (variable projection of family + effect on the
   equation-error data, simulated: :func:`stage1_start`).
3. **Augmentation** (:func:`augment`): per round, the top two candidates by output-error
   evidence and the top by equation-error evidence whose predicted BIC drop beats
   :data:`EFFECT_BIC_MARGIN` are refitted by output error (from the current optimum with
   the Gauss-Newton estimate of the effect); when that does not reach the noise, the
   candidate with the best stage-1 start is refitted from it (first, when the residual is
   far above the noise). A refit is accepted when it lowers BIC by more than the margin,
   its effect parameter is significant on its own (squared z-score above ``log N``) and it
   removes at least :data:`MIN_EXCESS_SHARE` of the residual's excess over the noise; the
   best accepted refit of the round wins, earlier effects that it makes redundant are
   dropped again, the residual is re-diagnosed, and the loop repeats until nothing is
   accepted. Only candidates with evidence are refitted: on data the model explains, the
   loop costs one Jacobian.
4. **Whiteness** (:func:`assess_residual`): the final residual is tested by a Ljung-Box
   test pooled over runs and its spectrum is averaged over runs. When it is not white and
   its RMS is clearly above the noise (:data:`NOISE_RATIO`), ``unexplained`` is set with
   the dominant frequency and a sentence such as "a resonance near 6.0 Hz that no
   catalogued effect explains".

:func:`close_loop` runs all of it on a fitted :class:`~hystdisc.discovery.stage1.Discovery` and
writes the ``effects``, ``effects_tried``, ``unexplained``, ``residual`` and ``model`` keys
of its results (DESIGN.md section 5).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from hystdisc.closing.diagnostics import WHITE_P, ljung_box_pooled, residual_spectrum, spectral_peak
from hystdisc.fitting.output_error import FamilyParametrization, FitData, OEFit, OutputErrorFitter
from hystdisc.models import EFFECTS, Z_TORQUE_TERMS, TermModel

#: An effect is accepted only when its refit lowers BIC by more than this (the margin
#: within which :mod:`hystdisc.discovery.stage1` calls two families equal fits), and refitted only
#: when the score test predicts such a drop.
EFFECT_BIC_MARGIN = 6.0
#: Local refits per round at most (two output-error leaders, the equation-error leader);
#: the stage-1 screening may add one more.
MAX_REFITS_PER_ROUND = 3
#: A final residual whose RMS exceeds the noise estimate by this factor is "clearly above".
NOISE_RATIO = 1.1
#: An accepted effect must also remove at least this share of the residual's excess over
#: the noise (RSS - N noise^2): a catalogued effect that only trims a structure it cannot
#: explain (a resonance) is not reported as found, whatever the sample size makes of it.
MIN_EXCESS_SHARE = 0.1
#: Above this many times the noise the current optimum may be a trap for the local views:
#: the stage-1 starts of the augmented structures are screened first.
FAR_RATIO = 5.0
#: Relative accuracy floor of the fitting simulator (see :func:`accuracy_floor`).
SIM_FLOOR_REL = 1e-5
#: Effects whose terms are linear in these signals need a rig spring to mean anything.
SPRING_EFFECTS = ("offset", "cubic_stiffness")


# ----------------------------------------------------------------------------- results


@dataclass
class EffectScore:
    """The diagnosis of one candidate effect against the current residual.

    Attributes
    ----------
    name : str
        Catalogue name.
    terms : tuple of str
        Torque terms the effect adds.
    evidence : float
        Share of the output-error RSS that the effect's projected signature explains
        (the Gauss-Newton predicted relative RSS reduction), pooled over runs.
    per_run : list of float
        Each run's part of the predicted RSS reduction over that run's RSS (the runs'
        parts, weighted by their RSS, add up to ``evidence``). A current effect also
        improves its 0 A run, through the shared parameters it frees.
    lm : float
        Score statistic: predicted RSS reduction over the residual variance (about
        chi-square with one degree of freedom per parameter when the effect is absent).
    predicted_rms : float
        Output-error RMS predicted after adding the effect.
    predicted_dbic : float
        Predicted BIC change (negative: better).
    estimate : dict
        One-step Gauss-Newton estimate of the effect's parameters.
    evidence_eq : float or None
        Share of the equation-error RSS that the effect's torque term explains after
        projecting out the model's own torque terms (None when not computed).
    predicted_dbic_eq : float or None
        BIC change that share means in equation error (effective sample size of the
        smoothed derivatives).
    start_rms : float or None
        Output-error RMS of the model plus the effect at the equation-error (stage 1) fit
        of that augmented structure, with the hysteresis shape re-optimized: a global view
        that does not rely on the current optimum (computed only while the residual is
        clearly above the noise).
    start_dbic : float or None
        BIC change of that start against the current fit.
    start : dict or None
        The stage-1 parameters themselves (a start for the refit).
    """

    name: str
    terms: tuple[str, ...]
    evidence: float
    per_run: list[float]
    lm: float
    predicted_rms: float
    predicted_dbic: float
    estimate: dict[str, float]
    evidence_eq: float | None = None
    predicted_dbic_eq: float | None = None
    start_rms: float | None = None
    start_dbic: float | None = None
    start: dict[str, float] | None = None

    def to_dict(self) -> dict:
        """Plain-dict form for ``results.json``."""
        return {
            "name": self.name,
            "terms": list(self.terms),
            "evidence": self.evidence,
            "evidence_per_run": list(self.per_run),
            "evidence_eq": self.evidence_eq,
            "predicted_dbic_eq": self.predicted_dbic_eq,
            "start_rms": self.start_rms,
            "start_dbic": self.start_dbic,
            "lm": self.lm,
            "predicted_rms": self.predicted_rms,
            "predicted_dbic": self.predicted_dbic,
            "estimate": dict(self.estimate),
        }


@dataclass
class LoopResult:
    """Outcome of :func:`augment`.

    Attributes
    ----------
    base : OEFit
        The fit the loop started from.
    fit : OEFit
        The final fit (the base fit plus every accepted effect).
    effects : list of str
        Accepted effects, in the order they were added.
    tried : list of dict
        Every refitted effect: name, evidence, RMS and BIC before and after, accepted.
    accepted : list of dict
        Accepted effects in the ``results.json`` format (parameters from the final fit).
    diagnosis : list of dict
        One entry per round: the ranked scores of every candidate.
    skipped : list of dict
        Catalogued effects not considered, with the reason.
    residual : dict
        ``rms``, ``whiteness_p``, ``dominant_hz`` (and more) of the final residual.
    unexplained : bool
        True when structure remains that no catalogued effect removes.
    unexplained_text : str or None
        That structure in plain words.
    """

    base: OEFit
    fit: OEFit
    effects: list[str] = field(default_factory=list)
    tried: list[dict] = field(default_factory=list)
    accepted: list[dict] = field(default_factory=list)
    diagnosis: list[dict] = field(default_factory=list)
    skipped: list[dict] = field(default_factory=list)
    residual: dict = field(default_factory=dict)
    unexplained: bool = False
    unexplained_text: str | None = None


# ----------------------------------------------------------------------------- candidates


def _n_levels(currents: np.ndarray) -> int:
    from hystdisc.data import distinct_currents

    return len(distinct_currents(currents))


def has_spring(fit: OEFit) -> bool:
    """True when the fitted rig spring ``k_s`` is significantly above zero.

    Parameters
    ----------
    fit : OEFit
        A family fit (its parameters include ``k_s``).

    Returns
    -------
    bool
        ``k_s > 0`` and the lower end of its 95 % interval above 0.
    """
    ks = fit.params.get("k_s", 0.0)
    lo = fit.ci95.get("k_s", (0.0, 0.0))[0]
    return bool(np.isfinite(ks) and ks > 0.0 and np.isfinite(lo) and lo > 0.0)


def candidate_effects(fit: OEFit, data: FitData) -> tuple[list[str], list[dict]]:
    """Catalogued effects the fitted model could still lack.

    Parameters
    ----------
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.output_error.FamilyParametrization` (possibly with effects).
    data : FitData
        The data it was fitted to (its currents decide what the current effects need).

    Returns
    -------
    candidates : list of str
        Effect names, in catalogue order.
    skipped : list of dict
        ``{"name", "reason"}`` for each effect left out.
    """
    par = fit.par
    tm = fit.term_model
    fam = par.family
    have = set(fam.torque_terms) | {t for e in par.effects for t in EFFECTS[e].terms}
    # terms the family can carry but fixed at zero (one current) do not count as present
    have |= {k for k, v in tm.torque.items() if v != 0.0}
    levels = _n_levels(data.currents)
    spring = has_spring(fit)
    out, skipped = [], []
    for name, eff in EFFECTS.items():
        reason = None
        if name in par.effects:
            continue
        if all(t in have for t in eff.terms):
            reason = f"{fam.name} already has {', '.join(eff.terms)}"
        elif any(t in Z_TORQUE_TERMS for t in eff.terms) and not tm.has_state:
            reason = f"{fam.name} has no hysteretic state z"
        elif any(t.startswith("i^2") for t in eff.terms) and levels < 3:
            reason = f"needs three current levels or more, the data have {levels}"
        elif any(t.startswith("i") for t in eff.terms) and levels < 2:
            reason = "needs two current levels or more, the data have one"
        elif name in SPRING_EFFECTS and not spring:
            reason = "no rig spring (k_s is not significantly above 0)"
        if reason is None:
            out.append(name)
        else:
            skipped.append({"name": name, "reason": reason})
    return out, skipped


# ----------------------------------------------------------------------------- diagnosis


def _with_effects(fit: OEFit, extra: Sequence[str], values: dict[str, float] | None = None):
    """Parametrization of ``fit`` plus ``extra`` effects, and its vector at the optimum."""
    par0 = fit.par
    start = dict(fit.params)
    for e in extra:
        for p in EFFECTS[e].params:
            start[p.name] = (values or {}).get(p.name, 0.0)
    par = par0.like(start, tuple(par0.effects) + tuple(extra))
    n0 = len(par0.names)
    if list(par.names[:n0]) != list(par0.names):  # pragma: no cover - guards a layout change
        raise RuntimeError("effect parameters are not appended after the model's parameters")
    x = np.concatenate([np.asarray(fit.x, dtype=float), [start[n] for n in par.names[n0:]]])
    return par, x


def _span(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column span of ``A`` (columns scaled, tiny directions dropped)."""
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    sc = np.sqrt((A**2).sum(axis=0))
    keep = sc > 0
    if not keep.any():
        return np.zeros((A.shape[0], 0))
    U, s, _ = np.linalg.svd(A[:, keep] / sc[keep], full_matrices=False)
    return U[:, s > s[0] * 1e-10]


def _model_complement(J, model_cols, npar, nnu, rows) -> Callable[[np.ndarray], np.ndarray]:
    """``M -> M`` minus its projection on the span of the model's Jacobian columns.

    The model's columns are its parameters (``model_cols``) and each run's ``nnu``
    initial-state columns (from column ``npar`` on), which are zero outside that run's
    ``rows``: they are projected out run by run, then the parameters' columns (so the cost
    and memory are linear in the number of runs, not cubic as an SVD of all columns).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> J = np.zeros((8, 3)); J[:, 0] = rng.normal(size=8)
    >>> J[:4, 1] = rng.normal(size=4); J[4:, 2] = rng.normal(size=4)
    >>> perp = _model_complement(J, [0], 1, 1, np.array([0, 4, 8]))
    >>> U = _span(J)
    >>> y = rng.normal(size=8)
    >>> bool(np.allclose(perp(y), y - U @ (U.T @ y)))
    True
    """
    A = J[:, model_cols]
    norms = np.sqrt((A**2).sum(axis=0))
    A = A[:, norms > 0] / norms[norms > 0]
    blocks = []
    for k in range(len(rows) - 1):
        sl = slice(int(rows[k]), int(rows[k + 1]))
        cols = slice(npar + k * nnu, npar + (k + 1) * nnu)
        blocks.append((sl, _span(J[sl, cols]) if nnu else None))

    def perp_runs(M):
        out = np.array(M, dtype=float, copy=True)
        for sl, Q in blocks:
            if Q is not None and Q.shape[1]:
                out[sl] -= Q @ (Q.T @ out[sl])
        return out

    if A.shape[1]:
        Ap = perp_runs(A)
        U, sv, _ = np.linalg.svd(Ap, full_matrices=False)
        U = U[:, sv > max(sv[0], 1.0) * 1e-10] if sv.size else U[:, :0]
    else:
        U = np.zeros((J.shape[0], 0))

    def perp(M):
        Mp = perp_runs(M)
        return Mp - U @ (U.T @ Mp)

    return perp


def _explained(G: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray]:
    """Squared norm of the projection of ``r`` on the columns of ``G``, and the coefficients."""
    if G.size == 0 or not np.any(G):
        return 0.0, np.zeros(G.shape[1])
    sc = np.sqrt((G**2).sum(axis=0))
    sc[sc == 0] = 1.0
    c = np.linalg.lstsq(G / sc, r, rcond=1e-10)[0]
    fit = (G / sc) @ c
    return float(fit @ fit), c / sc


def _equation_evidence(
    eq, tm: TermModel, candidates: Sequence[str]
) -> dict[str, tuple[float, float]]:
    """Equation-error evidence of each candidate (see the module docstring)."""
    from hystdisc.models import SIGN_EPS, TORQUE_TERMS
    from hystdisc.simulation import integrate_z

    if tm.has_state:
        z = integrate_z(tm.hysteresis_vector(), tm.n, eq.t, eq.theta_dot, SIGN_EPS)
    else:
        z = [np.zeros_like(t) for t in eq.t]
    terms = [k for k, v in tm.torque.items() if v != 0.0]
    coefs = np.array([tm.torque[t] for t in terms])
    A_rows, G_rows, res = [], [], []
    for k in range(len(eq.t)):
        m = eq.rows[k]
        th, w, zk = eq.theta[k][m], eq.theta_dot[k][m], z[k][m]
        i = float(eq.currents[k])
        A = np.column_stack([TORQUE_TERMS[t](th, w, zk, i) for t in terms] or [np.zeros(th.size)])
        pred = A @ coefs if terms else np.zeros(th.size)
        if eq.experiment == "forced":
            pred = pred + tm.J * eq.theta_ddot[k][m]
            A = np.column_stack([eq.theta_ddot[k][m], A])
        A_rows.append(A)
        G_rows.append(
            {t: TORQUE_TERMS[t](th, w, zk, i) for c in candidates for t in EFFECTS[c].terms}
        )
        res.append(eq.target[k][m] - pred)
    r = np.concatenate(res)
    rss = float(r @ r)
    U = _span(np.vstack(A_rows))
    r_perp = r - U @ (U.T @ r)
    rss_perp = float(r_perp @ r_perp)
    ne = eq.n_eff(r.size)
    out = {}
    for c in candidates:
        q = len(EFFECTS[c].terms)
        G = np.column_stack([np.concatenate([g[t] for g in G_rows]) for t in EFFECTS[c].terms])
        Gp = G - U @ (U.T @ G)
        if rss <= 0 or np.sqrt((Gp**2).sum()) <= 1e-8 * np.sqrt((G**2).sum()):
            red = 0.0
        else:
            red = _explained(Gp, r_perp)[0]
        left = max(rss_perp - red, 1e-300)
        dbic = float(ne * np.log(left / max(rss_perp, 1e-300)) + q * np.log(ne))
        out[c] = (red / rss if rss > 0 else 0.0, dbic)
    return out


def stage1_start(
    eq, fit: OEFit, effects: Sequence[str], data: FitData, s0: np.ndarray | None = None
) -> dict | None:
    """Equation-error (stage 1) start of ``fit``'s family plus ``effects``.

    The hysteresis shape constants and the torque coefficients of the family's terms, the
    spring and the effects' terms are fitted by variable projection on the equation-error
    data, then mapped to the family's and the effects' parameters (as discovery starts a
    family's output-error fit).

    Parameters
    ----------
    eq : EqData
        Equation-error data of the discovery.
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.output_error.FamilyParametrization`.
    effects : sequence of str
        Effects of the augmented structure.
    data : FitData
        The output-error data (for the number of current levels).
    s0 : ndarray, optional
        Shape constants to start the local search from (e.g. the family's own stage-1
        shape); default: discovery's grid first.

    Returns
    -------
    dict or None
        Parameter values by name; None when stage 1 fails.
    """
    from hystdisc.discovery.stage1 import family_start

    fam = fit.par.family
    eff_terms = [t for e in effects for t in EFFECTS[e].terms]
    try:
        with np.errstate(all="ignore"):
            p, coefs = family_start(
                eq,
                fam.name,
                eff_terms,
                s0=s0,
                one_level=_n_levels(data.currents) < 2,
                constant=False,
            )
    except Exception:  # noqa: BLE001 - a start is optional
        return None
    for e in effects:
        p.update(EFFECTS[e].from_torque(coefs, p["k_s"]))
    for k, v in fit.par.fixed.items():
        p[k] = v
    if not all(np.isfinite(v) for v in p.values()):
        return None
    return p


def _start_rss(data: FitData, fit: OEFit, effects: Sequence[str], start: dict) -> float:
    """Output-error RSS of ``fit``'s structure plus ``effects`` at the parameters ``start``."""
    par0 = fit.par
    extra = [e for e in effects if e not in par0.effects]
    par = par0.like(start, tuple(par0.effects) + tuple(extra))
    v = np.concatenate([par.x0, np.asarray(fit.nuisance, dtype=float).ravel()])
    with np.errstate(all="ignore"):
        r = OutputErrorFitter(data, par).residuals(v)
    return float(r @ r) if np.all(np.isfinite(r)) else float("inf")


def screen_starts(
    eq, data: FitData, fit: OEFit, scores: list[EffectScore], s0: np.ndarray | None = None
) -> None:
    """Fill ``start``/``start_rms``/``start_dbic`` of each score from a stage-1 start.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    data : FitData
        Output-error data.
    fit : OEFit
        The current fit.
    scores : list of EffectScore
        Candidates (updated in place).
    s0 : ndarray, optional
        Stage-1 shape constants of the family to start the shape search from (skips the
        grid, see :func:`stage1_start`).
    """
    N = sum(int(m.sum()) for m in data.mask)
    for sc in scores:
        effects = (*fit.par.effects, sc.name)
        st = stage1_start(eq, fit, effects, data, s0=s0)
        if st is None:
            continue
        rss = _start_rss(data, fit, effects, st)
        if not np.isfinite(rss):
            continue
        q = len(EFFECTS[sc.name].params)
        sc.start = st
        sc.start_rms = float(np.sqrt(rss / N))
        sc.start_dbic = float(N * np.log(max(rss, 1e-300) / max(fit.rss, 1e-300)) + q * np.log(N))


def score_effects(
    data: FitData, fit: OEFit, candidates: Sequence[str], eq=None
) -> list[EffectScore]:
    """Score each candidate effect by the output-error score test, best first.

    Parameters
    ----------
    data : FitData
        The data of the fit.
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.output_error.FamilyParametrization`, at its optimum.
    candidates : sequence of str
        Effect names (see :func:`candidate_effects`).
    eq : EqData, optional
        Equation-error data (``Discovery._eq``); when given, ``evidence_eq`` is computed.

    Returns
    -------
    list of EffectScore
        Sorted by decreasing evidence.
    """
    candidates = list(candidates)
    if not candidates:
        return []
    par, x = _with_effects(fit, candidates)
    fitter = OutputErrorFitter(data, par)
    v = np.concatenate([x, np.asarray(fit.nuisance, dtype=float).ravel()])
    with np.errstate(all="ignore"):
        r = fitter.residuals(v)
        J = fitter.jacobian(v)
    n0 = len(fit.par.names)
    npar = len(par.names)
    rows = np.cumsum([0] + [int(m.sum()) for m in data.mask])
    perp = _model_complement(J, list(range(n0)), npar, fitter.nnu, rows)
    N = r.size
    rss = float(r @ r)
    r_perp = perp(r)
    rss_perp = float(r_perp @ r_perp)
    s2 = rss / max(N - len(v), 1)
    eq_ev = {}
    if eq is not None:
        try:
            with np.errstate(all="ignore"):
                eq_ev = _equation_evidence(eq, fit.term_model, candidates)
        except Exception:  # noqa: BLE001 - the equation-error view is supplementary
            eq_ev = {}
    scores = []
    col = n0
    for c in candidates:
        q = len(EFFECTS[c].params)
        cols = list(range(col, col + q))
        col += q
        G = J[:, cols]
        Gp = perp(G)
        gnorm = np.sqrt((G**2).sum())
        if not np.all(np.isfinite(Gp)) or np.sqrt((Gp**2).sum()) <= 1e-8 * gnorm or gnorm == 0:
            red, beta = 0.0, np.zeros(q)
        else:
            red, beta = _explained(Gp, -r_perp)
        # each run's part of the predicted reduction (they add up to the pooled one)
        r_new = r_perp - Gp @ (-beta) if red > 0 else r_perp
        per_run = []
        for k in range(data.n_runs):
            sl = slice(rows[k], rows[k + 1])
            den = float(r[sl] @ r[sl])
            gain = float(r_perp[sl] @ r_perp[sl] - r_new[sl] @ r_new[sl])
            per_run.append(gain / den if den > 0 else 0.0)
        ev = red / rss if rss > 0 else 0.0
        left = max(rss_perp - red, 1e-300)
        dbic = float(N * np.log(left / max(rss_perp, 1e-300)) + q * np.log(N))
        names = [p.name for p in EFFECTS[c].params]
        scores.append(
            EffectScore(
                name=c,
                terms=EFFECTS[c].terms,
                evidence=float(ev),
                per_run=per_run,
                lm=float(red / s2) if s2 > 0 else 0.0,
                predicted_rms=float(np.sqrt(max(rss - red, 0.0) / N)),
                predicted_dbic=dbic,
                estimate=dict(zip(names, map(float, beta), strict=True)),
                evidence_eq=eq_ev[c][0] if c in eq_ev else None,
                predicted_dbic_eq=eq_ev[c][1] if c in eq_ev else None,
            )
        )
    scores.sort(key=lambda s: -s.evidence)
    return scores


# ----------------------------------------------------------------------------- refit


def refit_with(
    data: FitData,
    fit: OEFit,
    effect: str,
    estimate: dict[str, float] | None = None,
    max_nfev: int = 60,
    heldout: bool = False,
    start: dict[str, float] | None = None,
    good_rms: float = 0.0,
) -> OEFit:
    """Refit ``fit`` plus ``effect`` by output error.

    Starts: the current optimum with the effect at 0, with the effect at its one-step
    estimate ``estimate``, and the stage-1 start ``start``; the fit runs from the one with
    the lowest RSS, and once more from the best start of the other kind (local or stage 1)
    when the first does not lower BIC by the margin or stays above ``good_rms``.

    Parameters
    ----------
    data : FitData
        The data.
    fit : OEFit
        Current fit (a :class:`~hystdisc.fitting.output_error.FamilyParametrization`).
    effect : str
        Catalogue name of the effect to add.
    estimate : dict, optional
        One-step values of the effect's parameters (default 0).
    max_nfev : int
        Simulation budget of each fit.
    heldout : bool
        Also compute the leave-one-run-out error.
    start : dict, optional
        A full start (family, rig and effect parameters), e.g. from :func:`stage1_start`.
    good_rms : float
        An RMS that needs no second start (e.g. a little above the noise).

    Returns
    -------
    OEFit
        The refit with the lowest BIC.
    """
    local = []
    for values in [None] + ([estimate] if estimate and any(estimate.values()) else []):
        par, x = _with_effects(fit, [effect], values)
        st = dict(zip(par.names, map(float, x), strict=True))
        local.append((_start_rss(data, fit, [effect], st), st))
    local.sort(key=lambda t: t[0])
    groups = [local[0]]
    if start is not None:
        g = (_start_rss(data, fit, [effect], start), start)
        groups = [g, local[0]] if g[0] < local[0][0] else [local[0], g]
    best = None
    for _, st in groups:
        par0 = fit.par
        par = par0.like(st, (*par0.effects, effect))
        with np.errstate(all="ignore"):
            new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
        if best is None or (np.isfinite(new.bic) and new.bic < best.bic):
            best = new
        if _fit_ok(best, fit) and best.bic < fit.bic - EFFECT_BIC_MARGIN and best.rms <= good_rms:
            break
    return best


def _fit_ok(fit: OEFit, before: OEFit) -> bool:
    """A refit is usable: finite, and its simulation did not blow up."""
    if not (np.isfinite(fit.rms) and np.isfinite(fit.bic)):
        return False
    if not all(np.all(np.isfinite(p)) for p in fit.predictions):
        return False
    return bool(fit.rms < 10.0 * before.rms + 1e-300)


# ----------------------------------------------------------------------------- whiteness


def masked_residuals(fit: OEFit, data: FitData) -> list[np.ndarray]:
    """The residual of each run on the samples that enter the fit.

    Parameters
    ----------
    fit : OEFit
        An output-error fit.
    data : FitData
        Its data (the masks drop a driven run's transient).

    Returns
    -------
    list of ndarray
        Prediction minus measurement, per run.
    """
    return [np.asarray(r)[m] for r, m in zip(fit.residuals, data.mask, strict=True)]


def natural_frequency(fit: OEFit, experiment: str) -> float | None:
    """Undamped rig frequency ``sqrt(k_s / J) / 2 pi`` in Hz.

    Parameters
    ----------
    fit : OEFit
        A fit whose parameters hold ``k_s`` (and ``J`` for forced experiments).
    experiment : str
        ``release``, ``forced`` or ``driven`` (no rig oscillation: None).

    Returns
    -------
    float or None
        The frequency, or None without a spring.
    """
    if experiment == "driven":
        return None
    ks = fit.params.get("k_s", 0.0)
    J = fit.params.get("J", 1.0) or 1.0
    if not (np.isfinite(ks) and ks > 0 and J > 0):
        return None
    return float(np.sqrt(ks / J) / (2 * np.pi))


def assess_residual(
    residuals: list[np.ndarray],
    fs: float,
    noise_std: float,
    natural_hz: float | None = None,
) -> tuple[dict, bool, str | None]:
    """Whiteness and spectrum of the final residual.

    Parameters
    ----------
    residuals : list of ndarray
        Output-error residual of each run.
    fs : float
        Sampling rate in Hz.
    noise_std : float
        Estimated measurement noise.
    natural_hz : float, optional
        The rig's own frequency, to name a misfit of the main oscillation as such.

    Returns
    -------
    residual : dict
        ``rms``, ``whiteness_p`` (Ljung-Box pooled over runs), ``dominant_hz`` (None when
        white), ``rms_over_noise`` and ``peak_q`` (quality factor of the spectral peak).
    unexplained : bool
        Not white and RMS above ``NOISE_RATIO`` times the noise.
    text : str or None
        The remaining structure in plain words.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(3000) / 1000.0
    >>> white = [1e-3 * rng.normal(size=t.size) for _ in range(3)]
    >>> assess_residual(white, 1000.0, 1e-3)[1]
    False
    >>> ring = [w + 3e-3 * np.exp(-0.5 * t) * np.sin(2 * np.pi * 6 * t) for w in white]
    >>> res, unexplained, text = assess_residual(ring, 1000.0, 1e-3)
    >>> unexplained, round(res["dominant_hz"], 1)
    (True, 6.0)
    >>> text
    'a resonance near 6.0 Hz that no catalogued effect explains (residual RMS 1.6x the noise)'
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) > 10]
    allr = np.concatenate(res) if res else np.zeros(1)
    rms = float(np.sqrt(np.mean(allr**2)))
    p = ljung_box_pooled(res)
    ratio = rms / noise_std if noise_std > 0 else float("inf")
    out = {
        "rms": rms,
        "whiteness_p": p,
        "dominant_hz": None,
        "rms_over_noise": ratio if np.isfinite(ratio) else None,
        "peak_q": None,
    }
    structured = p < WHITE_P
    if structured and res:
        f, psd, resolution = residual_spectrum(res, fs)
        fk, q = spectral_peak(f, psd, f_min=resolution)
        if np.isfinite(fk):
            out["dominant_hz"] = fk
            out["peak_q"] = q if np.isfinite(q) else None
    unexplained = bool(structured and ratio > NOISE_RATIO)
    if not unexplained:
        return out, False, None
    fk = out["dominant_hz"]
    tail = f"that no catalogued effect explains (residual RMS {ratio:.1f}x the noise)"
    if fk is None:
        text = f"structure {tail}"
    elif natural_hz and abs(fk - natural_hz) <= 0.15 * natural_hz:
        text = (
            f"a misfit of the rig's own oscillation near {fk:.1f} Hz {tail}: the damper law "
            "itself may be wrong (try another family, or discover without --model)"
        )
    elif (out["peak_q"] or 0.0) >= 2.0:
        text = f"a resonance near {fk:.1f} Hz {tail}"
    else:
        text = f"broadband structure (most power near {fk:.1f} Hz) {tail}"
    return out, True, text


# ----------------------------------------------------------------------------- the loop


def _effect_entry(
    name: str, final: OEFit, step: dict, before: OEFit | None, after: OEFit | None
) -> dict:
    """An accepted effect in the ``results.json`` format.

    ``before``/``after`` are the fits without and with the effect along the final chain of
    accepted effects (when an effect was removed again, the chain is recomputed from the
    fits at hand); without them the values at the time of acceptance are used.
    """
    params = {}
    for p in EFFECTS[name].params:
        lo, hi = final.ci95.get(p.name, (float("nan"), float("nan")))
        params[p.name] = {"value": final.params.get(p.name), "ci95": [lo, hi]}
    pair = before is not None and after is not None
    return {
        "name": name,
        "terms": list(EFFECTS[name].terms),
        "parameters": params,
        "rms_before": before.rms if pair else step["rms_before"],
        "rms_after": after.rms if pair else step["rms_after"],
        "bic_before": before.bic if pair else step["bic_before"],
        "bic_after": after.bic if pair else step["bic_after"],
        "evidence": step["evidence"],
        "evidence_eq": step.get("evidence_eq"),
    }


def _refit_queue(scores: list[EffectScore]) -> list[EffectScore]:
    """Candidates worth a local output-error refit this round (at most three).

    The top two candidates by output-error evidence and the top by equation-error
    evidence (a second view that catches an effect the model's own terms mimic locally),
    each only when its predicted BIC drop beats the margin. Both output-error leaders are
    refitted because a hysteretic state mimics several effects to first order (a fast
    ``z`` looks like Coulomb friction), so the local ranking of close candidates is not
    trusted; the refits decide.
    """
    sig_oe = [s for s in scores if s.predicted_dbic < -EFFECT_BIC_MARGIN]
    sig_eq = sorted(
        (
            s
            for s in scores
            if s.predicted_dbic_eq is not None and s.predicted_dbic_eq < -EFFECT_BIC_MARGIN
        ),
        key=lambda s: -(s.evidence_eq or 0.0),
    )
    queue = sig_oe[:2]
    if sig_eq and sig_eq[0] not in queue:
        queue.append(sig_eq[0])
    return queue[:MAX_REFITS_PER_ROUND]


def _start_pick(scores: list[EffectScore]) -> EffectScore | None:
    """The candidate whose stage-1 start predicts the largest BIC drop (if beyond the margin)."""
    good = [s for s in scores if s.start_dbic is not None and s.start_dbic < -EFFECT_BIC_MARGIN]
    return min(good, key=lambda s: s.start_dbic) if good else None


def wald_chi2(fit: OEFit, effect: str) -> float:
    """Smallest squared z-score (value / standard error) of an effect's parameters in ``fit``.

    Parameters
    ----------
    fit : OEFit
        A fit whose parametrization includes ``effect``.
    effect : str
        Catalogue name.

    Returns
    -------
    float
        ``min (value / stderr)^2`` over the effect's parameters (about chi-square with one
        degree of freedom when the effect is absent).
    """
    out = np.inf
    for p in EFFECTS[effect].params:
        v = fit.params.get(p.name, 0.0)
        se = fit.stderr.get(p.name, np.inf)
        z2 = (v / se) ** 2 if se > 0 else (np.inf if v != 0 else 0.0)
        out = min(out, float(z2) if np.isfinite(z2) else (np.inf if se == 0 else 0.0))
    return float(out)


def _refit_without(data: FitData, fit: OEFit, like: OEFit, max_nfev: int, heldout: bool):
    """Refit the structure of ``like`` started from ``fit`` (which has one effect more)."""
    par0 = like.par
    par = par0.like(dict(fit.params), par0.effects)
    return OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)


def _backward(data, fit, out: LoopResult, max_nfev, heldout, say, fits: dict) -> OEFit:
    """Drop earlier effects that a later one made redundant (parameter not significant)."""
    while len(out.effects) > 1:
        weak = [
            (wald_chi2(fit, e), e)
            for e in out.effects[:-1]
            if wald_chi2(fit, e) <= np.log(fit.n_obs)
        ]
        if not weak:
            break
        _, name = min(weak)
        keep = [e for e in out.effects if e != name]
        say(f"closing the loop: {name} became redundant, refit without it")
        par0 = fit.par
        start = {k: v for k, v in fit.params.items()}
        par = par0.like(start, tuple(keep))
        with np.errstate(all="ignore"):
            new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
        if not (_fit_ok(new, fit) and new.bic < fit.bic):
            break
        out.effects.remove(name)
        fits[frozenset(out.effects)] = new
        for step in out.tried:
            if step["name"] == name and step["accepted"]:
                step["accepted"] = False
                step["removed"] = True
                step["note"] = (
                    f"{out.effects[-1]} made it redundant: its parameter was no longer significant"
                )
        fit = new
    return fit


class _Round:
    """The refits of one round of :func:`augment` (by effect: the best refit and its record)."""

    def __init__(self, data, current, round_no, max_nfev, heldout, noise_std, say):
        self.data = data
        self.noise_std = noise_std
        good_rms = NOISE_RATIO * noise_std
        self.current = current
        self.round_no = round_no
        self.max_nfev = max_nfev
        self.heldout = heldout
        self.good_rms = good_rms
        self.say = say
        self.results: dict[str, tuple[OEFit, dict]] = {}

    def attempt(self, s: EffectScore, start: dict | None = None) -> None:
        """Refit the current model plus ``s``'s effect and record the outcome."""
        cur = self.current
        self.say(f"closing the loop: refit with {s.name} (evidence {s.evidence:.3g})")
        with np.errstate(all="ignore"):
            new = refit_with(
                self.data,
                cur,
                s.name,
                s.estimate,
                self.max_nfev,
                self.heldout,
                start,
                self.good_rms,
            )
        ok = _fit_ok(new, cur)
        wald = wald_chi2(new, s.name) if ok else 0.0
        step = {
            "name": s.name,
            "round": self.round_no,
            "evidence": s.evidence,
            "evidence_eq": s.evidence_eq,
            "start_rms": s.start_rms,
            "rms_before": cur.rms,
            "rms_after": new.rms if ok else None,
            "bic_before": cur.bic,
            "bic_after": new.bic if ok else None,
            "wald_chi2": wald if np.isfinite(wald) else None,
            "converged": bool(new.success),
            "accepted": False,
            "_ok": ok,
            "_improves": ok and new.bic < cur.bic - EFFECT_BIC_MARGIN,
            "_significant": wald > np.log(new.n_obs),
        }
        # share of the excess over the noise that the effect removes
        excess = cur.rss - cur.n_obs * self.noise_std**2
        gain = cur.rss - new.rss if ok else 0.0
        share = gain / excess if excess > 0 else 1.0
        step["excess_share"] = float(share)
        step["_improves"] = step["_improves"] and share >= MIN_EXCESS_SHARE
        old = self.results.get(s.name)
        if old is None or (ok and (old[1]["bic_after"] is None or new.bic < old[0].bic)):
            self.results[s.name] = (new, step)

    def best(self) -> tuple[OEFit, dict] | None:
        """The acceptable refit with the lowest BIC."""
        ok = [(f, st) for f, st in self.results.values() if st["_improves"] and st["_significant"]]
        return min(ok, key=lambda t: t[0].bic) if ok else None

    def done(self) -> bool:
        """An acceptable refit is down to the noise."""
        w = self.best()
        return w is not None and w[0].rms <= self.good_rms

    def screen(self, eq, scores: list[EffectScore], diag: dict, s0) -> None:
        """Stage-1 starts of every augmented structure, then a refit from the best one.

        The local views can be trapped by the current optimum; this global one is not.
        """
        self.say("closing the loop: stage-1 starts of the augmented structures")
        screen_starts(eq, self.data, self.current, scores, s0=s0)
        diag["candidates"] = [s.to_dict() for s in scores]
        pick = _start_pick(scores)
        if pick is not None:
            self.attempt(pick, start=pick.start)


def augment(
    data: FitData,
    fit: OEFit,
    noise_std: float,
    max_nfev: int = 60,
    heldout: bool = False,
    eq=None,
    progress: Callable[[str], None] | None = None,
    s0: np.ndarray | None = None,
) -> LoopResult:
    """Diagnose, add the effects that improve BIC, and test the final residual.

    An effect is accepted when its refit converges to finite values, lowers BIC by more
    than :data:`EFFECT_BIC_MARGIN`, its parameter is significant on its own (squared
    z-score above ``log N``), and it removes at least :data:`MIN_EXCESS_SHARE` of the
    residual's excess over the noise. A refit that lowers BIC while the effect's parameter is not
    significant has found a better optimum of the model itself: the model is refitted
    without the effect from there and kept, and the effect is rejected.

    Parameters
    ----------
    data : FitData
        The data the fit was made on.
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.output_error.FamilyParametrization` (the selected or
        declared family).
    noise_std : float
        Estimated measurement noise (data units); raised to :func:`accuracy_floor` when
        smaller (noise-free data), where the loop does not run.
    max_nfev : int
        Simulation budget of each refit.
    heldout : bool
        Compute the leave-one-run-out error of the refits.
    eq : EqData, optional
        Equation-error data, for the supplementary ``evidence_eq``.
    progress : callable, optional
        Called with short progress messages.
    s0 : ndarray, optional
        The family's stage-1 shape constants (start of the stage-1 screening's search).

    Returns
    -------
    LoopResult
        The final fit, the tried/accepted effects, the diagnosis and the residual verdict.
    """
    say = progress or (lambda msg: None)
    floor = accuracy_floor(data)
    noise_std = max(float(noise_std), floor)
    good_rms = NOISE_RATIO * noise_std
    out = LoopResult(base=fit, fit=fit)
    current = fit
    candidates, skipped = candidate_effects(fit, data)
    out.skipped = skipped
    rejected: set[str] = set()
    steps: dict[str, dict] = {}
    fits: dict[frozenset, OEFit] = {frozenset(): fit}  # best fit of each effect set
    for round_no in range(1, 2 * len(EFFECTS) + 1):
        if current.rms <= good_rms and noise_std == floor:
            break  # within the simulator's own accuracy (noise-free data): nothing to explain
        pool = [c for c in candidates if c not in out.effects and c not in rejected]
        if not pool:
            break
        scores = score_effects(data, current, pool, eq=eq)
        diag = {"round": round_no, "candidates": [s.to_dict() for s in scores]}
        out.diagnosis.append(diag)
        rnd = _Round(data, current, round_no, max_nfev, heldout, noise_std, say)
        screened = False
        if eq is not None and current.rms > FAR_RATIO * noise_std:
            rnd.screen(eq, scores, diag, s0)  # far from the noise: the global view first
            screened = True
        if not (screened and rnd.done()):
            for s in _refit_queue(scores):
                if s.name not in rnd.results:
                    rnd.attempt(s)
        if not rnd.done() and not screened and eq is not None and current.rms > good_rms:
            rnd.screen(eq, scores, diag, s0)
        results = rnd.results
        w = rnd.best()
        for _, step in results.values():
            step_ok, improves = step.pop("_ok"), step.pop("_improves")
            significant = step.pop("_significant")
            out.tried.append(step)
            if w is not None and step is w[1]:
                continue
            if w is not None and step_ok and improves and significant:
                step["note"] = f"{w[1]['name']} lowered BIC more"
                continue
            rejected.add(step["name"])
            if (
                not improves
                and step_ok
                and step["bic_after"] < step["bic_before"] - EFFECT_BIC_MARGIN
            ):
                step["note"] = (
                    f"removes only {100 * step['excess_share']:.0f} % of the residual's excess "
                    "over the noise"
                )
            elif not improves:
                step["note"] = "did not lower BIC"
            else:
                wz = np.sqrt(step["wald_chi2"] or 0.0)
                step["note"] = f"its parameter is not significant (z = {wz:.2g})"
        if w is not None:
            new, step = w
            step["accepted"] = True
            steps[step["name"]] = step
            out.effects.append(step["name"])
            fits[frozenset(out.effects)] = new
            current = _backward(data, new, out, max_nfev, heldout, say, fits)
            continue
        hops = [
            (f, st)
            for f, st in results.values()
            if st["bic_after"] is not None
            and f.bic < current.bic - EFFECT_BIC_MARGIN
            and (st["wald_chi2"] or 0.0) <= np.log(f.n_obs)
        ]
        if hops:
            # no effect was needed, but a refit left the model's own local optimum
            hop, st = min(hops, key=lambda t: t[0].bic)
            with np.errstate(all="ignore"):
                base = _refit_without(data, hop, current, max_nfev, heldout)
            if _fit_ok(base, current) and base.bic < current.bic - EFFECT_BIC_MARGIN:
                st["note"] += (
                    f"; its refit found a better optimum of the model without it (RMS "
                    f"{current.rms:.4g} -> {base.rms:.4g}), which is kept"
                )
                current = base
                fits[frozenset(out.effects)] = base
                continue
        break
    out.fit = current
    out.accepted = [
        _effect_entry(
            n,
            current,
            steps[n],
            fits.get(frozenset(out.effects[:j])),
            fits.get(frozenset(out.effects[: j + 1])),
        )
        for j, n in enumerate(out.effects)
    ]
    fs = _sampling_rate(data)
    out.residual, out.unexplained, out.unexplained_text = assess_residual(
        masked_residuals(current, data),
        fs,
        noise_std,
        natural_frequency(current, data.experiment),
    )
    out.residual["noise_used"] = noise_std
    return out


def accuracy_floor(data: FitData) -> float:
    """The smallest residual RMS the fit can resolve: ``SIM_FLOOR_REL`` of the signal's peak.

    The fitting simulator is accurate to about 1e-6 of the signal; below this floor a
    residual is numerical (noise-free synthetic data) and is treated as noise of that size.

    Parameters
    ----------
    data : FitData
        The fitted data.

    Returns
    -------
    float
        The floor, in data units.
    """
    peak = max(
        (float(np.max(np.abs(y[m]))) for y, m in zip(data.y, data.mask, strict=True) if m.any()),
        default=0.0,
    )
    return SIM_FLOOR_REL * peak


def _sampling_rate(data: FitData) -> float:
    dts = [np.median(np.diff(t)) for t in data.t if len(t) > 1]
    return float(1.0 / np.median(dts)) if dts else 1.0


def _final_entry(fit: OEFit, family: str, effects: list[str]) -> dict:
    params = {}
    for k, v in fit.params.items():
        lo, hi = fit.ci95.get(k, (float("nan"), float("nan")))
        params[k] = {"value": v, "ci95": [lo, hi], "identifiable": fit.identifiable.get(k, True)}
    return {
        "family": family,
        "effects": list(effects),
        "parameters": params,
        "rms": fit.rms,
        "bic": fit.bic,
        "heldout_rms": fit.heldout_rms,
        "n_params": fit.n_params,
        "converged": fit.success,
        "notes": list(fit.notes),
    }


def _stage1_shape(disc, fit: OEFit) -> np.ndarray | None:
    """The discovery's stage-1 shape constants of the fitted family's hysteresis shape."""
    from hystdisc.discovery.library import FAMILY_SHAPE

    shape = FAMILY_SHAPE.get(fit.par.family.name)
    found = getattr(disc, "stage1_", {}).get(shape)
    return None if found is None else np.asarray(found.s, dtype=float)


def close_loop(disc, dataset) -> None:
    """Close the loop on a fitted :class:`~hystdisc.discovery.stage1.Discovery`, in place.

    Runs :func:`augment` on the fit of the selected (or declared) family and records the
    outcome: ``disc.final_fit_`` (the fit with every accepted effect), ``disc.effects_``
    (their names), ``disc.loop_`` (the :class:`LoopResult`), and in ``disc.results_`` the
    keys ``effects``, ``effects_tried``, ``effects_skipped``, ``diagnosis``,
    ``unexplained``, ``unexplained_text``, ``residual``, ``final`` and ``model`` (the final
    term model, which ``hystdisc predict`` simulates).

    Parameters
    ----------
    disc : Discovery
        A fitted discovery (``family_fits_``, ``family_``, ``_fd``, ``noise_std_``,
        ``results_``).
    dataset : Dataset
        The dataset it was fitted on (unused beyond what ``disc`` holds; kept for the
        hook's signature).
    """
    import warnings

    from hystdisc.errors import HystdiscError, HystdiscWarning
    from hystdisc.results import Results, term_model_to_dict

    fit = disc.family_fits_[disc.family_]
    progress = getattr(disc, "progress", None)
    try:
        if not isinstance(fit.par, FamilyParametrization):
            raise HystdiscError("the fit is not a family's own parametrization")
        loop = augment(
            disc._fd,
            fit,
            disc.noise_std_,
            max_nfev=getattr(disc, "max_nfev", 60),
            heldout=bool(getattr(disc, "heldout", False)) and fit.heldout_rms is not None,
            eq=getattr(disc, "_eq", None),
            progress=progress,
            s0=_stage1_shape(disc, fit),
        )
    except (HystdiscError, np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
        warnings.warn(
            f"closing the loop failed ({exc}); the residual of {disc.family_} is reported "
            "without effects",
            HystdiscWarning,
            stacklevel=2,
        )
        loop = LoopResult(base=fit, fit=fit)
        noise = max(float(disc.noise_std_), accuracy_floor(disc._fd))
        loop.residual, loop.unexplained, loop.unexplained_text = assess_residual(
            masked_residuals(fit, disc._fd),
            _sampling_rate(disc._fd),
            noise,
            natural_frequency(fit, disc._fd.experiment),
        )
    disc.loop_ = loop
    disc.final_fit_ = loop.fit
    disc.effects_ = list(loop.effects)
    data = dict(disc.results_._data)
    data.update(
        {
            "model": term_model_to_dict(loop.fit.term_model),
            "effects": loop.accepted,
            "effects_tried": loop.tried,
            "effects_skipped": loop.skipped,
            "diagnosis": loop.diagnosis,
            "unexplained": loop.unexplained,
            "unexplained_text": loop.unexplained_text,
            "residual": loop.residual,
            "final": _final_entry(loop.fit, disc.family_, loop.effects),
        }
    )
    disc.results_ = Results(data)
