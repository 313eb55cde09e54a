"""The effect catalogue: physical mechanisms a declared model may lack.

See doc/design.rst section 6 (closing the loop) for the catalogue and how it is used.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from hystdisc.models.params import BIG, Param


@dataclass(frozen=True)
class Effect:
    """A catalogued physical effect: parameters and the torque terms they add."""

    name: str
    params: tuple[Param, ...]
    terms: tuple[str, ...]
    doc: str
    to_torque: Callable[[Mapping[str, float], float], dict[str, float]]
    from_torque: Callable[[Mapping[str, float], float], dict[str, float]]


def _one_term_effect(name: str, param: Param, term: str, doc: str) -> Effect:
    """An effect whose single parameter is the coefficient of a single torque term."""
    return Effect(
        name,
        (param,),
        (term,),
        doc,
        lambda p, ks: {term: p[param.name]},
        lambda c, ks: {param.name: c.get(term, 0.0)},
    )


CURRENT_VISCOUS = _one_term_effect(
    "current_viscous",
    Param("c_i", "N*m*s/(rad*A)", -BIG, BIG, 0.6, "current-dependent viscous damping"),
    "i*theta_dot",
    "viscous damping that grows with current (the seed's finding for Dahl at 1 A)",
)

CURRENT_SATURATION = _one_term_effect(
    "current_saturation",
    Param("a_ii", "N*m/A^2", -BIG, BIG, -0.6, "quadratic current dependence of z torque"),
    "i^2*z",
    "hysteretic torque not linear in current (saturating field): i^2 * z",
)

COULOMB = _one_term_effect(
    "coulomb",
    Param("f_c", "N*m", -BIG, BIG, 0.3, "Coulomb (bearing) friction torque"),
    "sign(theta_dot)",
    "dry friction, f_c * sign(theta_dot)",
)

QUADRATIC_DAMPING = _one_term_effect(
    "quadratic_damping",
    Param("c_q", "N*m*s^2/rad^2", -BIG, BIG, 0.3, "quadratic (aerodynamic) damping"),
    "theta_dot*|theta_dot|",
    "damping growing with velocity squared, c_q * theta_dot*|theta_dot|",
)

CUBIC_STIFFNESS = _one_term_effect(
    "cubic_stiffness",
    Param("k_3", "N*m/rad^3", -BIG, BIG, 300.0, "cubic spring stiffness"),
    "theta^3",
    "large-angle stiffening of the spring (or gravity), k_3 * theta^3",
)

OFFSET = Effect(
    "offset",
    (Param("theta_off", "rad", -BIG, BIG, 0.02, "neutral angle of the spring"),),
    ("1",),
    "the spring's neutral angle differs from the sensor zero: k_s*(theta - theta_off)",
    lambda p, ks: {"1": -ks * p["theta_off"]},
    lambda c, ks: {"theta_off": -c.get("1", 0.0) / ks if ks else 0.0},
)
