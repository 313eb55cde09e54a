"""Stage 1 of the discovery: the sparse equation-error regression.

Stage 1 (equation error, sparse): ``z`` is never measured, but given the few shape
constants of a hysteresis candidate it is computed from the velocity record by
integrating its rate. For each candidate shape (none, Dahl-type, Bouc-Wen seed form,
Bouc-Wen standard form) the shape constants are found by variable projection (grid, then
Nelder-Mead on the least-squares residual of the torque-side regression), the torque-side
terms are selected by pysindy's STLSQ along a threshold path scored by BIC, and the shapes
are compared by BIC. The winner is the *discovered structure*.

The estimator that runs both stages is :class:`hystdisc.estimator.Discovery`.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pysindy as ps
from scipy.optimize import minimize

from hystdisc.discovery.library import FAMILY_SHAPE, SHAPES
from hystdisc.models import (
    FAMILIES,
    HYSTERESIS_TERM_NAMES,
    SIGN_EPS,
    TORQUE_TERMS,
    Z_TORQUE_TERMS,
    TermModel,
    get_family,
)
from hystdisc.registry import family_names
from hystdisc.simulation import concat_runs, integrate_z_flat

#: warnings.catch_warnings changes process-wide state: one thread at a time.
_WARN_LOCK = threading.Lock()


# ----------------------------------------------------------------------------- stage 1 data


@dataclass
class EqData:
    """Equation-error data of all runs (rows where the equation is evaluated)."""

    experiment: str
    t: list[np.ndarray]
    theta: list[np.ndarray]
    theta_dot: list[np.ndarray]
    theta_ddot: list[np.ndarray]
    target: list[np.ndarray]
    currents: np.ndarray
    rows: list[np.ndarray]  # boolean masks of rows used
    window: int = 1
    scale: float = 1.0  # displacement amplitude

    @property
    def yy(self) -> float:
        """Sum of squares of the regression target over the rows used."""
        return float(sum(np.sum(y[m] ** 2) for y, m in zip(self.target, self.rows, strict=True)))

    @cached_property
    def _flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t, offsets = concat_runs(self.t)
        w, _ = concat_runs(self.theta_dot)
        return t, w, offsets

    @cached_property
    def row_index(self) -> np.ndarray:
        """Indices of the rows used, in the concatenation of all runs' samples."""
        offsets = self._flat[2]
        return np.concatenate(
            [o + np.flatnonzero(m) for o, m in zip(offsets[:-1], self.rows, strict=True)]
        )

    def z_flat(self, shape, s) -> np.ndarray:
        """z of every run for the shape constants ``s``, all runs concatenated."""
        t, w, offsets = self._flat
        if shape.name == "none":
            return np.zeros_like(t)
        b, n = shape.vector(s)
        return integrate_z_flat(b, n, t, w, offsets, SIGN_EPS)

    def z_list(self, shape, s) -> list[np.ndarray]:
        """z of every run for the shape constants ``s`` (zeros for the shape 'none')."""
        z = self.z_flat(shape, s)
        offsets = self._flat[2]
        return [z[a:b] for a, b in zip(offsets[:-1], offsets[1:], strict=True)]

    def design(self, terms: Sequence[str], z_list) -> tuple[np.ndarray, np.ndarray]:
        """Design matrix (``J``'s column first when forced) and target over the rows used."""
        return Design(self, terms).build(z_list)

    def n_eff(self, n: int) -> float:
        """Effective number of independent equation-error samples (smoothing correlates them)."""
        if self.experiment == "driven":
            return float(n)
        return float(n) * 2.0 / max(self.window, 2)


