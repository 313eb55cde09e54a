"""The open library's candidate terms by name: each name says how to compute its column.

A term's name is its formula in the states and inputs (``theta``, ``theta_dot``, the
current ``i``, the time ``t``), with its constants written out: ``tanh(theta_dot/0.0123)``,
``bias[i=1.5 A]``, ``play(theta,0.0005)-theta``. :func:`term_column` computes any name the
open library (:mod:`hystdisc.closing.open_library`) can select, so that a selected term
set can be refitted and predicted on new runs from its names alone (a ``results.json``
holds the names).

Examples
--------
>>> th = np.array([0.0, 0.1, 0.2]); w = np.array([1.0, -1.0, 2.0])
>>> term_column("i*[theta_dot>0]", th, w, 2.0, np.arange(3.0)).tolist()
[2.0, 0.0, 2.0]
>>> term_column("bias[i=1.5 A]", th, w, 1.5, np.arange(3.0)).tolist()
[1.0, 1.0, 1.0]
"""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np

from hystdisc.models.backlash import play
from hystdisc.models.terms import TORQUE_TERMS, TermModel

Column = Callable[[np.ndarray, np.ndarray, float, np.ndarray], np.ndarray]


def _pos(a: np.ndarray) -> np.ndarray:
    return (a > 0).astype(float)


#: Names without constants: ``f(theta, theta_dot, i, t)``.
FIXED: dict[str, Column] = {
    "theta^2": lambda th, w, i, t: th * th,
    "theta_dot^3": lambda th, w, i, t: w**3,
    "sign(theta_dot)*|theta_dot|^0.5": lambda th, w, i, t: np.sign(w) * np.sqrt(np.abs(w)),
    "[theta_dot>0]": lambda th, w, i, t: _pos(w),
    "theta_dot*[theta_dot>0]": lambda th, w, i, t: w * _pos(w),
    "theta*[theta>0]": lambda th, w, i, t: th * _pos(th),
}


def _bias(level: float) -> Column:
    tol = 1e-9 * max(1.0, abs(level))
    return lambda th, w, i, t: np.full(th.size, float(abs(i - level) <= tol))


def _tanh(v0: float) -> Column:
    return lambda th, w, i, t: np.tanh(w / v0)


def _gap(r: float) -> Column:
    return lambda th, w, i, t: play(np.ascontiguousarray(th, dtype=np.float64), r) - th


def _lost(r: float) -> Column:
    gap = _gap(r)
    return lambda th, w, i, t: (
        np.gradient(gap(th, w, i, t), t) if th.size > 1 else np.zeros(th.size)
    )


#: A play's gap to the motion, and the velocity it loses (the width is the constant).
GAP = re.compile(r"play\(theta,(.+)\)-theta")
LOST = re.compile(r"d/dt\[play\(theta,(.+)\)-theta\]")
#: Names with one constant: ``pattern -> constructor(constant)``.
PATTERNS: tuple[tuple[re.Pattern, Callable[[float], Column]], ...] = (
    (re.compile(r"bias\[i=(.+) A\]"), _bias),
    (re.compile(r"tanh\(theta_dot/(.+)\)"), _tanh),
    (GAP, _gap),
    (LOST, _lost),
)


def bias_name(level: float) -> str:
    """The name of the bias at current ``level``."""
    return f"bias[i={level:g} A]"


def tanh_name(v0: float) -> str:
    """The name of ``tanh(theta_dot/v0)`` (``v0`` to 3 digits, as computed)."""
    return f"tanh(theta_dot/{v0:.3g})"


def play_names(r: float) -> tuple[str, str]:
    """The names of a play of width ``r``: its gap to the motion and the velocity it loses."""
    return f"play(theta,{r:g})-theta", f"d/dt[play(theta,{r:g})-theta]"


def play_term(name: str) -> tuple[float, bool, bool] | None:
    """A play term's width, whether it is the velocity the play loses (``d/dt[...]``)
    rather than its gap, and whether it is scaled by the current (``i*``); None for a
    term without a play.

    Examples
    --------
    >>> play_term("i*d/dt[play(theta,0.0005)-theta]"), play_term("theta^2")
    ((0.0005, True, True), None)
    """
    by_i = name.startswith("i*")
    base = name[2:] if by_i else name
    for lost, pattern in ((False, GAP), (True, LOST)):
        m = pattern.fullmatch(base)
        if m is not None:
            return float(m.group(1)), lost, by_i
    return None


def term_column(
    name: str,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    i: float,
    t: np.ndarray,
    z: np.ndarray | None = None,
) -> np.ndarray:
    """The values of term ``name`` on one run.

    Parameters
    ----------
    name : str
        A catalogued torque term (:data:`~hystdisc.models.TORQUE_TERMS`, evaluated at
        ``z``, zero when not given), a name of :data:`FIXED` or :data:`PATTERNS`, or
        ``i*`` followed by any of those.
    theta, theta_dot, t : ndarray
        The motion and its time.
    i : float
        The run's current.
    z : ndarray, optional
        The hysteretic state, for a catalogued term in ``z``.

    Returns
    -------
    ndarray
        One value per sample.

    Raises
    ------
    ValueError
        For a name no form matches.
    """
    th = np.asarray(theta, dtype=float)
    w = np.asarray(theta_dot, dtype=float)
    if name in TORQUE_TERMS:
        zz = np.zeros_like(th) if z is None else z
        return np.broadcast_to(TermModel({}).term(name, th, w, zz, i), th.shape).astype(float)
    if name in FIXED:
        return FIXED[name](th, w, i, t)
    for pattern, make in PATTERNS:
        m = pattern.fullmatch(name)
        if m is not None:
            return make(float(m.group(1)))(th, w, i, np.asarray(t, dtype=float))
    if name.startswith("i*"):
        return i * term_column(name[2:], th, w, i, t, z)
    raise ValueError(f"unknown term '{name}': not a form of the open library's candidates")
