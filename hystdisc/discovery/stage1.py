"""Two-stage discovery of the hysteresis model: :class:`Discovery`.

Stage 1 (equation error, sparse): ``z`` is never measured, but given the few shape
constants of a hysteresis candidate it is computed from the velocity record by
integrating its rate. For each candidate shape (none, Dahl-type, Bouc-Wen seed form,
Bouc-Wen standard form) the shape constants are found by variable projection (grid, then
Nelder-Mead on the least-squares residual of the torque-side regression), the torque-side
terms are selected by pysindy's STLSQ along a threshold path scored by BIC, and the shapes
are compared by BIC. The winner is the *discovered structure*.

Stage 2 (output error): each family's own structure is fitted by simulating every run
(:mod:`hystdisc.fitting.output_error`), started from a stage-1 fit of that structure; families are
ranked by BIC (nested ties resolved towards fewer parameters) and by leave-one-run-out
held-out RMS.

Examples
--------
>>> from hystdisc.models import Model
>>> from hystdisc.simulation.synth import generate
>>> data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3, noise=1e-3, seed=1)
>>> d = Discovery(families=["dahl", "bingham"], heldout=False).fit(data)
>>> d.family_
'dahl'
>>> bool(d.results_.families["dahl"]["rms"] < 1.2e-3)
True
"""

from __future__ import annotations

import os
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pysindy as ps
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from hystdisc.data import Dataset, distinct_currents, estimate_noise, trim_release, validate
from hystdisc.discovery.differentiation import differentiate
from hystdisc.discovery.library import DEFAULT_TORQUE_TERMS, FAMILY_SHAPE, SHAPES
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.fitting.output_error import (
    FamilyParametrization,
    FitData,
    OEFit,
    OutputErrorFitter,
    TermParametrization,
)
from hystdisc.models import (
    FAMILIES,
    HYSTERESIS_TERM_NAMES,
    SIGN_EPS,
    TORQUE_TERMS,
    Z_TORQUE_TERMS,
    TermModel,
    format_equation,
    get_family,
)
from hystdisc.simulation import concat_runs, integrate_z_flat

ALL_FAMILIES = ("bingham", "dahl", "lugre", "bouc-wen", "bouc-wen-std")
#: Default upper limit of the threads of one discovery.
MAX_THREADS = 4
_SAY_LOCK = threading.Lock()
#: warnings.catch_warnings changes process-wide state: one thread at a time.
_WARN_LOCK = threading.Lock()


def _n_threads(n_jobs: int | None) -> int:
    if n_jobs is not None:
        return max(1, int(n_jobs))
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, MAX_THREADS))


#: Families whose BIC lies within this of the best "fit equally well".
EQUAL_FIT_BIC = 6.0


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
    for name in ALL_FAMILIES:
        ft, _ = _family_terms(name)
        if FAMILY_SHAPE[name] == shape and set(ft) == tset:
            return FAMILIES[name].title if name != "lugre" else "LuGre"
    if shape == "dahl" and tset == {"theta_dot", "z", "i*z", "i*theta_dot"}:
        return "modified Dahl (Dahl + i*theta_dot)"
    return f"{SHAPES[shape].name} hysteresis with torque terms {sorted(tset)}"


def _normalization(name: str, start: dict[str, float]) -> tuple[dict[str, float], str]:
    """Scale of z for the output-error fit of ``name`` started at ``start``.

    Bouc-Wen loops that saturate are fitted with ``z_sat = 1``; loops that never saturate
    (``beta + gamma <= 0``) have no such scale, so z is taken in torque units
    (``alpha_1 = 1``) and the start is rescaled to it.
    """
    fam = FAMILIES[name]
    if not name.startswith("bouc-wen"):
        return start, "z_sat"
    zs = fam.z_sat(start["delta"], start["beta"], start["gamma"], start["n"])
    a = start.get("alpha_1", 0.0)
    if np.isfinite(zs) and zs > 0:
        return start, "z_sat"
    q = dict(start)
    if np.isfinite(a) and a > 0:
        n = start["n"]
        q["delta"] = start["delta"] * a
        q["beta"] = start["beta"] * a ** (1.0 - n)
        q["gamma"] = start["gamma"] * a ** ((1.0 - n) if name == "bouc-wen-std" else -n)
        q["alpha_2"] = start.get("alpha_2", 0.0) / a
    q["alpha_1"] = 1.0
    return q, "alpha_1"


