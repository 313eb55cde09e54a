"""Free parameters <-> term model: what an output-error fit varies.

:class:`FamilyParametrization` fits a family's own parameters (plus the rig spring, the
inertia when it is identifiable, and the parameters of added effects);
:class:`TermParametrization` fits the coefficients of a discovered set of torque terms and
the shape constants of a hysteresis shape.

Examples
--------
>>> p = FamilyParametrization("dahl", "release", {})
>>> p.names[-1]
'k_s'
>>> sorted(p.terms(p.x0).hysteresis)
['theta_dot', '|theta_dot|*z']
"""

from __future__ import annotations

import numpy as np

from hystdisc.discovery import SHAPES
from hystdisc.errors import HystdiscError
from hystdisc.fitting.simulate import simulate_entries, simulate_systems
from hystdisc.models import (
    EFFECTS,
    HYSTERESIS_TERM_NAMES,
    RIG_PARAMS,
    Family,
    Param,
    TermModel,
    apply_effects,
    get_family,
)
from hystdisc.models.system import StateSpaceModel
from hystdisc.registry import get_experiment


class Parametrization:
    """Free parameters <-> a simulated model. Subclasses define names, start and bounds.

    The fit asks a parametrization for the model of a free vector (:meth:`model`),
    simulates a batch of (model, run) pairs with :meth:`simulate`, and reads whether the
    model has a hysteretic state (:meth:`has_state`: its initial value is then a nuisance
    parameter of runs that may start mid-motion). The term-form parametrizations simulate
    on the fixed-step term kernels; :class:`SystemParametrization` on the integrator of
    any state-space model.
    """

    names: list[str]
    x0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    normalization: str = ""

    def terms(self, x: np.ndarray) -> TermModel:  # pragma: no cover - abstract
        """The term model at the free parameter vector ``x``."""
        raise NotImplementedError

    def model(self, x: np.ndarray):
        """What :meth:`simulate` takes for the free vector ``x`` (the term model here)."""
        return self.terms(x)

    def has_state(self) -> bool:
        """The model carries a hysteretic state ``z``."""
        return bool(self.terms(self.x0).hysteresis)

    def simulate(self, data, models, runs, nuis, status_out=None, work_out=None):
        """Predicted outputs of (model, run) pairs (see :func:`simulate_entries`)."""
        return simulate_entries(data, models, runs, nuis, status_out, work_out)

    def params(self, x: np.ndarray) -> dict[str, float]:
        """Every reported parameter (free and derived) for the free vector ``x``."""
        return dict(zip(self.names, map(float, x), strict=True))


def _clip_start(x0, lo, hi):
    """Clip a start strictly inside the bounds (the projected Levenberg-Marquardt starts inside them)."""
    x0 = np.asarray(x0, dtype=float).copy()
    lo_in = np.where(np.isfinite(lo), lo + 1e-10 * (np.abs(lo) + 1e-3), lo)
    hi_in = np.where(np.isfinite(hi), hi - 1e-10 * (np.abs(hi) + 1e-3), hi)
    return np.clip(x0, lo_in, hi_in)


