"""Measured against simulated runs, and a fit with its residual."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import YLABEL, fill_doc, new_axes


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


@fill_doc
def plot_runs(
    dataset: Any,
    predictions: Sequence[Any] | Mapping[str, Any] | None = None,
    ax: Axes | Sequence[Axes] | None = None,
    label: str = "model",
) -> Figure:
    """Measured signal of every run against time, with the simulated one beside it.

    Parameters
    ----------
    dataset : hystdisc.data.Dataset
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

    %(returns)s

    Examples
    --------
    >>> from hystdisc.simulation.synth import generate
    >>> ds = generate("dahl", currents=(0, 1), duration=1.0)
    >>> fig = plot_runs(ds, predictions=[r.theta for r in ds])
    >>> [len(a.lines) for a in fig.axes]
    [2, 2]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    runs = list(dataset.runs)
    measured = dataset.measured() if hasattr(dataset, "measured") else "theta"
    if ax is None:
        axes = new_axes(len(runs), 1, sharex=True, figsize=(8, 1.6 + 1.4 * len(runs)))
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
        a.set_ylabel(YLABEL.get(measured, measured))
        if not single:
            a.legend(fontsize="x-small", loc="upper right")
    axes[-1].set_xlabel("time [s]")
    if single:
        axes[0].legend(fontsize="x-small", loc="upper right")
    return axes[0].figure


@fill_doc
def plot_fit(
    t: np.ndarray,
    measured: np.ndarray,
    simulated: np.ndarray | None = None,
    ax: Axes | None = None,
    residual_ax: Axes | None = None,
    label: str = "model",
    ylabel: str = YLABEL["theta"],
    title: str | None = None,
    draw_measured: bool = True,
    legend: bool = True,
    **style: Any,
) -> Figure:
    """Measured signal of one run against time, the simulated one over it, and the residual.

    Call it once per model on the same axes to overlay several models (``draw_measured=False``
    after the first).

    Parameters
    ----------
    t, measured : array_like
        Time [s] and the measured signal (angle, or torque of a driven run).
    simulated : array_like, optional
        The model's output on the same samples, drawn dashed.
    ax : Axes, optional
        Where to draw the signals; a new figure (with a residual panel below) when omitted.
    residual_ax : Axes, optional
        Where to draw ``simulated - measured`` (nothing is drawn when None and ``ax`` is given).
    label : str
        Legend label of ``simulated``.
    ylabel : str
        Label of the signal axis.
    title : str, optional
        Title of ``ax``.
    draw_measured : bool
        Draw the measured signal (grey).
    legend : bool
        Draw a legend on ``ax``.
    **style
        Passed to ``Axes.plot`` for the simulated line (and the residual).

    %(returns)s

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 100)
    >>> fig = plot_fit(t, np.sin(6 * t), np.sin(6 * t) + 0.01, label="dahl")
    >>> [len(a.lines) for a in fig.axes], fig.axes[1].get_ylabel()  # residual and its zero
    ([2, 2], 'residual')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(measured, dtype=float)
    if ax is None:
        ax, residual_ax = new_axes(2, 1, sharex=True, figsize=(8, 4.5), height_ratios=[3, 1])
    if draw_measured:
        ax.plot(t, y, color="0.35", lw=0.8, label="measured")
        if residual_ax is not None:
            residual_ax.axhline(0.0, color="0.6", lw=0.5)
    if simulated is not None:
        p = np.asarray(simulated, dtype=float)
        style = {"ls": "--", "lw": 1.1, **style}
        ax.plot(t, p, label=label, **style)
        if residual_ax is not None:
            rstyle = {k: v for k, v in style.items() if k not in ("ls", "linestyle")}
            rstyle["lw"] = 0.6
            residual_ax.plot(t, p - y, label=label, **rstyle)
    if residual_ax is not None:
        residual_ax.set_ylabel("residual")
        residual_ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    if residual_ax is None:
        ax.set_xlabel("time [s]")
    if title:
        ax.set_title(title, fontsize="medium")
    if legend:
        ax.legend(fontsize="x-small", loc="upper right")
    return ax.figure
