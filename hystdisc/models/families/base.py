"""What a family is: its parameters and its mapping to and from the term form."""

from __future__ import annotations

from collections.abc import Mapping

from hystdisc.models.params import Param
from hystdisc.models.terms import TermModel


class Family:
    """One model family: its parameters and its mapping to and from the term form."""

    name: str = ""
    title: str = ""
    params: tuple[Param, ...] = ()
    normalization: str = ""
    torque_terms: tuple[str, ...] = ()
    hysteresis_terms: tuple[str, ...] = ()
    #: Parameters that multiply the current (fixed at 0 when every run has one current).
    current_params: tuple[str, ...] = ()
    #: Current laws: a name -> (passive parameter, its per-ampere slope), for the
    #: parameters whose value at current ``i`` is ``passive + slope * i`` (the seed's
    #: linear law; the staged fit of issue 15 chooses among other laws for them).
    current_laws: Mapping[str, tuple[str, str]] = {}
    #: Torque terms whose coefficient is one parameter (term -> parameter name), in the
    #: order of the term form.
    linear_torque: Mapping[str, str] = {}

    def param_names(self) -> list[str]:
        """Names of the damper parameters (rig parameters excluded)."""
        return [p.name for p in self.params]

    def defaults(self) -> dict[str, float]:
        """Demo defaults of the damper parameters."""
        return {p.name: p.default for p in self.params}

    def linear_coefs(self, p: Mapping[str, float]) -> dict[str, float]:
        """Coefficients of the :attr:`linear_torque` terms for the parameters ``p``."""
        return {term: p[name] for term, name in self.linear_torque.items()}

    def to_terms(self, p: Mapping[str, float]) -> TermModel:  # pragma: no cover - abstract
        raise NotImplementedError

    def from_terms(self, tm: TermModel) -> dict[str, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    def equations(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    #: False: the family is a term model (:meth:`to_terms`); True: a state-space system
    #: of its own (:class:`SystemFamily`).
    is_system: bool = False

    def __repr__(self) -> str:
        return f"<Family {self.name}: {', '.join(self.param_names())}>"


class SystemFamily(Family):
    """A family that is a state-space system of its own (an internal degree of freedom, a
    state the term form has no rate for): it is simulated by the error-controlled
    integrator, not written in terms.

    Subclasses provide :meth:`system` (the model for an experiment type, with added
    torque effects) and may report identifiable combinations of their parameters
    (:meth:`derived`) and the starts of an output-error fit (:meth:`starts`).
    """

    is_system = True

    def system(self, experiment: str, effects: tuple[str, ...] = ()):
        """The :class:`~hystdisc.models.system.FamilySystem` of this family for an
        experiment type, with the torque terms of ``effects`` added (the family's compiled
        ``driven_*``/``mech_*`` functions, states and :meth:`block`)."""
        from hystdisc.models.system import FamilySystem  # system.py builds on families

        return FamilySystem(self, experiment, effects)

    def derived(self, p: Mapping[str, float]) -> dict[str, float]:
        """Identifiable combinations of the parameters ``p`` (none by default)."""
        return {}

    def starts(
        self, base: Mapping[str, float], velocity: float = 1.0
    ) -> list[tuple[str, dict[str, float]]]:
        """Labelled starts of an output-error fit from a fitted standard Bouc-Wen ``base``
        (``velocity``: the runs' median peak velocity, for the families that need a scale)."""
        return [("defaults", self.defaults())]

    def to_terms(self, p):
        raise NotImplementedError(f"{self.name} is a state-space family: use system()")

    def from_terms(self, tm):
        raise NotImplementedError(f"{self.name} is a state-space family: use system()")
