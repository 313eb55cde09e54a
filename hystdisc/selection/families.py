"""Which family is selected: admissible, predicting the held-out runs, then BIC.

:func:`select_family` is the rule of the family table (:class:`hystdisc.Discovery`) and of
the families compared again with the rig's effects (:mod:`hystdisc.closing.reselect`):

1. the families whose fit is physically admissible (all of them when none is);
2. of those with a held-out RMS, the ones within :data:`HELDOUT_CLEARLY_WORSE` of the best
   (a family whose held-out prediction diverged, with no held-out RMS while others have
   one, did not predict the data it did not see and is left out);
3. the lowest BIC, families within :data:`SELECTION_TIE_BIC` of it resolved towards fewer
   parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: Families within this BIC of the lowest are a tie, resolved towards fewer parameters.
SELECTION_TIE_BIC = 2.0
#: A family whose held-out RMS exceeds the best family's by more than this factor is not
#: selected on BIC alone.
HELDOUT_CLEARLY_WORSE = 1.1


def select_family(fits: Mapping[str, Any], admissible: Mapping[str, Any]) -> tuple[str, str | None]:
    """The selected family and, when BIC alone would have chosen another, why not.

    Parameters
    ----------
    fits : mapping of str to OEFit
        Each family's fit (``bic``, ``n_params``, ``heldout_rms``: None when not computed
        or diverged).
    admissible : mapping of str to Admissibility
        Each family's :func:`~hystdisc.simulation.admissibility.check_admissible` outcome
        (``ok``, ``violations``).

    Returns
    -------
    pick : str
    note : str or None
        None when BIC alone picks the same family.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> fits = {"dahl": NS(bic=-300.0, n_params=10, heldout_rms=2e-3),
    ...         "lugre": NS(bic=-200.0, n_params=12, heldout_rms=1e-3)}
    >>> ok = NS(ok=True, violations=[])
    >>> select_family(fits, {"dahl": ok, "lugre": ok})[1]
    "BIC prefers dahl, but its held-out error 0.002 is 100 % above lugre's 0.001: lugre selected"
    """
    bics = {n: f.bic for n, f in fits.items()}

    def by_bic(names):
        bmin = min(bics[n] for n in names)
        close = [n for n in names if bics[n] - bmin < SELECTION_TIE_BIC]
        return min(close, key=lambda n: (fits[n].n_params, bics[n]))

    bic_pick = by_bic(list(fits))
    pool = [n for n in fits if admissible[n].ok] or list(fits)
    held = {n: fits[n].heldout_rms for n in pool if fits[n].heldout_rms is not None}
    if held:
        best = min(held.values())
        pool = [n for n in held if held[n] <= HELDOUT_CLEARLY_WORSE * best]
    pick = by_bic(pool)
    if pick == bic_pick:
        return pick, None
    h0, h1 = fits[bic_pick].heldout_rms, fits[pick].heldout_rms
    if not admissible[bic_pick].ok:
        why = f"it is not physical ({admissible[bic_pick].violations[0]})"
    elif h0 is None:
        why = "its held-out prediction diverged"
    else:
        why = f"its held-out error {h0:.4g} is {100 * (h0 / h1 - 1):.0f} % above {pick}'s {h1:.4g}"
    return pick, f"BIC prefers {bic_pick}, but {why}: {pick} selected"
