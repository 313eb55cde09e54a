"""The one registry of families, effects and experiment types.

Every list of names in the package (the CLI's choices and help, the report's tables, the
tests' parametrizations, the benchmarks) reads it from here. Entries are looked up by
dotted path and imported on first use, so listing names costs no import of numpy or
numba (``hystdisc --help`` stays fast).

To add a family: write its module under ``hystdisc/models/families/`` and add one line
to :data:`FAMILIES`; an effect, one object and one line in :data:`EFFECTS` (see
``doc/develop.rst``). A family or effect defined elsewhere (a plugin, a test) is added at
run time by :func:`register_family` / :func:`register_effect`, and taken away again by
:func:`unregister` (or used inside :func:`registered`).

Examples
--------
>>> from hystdisc import registry
>>> registry.family_names()
('bingham', 'dahl', 'lugre', 'bouc-wen', 'bouc-wen-std', 'spencer', 'tanh')
>>> registry.term_family_names()[-1]
'bouc-wen-std'
>>> registry.get_family("Bouc_Wen").name
'bouc-wen'
>>> registry.get_experiment("release").output
'theta'
>>> registry.get_effect("nope")
Traceback (most recent call last):
...
hystdisc.errors.HystdiscError: unknown effect 'nope'; fix: use one of current_viscous, current_saturation, coulomb, ...
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from hystdisc.errors import HystdiscError

#: Family name -> ``module:attribute`` of its (instantiated) family object (or the object).
FAMILIES: dict[str, Any] = {
    "bingham": "hystdisc.models.families.bingham:BINGHAM",
    "dahl": "hystdisc.models.families.dahl:DAHL",
    "lugre": "hystdisc.models.families.lugre:LUGRE",
    "bouc-wen": "hystdisc.models.families.boucwen:BOUC_WEN",
    "bouc-wen-std": "hystdisc.models.families.boucwen:BOUC_WEN_STD",
    "spencer": "hystdisc.models.families.spencer:SPENCER",
    "tanh": "hystdisc.models.families.tanh:TANH",
}

#: Effect name -> ``module:attribute`` of its effect object (or the object).
EFFECTS: dict[str, Any] = {
    "current_viscous": "hystdisc.models.effects:CURRENT_VISCOUS",
    "current_saturation": "hystdisc.models.effects:CURRENT_SATURATION",
    "coulomb": "hystdisc.models.effects:COULOMB",
    "quadratic_damping": "hystdisc.models.effects:QUADRATIC_DAMPING",
    "cubic_stiffness": "hystdisc.models.effects:CUBIC_STIFFNESS",
    "offset": "hystdisc.models.effects:OFFSET",
    "channel_delay": "hystdisc.models.effects:CHANNEL_DELAY",
    "series_compliance": "hystdisc.models.wheel:SERIES_COMPLIANCE",
    "shear_thinning": "hystdisc.models.effects:SHEAR_THINNING",
    "bias": "hystdisc.models.effects:BIAS",
    "current_bias": "hystdisc.models.effects:CURRENT_BIAS",
    "level_bias": "hystdisc.models.level_bias:LEVEL_BIAS",
    "asymmetric_damping": "hystdisc.models.effects:ASYMMETRIC_DAMPING",
    "asymmetric_yield": "hystdisc.models.effects:ASYMMETRIC_YIELD",
    "backlash": "hystdisc.models.backlash:BACKLASH",
}

#: Experiment name -> ``module:attribute`` of its experiment object.
EXPERIMENTS: dict[str, str] = {
    "release": "hystdisc.experiments.catalog:RELEASE",
    "driven": "hystdisc.experiments.catalog:DRIVEN",
    "forced": "hystdisc.experiments.catalog:FORCED",
}

_ALIASES = {"boucwen": "bouc-wen", "bw": "bouc-wen", "boucwen-std": "bouc-wen-std"}


def _resolve(path: Any) -> Any:
    if not isinstance(path, str):  # registered as the object itself
        return path
    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


def family_names() -> tuple[str, ...]:
    """Names of the registered families, in the order reports list them."""
    return tuple(FAMILIES)


def term_family_names() -> tuple[str, ...]:
    """Names of the families written in the term form (stage 1 has a shape for each);
    the others are state-space systems of their own (``Family.is_system``), fitted after
    them from their optima."""
    return tuple(n for n in FAMILIES if not get_family(n).is_system)


def register_family(family: Any, path: str | None = None) -> None:
    """Add ``family`` (a :class:`~hystdisc.models.Family` object, registered under its
    ``name``) to the registry, after the others.

    Parameters
    ----------
    family : Family
        The family object.
    path : str, optional
        Its ``module:attribute``, to be imported lazily instead (then ``family`` is its
        name).

    Raises
    ------
    HystdiscError
        When the name is taken.
    """
    name = family if path is not None else family.name
    if name in FAMILIES:
        raise HystdiscError(f"a family '{name}' is registered already; fix: choose another name")
    FAMILIES[name] = path if path is not None else family


def register_effect(effect: Any, path: str | None = None) -> None:
    """Add ``effect`` (a :class:`~hystdisc.models.Effect`, registered under its ``name``)
    to the catalogue, after the others (``path``: as for :func:`register_family`).

    Raises
    ------
    HystdiscError
        When the name is taken.
    """
    name = effect if path is not None else effect.name
    if name in EFFECTS:
        raise HystdiscError(f"an effect '{name}' is registered already; fix: choose another name")
    EFFECTS[name] = path if path is not None else effect


def unregister(name: str) -> None:
    """Take the family or effect ``name`` out of the registry (what
    :func:`register_family` or :func:`register_effect` added)."""
    FAMILIES.pop(name, None)
    EFFECTS.pop(name, None)


@contextmanager
def registered(*items: Any) -> Iterator[None]:
    """Families and effects registered inside the ``with`` block only.

    Examples
    --------
    >>> from hystdisc.models.effects import COULOMB
    >>> import dataclasses
    >>> extra = dataclasses.replace(COULOMB, name="dry_friction")
    >>> with registered(extra):
    ...     "dry_friction" in effect_names()
    True
    >>> "dry_friction" in effect_names()
    False
    """
    names = []
    try:
        for item in items:
            is_effect = hasattr(item, "to_torque")
            (register_effect if is_effect else register_family)(item)
            names.append(item.name)
        yield
    finally:
        for name in names:
            unregister(name)


def effect_names() -> tuple[str, ...]:
    """Names of the catalogued effects."""
    return tuple(EFFECTS)


def experiment_names() -> tuple[str, ...]:
    """Names of the experiment types."""
    return tuple(EXPERIMENTS)


def family_key(name: str) -> str:
    """The registered name for ``name`` (case, ``_`` and common aliases folded).

    Raises
    ------
    HystdiscError
        When no family has that name.
    """
    key = str(name).strip().lower().replace("_", "-")
    key = _ALIASES.get(key, key)
    if key not in FAMILIES:
        raise HystdiscError(f"unknown model '{name}'; fix: use one of {', '.join(FAMILIES)}")
    return key


def get_family(name: str) -> Any:
    """The family object registered under ``name`` (see :func:`family_key`)."""
    return _resolve(FAMILIES[family_key(name)])


def get_effect(name: str) -> Any:
    """The effect object registered under ``name``."""
    key = str(name).strip().lower().replace("-", "_")
    if key not in EFFECTS:
        raise HystdiscError(f"unknown effect '{name}'; fix: use one of {', '.join(EFFECTS)}")
    return _resolve(EFFECTS[key])


def get_experiment(name: Any) -> Any:
    """The experiment object for ``name`` (an experiment object is returned as it is)."""
    if hasattr(name, "motion_imposed"):
        return name
    key = str(name).strip().lower()
    if key not in EXPERIMENTS:
        raise HystdiscError(
            f"unknown experiment type '{name}'; fix: use one of {', '.join(EXPERIMENTS)}"
        )
    return _resolve(EXPERIMENTS[key])