class Design:
    """Design matrix of torque terms on the equation-error rows of all runs.

    The columns that do not depend on ``z`` (and the regression target) are evaluated once;
    :meth:`build` only writes the ``z`` columns, so the shape search of :func:`_varpro`
    costs one ``z`` integration and one small least-squares solve per evaluation. The
    values are exactly those of the terms (:data:`hystdisc.models.TORQUE_TERMS`) evaluated
    on ``[theta, theta_dot, z, i]``, as pysindy's :class:`~hystdisc.discovery.library.TorqueLibrary`
    computes them.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    terms : sequence of str
        Torque terms, in column order (a forced experiment's ``theta_ddot`` column for the
        inertia comes first).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> eq = EqData("driven", [t], [t], [np.ones(5)], [np.zeros(5)], [2 * t],
    ...             np.array([0.5]), [np.ones(5, dtype=bool)])
    >>> F, y = Design(eq, ["theta", "i*z"]).build([np.full(5, 2.0)])
    >>> F[0].tolist(), y.tolist()
    ([0.0, 1.0], [0.0, 0.5, 1.0, 1.5, 2.0])
    """

    def __init__(self, eq: EqData, terms: Sequence[str]) -> None:
        unknown = [t for t in terms if t not in TORQUE_TERMS]
        if unknown:
            raise ValueError(f"unknown torque terms {unknown}; known: {list(TORQUE_TERMS)}")
        self.terms = list(terms)
        self.rows = eq.row_index
        ms = eq.rows
        cat = lambda xs: np.concatenate([x[m] for x, m in zip(xs, ms, strict=True)])  # noqa: E731
        th, w = cat(eq.theta), cat(eq.theta_dot)
        i = np.concatenate([np.full(int(m.sum()), c) for m, c in zip(ms, eq.currents, strict=True)])
        self.y = cat(eq.target)
        off = 1 if eq.experiment == "forced" else 0
        F = np.empty((self.y.size, off + len(self.terms)))
        if off:
            F[:, 0] = cat(eq.theta_ddot)
        self._z_cols = []
        for j, t in enumerate(self.terms):
            if t in Z_TORQUE_TERMS:
                # the z columns are z times a z-free factor (|theta_dot|, i, i^2)
                self._z_cols.append((off + j, TORQUE_TERMS[t](th, w, np.ones_like(th), i)))
            else:
                F[:, off + j] = TORQUE_TERMS[t](th, w, None, i)
        self._F = F

    def build_flat(self, z_flat: np.ndarray, copy: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Design and target for z given on all samples, concatenated (``EqData.z_flat``).

        With ``copy=False`` the returned matrix is overwritten by the next call.
        """
        z = z_flat[self.rows]
        F = self._F
        for j, factor in self._z_cols:
            F[:, j] = factor * z
        return (F.copy() if copy else F), self.y

    def build(self, z_list: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Design and target for z given per run."""
        return self.build_flat(np.concatenate([np.asarray(z, dtype=float) for z in z_list]))


def _samples_per_cycle(w: np.ndarray) -> float:
    """Samples per cycle of a velocity record (from its zero crossings)."""
    sgn = np.signbit(w)
    crossings = np.count_nonzero(sgn[1:] != sgn[:-1])
    return 2.0 * w.size / max(crossings, 1)


def _lstsq(F, y):
    """Least squares through the (small) Gram matrix of scaled columns; returns coefs, RSS."""
    sc = np.sqrt((F**2).mean(axis=0))
    sc[sc == 0] = 1.0
    Fn = F / sc
    G = Fn.T @ Fn
    try:
        c = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(G.shape[0]), Fn.T @ y) / sc
    except np.linalg.LinAlgError:
        c = np.linalg.lstsq(G, Fn.T @ y, rcond=1e-13)[0] / sc
    r = y - F @ c
    return c, float(r @ r)


@dataclass
class ShapeFit:
    """Stage-1 result for one hysteresis shape."""

    shape: str
    s: np.ndarray
    terms: list[str]
    coefs: dict[str, float]
    J: float
    rss: float
    bic: float
    path: list[dict] = field(default_factory=list)
    inclusion: dict[str, float] | None = None

    def term_model(self) -> TermModel:
        sh = SHAPES[self.shape]
        b, n = sh.vector(self.s)
        hyst = {k: float(v) for k, v in zip(HYSTERESIS_TERM_NAMES, b, strict=True) if v != 0.0}
        return TermModel(dict(self.coefs), hyst, n, self.J)


def _varpro(eq: EqData, shape_name: str, terms: Sequence[str], s0=None):
    """Shape constants minimizing the torque-side least-squares residual.

    Grid (or ``s0``), then Nelder-Mead on the log residual sum of squares; the torque-side
    coefficients are projected out by least squares at every evaluation.
    Returns the shape constants, the coefficients and the RSS.
    """
    shape = SHAPES[shape_name]
    design = Design(eq, terms)
    if shape_name == "none":
        c, rss = _lstsq(*design.build_flat(eq.z_flat(shape, np.zeros(0)), copy=False))
        return np.zeros(0), c, rss

    def obj(s):
        s = shape.clip(s, eq.scale)
        with np.errstate(all="ignore"):
            z = eq.z_flat(shape, s)
            if not np.all(np.isfinite(z)) or np.abs(z).max() > 1e6:
                return 1e300
            return _lstsq(*design.build_flat(z, copy=False))[1]

    grid = [s0] if s0 is not None else shape.grid(eq.scale)
    vals = [obj(s) for s in grid]
    best = np.asarray(grid[int(np.argmin(vals))], dtype=float)
    res = minimize(
        lambda s: np.log(obj(s)),
        best,
        method="Nelder-Mead",
        options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 80 * len(best)},
    )
    s = shape.clip(res.x if res.fun <= np.log(min(vals)) else best, eq.scale)
    c, rss = _lstsq(*design.build_flat(eq.z_flat(shape, s), copy=False))
    return s, c, rss