class FamilyParametrization(Parametrization):
    """A family's own parameters (+ its current laws' coefficients + rig ``k_s``/``J`` +
    effect parameters).

    Bouc-Wen families are normalized to ``z_sat = 1`` (``delta = beta + gamma``, so
    ``delta`` is derived); the other families carry their own scale. ``laws`` (law name
    -> ``linear``, ``quadratic`` or ``saturating``) gives a law of the family's
    ``current_laws`` that is not linear its coefficient as a free parameter (``alpha_i0``,
    :meth:`~hystdisc.models.Family.law_params`), carried into the term model
    (:meth:`~hystdisc.models.Family.apply_laws`) and into every :meth:`like`.

    Examples
    --------
    >>> par = FamilyParametrization("bouc-wen-std", "driven", {"alpha_i0": 0.5},
    ...                             laws={"alpha": "saturating"})
    >>> par.names
    ['alpha_1', 'alpha_2', 'c_1', 'c_2', 'beta', 'gamma', 'n', 'alpha_i0', 'k_s']
    >>> par.terms(par.x0).saturation
    {'z': 0.5}
    """

    def __init__(
        self,
        family: str | Family,
        experiment: str,
        start: dict[str, float],
        effects: tuple[str, ...] = (),
        fixed: dict[str, float] | None = None,
        normalization: str = "z_sat",
        laws: dict[str, str] | None = None,
    ) -> None:
        self.family = get_family(family) if isinstance(family, str) else family
        self.laws = self.family.check_laws(laws)
        self.fixed = dict(fixed or {})
        if normalization not in ("z_sat", "alpha_1"):
            raise HystdiscError(
                f"unknown normalization '{normalization}'; fix: use z_sat or alpha_1"
            )
        # a scale the family does not have is its own (z_sat)
        norm = normalization if normalization in self.family.normalizations else "z_sat"
        for k, v in self.family.fixed_by(norm).items():  # z in torque units: alpha_1 = 1
            self.fixed.setdefault(k, v)
        self.experiment = experiment
        self.effects = tuple(effects)
        self.norm = norm
        self.derived = list(self.family.derived_names(norm))
        self.normalization = (
            self.family.normalization
            if norm == "z_sat"
            else ", ".join(f"{k} = {v:g}" for k, v in self.family.fixed_by(norm).items())
            + " (z in torque units)"
        )
        specs: list[Param] = [
            p
            for p in (*self.family.params, *self.family.law_params(self.laws))
            if p.name not in self.derived and p.name not in self.fixed
        ]
        if "k_s" not in self.fixed:  # held, e.g., by the per-level fits of the laws
            specs.append(RIG_PARAMS[0])  # k_s
        if get_experiment(experiment).inertia_identifiable and "J" not in self.fixed:
            specs.append(RIG_PARAMS[1])  # J
        for e in self.effects:
            specs.extend(EFFECTS[e].params)
        self.specs = specs
        self.names = [p.name for p in specs]
        self.lower = np.array([p.lower for p in specs], dtype=float)
        self.upper = np.array([p.upper for p in specs], dtype=float)
        x0 = [start.get(p.name, p.default) for p in specs]
        self.x0 = _clip_start(x0, self.lower, self.upper)

    def like(self, start: dict[str, float], effects: tuple[str, ...]) -> FamilyParametrization:
        """The same family, normalization and fixed parameters with other ``effects`` (a
        :class:`StructuralParametrization` when one of them is structural)."""
        return family_parametrization(
            self.family, self.experiment, start, effects, self.fixed, self.norm, self.laws
        )

    def params(self, x):
        p = dict(zip(self.names, map(float, x), strict=True))
        p.update(self.fixed)
        return self.family.complete(p, self.norm)

    def rigid_terms(self, x) -> TermModel:
        """The term form of the family, rig spring and term effects: the whole model here;
        without the internal states of a structural effect in a
        :class:`StructuralParametrization`."""
        return FamilyParametrization.terms(self, x)

    def terms(self, x):
        p = self.params(x)
        tm = self.family.apply_laws(self.family.to_terms(p), p)
        tm.torque["theta"] = tm.torque.get("theta", 0.0) + p["k_s"]
        tm.J = p.get("J", 1.0)
        return apply_effects(tm, [EFFECTS[e] for e in self.effects], p, p["k_s"])


