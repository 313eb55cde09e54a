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
the law, :func:`choose_law`); :class:`LawParametrization` is the joint output-error fit
of every run with the chosen laws.

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
from hystdisc.fitting.parametrization import Parametrization

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
#: family selection's rule, ``HELDOUT_CLEARLY_WORSE``).
SIMPLER_WITHIN = 1.1
#: The linear law is kept without a contest when it predicts the left-out levels within
#: their uncertainty: the chi-square test of its leave-one-level-out errors (each over the
#: level's variance plus the prediction's) has a p-value of at least this.
LINEAR_P = 0.05
#: Range of the saturation current searched, in units of the largest current.
I0_RANGE = (0.02, 50.0)
#: Interval floor, relative to the largest |value| (an interval of 0 would let one level
#: decide everything).
SE_FLOOR = 1e-3


def law_value(law: str, coefs: Mapping[str, float], i) -> np.ndarray | float:
    """The law's value at current(s) ``i`` for coefficients ``{a, b[, q | i0]}``.

    Examples
    --------
    >>> law_value("quadratic", {"a": 1.0, "b": 2.0, "q": -1.0}, 2.0)
    1.0
    """
    a, b = coefs["a"], coefs["b"]
    i = np.asarray(i, dtype=float)
    if law == "linear":
        out = a + b * i
    elif law == "quadratic":
        out = a + b * i + coefs["q"] * i * i
    elif law == "saturating":
        out = a + b * coefs["i0"] * np.tanh(i / coefs["i0"])
    else:
        raise HystdiscError(f"unknown current law '{law}'; fix: use one of {', '.join(LAWS)}")
    return out if np.ndim(out) else float(out)
    raise HystdiscError(f"unknown current law '{law}'; fix: use one of {', '.join(LAWS)}")


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
    family's names; the extra coefficient is ``<key>_i2`` or ``<key>_i0``)."""
    extra = {"linear": [], "quadratic": [f"{key}_i2"], "saturating": [f"{key}_i0"]}[law]
    return [passive, slope, *extra]


class LawParametrization(Parametrization):
    """A family's joint fit over every run with a current law per parameter.

    The free parameters are the shared ones (every parameter of ``base`` that is not the
    passive parameter of a law) and each law's coefficients (:func:`law_names`). A run's
    model is the family at its current: the law parameters evaluated by their laws, the
    per-ampere slopes at 0 (:meth:`run_model`, the one place that makes it; ``base``
    decides what a model is, so a state-space family's :class:`SystemParametrization`
    plugs in as well as a :class:`FamilyParametrization`).

    Parameters
    ----------
    base : Parametrization
        The family at one current: its current-dependent parameters fixed at 0
        (``fixed``), so that its passive parameters are the values at the current.
    laws : dict
        Law name (a key of the family's ``current_laws``) -> law (a key of :data:`LAWS`).
    start : dict
        Start values: shared parameters by name, law coefficients by :func:`law_names`.

    Examples
    --------
    >>> from hystdisc.fitting import FamilyParametrization
    >>> base = FamilyParametrization("bouc-wen-std", "driven", {},
    ...                              fixed={"alpha_2": 0.0, "c_2": 0.0})
    >>> par = LawParametrization(base, {"alpha": "saturating", "c": "linear"},
    ...                          {"alpha_1": 1.0, "alpha_2": 2.0, "alpha_i0": 0.5})
    >>> par.names
    ['beta', 'gamma', 'n', 'k_s', 'alpha_1', 'alpha_2', 'alpha_i0', 'c_1', 'c_2']
    >>> round(par.values_at(par.params(par.x0), 0.5)["alpha_1"], 4)
    1.7616
    """

    def __init__(
        self, base: Parametrization, laws: Mapping[str, str], start: Mapping[str, float]
    ) -> None:
        self.base = base
        family = base.family if hasattr(base, "family") else base.system
        declared = dict(family.current_laws)
        unknown = [k for k in laws if k not in declared]
        if unknown:
            raise HystdiscError(
                f"{family.name} has no current law '{unknown[0]}'; fix: use one of "
                f"{', '.join(declared) or '(none)'}"
            )
        self.family = family
        self.laws = {k: laws[k] for k in declared if k in laws}
        passives = {declared[k][0] for k in self.laws}
        spec = dict(zip(base.names, zip(base.lower, base.upper, strict=True), strict=True))
        bounds = {p.name: (p.lower, p.upper) for p in family.params}
        names, lo, hi, x0 = [], [], [], []
        b0 = base.params(base.x0)
        for n in base.names:
            if n not in passives:
                names.append(n)
                lo.append(spec[n][0])
                hi.append(spec[n][1])
                x0.append(start.get(n, b0[n]))
        self.coef_names: dict[str, list[str]] = {}
        for key, law in self.laws.items():
            passive, slope = declared[key]
            cn = law_names(key, passive, slope, law)
            self.coef_names[key] = cn
            extra = {
                "linear": [],
                "quadratic": [(-np.inf, np.inf)],
                "saturating": [(1e-6, np.inf)],
            }[law]
            for name, (lo_k, hi_k) in zip(
                cn, [spec[passive], bounds.get(slope, (-np.inf, np.inf)), *extra], strict=True
            ):
                names.append(name)
                lo.append(lo_k)
                hi.append(hi_k)
                default = {"quadratic": 0.0, "saturating": 1.0}.get(law, 0.0)
                x0.append(start.get(name, b0.get(name, default)))
        self.names = names
        self.lower = np.array(lo, dtype=float)
        self.upper = np.array(hi, dtype=float)
        x0 = np.clip(np.asarray(x0, dtype=float), self.lower, self.upper)
        self.x0 = x0
        self.normalization = getattr(base, "normalization", "")
        self.declared = declared

    def params(self, x: np.ndarray) -> dict[str, float]:
        return dict(zip(self.names, map(float, x), strict=True))

    def coefs(self, p: Mapping[str, float], key: str) -> dict[str, float]:
        """The coefficients ``{a, b[, q | i0]}`` of law ``key`` in the parameters ``p``."""
        cn = self.coef_names[key]
        c = {"a": p[cn[0]], "b": p[cn[1]]}
        law = self.laws[key]
        if law != "linear":
            c[LAWS[law][2]] = p[cn[2]]
        return c

    def values_at(self, p: Mapping[str, float], current: float) -> dict[str, float]:
        """The base's parameters at ``current``: shared values, law values for the
        passive parameters (the slopes stay at the base's fixed 0)."""
        out = {n: p[n] for n in self.base.names if n in p}
        for key, law in self.laws.items():
            out[self.declared[key][0]] = float(law_value(law, self.coefs(p, key), current))
        return out

    def run_model(self, p: Mapping[str, float], current: float):
        """The family's model at ``current`` (what ``base.simulate`` takes)."""
        q = self.values_at(p, current)
        return self.base.model(np.array([q[n] for n in self.base.names], dtype=float))

    def model(self, x: np.ndarray):
        return self.params(x)

    def terms(self, x: np.ndarray):
        raise HystdiscError(
            "a fit with current laws has one model per current, not one term model; fix: "
            "use terms_at(x, current)"
        )

    def terms_at(self, x: np.ndarray, current: float):
        """The model at ``current`` for the free vector ``x``."""
        return self.run_model(self.params(x), current)

    def has_state(self) -> bool:
        return self.base.has_state()

    def simulate(self, data, models, runs, nuis, status_out=None, work_out=None):
        resolved = [
            self.run_model(p, float(data.currents[r])) for p, r in zip(models, runs, strict=True)
        ]
        return self.base.simulate(data, resolved, runs, nuis, status_out, work_out)
