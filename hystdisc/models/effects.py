"""The effect catalogue: physical mechanisms a declared model may lack.

See doc/design.rst section 6 (closing the loop) for the catalogue and how it is used.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hystdisc.models.params import BIG, Param
from hystdisc.models.terms import LAW_PREFIXES, SHEAR_M0, SHEAR_TERM, TermModel


@dataclass(frozen=True)
class Structure:
    """How a structural effect is realized: a state-space model built around the rest of
    the model, and the three parameters of its internal degree of freedom (an inertia, a
    stiffness and a damping), by which the closing loop lays its grid of starts
    (:mod:`hystdisc.closing.structural`).

    Attributes
    ----------
    build : callable
        ``build(terms, experiment)``: the state-space model around ``terms`` (the damper,
        rig spring and term effects) for an experiment type.
    inertia, stiffness, damping : str
        The names of the degree of freedom's inertia, stiffness and damping parameters.

    Examples
    --------
    >>> s = Structure(lambda terms, exp: None, "m", "k", "c")
    >>> v = s.values(stiffness=100.0, inertia=1.0, damping_ratio=0.5)
    >>> v, round(s.frequency(v), 4)
    ({'m': 1.0, 'k': 100.0, 'c': 10.0}, 1.5915)
    """

    build: Callable[[TermModel, str], Any]
    inertia: str
    stiffness: str
    damping: str

    def values(self, stiffness: float, inertia: float, damping_ratio: float) -> dict[str, float]:
        """The three parameters for a stiffness, an inertia and a damping ratio."""
        c = 2.0 * damping_ratio * np.sqrt(stiffness * inertia)
        return {self.inertia: inertia, self.stiffness: stiffness, self.damping: float(c)}

    def frequency(self, values: Mapping[str, float]) -> float:
        """The natural frequency (Hz) of the degree of freedom at ``values``."""
        return float(np.sqrt(values[self.stiffness] / values[self.inertia]) / (2.0 * np.pi))


#: The roles an effect may declare (:attr:`Effect.roles`).
ROLES = ("spring", "current_law", "measurement", "no_spring")


@dataclass(frozen=True)
class Effect:
    """A catalogued physical effect: parameters and the torque terms they add.

    Attributes
    ----------
    name : str
        Catalogue name.
    params : tuple of Param
        Its parameters; their bounds are what is physically admissible (a damping or a
        friction force is not negative).
    terms : tuple of str
        The torque terms it adds.
    doc : str
        What it is, in one line.
    to_torque, from_torque : callable
        Parameters (and the rig spring ``k_s``) to torque coefficients, and back.
    hint : str
        What the data point at when they want the effect with a sign outside its
        admissible bounds (it is then reported, not added).
    structure : Structure or None
        None for an effect in term form. A *structural* effect adds states instead of
        torque terms: its :class:`Structure` builds the
        :class:`~hystdisc.models.system.StateSpaceModel` that realizes it around the rest of
        the model in term form (:meth:`system_model`); it has no ``terms`` and is fitted as
        a state-space system.
    significance : tuple of str
        The parameters whose significance (value over standard error) says the effect is
        there; empty: all of them.
    experiments : tuple of str
        The experiment types the effect is built for; empty: all.
    rig : bool
        The effect belongs to the rig or the measurement chain (the spring's neutral angle,
        its stiffening, a delay between channels, a compliant wheel or mount), not to the
        damper: every family shares it, so the families are compared again with it when
        the loop accepts it (:mod:`hystdisc.closing.reselect`).
    exponents : tuple of (str, str)
        Parameters that are not torque coefficients but an exponent of the term model:
        (parameter name, :class:`~hystdisc.models.TermModel` attribute), e.g. the
        shear-thinning exponent ``("m_st", "m")``. The effect is absent when its torque
        coefficients are 0, whatever its exponents (:meth:`off_values`).
    roles : tuple of str
        What else the pipeline must know of it, from :data:`ROLES`: ``"spring"`` (its
        terms are linear in the angle: it means something only on a rig with a spring),
        ``"current_law"`` (a current law that is not linear: the staged fit, which chooses
        the laws, decides it), ``"measurement"`` (it acts on the record, not on the
        damper: every family carries it alike, and so does the staged fit's each level),
        ``"no_spring"`` (on a rig with a spring it is a spring effect already, the same
        model in other words: a constant force is the spring's neutral angle, ``offset``;
        it is tried only where the rig has no spring).
    scaled : tuple of (str, str, str)
        Terms whose coefficient is a share of a force the model already has:
        ``(parameter, term, base)`` adds the parameter's value times the model's
        coefficient of ``base`` to that of ``term``, and the same for their current laws
        (``i*``, ``i^2*`` and a saturating law's current). Bounds on such a share keep
        the sum admissible whatever the model's values (a damping that differs in tension
        and compression stays non-negative in both for ``|r_c| <= 1``). Such effects are
        applied after the others (:func:`apply_effects`): the share is of the whole force.
    shift_param : str
        The parameter that shifts the measured angle (the spring's neutral angle): the
        model plus the effect is restarted from the family fitted on the shifted data
        (:mod:`hystdisc.closing.motion_restart`); empty: none.
    delay_param : str
        The parameter that delays the recorded output behind the motion or input (s),
        written into the term model's ``delay`` (:meth:`apply`) and into a state-space
        model's output delay; empty: none.
    play_param : str
        The parameter that is the half-width of a play between a driven test's measured
        motion and the damper (:mod:`hystdisc.models.backlash`), written into the term
        model's ``play`` (:meth:`apply`); empty: none.
    """

    name: str
    params: tuple[Param, ...]
    terms: tuple[str, ...]
    doc: str
    to_torque: Callable[[Mapping[str, float], float], dict[str, float]]
    from_torque: Callable[[Mapping[str, float], float], dict[str, float]]
    hint: str = ""
    structure: Structure | None = None
    significance: tuple[str, ...] = ()
    experiments: tuple[str, ...] = ()
    rig: bool = False

    @property
    def structural(self) -> bool:
        """The effect adds states (a state-space model realizes it), not torque terms."""
        return self.structure is not None

    def system_model(self, terms, experiment: str = "release"):
        """The state-space model of a structural effect around ``terms`` (the rest of the
        model in term form: damper, rig spring, term effects) for ``experiment``.

        Examples
        --------
        >>> from hystdisc.models import Model, get_effect
        >>> get_effect("series_compliance").system_model(Model("dahl").to_terms()).states
        ('theta', 'theta_dot', 'z', 'y', 'y_dot')
        """
        if self.structure is None:
            raise ValueError(f"{self.name} is not a structural effect")
        return self.structure.build(terms, experiment)

    exponents: tuple[tuple[str, str], ...] = ()
    roles: tuple[str, ...] = ()
    shift_param: str = ""
    delay_param: str = ""
    play_param: str = ""
    scaled: tuple[tuple[str, str, str], ...] = ()

    @property
    def shares(self) -> tuple[str, ...]:
        """The parameters that are shares of a force of the model (:attr:`scaled`).

        Examples
        --------
        >>> ASYMMETRIC_YIELD.shares, COULOMB.shares
        (('r_y',), ())
        """
        return tuple(name for name, _, _ in self.scaled)

    def has_role(self, role: str) -> bool:
        """The effect has ``role`` (one of :data:`ROLES`).

        Examples
        --------
        >>> OFFSET.has_role("spring"), COULOMB.has_role("spring")
        (True, False)
        """
        if role not in ROLES:
            raise ValueError(f"unknown role '{role}'; use one of {', '.join(ROLES)}")
        return role in self.roles

    def apply(self, tm: TermModel, values: Mapping[str, float], k_s: float) -> TermModel:
        """Add the effect at parameters ``values`` to the term model ``tm`` (in place).

        Examples
        --------
        >>> tm = SHEAR_THINNING.apply(TermModel({"theta_dot": 1.0}), {"c_st": 2.0, "m_st": 0.4}, 0.0)
        >>> tm.torque, tm.m
        ({'theta_dot': 1.0, 'sign(theta_dot)*|theta_dot|^m': 2.0}, 0.4)
        """
        for k, v in self.to_torque(values, k_s).items():
            tm.torque[k] = tm.torque.get(k, 0.0) + v
        for name, term, base in self.scaled:
            share = float(values[name])
            for law in ("", *LAW_PREFIXES):
                if law + base in tm.torque:
                    a = share * tm.torque[law + base]
                    tm.torque[law + term] = tm.torque.get(law + term, 0.0) + a
            if base in tm.saturation:
                tm.saturation[term] = tm.saturation[base]
        for name, attr in self.exponents:
            setattr(tm, attr, float(values[name]))
        if self.delay_param:
            tm.delay = float(values[self.delay_param])
        if self.play_param:
            tm.play = float(values[self.play_param])
        return tm

    def off_values(self) -> dict[str, float]:
        """Parameter values at which the effect is absent: torque coefficients 0, exponents
        at their defaults (where the closing loop's score test switches the effect on).

        Examples
        --------
        >>> SHEAR_THINNING.off_values(), COULOMB.off_values()
        ({'c_st': 0.0, 'm_st': 0.5}, {'f_c': 0.0})
        """
        shape = {name for name, _ in self.exponents}
        return {p.name: (p.default if p.name in shape else 0.0) for p in self.params}

    def inadmissible(self, values: Mapping[str, float]) -> list[str]:
        """The parameters whose ``values`` lie outside their admissible bounds.

        Examples
        --------
        >>> QUADRATIC_DAMPING.inadmissible({"c_q": -1e5}), QUADRATIC_DAMPING.inadmissible({"c_q": 2.0})
        (['c_q'], [])
        """
        return [p.name for p in self.params if not p.lower <= values.get(p.name, 0.0) <= p.upper]


def apply_effects(
    tm: TermModel, effects: Iterable[Effect], values: Mapping[str, float], k_s: float
) -> TermModel:
    """Add ``effects`` at ``values`` to the term model ``tm`` (in place), those that
    scale a force of the model (:attr:`Effect.scaled`) last, so that their share is of
    the force with every other effect in it.

    Examples
    --------
    >>> tm = TermModel({"theta_dot": 1.0})
    >>> vals = {"r_c": 0.5, "c_i": 2.0}
    >>> apply_effects(tm, [ASYMMETRIC_DAMPING, CURRENT_VISCOUS], vals, 0.0).torque
    {'theta_dot': 1.0, 'i*theta_dot': 2.0, '|theta_dot|': 0.5, 'i*|theta_dot|': 1.0}
    """
    for eff in sorted(effects, key=lambda e: bool(e.scaled)):
        eff.apply(tm, values, k_s)
    return tm


def scaled_effect_reason(family: str, effect: Effect) -> str:
    """Why ``effect``, which scales torque terms of the model (:attr:`Effect.scaled`),
    has no form on the state-space family ``family`` (one whose compiled force does not
    carry it): its force is not a sum of torque terms, so the share would be of nothing
    and the effect zero.

    Examples
    --------
    >>> scaled_effect_reason("spencer", ASYMMETRIC_DAMPING)
    'spencer is a state-space family: its force has no theta_dot term for asymmetric_damping to scale (the form on it is not built)'
    """
    bases = ", ".join(dict.fromkeys(base for _, _, base in effect.scaled))
    return (
        f"{family} is a state-space family: its force has no {bases} term for {effect.name} "
        "to scale (the form on it is not built)"
    )


def scaled_effect_message(family: str, effect: Effect, families: Iterable[str]) -> str:
    """The one-line error for ``effect`` asked of the state-space family ``family``
    (:func:`scaled_effect_reason`), with the fix: one of ``families`` (those that carry
    it: the term families and the state-space families with its form).

    Examples
    --------
    >>> msg = scaled_effect_message("spencer", ASYMMETRIC_DAMPING, ["dahl", "tanh"])
    >>> msg.startswith("spencer: asymmetric_damping would be zero"), msg.endswith("(dahl, tanh)")
    (True, True)
    """
    return (
        f"{family}: {effect.name} would be zero: {scaled_effect_reason(family, effect)}; "
        f"fix: leave {effect.name} out, or use a family that carries it "
        f"({', '.join(families)})"
    )


def one_term_effect(name: str, param: Param, term: str, doc: str, hint: str = "") -> Effect:
    """An effect whose single parameter is the coefficient of a single torque term."""
    return Effect(
        name,
        (param,),
        (term,),
        doc,
        lambda p, ks: {term: p[param.name]},
        lambda c, ks: {param.name: c.get(term, 0.0)},
        hint,
    )


#: The single-term effects: name, parameter (unit, admissible bounds, demo value), the
#: torque term, what it is, and what a wish for an inadmissible sign points at.
_ONE_TERM = (
    (
        "current_viscous",
        Param("c_i", "N*m*s/(rad*A)", 0.0, BIG, 0.6, "current-dependent viscous damping"),
        "i*theta_dot",
        "viscous damping that grows with current (the seed's finding for Dahl at 1 A)",
        "a viscous force that falls with current: the family's own current terms overstate "
        "it, or the current law is not linear",
    ),
    (
        "current_saturation",
        Param("a_ii", "N*m/A^2", -BIG, BIG, -0.6, "quadratic current dependence of z torque"),
        "i^2*z",
        "hysteretic torque not linear in current (saturating field): i^2 * z",
        "",
    ),
    (
        "coulomb",
        Param("f_c", "N*m", 0.0, BIG, 0.3, "Coulomb (bearing) friction torque"),
        "sign(theta_dot)",
        "dry friction, f_c * sign(theta_dot)",
        "a force that falls where the velocity reverses: the model's yield force is too "
        "large at low velocity",
    ),
    (
        "quadratic_damping",
        Param("c_q", "N*m*s^2/rad^2", 0.0, BIG, 0.3, "quadratic (aerodynamic) damping"),
        "theta_dot*|theta_dot|",
        "damping growing with velocity squared, c_q * theta_dot*|theta_dot|",
        "a damping force that grows less than linearly with velocity: shear_thinning "
        "(c_st * sign(theta_dot)*|theta_dot|^m with m < 1), a yield force that saturates",
    ),
    (
        "cubic_stiffness",
        Param("k_3", "N*m/rad^3", -BIG, BIG, 300.0, "cubic spring stiffness"),
        "theta^3",
        "large-angle stiffening of the spring (or gravity), k_3 * theta^3",
        "",
    ),
)

CURRENT_VISCOUS, CURRENT_SATURATION, COULOMB, QUADRATIC_DAMPING, CUBIC_STIFFNESS = (
    one_term_effect(*row) for row in _ONE_TERM
)
CUBIC_STIFFNESS = replace(CUBIC_STIFFNESS, rig=True, roles=("spring",))  # the rig's spring
CURRENT_SATURATION = replace(CURRENT_SATURATION, roles=("current_law",))

OFFSET = Effect(
    "offset",
    (Param("theta_off", "rad", -BIG, BIG, 0.02, "neutral angle of the spring"),),
    ("1",),
    "the spring's neutral angle differs from the sensor zero: k_s*(theta - theta_off)",
    lambda p, ks: {"1": -ks * p["theta_off"]},
    lambda c, ks: {"theta_off": -c.get("1", 0.0) / ks if ks else 0.0},
    rig=True,
    roles=("spring",),
    shift_param="theta_off",
)

#: Admissible channel delay [s]: either sign, at most this long (a delay of a tenth of a
#: second between two channels of one acquisition is not a delay but a wrong record).
MAX_DELAY = 0.1

CHANNEL_DELAY = Effect(
    "channel_delay",
    (
        Param(
            "tau_d",
            "s",
            -MAX_DELAY,
            MAX_DELAY,
            0.002,
            "delay of the output channel behind the motion (driven) or the input (forced)",
        ),
    ),
    (),
    "a time delay between the two recorded channels: the measured output is the model's "
    "y(t - tau_d) (driven and forced experiments, fractional samples)",
    lambda p, ks: {},
    lambda c, ks: {"tau_d": 0.0},
    rig=True,
    roles=("measurement",),
    delay_param="tau_d",
)


SHEAR_THINNING = Effect(
    "shear_thinning",
    (
        Param("c_st", "N*m*(s/rad)^m", 0.0, BIG, 0.3, "shear-thinning viscous coefficient"),
        Param("m_st", "1", 1e-6, 1.0, SHEAR_M0, "shear-thinning exponent (0 < m <= 1)"),
    ),
    (SHEAR_TERM,),
    "post-yield viscous torque growing as |theta_dot|^m, m <= 1 (Herschel-Bulkley MR "
    "fluid), c_st * sign(theta_dot)*|theta_dot|^m",
    lambda p, ks: {SHEAR_TERM: p["c_st"]},
    # the stage-1 column is evaluated at the exponent SHEAR_M0
    lambda c, ks: {"c_st": c.get(SHEAR_TERM, 0.0), "m_st": SHEAR_M0},
    "a torque that grows faster than linearly with velocity (quadratic_damping), or a "
    "yield torque too large at low velocity",
    exponents=(("m_st", "m"),),
)


BIAS = Effect(
    "bias",
    (
        Param(
            "f_0",
            "N*m",
            -BIG,
            BIG,
            0.2,
            "force bias not tied to a spring (a gas accumulator's force, a load cell's zero)",
        ),
    ),
    ("1",),
    "a constant force not tied to a spring, f_0 (a gas accumulator's force, a zero of the "
    "force sensor): the same at every velocity and angle, so the yield force differs in "
    "tension and compression by 2 f_0",
    lambda p, ks: {"1": p["f_0"]},
    lambda c, ks: {"f_0": c.get("1", 0.0)},
    "",
    roles=("no_spring",),
)
"""A constant torque ``f_0``. Where the rig has a spring it is the spring's neutral angle
(``offset``, ``k_s * theta_off``), so it is tried only where it has none (role
``"no_spring"``): a driven characterization machine."""

CURRENT_BIAS = Effect(
    "current_bias",
    (
        Param("f_0a", "N*m", -BIG, BIG, 0.2, "force bias at 0 A (of current_bias)"),
        Param("f_0i", "N*m/A", -BIG, BIG, -0.2, "growth of the force bias with the current"),
    ),
    ("1", "i"),
    "a force bias that differs per current level, f_0a + f_0i * i (a field-dependent "
    "zero of the force sensor, a magnetized part's pull)",
    lambda p, ks: {"1": p["f_0a"], "i": p["f_0i"]},
    lambda c, ks: {"f_0a": c.get("1", 0.0), "f_0i": c.get("i", 0.0)},
    "",
    significance=("f_0i",),
    roles=("no_spring",),
)
"""The bias with its current law, ``f_0a + f_0i * i``, one effect: a bias whose mean
over the currents is small is not found by its constant or its slope alone (the loop adds
one effect at a time and does not try a rejected one again). It is there when its slope
is significant (``significance``); a bias the current does not change is :data:`BIAS`
(one parameter less). One parameter per current level would fit each level's bias but
predict no other level (the loop accepts an effect by its error on held-out conditions,
currents among them), and the parametrizations have no parameters per run but the
initial states: the bias is a law of the current, linear like the families' laws. On a
rig with a spring its constant is the spring's neutral angle (role ``"no_spring"``)."""

#: The term of :data:`ASYMMETRIC_DAMPING`: ``|theta_dot|``, a viscous torque even in the
#: velocity (with ``theta_dot`` it is a damping that differs in the velocity's sign).
ABS_RATE = "|theta_dot|"


def _share_start(c: Mapping[str, float], ks: float) -> dict[str, float]:
    """``r_c`` from stage-1 coefficients: the ``|theta_dot|`` torque over the viscous
    damping at the middle of a 0-1 A range (stage 1 fits the ``|theta_dot|`` term with one
    coefficient for all currents), kept within its bounds."""
    damping = c.get("theta_dot", 0.0) + 0.5 * c.get("i*theta_dot", 0.0)
    share = c.get(ABS_RATE, 0.0) / damping if damping > 0.0 else 0.0
    return {"r_c": float(np.clip(share, -1.0, 1.0))}


ASYMMETRIC_DAMPING = Effect(
    "asymmetric_damping",
    (
        Param(
            "r_c",
            "1",
            -1.0,
            1.0,
            0.3,
            "asymmetry of the viscous damping c: (1 + r_c) c for theta_dot > 0 (tension), "
            "(1 - r_c) c for theta_dot < 0 (compression)",
        ),
    ),
    (ABS_RATE,),
    "viscous damping that differs in tension and compression (a single-ended piston rod: "
    "the two chambers' areas differ), r_c * c(i) * |theta_dot| with c(i) the model's "
    "viscous damping and its current law",
    lambda p, ks: {},
    _share_start,
    "a damping that would be negative in one direction: a force even in the velocity "
    "that is not viscous (a force bias: bias, current_bias)",
    scaled=(("r_c", ABS_RATE, "theta_dot"),),
)
"""A share ``r_c`` of the model's linear viscous damping ``c(i) theta_dot`` that changes
sign with the velocity: ``c(i) theta_dot (1 + r_c sign(theta_dot))``. The damping is
``(1 + r_c) c`` in tension and ``(1 - r_c) c`` in compression, both non-negative for the
admissible ``|r_c| <= 1`` whatever the family's ``c`` (``|theta_dot|`` does no net work
over a symmetric cycle, so the energy check of the admissibility could not catch a
negative damping in one direction: the bounds do). A state-space family's damping is not
in the term form: the effect exists on one only where the family's own compiled force
carries it (:attr:`~hystdisc.models.families.base.SystemFamily.scaled_effects`: the tanh
family's ``c(i) x' (1 + r_c sign(x'))``)."""


#: The term of :data:`ASYMMETRIC_YIELD`: ``|z|``, a hysteretic torque even in ``z`` (with
#: ``z`` it is a yield force that differs in tension and compression).
ABS_Z = "|z|"


def _yield_share_start(c: Mapping[str, float], ks: float) -> dict[str, float]:
    """``r_y`` from stage-1 coefficients: the ``|z|`` torque over the hysteretic torque at
    the middle of a 0-1 A range, kept within its bounds (as :func:`_share_start`)."""
    alpha = c.get("z", 0.0) + 0.5 * c.get("i*z", 0.0)
    share = c.get(ABS_Z, 0.0) / alpha if alpha > 0.0 else 0.0
    return {"r_y": float(np.clip(share, -1.0, 1.0))}


ASYMMETRIC_YIELD = Effect(
    "asymmetric_yield",
    (
        Param(
            "r_y",
            "1",
            -1.0,
            1.0,
            0.3,
            "asymmetry of the hysteretic (yield) torque alpha: (1 + r_y) alpha for z > 0 "
            "(tension), (1 - r_y) alpha for z < 0 (compression)",
        ),
    ),
    (ABS_Z,),
    "a yield force that differs in tension and compression (a single-ended piston rod, "
    "a valve that favours one direction), r_y * alpha(i) * |z| with alpha(i) the model's "
    "hysteretic torque and its current law",
    lambda p, ks: {},
    _yield_share_start,
    "a yield force that would be negative in one direction: a force that does not follow "
    "the hysteretic state (a force bias: bias, current_bias)",
    scaled=(("r_y", ABS_Z, "z"),),
)
"""A share ``r_y`` of the model's hysteretic torque ``alpha(i) z`` that is even in ``z``:
``alpha(i) z (1 + r_y sign(z))``. Where ``z`` saturates (the post-yield branches) the
yield force is ``(1 + r_y) alpha`` in tension and ``(1 - r_y) alpha`` in compression, both
non-negative for the admissible ``|r_y| <= 1`` whatever the family's ``alpha`` (like
``|theta_dot|``, ``|z|`` does no net work over a symmetric cycle). A force bias shifts
both branches alike at every state; this one only where ``z`` is away from 0, so the two
differ at the velocity's reversals. Families without a hysteretic state (Bingham, whose
yield is ``sign(theta_dot)``) do not carry it; a state-space family's hysteretic torque is
not in the term form: the effect exists on one only where the family's own compiled force
carries it (:attr:`~hystdisc.models.families.base.SystemFamily.scaled_effects`: Spencer's
``alpha(i) z (1 + r_y sign(z))`` at the internal node, the tanh family's yield
``alpha(i) h (1 + r_y sign(h))`` with ``h`` its hyperbolic tangent)."""
