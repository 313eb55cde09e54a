"""Variable projection: the shape constants of a hysteresis shape by least squares.

Given the shape constants, ``z`` is integrated from the velocity record and the torque
side is linear in its coefficients; the coefficients are projected out by least squares
at every evaluation, and the shape constants minimize the residual (a grid, then
Nelder-Mead on the log residual sum of squares).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize

from hystdisc.discovery.data import EqData
from hystdisc.discovery.design import Design
from hystdisc.models.shapes import SHAPES


def scaled_lstsq(F: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares through the (small) Gram matrix of scaled columns.

    Returns
    -------
    coefs : ndarray
        The coefficients of the columns of ``F``.
    rss : float
        The residual sum of squares.

    Examples
    --------
    >>> F = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    >>> c, rss = scaled_lstsq(F, F @ np.array([3.0, -1.0]))
    >>> np.round(c, 12).tolist(), rss < 1e-20
    ([3.0, -1.0], True)
    """
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


def varpro(
    eq: EqData, shape_name: str, terms: Sequence[str], s0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """Shape constants minimizing the torque-side least-squares residual.

    Grid (or ``s0``), then Nelder-Mead on the log residual sum of squares; the torque-side
    coefficients are projected out by least squares at every evaluation.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    shape_name : str
        Key of :data:`~hystdisc.models.shapes.SHAPES`.
    terms : sequence of str
        Torque terms (the design's columns).
    s0 : ndarray, optional
        Start of the local search instead of the shape's grid.

    Returns
    -------
    s : ndarray
        The shape constants.
    coefs : ndarray
        The coefficients of the design's columns (``J`` first when it is identifiable).
    rss : float
        The residual sum of squares.
    """
    shape = SHAPES[shape_name]
    design = Design(eq, terms)
    if not shape.shape_names:
        c, rss = scaled_lstsq(*design.build_flat(eq.z_flat(shape, np.zeros(0)), copy=False))
        return np.zeros(0), c, rss

    obj = _objective(eq, shape, design)
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
    c, rss = scaled_lstsq(*design.build_flat(eq.z_flat(shape, s), copy=False))
    return s, c, rss


def _objective(eq: EqData, shape, design: Design):
    """The torque-side RSS as a function of the shape constants (1e300 where z blows up)."""

    def obj(s):
        s = shape.clip(s, eq.scale)
        with np.errstate(all="ignore"):
            z = eq.z_flat(shape, s)
            if not np.all(np.isfinite(z)) or np.abs(z).max() > 1e6:
                return 1e300
            return scaled_lstsq(*design.build_flat(z, copy=False))[1]

    return obj


def grid_minima(
    eq: EqData, shape_name: str, terms: Sequence[str], k: int, min_dist: float = 1.0
) -> list[np.ndarray]:
    """The ``k`` points of the shape's grid with the lowest torque-side RSS, each at least
    ``min_dist`` (max-norm, in the shape's own coordinates: log rates, splits, log
    exponents) from every better one: the starts of distinct basins.

    Examples
    --------
    A driven record of a damper whose torque is ``0.5 tanh(5 theta_dot)``:

    >>> t = np.linspace(0.0, 4.0, 801)
    >>> th, w = np.sin(3 * t), 3 * np.cos(3 * t)
    >>> eq = EqData("driven", [t], [th], [w], [0 * t], [0.5 * np.tanh(5 * w)],
    ...             np.array([0.0]), [np.ones(t.size, dtype=bool)])
    >>> pts = grid_minima(eq, "dahl", ["theta", "theta_dot", "z"], 3)
    >>> len(pts), all(abs(a[0] - b[0]) >= 1.0 for a, b in zip(pts, pts[1:]))
    (3, True)
    """
    shape = SHAPES[shape_name]
    if not shape.shape_names:
        return [np.zeros(0)]
    obj = _objective(eq, shape, Design(eq, terms))
    grid = [np.asarray(g, dtype=float) for g in shape.grid(eq.scale)]
    vals = np.array([obj(g) for g in grid])
    out: list[np.ndarray] = []
    for i in np.argsort(vals):
        if vals[i] >= 1e300:
            break
        if all(np.max(np.abs(grid[i] - o)) >= min_dist for o in out):
            out.append(grid[i])
        if len(out) == k:
            break
    return out


def coef_dict(eq: EqData, terms: Sequence[str], c: np.ndarray) -> tuple[dict[str, float], float]:
    """The torque coefficients by term and ``J`` (1 unless the inertia is identifiable)."""
    off = 1 if eq.experiment_type.inertia_identifiable else 0
    J = float(c[0]) if off else 1.0
    return {t: float(v) for t, v in zip(terms, c[off:], strict=True)}, J
