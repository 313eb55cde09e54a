"""Models as small state-space systems: named states, parameters, a rate and an output.

A :class:`StateSpaceModel` is what the simulator integrates, whatever the physics::

    dx/dt = f(x, u, p)        (the compiled ``rate(x, u, p, dx)``)
    y     = g(x, u, p)        (the compiled ``output(x, u, p)``)

``x`` holds the named :attr:`~StateSpaceModel.states`, ``u`` the exogenous signals named
by :attr:`~StateSpaceModel.inputs` at the current time (an input force, an imposed
motion), and ``p`` one run's packed parameter vector, built by
:meth:`~StateSpaceModel.run_parameters` from named parameter values and the run's coil
current (the current law is folded in once per run). ``rate`` and ``output`` are numba
functions compiled once per model class; :func:`hystdisc.simulation.simulate_system`
integrates any model with one compiled integrator.

The term form (:mod:`hystdisc.models.terms`) is one such system, :class:`TermSystem`:
the states of the rig and the hysteretic state of the damper, with the rate and output
equations of :mod:`hystdisc.models.compiled`. A model with more states (an internal
degree of freedom, a compliant wheel, a filter) is a subclass with its own compiled
functions, and nothing else in the package needs to know about it: see
:mod:`hystdisc.models.wheel`.

Examples
--------
>>> from hystdisc.models import Model
>>> sys = TermSystem(Model("dahl").to_terms(), "release")
>>> sys.states, sys.inputs, sys.output
(('theta', 'theta_dot', 'z'), (), 'theta')
>>> sys.run_parameters({}, current=1.0)[:3].tolist()  # k_s, k_x, k_wa + k_wb * 1
[158.0, 0.8, 2.0]
"""

from __future__ import annotations

from collections.abc import Mapping

import numba
import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.models.compiled import (
    N_BASE,
    TERM_SIZE,
    base_coefficients,
    term_torque,
    term_vector,
    vector_rate,
)
from hystdisc.models.effects import apply_effects, scaled_effect_message
from hystdisc.models.params import RIG_PARAMS, Param, check_params
from hystdisc.models.terms import SIGN_EPS, TermModel
from hystdisc.registry import effect_names, family_names, get_effect, get_experiment, get_family


def carries(family: str) -> tuple[str, ...]:
    """The effects that scale a force of the model (:attr:`~hystdisc.models.effects.Effect.scaled`)
    which the family ``family`` carries: a term family those whose scaled terms it has, a
    state-space one those of its
    :attr:`~hystdisc.models.families.base.SystemFamily.scaled_effects`.

    Examples
    --------
    >>> carries("dahl"), carries("bingham"), carries("spencer")
    (('asymmetric_damping', 'asymmetric_yield'), ('asymmetric_damping',), ('asymmetric_yield',))
    """
    fam = get_family(family)
    out = []
    for name in effect_names():
        eff = get_effect(name)
        if not eff.scaled:
            continue
        if fam.is_system:
            if name in fam.scaled_effects:
                out.append(name)
        elif all(base in fam.torque_terms for _, _, base in eff.scaled):
            out.append(name)
    return tuple(out)


def delay_params() -> tuple[str, ...]:
    """The parameters of the registered effects that delay the recorded output
    (:attr:`~hystdisc.models.effects.Effect.delay_param`)."""
    found = (get_effect(n).delay_param for n in effect_names())
    return tuple(p for p in found if p)


def play_params() -> tuple[str, ...]:
    """The parameters of the registered effects that put a play between a driven test's
    measured motion and the damper (:attr:`~hystdisc.models.effects.Effect.play_param`)."""
    found = (get_effect(n).play_param for n in effect_names())
    return tuple(p for p in found if p)


