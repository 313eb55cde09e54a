"""Models: parameters, the term form, hysteresis families, effects and state-space systems.

Families and effects are looked up through :mod:`hystdisc.registry`; :data:`FAMILIES`
and :data:`EFFECTS` here are that registry's objects by name, in its order.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from hystdisc import registry
from hystdisc.models.effects import Effect, apply_effects
from hystdisc.models.families.base import CURRENT_LAWS, LAW_SUFFIX, Family
from hystdisc.models.model import Model
from hystdisc.models.params import BIG, RIG_PARAMS, Param, check_params
from hystdisc.models.terms import (
    EVEN_Z_TORQUE_TERMS,
    HYSTERESIS_TERM_NAMES,
    HYSTERESIS_TERMS,
    LAW_GROUPS,
    LAW_PREFIXES,
    SHEAR_M0,
    SHEAR_TERM,
    SIGN_EPS,
    TORQUE_TERM_NAMES,
    TORQUE_TERMS,
    Z_TORQUE_TERMS,
    TermModel,
    current_law,
    effective_current,
    format_equation,
    smooth_power,
    smooth_sign,
)

get_family = registry.get_family
get_effect = registry.get_effect


class _Registered(Mapping):
    """A live, read-only view of the registry: name -> object, in its order (what is
    registered later, a plugin's family or effect, is in it too)."""

    def __init__(self, names, get) -> None:
        self._names, self._get = names, get

    def __getitem__(self, name: str):
        if name not in self._names():
            raise KeyError(name)
        return self._get(name)

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())

    def __repr__(self) -> str:
        return f"<registered: {', '.join(self._names())}>"


#: Family name -> family object, in the registry's order.
FAMILIES: Mapping[str, Family] = _Registered(registry.family_names, registry.get_family)
#: Effect name -> effect object, in the registry's order.
EFFECTS: Mapping[str, Effect] = _Registered(registry.effect_names, registry.get_effect)

__all__ = [
    "BIG",
    "CURRENT_LAWS",
    "EFFECTS",
    "EVEN_Z_TORQUE_TERMS",
    "FAMILIES",
    "HYSTERESIS_TERMS",
    "HYSTERESIS_TERM_NAMES",
    "LAW_GROUPS",
    "LAW_PREFIXES",
    "LAW_SUFFIX",
    "RIG_PARAMS",
    "SHEAR_M0",
    "SHEAR_TERM",
    "SIGN_EPS",
    "TORQUE_TERMS",
    "TORQUE_TERM_NAMES",
    "Z_TORQUE_TERMS",
    "Effect",
    "Family",
    "Model",
    "Param",
    "TermModel",
    "apply_effects",
    "check_params",
    "current_law",
    "effective_current",
    "format_equation",
    "get_effect",
    "get_family",
    "smooth_power",
    "smooth_sign",
]
