"""Stage 1: numerical differentiation and sparse regression with a latent hysteretic state.

``z`` is never measured, but given the few shape constants of a hysteresis candidate it is
computed from the velocity record by integrating its rate. For each candidate shape (none,
Dahl-type, Bouc-Wen seed form, Bouc-Wen standard form; :mod:`~hystdisc.models.shapes`)
the shape constants are found by variable projection (a grid, then Nelder-Mead on the
least-squares residual of the torque-side regression; :mod:`~hystdisc.discovery.varpro`),
the torque-side terms are selected by pysindy's STLSQ along a threshold path scored by BIC
(:mod:`~hystdisc.discovery.selection`), and the shapes are compared by BIC. The winner is
the *discovered structure*. The design matrix of the regression is the pysindy feature
library :class:`TorqueLibrary` (:mod:`~hystdisc.discovery.library`,
:mod:`~hystdisc.discovery.design`). See doc/design.rst, sections 3 (the terms) and 4 (the
pipeline, step 3).

Modules
-------
differentiation  smoothing and derivatives of the measured angle
data             :class:`EqData`, the equation-error data of all runs
library          :class:`TorqueLibrary`, the pysindy library of torque terms
design           :class:`Design`, the library on the equation-error rows
(shapes          :class:`HysteresisShape` and :data:`SHAPES`, in :mod:`hystdisc.models.shapes`)
varpro           :func:`varpro`, the shape constants by variable projection
selection        :func:`fit_shape`, term selection for one shape
starts           :func:`family_start`, :func:`family_starts` (stage 2's starts), :func:`describe_structure`
"""

from hystdisc.discovery.data import EqData
from hystdisc.discovery.design import Design
from hystdisc.discovery.differentiation import differentiate
from hystdisc.discovery.library import (
    DEFAULT_TORQUE_TERMS,
    TorqueLibrary,
    torque_state,
    torque_terms_for,
)
from hystdisc.discovery.selection import ShapeFit, fit_shape
from hystdisc.discovery.starts import describe_structure, family_start, family_starts
from hystdisc.discovery.varpro import varpro
from hystdisc.models.shapes import (
    DEFAULT_SHAPES,
    FAMILY_SHAPE,
    N_RANGE,
    SHAPES,
    HysteresisShape,
)

__all__ = [
    "DEFAULT_SHAPES",
    "DEFAULT_TORQUE_TERMS",
    "FAMILY_SHAPE",
    "N_RANGE",
    "SHAPES",
    "Design",
    "EqData",
    "HysteresisShape",
    "ShapeFit",
    "TorqueLibrary",
    "describe_structure",
    "differentiate",
    "family_start",
    "family_starts",
    "fit_shape",
    "torque_state",
    "torque_terms_for",
    "varpro",
]
