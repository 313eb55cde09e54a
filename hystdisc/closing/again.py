"""The selection reconsidered after the closing loop: with the loop's effects in every
family (:mod:`hystdisc.closing.reselect`), then reduced to a smaller family plus effects
when the selected one's intervals put it there (:mod:`hystdisc.closing.reduction`).

:func:`compare_again` runs both in that order, each on the family the previous step
left selected, and returns what was selected in the end, with the BICs of the comparison
that made that choice (the basis of the "fit equally well" list).

An effect stage 1 saw before the families were compared (a channel delay its scan saw
but did not call) is carried into the comparison too when the loop's refit on the
selected family wanted it (lower BIC by the margin, significant) and still rejected it
(:func:`absorbed`): the selected family may be the one whose shape absorbed it. A 2 ms
delay behind a tanh damper (never-drawn driven set 17) left Bouc-Wen selected, where the
delay removed 2 % of the residual's excess; only tanh with the delay predicts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hystdisc.closing.reduction import Reduction, reduce_family
from hystdisc.closing.refit import EFFECT_BIC_MARGIN
from hystdisc.closing.reselect import Context, Reselection, reselect, term_effects
from hystdisc.fitting import OEFit


@dataclass
class Again:
    """What :func:`compare_again` decided.

    Attributes
    ----------
    family : str
        The selected family (the one before when nothing switched).
    note : str or None
        Why it was switched (None: not switched).
    loop : LoopResult
        The loop of the selected family.
    reselection : Reselection or None
        The families compared again with the loop's term effects (None: none accepted).
    reduction : Reduction or None
        The reduction tried (None: no reduction's values inside the intervals).
    bics : dict of str to float or None
        The BICs of the comparison that switched the family (None: not switched).
    """

    family: str
    note: str | None
    loop: Any
    reselection: Reselection | None = None
    reduction: Reduction | None = None
    bics: dict[str, float] | None = None


def absorbed(loop: Any, seen: Mapping[str, Any]) -> list[str]:
    """The effects of ``seen`` that the loop refitted, found wanted (BIC lower by more
    than :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN`, significant) and rejected.

    Examples
    --------
    >>> from types import SimpleNamespace as V
    >>> tried = [V(name="channel_delay", ok=True, significant=True, bic_before=0.0,
    ...            bic_after=-300.0), V(name="backlash", ok=True, significant=False,
    ...            bic_before=0.0, bic_after=-1.0)]
    >>> absorbed(V(effects=[], tried=tried), {"channel_delay": {}, "backlash": {}})
    ['channel_delay']
    >>> absorbed(V(effects=["channel_delay"], tried=tried), {"channel_delay": {}})
    []
    """
    out = []
    for name in seen:
        if name in loop.effects:
            continue
        wanted = [
            v
            for v in loop.tried
            if v.name == name
            and v.ok
            and v.significant
            and v.bic_after is not None
            and v.bic_after < v.bic_before - EFFECT_BIC_MARGIN
        ]
        if wanted:
            out.append(name)
    return out


def compare_again(
    table: Mapping[str, OEFit],
    family: str,
    loop: Any,
    ctx: Context,
    seen: Mapping[str, Mapping[str, float]] | None = None,
) -> Again:
    """Reselect with the loop's term effects, then reduce (see the module docstring).

    Parameters
    ----------
    table : mapping of str to OEFit
        The family table's fits (every family, state-space ones included), without
        effects; ``family`` among them.
    family : str
        The family selected from the table.
    loop : LoopResult
        The loop closed on ``family``.
    ctx : Context
        The data and the callbacks (:class:`~hystdisc.closing.reselect.Context`).
    seen : mapping of str to mapping, optional
        Effects stage 1 saw, each with the start values of its parameters: carried too
        when the loop wanted and rejected them (:func:`absorbed`).

    Returns
    -------
    Again
    """
    out = Again(family, None, loop)
    seen = seen or {}
    wanted = absorbed(loop, seen)
    carried = term_effects(loop.effects) + wanted
    if carried:
        starts = {k: v for e in wanted for k, v in seen[e].items()}
        res = reselect(table, family, loop, carried, ctx, starts=starts)
        out.reselection = res
        if res.switched:
            out.family, out.note, out.loop = res.pick, res.note, res.loop
            out.bics = {n: f.bic for n, f in res.fits.items()}
    red = reduce_family(out.loop, out.family, table, ctx)
    out.reduction = red
    if red is not None and red.switched:
        out.family, out.note, out.loop = red.to, red.note, red.loop
        out.bics = dict(red.final_bic)
    return out
