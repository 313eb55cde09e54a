"""Shared pieces of the plotting functions: axis labels, docstring fragments, a new figure."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from matplotlib.axes import Axes

#: Axis labels of the horizontal variable of a loop.
XLABEL = {"velocity": "velocity [rad/s]", "displacement": "angle [rad]"}
#: Axis labels of a measured signal.
YLABEL = {"theta": "angle [rad]", "torque": "torque [N*m]"}

#: Docstring fragments of the plotting functions, filled in by :func:`fill_doc`.
DOCS = {
    "ax": "ax : Axes, optional\n    Where to draw; a new figure when omitted.",
    "returns": "Returns\n-------\nmatplotlib.figure.Figure",
}

F = TypeVar("F", bound=Callable[..., Any])


def fill_doc(func: F) -> F:
    """Fill the ``%(name)s`` placeholders of ``func``'s docstring from :data:`DOCS`.

    As matplotlib's ``_docstring.interpd``: each line of a fragment is indented like the
    line of its placeholder, so that ``help()`` and numpydoc see the whole docstring.

    Examples
    --------
    >>> @fill_doc
    ... def f(ax=None):
    ...     '''Draw nothing.
    ...
    ...     Parameters
    ...     ----------
    ...     %(ax)s
    ...     '''
    >>> print(f.__doc__.splitlines()[-2])
            Where to draw; a new figure when omitted.
    """

    def fill(line: str) -> str:
        indent = "\n" + line[: len(line) - len(line.lstrip())]
        return re.sub(r"%\((\w+)\)s", lambda m: DOCS[m[1]].replace("\n", indent), line)

    if func.__doc__:  # None under python -OO
        func.__doc__ = "\n".join(fill(line) for line in func.__doc__.split("\n"))
    return func


def new_axes(nrows: int = 1, ncols: int = 1, **kw: Any) -> list[Axes]:
    """A new figure's ``nrows`` x ``ncols`` axes, flattened (``figsize`` sizes the figure,
    the rest of ``kw`` goes to ``Figure.subplots``)."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=kw.pop("figsize", None))
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return list(np.asarray(axes).ravel())
