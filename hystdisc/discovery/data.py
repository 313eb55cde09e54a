"""Equation-error data of stage 1: :class:`EqData`.

The smoothed, differentiated and decimated records of all runs with the regression
target of the experiment type (``-theta_ddot`` after a release, the torque of a driven
experiment, the input of a forced one) and the rows where the equation is evaluated.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from hystdisc.models import SIGN_EPS
from hystdisc.models.shapes import HysteresisShape
from hystdisc.registry import get_experiment
from hystdisc.simulation import concat_runs, integrate_z_flat

#: Bytes of ``z`` trajectories :meth:`EqData.z_flat` keeps for shape constants it may be
#: asked for again (the shape grids, a search's start simplex, clipped corners).
Z_MEMO_BYTES = 256 * 2**20


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
    _z_memo: OrderedDict = field(default_factory=OrderedDict, init=False, repr=False, compare=False)
    _z_lock: threading.Lock = field(
        default_factory=threading.Lock, init=False, repr=False, compare=False
    )

    def __getstate__(self) -> dict:
        # the memo is recomputed where it is needed, not shipped; a lock cannot be
        return {k: v for k, v in self.__dict__.items() if k not in ("_z_memo", "_z_lock")}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, _z_memo=OrderedDict(), _z_lock=threading.Lock())

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
        """z of every run for the shape constants ``s``, all runs concatenated (read-only).

        The stage-1 searches ask for the same constants again and again (every augmented
        structure of the closing loop searches the same shape grid from the same start),
        so the last :data:`Z_MEMO_BYTES` of trajectories are kept: the same constants give
        the same array, bit for bit, without integrating again.
        """
        t, w, offsets = self._flat
        if not shape.has_state:
            return np.zeros_like(t)
        b, n = shape.vector(s)
        key = (b.tobytes(), float(n))  # z depends on the rate coefficients alone
        with self._z_lock:
            z = self._z_memo.get(key)
            if z is not None:
                self._z_memo.move_to_end(key)
                return z
        z = integrate_z_flat(b, n, t, w, offsets, SIGN_EPS)
        z.flags.writeable = False
        with self._z_lock:
            self._z_memo[key] = z
            while len(self._z_memo) * z.nbytes > Z_MEMO_BYTES and len(self._z_memo) > 1:
                self._z_memo.popitem(last=False)
        return z

    def memo_size(self) -> int:
        """Number of ``z`` trajectories :meth:`z_flat` keeps now."""
        return len(self._z_memo)

    def forget(self) -> None:
        """Drop the kept ``z`` trajectories (a finished discovery keeps its data, not them)."""
        with self._z_lock:
            self._z_memo.clear()

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
