"""Diagnosis of the residual: how much each catalogued effect would explain.

The score (Lagrange-multiplier) test in output-error space (:func:`score_effects`): all
candidates are appended to the model at value 0, and one Jacobian of the fitter
(:meth:`~hystdisc.fitting.OutputErrorFitter.jacobian`) at the current optimum gives each
effect's signature ``g`` (how the simulated output moves when the effect is switched on)
beside the model's own columns ``A``
(parameters and initial states). ``g`` is projected out of the span of ``A``; what the
projected column explains of the residual is the Gauss-Newton predicted RSS reduction of
adding the effect and refitting everything. Its share of the RSS is the effect's
*evidence* (pooled, and each run's part), and it predicts the BIC change
``N log(1 - share) + q log N``. The *equation-error evidence* is the same share for the
equation residual ``target - T(theta, theta_dot, z, i)`` and the effect's torque term,
the model's terms projected out (a second view that the local optimum cannot trap).
:func:`wald_chi2` is the significance of an effect's parameter after its refit.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from hystdisc.fitting import OEFit, OutputErrorFitter
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS, SIGN_EPS, TORQUE_TERMS, TermModel
from hystdisc.registry import get_experiment
from hystdisc.simulation import integrate_z
from hystdisc.stats import bic_change


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
    starts : list of dict or None
        A structural effect's screened starts, best first
        (:func:`~hystdisc.closing.structural.score_structural`).
    signature : str or None
        A structural effect's signature in the residual, in words (a resonance above the
        beam's frequency), when there is one.
    cells : list of dict or None
        Release: the wheel values of the grid's screened cells, best first; the loop's
        next round screens the best of them only
        (:func:`~hystdisc.closing.structural.score_structural`).
    not_refitted : str or None
        Why a candidate whose evidence called for a refit was not refitted (an earlier
        refit of the round had already brought the residual to the noise); None otherwise.
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
    starts: list[dict[str, float]] | None = None
    signature: str | None = None
    cells: list[dict] | None = None
    not_refitted: str | None = None


def with_effects(fit: OEFit, extra: Sequence[str], values: dict[str, float] | None = None):
    """Parametrization of ``fit`` plus ``extra`` effects, and its vector at the optimum.

    The effects' parameters are appended after the model's, at ``values`` (default: where
    the effect is absent, :meth:`~hystdisc.models.Effect.off_values`: torque coefficients
    0, exponents at their defaults).
    """
    par0 = fit.par
    start = dict(fit.params)
    for e in extra:
        off = EFFECTS[e].off_values()
        for p in EFFECTS[e].params:
            start[p.name] = (values or {}).get(p.name, off[p.name])
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


def equation_state(eq, tm: TermModel) -> list[np.ndarray]:
    """The hysteretic state of ``tm`` along each run of the equation-error data ``eq``
    (zeros for a model without one)."""
    if tm.has_state:
        return integrate_z(tm.hysteresis_vector(), tm.n, eq.t, eq.theta_dot, SIGN_EPS)
    return [np.zeros_like(t) for t in eq.t]


def _equation_evidence(
    eq, tm: TermModel, candidates: Sequence[str]
) -> dict[str, tuple[float, float]]:
    """Equation-error evidence of each candidate (see the module docstring)."""
    z = equation_state(eq, tm)
    terms = [k for k, v in tm.torque.items() if v != 0.0]
    coefs = np.array([tm.torque[t] for t in terms])
    inertia = get_experiment(eq.experiment).inertia_identifiable
    A_rows, G_rows, res = [], [], []
    for k in range(len(eq.t)):
        m = eq.rows[k]
        th, w, zk = eq.theta[k][m], eq.theta_dot[k][m], z[k][m]
        i = float(eq.currents[k])
        A = np.column_stack([tm.term(t, th, w, zk, i) for t in terms] or [np.zeros(th.size)])
        pred = A @ coefs if terms else np.zeros(th.size)
        if inertia:
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
        if q == 0:  # no torque term: nothing to see in equation error
            out[c] = (0.0, 0.0)
            continue
        G = np.column_stack([np.concatenate([g[t] for g in G_rows]) for t in EFFECTS[c].terms])
        Gp = G - U @ (U.T @ G)
        if rss <= 0 or np.sqrt((Gp**2).sum()) <= 1e-8 * np.sqrt((G**2).sum()):
            red = 0.0
        else:
            red = _explained(Gp, r_perp)[0]
        left = max(rss_perp - red, 1e-300)
        dbic = bic_change(left, rss_perp, ne, q)
        out[c] = (red / rss if rss > 0 else 0.0, dbic)
    return out


#: Where an effect's output is not differentiable at its off value (a play of width
#: ``r`` changes the force as ``sqrt(r)`` near the reversals), its score column is the
#: secant to this share of the smallest run's motion amplitude instead of the tangent.
PLAY_PROBE = 0.02


def _secant_columns(
    data: FitData, fitter: OutputErrorFitter, par, v: np.ndarray, r: np.ndarray, J: np.ndarray
) -> None:
    """Replace (in place) the columns of ``J`` of the parameters that set a driven run's
    backlash (:attr:`~hystdisc.models.Effect.play_param`) by the secant of the residuals
    ``r`` to :data:`PLAY_PROBE` of the smallest motion amplitude: the tangent at a width
    of 0 sees only a sliver of what a width does, and the effect would rank below
    effects that explain less."""
    plays = {e.play_param for e in (EFFECTS[n] for n in par.effects) if e.play_param}
    if not plays or not data.exp.motion_imposed:
        return
    probe = PLAY_PROBE * min(0.5 * float(np.ptp(th)) for th in data.theta)
    for j, name in enumerate(par.names):
        if name in plays and probe > v[j]:  # at its off value (inside its bound)
            vj = v.copy()
            vj[j] = probe
            J[:, j] = (fitter.residuals(vj) - r) / (probe - v[j])


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
        Effect names (see :func:`candidate_effects`); structural effects among them are
        left out (their diagnosis is :func:`~hystdisc.closing.structural.score_structural`).
    eq : EqData, optional
        Equation-error data (``Discovery.eq_data_``); when given, ``evidence_eq`` is computed.

    Returns
    -------
    list of EffectScore
        Sorted by decreasing evidence.
    """
    candidates = [c for c in candidates if not EFFECTS[c].structural]
    if not candidates:
        return []
    par, x = with_effects(fit, candidates)
    fitter = OutputErrorFitter(data, par)
    v = np.concatenate([x, np.asarray(fit.nuisance, dtype=float).ravel()])
    with np.errstate(all="ignore"):
        r = fitter.residuals(v)
        J = fitter.jacobian(v)
        _secant_columns(data, fitter, par, v, r, J)
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
                eq_ev = _equation_evidence(eq, fit.term_part, candidates)
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
        dbic = bic_change(left, rss_perp, N, q)
        names = [p.name for p in EFFECTS[c].params]
        # the step from where the effect is off (an exponent's column is 0 there)
        off = EFFECTS[c].off_values()
        beta = [off[n] + b for n, b in zip(names, beta, strict=True)]
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


