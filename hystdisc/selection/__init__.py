"""Choosing among fits: the family, the current laws, the seed's staged flowchart.

:func:`~hystdisc.selection.families.select_family` picks a family from the table by
held-out error, admissibility and BIC; :mod:`hystdisc.selection.laws` chooses a current
law (linear, quadratic, saturating) by leaving one current level out; and
:func:`~hystdisc.selection.staged.staged_fit` runs the seed's flowchart (0 A first, then
each current level).
"""

from hystdisc.selection.families import select_family
from hystdisc.selection.staged import MIN_STAGED_LEVELS, StagedFit, staged_fit

__all__ = ["MIN_STAGED_LEVELS", "StagedFit", "select_family", "staged_fit"]
