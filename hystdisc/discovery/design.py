"""The design matrix of stage 1: the pysindy :class:`~hystdisc.discovery.library.TorqueLibrary`
on the equation-error rows of all runs."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hystdisc.discovery.data import EqData
from hystdisc.discovery.library import TorqueLibrary, torque_state


class Design:
    """Design matrix of torque terms on the equation-error rows of all runs.

    The columns are those of :class:`~hystdisc.discovery.library.TorqueLibrary` on the
    state ``[theta, theta_dot, z]`` with the current as the control column. The columns
    that do not depend on ``z`` (and the regression target) are evaluated once
    (:meth:`TorqueLibrary.transform_z_free`); :meth:`build_flat` only rewrites the ``z``
    columns (:meth:`TorqueLibrary.refresh_z`), so the shape search costs one ``z``
    integration and one small least-squares solve per evaluation.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    terms : sequence of str
        Torque terms, in column order (an experiment whose inertia is identifiable gets
        its ``theta_ddot`` column for ``J`` first).

    Attributes
    ----------
    library : TorqueLibrary
        The fitted library that makes the torque columns.
    terms : list of str
        The torque terms.
    rows : ndarray
        Indices of the rows used in the concatenation of all runs' samples.
    y : ndarray
        The regression target on those rows.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> eq = EqData("driven", [t], [t], [np.ones(5)], [np.zeros(5)], [2 * t],
    ...             np.array([0.5]), [np.ones(5, dtype=bool)])
    >>> F, y = Design(eq, ["theta", "i*z"]).build([np.full(5, 2.0)])
    >>> F[0].tolist(), y.tolist()
    ([0.0, 1.0], [0.0, 0.5, 1.0, 1.5, 2.0])
    """

    def __init__(self, eq: EqData, terms: Sequence[str]) -> None:
        self.terms = list(terms)
        self.rows = eq.row_index
        ms = eq.rows
        cat = lambda xs: np.concatenate([x[m] for x, m in zip(xs, ms, strict=True)])  # noqa: E731
        th, w = cat(eq.theta), cat(eq.theta_dot)
        i = np.concatenate([np.full(int(m.sum()), c) for m, c in zip(ms, eq.currents, strict=True)])
        self.y = cat(eq.target)
        x = torque_state(th, w, 0.0, i)  # z is filled in by build_flat
        self.library = TorqueLibrary(self.terms).fit(x)
        off = 1 if eq.experiment_type.inertia_identifiable else 0
        F = np.empty((self.y.size, off + len(self.terms)))
        if off:
            F[:, 0] = cat(eq.theta_ddot)
        self._torque = F[:, off:]  # a view: the library writes into F
        _, self._z_factors = self.library.transform_z_free(x, out=self._torque)
        self._F = F

    def build_flat(self, z_flat: np.ndarray, copy: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Design and target for z given on all samples, concatenated (``EqData.z_flat``).

        With ``copy=False`` the returned matrix is overwritten by the next call.
        """
        TorqueLibrary.refresh_z(self._torque, z_flat[self.rows], self._z_factors)
        return (self._F.copy() if copy else self._F), self.y

    def build(self, z_list: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Design and target for z given per run."""
        return self.build_flat(np.concatenate([np.asarray(z, dtype=float) for z in z_list]))
