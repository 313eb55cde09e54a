"""Plotting functions: each takes ``ax=`` (or ``axes=``) and returns its figure.

Conventions (those of python-control): every function takes an ``ax=`` (or ``axes=``) to draw
into and returns the :class:`~matplotlib.figure.Figure`; without one it opens a new pyplot
figure. Nothing here calls ``plt.show()`` or changes ``rcParams``. One module per kind of
figure: :mod:`~hystdisc.plotting.loops`, :mod:`~hystdisc.plotting.fits`,
:mod:`~hystdisc.plotting.selection`, :mod:`~hystdisc.plotting.spectrum`,
:mod:`~hystdisc.plotting.residuals`,
:mod:`~hystdisc.plotting.families`, :mod:`~hystdisc.plotting.currents`,
:mod:`~hystdisc.plotting.control`.

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

from hystdisc.plotting.control import plot_closed_loop
from hystdisc.plotting.currents import plot_current_laws
from hystdisc.plotting.families import plot_family_comparison
from hystdisc.plotting.fits import plot_fit, plot_runs
from hystdisc.plotting.loops import loops_figure, plot_loops
from hystdisc.plotting.residuals import plot_residual_map
from hystdisc.plotting.selection import plot_inclusion, plot_selection_path
from hystdisc.plotting.spectrum import plot_residual_spectrum
from hystdisc.plotting.studies import plot_study

__all__ = [
    "loops_figure",
    "plot_closed_loop",
    "plot_current_laws",
    "plot_family_comparison",
    "plot_fit",
    "plot_inclusion",
    "plot_loops",
    "plot_residual_map",
    "plot_residual_spectrum",
    "plot_runs",
    "plot_selection_path",
    "plot_study",
]
