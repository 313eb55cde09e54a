"""The selected family reduced to a smaller one plus effects, when the data put it there.

Some families are another family plus catalogued effects at a value of their own
parameters (:attr:`hystdisc.models.families.base.Family.reductions`): LuGre with
``sigma_1 = 0`` is Dahl with a current-dependent viscous term (``sigma_b i theta_dot``);
the standard Bouc-Wen at ``n = 1, beta = 0`` is the same Dahl model. On a Dahl damper
with a current-dependent viscous term (the seed's own finding) the family table compares
the families without effects, so LuGre, which carries that term natively, is selected
with ``sigma_1`` at 0 and reported not identifiable: the same model in a larger family,
with a parameter more than the data ask for.

When every parameter of a reduction has its 95 % interval around the reduction's value,
:func:`reduce_family` fits the smaller family with the reduction's effects (and the term
effects the loop accepted), and, when the family table's rule
(:func:`~hystdisc.selection.families.select_family`: admissible, held-out error, BIC)
prefers that fit, closes the loop again from the smaller family's table fit and applies
the same rule to the two final models; the smaller model is selected only when the rule
picks it there too. A parameter whose interval excludes the value (a LuGre damper whose
``sigma_1`` is significant) is never reduced.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from hystdisc.closing.reselect import (
    Context,
    effect_values,
    judge,
    refit_families,
    term_effects,
    versus,
)
from hystdisc.fitting import OEFit


def reduction_held(fit: OEFit) -> tuple[dict[str, float], str, tuple[str, ...]] | None:
    """The first of the fitted family's reductions whose every parameter's 95 % interval
    holds the reduction's value (an interval that could not be computed holds every
    value), or None (a state-space fit has none).

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> from hystdisc.models import get_family
    >>> fit = NS(is_system=False, par=NS(family=get_family("lugre")),
    ...          ci95={"sigma_1": (-0.02, 0.03)})
    >>> reduction_held(fit)
    ({'sigma_1': 0.0}, 'dahl', ('current_viscous',))
    >>> fit.ci95["sigma_1"] = (0.4, 0.6)
    >>> reduction_held(fit) is None
    True
    """
    if fit.is_system:
        return None
    for values, family, effects in fit.par.family.reductions:
        if all(_holds(fit.ci95.get(name), v) for name, v in values.items()):
            return dict(values), family, tuple(effects)
    return None


def _holds(ci: tuple[float, float] | None, value: float) -> bool:
    if ci is None:
        return False
    lo, hi = ci
    return not (lo > value or hi < value)  # NaN bounds (no interval) hold every value


@dataclass
class Reduction:
    """The selected family reduced to a smaller family plus effects.

    Attributes
    ----------
    family : str
        The family selected before.
    to : str
        The smaller family.
    at : dict of str to float
        The parameters of ``family`` whose intervals hold these values.
    effects : list of str
        The effects ``to`` was fitted with (the reduction's, then the loop's term effects).
    fit : OEFit
        ``to`` fitted with ``effects``.
    switched : bool
        True when the rule selected ``to``'s fit and its final model (the loop closed
        again from it): it is the selected family.
    final_heldout : dict of str to float or None
        The held-out RMS of the final model of ``family`` and (when the loop was closed
        again) of ``to``.
    final_bic : dict of str to float
        Their BIC.
    note : str
        What was compared and decided, in one sentence.
    loop : LoopResult or None
        The loop closed again from ``to`` (None when the rule kept ``family`` at once).
    """

    family: str
    to: str
    at: dict[str, float]
    effects: list[str]
    fit: OEFit
    switched: bool = False
    final_heldout: dict[str, float | None] = field(default_factory=dict)
    final_bic: dict[str, float] = field(default_factory=dict)
    note: str = ""
    loop: Any = None

    def to_dict(self) -> dict[str, Any]:
        """The ``reduction`` entry of ``results.json``."""
        return {
            "family": self.family,
            "to": self.to,
            "at": dict(self.at),
            "effects": list(self.effects),
            "fit": {
                "rms": self.fit.rms,
                "heldout_rms": self.fit.heldout_rms,
                "bic": self.fit.bic,
            },
            "switched": self.switched,
            "final_heldout": dict(self.final_heldout),
            "final_bic": dict(self.final_bic),
            "note": self.note,
        }


def reduce_family(
    loop: Any, before: str, family_fits: Mapping[str, OEFit], ctx: Context
) -> Reduction | None:
    """Reduce the selected family ``before`` to a smaller family plus effects, when the
    intervals of its final fit hold a reduction's values (see the module docstring).

    Parameters
    ----------
    loop : LoopResult
        The loop closed on ``before`` (its ``fit`` is the final model).
    before : str
        The selected family.
    family_fits : mapping of str to OEFit
        The family table's fits (every family, state-space ones included), without
        effects.
    ctx : Context
        The data and the callbacks (:class:`~hystdisc.closing.reselect.Context`).

    Returns
    -------
    Reduction or None
        None when no reduction's values lie inside the final fit's intervals, or the
        smaller family is not in the table.
    """
    say = ctx.say
    final = loop.fit
    held = reduction_held(final)
    if held is None or held[1] not in family_fits:
        return None
    at, to, own = held
    effects = list(own) + [e for e in term_effects(loop.effects) if e not in own]
    where = ", ".join(f"{k} = {v:g}" for k, v in at.items())
    say(f"reduction: {before} at {where} is {to} with {', '.join(own)}; fitting it")
    values = effect_values(final, effects)
    fit = refit_families({to: family_fits[to]}, effects, ctx.data, ctx.eq, values, ctx.shapes,
                         ctx.max_nfev, ctx.heldout)[to]  # fmt: skip
    red = Reduction(before, to, at, effects, fit)
    red.final_heldout[before], red.final_bic[before] = final.heldout_rms, final.bic
    names = ", ".join(effects)
    winner, adm = judge({before: final, to: fit}, ctx.envelope)
    if winner != to:
        red.note = (
            f"{before}'s intervals hold {where}, where it is {to} with {', '.join(own)}; "
            f"{to} with {names} is not selected over it ({versus(fit, final)}): {before} kept"
        )
        return red
    say(f"reduction: {to} with {names} is selected; closing the loop from it")
    red.loop = ctx.close(family_fits[to])
    new = red.loop.fit
    red.final_heldout[to], red.final_bic[to] = new.heldout_rms, new.bic
    winner, adm = judge({before: final, to: new}, ctx.envelope)
    if winner != to or not adm[to].ok:
        why = "" if adm[to].ok else f", not physical: {adm[to].violations[0]}"
        red.note = (
            f"{before}'s intervals hold {where}, where it is {to} with {', '.join(own)}; "
            f"{to} with {names} was selected over it ({versus(fit, final)}), but its final "
            f"model was not ({versus(new, final)}{why}): {before} kept"
        )
        return red
    red.switched = True
    red.note = (
        f"{before}'s intervals hold {where}, where it is {to} with {', '.join(own)}: the same "
        f"model with fewer parameters; {to}'s final model is selected "
        f"({versus(new, final)}): {to} selected"
    )
    return red
