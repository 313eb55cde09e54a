"""Hysteresis loops: torque against velocity or displacement (``ax=``, returns the figure)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import XLABEL, YLABEL, fill_doc, new_axes


@fill_doc
def plot_loops(
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray | None,
    torque: np.ndarray,
    current: float | None = None,
    ax: Axes | None = None,
    kind: str = "velocity",
    label: str | None = None,
    **style: Any,
) -> Figure:
    """Draw one hysteresis loop: torque against velocity or against displacement.

    Parameters
    ----------
    t, theta, theta_dot, torque : array_like
        Samples of the loop (``theta_dot`` may be None: it is then ``np.gradient(theta, t)``).
    current : float, optional
        Coil current, used for the default label ``"<i> A"``.
    %(ax)s
    kind : {"velocity", "displacement"}
        Horizontal axis: ``theta_dot`` or ``theta``.
    label : str, optional
        Legend label (default from ``current``).
    **style
        Passed to ``Axes.plot`` (color, linestyle, ...).

    %(returns)s
        The figure holding ``ax``.
    """
    if kind not in XLABEL:
        raise ValueError(f"kind must be 'velocity' or 'displacement', not {kind!r}")
    theta = np.asarray(theta, dtype=float)
    if theta_dot is None:
        theta_dot = np.gradient(theta, np.asarray(t, dtype=float))
    x = np.asarray(theta_dot if kind == "velocity" else theta, dtype=float)
    if ax is None:
        ax = new_axes()[0]
    if label is None and current is not None:
        label = f"{current:g} A"
    ax.plot(x, np.asarray(torque, dtype=float), label=label, **style)
    ax.set_xlabel(XLABEL[kind])
    ax.set_ylabel(YLABEL["torque"])
    return ax.figure


def _loop_items(loops: Any) -> list[dict[str, Any]]:
    if isinstance(loops, Mapping):
        return [dict(loops)]
    if hasattr(loops, "runs") and hasattr(loops, "experiment"):  # a Dataset with torque
        items = []
        for r in loops.runs:
            if r.torque is None:
                raise ValueError("loops_figure needs torque; this dataset has none (not driven)")
            items.append(
                {
                    "t": r.t,
                    "theta": r.theta,
                    "theta_dot": r.theta_dot,
                    "torque": r.torque,
                    "current": r.current,
                    "label": f"run {r.name}, {r.current:g} A",
                }
            )
        return items
    return [dict(item) for item in loops]


@fill_doc
def loops_figure(
    loops: Mapping[str, Any] | Sequence[Mapping[str, Any]] | Any,
    axes: Sequence[Axes] | None = None,
    title: str | None = None,
    legend: bool = True,
) -> Figure:
    """Two panels, torque against velocity (left) and against displacement (right).

    Parameters
    ----------
    loops : dict, list of dicts, or Dataset
        Each loop has ``t, theta, theta_dot, torque`` and optionally ``current``, ``label``
        and ``style`` (a dict for ``Axes.plot``); a driven Dataset gives one loop per run.
    axes : pair of Axes, optional
        Where to draw; a new 1 x 2 figure when omitted.
    title : str, optional
        Figure title.
    legend : bool
        Draw a legend when the loops have labels.

    %(returns)s

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 100)
    >>> loop = {"t": t, "theta": np.sin(6.28 * t), "theta_dot": 6.28 * np.cos(6.28 * t),
    ...         "torque": np.cos(6.28 * t), "label": "a"}
    >>> fig = loops_figure([loop, loop])
    >>> [len(a.lines) for a in fig.axes]
    [2, 2]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    items = _loop_items(loops)
    if axes is None:
        axes = new_axes(1, 2, figsize=(10, 4))
    if len(axes) != 2:
        raise ValueError(f"loops_figure needs two axes, got {len(axes)}")
    for item in items:
        style = dict(item.get("style") or {})
        for ax, kind in zip(axes, ("velocity", "displacement"), strict=True):
            plot_loops(
                item["t"],
                item["theta"],
                item.get("theta_dot"),
                item["torque"],
                current=item.get("current"),
                ax=ax,
                kind=kind,
                label=item.get("label"),
                **style,
            )
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig = axes[0].figure
    if legend and any(ax.get_legend_handles_labels()[1] for ax in axes):
        axes[0].legend(fontsize="small")
    if title:
        fig.suptitle(title)
    return fig
