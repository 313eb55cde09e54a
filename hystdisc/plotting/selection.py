"""Stage 1: the STLSQ threshold path and the ensemble inclusion probabilities."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc, new_axes


def _path_x(thresholds: np.ndarray) -> tuple[np.ndarray, float | None]:
    """Positions on a log axis; a threshold of 0 goes one decade-step left of the smallest."""
    pos = thresholds[thresholds > 0]
    if pos.size == 0:
        return np.ones_like(thresholds), 1.0
    lo = float(pos.min())
    ratio = float(np.exp(np.median(np.diff(np.log(np.unique(pos)))))) if pos.size > 1 else 10.0
    zero_at = lo / max(ratio, 1.5) ** 2 if np.any(thresholds <= 0) else None
    x = np.where(thresholds > 0, thresholds, zero_at if zero_at is not None else lo)
    return x, zero_at


@fill_doc
def plot_selection_path(
    path: Sequence[Mapping[str, Any]],
    ax: Axes | Sequence[Axes] | None = None,
    title: str | None = None,
) -> Figure:
    """Term-selection path of the sparse regression: coefficients against the STLSQ threshold.

    Every coefficient is divided by its largest magnitude along the path, so terms of very
    different size (the spring ``theta`` and a damping term) share one axis; a term drops
    to 0 where the threshold removes it. The BIC of each threshold is drawn below (or on a
    second y axis when a single Axes is given) and the threshold with the lowest BIC, the
    one selected, is marked.

    Parameters
    ----------
    path : list of dict
        ``{"threshold", "coefs", "bic"}`` per threshold (``Discovery.stage1_[shape].path``).
        A threshold of 0 (plain least squares) is drawn left of the others, labelled ``0``.
    ax : Axes or pair of Axes, optional
        One Axes (coefficients, BIC on a twin axis), a pair (coefficients, BIC), or None
        for a new two-panel figure.
    title : str, optional
        Title of the coefficient panel.

    %(returns)s

    Examples
    --------
    >>> path = [{"threshold": 0.0, "coefs": {"z": 1.0, "theta_dot": 0.1}, "bic": -10.0},
    ...         {"threshold": 0.01, "coefs": {"z": 1.0, "theta_dot": 0.1}, "bic": -12.0},
    ...         {"threshold": 0.3, "coefs": {"z": 1.1, "theta_dot": 0.0}, "bic": 5.0}]
    >>> fig = plot_selection_path(path)
    >>> [a.get_xscale() for a in fig.axes], [a.get_label() for a in fig.axes[0].lines[:2]]
    (['log', 'log'], ['z', 'theta_dot'])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if not path:
        raise ValueError("the selection path is empty")
    th = np.array([float(p["threshold"]) for p in path])
    order = np.argsort(th, kind="stable")
    th = th[order]
    steps = [path[k] for k in order]
    bic = np.array([float(p["bic"]) for p in steps])
    names: list[str] = []
    for p in steps:
        names += [k for k in p["coefs"] if k not in names]
    x, zero_at = _path_x(th)
    if ax is None:
        ax_c, ax_b = new_axes(2, 1, sharex=True, figsize=(8, 5.5), height_ratios=[3, 1.4])
    elif isinstance(ax, Axes):
        ax_c, ax_b = ax, ax.twinx()
    else:
        ax_c, ax_b = list(ax)
    for name in names:
        c = np.array([float(p["coefs"].get(name, 0.0)) for p in steps])
        scale = np.max(np.abs(c))
        ax_c.plot(x, c / scale if scale > 0 else c, marker=".", ms=4, lw=1.2, label=name)
    ax_c.axhline(0.0, color="0.6", lw=0.5)
    ax_c.set_ylabel("coefficient / max |coefficient|")
    ax_c.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    best = int(np.argmin(bic))
    twin = ax_b is not ax_c and isinstance(ax, Axes)
    ax_b.plot(x, bic, color="k", lw=1.0, ls=":" if twin else "-", marker="." if not twin else None)
    ax_b.set_ylabel("BIC (equation error)")
    for a in {id(ax_c): ax_c, id(ax_b): ax_b}.values():
        a.axvline(x[best], color="tab:red", lw=1.0, ls="--")
        a.set_xscale("log")
    ax_b.plot([x[best]], [bic[best]], "o", color="tab:red", ms=5)
    ax_b.annotate(
        f"selected: {th[best]:.3g}" if th[best] > 0 else "selected: 0",
        (x[best], bic[best]),
        textcoords="offset points",
        xytext=(6, 6),
        fontsize="x-small",
        color="tab:red",
    )
    bottom = ax_c if twin else ax_b
    bottom.set_xlabel("STLSQ threshold (normalized columns)")
    if zero_at is not None:
        ticks = [v for v in bottom.get_xticks() if v > zero_at * 1.5]
        bottom.set_xticks([zero_at, *ticks], ["0", *[f"{v:.0e}" for v in ticks]])
        bottom.set_xlim(zero_at / 1.5, x.max() * 1.5)
    if title:
        ax_c.set_title(title, fontsize="medium")
    return ax_c.figure


@fill_doc
def plot_inclusion(
    inclusion: Mapping[str, float],
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """Inclusion probability of each library term over bootstrap resamples (horizontal bars).

    Parameters
    ----------
    inclusion : dict
        Term -> probability in [0, 1] (``Discovery(ensemble=True)``: ``stage1_[shape].inclusion``).
    %(ax)s
    title : str, optional
        Axes title.

    %(returns)s

    Examples
    --------
    >>> fig = plot_inclusion({"z": 1.0, "i*z": 0.95, "sign(theta_dot)": 0.1})
    >>> len(fig.axes[0].patches), [float(v) for v in fig.axes[0].get_xlim()]
    (3, [0.0, 1.0])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if ax is None:
        ax = new_axes(figsize=(6, 0.8 + 0.35 * max(len(inclusion), 1)))[0]
    names = list(inclusion)
    p = np.array([float(inclusion[k]) for k in names])
    y = np.arange(len(names))[::-1]
    colors = ["tab:blue" if v >= 0.5 else "0.7" for v in p]
    ax.barh(y, p, color=colors)
    ax.set_yticks(y, names)
    ax.set_xlim(0.0, 1.0)
    ax.axvline(0.5, color="0.4", lw=0.6, ls=":")
    ax.set_xlabel("inclusion probability (bagged STLSQ)")
    if title:
        ax.set_title(title, fontsize="medium")
    return ax.figure
