"""Current laws: how a family's current-dependent parameters follow the coil current.

A family declares its current laws (:attr:`hystdisc.models.Family.current_laws`): a law
name -> (passive parameter, per-ampere slope), e.g. Bouc-Wen's ``alpha`` ->
``("alpha_1", "alpha_2")``. Three laws are candidates for the value ``v(i)`` of such a
parameter at current ``i`` (``a`` = the passive parameter, ``b`` = the slope parameter,
both keep their family names):

============  ==============================  =========================================
law           ``v(i)``                        extra coefficient
============  ==============================  =========================================
linear        ``a + b i``                     none (the seed's law)
quadratic     ``a + b i + q i^2``             ``<law>_i2`` (unit per A^2)
saturating    ``a + b i0 tanh(i / i0)``       ``<law>_i0`` (A): slope ``b`` at 0 A,
                                              level ``a + b i0`` at large currents
============  ==============================  =========================================

The saturating law is written with the slope at 0 A so that it is nested in the linear
one (``i0 -> infinity``); ``a + B tanh(i / i0)`` is the same law with ``B = b i0``.

:func:`fit_law` fits a law to per-level values weighted by their intervals;
:func:`loo_error` predicts each level from the others (the held-out error that chooses
the law, :func:`choose_law`). The joint output-error fit of every run with the chosen
laws is the family's own parametrization with those laws
(:class:`~hystdisc.fitting.FamilyParametrization` ``laws=``): the laws are part of the
family's model (:meth:`hystdisc.models.Family.law_value`).

Examples
--------
>>> import numpy as np
>>> i = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
>>> v = 100 + 1000 * 0.4 * np.tanh(i / 0.4)
>>> c = fit_law("saturating", i, v, np.ones(5))
>>> round(c["a"], 6), round(c["b"], 3), round(c["i0"], 4)
(100.0, 1000.0, 0.4)
>>> round(law_value("saturating", c, 2.0), 1)
500.0
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import chi2

from hystdisc.errors import HystdiscError
from hystdisc.models import LAW_SUFFIX, current_law

#: The candidate laws, simplest first, and their coefficients.
LAWS: dict[str, tuple[str, ...]] = {
    "linear": ("a", "b"),
    "quadratic": ("a", "b", "q"),
    "saturating": ("a", "b", "i0"),
}
#: Levels a law needs before it is a candidate (quadratic and saturating: 4, so that
#: leaving one out still leaves as many levels as coefficients).
MIN_LEVELS = {"linear": 3, "quadratic": 4, "saturating": 4}
#: A simpler law whose held-out error is within this factor of the best one's wins (the
#: family selection's rule, :data:`~hystdisc.selection.families.HELDOUT_CLEARLY_WORSE`).
SIMPLER_WITHIN = 1.1
#: The linear law is kept without a contest when it predicts the left-out levels within
#: their uncertainty: the chi-square test of its leave-one-level-out errors (each over the
#: level's variance plus the prediction's) has a p-value of at least this.
LINEAR_P = 0.05
#: Range of the saturation current searched, in units of the largest current.
I0_RANGE = (0.02, 50.0)
#: Interval floor, relative to the largest ``|value|`` (an interval of 0 would let one level
#: decide everything).
SE_FLOOR = 1e-3


def law_value(law: str, coefs: Mapping[str, float], i) -> np.ndarray | float:
    """The law's value at current(s) ``i`` for coefficients ``{a, b[, q | i0]}``.

    The law's name is checked here; the value is :func:`hystdisc.models.current_law`,
    the one implementation the families use too.

    Examples
    --------
    >>> law_value("quadratic", {"a": 1.0, "b": 2.0, "q": -1.0}, 2.0)
    1.0
    """
    if law not in LAWS:
        raise HystdiscError(f"unknown current law '{law}'; fix: use one of {', '.join(LAWS)}")
    q = coefs["q"] if law == "quadratic" else 0.0
    i0 = coefs["i0"] if law == "saturating" else None
    out = current_law(np.asarray(i, dtype=float), coefs["a"], coefs["b"], q=q, i0=i0)
    return out if np.ndim(out) else float(out)


def _wls(X: np.ndarray, v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, float]:
    """Weighted least squares: coefficients and the weighted residual sum of squares."""
    sw = np.sqrt(w)
    beta, *_ = np.linalg.lstsq(X * sw[:, None], v * sw, rcond=None)
    r = (X @ beta - v) * sw
    return beta, float(r @ r)


def fit_law(law: str, i: Sequence[float], v: Sequence[float], se: Sequence[float]) -> dict:
    """Fit ``law`` to values ``v`` at currents ``i`` with standard errors ``se``.

    Weighted least squares (weights ``1/se^2``); the saturating law's ``i0`` is searched
    on a log grid over :data:`I0_RANGE` times the largest current, then refined.
    """
    i = np.asarray(i, dtype=float)
    v = np.asarray(v, dtype=float)
    w = 1.0 / np.square(np.asarray(se, dtype=float))
    one = np.ones_like(i)
    if law == "linear":
        (a, b), _ = _wls(np.column_stack([one, i]), v, w)
        return {"a": float(a), "b": float(b)}
    if law == "quadratic":
        (a, b, q), _ = _wls(np.column_stack([one, i, i * i]), v, w)
        return {"a": float(a), "b": float(b), "q": float(q)}
    if law == "saturating":
        scale = float(np.max(np.abs(i))) or 1.0

        def cost(log_i0):
            i0 = np.exp(log_i0)
            return _wls(np.column_stack([one, i0 * np.tanh(i / i0)]), v, w)[1]

        grid = np.linspace(np.log(I0_RANGE[0] * scale), np.log(I0_RANGE[1] * scale), 61)
        costs = [cost(g) for g in grid]
        k = int(np.argmin(costs))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        best = minimize_scalar(cost, bounds=(lo, hi), method="bounded")
        log_i0 = best.x if best.fun <= costs[k] else grid[k]
        i0 = float(np.exp(log_i0))
        (a, b), _ = _wls(np.column_stack([one, i0 * np.tanh(i / i0)]), v, w)
        return {"a": float(a), "b": float(b), "i0": i0}
    raise HystdiscError(f"unknown current law '{law}'; fix: use one of {', '.join(LAWS)}")


def floored_se(v: Sequence[float], se: Sequence[float]) -> np.ndarray:
    """The standard errors with the floor :data:`SE_FLOOR` (relative to the largest value)."""
    v = np.asarray(v, dtype=float)
    floor = SE_FLOOR * max(float(np.max(np.abs(v))), 1e-300)
    return np.maximum(np.nan_to_num(np.asarray(se, dtype=float), nan=floor), floor)


def loo_error(law: str, i: Sequence[float], v: Sequence[float], se: Sequence[float]) -> dict:
    """Leave one current level out: each level's value predicted by ``law`` fitted to the
    other levels.

    Returns ``{"z": RMS of the errors in units of each level's standard error,
    "rms": RMS error in the parameter's unit, "pred": the predictions}``. ``z`` chooses
    the law (a level known to 1 % counts more than one known to 30 %).
    """
    i = np.asarray(i, dtype=float)
    v = np.asarray(v, dtype=float)
    se = floored_se(v, se)
    pred = np.empty_like(v)
    for k in range(v.size):
        keep = np.arange(v.size) != k
        c = fit_law(law, i[keep], v[keep], se[keep])
        pred[k] = law_value(law, c, float(i[k]))
    e = pred - v
    return {
        "z": float(np.sqrt(np.mean(np.square(e / se)))),
        "rms": float(np.sqrt(np.mean(np.square(e)))),
        "pred": pred.tolist(),
    }


def linear_consistency(i: Sequence[float], v: Sequence[float], se: Sequence[float]) -> float:
    """p-value of the linear law's leave-one-level-out errors (chi-square, one degree of
    freedom per level): each error over its standard deviation, from the left-out level's
    standard error and the variance of the prediction of the weighted fit to the others.

    Examples
    --------
    >>> round(linear_consistency([0, 0.25, 0.5, 0.75, 1], [1, 1.5, 2, 2.5, 3], [0.1] * 5), 3)
    1.0
    >>> linear_consistency([0, 0.25, 0.5, 0.75, 1], [1, 2, 2.4, 2.6, 2.7], [0.01] * 5) < 1e-6
    True
    """
    i = np.asarray(i, dtype=float)
    v = np.asarray(v, dtype=float)
    se = floored_se(v, se)
    X = np.column_stack([np.ones_like(i), i])
    stat = 0.0
    for k in range(v.size):
        keep = np.arange(v.size) != k
        w = 1.0 / se[keep] ** 2
        beta, _ = _wls(X[keep], v[keep], w)
        cov = np.linalg.pinv((X[keep] * w[:, None]).T @ X[keep])
        var = se[k] ** 2 + float(X[k] @ cov @ X[k])
        stat += float((X[k] @ beta - v[k]) ** 2 / var)
    return float(chi2.sf(stat, v.size))


def choose_law(i: Sequence[float], v: Sequence[float], se: Sequence[float]) -> dict:
    """Choose a law for values ``v`` at currents ``i`` by their held-out error.

    Every law with enough levels (:data:`MIN_LEVELS`) is scored by :func:`loo_error`.
    The linear law is kept when it predicts the left-out levels within their uncertainty
    (:func:`linear_consistency` at least :data:`LINEAR_P`: a curvature the intervals do
    not show is not claimed); otherwise the law with the fewest coefficients whose error
    is within :data:`SIMPLER_WITHIN` of the best is chosen (linear when nothing else has
    enough levels).

    Returns
    -------
    dict
        ``law`` (the choice), ``coefs`` (its coefficients fitted to every level),
        ``candidates`` (each law's :func:`loo_error`, or None without enough levels),
        ``linear_p`` (:func:`linear_consistency`).

    Examples
    --------
    >>> i = [0.0, 0.25, 0.5, 0.75, 1.0]
    >>> choose_law(i, [1.0 + 2.0 * x for x in i], [0.01] * 5)["law"]
    'linear'
    """
    n = len(i)
    se_f = floored_se(v, se)
    cand = {law: (loo_error(law, i, v, se_f) if n >= MIN_LEVELS[law] else None) for law in LAWS}
    scored = {k: c["z"] for k, c in cand.items() if c is not None and np.isfinite(c["z"])}
    p_lin = linear_consistency(i, v, se_f) if n >= MIN_LEVELS["linear"] else 1.0
    if not scored or p_lin >= LINEAR_P:
        law = "linear"
    else:
        best = min(scored.values())
        law = next(k for k in LAWS if k in scored and scored[k] <= SIMPLER_WITHIN * best)
    return {
        "law": law,
        "coefs": fit_law(law, i, v, se_f),
        "candidates": cand,
        "linear_p": p_lin,
    }


def law_names(key: str, passive: str, slope: str, law: str) -> list[str]:
    """Free-parameter names of ``law`` for the family law ``key`` (``a``, ``b`` keep the
    family's names; the extra coefficient is ``<key>_i2`` or ``<key>_i0``, the parameter
    a family's model carries: :meth:`hystdisc.models.Family.law_params`)."""
    return [passive, slope, *([key + LAW_SUFFIX[law]] if law in LAW_SUFFIX else [])]
