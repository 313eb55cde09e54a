"""Term selection of stage 1 for one hysteresis shape: :func:`fit_shape`.

The shape constants are found by variable projection (:func:`~hystdisc.discovery.varpro.
varpro`), the torque terms are selected by pysindy's STLSQ along a threshold path scored
by the BIC (:func:`hystdisc.stats.bic`, on the effective number of samples), and the shape
is re-optimized with the selected terms (see doc/design.rst, section 4, step 3).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pysindy as ps

from hystdisc.discovery.data import EqData
from hystdisc.discovery.design import Design
from hystdisc.discovery.library import torque_terms_for
from hystdisc.discovery.varpro import coef_dict, scaled_lstsq, varpro
from hystdisc.models import HYSTERESIS_TERM_NAMES, TermModel
from hystdisc.models.shapes import SHAPES
from hystdisc.stats import bic

#: Equation-error fits better than this (relative RSS; 1e-4 relative RMS) are equally exact:
#: on clean data the residual is differentiation error (~1e-10), which extra terms would soak up.
EQ_RSS_FLOOR = 1e-8

#: warnings.catch_warnings and the ensemble's use of numpy's global generator change
#: process-wide state: one thread at a time.
_WARN_LOCK = threading.Lock()


@dataclass
class ShapeFit:
    """Stage-1 result for one hysteresis shape.

    Attributes
    ----------
    shape : str
        Name of the hysteresis shape.
    s : ndarray
        Its shape constants.
    terms : list of str
        The selected torque terms.
    coefs : dict
        Their coefficients.
    J : float
        Inertia (1 unless it is identifiable).
    rss : float
        Equation-error residual sum of squares.
    bic : float
        Equation-error BIC.
    path : list of dict
        The threshold path: ``threshold``, ``coefs`` and ``bic`` of each point.
    inclusion : dict, optional
        Inclusion probability of each term (with ``ensemble``).
    """

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
        """The fitted structure in the term form."""
        sh = SHAPES[self.shape]
        b, n = sh.vector(self.s)
        hyst = {k: float(v) for k, v in zip(HYSTERESIS_TERM_NAMES, b, strict=True) if v != 0.0}
        return TermModel(dict(self.coefs), hyst, n, self.J)


def fit_shape(
    eq: EqData,
    shape_name: str,
    terms: Sequence[str],
    threshold: float | None = None,
    ensemble: bool = False,
    seed: int = 0,
) -> ShapeFit:
    """Stage 1 for one hysteresis shape: variable projection + STLSQ term selection.

    Parameters
    ----------
    eq, shape_name
        As in :func:`varpro`.
    terms : sequence of str
        The torque library (the z terms are dropped for a shape without state).
    threshold : float, optional
        Fixed STLSQ threshold on normalized columns; default: the point of lowest BIC on
        a path of thresholds from plain least squares.
    ensemble : bool
        Also estimate inclusion probabilities (:func:`inclusion`).
    seed : int
        Seed of the ensemble's resampling.

    Returns
    -------
    ShapeFit
    """
    terms = torque_terms_for(shape_name, terms)
    shape = SHAPES[shape_name]
    s, c, rss = varpro(eq, shape_name, terms)
    F, y = Design(eq, terms).build_flat(eq.z_flat(shape, s))
    off = 1 if eq.experiment_type.inertia_identifiable else 0
    sc = np.sqrt((F**2).mean(axis=0))
    sc[sc == 0] = 1.0
    ys = np.sqrt((y**2).mean()) or 1.0
    Fn = F / sc
    n = y.size
    n_eff = eq.n_eff(n)
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
        cs, r2 = scaled_lstsq(F[:, support], y)
        k = int(support.sum()) + len(shape.shape_names)
        b = bic(r2, n, k, n_eff=n_eff, floor=EQ_RSS_FLOOR * eq.yy)
        full = np.zeros(len(names))
        full[support] = cs
        path.append(
            {"threshold": th, "coefs": dict(zip(names, map(float, full), strict=True)), "bic": b}
        )
        if best is None or b < best[0] - 1e-9:
            best = (b, support.copy(), th)
    _, support, th_best = best
    sel = [t for t, on in zip(terms, support[off:], strict=True) if on]
    # re-optimize the shape with the selected terms
    s2, c2, rss2 = varpro(eq, shape_name, sel, s0=s)
    coefs, J = coef_dict(eq, sel, c2)
    k = len(sel) + off + len(shape.shape_names)
    probs = inclusion(F, y, names, th_best, seed) if ensemble else None
    b2 = bic(rss2, n, k, n_eff=n_eff, floor=EQ_RSS_FLOOR * eq.yy)
    return ShapeFit(shape_name, s2, sel, coefs, J, rss2, b2, path, probs)


def inclusion(
    F: np.ndarray,
    y: np.ndarray,
    names: Sequence[str],
    threshold: float,
    seed: int,
    n_models: int = 40,
) -> dict[str, float]:
    """Inclusion probability of each term over bootstrap resamples (pysindy EnsembleOptimizer).

    pysindy's ``EnsembleOptimizer`` (2.x) takes no random state: it draws its resamples
    from numpy's global generator. The draws are made from the generator seeded with
    ``seed``, under the module's lock, and the generator's state is restored afterwards,
    so a caller's own draws from ``np.random`` are not moved (code drawing from it on
    another thread at the same moment would still interleave with these draws).
    """
    sc = np.sqrt((F**2).mean(axis=0))
    sc[sc == 0] = 1.0
    ys = np.sqrt((y**2).mean()) or 1.0
    opt = ps.EnsembleOptimizer(
        opt=ps.STLSQ(threshold=threshold, alpha=1e-10, unbias=True), bagging=True, n_models=n_models
    )
    seeded_fit(opt, F / sc, y / ys, seed)
    coefs = np.array([np.asarray(c).ravel() for c in opt.coef_list])
    p = (np.abs(coefs) > 0).mean(axis=0)
    return dict(zip(names, map(float, p), strict=True))


def seeded_fit(opt, X: np.ndarray, y: np.ndarray, seed: int):
    """``opt.fit(X, y)`` for a pysindy optimizer that draws from numpy's global generator
    (``EnsembleOptimizer``): seeded with ``seed``, under the module's lock, warnings
    silenced, and the generator's state restored afterwards (:func:`global_seed`)."""
    with _WARN_LOCK, warnings.catch_warnings(), global_seed(seed):
        warnings.simplefilter("ignore")
        return opt.fit(X, y)


@contextmanager
def global_seed(seed: int) -> Iterator[None]:
    """numpy's global generator seeded with ``seed`` inside the block, its state as it was
    before the block afterwards."""
    saved = np.random.get_state()  # noqa: NPY002 - pysindy's ensemble draws from it
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(saved)  # noqa: NPY002