class TermParametrization(Parametrization):
    """Free coefficients of chosen torque terms plus the shape constants of a hysteresis shape."""

    def __init__(
        self,
        torque_terms,
        shape,
        start_coefs: dict[str, float],
        start_shape,
        J0=1.0,
        experiment="release",
    ):
        self.shape = SHAPES[shape] if isinstance(shape, str) else shape
        self.torque_terms = list(torque_terms)
        self.experiment = experiment
        self.normalization = "z_sat = 1" if self.shape.name != "none" else "none"
        self.names = list(self.torque_terms) + list(self.shape.shape_names)
        self.inertia = get_experiment(experiment).inertia_identifiable
        x0 = [start_coefs.get(k, 0.0) for k in self.torque_terms] + list(start_shape)
        lo = [-np.inf] * len(self.torque_terms) + [-np.inf] * len(self.shape.shape_names)
        hi = [np.inf] * len(self.names)
        if self.inertia:
            self.names.append("J")
            x0.append(J0)
            lo.append(1e-12)
            hi.append(np.inf)
        self.lower = np.array(lo, dtype=float)
        self.upper = np.array(hi, dtype=float)
        self.x0 = _clip_start(x0, self.lower, self.upper)

    def terms(self, x):
        nt = len(self.torque_terms)
        ns = len(self.shape.shape_names)
        b, n = self.shape.vector(np.asarray(x[nt : nt + ns]))
        hyst = {k: float(v) for k, v in zip(HYSTERESIS_TERM_NAMES, b, strict=True) if v != 0.0}
        tm = TermModel(dict(zip(self.torque_terms, map(float, x[:nt]), strict=True)), hyst, n)
        if self.inertia:
            tm.J = float(x[-1])
        return tm

    def params(self, x):
        nt = len(self.torque_terms)
        ns = len(self.shape.shape_names)
        p = dict(zip(self.torque_terms, map(float, x[:nt]), strict=True))
        p.update(self.shape.shape_dict(np.asarray(x[nt : nt + ns])))
        if self.inertia:
            p["J"] = float(x[-1])
        return p


class SystemParametrization(Parametrization):
    """The named parameters of any :class:`~hystdisc.models.system.StateSpaceModel`.

    Free parameters are the model's own (with their admissible bounds) minus ``fixed``;
    the model is simulated by the error-controlled integrator
    (:func:`~hystdisc.fitting.simulate.simulate_systems`), so a model with internal states
    (a compliant wheel, an internal degree of freedom) is fitted like a family.

    Parameters
    ----------
    model : StateSpaceModel
        The model.
    start : dict
        Start values (unset parameters start at their defaults).
    fixed : dict, optional
        Parameters held at a value.

    Examples
    --------
    >>> from hystdisc.models.wheel import BeamOnCompliantWheel
    >>> par = SystemParametrization(BeamOnCompliantWheel("dahl"), {"k_w": 800.0}, {"m_w": 0.3})
    >>> par.names[-2:], par.has_state()
    (['k_w', 'c_w'], True)
    """

    def __init__(
        self,
        model: StateSpaceModel,
        start: dict[str, float],
        fixed: dict[str, float] | None = None,
    ) -> None:
        self.system = model
        self.fixed = dict(fixed or {})
        specs = [p for p in model.params if p.name not in self.fixed]
        self.names = [p.name for p in specs]
        self.lower = np.array([p.lower for p in specs], dtype=float)
        self.upper = np.array([p.upper for p in specs], dtype=float)
        self.x0 = _clip_start([start.get(p.name, p.default) for p in specs], self.lower, self.upper)
        self.normalization = ""

    def params(self, x: np.ndarray) -> dict[str, float]:
        p = dict(zip(self.names, map(float, x), strict=True))
        p.update(self.fixed)
        return p

    def model(self, x: np.ndarray):
        return (self.system, self.params(x))

    def terms(self, x: np.ndarray) -> TermModel:
        raise HystdiscError(
            f"{self.system.name} is a state-space model, not a term model; fix: use "
            "model(x) and simulate()"
        )

    def has_state(self) -> bool:
        return "z" in self.system.states

    def simulate(self, data, models, runs, nuis, status_out=None, work_out=None):
        return simulate_systems(data, models, runs, nuis, status_out, work_out)


