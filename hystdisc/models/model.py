"""A family with parameter values, rig parameters and effects."""

from __future__ import annotations

from collections.abc import Mapping

from hystdisc.models.effects import apply_effects
from hystdisc.models.params import RIG_PARAMS, check_params
from hystdisc.models.terms import TermModel
from hystdisc.registry import get_effect, get_family


class Model:
    """A family with parameter values, rig parameters and optional effects.

    Parameters
    ----------
    family : str
        Family name (see :func:`get_family`).
    params : dict, optional
        Damper and rig parameters (``k_s``, ``J``); unset ones take the demo defaults.
    effects : dict, optional
        Effect name -> dict of its parameters (unset ones take defaults).

    Notes
    -----
    A current law's coefficient among ``params`` (``alpha_i0``: the family's ``alpha``
    saturates, ``alpha_i2``: it is quadratic; see
    :meth:`~hystdisc.models.Family.law_params`) makes that law the model's.

    Examples
    --------
    >>> m = Model("bouc-wen", {"c_2": 0.0}, effects={"coulomb": {"f_c": 0.2}})
    >>> m.to_terms().torque["sign(theta_dot)"]
    0.2
    >>> Model("dahl", {"k_wb": 3.0, "k_w_i0": 0.3}).to_terms().saturation
    {'z': 0.3}
    >>> Model("dahl", {"rho": -1})
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: dahl: parameter rho=-1 is outside its physical bounds [1e-09, 1e+09]; fix: give a value within them
    """

    def __init__(
        self,
        family: str,
        params: Mapping[str, float] | None = None,
        effects: Mapping[str, Mapping[str, float]] | None = None,
    ) -> None:
        self.family = get_family(family)
        params = dict(params or {})
        laws = self.family.laws_of(params)
        specs = self.family.params + self.family.law_params(laws) + RIG_PARAMS
        self.params = check_params(self.family.name, specs, params)
        self.laws = laws
        self.effects: dict[str, dict[str, float]] = {}
        for name, ep in (effects or {}).items():
            eff = get_effect(name)
            self.effects[eff.name] = check_params(f"effect {eff.name}", eff.params, ep or {})

    @property
    def k_s(self) -> float:
        """The rig's spring stiffness ``k_s`` (a rig parameter of :attr:`params`)."""
        return self.params["k_s"]

    def system(self, experiment: str):
        """The model as a state-space system with its values, for a system family
        (:class:`~hystdisc.models.families.base.SystemFamily`).

        Parameters
        ----------
        experiment : str
            The experiment type the system simulates (``release``, ``driven``, ``forced``).

        Returns
        -------
        system : StateSpaceModel
            The family's system with this model's effects and current laws.
        values : dict of str to float
            The parameter values the system takes (its own and the effects').
        """
        sys = self.family.system(experiment, tuple(self.effects), self.laws)
        names = {p.name for p in sys.params}
        values = {k: v for k, v in self.params.items() if k in names}
        for ep in self.effects.values():
            values.update(ep)
        return sys, values

    def to_terms(self) -> TermModel:
        """The generic term form of this model (spring, damper and effects).

        Returns
        -------
        TermModel
            The family's terms with its current laws, the rig spring ``k_s`` on ``theta``,
            the inertia ``J`` and the effects applied.
        """
        tm = self.family.apply_laws(self.family.to_terms(self.params), self.params)
        tm.torque["theta"] = tm.torque.get("theta", 0.0) + self.params["k_s"]
        tm.J = self.params["J"]
        values = {k: v for ep in self.effects.values() for k, v in ep.items()}
        effects = [get_effect(name) for name in self.effects]
        return apply_effects(tm, effects, values, self.params["k_s"])

    def __repr__(self) -> str:
        ps = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        eff = "".join(
            f" + {k}({', '.join(f'{pk}={pv:g}' for pk, pv in ep.items())})"
            for k, ep in self.effects.items()
        )
        return f"Model({self.family.name}{eff}: {ps})"
