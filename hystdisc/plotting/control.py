"""Closed-loop responses: signals of python-control simulations overlaid, one axes each."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc, new_axes

#: Axis labels of the closed-loop signals (:func:`hystdisc.apply.control.closed_loop`).
SIGNAL_LABELS = {
    "beam": "beam angle [rad]",
    "beam_dot": "beam velocity [rad/s]",
    "beam_ddot": "beam acceleration [rad/s²]",
    "wheel": "wheel [rad]",
    "theta_dot": "velocity across the damper [rad/s]",
    "current": "current [A]",
    "torque": "damper torque [N*m per unit J]",
}


@fill_doc
def plot_closed_loop(
    responses: Mapping[str, Any],
    signals: Sequence[str] = ("beam", "current"),
    axes: Axes | Sequence[Axes] | None = None,
    styles: Mapping[str, Mapping[str, Any]] | None = None,
) -> Figure:
    """Overlay the named output signals of several closed-loop simulations.

    Parameters
    ----------
    responses : dict of str to TimeResponseData
        Label -> a ``control.input_output_response`` result (its ``time``, ``outputs``
        and ``output_labels``).
    signals : sequence of str
        Output labels to draw, one axes each (top to bottom).
    axes : Axes or sequence of Axes, optional
        One per signal; a new figure when omitted.
    styles : dict of str to dict, optional
        Label -> keyword arguments of ``Axes.plot`` (color, linestyle, ...).

    %(returns)s

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> t = np.linspace(0.0, 1.0, 50)
    >>> r = SimpleNamespace(time=t, outputs=np.vstack([np.sin(t), t > 0.5]),
    ...                     output_labels=["beam", "current"])
    >>> fig = plot_closed_loop({"a": r, "b": r})
    >>> [len(ax.lines) for ax in fig.axes], fig.axes[1].get_ylabel()
    ([2, 2], 'current [A]')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if axes is None:
        axes = new_axes(len(signals), 1, figsize=(9, 2.2 * len(signals)), sharex=True)
    elif isinstance(axes, Axes):
        axes = [axes] * len(signals)
    styles = styles or {}
    for ax, name in zip(axes, signals, strict=True):
        for label, resp in responses.items():
            y = resp.outputs[list(resp.output_labels).index(name)]
            ax.plot(resp.time, y, label=label, **dict(styles.get(label, {})))
        ax.set_ylabel(SIGNAL_LABELS.get(name, name))
    axes[-1].set_xlabel("time [s]")
    axes[0].legend(loc="upper right", fontsize="small")
    return axes[0].figure
