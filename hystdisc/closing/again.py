"""The selection reconsidered after the closing loop: with the loop's effects in every
family (:mod:`hystdisc.closing.reselect`), then reduced to a smaller family plus effects
when the selected one's intervals put it there (:mod:`hystdisc.closing.reduction`).

:func:`compare_again` runs both in that order, each on the family the previous step
left selected, and returns what was selected in the end, with the BICs of the comparison
that made that choice (the basis of the "fit equally well" list).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hystdisc.closing.reduction import Reduction, reduce_family
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


def compare_again(table: Mapping[str, OEFit], family: str, loop: Any, ctx: Context) -> Again:
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

    Returns
    -------
    Again
    """
    out = Again(family, None, loop)
    carried = term_effects(loop.effects)
    if carried:
        res = reselect(table, family, loop, carried, ctx)
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