class FamilySystemParametrization(SystemParametrization):
    """A system family's own parameters (+ rig ``k_s``/``J`` + effect parameters), like
    :class:`FamilyParametrization` for the families in term form.

    The reported parameters add the family's identifiable combinations
    (:meth:`~hystdisc.models.families.base.SystemFamily.derived`), with intervals.

    Examples
    --------
    >>> par = FamilySystemParametrization("spencer", "driven", {"c1_a": 9.0})
    >>> par.names[:3], par.has_state()
    (['alpha_a', 'alpha_b', 'c0_a'], True)
    >>> sorted(k for k in par.params(par.x0) if k.startswith("c_post"))
    ['c_post_0', 'c_post_1']
    >>> FamilySystemParametrization("spencer", "driven", {}, laws={"alpha": "saturating"}).names[-1]
    'alpha_i0'
    """

    def __init__(
        self,
        family: str | Family,
        experiment: str,
        start: dict[str, float],
        effects: tuple[str, ...] = (),
        fixed: dict[str, float] | None = None,
        laws: dict[str, str] | None = None,
    ) -> None:
        self.family = get_family(family) if isinstance(family, str) else family
        self.experiment = experiment
        self.effects = tuple(effects)
        self.laws = self.family.check_laws(laws)
        super().__init__(self.family.system(experiment, self.effects, self.laws), start, fixed)
        self.normalization = self.family.normalization

    def like(
        self, start: dict[str, float], effects: tuple[str, ...]
    ) -> FamilySystemParametrization:
        """The same family, current laws and fixed parameters with other ``effects``."""
        return FamilySystemParametrization(
            self.family, self.experiment, start, effects, self.fixed, self.laws
        )

    def values(self, x: np.ndarray) -> dict[str, float]:
        """The model's own parameter values (free and fixed) for the free vector ``x``."""
        return super().params(x)

    def params(self, x: np.ndarray) -> dict[str, float]:
        p = self.values(x)
        p.update(self.family.derived(p))
        return p

    def model(self, x: np.ndarray):
        return (self.system, self.values(x))


class StructuralParametrization(FamilyParametrization, SystemParametrization):
    """A family plus effects of which one is *structural* (it adds states, e.g.
    ``series_compliance``): fitted as the state-space model that realizes it.

    Parameters, bounds and :meth:`like` are those of :class:`FamilyParametrization`
    (the structural effect's parameters among the effects'); :meth:`model` is the
    effect's state-space model (:meth:`~hystdisc.models.Effect.system_model`) around the
    rest of the model in term form (:meth:`rigid_terms`), simulated by the
    error-controlled integrator. :meth:`terms` raises as for any state-space model.

    Examples
    --------
    >>> par = family_parametrization("dahl", "release", {"k_w": 900.0}, ("series_compliance",))
    >>> type(par).__name__, par.names[-3:], par.has_state()
    ('StructuralParametrization', ['m_w', 'k_w', 'c_w'], True)
    >>> system, values = par.model(par.x0)
    >>> system.states, values["k_w"]
    (('theta', 'theta_dot', 'z', 'y', 'y_dot'), 900.0)
    """

    def __init__(self, *args, **kwargs) -> None:
        FamilyParametrization.__init__(self, *args, **kwargs)
        found = [e for e in self.effects if EFFECTS[e].structural]
        if len(found) != 1:
            raise HystdiscError(
                f"{self.family.name}: {len(found)} structural effects among "
                f"{', '.join(self.effects) or 'none'}; fix: add exactly one"
            )
        self.structure = EFFECTS[found[0]]
        self.system = self.structure.system_model(self.rigid_terms(self.x0), self.experiment)

    def model(self, x: np.ndarray):
        p = self.params(x)
        system = self.structure.system_model(self.rigid_terms(x), self.experiment)
        return (system, {q.name: p[q.name] for q in self.structure.params})

    def terms(self, x: np.ndarray) -> TermModel:
        return SystemParametrization.terms(self, x)

    def has_state(self) -> bool:
        return bool(self.rigid_terms(self.x0).hysteresis)

    def simulate(self, data, models, runs, nuis, status_out=None, work_out=None):
        return simulate_systems(data, models, runs, nuis, status_out, work_out)


def family_parametrization(
    family: str | Family,
    experiment: str,
    start: dict[str, float],
    effects: tuple[str, ...] = (),
    fixed: dict[str, float] | None = None,
    normalization: str = "z_sat",
    laws: dict[str, str] | None = None,
) -> FamilyParametrization:
    """A :class:`FamilyParametrization`, or a :class:`StructuralParametrization` when one
    of ``effects`` is structural (same arguments)."""
    cls = (
        StructuralParametrization
        if any(EFFECTS[e].structural for e in effects)
        else FamilyParametrization
    )
    return cls(family, experiment, start, tuple(effects), fixed, normalization, laws)