class StateSpaceModel:
    """Base of every model the simulator integrates (see the module docstring).

    Subclasses set the class attributes and provide the compiled :attr:`rate` and
    :attr:`output` functions; the base owns the common work (named parameters checked
    against their admissible bounds, initial states, printing).

    Attributes
    ----------
    name : str
        Short name of the model.
    states : tuple of str
        Names of the state variables, in the order of ``x``.
    inputs : tuple of str
        Names of the exogenous signals, in the order of ``u`` (may be empty).
    output : str
        Name of the output ``y`` (the measured signal).
    params : tuple of Param
        Named parameters with units and admissible bounds.
    rate : numba function
        ``rate(x, u, p, dx)`` writes ``dx/dt`` into ``dx``.
    observe : numba function
        ``observe(x, u, p)`` returns the output.
    rate_jac, observe_grad : numba function or None
        The partial derivatives, for exact sensitivities
        (:mod:`hystdisc.simulation.sensitivity_ode`); None when the model has none (its
        Jacobian is then taken by differences). ``rate_jac(x, u, p, need, jx, jp, work)``
        writes ``d rate / d x`` into ``jx`` (states x states) and ``d rate / d p`` into
        ``jp`` (states x ``len(p)``); ``observe_grad(x, u, p, need, gx, gp, work)`` writes
        the output's into ``gx`` and ``gp``. Each call writes every entry it ever makes
        nonzero (the caller zeroes the arrays once); ``need`` flags the entries of ``p``
        whose derivatives are wanted (others may be skipped), ``work`` is scratch of
        :data:`~hystdisc.simulation.sensitivity_ode.WORK_SIZE` floats.
    """

    name: str = ""
    states: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    output: str = ""
    params: tuple[Param, ...] = ()
    rate = None
    observe = None
    rate_jac = None
    observe_grad = None

    def check(self, values: Mapping[str, float]) -> dict[str, float]:
        """Every parameter's value (defaults for the unset ones), checked against its bounds.

        Raises
        ------
        HystdiscError
            For an unknown name, a non-finite value or one outside its admissible bounds.
        """
        return check_params(self.name, self.params, values)

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        """One run's packed parameter vector ``p`` (subclasses fold the current in)."""
        v = self.check(values)
        return np.array([v[p.name] for p in self.params], dtype=float)

    def initial_state(self, **given: float) -> np.ndarray:
        """A state vector: zeros except the named states given.

        Examples
        --------
        >>> from hystdisc.models import Model
        >>> TermSystem(Model("dahl").to_terms(), "release").initial_state(theta=0.3).tolist()
        [0.3, 0.0, 0.0]
        """
        x = np.zeros(len(self.states))
        for k, v in given.items():
            if k not in self.states:
                raise ValueError(f"{self.name}: no state '{k}'; states are {self.states}")
            x[self.states.index(k)] = float(v)
        return x

    def output_delay(self, values: Mapping[str, float]) -> float:
        """Delay (s) of the measured output behind the model's: a delay parameter of an
        effect (:attr:`~hystdisc.models.effects.Effect.delay_param`) among ``values``,
        else the delay of the term model the system is built around (a structural
        effect's), else 0."""
        for name in delay_params():
            if name in values:
                return float(values[name])
        terms = getattr(self, "terms", None)
        return float(terms.delay) if terms is not None else 0.0

    def input_play(self, values: Mapping[str, float]) -> float:
        """Half-width of a play between a driven test's measured motion and the model (the
        :mod:`~hystdisc.models.backlash` effect): a play parameter among ``values``, else
        the play of the term model the system is built around, else 0."""
        for name in play_params():
            if name in values:
                return float(values[name])
        terms = getattr(self, "terms", None)
        return float(terms.play) if terms is not None else 0.0

    def equations(self) -> str:  # pragma: no cover - documented by subclasses
        """The model's equations, one per line."""
        return ""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}: states {', '.join(self.states)}>"


# ----------------------------------------------------------------------------- term form
# p layout: term_vector (base coefficients, hysteresis, n), J, eps
_J = TERM_SIZE
_EPS = _J + 1