def wald_chi2(fit: OEFit, effect: str) -> float:
    """Smallest squared z-score (value / standard error) of an effect's parameters in ``fit``
    (of its :attr:`~hystdisc.models.Effect.significance` parameters when it names them: the
    compliance ``1/k_w`` of ``series_compliance`` has the z-score of ``k_w``).

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
    return effect_z2(effect, fit.params, fit.stderr)


def significance_params(effect: str) -> list[str]:
    """The parameters whose z-scores say the effect ``effect`` is there (its
    :attr:`~hystdisc.models.Effect.significance` ones when it names them, else all)."""
    eff = EFFECTS[effect]
    return [p.name for p in eff.params if not eff.significance or p.name in eff.significance]


def effect_z2(effect: str, values: Mapping[str, float], stderr: Mapping[str, float]) -> float:
    """:func:`wald_chi2` from the parameters' ``values`` and standard errors ``stderr``
    (a parameter missing from them counts as 0 with an infinite error).

    Examples
    --------
    >>> effect_z2("coulomb", {"f_c": 0.3}, {"f_c": 0.1})
    9.0
    """
    out = np.inf
    for name in significance_params(effect):
        v = values.get(name, 0.0)
        se = stderr.get(name, np.inf)
        z2 = (v / se) ** 2 if se > 0 else (np.inf if v != 0 else 0.0)
        out = min(out, float(z2) if np.isfinite(z2) else (np.inf if se == 0 else 0.0))
    return float(out)
