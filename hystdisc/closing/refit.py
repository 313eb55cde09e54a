"""Refits of the model plus an effect, and what decides which effects are candidates.

:func:`candidate_effects` lists the catalogued effects the fitted model could still lack;
:func:`stage1_start` and :func:`screen_starts` give each augmented structure an
equation-error (stage 1) start that does not rely on the current optimum;
:func:`refit_with` refits the model plus one effect by output error from the better of
the local and the stage-1 starts.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hystdisc.closing.scores import EffectScore, with_effects
from hystdisc.data import distinct_currents
from hystdisc.discovery import family_start
from hystdisc.fitting import OEFit, OutputErrorFitter
from hystdisc.fitting.multistart import screen_start
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS, LAW_PREFIXES, Z_TORQUE_TERMS
from hystdisc.models.effects import scaled_effect_reason
from hystdisc.stats import bic_change

#: An effect is accepted only when its refit lowers BIC by more than this (the margin
#: within which :mod:`hystdisc.pipeline.close` calls two families equal fits,
#: ``EQUAL_FIT_BIC``), and refitted only when the score test predicts such a drop.
EFFECT_BIC_MARGIN = 6.0


@dataclass(frozen=True)
class EffectSkipped:
    """A catalogued effect that is no candidate for a model (:func:`candidate_effects`).

    Attributes
    ----------
    name : str
        Catalogue name.
    reason : str
        Why (the model has its terms, one current level, no rig spring, ...).
    """

    name: str
    reason: str


def current_levels(currents: np.ndarray) -> int:
    """Number of distinct current levels among the runs' currents."""
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
        ``k_s > 0`` and the lower end of its 95 % interval above 0, or no finite lower
        end: along a direction the data leave flat (a base fit bent by a missing offset
        into a degenerate optimum) ``k_s`` is undetermined, not shown to be 0.
    """
    ks = fit.params.get("k_s", 0.0)
    lo = fit.ci95.get("k_s", (0.0, 0.0))[0]
    if lo is None or not np.isfinite(lo):
        lo = np.inf  # undetermined: the value decides
    return bool(np.isfinite(ks) and ks > 0.0 and lo > 0.0)


def candidate_effects(fit: OEFit, data: FitData) -> tuple[list[str], list[EffectSkipped]]:
    """Catalogued effects the fitted model could still lack.

    Parameters
    ----------
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.FamilyParametrization` (possibly with effects).
    data : FitData
        The data it was fitted to (its currents decide what the current effects need).

    Returns
    -------
    candidates : list of str
        Effect names, in catalogue order.
    skipped : list of EffectSkipped
        Each effect left out, with the reason.
    """
    par = fit.par
    system = fit.is_system  # a state-space family: no term form
    tm = None if system else fit.term_part
    fam = par.family
    have = set(fam.torque_terms) | {t for e in par.effects for t in EFFECTS[e].terms}
    # terms the family can carry but fixed at zero (one current) do not count as present
    if tm is not None:
        have |= {k for k, v in tm.torque.items() if v != 0.0}
    has_state = tm.has_state if tm is not None else "z" in par.system.states
    levels = current_levels(data.currents)
    spring = has_spring(fit)
    exp = data.exp
    out, skipped = [], []
    for name, eff in EFFECTS.items():
        reason = None
        if name in par.effects:
            continue
        # a share of a torque term the family does not have (nor its compiled force)
        carried = system and name in fam.scaled_effects  # its form is the family's own
        if system and eff.scaled and not carried:
            reason = scaled_effect_reason(fam.name, eff)
        # a state-space family's own laws make its damping and yield depend on the
        # current; a force bias's law (current_bias: the term ``i``) is no law of its own
        elif system and (eff.structural or any(t.startswith(LAW_PREFIXES) for t in eff.terms)):
            reason = f"{fam.name} is a state-space family: " + (
                "the loop does not refit its structural form"
                if eff.structural
                else "its own current laws cover the current dependence"
            )
        elif eff.experiments and data.experiment not in eff.experiments:
            reason = (
                f"built for {', '.join(eff.experiments)} experiments only (its {data.experiment} "
                "form is not built)"
            )
        elif eff.structural:
            if any(EFFECTS[e].structural for e in par.effects):
                reason = "the model already has a structural effect"
            elif not exp.motion_imposed and not has_spring(fit):
                reason = "no rig spring (k_s is not significantly above 0): no beam to start from"
        elif not eff.terms:  # a measurement effect: it needs two recorded channels
            if not (exp.motion_imposed or exp.has_input):
                reason = f"a {exp.name} experiment records one channel"
        # one current: the family's own current terms are fixed at 0, so "already has" would
        # mislead; the levels are what rules a current effect out
        elif any(t.startswith("i") for t in eff.terms) and levels < 2:
            reason = "needs two current levels or more, the data have one"
        elif all(t in have for t in eff.terms):
            reason = f"{fam.name} already has {', '.join(eff.terms)}"
        elif any(t in Z_TORQUE_TERMS for t in eff.terms) and not has_state and not carried:
            reason = f"{fam.name} has no hysteretic state z"
        elif any(t.startswith("i^2") for t in eff.terms) and levels < 3:
            reason = f"needs three current levels or more, the data have {levels}"
        elif eff.has_role("spring") and not spring:
            reason = "no rig spring (k_s is not significantly above 0)"
        if reason is None:
            out.append(name)
        else:
            skipped.append(EffectSkipped(name, reason))
    return out, skipped


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
        Fit of a :class:`~hystdisc.fitting.FamilyParametrization`.
    effects : sequence of str
        Effects of the augmented structure.
    data : FitData
        The output-error data (for the number of current levels).
    s0 : ndarray, optional
        Shape constants to start the local search from (e.g. the family's own stage-1
        shape); the shape's grid is searched too, and of the two starts the one with the
        lower output-error RSS is returned.

    Returns
    -------
    dict or None
        Parameter values by name; None when stage 1 fails.
    """
    fam = fit.par.family
    eff_terms = [t for e in effects for t in EFFECTS[e].terms]
    found = []
    # from the family's stage-1 shape and from the shape's own grid: the first can be a
    # basin the missing effect made (an offset absorbed by a distorted z), the second not
    for shape0 in [s0, None] if s0 is not None else [None]:
        try:
            with np.errstate(all="ignore"):
                p, coefs = family_start(
                    eq,
                    fam.name,
                    eff_terms,
                    s0=shape0,
                    one_level=current_levels(data.currents) < 2,
                    constant=False,
                )
        except Exception:  # noqa: BLE001 - a start is optional
            continue
        p = _with_effect_values(p, coefs, fit, effects)
        if p is not None:
            found.append(p)
    if len(found) < 2:
        return found[0] if found else None
    rss = [_start_rss(data, fit, effects, p) for p in found]
    return found[int(np.argmin(rss))]


def _with_effect_values(p: dict, coefs: dict, fit: OEFit, effects: Sequence[str]) -> dict | None:
    """A stage-1 start ``p`` with the effects' parameters from the torque ``coefs``."""
    for e in effects:
        p.update(EFFECTS[e].from_torque(coefs, p["k_s"]))
        if EFFECTS[e].structural:  # its states are not in stage 1: keep the fitted values
            p.update(
                {q.name: fit.params[q.name] for q in EFFECTS[e].params if q.name in fit.params}
            )
    for k, v in fit.par.fixed.items():
        p[k] = v
    laws = getattr(fit.par, "laws", {})
    for q in fit.par.family.law_params(laws):  # stage 1 knows linear laws only
        p.setdefault(q.name, fit.params[q.name])
    if not all(np.isfinite(v) for v in p.values()):
        return None
    return p


def _start_rss(data: FitData, fit: OEFit, effects: Sequence[str], start: dict) -> float:
    """Output-error RSS of ``fit``'s structure plus ``effects`` at the parameters ``start``."""
    par0 = fit.par
    extra = [e for e in effects if e not in par0.effects]
    par = par0.like(start, tuple(par0.effects) + tuple(extra))
    return screen_start(data, par, 0, nuisance=fit.nuisance)[1]


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
    if fit.is_system:
        return  # a state-space family has no stage-1 structure to start from
    for sc in scores:
        if EFFECTS[sc.name].structural:
            continue  # its own starts (closing.structural)
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
        sc.start_dbic = bic_change(rss, fit.rss, N, q)


def refit_with(
    data: FitData,
    fit: OEFit,
    effect: str | Sequence[str],
    estimate: dict[str, float] | None = None,
    max_nfev: int = 60,
    heldout: bool = False,
    start: dict[str, float] | None = None,
    good_rms: float = 0.0,
    fallback: Callable[[], dict[str, float] | None] | None = None,
) -> OEFit:
    """Refit ``fit`` plus ``effect`` (one effect or several) by output error.

    Starts: the current optimum with the effect at 0, with the effect at its one-step
    estimate ``estimate``, and the stage-1 start ``start``; the fit runs from the one with
    the lowest RSS, and once more from the best start of the other kind (local or stage 1)
    when the first does not lower BIC by the margin or stays above ``good_rms``. Without
    ``start``, a local refit that does so runs once more from ``fallback()`` (a stage-1
    start made only then): a base fit distorted by the missing effect (an offset
    absorbed by ``n = 7.6``) keeps the local refit in its basin at 1.7 times the noise,
    where the stage-1 start, 9 times the noise away, converges to it.

    Parameters
    ----------
    data : FitData
        The data.
    fit : OEFit
        Current fit (a :class:`~hystdisc.fitting.FamilyParametrization`).
    effect : str or sequence of str
        Catalogue name of the effect to add, or the names of several.
    estimate : dict, optional
        One-step values of the effects' parameters (default 0).
    max_nfev : int
        Simulation budget of each fit.
    heldout : bool
        Also compute the held-out error (leave one test condition out, or one run).
    start : dict, optional
        A full start (family, rig and effect parameters), e.g. from :func:`stage1_start`.
    good_rms : float
        An RMS that needs no second start (e.g. a little above the noise).
    fallback : callable, optional
        Makes a full start when the local refit needs another (see above); None when it
        has none.

    Returns
    -------
    OEFit
        The refit with the lowest BIC.
    """
    added = [effect] if isinstance(effect, str) else list(effect)
    local = []
    for values in [None] + ([estimate] if estimate and any(estimate.values()) else []):
        par, x = with_effects(fit, added, values)
        st = dict(zip(par.names, map(float, x), strict=True))
        local.append((_start_rss(data, fit, added, st), st))
    local.sort(key=lambda t: t[0])
    groups = [local[0]]
    if start is not None:
        g = (_start_rss(data, fit, added, start), start)
        groups = [g, local[0]] if g[0] < local[0][0] else [local[0], g]
    if start is None and fallback is not None:
        groups.append((np.inf, fallback))  # made only when the local refit falls short
    best = None
    for _, st in groups:
        if callable(st) and (st := st()) is None:
            break
        par0 = fit.par
        par = par0.like(st, (*par0.effects, *added))
        with np.errstate(all="ignore"):
            new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
        if best is None or (np.isfinite(new.bic) and new.bic < best.bic):
            best = new
        if fit_ok(best, fit) and best.bic < fit.bic - EFFECT_BIC_MARGIN and best.rms <= good_rms:
            break
    return best


def fit_ok(fit: OEFit, before: OEFit) -> bool:
    """A refit is usable: finite, and its simulation did not blow up."""
    if not (np.isfinite(fit.rms) and np.isfinite(fit.bic)):
        return False
    if not all(np.all(np.isfinite(p)) for p in fit.predictions):
        return False
    return bool(fit.rms < 10.0 * before.rms + 1e-300)


def refit_without(data: FitData, fit: OEFit, like: OEFit, max_nfev: int, heldout: bool):
    """Refit the structure of ``like`` started from ``fit`` (which has one effect more)."""
    par0 = like.par
    par = par0.like(dict(fit.params), par0.effects)
    return OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