@numba.njit(cache=True, nogil=True)
def _mech_rate(x, u, p, dx):
    """Release/forced rig: ``J theta'' = u - T``, ``z' = g(theta', z)``."""
    th, w, z = x[0], x[1], x[2]
    uu = u[0] if u.shape[0] > 0 else 0.0
    dx[0] = w
    dx[1] = (uu - term_torque(p[:N_BASE], th, w, z, p[_EPS])) / p[_J]
    dx[2] = vector_rate(p, w, z)


@numba.njit(cache=True, nogil=True)
def _mech_output(x, u, p):
    return x[0]


@numba.njit(cache=True, nogil=True)
def _driven_rate(x, u, p, dx):
    """Imposed motion ``u = (theta, theta_dot)``: only ``z`` is integrated."""
    dx[0] = vector_rate(p, u[1], x[0])


@numba.njit(cache=True, nogil=True)
def _driven_output(x, u, p):
    return term_torque(p[:N_BASE], u[0], u[1], x[0], p[_EPS])


class TermSystem(StateSpaceModel):
    """A model in term form as a state-space system, for one experiment type.

    Release and forced: states ``theta, theta_dot, z``, output ``theta`` (a forced run has
    the input ``u``). Driven: the motion is imposed (inputs ``theta, theta_dot``), the
    state is ``z`` and the output the torque.

    Parameters
    ----------
    terms : TermModel
        The model (a family's ``to_terms()``, a discovered structure, ...).
    experiment : str or Experiment
        ``release``, ``driven`` or ``forced``.
    """

    def __init__(self, terms: TermModel, experiment: str = "release") -> None:
        self.terms = terms
        self.experiment = get_experiment(experiment)
        self.name = f"term model ({self.experiment.name})"
        if self.experiment.motion_imposed:
            self.states, self.inputs, self.output = ("z",), ("theta", "theta_dot"), "torque"
            self.rate, self.observe = _driven_rate, _driven_output
        else:
            self.states, self.output = ("theta", "theta_dot", "z"), "theta"
            self.inputs = ("u",) if self.experiment.has_input else ()
            self.rate, self.observe = _mech_rate, _mech_output

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        """The term coefficients with ``current`` folded in (``values`` is not used: a
        term model carries its coefficients)."""
        tm = self.terms
        J = tm.J if self.experiment.inertia_identifiable else 1.0
        return np.concatenate([term_vector(tm, current), [J, SIGN_EPS]])

    def equations(self) -> str:
        return self.terms.equations()


# ----------------------------------------------------------------------- system families
# p layout of a system family's model: the effects' base coefficients (term form, current
# folded in), eps, k_s, J, then the family's own block (see its module)
EFFECTS_AT = 0
EPS_AT = N_BASE
KS_AT = N_BASE + 1
J_AT = N_BASE + 2
FAMILY_AT = N_BASE + 3


