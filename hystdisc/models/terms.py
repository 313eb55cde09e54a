"""The term form: the language stage 1 writes a discovered structure in.

Every model of the seed's families (and a family plus effects) reduces to one generic
form, a :class:`TermModel`: a damper torque that is a linear combination of named
*torque terms* and a hysteretic state ``z`` whose rate is a linear combination of named
*hysteresis terms*::

    T  = sum_k a_k * torque_term_k(theta, theta_dot, z, i)
    dz = sum_j b_j * hysteresis_term_j(theta_dot, z; n)

The rig spring ``k_s`` is the coefficient of the ``theta`` torque term. The term library
of the sparse regression, the compiled term simulator and the output-error fit of these
models all work on this one form.

Examples
--------
>>> from hystdisc.models import Model
>>> m = Model("dahl", {"k_s": 158.0})
>>> m.params["rho"]
20.0
>>> tm = m.to_terms()
>>> tm.torque["z"], tm.hysteresis["|theta_dot|*z"]
(0.5, -20.0)
>>> print(m.family.equations())
T = k_x*theta_dot + (k_wa + k_wb*i)*z
dz/dt = rho*(theta_dot - |theta_dot|*z)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from hystdisc.errors import HystdiscError

#: Width of the smoothed sign function ``tanh(theta_dot / SIGN_EPS)`` (rad/s or m/s).
SIGN_EPS = 1e-3


def smooth_sign(v: np.ndarray | float, eps: float = SIGN_EPS) -> np.ndarray:
    """Smoothed ``sign(v)``: ``tanh(v / eps)``, used for Coulomb-type terms."""
    return np.tanh(np.asarray(v, dtype=float) / eps)


def _pow_abs(z: np.ndarray, n: float) -> np.ndarray:
    return np.abs(z) ** n


#: The shear-thinning (Herschel-Bulkley) torque term ``sign(theta_dot)*|theta_dot|^m``; its
#: exponent is the term model's ``m`` (:attr:`TermModel.m`).
SHEAR_TERM = "sign(theta_dot)*|theta_dot|^m"
#: The exponent ``m`` of :data:`SHEAR_TERM` where the closing loop's score test and the
#: stage-1 (equation-error) columns evaluate it, and a term model's default.
SHEAR_M0 = 0.5


def smooth_power(v: np.ndarray | float, m: float = SHEAR_M0, eps: float = SIGN_EPS) -> np.ndarray:
    """Smoothed ``sign(v) |v|^m``: ``v (v^2 + eps^2)^((m - 1)/2)``.

    Like :func:`smooth_sign` for Coulomb terms, the smoothing bounds the slope at ``v = 0``
    (``eps^(m-1)`` instead of infinite for ``m < 1``); beyond a few ``eps`` it is the power
    law (relative difference ``(1 - m) eps^2 / (2 v^2)``), and ``m = 1`` is ``v`` exactly.

    Examples
    --------
    >>> round(float(smooth_power(4.0, 0.5)), 6), float(smooth_power(-0.25, 1.0))
    (2.0, -0.25)
    """
    v = np.asarray(v, dtype=float)
    return v * (v * v + eps * eps) ** (0.5 * (m - 1.0))


# name -> f(theta, theta_dot, z, i); i is the run's coil current (scalar or array)
TORQUE_TERMS: dict[str, Callable[..., np.ndarray]] = {
    "theta": lambda th, w, z, i: th,
    "theta_dot": lambda th, w, z, i: w,
    "i*theta_dot": lambda th, w, z, i: i * w,
    "z": lambda th, w, z, i: z,
    "i*z": lambda th, w, z, i: i * z,
    "|theta_dot|*z": lambda th, w, z, i: np.abs(w) * z,
    "sign(theta_dot)": lambda th, w, z, i: smooth_sign(w),
    "i*sign(theta_dot)": lambda th, w, z, i: i * smooth_sign(w),
    "i^2*z": lambda th, w, z, i: i * i * z,
    "theta_dot*|theta_dot|": lambda th, w, z, i: w * np.abs(w),
    "theta^3": lambda th, w, z, i: th**3,
    "1": lambda th, w, z, i: np.ones_like(np.asarray(th, dtype=float)),
    # a constant torque that grows with the current (the current law of the constant "1")
    "i": lambda th, w, z, i: i * np.ones_like(np.asarray(th, dtype=float)),
    "i^2*theta_dot": lambda th, w, z, i: i * i * w,
    # at the exponent SHEAR_M0; a term model evaluates it at its own m (TermModel.term)
    SHEAR_TERM: lambda th, w, z, i, m=SHEAR_M0: smooth_power(w, m),
    # a quadratic current law of the Coulomb torque (Family.apply_laws)
    "i^2*sign(theta_dot)": lambda th, w, z, i: i * i * smooth_sign(w),
    # a viscous torque even in the velocity: with theta_dot, damping that differs in
    # tension and compression (the asymmetric_damping effect), with its current laws
    "|theta_dot|": lambda th, w, z, i: np.abs(w),
    "i*|theta_dot|": lambda th, w, z, i: i * np.abs(w),
    "i^2*|theta_dot|": lambda th, w, z, i: i * i * np.abs(w),
    # a hysteretic torque even in z: with z, a yield force that differs in tension and
    # compression (the asymmetric_yield effect), with its current laws
    "|z|": lambda th, w, z, i: np.abs(z),
    "i*|z|": lambda th, w, z, i: i * np.abs(z),
    "i^2*|z|": lambda th, w, z, i: i * i * np.abs(z),
}
TORQUE_TERM_NAMES: tuple[str, ...] = tuple(TORQUE_TERMS)

# name -> f(theta_dot, z, n)
HYSTERESIS_TERMS: dict[str, Callable[..., np.ndarray]] = {
    "theta_dot": lambda w, z, n: w,
    "|theta_dot|*z": lambda w, z, n: np.abs(w) * z,
    "theta_dot*|z|^n": lambda w, z, n: w * _pow_abs(z, n),
    "|theta_dot|*z*|z|^n": lambda w, z, n: np.abs(w) * z * _pow_abs(z, n),
    "|theta_dot|*z*|z|^(n-1)": lambda w, z, n: np.abs(w) * np.sign(z) * _pow_abs(z, n),
}
HYSTERESIS_TERM_NAMES: tuple[str, ...] = tuple(HYSTERESIS_TERMS)

# Torque terms that depend on z (zero contribution when the model has no hysteresis).
Z_TORQUE_TERMS = ("z", "i*z", "|theta_dot|*z", "i^2*z", "|z|", "i*|z|", "i^2*|z|")
#: The z terms that are a z-free factor times ``|z|`` (the others: times ``z``).
EVEN_Z_TORQUE_TERMS = ("|z|", "i*|z|", "i^2*|z|")

#: The torque terms a current multiplies, by group: the coefficient of ``i*<group>`` is a
#: current law's slope. A term model's :attr:`TermModel.saturation` maps a group to the
#: saturation current ``i0`` of its law.
LAW_GROUPS = ("z", "theta_dot", "sign(theta_dot)", "|theta_dot|", "|z|")
#: Prefixes of a group's current-law terms: ``i*<group>`` (the slope) and ``i^2*<group>``
#: (a quadratic law's curvature).
LAW_PREFIXES = ("i*", "i^2*")


def effective_current(i, i0: float | None = None):
    """The current a saturating law sees: ``i0 tanh(i / i0)`` (``i`` itself for no ``i0``).

    Written so that the slope at 0 A is 1 whatever ``i0``, and the linear law is the limit
    ``i0 -> infinity``; at large currents it levels off at ``i0``.

    Examples
    --------
    >>> round(float(effective_current(0.5, 0.4)), 4), effective_current(0.5)
    (0.3393, 0.5)
    """
    if i0 is None:
        return i
    return i0 * np.tanh(np.asarray(i, dtype=float) / i0) if np.ndim(i) else i0 * math.tanh(i / i0)


def current_law(i, a: float, b: float, q: float = 0.0, i0: float | None = None):
    """A current law's value, the one implementation: ``a + b s(i) + q i^2``.

    ``s(i)`` is :func:`effective_current` (``i`` itself without ``i0``), so the linear law
    is ``q = 0`` and no ``i0``, the quadratic law a ``q``, the saturating law an ``i0``.
    The current-law selection (:mod:`hystdisc.selection.laws`) and the families' laws
    (:meth:`hystdisc.models.Family.law_value`) both compute with it.

    Examples
    --------
    >>> current_law(2.0, 1.0, 2.0, q=-1.0), round(float(current_law(2.0, 0.5, 3.0, i0=0.3)), 4)
    (1.0, 1.4)
    >>> current_law(np.array([0.0, 1.0]), 1.0, 2.0)
    array([1., 3.])
    """
    return a + b * effective_current(i, i0) + q * i * i


@dataclass
class TermModel:
    """A model in generic term form (see module docstring).

    Parameters
    ----------
    torque : dict
        Torque term name -> coefficient (names from ``TORQUE_TERM_NAMES``).
    hysteresis : dict
        Hysteresis term name -> coefficient (names from ``HYSTERESIS_TERM_NAMES``).
    n : float
        Exponent used by the ``|z|^n`` hysteresis terms.
    J : float
        Inertia (mass); only used by ``forced`` experiments.
    m : float
        Exponent of the shear-thinning torque term :data:`SHEAR_TERM` (used only when the
        model has that term).
    delay : float
        Delay of the measured output behind the model's, in s (the ``channel_delay``
        effect): the output is recorded as ``y(t - delay)``; 0 for none.
    saturation : dict
        Saturating current laws: a group of :data:`LAW_GROUPS` -> its saturation current
        ``i0`` (A). The ``i*<group>`` term of such a group sees the current
        ``i0 tanh(i / i0)`` (:func:`effective_current`) instead of ``i``; its coefficient
        stays the slope at 0 A. Empty: every law linear (a quadratic law is an ``i^2``
        term).
    play : float
        Half-width of a play between a driven test's measured motion and the damper (the
        ``backlash`` effect, :mod:`hystdisc.models.backlash`): the model is driven by the
        play operator's output; 0 for none.

    Examples
    --------
    >>> tm = TermModel({"z": 0.5, "i*z": 3.0}, {"theta_dot": 1.0}, saturation={"z": 0.3})
    >>> round(float(tm.eval_torque(0.0, 0.0, 1.0, 2.0)), 4)  # 0.5 + 3 * 0.3 tanh(2 / 0.3)
    1.4
    >>> print(tm.equations().splitlines()[0])
    T = 0.5 z + 0.9 tanh(i/0.3)*z
    """

    torque: dict[str, float] = field(default_factory=dict)
    hysteresis: dict[str, float] = field(default_factory=dict)
    n: float = 1.0
    J: float = 1.0
    m: float = SHEAR_M0
    delay: float = 0.0
    saturation: dict[str, float] = field(default_factory=dict)
    play: float = 0.0

    def __post_init__(self) -> None:
        for name in self.torque:
            if name not in TORQUE_TERMS:
                raise HystdiscError(
                    f"unknown torque term '{name}'; fix: use one of {', '.join(TORQUE_TERM_NAMES)}"
                )
        for name in self.hysteresis:
            if name not in HYSTERESIS_TERMS:
                raise HystdiscError(
                    f"unknown hysteresis term '{name}'; fix: use one of "
                    f"{', '.join(HYSTERESIS_TERM_NAMES)}"
                )
        self.torque = {k: float(v) for k, v in self.torque.items()}
        self.hysteresis = {k: float(v) for k, v in self.hysteresis.items()}
        self.n = float(self.n)
        self.J = float(self.J)
        self.m = float(self.m)
        self.delay = float(self.delay)
        self.play = float(self.play)
        self.saturation = {k: float(v) for k, v in self.saturation.items()}
        for group, i0 in self.saturation.items():
            if group not in LAW_GROUPS:
                raise HystdiscError(
                    f"no current law for the torque term group '{group}'; fix: use one of "
                    f"{', '.join(LAW_GROUPS)}"
                )
            if not (i0 > 0.0 and math.isfinite(i0)):
                raise HystdiscError(
                    f"saturation current of '{group}' is {i0:g} A; fix: give a positive number"
                )

    def current(self, group: str, i):
        """The current the ``i*<group>`` term sees (:func:`effective_current`).

        Parameters
        ----------
        group : str
            The term the current multiplies (``z``, ``theta_dot``, ...).
        i : float or numpy.ndarray
            The coil current, A.

        Returns
        -------
        float or numpy.ndarray
            ``i``, or ``i0 tanh(i / i0)`` when the group's current law saturates.
        """
        return effective_current(i, self.saturation.get(group))

    def torque_vector(self) -> np.ndarray:
        """Coefficients in ``TORQUE_TERM_NAMES`` order (absent terms are 0).

        Returns
        -------
        numpy.ndarray
            One coefficient per torque term.
        """
        return np.array([self.torque.get(k, 0.0) for k in TORQUE_TERM_NAMES])

    def hysteresis_vector(self) -> np.ndarray:
        """Coefficients in ``HYSTERESIS_TERM_NAMES`` order (absent terms are 0).

        Returns
        -------
        numpy.ndarray
            One coefficient per hysteresis term.
        """
        return np.array([self.hysteresis.get(k, 0.0) for k in HYSTERESIS_TERM_NAMES])

    @property
    def has_state(self) -> bool:
        """True when the model carries a hysteretic state ``z``."""
        return any(v != 0.0 for v in self.hysteresis.values())

    def term(self, name: str, theta, theta_dot, z, i) -> np.ndarray:
        """The values of torque term ``name`` (:data:`SHEAR_TERM` at this model's ``m``).

        Parameters
        ----------
        name : str
            A key of :data:`TORQUE_TERMS`.
        theta, theta_dot, z, i : float or numpy.ndarray
            Angle (or displacement), its rate, the hysteretic state and the current
            (broadcast together).

        Returns
        -------
        numpy.ndarray
            The term's values (a current term sees :meth:`current`).

        Examples
        --------
        >>> tm = TermModel({SHEAR_TERM: 1.0}, m=0.25)
        >>> round(float(tm.term(SHEAR_TERM, 0.0, 16.0, 0.0, 0.0)), 6)
        2.0
        """
        if name == SHEAR_TERM:
            return TORQUE_TERMS[name](theta, theta_dot, z, i, self.m)
        if name.startswith("i*") and name[2:] in self.saturation:
            i = self.current(name[2:], i)
        return TORQUE_TERMS[name](theta, theta_dot, z, i)

    def eval_torque(self, theta, theta_dot, z, i) -> np.ndarray:
        """Damper (plus spring) torque for arrays of states at current(s) ``i``.

        Parameters
        ----------
        theta, theta_dot, z, i : float or numpy.ndarray
            Angle (or displacement), its rate, the hysteretic state and the current
            (broadcast together).

        Returns
        -------
        numpy.ndarray
            The sum of the torque terms times their coefficients.
        """
        out = np.zeros(np.broadcast(theta, theta_dot, z, i).shape)
        for name, c in self.torque.items():
            if c != 0.0:
                out = out + c * self.term(name, theta, theta_dot, z, i)
        return out

    def eval_rate(self, theta_dot, z) -> np.ndarray:
        """Hysteretic rate ``dz/dt``.

        Parameters
        ----------
        theta_dot, z : float or numpy.ndarray
            Velocity and hysteretic state (broadcast together).

        Returns
        -------
        numpy.ndarray
            The sum of the hysteresis terms times their coefficients.
        """
        out = np.zeros(np.broadcast(theta_dot, z).shape)
        for name, c in self.hysteresis.items():
            if c != 0.0:
                out = out + c * HYSTERESIS_TERMS[name](theta_dot, z, self.n)
        return out

    def __add__(self, other: TermModel) -> TermModel:
        torque = dict(self.torque)
        for k, v in other.torque.items():
            torque[k] = torque.get(k, 0.0) + v
        hyst = dict(self.hysteresis)
        for k, v in other.hysteresis.items():
            hyst[k] = hyst.get(k, 0.0) + v
        m = self.m if SHEAR_TERM in self.torque else other.m
        sat = {**other.saturation, **self.saturation}
        return TermModel(torque, hyst, self.n, self.J, m, self.delay, sat, self.play or other.play)

    def equations(self, precision: int = 4) -> str:
        """pysindy-style two-line print of the model (a third line for a channel delay).

        Parameters
        ----------
        precision : int, default 4
            Significant digits of the coefficients.

        Returns
        -------
        str
            ``T = ...`` and ``dz/dt = ...``, one per line.

        Examples
        --------
        >>> print(TermModel({"theta_dot": 2.0}, delay=0.004).equations())
        T = 2 theta_dot
        dz/dt = 0
        measured(t) = model(t - 0.004 s)
        """

        def power(e: float) -> str:  # "*|z|^e", written plainly for e = 0 and 1
            txt = f"{e:.{precision}g}"
            return {"0": "", "1": "*|z|"}.get(txt, f"*|z|^{txt}")

        rate = format_equation("dz/dt", self.hysteresis, precision)
        rate = rate.replace("*|z|^(n-1)", power(self.n - 1.0)).replace("*|z|^n", power(self.n))
        torque = format_equation("T", self.torque, precision, self.saturation)
        torque = torque.replace("|theta_dot|^m", f"|theta_dot|^{self.m:.{precision}g}")
        out = torque + "\n" + rate
        if self.delay:
            out += f"\nmeasured(t) = model(t - {self.delay:.{precision}g} s)"
        if self.play:
            out += f"\ndamper motion = play(theta, {self.play:.{precision}g})"
        return out


def format_equation(
    lhs: str,
    coefs: Mapping[str, float],
    precision: int = 4,
    saturation: Mapping[str, float] | None = None,
) -> str:
    """Format ``lhs = c1 term1 + c2 term2`` like pysindy's ``print()``.

    A saturating term ``i*<group>`` (``saturation``: group -> ``i0``) is printed as
    ``c i0 tanh(i/i0)*<group>``."""
    parts = []
    sat = saturation or {}
    for name, c in coefs.items():
        if c == 0.0:
            continue
        term = "" if name == "1" else f" {name}"
        if name.startswith("i*") and name[2:] in sat:
            i0 = sat[name[2:]]
            c, term = c * i0, f" tanh(i/{i0:.{precision}g})*{name[2:]}"
        parts.append(f"{c:.{precision}g}{term}")
    rhs = " + ".join(parts) if parts else "0"
    return f"{lhs} = {rhs}".replace("+ -", "- ")
