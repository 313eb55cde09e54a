"""The seed's parameter studies drawn: loops of a model while one parameter varies."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc
from hystdisc.plotting.loops import loops_figure
from hystdisc.simulation.studies import CURRENT_NAMES


@fill_doc
def plot_study(
    study: Sequence[Mapping[str, Any]],
    ax: Sequence[Axes] | None = None,
    title: str | None = None,
    cmap: str = "viridis",
) -> Figure:
    """Overlay the loops of a study: torque against velocity and against displacement.

    Parameters
    ----------
    study : list of dict
        From :func:`parameter_study` (or any loops with ``label``).
    ax : pair of Axes, optional
        Where to draw; a new 1 x 2 figure when omitted.
    title : str, optional
        Figure title (default: the family, the parameter and the conditions).
    cmap : str
        Colour map running over the values.

    %(returns)s

    Examples
    --------
    >>> from hystdisc.simulation.studies import parameter_study
    >>> fig = plot_study(parameter_study("lugre", "sigma_2", [0.5, 1.0, 2.0]))
    >>> [len(a.lines) for a in fig.axes]
    [3, 3]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    colors = matplotlib.colormaps[cmap](np.linspace(0.0, 0.9, max(len(study), 1)))
    loops = []
    for s, c in zip(study, colors, strict=False):
        item = dict(s)
        item["style"] = {"color": c, "lw": 1.5}
        loops.append(item)
    if title is None and study and "model" in study[0]:
        s0 = study[0]
        what = f"{s0['param']} varied" if s0.get("param") else ""
        cur = "" if s0.get("param") in CURRENT_NAMES else f", {s0['current']:g} A"
        title = (
            f"{s0['model'].family.title}: {what} ({s0['amplitude']:g} rad at "
            f"{s0['frequency']:g} Hz{cur})"
        )
    return loops_figure(loops, axes=ax, title=title)
