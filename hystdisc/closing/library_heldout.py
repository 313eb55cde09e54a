"""The open library's stable terms judged on held-out conditions.

:func:`heldout_terms` leaves each test condition out in turn, refits the model's own
columns (its sensitivities at the optimum: one Gauss-Newton step of its parameters) with
and without the terms on the other conditions, and predicts the left-out one:
:class:`HeldOutTerms` is the verdict the open library
(:mod:`hystdisc.closing.open_library`) reports beside a driven test's terms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class HeldOutTerms:
    """The stable terms of the open library judged on held-out conditions: each condition
    left out in turn, the model's parameters and the terms' coefficients refitted on the
    others by one Gauss-Newton step from the fit's optimum (the model linearized there),
    the left-out condition predicted; the same without the terms is the reference.

    The term set itself was chosen on all the data; the refits are what is held out.

    Attributes
    ----------
    before, after : float
        The pooled held-out RMS without and with the terms (the output's units).
    folds : int
        The held-out conditions.
    lower : int
        The conditions the terms predict better.

    Examples
    --------
    >>> HeldOutTerms(62.1, 55.0, 6, 6).sentence()
    'held out (each condition left out, refitted with the model): 62.1 -> 55 (lower in 6 of 6 conditions)'
    """

    before: float
    after: float
    folds: int
    lower: int

    def sentence(self) -> str:
        """One line: the held-out RMS without and with the terms."""
        return (
            f"held out (each condition left out, refitted with the model): "
            f"{self.before:.4g} -> {self.after:.4g} (lower in {self.lower} of {self.folds} "
            "conditions)"
        )

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        return {"before": self.before, "after": self.after, "folds": self.folds,
                "lower": self.lower}  # fmt: skip


def heldout_terms(
    G: np.ndarray, r: np.ndarray, A: np.ndarray, fold: np.ndarray
) -> HeldOutTerms | None:
    """The columns ``G`` (selected terms) judged on held-out folds of the rows.

    Each fold's rows are left out in turn; on the other rows the residual ``r`` is
    regressed by least squares on the model's own columns ``A`` (its sensitivities at the
    optimum: one Gauss-Newton step of its parameters), without and with ``G``, and the
    fold's rows are predicted by each.

    Parameters
    ----------
    G : ndarray (rows, terms)
        The terms' columns.
    r : ndarray
        The residual, measured minus modelled.
    A : ndarray (rows, k)
        The model's own columns; a column zero on the training rows (a left-out run's
        initial state) is left out of that fold's refit.
    fold : ndarray of int
        Each row's fold.

    Returns
    -------
    HeldOutTerms or None
        None for fewer than two folds.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(size=(600, 1)); g = np.tanh(3 * x)
    >>> r = 0.5 * g[:, 0] + 0.01 * rng.normal(size=600)  # x alone leaves 0.20
    >>> h = heldout_terms(g, r, x, np.repeat([0, 1, 2], 200))
    >>> round(h.before, 2), round(h.after, 3), h.lower, h.folds
    (0.2, 0.01, 3, 3)
    """
    labels = np.unique(fold)
    if labels.size < 2:
        return None
    sq0 = sq1 = 0.0
    lower = 0
    for f in labels:
        out = fold == f
        train = ~out
        keep = np.any(A[train] != 0.0, axis=0)
        without = A[:, keep]
        with_terms = np.column_stack([without, G])
        e = []
        for B in (without, with_terms):
            sc = np.sqrt(np.mean(B[train] ** 2, axis=0))
            sc[sc == 0] = 1.0
            c, *_ = np.linalg.lstsq(B[train] / sc, r[train], rcond=1e-12)
            e.append(r[out] - (B[out] / sc) @ c)
        s0, s1 = float(e[0] @ e[0]), float(e[1] @ e[1])
        sq0, sq1, lower = sq0 + s0, sq1 + s1, lower + int(s1 < s0)
    n = int(fold.size)
    return HeldOutTerms(float(np.sqrt(sq0 / n)), float(np.sqrt(sq1 / n)), int(labels.size), lower)
