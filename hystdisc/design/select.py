"""Choosing runs: greedy interval shrinking, and separating families that fit equally well.

The 95 % intervals after a set of runs are predicted from the information of the runs
the fit saw plus theirs (:func:`interval_widths`: ``2 z95 sqrt(diag(G F^+ G^T))``, ``G``
the derivative of the reported parameters by the free ones). :func:`greedy` adds, run
after run, the candidate that most lowers the widest interval relative to its value.
:func:`separation` ranks candidates by how far apart two fitted families' outputs would
be on them, in noise units: ``sum((y_a - y_b)^2) / sigma^2``, the expected log-likelihood
ratio of one run (about 10 or more: the run tells them apart).

Examples
--------
>>> import numpy as np
>>> F0 = np.diag([100.0, 1.0])
>>> cands = np.array([np.diag([1.0, 0.0]), np.diag([0.0, 3.0])])
>>> widths = lambda F: 2 * 1.96 / np.sqrt(np.diag(F))
>>> objective = lambda F: float(np.max(widths(F)))
>>> greedy(F0, cands, objective, budget=2)[0]
[1, 1]
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hystdisc.design.information import Z95
from hystdisc.fitting import Parametrization


def covariance(F: np.ndarray) -> np.ndarray:
    """The covariance ``F^+`` of an information matrix, computed column-scaled as the
    fitter does (directions below ``1e-10`` of the largest singular value are dropped).

    Examples
    --------
    >>> covariance(np.diag([4.0, 0.25])).tolist()
    [[0.25, 0.0], [0.0, 4.0]]
    """
    d = np.sqrt(np.clip(np.diag(F), 0.0, None))
    d[d == 0] = 1.0
    ev, V = np.linalg.eigh(F / np.outer(d, d))
    s = np.sqrt(np.clip(ev, 0.0, None))
    keep = s > (s.max() * 1e-10 if s.size else 0.0)
    inv = np.where(keep, 1.0 / np.where(keep, ev, 1.0), 0.0)
    return (V * inv) @ V.T / np.outer(d, d)


def parameter_gradient(par: Parametrization, x: np.ndarray, keys: list[str]) -> np.ndarray:
    """``d p / d x`` of the reported parameters ``keys`` (free and derived) by the free
    vector, by forward differences (the fitter's step, ``1e-7 max(|x|, 1e-6)``)."""
    p = par.params(x)
    G = np.zeros((len(keys), len(x)))
    for j in range(len(x)):
        h = 1e-7 * max(abs(x[j]), 1e-6)
        xj = x.copy()
        xj[j] += h
        pj = par.params(xj)
        G[:, j] = [(pj[k] - p[k]) / h for k in keys]
    return G


def interval_widths(F: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Widths of the 95 % intervals of the reported parameters for information ``F``.

    Examples
    --------
    >>> interval_widths(np.diag([4.0, 1.0]), np.eye(2)).round(4).tolist()
    [1.96, 3.9199]
    """
    cov = G @ covariance(F) @ G.T
    return 2 * Z95 * np.sqrt(np.clip(np.diag(cov), 0.0, None))


def greedy(
    F0: np.ndarray,
    candidates: np.ndarray,
    objective: Callable[[np.ndarray], float],
    budget: int,
) -> tuple[list[int], list[float]]:
    """Pick ``budget`` runs one after another, each the candidate that most lowers
    ``objective`` of the accumulated information (a candidate may be picked again: a
    repeat of the best run).

    Parameters
    ----------
    F0 : ndarray
        Information already in hand, ``(k, k)``.
    candidates : ndarray
        Each candidate's information, ``(n, k, k)``.
    objective : callable
        Information -> the number to lower (the widest relative interval).
    budget : int
        Runs to pick.

    Returns
    -------
    picks : list of int
        The chosen candidates, in order.
    values : list of float
        ``objective`` after each pick.
    """
    F = F0.copy()
    picks: list[int] = []
    values: list[float] = []
    for _ in range(budget):
        scores = [objective(F + Fc) for Fc in candidates]
        best = int(np.argmin(scores))
        picks.append(best)
        values.append(float(scores[best]))
        F = F + candidates[best]
    return picks, values


def separation(
    y_a: list[np.ndarray], y_b: list[np.ndarray], masks: list[np.ndarray], sigma: float
) -> np.ndarray:
    """How far apart two models' outputs are on each run, in noise units:
    ``sum((y_a - y_b)^2) / sigma^2`` over the samples a fit would use.

    Examples
    --------
    >>> separation([np.zeros(4)], [np.full(4, 0.5)], [np.ones(4, bool)], 0.5).tolist()
    [4.0]
    """
    out = []
    for a, b, m in zip(y_a, y_b, masks, strict=True):
        d = (np.asarray(a) - np.asarray(b))[m]
        out.append(float(d @ d) / sigma**2 if np.all(np.isfinite(d)) else 0.0)
    return np.array(out)
