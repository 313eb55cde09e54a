"""Shared pieces of the plotting functions: axis labels and a new figure."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.axes import Axes

#: Axis labels of the horizontal variable of a loop.
XLABEL = {"velocity": "velocity [rad/s]", "displacement": "angle [rad]"}
#: Axis labels of a measured signal.
YLABEL = {"theta": "angle [rad]", "torque": "torque [N*m]"}


def new_axes(nrows: int = 1, ncols: int = 1, **kw: Any) -> list[Axes]:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=kw.pop("figsize", None))
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return list(np.asarray(axes).ravel())
