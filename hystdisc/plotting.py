"""Plots of hysteresis loops and of measured against simulated runs.

Conventions (those of python-control): every function takes an ``ax=`` (or ``axes=``) to draw
into and returns the :class:`~matplotlib.figure.Figure`; without one it opens a new pyplot
figure. Nothing here calls ``plt.show()`` or changes ``rcParams``.

Examples
--------
>>> import numpy as np
>>> from hystdisc.plotting import plot_loops
>>> t = np.linspace(0, 1, 200)
>>> th, w = 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)
>>> fig = plot_loops(t, th, w, 2 * np.tanh(5 * w), current=0.5)
>>> len(fig.axes[0].lines), fig.axes[0].get_xlabel()
(1, 'velocity [rad/s]')
>>> import matplotlib.pyplot as plt; plt.close(fig)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

__all__ = ["loops_figure", "plot_loops", "plot_runs"]

_XLABEL = {"velocity": "velocity [rad/s]", "displacement": "angle [rad]"}
_YLABEL = {"theta": "angle [rad]", "torque": "torque [N*m]"}


def _new_axes(nrows: int = 1, ncols: int = 1, **kw: Any) -> list[Axes]:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=kw.pop("figsize", None))
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return list(np.asarray(axes).ravel())


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
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.
    kind : {"velocity", "displacement"}
        Horizontal axis: ``theta_dot`` or ``theta``.
    label : str, optional
        Legend label (default from ``current``).
    **style
        Passed to ``Axes.plot`` (color, linestyle, ...).

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    if kind not in _XLABEL:
        raise ValueError(f"kind must be 'velocity' or 'displacement', not {kind!r}")
    theta = np.asarray(theta, dtype=float)
    if theta_dot is None:
        theta_dot = np.gradient(theta, np.asarray(t, dtype=float))
    x = np.asarray(theta_dot if kind == "velocity" else theta, dtype=float)
    if ax is None:
        ax = _new_axes()[0]
    if label is None and current is not None:
        label = f"{current:g} A"
    ax.plot(x, np.asarray(torque, dtype=float), label=label, **style)
    ax.set_xlabel(_XLABEL[kind])
    ax.set_ylabel(_YLABEL["torque"])
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

    Returns
    -------
    matplotlib.figure.Figure

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
        axes = _new_axes(1, 2, figsize=(10, 4))
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


def _prediction_for(predictions: Any, k: int, name: str, measured: str) -> np.ndarray | None:
    if predictions is None:
        return None
    if isinstance(predictions, Mapping):
        p = predictions.get(name)
    else:
        p = predictions[k]
    if p is None:
        return None
    if hasattr(p, measured) and not isinstance(p, np.ndarray):  # a SimResult
        p = getattr(p, measured)
    return np.asarray(p, dtype=float)


def plot_runs(
    dataset: Any,
    predictions: Sequence[Any] | Mapping[str, Any] | None = None,
    ax: Axes | Sequence[Axes] | None = None,
    label: str = "model",
) -> Figure:
    """Measured signal of every run against time, with the simulated one beside it.

    Parameters
    ----------
    dataset : hystdisc.io.Dataset
        The runs; ``theta`` is drawn (``torque`` for driven datasets).
    predictions : sequence or dict, optional
        One simulated signal per run (arrays, or objects with a ``theta``/``torque``
        attribute such as :class:`~hystdisc.simulation.SimResult`), in run order or keyed
        by run name. Drawn dashed in the colour of the measurement.
    ax : Axes or sequence of Axes, optional
        A single Axes overlays all runs; a sequence gives one Axes per run; by default a
        new figure with one row per run.
    label : str
        Legend label of the predictions.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from hystdisc.synth import generate
    >>> ds = generate("dahl", currents=(0, 1), duration=1.0)
    >>> fig = plot_runs(ds, predictions=[r.theta for r in ds])
    >>> [len(a.lines) for a in fig.axes]
    [2, 2]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    runs = list(dataset.runs)
    measured = dataset.measured() if hasattr(dataset, "measured") else "theta"
    if ax is None:
        axes = _new_axes(len(runs), 1, sharex=True, figsize=(8, 1.6 + 1.4 * len(runs)))
    elif isinstance(ax, Axes):
        axes = [ax] * len(runs)
    else:
        axes = list(ax)
        if len(axes) != len(runs):
            raise ValueError(f"{len(axes)} axes for {len(runs)} runs; pass one per run")
    single = len({id(a) for a in axes}) == 1
    for k, (run, a) in enumerate(zip(runs, axes, strict=True)):
        y = getattr(run, measured)
        (line,) = a.plot(run.t, y, lw=0.8, label=f"run {run.name} ({run.current:g} A)")
        p = _prediction_for(predictions, k, run.name, measured)
        if p is not None:
            a.plot(
                run.t,
                p,
                "--",
                color=line.get_color(),
                lw=1.0,
                label=label if (not single or k == 0) else None,
            )
        a.set_ylabel(_YLABEL.get(measured, measured))
        if not single:
            a.legend(fontsize="x-small", loc="upper right")
    axes[-1].set_xlabel("time [s]")
    if single:
        axes[0].legend(fontsize="x-small", loc="upper right")
    return axes[0].figure