def _coef_dict(eq: EqData, terms, c):
    off = 1 if eq.experiment == "forced" else 0
    J = float(c[0]) if off else 1.0
    return {t: float(v) for t, v in zip(terms, c[off:], strict=True)}, J


#: Equation-error fits better than this (relative RSS; 1e-4 relative RMS) are equally exact:
#: on clean data the residual is differentiation error (~1e-10), which extra terms would soak up.
EQ_RSS_FLOOR = 1e-8


def _eq_bic(eq, rss, n, k):
    ne = eq.n_eff(n)
    floor = EQ_RSS_FLOOR * eq.yy
    return float(ne * np.log(max(rss, floor, 1e-300) / n) + k * np.log(ne))


def fit_shape(
    eq: EqData,
    shape_name: str,
    terms: Sequence[str],
    threshold: float | None = None,
    ensemble: bool = False,
    seed: int = 0,
) -> ShapeFit:
    """Stage 1 for one hysteresis shape: variable projection + STLSQ term selection."""
    from hystdisc.discovery.library import torque_terms_for

    terms = torque_terms_for(shape_name, terms)
    shape = SHAPES[shape_name]
    s, c, rss = _varpro(eq, shape_name, terms)
    F, y = eq.design(terms, eq.z_list(shape, s))
    off = 1 if eq.experiment == "forced" else 0
    sc = np.sqrt((F**2).mean(axis=0))
    sc[sc == 0] = 1.0
    ys = np.sqrt((y**2).mean()) or 1.0
    Fn = F / sc
    n = y.size
    names = (["J"] if off else []) + list(terms)
    thresholds = [threshold] if threshold is not None else list(np.geomspace(1e-4, 0.5, 16))
    path = []
    best = None
    # a fixed threshold is used as given; otherwise the whole path (from plain least squares)
    for th in thresholds if threshold is not None else [0.0, *thresholds]:
        opt = ps.STLSQ(threshold=th, alpha=1e-10, max_iter=50, unbias=True)
        with _WARN_LOCK, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opt.fit(Fn, y / ys)
        coef = np.asarray(opt.coef_).ravel()
        support = np.abs(coef) > 0
        if off:
            support[0] = True  # inertia always
        if not support.any():
            continue
        cs, r2 = _lstsq(F[:, support], y)
        k = int(support.sum()) + len(shape.shape_names)
        bic = _eq_bic(eq, r2, n, k)
        full = np.zeros(len(names))
        full[support] = cs
        path.append(
            {"threshold": th, "coefs": dict(zip(names, map(float, full), strict=True)), "bic": bic}
        )
        if best is None or bic < best[0] - 1e-9:
            best = (bic, support.copy(), th)
    _, support, th_best = best
    sel = [t for t, on in zip(terms, support[off:], strict=True) if on]
    # re-optimize the shape with the selected terms
    s2, c2, rss2 = (
        _varpro(eq, shape_name, sel, s0=s) if shape_name != "none" else _varpro(eq, "none", sel)
    )
    coefs, J = _coef_dict(eq, sel, c2)
    k = len(sel) + off + len(shape.shape_names)
    inclusion = None
    if ensemble:
        inclusion = _inclusion(F, y, names, th_best, seed)
    return ShapeFit(shape_name, s2, sel, coefs, J, rss2, _eq_bic(eq, rss2, n, k), path, inclusion)


