"""The torque-side term library of stage 1, a pysindy feature library.

The torque side is linear in its coefficients once the latent state ``z`` is known, so it
is a pysindy feature library (:class:`TorqueLibrary`, a ``BaseFeatureLibrary``) evaluated
on the state ``[theta, theta_dot, z]`` with the coil current as pysindy's control input
``u`` (appended as the last column, the way ``pysindy.SINDy`` passes it). It is the
design matrix of stage 1: :class:`~hystdisc.discovery.design.Design` takes its columns
from it. The values of a column are those of the term in the one term table,
:data:`hystdisc.models.TORQUE_TERMS`.

The shape search evaluates the same design for many ``z``: :meth:`TorqueLibrary.
transform_z_free` computes the columns that do not depend on ``z`` once, and
:meth:`TorqueLibrary.refresh_z` rewrites only the ``z`` columns (every ``z`` term is
linear in ``z``: its value is its value at ``z = 1`` times ``z``).

The hysteresis side (the shapes) is in :mod:`hystdisc.models.shapes`.

Examples
--------
>>> import numpy as np
>>> lib = TorqueLibrary(["theta", "theta_dot", "i*z"]).fit(np.zeros((3, 4)))
>>> lib.get_feature_names()
['theta', 'theta_dot', 'i*z']
>>> X = np.array([[0.1, 2.0, 0.5, 1.0]])  # theta, theta_dot, z, current
>>> lib.transform(X).tolist()
[[0.1, 2.0, 0.5]]
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pysindy.feature_library.base import BaseFeatureLibrary, x_sequence_or_item
from sklearn.utils.validation import check_is_fitted

from hystdisc.models import EVEN_Z_TORQUE_TERMS, TORQUE_TERM_NAMES, TORQUE_TERMS, Z_TORQUE_TERMS
from hystdisc.models.shapes import SHAPES

__all__ = [
    "DEFAULT_TORQUE_TERMS",
    "TorqueLibrary",
    "torque_state",
    "torque_terms_for",
]

#: Torque-side terms of the discovery library (doc/design.rst, section 3), spring first.
DEFAULT_TORQUE_TERMS: tuple[str, ...] = (
    "theta",
    "theta_dot",
    "i*theta_dot",
    "z",
    "i*z",
    "|theta_dot|*z",
    "sign(theta_dot)",
    "i*sign(theta_dot)",
)

#: Column of each variable in the library's input ``[theta, theta_dot, z, i]``.
THETA, THETA_DOT, Z, CURRENT = range(4)


def torque_state(theta, theta_dot, z, current) -> np.ndarray:
    """The library's input ``[theta, theta_dot, z, i]`` as an ``(n, 4)`` array.

    Parameters
    ----------
    theta, theta_dot, z : array_like
        Angle, velocity and hysteretic state per sample (``z`` may be a scalar, e.g. 0
        when only the z-free columns are wanted).
    current : float or array_like
        Coil current, per sample or one value for all.

    Examples
    --------
    >>> torque_state([0.0, 1.0], [2.0, 3.0], 0.0, 0.5).tolist()
    [[0.0, 2.0, 0.0, 0.5], [1.0, 3.0, 0.0, 0.5]]
    """
    theta = np.asarray(theta, dtype=float)
    cols = [theta, theta_dot, z, current]
    return np.column_stack([np.broadcast_to(np.asarray(c, dtype=float), theta.shape) for c in cols])


class TorqueLibrary(BaseFeatureLibrary):
    """pysindy feature library of named torque terms of ``[theta, theta_dot, z, i]``.

    Inside ``pysindy.SINDy`` the state is ``[theta, theta_dot, z]`` and the current is the
    control input ``u``.

    Parameters
    ----------
    terms : sequence of str
        Term names from :data:`hystdisc.models.TORQUE_TERM_NAMES`, in column order.

    Attributes
    ----------
    n_features_in_ : int
        4 (``theta, theta_dot, z, i``).
    n_output_features_ : int
        Number of terms.
    """

    def __init__(self, terms: Sequence[str] = DEFAULT_TORQUE_TERMS) -> None:
        self.terms = terms

    @x_sequence_or_item
    def fit(self, x_full, y=None) -> TorqueLibrary:
        """Check the terms and the input's columns ``[theta, theta_dot, z, i]``."""
        unknown = [t for t in self.terms if t not in TORQUE_TERMS]
        if unknown:
            raise ValueError(f"unknown torque terms {unknown}; known: {list(TORQUE_TERM_NAMES)}")
        for x in x_full:
            if np.ndim(x) != 2 or np.shape(x)[1] != 4:
                raise ValueError("TorqueLibrary expects columns [theta, theta_dot, z, i]")
        self.n_features_in_ = 4
        self.n_output_features_ = len(self.terms)
        return self

    @x_sequence_or_item
    def transform(self, x_full) -> list[np.ndarray]:
        """The terms' values, one column per term (a list of arrays for a list input)."""
        check_is_fitted(self)
        out = []
        for x in x_full:
            th, w, z, i = self._columns(x)
            F = np.empty((th.size, len(self.terms)))
            for j, t in enumerate(self.terms):
                F[:, j] = TORQUE_TERMS[t](th, w, z, i)
            out.append(F)
        return out

    def transform_z_free(
        self, x, out: np.ndarray | None = None
    ) -> tuple[np.ndarray, list[tuple[int, np.ndarray]]]:
        """The columns that do not depend on ``z``, once for many ``z``.

        The ``z`` column of ``x`` is not read. Follow with :meth:`refresh_z` for each
        ``z``; the result equals :meth:`transform` with that ``z``.

        Parameters
        ----------
        x : ndarray, shape (n, 4)
            ``[theta, theta_dot, z, i]``.
        out : ndarray, shape (n, n_terms), optional
            Where to write the columns (e.g. a view into a larger design matrix).

        Returns
        -------
        F : ndarray
            The design with its z-free columns filled (``out`` when given); the ``z``
            columns are left for :meth:`refresh_z`.
        z_factors : list of (int, ndarray, bool)
            For each ``z`` column, its index, its value at ``z = 1`` and whether it is
            that factor times ``|z|`` (:data:`~hystdisc.models.EVEN_Z_TORQUE_TERMS`)
            rather than times ``z``.
        """
        check_is_fitted(self)
        th, w, _, i = self._columns(x)
        F = np.empty((th.size, len(self.terms))) if out is None else out
        z_factors = []
        for j, t in enumerate(self.terms):
            if t in Z_TORQUE_TERMS:
                # a z term is its z-free factor (1, |theta_dot|, i, i^2) times z (or |z|)
                factor = TORQUE_TERMS[t](th, w, np.ones_like(th), i)
                z_factors.append((j, factor, t in EVEN_Z_TORQUE_TERMS))
            else:
                F[:, j] = TORQUE_TERMS[t](th, w, None, i)
        return F, z_factors

    @staticmethod
    def refresh_z(
        F: np.ndarray, z: np.ndarray, z_factors: Sequence[tuple[int, np.ndarray, bool]]
    ) -> np.ndarray:
        """Write the ``z`` columns of ``F`` (from :meth:`transform_z_free`) for ``z``.

        Returns ``F``, overwritten in place.
        """
        az = None
        for j, factor, even in z_factors:
            if even:
                az = np.abs(z) if az is None else az
                F[:, j] = factor * az
            else:
                F[:, j] = factor * z
        return F

    def get_feature_names(self, input_features=None) -> list[str]:
        """The term names (the input names are fixed: ``theta, theta_dot, z, i``)."""
        return list(self.terms)

    @staticmethod
    def _columns(x) -> tuple[np.ndarray, ...]:
        """``theta, theta_dot, z, i`` of ``x``, each a contiguous float array."""
        x = np.asarray(x, dtype=float)
        return tuple(np.ascontiguousarray(x[:, k]) for k in (THETA, THETA_DOT, Z, CURRENT))


def torque_terms_for(shape: str, terms: Sequence[str]) -> list[str]:
    """Drop the z-dependent torque terms when the shape carries no state."""
    if not SHAPES[shape].has_state:
        return [t for t in terms if t not in Z_TORQUE_TERMS]
    return list(terms)
