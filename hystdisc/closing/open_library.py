"""An open library for the residual: sparse regression where the catalogue ends.

When the catalogued effects leave structure in the residual, the equation-error residual
of the model (``target - T(theta, theta_dot, z, i)``, the model's own terms projected out)
is regressed on a broad library of named candidate forces in the states and the inputs
(:func:`candidate_library`):

* the catalogue's torque terms the model does not have (:data:`~hystdisc.models.TORQUE_TERMS`);
* a constant, its current slope and a bias per current level (``bias[i=0.75 A]``);
* polynomials (``theta^2``, ``theta_dot^3``), ``|theta_dot|^m`` forms and
  ``tanh(theta_dot/v0)`` at several velocity scales;
* terms that differ in tension and compression (``[theta_dot>0]``,
  ``theta_dot*[theta_dot>0]``, ``theta*[theta>0]``);
* the output of a play (backlash) operator of the motion against the motion, at several
  widths (``play(theta,0.0005)-theta``: one physical width for every run, a share of the
  runs' median half-range), and the velocity the play loses;
* products of the main ones with the current (``i*...``).

Terms are selected by pysindy's forward regression (FROLS: orthogonal least squares, robust
to a library of strongly correlated candidates) along its path scored by BIC (effective
sample size of the record) sets how many terms a fit may take; a term is kept when it is
stable: selected in at least :data:`MIN_INCLUSION` of bootstrap refits of that size
(pysindy's ``EnsembleOptimizer``; stability selection as Meinshausen and Bühlmann define
it, whether or not the one full-data path holds it: where several candidates are about
equally correlated with the residual, which of them that path takes first is chance).
The stable set is then pruned by BIC (a term that only corrected unkept ones goes), and
identical columns keep one name. What is selected is mapped to a catalogued effect whose
torque terms it covers, a play term to the catalogued play (``backlash``) (:attr:`ResidualTerms.effects`:
the loop tries those it has not refitted by output error,
:func:`hystdisc.pipeline.close.library_effects`); the rest
is a *discovered effect*, reported with its equation. Nothing here is accepted: a term
set is evidence, and only a refit that predicts held-out conditions better is a verdict.
On a driven test's force residual the stable terms are judged so (:func:`~hystdisc.closing.library_heldout.heldout_terms`):
each test condition is left out, the model's parameters (linearized at the optimum) and
the terms' coefficients are refitted on the others, and the held-out RMS with the terms is
reported beside the one without (:attr:`ResidualTerms.heldout`). When that screen says
they predict better, the terms are refitted into the model by output error and judged on
held-out conditions like every effect (:func:`~hystdisc.closing.library_refit.refit_terms`,
:attr:`ResidualTerms.refit`).

Examples
--------
>>> t = np.arange(4000) / 1000.0
>>> th = np.sin(2 * np.pi * t)
>>> gap = term_column("play(theta,0.1)-theta", th, np.gradient(th, t), 0.0, t)
>>> round(float(np.mean(gap)), 3), round(float(np.max(np.abs(gap))), 3)
(0.0, 0.1)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pysindy as ps

from hystdisc.closing.library_heldout import HeldOutTerms, heldout_terms
from hystdisc.closing.library_refit import TermsRefit
from hystdisc.closing.scores import equation_state
from hystdisc.discovery.selection import seeded_fit
from hystdisc.fitting import OutputErrorFitter
from hystdisc.models import EFFECTS, TORQUE_TERMS, TermModel
from hystdisc.models.term_columns import FIXED, bias_name, play_names, tanh_name, term_column
from hystdisc.registry import get_experiment
from hystdisc.stats import bic

#: A term is kept when it is selected in at least this share of the bootstrap refits.
MIN_INCLUSION = 0.8
#: Bootstrap refits of the stability selection.
N_MODELS = 40
#: Widths of the play (backlash) operator, in units of the runs' median half-range of the
#: motion: one physical width for every run (a damper's play does not scale with the stroke).
PLAY_WIDTHS = (0.02, 0.05, 0.1)
#: Velocity scales of the ``tanh`` terms, in units of the largest ``|theta_dot|``.
TANH_SCALES = (0.02, 0.1)
#: Rows of the regression at most (every k-th row of a longer record).
MAX_ROWS = 6000
#: At most this many terms along the forward path.
MAX_TERMS = 8


@dataclass
class DiscoveredTerm:
    """One term the residual regression selected.

    Attributes
    ----------
    name : str
        The candidate's name (its formula in the states and inputs).
    coefficient : float
        Its coefficient in the output's units (torque or force per the term's unit).
    inclusion : float
        Share of the bootstrap refits that selected it.
    effect : str
        The catalogued effect whose terms it belongs to ("" for none: discovered).
    """

    name: str
    coefficient: float
    inclusion: float
    effect: str = ""

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        return {
            "name": self.name,
            "coefficient": self.coefficient,
            "inclusion": self.inclusion,
            "effect": self.effect,
        }


@dataclass
class ResidualTerms:
    """What the open library found in a residual.

    Attributes
    ----------
    terms : list of DiscoveredTerm
        The stable terms, largest contribution first.
    explained : float
        Share of the residual's sum of squares (the model's terms projected out) the
        selected terms explain together.
    effects : list of str
        Catalogued effects whose torque terms are all among the selected.
    candidates : int
        Candidate terms in the library.
    heldout : ~hystdisc.closing.library_heldout.HeldOutTerms or None
        The stable terms judged on held-out conditions (:func:`~hystdisc.closing.library_heldout.heldout_terms`; None: not
        judged, a test whose output is not the force or a single condition).
    refit : ~hystdisc.closing.library_refit.TermsRefit or None
        The terms refitted into the model by output error and judged on held-out
        conditions (:func:`~hystdisc.closing.library_refit.refit_admissible`; None: not
        refitted).
    """

    terms: list[DiscoveredTerm] = field(default_factory=list)
    explained: float = 0.0
    effects: list[str] = field(default_factory=list)
    candidates: int = 0
    heldout: HeldOutTerms | None = None
    refit: TermsRefit | None = None

    @property
    def discovered(self) -> list[DiscoveredTerm]:
        """The selected terms no catalogued effect accounts for."""
        return [t for t in self.terms if not t.effect]

    def play_found(self) -> float | None:
        """The width (in the motion's units) of the largest selected play term; None when
        none was selected."""
        widths = [play_width(t.name) for t in self.terms]  # largest contribution first
        return next((r for r in widths if r is not None), None)

    def equation(self) -> str:
        """The discovered effect as an equation of the extra torque (empty: none).

        Examples
        --------
        >>> ResidualTerms([DiscoveredTerm("[theta_dot>0]", 0.05, 1.0)]).equation()
        'T_extra = 0.05*[theta_dot>0]'
        """
        found = self.discovered
        if not found:
            return ""
        parts = [f"{t.coefficient:+.4g}*{t.name}" for t in found]
        text = " ".join(parts).lstrip("+")
        return "T_extra = " + text.replace(" +", " + ").replace(" -", " - ")

    def summary(self) -> str:
        """Readable lines: the selected terms, their inclusion and what they map to."""
        if not self.terms:
            return f"open library ({self.candidates} candidates): no stable term"
        lines = [
            f"open library ({self.candidates} candidates): {len(self.terms)} stable terms "
            f"explain {self.explained:.0%} of the residual"
        ]
        for t in self.terms:
            where = f" -> {t.effect}" if t.effect else " (discovered)"
            lines.append(f"  {t.name}: {t.coefficient:.4g}, inclusion {t.inclusion:.2f}{where}")
        if self.discovered:
            lines.append("  " + self.equation())
        if self.heldout is not None:
            lines.append("  " + self.heldout.sentence())
        if self.refit is not None:
            lines += ["  " + self.refit.equation(), "  " + self.refit.sentence()]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        out = {
            "terms": [t.to_dict() for t in self.terms],
            "explained": self.explained,
            "effects": list(self.effects),
            "candidates": self.candidates,
            "equation": self.equation(),
        }
        if self.heldout is not None:
            out["heldout"] = self.heldout.to_dict()
        if self.refit is not None:
            out["refit"] = self.refit.to_dict()
        return out


def _open_terms(levels: Sequence[float], w_max: float, half: float) -> list[str]:
    """The candidates beyond the catalogue, by name (:func:`~hystdisc.models.term_columns.term_column`
    computes each); ``w_max`` is the largest ``|theta_dot|``, ``half`` the runs' median
    half-range."""
    names = ["i", *FIXED, "i*[theta_dot>0]"]
    names += [bias_name(lv) for lv in levels[2:]]  # with "1" and "i": any bias per level
    for s in TANH_SCALES:
        names += [tanh_name(s * w_max), "i*" + tanh_name(s * w_max)]
    for share in PLAY_WIDTHS:
        gap, lost = play_names(float(f"{share * half:.3g}"))  # the width its name says
        names += [gap, lost, "i*" + lost]
    return [n for n in dict.fromkeys(names) if n not in TORQUE_TERMS]  # catalogued: one name


def play_width(name: str) -> float | None:
    """The width ``r`` of a play term's name (``play(theta,0.0005)-theta`` and its
    derivatives: 0.0005, in the motion's units); None for another term.

    Examples
    --------
    >>> play_width("i*d/dt[play(theta,0.0005)-theta]"), play_width("theta^2")
    (0.0005, None)
    """
    head = "play(theta,"
    at = name.find(head)
    if at < 0:
        return None
    end = name.find(")", at)
    try:
        return float(name[at + len(head) : end])
    except ValueError:
        return None


def median_half_range(theta: Sequence[np.ndarray]) -> float:
    """The median over runs of half the motion's range (the play widths' unit).

    Examples
    --------
    >>> median_half_range([np.array([-0.2, 0.2]), np.array([0.0, 0.1]), np.array([])])
    0.1
    """
    half = [0.5 * float(np.ptp(th)) for th in theta if np.size(th)]
    return float(np.median(half)) if half else 0.0


def candidate_library(eq, tm: TermModel) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """The residual to explain and the candidate columns (see the module docstring).

    Parameters
    ----------
    eq : EqData
        Equation-error data of the runs.
    tm : TermModel
        The model in term form (its torque terms and hysteresis state).

    Returns
    -------
    names : list of str
        The candidates.
    G : ndarray (rows, candidates)
        Their values on the equation's rows, all runs.
    r : ndarray
        The equation residual ``target - T``.
    A : ndarray
        The model's own columns (its torque terms, and the inertia where identifiable).
    """
    z = equation_state(eq, tm)
    own = [k for k, v in tm.torque.items() if v != 0.0]
    coefs = np.array([tm.torque[k] for k in own])
    catalogue = [k for k in TORQUE_TERMS if k not in own and k != "z"]
    levels = sorted({float(c) for c in eq.currents})
    w_max = max(
        float(np.max(np.abs(w[m]))) if m.any() else 0.0
        for w, m in zip(eq.theta_dot, eq.rows, strict=True)
    )
    opened = _open_terms(levels, max(w_max, 1e-300), median_half_range(eq.theta))
    names = catalogue + list(opened)
    inertia = get_experiment(eq.experiment).inertia_identifiable
    A_rows, G_rows, res = [], [], []
    for k in range(len(eq.t)):
        m = eq.rows[k]
        t, th, w, zk = eq.t[k], eq.theta[k], eq.theta_dot[k], z[k]
        i = float(eq.currents[k])
        A = np.column_stack([tm.term(n, th, w, zk, i)[m] for n in own] or [np.zeros(int(m.sum()))])
        pred = A @ coefs if own else np.zeros(int(m.sum()))
        if inertia:
            pred = pred + tm.J * eq.theta_ddot[k][m]
            A = np.column_stack([eq.theta_ddot[k][m], A])
        cols = [np.broadcast_to(tm.term(n, th, w, zk, i), th.shape)[m] for n in catalogue]
        cols += [term_column(n, th, w, i, t)[m] for n in opened]
        A_rows.append(A)
        G_rows.append(np.column_stack(cols))
        res.append(eq.target[k][m] - pred)
    return names, np.vstack(G_rows), np.concatenate(res), np.vstack(A_rows)


def stable_terms(
    G: np.ndarray, r: np.ndarray, names: Sequence[str], k: int, seed: int
) -> dict[str, float]:
    """Stability selection: the share of bootstrap refits (pysindy's ``EnsembleOptimizer``
    around a ``k``-term forward regression, FROLS) that select each term."""
    opt = ps.EnsembleOptimizer(
        opt=ps.FROLS(max_iter=k, alpha=1e-8, unbias=True), bagging=True, n_models=N_MODELS
    )
    seeded_fit(opt, G, r / (np.sqrt(np.mean(r * r)) or 1.0), seed)
    coefs = np.array([np.asarray(c).ravel() for c in opt.coef_list])
    return dict(zip(names, map(float, (np.abs(coefs) > 0).mean(axis=0)), strict=True))


def regress_residual(eq, tm: TermModel, seed: int = 0) -> ResidualTerms:
    """The stable terms of the open library in the model's equation residual.

    Parameters
    ----------
    eq : EqData
        Equation-error data of the runs.
    tm : TermModel
        The fitted model in term form (``OEFit.term_part``).
    seed : int
        Seed of the bootstrap refits.

    Returns
    -------
    ResidualTerms
    """
    names, G, r, A = candidate_library(eq, tm)
    n_all = r.size
    if n_all > MAX_ROWS:  # neighbouring rows say the same (n_eff counts what they say)
        step = int(np.ceil(n_all / MAX_ROWS))
        G, r, A = G[::step], r[::step], A[::step]
    return select_terms(names, G, r, A, min(float(eq.n_eff(n_all)), float(r.size)), seed)


def regress_output_residual(data, fit, seed: int = 0) -> ResidualTerms:
    """The stable terms of the open library in the output-error residual of a test whose
    output is the force (driven: motion imposed), any family, state-space ones included.

    The residual ``measured - simulated`` is a force; the candidates are evaluated on the
    motion (no hysteretic state: a state-space family's is not the term form's), and the
    model's own sensitivities at its optimum (the fitter's Jacobian) are projected out, so
    that what a refit of the model itself would absorb is not credited to a new term.

    Parameters
    ----------
    data : FitData
        The fit's data (``torque`` output).
    fit : OEFit
        The fit at its optimum.
    seed : int
        Seed of the bootstrap refits.

    Returns
    -------
    ResidualTerms
    """
    if data.exp.output != "torque":
        raise ValueError("the output-error library needs a force output (a driven test)")
    par = fit.par.like(dict(fit.params), fit.par.effects)  # at the optimum
    v = np.concatenate([par.x0, np.asarray(fit.nuisance, dtype=float).ravel()])
    fitter = OutputErrorFitter(data, par)
    with np.errstate(all="ignore"):
        r = -fitter.residuals(v)  # measured - simulated
        J = fitter.jacobian(v)
    levels = sorted({float(c) for c in data.currents})
    w_max = 0.0
    motion = []
    for k in range(data.n_runs):
        t = np.asarray(data.t[k], dtype=float)
        th = np.asarray(data.theta[k], dtype=float)
        w = np.gradient(th, t)
        motion.append((t, th, w))
        w_max = max(w_max, float(np.max(np.abs(w[data.mask[k]]))))
    opened = _open_terms(levels, max(w_max, 1e-300), median_half_range(data.theta))
    catalogue = [k for k in TORQUE_TERMS if "z" not in k and "^m" not in k]
    names = catalogue + list(opened)
    cols = []
    for k, (t, th, w) in enumerate(motion):
        m, i = data.mask[k], float(data.currents[k])
        z = np.zeros_like(th)
        tm = TermModel({})
        block = [np.broadcast_to(tm.term(n, th, w, z, i), th.shape)[m] for n in catalogue]
        block += [term_column(n, th, w, i, t)[m] for n in opened]
        cols.append(np.column_stack(block))
    G = np.vstack(cols)
    of_run = np.repeat(np.arange(data.n_runs), [int(m.sum()) for m in data.mask])
    fold = np.zeros(data.n_runs, dtype=int)
    for f, runs in enumerate(data.folds()):
        fold[runs] = f
    n_all, n_eff = r.size, float(data.n_eff())
    if n_all > MAX_ROWS:
        step = int(np.ceil(n_all / MAX_ROWS))
        G, r, J, of_run = G[::step], r[::step], J[::step], of_run[::step]
    A = J[:, np.any(J != 0.0, axis=0) & np.all(np.isfinite(J), axis=0)]
    out = select_terms(names, G, r, A, min(n_eff, float(r.size)), seed)
    if out.terms:
        chosen = [names.index(t.name) for t in out.terms]
        out.heldout = heldout_terms(G[:, chosen], r, A, fold[of_run])
    return out


def select_terms(
    names: Sequence[str], G: np.ndarray, r: np.ndarray, A: np.ndarray, n_eff: float, seed: int
) -> ResidualTerms:
    """Forward regression of ``r`` on the columns ``G`` named ``names``, the span of
    ``A`` (the model's own columns) projected out of both; BIC along the path with
    ``n_eff`` effective samples, then stability selection (see the module docstring)."""
    names = list(names)
    q, _ = np.linalg.qr(A)
    r_perp = r - q @ (q.T @ r)
    Gp = G - q @ (q.T @ G)
    sc = np.sqrt((Gp**2).mean(axis=0))
    usable = sc > 1e-9 * max(float(sc.max()), 1e-300)
    usable &= ~_repeated(Gp, sc, usable)
    names = [n for n, u in zip(names, usable, strict=True) if u]
    Gp, sc = Gp[:, usable], sc[usable]
    rss0 = float(r_perp @ r_perp)
    out = ResidualTerms(candidates=len(names))
    if rss0 <= 0.0 or not names:
        return out
    n = r_perp.size
    k_max = min(MAX_TERMS, len(names))
    frols = ps.FROLS(normalize_columns=False, max_iter=k_max, alpha=1e-8, unbias=True)
    frols.fit(Gp / sc, r_perp / np.sqrt(rss0 / n))
    # the forward path: BIC of each number of terms, refitted by least squares
    best_k, best_b = 0, bic(rss0, n, 0, n_eff=n_eff)
    for k, coef in enumerate(frols.history_[:k_max], start=1):
        support = np.abs(np.asarray(coef).ravel()) > 0
        c, *_ = np.linalg.lstsq(Gp[:, support], r_perp, rcond=None)
        e = r_perp - Gp[:, support] @ c
        b = bic(float(e @ e), n, int(support.sum()), n_eff=n_eff)
        if b < best_b - 1e-9:
            best_k, best_b = k, b
    if best_k == 0:
        return out
    probs = stable_terms(Gp / sc, r_perp, names, best_k, seed)
    keep = np.array([probs[nm] >= MIN_INCLUSION for nm in names])
    keep = _pruned(Gp, r_perp, keep, n_eff)
    if not keep.any():
        return out
    c, *_ = np.linalg.lstsq(Gp[:, keep], r_perp, rcond=None)
    e = r_perp - Gp[:, keep] @ c
    kept = [nm for nm, k in zip(names, keep, strict=True) if k]
    effects = [
        name
        for name, eff in EFFECTS.items()
        if eff.terms and not eff.structural and all(t in kept for t in eff.terms)
    ]
    owner = {t: name for name in effects for t in EFFECTS[name].terms}
    # a play operator's terms are the catalogued play effect's signature (it has no
    # torque term: it acts on the motion the damper sees)
    plays = [name for name, eff in EFFECTS.items() if eff.play_param]
    for t in kept:
        if plays and play_width(t) is not None:
            owner[t] = plays[0]
            if plays[0] not in effects:
                effects.append(plays[0])
    size = np.abs(c) * np.sqrt((Gp[:, keep] ** 2).mean(axis=0))
    order = np.argsort(-size)
    out.terms = [
        DiscoveredTerm(kept[j], float(c[j]), float(probs[kept[j]]), owner.get(kept[j], ""))
        for j in order
    ]
    out.explained = 1.0 - float(e @ e) / rss0
    out.effects = effects
    return out


def _repeated(G: np.ndarray, sc: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Columns that repeat an earlier one (up to scale: ``|corr| > 1 - 1e-9``); the first
    keeps the name (the catalogue's come first). Two copies of one column would share the
    bootstrap refits' picks between them, and neither might reach the inclusion a term
    needs (``sign(theta_dot)*|theta_dot|^0.5`` is the catalogued ``^m`` at its start)."""
    out = np.zeros(G.shape[1], dtype=bool)
    cols = np.flatnonzero(usable)
    U = G[:, cols] / (sc[cols] * np.sqrt(G.shape[0]))
    C = np.abs(U.T @ U)
    for a in range(cols.size):
        if not out[cols[a]]:
            for b in range(a + 1, cols.size):
                if C[a, b] > 1.0 - 1e-9:
                    out[cols[b]] = True
    return out


def _pruned(G: np.ndarray, r: np.ndarray, keep: np.ndarray, n_eff: float) -> np.ndarray:
    """The stable set without its terms that do not earn their place together: the term
    whose removal lowers the set's BIC most is removed, until none does. A term stable in
    the bootstrap refits of a larger path may explain nothing beside the other stable
    terms alone (it was picked to correct terms that did not reach the inclusion)."""
    keep = keep.copy()
    n = r.size

    def score(mask: np.ndarray) -> float:
        if not mask.any():
            return bic(float(r @ r), n, 0, n_eff=n_eff)
        c, *_ = np.linalg.lstsq(G[:, mask], r, rcond=None)
        e = r - G[:, mask] @ c
        return bic(float(e @ e), n, int(mask.sum()), n_eff=n_eff)

    now = score(keep)
    while keep.any():
        trials = []
        for j in np.flatnonzero(keep):
            m = keep.copy()
            m[j] = False
            trials.append((score(m), j))
        best, j = min(trials)
        if not best < now:
            break
        keep[j], now = False, best
    return keep
