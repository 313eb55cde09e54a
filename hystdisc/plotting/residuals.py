"""Where the model misses: the residual against displacement and velocity, per current,
with the measurement's repeatability band."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import XLABEL, new_axes

#: Bins of the mean residual along each axis.
BINS = 30


def binned_mean(x: np.ndarray, r: np.ndarray, bins: int = BINS) -> tuple[np.ndarray, np.ndarray]:
    """The mean of ``r`` in ``bins`` equal bins of ``x`` (bin centres, means; empty bins
    left out).

    Examples
    --------
    >>> x = np.linspace(-1, 1, 1001)
    >>> c, m = binned_mean(x, 2 * x, bins=4)
    >>> np.round(c, 2).tolist(), np.round(m, 2).tolist()
    ([-0.75, -0.25, 0.25, 0.75], [-1.5, -0.5, 0.5, 1.5])
    """
    x, r = np.asarray(x, dtype=float), np.asarray(r, dtype=float)
    ok = np.isfinite(x) & np.isfinite(r)
    x, r = x[ok], r[ok]
    if x.size == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.linspace(x.min(), x.max(), bins + 1)
    k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    n = np.bincount(k, minlength=bins)
    s = np.bincount(k, weights=r, minlength=bins)
    centres = 0.5 * (edges[:-1] + edges[1:])
    has = n > 0
    return centres[has], s[has] / n[has]


def plot_residual_map(
    residuals: Sequence[np.ndarray],
    displacement: Sequence[np.ndarray],
    velocity: Sequence[np.ndarray],
    currents: Sequence[float],
    floor: float | None = None,
    axes: Sequence[Axes] | None = None,
    **style: Any,
) -> Figure:
    """The residual (simulated - measured) against displacement and velocity, per current.

    Each current's residual is drawn as its mean in :data:`BINS` bins of the variable
    (a line per current, coloured by the current), over the repeatability band
    ``±floor`` (what no deterministic model of the motion can fit). Structure above the
    band is what the model still misses: an offset that differs per current, a step at
    zero velocity (friction, yield), a slope in displacement (a spring), a lag at the
    reversals (backlash).

    Parameters
    ----------
    residuals, displacement, velocity : sequence of array
        Per run, on the same samples.
    currents : sequence of float
        Each run's current (runs of one current are pooled).
    floor : float, optional
        The measurement's floor (one standard deviation): the band drawn.
    axes : two Axes, optional
        Where to draw (displacement, velocity); a new figure when omitted.
    **style
        Passed to ``Axes.plot``.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> t = np.linspace(0, 2, 400)
    >>> x, v = np.sin(2 * np.pi * t), 2 * np.pi * np.cos(2 * np.pi * t)
    >>> fig = plot_residual_map([0.1 * np.sign(v), 0.3 * np.sign(v)], [x, x], [v, v], [0, 1],
    ...                         floor=0.05)
    >>> len(fig.axes), len(fig.axes[1].lines), fig.axes[1].get_xlabel()  # a line per current, 0
    (2, 3, 'velocity [rad/s]')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if axes is None:
        axes = new_axes(1, 2, figsize=(10, 3.6))
    ax_x, ax_v = axes
    cur = np.asarray(currents, dtype=float)
    levels = np.unique(cur)
    lo, hi = (levels.min(), levels.max()) if levels.size else (0.0, 1.0)
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    for level in levels:
        runs = np.flatnonzero(np.isclose(cur, level))
        r = np.concatenate([np.asarray(residuals[k], dtype=float).ravel() for k in runs])
        colour = cmap(0.0 if hi == lo else 0.9 * (level - lo) / (hi - lo))
        for ax, var in ((ax_x, displacement), (ax_v, velocity)):
            x = np.concatenate([np.asarray(var[k], dtype=float).ravel() for k in runs])
            c, m = binned_mean(x, r)
            ax.plot(c, m, color=colour, lw=1.2, label=f"{level:g} A", **style)
    for ax, var in ((ax_x, "displacement"), (ax_v, "velocity")):
        if floor is not None and np.isfinite(floor) and floor > 0:
            ax.axhspan(-floor, floor, color="0.85", zorder=0, label=f"repeatability ±{floor:.3g}")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_xlabel(XLABEL[var])
        ax.set_ylabel("residual (binned mean)")
    ax_v.legend(fontsize="x-small", ncols=2)
    return ax_x.figure