class FamilySystem(StateSpaceModel):
    """The state-space model of a system family (:class:`~hystdisc.models.families.base.SystemFamily`)
    for one experiment type, with catalogued torque effects added.

    Release and forced: the damper acts on the rig (``J theta'' = u - k_s theta - T``;
    ``J`` is a parameter only when the experiment identifies it); driven: the motion is
    imposed and the output is the damper's torque. The family's compiled functions read
    the parameter vector laid out as: the effects' term-form coefficients (current folded
    in), ``eps``, ``k_s``, ``J``, then the family's own block
    (:meth:`~hystdisc.models.families.base.SystemFamily.block`).

    Parameters
    ----------
    family : SystemFamily
        The family (its ``driven`` and ``mech`` compiled functions, states and block).
    experiment : str or Experiment
        ``release``, ``driven`` or ``forced``.
    effects : tuple of str
        Catalogued effects whose torque terms are added to the damper's.
    laws : dict, optional
        Current laws that are not linear (law name -> ``quadratic`` or ``saturating``):
        their coefficients (``alpha_i0``, ...) are parameters after the family's, and the
        family's :meth:`block` folds them in (``Family.law_value``).
    """

    def __init__(
        self,
        family,
        experiment: str = "driven",
        effects: tuple[str, ...] = (),
        laws: Mapping[str, str] | None = None,
    ) -> None:
        self.family = family
        self.laws = family.check_laws(laws)
        self.experiment = get_experiment(experiment)
        self.effects = tuple(get_effect(e).name for e in effects)
        self._effects = [get_effect(e) for e in self.effects]
        for eff in self._effects:
            # its share is of a torque term this family does not have, unless the family's
            # own compiled force carries it (its block reads the share)
            if eff.scaled and eff.name not in family.scaled_effects:
                carriers = [n for n in family_names() if eff.name in carries(n)]
                raise HystdiscError(scaled_effect_message(family.name, eff, carriers))
        exp = self.experiment
        self.name = f"{family.name} ({exp.name})"
        fam_params = tuple(p for p in family.params if p.name not in family.mech_drop)
        if exp.motion_imposed:
            self.states = family.driven_states
            self.inputs, self.output = ("theta", "theta_dot"), "torque"
            self.rate, self.observe = family.driven_rate, family.driven_output
            self.rate_jac, self.observe_grad = family.driven_rate_jac, family.driven_output_grad
            rig: tuple[Param, ...] = ()
            fam_params = family.params
        else:
            self.states = ("theta", "theta_dot", *family.mech_states)
            self.inputs = ("u",) if exp.has_input else ()
            self.output = "theta"
            self.rate, self.observe = family.mech_rate, family.mech_output
            self.rate_jac, self.observe_grad = family.mech_rate_jac, family.mech_output_grad
            rig = (RIG_PARAMS[0],) + ((RIG_PARAMS[1],) if exp.inertia_identifiable else ())
        eff_params = tuple(p for e in self._effects for p in e.params)
        self.params = (*fam_params, *family.law_params(self.laws), *rig, *eff_params)
        #: The structural effect the model is built around (a driven test's compliant
        #: mount), or None.
        self.structure = self._structural(family, exp)
        if self.structure is not None:
            self.states = family.mount_states
            self.rate, self.observe = family.mount_rate, family.mount_output
            self.rate_jac, self.observe_grad = family.mount_rate_jac, family.mount_output_grad

    def _structural(self, family, exp):
        """The one structural effect among the effects (None: none), checked buildable."""
        found = [e for e in self._effects if e.structural]
        if not found:
            return None
        if len(found) > 1 or not exp.motion_imposed or family.mount_rate is None:
            built = "driven tests" if family.mount_rate is not None else "no test"
            raise HystdiscError(
                f"{family.name}: {', '.join(e.name for e in found)} is built for {built} "
                f"of this family, not a {exp.name} one; fix: leave it out of the effects"
            )
        return found[0].structure

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        v = self.check(values)
        ks = v.get("k_s", 0.0)
        effects = apply_effects(TermModel(), self._effects, v, ks)
        head = base_coefficients(effects, current)
        tail = [SIGN_EPS, ks, v.get("J", 1.0)]
        out = [head, tail, self.family.block(v, current)]
        if self.structure is not None:
            s = self.structure
            out.append([v[s.inertia], v[s.stiffness], v[s.damping]])
        return np.concatenate(out)

    def equations(self) -> str:
        extra = "".join(f"\n+ {e.name}: {e.doc}" for e in self._effects)
        laws = self.family.law_equations(self.laws)
        if self.structure is not None:
            s = self.structure
            extra += (
                f"\nbehind the mount: {s.inertia}*y'' = {s.stiffness}*(theta - y) + "
                f"{s.damping}*(theta_dot - y_dot) - F(y, y_dot), the damper moving with y"
            )
        return self.family.equations() + (f"\n{laws}" if laws else "") + extra