# ----------------------------------------------------------------------------- estimator


class Discovery:
    """Discover the hysteresis model of an MR damper from runs at several currents.

    Parameters
    ----------
    experiment : {'release', 'driven', 'forced'}, optional
        Overrides the dataset's experiment type.
    families : sequence of str, optional
        Families fitted and compared by output error (default: all five).
    model : str, optional
        Declare the family instead of selecting one (it is still compared to no others).
    torque_terms : sequence of str
        Torque-side library (DESIGN.md section 3).
    shapes : sequence of str
        Hysteresis-side candidates for stage 1.
    threshold : float, optional
        Fixed STLSQ threshold (on normalized columns); default: chosen by BIC on a path.
    ensemble : bool
        Also estimate inclusion probabilities with pysindy's ``EnsembleOptimizer``.
    heldout : bool
        Compute leave-one-run-out held-out RMS.
    seed : int
        Seed for the ensemble resampling.
    progress : callable, optional
        Called with short progress messages (the CLI prints them on stderr).
    max_nfev : int
        Limit of simulations of the output-error fit per family.
    close_loop : bool
        After the fit, diagnose the residual against the effect catalogue, add effects
        that improve BIC and test the final residual for whiteness (:mod:`hystdisc.closing.loop`).
    single_current : bool
        Compare the families on runs at one current (a rig without a coil, such as the
        hysteretic benchmark); the current-dependent parameters are fixed at 0. Without it,
        one current is an error unless ``model`` declares the family.
    input_hold : {'cubic', 'linear', 'zoh'}
        Forced experiments: how the input is interpolated between its samples (a cubic
        spline for a sampled smooth force; ``zoh`` for a DAC output held between samples).
    n_jobs : int, optional
        Threads for the independent fits (stage-1 shapes, stage-2 families); default: the
        usable CPUs, at most :data:`MAX_THREADS`. The results do not depend on it.
    """

    def __init__(
        self,
        experiment: str | None = None,
        families: Sequence[str] | None = None,
        model: str | None = None,
        torque_terms: Sequence[str] = DEFAULT_TORQUE_TERMS,
        shapes: Sequence[str] = ("none", "dahl", "bouc-wen", "bouc-wen-std"),
        threshold: float | None = None,
        ensemble: bool = False,
        heldout: bool = True,
        seed: int = 0,
        progress: Callable[[str], None] | None = None,
        max_nfev: int = 40,
        close_loop: bool = True,
        input_hold: str = "cubic",
        single_current: bool = False,
        n_jobs: int | None = None,
    ) -> None:
        self.experiment = experiment
        self.families = families
        self.model = model
        self.torque_terms = torque_terms
        self.shapes = shapes
        self.threshold = threshold
        self.ensemble = ensemble
        self.heldout = heldout
        self.seed = seed
        self.progress = progress
        self.max_nfev = max_nfev
        self.close_loop = close_loop
        self.input_hold = input_hold
        self.n_jobs = n_jobs
        self.single_current = single_current

    # -- helpers
    def _say(self, msg: str) -> None:
        if self.progress is not None:
            with _SAY_LOCK:
                self.progress(msg)

    def _map(self, fn, items: list, serial: bool = False) -> list:
        """``fn`` over ``items`` (independent fits) on up to ``n_jobs`` threads, in order.

        The compiled kernels release the GIL; numpy's error state is per thread, so each
        worker ignores floating-point warnings as the caller does.
        """

        def work(item):
            with np.errstate(all="ignore"):
                return fn(item)

        n = _n_threads(self.n_jobs)
        if serial or n <= 1 or len(items) <= 1:
            return [work(x) for x in items]
        with ThreadPoolExecutor(max_workers=min(n, len(items))) as pool:
            return list(pool.map(work, items))

    def _prepare(self, dataset: Dataset) -> tuple[EqData, FitData]:
        exp = self.experiment or dataset.experiment
        if exp not in ("release", "driven", "forced"):
            raise HystdiscError(
                f"{dataset.source}: unknown experiment type '{exp}'; fix: use release, driven or forced"
            )
        runs = list(dataset.runs)
        if exp == "driven" and any(r.torque is None for r in runs):
            raise HystdiscError(
                f"{dataset.source}: a driven experiment needs a torque column; fix: add it or use "
                "--experiment release"
            )
        if exp == "forced" and any(r.input is None for r in runs):
            raise HystdiscError(
                f"{dataset.source}: a forced experiment needs an input column; fix: add it or use "
                "--experiment release"
            )
        sig = "torque" if exp == "driven" else "theta"
        noises = [estimate_noise(getattr(r, sig), r.fs) for r in runs]
        noise = float(np.median(noises))
        theta_noise = float(np.median([estimate_noise(r.theta, r.fs) for r in runs]))
        if exp == "release":
            runs = [trim_release(r, theta_noise) for r in runs]
        eq_t, eq_th, eq_w, eq_a, eq_y, rows = [], [], [], [], [], []
        fd = FitData(
            exp,
            [r.name for r in runs],
            [],
            [],
            np.array([r.current for r in runs]),
            [],
            [],
            [],
            [],
            noise,
            self.input_hold,
        )
        windows = []
        for r in runs:
            d = differentiate(r.t, r.theta, theta_noise)
            windows.append(d.window)
            if not np.all(np.isfinite(d.theta_dot)) or np.ptp(r.theta) == 0:
                raise HystdiscError(
                    f"{dataset.source}, run {r.name}: the run never moves; fix: remove the run"
                )
            m = np.ones(r.t.size, dtype=bool)
            m[: d.window // 2] = False
            m[-(d.window // 2) or None :] = False
            if exp == "driven":
                # forget the unknown initial z: skip until the motion has swept its range once
                travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(d.theta)))])
                m &= travel >= np.ptp(d.theta)
                if m.sum() < 20:
                    m[:] = True
            eq_t.append(r.t)
            eq_th.append(d.theta)
            eq_w.append(d.theta_dot)
            eq_a.append(d.theta_ddot)
            if exp == "release":
                eq_y.append(-d.theta_ddot)
            elif exp == "driven":
                eq_y.append(np.asarray(r.torque, dtype=float))
            else:
                eq_y.append(np.asarray(r.input, dtype=float))
            rows.append(m)
            fd.t.append(r.t)
            fd.y.append(np.asarray(r.torque if exp == "driven" else r.theta, dtype=float))
            fd.theta.append(d.theta if exp == "driven" else np.asarray(r.theta, dtype=float))
            fd.theta_dot.append(d.theta_dot)
            fd.u.append(np.asarray(r.input, dtype=float) if exp == "forced" else np.zeros(r.t.size))
            fd.mask.append(m if exp == "driven" else np.ones(r.t.size, dtype=bool))
        scale = float(np.median([np.ptp(th) / 2 for th in eq_th])) or 1.0
        # the smoothed signals are band-limited by the window: decimate the equation-error
        # stage (z is still integrated with sub-steps on the decimated grid)
        q = max(1, int(np.median(windows)) // 16)
        qs = [q] * len(runs)
        if exp == "driven":
            # torque is not differentiated; keep ~200 samples per cycle of each run's motion
            qs = [max(1, int(_samples_per_cycle(w) // 200)) for w in eq_w]
            q = max(1, int(np.median(qs)))
        dec = lambda xs: [x[::qk] for x, qk in zip(xs, qs, strict=True)]  # noqa: E731
        eq = EqData(
            exp,
            dec(eq_t),
            dec(eq_th),
            dec(eq_w),
            dec(eq_a),
            dec(eq_y),
            fd.currents,
            dec(rows),
            max(1, int(np.median(windows)) // q),
            scale,
        )
        return eq, fd

    def _family_start(self, eq: EqData, name: str) -> dict[str, float]:
        # the stage-1 search of this shape is the natural start (no second grid search)
        shape = FAMILY_SHAPE[name]
        s0 = self.stage1_[shape].s if shape in getattr(self, "stage1_", {}) else None
        p, _ = family_start(eq, name, s0=s0, one_level=self.single_current_)
        return p

    # -- public API
    def fit(self, dataset: Dataset) -> Discovery:
        """Discover terms, fit the families and select one. Returns ``self``."""
        # small dense algebra on tall matrices: extra BLAS threads only add overhead
        with np.errstate(all="ignore"), threadpool_limits(limits=1):
            return self._fit(dataset)

    def _fit(self, dataset: Dataset) -> Discovery:
        from hystdisc.results import build_results

        if not isinstance(dataset, Dataset):
            raise TypeError(
                "Discovery.fit expects a hystdisc.data.Dataset (see hystdisc.load)"
            )
        if self.model is not None:
            fams = [get_family(self.model).name]
        else:
            fams = [get_family(f).name for f in (self.families or ALL_FAMILIES)]
        # selecting a family needs several currents, unless the user declared the family or
        # asked for a comparison at one current (a rig without a coil, e.g. a benchmark)
        one = self.model is not None or self.single_current
        validate(dataset, need_currents=1 if one else 2)
        self.single_current_ = len(distinct_currents(dataset.currents)) < 2
        if self.single_current_:
            warnings.warn(
                f"{dataset.source}: all runs share one current; the current-dependent "
                "parameters are fixed at 0 and the i* terms left out of the library",
                HystdiscWarning,
                stacklevel=2,
            )
        self._say("preparing data (noise, derivatives)")
        eq, fd = self._prepare(dataset)
        self.experiment_ = eq.experiment
        self.noise_std_ = fd.noise_std
        self.n_runs_ = fd.n_runs
        self.currents_ = fd.currents
        self.window_ = eq.window
        self._eq, self._fd = eq, fd

        # stage 1
        terms = list(self.torque_terms)
        if eq.experiment == "driven" and "theta" not in terms:
            terms = ["theta", *terms]
        if self.single_current_:
            terms = [t for t in terms if not t.startswith("i")]
        # the lazily built arrays the workers share are built before they start
        eq.row_index  # noqa: B018
        fd.bulk()
        if eq.experiment == "forced" and fd.hold == "cubic":
            fd.input_slopes()

        def shape_fit(shape):
            self._say(f"stage 1: sparse regression with hysteresis shape '{shape}'")
            return fit_shape(eq, shape, terms, self.threshold, self.ensemble, self.seed)

        # the ensemble draws from numpy's global generator: one shape after the other
        fits = self._map(shape_fit, list(self.shapes), serial=self.ensemble)
        self.stage1_ = dict(zip(self.shapes, fits, strict=True))
        best = min(self.stage1_.values(), key=lambda f: f.bic)
        self.discovered_shape_ = best.shape
        self.discovered_ = best.term_model()
        self.terms_ = {
            "torque": [t for t in best.terms if not (t == "theta" and eq.experiment != "driven")],
            "hysteresis": list(SHAPES[best.shape].terms),
        }
        self.discovered_name_ = describe_structure(best.terms, best.shape)

        # stage 2: each family by output error (and the discovered structure when it is not
        # one of them), each fit on its own
        same = [
            n
            for n in fams
            if FAMILY_SHAPE[n] == best.shape
            and set(FAMILIES[n].torque_terms) == set(best.terms) - {"theta"}
        ]

        def family_fit(k):
            if k == len(fams):
                self._say("stage 2: output-error fit of the discovered structure")
                tpar = TermParametrization(
                    best.terms, best.shape, best.coefs, best.s, best.J, eq.experiment
                )
                return OutputErrorFitter(fd, tpar, max_nfev=self.max_nfev).fit(heldout=False)
            name = fams[k]
            self._say(f"stage 2: output-error fit of {name} ({k + 1}/{len(fams)})")
            start = self._family_start(eq, name)
            fixed = {p: 0.0 for p in FAMILIES[name].current_params} if self.single_current_ else {}
            start, norm = _normalization(name, start)
            par = FamilyParametrization(name, eq.experiment, start, fixed=fixed, normalization=norm)
            fitter = OutputErrorFitter(fd, par, max_nfev=self.max_nfev)
            return fitter.fit(heldout=self.heldout)

        fits = self._map(family_fit, list(range(len(fams) + (0 if same else 1))))
        self.family_fits_: dict[str, OEFit] = dict(zip(fams, fits, strict=False))
        self.discovered_fit_ = self.family_fits_[same[0]] if same else fits[-1]

        # selection: lowest BIC; within EQUAL_FIT_BIC, fewest parameters wins
        bics = {n: f.bic for n, f in self.family_fits_.items()}
        bmin = min(bics.values())
        close = [n for n, b in bics.items() if b - bmin < 2.0]
        self.family_ = min(close, key=lambda n: (self.family_fits_[n].n_params, bics[n]))
        self.equal_fits_ = sorted(
            n
            for n, b in bics.items()
            if b - bics[self.family_] < EQUAL_FIT_BIC and n != self.family_
        )
        self.declared_ = self.model is not None
        self.results_ = build_results(self, dataset)
        if self.close_loop:
            from hystdisc.closing.loop import close_loop

            self._say("closing the loop: residual -> catalogued effects")
            close_loop(self, dataset)
        return self

    def _check_fitted(self):
        if not hasattr(self, "results_"):
            raise HystdiscError("this Discovery is not fitted yet; fix: call fit(dataset) first")

    @property
    def selected_fit_(self) -> OEFit:
        self._check_fitted()
        return self.family_fits_[self.family_]

    def predict(self, dataset: Dataset, family: str | None = None) -> list[np.ndarray]:
        """Simulate the fitted model on the runs of ``dataset``.

        Without ``family``: the selected family with the effects the closing loop accepted.
        """
        self._check_fitted()
        from hystdisc.fitting.predict import predict_dataset

        if family is None and getattr(self, "final_fit_", None) is not None:
            fit = self.final_fit_  # the selected family with its accepted effects
        else:
            fit = self.family_fits_[family or self.family_]
        return predict_dataset(fit.term_model, dataset, self.experiment_, self.input_hold)

    def score(self, dataset: Dataset) -> float:
        """Coefficient of determination R^2 of the simulated output on ``dataset``."""
        preds = self.predict(dataset)
        meas = [r.torque if self.experiment_ == "driven" else r.theta for r in dataset.runs]
        y = np.concatenate(meas)
        p = np.concatenate(preds)
        return float(1.0 - np.sum((y - p) ** 2) / np.sum((y - y.mean()) ** 2))

    def equations(self) -> str:
        """pysindy-style print of the discovered equations."""
        if not hasattr(self, "discovered_fit_"):
            self._check_fitted()
        tm = self.discovered_fit_.term_model
        lines = [format_equation("T", tm.torque)]
        if tm.hysteresis:
            lines.append(tm.equations().splitlines()[1])
        if self.experiment_ == "forced":
            lines.insert(0, f"J = {tm.J:.4g}")
        return "\n".join(lines)

    def print(self, file=None) -> None:
        """Print the discovered equations (like ``pysindy.SINDy.print``)."""
        print(self.equations(), file=file or sys.stdout)

    def _repr_html_(self) -> str:
        if not hasattr(self, "results_"):
            return "<p>Discovery (not fitted)</p>"
        return self.results_._repr_html_()
