"""Equation-error data of stage 1: :class:`EqData`.

The smoothed, differentiated and decimated records of all runs with the regression
target of the experiment type (``-theta_ddot`` after a release, the torque of a driven
experiment, the input of a forced one) and the rows where the equation is evaluated.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hystdisc.models import SIGN_EPS
from hystdisc.models.shapes import HysteresisShape
from hystdisc.registry import get_experiment
from hystdisc.simulation import concat_runs, integrate_z_flat


@dataclass
class EqData:
    """Equation-error data of all runs (rows where the equation is evaluated).

    Attributes
    ----------
    experiment : str
        Experiment type (``release``, ``driven`` or ``forced``).
    t, theta, theta_dot, theta_ddot : list of ndarray
        Per run: times, smoothed angle and its derivatives.
    target : list of ndarray
        Per run: the regression target of the experiment type.
    currents : ndarray
        Coil current of each run.
    rows : list of ndarray
        Per run: boolean mask of the rows used.
    window : int
        Smoothing window of the differentiation, in (decimated) samples.
    scale : float
        Displacement amplitude (sets the grid of the shape constants).

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> eq = EqData("release", [t], [t], [np.ones(5)], [np.zeros(5)], [2 * t],
    ...             np.array([0.5]), [np.ones(5, dtype=bool)], window=4)
    >>> eq.yy, eq.n_eff(5)
    (7.5, 2.5)
    """

    experiment: str
    t: list[np.ndarray]
    theta: list[np.ndarray]
    theta_dot: list[np.ndarray]
    theta_ddot: list[np.ndarray]
    target: list[np.ndarray]
    currents: np.ndarray
    rows: list[np.ndarray]  # boolean masks of rows used
    window: int = 1
    scale: float = 1.0  # displacement amplitude

    @property
    def experiment_type(self):
        """The :class:`~hystdisc.experiments.base.Experiment` object of :attr:`experiment`."""
        return get_experiment(self.experiment)

    @property
    def yy(self) -> float:
        """Sum of squares of the regression target over the rows used."""
        return float(sum(np.sum(y[m] ** 2) for y, m in zip(self.target, self.rows, strict=True)))

    @cached_property
    def _flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t, offsets = concat_runs(self.t)
        w, _ = concat_runs(self.theta_dot)
        return t, w, offsets

    @cached_property
    def row_index(self) -> np.ndarray:
        """Indices of the rows used, in the concatenation of all runs' samples."""
        offsets = self._flat[2]
        return np.concatenate(
            [o + np.flatnonzero(m) for o, m in zip(offsets[:-1], self.rows, strict=True)]
        )

    def z_flat(self, shape: HysteresisShape, s) -> np.ndarray:
        """z of every run for the shape constants ``s``, all runs concatenated."""
        t, w, offsets = self._flat
        if not shape.has_state:
            return np.zeros_like(t)
        b, n = shape.vector(s)
        return integrate_z_flat(b, n, t, w, offsets, SIGN_EPS)

    def z_list(self, shape: HysteresisShape, s) -> list[np.ndarray]:
        """z of every run for the shape constants ``s`` (zeros for a shape without state)."""
        z = self.z_flat(shape, s)
        offsets = self._flat[2]
        return [z[a:b] for a, b in zip(offsets[:-1], offsets[1:], strict=True)]

    def n_eff(self, n: int) -> float:
        """Effective number of independent equation-error samples (smoothing correlates them).

        A measured torque target (imposed motion) is not smoothed: its samples count fully.
        """
        if self.experiment_type.target == "torque":
            return float(n)
        return float(n) * 2.0 / max(self.window, 2)