def _inclusion(F, y, names, threshold, seed, n_models=40):
    """Inclusion probability of each term over bootstrap resamples (pysindy EnsembleOptimizer)."""
    sc = np.sqrt((F**2).mean(axis=0))
    sc[sc == 0] = 1.0
    ys = np.sqrt((y**2).mean()) or 1.0
    np.random.seed(seed)  # noqa: NPY002 - EnsembleOptimizer draws from numpy's global generator
    opt = ps.EnsembleOptimizer(
        opt=ps.STLSQ(threshold=threshold, alpha=1e-10, unbias=True), bagging=True, n_models=n_models
    )
    with _WARN_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        opt.fit(F / sc, y / ys)
    coefs = np.array([np.asarray(c).ravel() for c in opt.coef_list])
    p = (np.abs(coefs) > 0).mean(axis=0)
    return dict(zip(names, map(float, p), strict=True))


# ----------------------------------------------------------------------------- helpers


def family_start(
    eq: EqData,
    family: str,
    extra_terms: Sequence[str] = (),
    s0: np.ndarray | None = None,
    one_level: bool = False,
    constant: bool = True,
) -> tuple[dict[str, float], dict[str, float]]:
    """Stage-1 (equation-error) start of a family's output-error fit.

    The shape constants of the family's hysteresis shape and the coefficients of its
    torque terms (with the spring ``theta`` and ``extra_terms``, e.g. an effect's) are
    found by variable projection and mapped to the family's parameters, clipped inside
    their bounds. Discovery starts every family's fit from it; the closing loop starts the
    augmented structures from it.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    family : str
        Family name.
    extra_terms : sequence of str
        Torque terms added to the family's (the ones it already has are ignored).
    s0 : ndarray, optional
        Shape constants to start the local search from (skips the grid).
    one_level : bool
        All runs share one current: the ``i*`` terms are left out.
    constant : bool
        Add a constant column for release and forced experiments (keeps an offset in the
        data from corrupting the start: z, integrated from 0, would imitate it).

    Returns
    -------
    params : dict
        Family parameters, ``k_s`` and ``J``.
    coefs : dict
        The fitted torque coefficients by term.

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> from hystdisc.simulation.synth import generate
    >>> from hystdisc.estimator import Discovery
    >>> data = generate(Model("dahl"), currents=(0, 1), duration=3, noise=1e-4, seed=1)
    >>> d = Discovery(); d.single_current_ = False
    >>> eq, _ = d._prepare(data)
    >>> p, _ = family_start(eq, "bingham")
    >>> sorted(p)
    ['J', 'c_a', 'c_b', 'f_a', 'f_b', 'k_s']
    """
    fam = get_family(family)
    ft = [t for t in fam.torque_terms if not (one_level and t.startswith("i"))]
    lead = ["theta", "1"] if constant and eq.experiment != "driven" else ["theta"]
    terms = [*lead, *ft]
    terms += [t for t in dict.fromkeys(extra_terms) if t not in terms]
    shape = FAMILY_SHAPE[fam.name]
    if s0 is not None and len(s0) != len(SHAPES[shape].shape_names):
        s0 = None
    s, c, _ = _varpro(eq, shape, terms, s0=None if s0 is None else np.asarray(s0, dtype=float))
    coefs, J = _coef_dict(eq, terms, c)
    b, n = SHAPES[shape].vector(s)
    hyst = {k: float(v) for k, v in zip(HYSTERESIS_TERM_NAMES, b, strict=True) if v != 0.0}
    with np.errstate(all="ignore"):
        p = fam.from_terms(TermModel(coefs, hyst, n, J))
    p["k_s"] = max(coefs.get("theta", 0.0), 0.0)
    p["J"] = J if J > 0 else 1.0
    # keep the start inside the physical bounds
    for spec in fam.params:
        v = p.get(spec.name, spec.default)
        if not np.isfinite(v):
            v = spec.default
        p[spec.name] = float(np.clip(v, spec.lower, spec.upper))
    return p, coefs


def _family_terms(name: str) -> tuple[list[str], list[str]]:
    fam = FAMILIES[name]
    return list(fam.torque_terms), list(fam.hysteresis_terms)


def describe_structure(torque: Sequence[str], shape: str) -> str:
    """Name a discovered structure after the family it matches (or 'modified Dahl')."""
    tset = {t for t in torque if t not in ("theta", "1")}
    for name in family_names():
        ft, _ = _family_terms(name)
        if FAMILY_SHAPE[name] == shape and set(ft) == tset:
            return FAMILIES[name].title if name != "lugre" else "LuGre"
    if shape == "dahl" and tset == {"theta_dot", "z", "i*z", "i*theta_dot"}:
        return "modified Dahl (Dahl + i*theta_dot)"
    return f"{SHAPES[shape].name} hysteresis with torque terms {sorted(tset)}"
