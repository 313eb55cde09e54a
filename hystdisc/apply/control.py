"""A fitted damper in a controller designer's hands: export to python-control.

:func:`to_control` turns a fitted model (a model in term form, or a state-space model
with its parameter values: what :meth:`hystdisc.results.Results.simulation_model`
returns) into a ``control.NonlinearIOSystem`` of the damper alone::

    inputs   theta, theta_dot, current   the motion across the damper (rad and rad/s, or
                                         m and m/s) and the coil current (A)
    states   the model's own             z (term families), Spencer's d and z, a mount's
                                         d, y_dot and z, ... (all 0 at t = 0)
    output   torque                      the damper's torque (N*m) or force (N)

The rate and output are the compiled equations hystdisc's simulators integrate
(:class:`~hystdisc.models.system.StateSpaceModel`), so the exported system is the same
ODE: fed the motion ``hystdisc predict`` imposes (:func:`driven_inputs`), it reproduces
the predicted torque up to the integrators' tolerances. The current may vary in time (a
semi-active controller switches it); the current law of the fit is evaluated at every
call (cached per current value). What the export leaves out, and why:

* the rig: a release or forced fit carries the rig's spring (the terms in ``theta``
  alone, :data:`~hystdisc.models.wheel.RIG_TERMS`, or a system family's ``k_s``) and
  inertia; the exported damper has neither (a driven fit's ``theta`` term is the
  damper's own stiffness and stays). A release fit's torque is per unit beam inertia.
* the measurement chain: a channel delay and a declared filter are properties of the
  recording, not of the damper.
* a structural effect on the rig (``series_compliance`` in a release fit: the beam on a
  compliant wheel) is part of the plant, not of the damper: export the family's own fit
  and put the wheel in the loop. A driven fit's compliant mount is exported (it sits
  between the measured motion and the damper).

The open library's accepted terms (``extra``, :attr:`hystdisc.results.Results.open_library`)
are added to the output from their names; a play's term through a state of its own
(``play_<k>``: the damper end's position behind the play of the k-th width, 0 at t = 0
as the motion is).

Examples
--------
>>> import numpy as np
>>> from hystdisc.models import Model
>>> sys = to_control(Model("dahl").to_terms(), "driven")
>>> sys.input_labels, sys.state_labels, sys.output_labels
(['theta', 'theta_dot', 'current'], ['z'], ['torque'])
>>> sys.dynamics(0.0, [0.0], [0.0, 1.0, 0.5]).tolist()  # dz/dt = rho theta_dot at z = 0
[20.0]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from hystdisc.apply.predict import signals
from hystdisc.data import Dataset
from hystdisc.errors import HystdiscError
from hystdisc.models import Model, TermModel
from hystdisc.models.system import FamilySystem, StateSpaceModel, TermSystem
from hystdisc.models.term_columns import play_term, term_column
from hystdisc.models.wheel import RIG_TERMS
from hystdisc.registry import get_experiment

#: Input names of the exported system, in order.
INPUTS = ("theta", "theta_dot", "current")
#: Output name of the exported system.
OUTPUT = "torque"
#: Tolerances that make ``control.input_output_response`` (``solve_ivp``) as accurate as
#: hystdisc's simulators: pass ``solve_ivp_kwargs=SOLVE_IVP_KWARGS``. The absolute one
#: matters where a state crosses zero: on a Spencer fit (``tests/test_control.py``) the
#: export was 1.5e-8 of the peak from a 1e-12 integration with ``atol`` 1e-13 and 2.8e-9
#: with 1e-14 (``rtol`` 1e-11 both).
SOLVE_IVP_KWARGS = {"rtol": 1e-11, "atol": 1e-14}
#: The share of a play's width over which the damper's end takes up the motion's velocity
#: in the exported system (:func:`to_control`'s ``extra``).
PLAY_RAMP = 1e-3
#: Tolerances for a system with a play term (``extra``): its ramp is stiff, which an
#: implicit method takes in its stride and an explicit one at 1e-11 crawls through.
PLAY_SOLVE_IVP_KWARGS = {"method": "LSODA", "rtol": 1e-8, "atol": 1e-10}
#: Currents whose packed parameters are kept (a switching controller uses two or three).
CACHE_SIZE = 64

_FIX = "fix: pip install 'hystdisc[control]' (python-control >= 0.10)"


def _control():
    """The python-control module, or a one-line error naming the extra to install."""
    try:
        import control
    except ImportError:
        raise HystdiscError(f"python-control is not installed; {_FIX}") from None
    return control


def damper_model(
    model: TermModel | tuple[StateSpaceModel, Mapping[str, float]], experiment: str
) -> tuple[StateSpaceModel, dict[str, float]]:
    """The damper of a fitted model as a motion-imposed state-space model and its values.

    Parameters
    ----------
    model : TermModel or (StateSpaceModel, dict)
        The fitted model (:meth:`hystdisc.results.Results.simulation_model`).
    experiment : str
        The experiment it was fitted on: a release or forced fit loses its rig (the terms
        in ``theta`` alone, the spring ``k_s``, the inertia); a driven fit is the damper.

    Returns
    -------
    system : StateSpaceModel
        Inputs ``theta, theta_dot``, output ``torque``.
    values : dict
        Its parameter values (empty for a term model, which carries its coefficients).

    Raises
    ------
    HystdiscError
        For a model whose damper cannot be separated from the rig (a structural effect of
        the rig).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> system, values = damper_model(Model("dahl").to_terms(), "release")
    >>> system.states, system.inputs, "theta" in system.terms.torque, values
    (('z',), ('theta', 'theta_dot'), False, {})
    """
    motion = get_experiment(experiment).motion_imposed
    if isinstance(model, TermModel):
        if not motion:  # the rig's spring is no part of the damper
            torque = {k: v for k, v in model.torque.items() if k not in RIG_TERMS}
            model = replace(model, torque=torque, hysteresis=dict(model.hysteresis))
        return TermSystem(model, "driven"), {}
    system, values = model
    if tuple(system.inputs) == ("theta", "theta_dot") and system.output == OUTPUT:
        return system, dict(values)
    if isinstance(system, FamilySystem):
        driven = FamilySystem(system.family, "driven", system.effects, system.laws)
        names = {p.name for p in driven.params}
        kept = {k: float(v) for k, v in values.items() if k in names}
        # the parameter a rig fit leaves out is the rig's spring (Spencer's k1, tanh's k)
        kept.update({k: 0.0 for k in system.family.mech_drop})
        return driven, kept
    raise HystdiscError(
        f"{system.name}: not exportable as a damper (the model holds the rig's structure, "
        "not only the damper); fix: export a family's own fit (family=...) and model the "
        "rig's structure in the loop"
    )


class _Packed:
    """A system's packed parameter vector as a function of the current (cached)."""

    def __init__(self, system: StateSpaceModel, values: Mapping[str, float]) -> None:
        self.system, self.values = system, dict(values)
        self.cache: dict[float, np.ndarray] = {}
        self(0.0)  # checks the values once, now

    def __call__(self, current: float) -> np.ndarray:
        key = float(current)
        p = self.cache.get(key)
        if p is None:
            if len(self.cache) >= CACHE_SIZE:
                self.cache.clear()
            p = np.ascontiguousarray(self.system.run_parameters(self.values, key))
            self.cache[key] = p
        return p


class _Extra:
    """The open library's terms on one sample: a play's from the state of its width (the
    damper end's position behind it), the others from their names
    (:func:`~hystdisc.models.term_columns.term_column`)."""

    def __init__(self, terms: Mapping[str, float]) -> None:
        self.static: dict[str, float] = {}
        #: (coefficient, index of the width, the lost velocity (else the gap), times i)
        self.plays: list[tuple[float, int, bool, bool]] = []
        self.widths: list[float] = []
        for name, c in terms.items():
            found = play_term(name)
            if found is None:
                term_column(name, np.zeros(1), np.zeros(1), 0.0, np.zeros(1))  # known?
                self.static[name] = float(c)
                continue
            r, lost, by_i = found
            if r not in self.widths:
                self.widths.append(r)
            self.plays.append((float(c), self.widths.index(r), lost, by_i))

    def rates(self, y: np.ndarray, theta: float, theta_dot: float) -> np.ndarray:
        """The velocity of the damper's end behind each play: the motion's while the gap
        is closed and pushing, 0 while it is open, and in between over the last
        :data:`PLAY_RAMP` of the width (a switch exactly at the width makes an ODE
        solver chatter across it; the ramp holds the gap within that share of it)."""
        out = np.zeros(len(self.widths))
        for k, r in enumerate(self.widths):
            push = (theta - y[k]) * np.sign(theta_dot)  # how far the gap is closed
            share = (push - (1.0 - PLAY_RAMP) * r) / (PLAY_RAMP * r)
            out[k] = theta_dot * min(max(share, 0.0), 1.0)
        return out

    def force(self, y: np.ndarray, u: np.ndarray, t: float) -> float:
        """The terms' sum at states ``y`` (the plays') and inputs ``u``."""
        theta, theta_dot, i = (float(v) for v in u[:3])
        th, w, tt = np.array([theta]), np.array([theta_dot]), np.array([t])
        f = sum(c * float(term_column(n, th, w, i, tt)[0]) for n, c in self.static.items())
        rates = self.rates(y, theta, theta_dot)
        for c, k, lost, by_i in self.plays:
            value = rates[k] - theta_dot if lost else y[k] - theta
            f += c * value * (i if by_i else 1.0)
        return float(f)


def to_control(
    model: TermModel | tuple[StateSpaceModel, Mapping[str, float]] | Model,
    experiment: str = "driven",
    name: str = "damper",
    extra: Mapping[str, float] | None = None,
) -> Any:
    """The damper of a fitted model as a ``control.NonlinearIOSystem``.

    Parameters
    ----------
    model : TermModel, (StateSpaceModel, dict) or Model
        The fitted model (:meth:`hystdisc.results.Results.simulation_model`), or a known
        damper (a :class:`~hystdisc.models.Model`, as the simulator runs it in
        ``experiment``).
    experiment : str
        The experiment the model was fitted on (see :func:`damper_model`).
    name : str
        The system's name in an interconnection.
    extra : dict of str to float, optional
        Terms added to the output, by name and coefficient (the open library's accepted
        terms: :class:`~hystdisc.results.loop_sections.LibraryRefitRecord`
        ``coefficients``); a play's adds a state ``play_<k>`` (simulate it with
        ``solve_ivp_kwargs=PLAY_SOLVE_IVP_KWARGS``).

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``theta, theta_dot, current``, output ``torque``, the model's states (see
        the module docstring). Simulate it with ``control.input_output_response(sys, T,
        U, solve_ivp_kwargs=SOLVE_IVP_KWARGS)`` from the zero state.

    Raises
    ------
    HystdiscError
        Without python-control, or for a model that is not exportable.

    Examples
    --------
    The torque of a Bouc-Wen damper under a sine, against hystdisc's own simulator:

    >>> import control
    >>> from hystdisc.models import Model
    >>> from hystdisc.simulation import simulate_driven
    >>> tm = Model("bouc-wen").to_terms()
    >>> t = np.linspace(0.0, 1.0, 201)
    >>> x, v = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    >>> resp = control.input_output_response(to_control(tm), t, [x, v, 0.5 + 0 * t],
    ...                                      solve_ivp_kwargs=SOLVE_IVP_KWARGS)
    >>> ref = simulate_driven(tm, t, 0.5, x, v).torque
    >>> bool(np.max(np.abs(resp.outputs[0] - ref)) < 1e-6 * np.max(np.abs(ref)))
    True
    """
    ct = _control()
    if isinstance(model, Model):  # a known damper: what the simulator runs for experiment
        model = model.system(experiment) if model.family.is_system else model.to_terms()
    system, values = damper_model(model, experiment)
    packed = _Packed(system, values)
    rate, observe, n = system.rate, system.observe, len(system.states)
    try:
        terms = _Extra(extra or {})
    except ValueError as err:
        raise HystdiscError(f"{err}; fix: pass the open library's own term names") from None
    labels = [*system.states, *(f"play_{k}" for k in range(len(terms.widths)))]

    def updfcn(t, x, u, params):
        dx = np.empty(len(labels))
        motion = np.array(u[:2], dtype=float)
        if n:
            rate(np.ascontiguousarray(x[:n], dtype=float), motion, packed(u[2]), dx[:n])
        dx[n:] = terms.rates(x[n:], motion[0], motion[1])
        return dx

    def outfcn(t, x, u, params):
        y = observe(
            np.ascontiguousarray(x[:n], dtype=float), np.array(u[:2], dtype=float), packed(u[2])
        )
        return np.array([y + terms.force(x[n:], u, t)])

    states = {"states": labels} if labels else {}  # none: a static damper (tanh)
    return ct.nlsys(
        updfcn if labels else None,
        outfcn,
        inputs=list(INPUTS),
        outputs=[OUTPUT],
        name=name,
        **states,
    )


def driven_inputs(dataset: Dataset) -> list[tuple[np.ndarray, np.ndarray]]:
    """The input of the exported system for every run of ``dataset``: ``(T, U)`` with
    ``U`` rows ``theta, theta_dot, current``, the motion ``hystdisc predict`` imposes.

    That motion is the fit's estimate of it (:func:`hystdisc.apply.predict.signals`:
    a periodic run's harmonic series, else local fits), and, when the rig file declares a
    filter on ``theta``, the motion rebuilt from the filtered record
    (:func:`hystdisc.measurement.chain.unfiltered_motion`).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> from hystdisc.simulation.synth import generate
    >>> data = generate(Model("dahl"), "driven", currents=(0.5,), duration=1.0, seed=0)
    >>> (T, U), = driven_inputs(data)
    >>> U.shape, float(U[2, 0])
    ((3, 1000), 0.5)
    """
    out = []
    for r, d in zip(dataset.runs, signals(dataset, get_experiment("driven")), strict=True):
        current = np.full(r.t.size, float(r.current))
        out.append((np.asarray(r.t, dtype=float), np.vstack([d.theta, d.theta_dot, current])))
    return out


def sas_rig(
    k_s: float = 158.0, m_w: float = 0.2, k_w: float = 5000.0, c_w: float = 5.0, name: str = "rig"
) -> Any:
    """The SAS rig's beam on a compliant wheel, driven by the road, as a control system.

    The rig of :class:`~hystdisc.models.wheel.BeamOnCompliantWheel` (per unit beam
    inertia: the damper's torque per unit inertia, as a release fit gives it) with the
    ground under the wheel moving (``road``)::

        theta_b''  = -k_s theta_b - T
        m_w y''    = T - k_w (y - road) - c_w (y' - road_dot)

    Parameters
    ----------
    k_s : float
        The beam's spring (the rig's ``k_s``).
    m_w, k_w, c_w : float
        The wheel's inertia, stiffness and damping (``series_compliance``'s defaults).
    name : str
        The system's name.

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``torque`` (the damper's), ``road``, ``road_dot``; states ``beam,
        beam_dot, wheel, wheel_dot``; outputs ``theta, theta_dot`` (the motion across the
        damper, the damper's inputs), ``beam, beam_dot, beam_ddot`` and ``wheel``.

    Examples
    --------
    >>> rig = sas_rig()
    >>> rig.output(0.0, [0.3, 0.0, 0.1, 0.0], [0.0, 0.0, 0.0])[:3].tolist()
    [0.19999999999999998, 0.0, 0.3]
    """
    ct = _control()

    def updfcn(t, x, u, params):
        th, w, y, v = x
        T, r, rd = u
        return np.array([w, -k_s * th - T, v, (T - k_w * (y - r) - c_w * (v - rd)) / m_w])

    def outfcn(t, x, u, params):
        th, w, y, v = x
        return np.array([th - y, w - v, th, w, -k_s * th - u[0], y])

    return ct.nlsys(
        updfcn,
        outfcn,
        inputs=["torque", "road", "road_dot"],
        states=["beam", "beam_dot", "wheel", "wheel_dot"],
        outputs=["theta", "theta_dot", "beam", "beam_dot", "beam_ddot", "wheel"],
        name=name,
    )


def skyhook(i_max: float = 1.0, i_min: float = 0.0, name: str = "skyhook") -> Any:
    """The on-off skyhook law as a static control system: the current is ``i_max`` when
    the beam's absolute velocity and the velocity across the damper have the same sign
    (the damper's force then opposes the beam's motion), else ``i_min``.

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``beam_dot, theta_dot``, output ``current``.

    Examples
    --------
    >>> law = skyhook(i_max=1.0)
    >>> float(law.output(0.0, [], [0.5, 0.2])[0]), float(law.output(0.0, [], [0.5, -0.2])[0])
    (1.0, 0.0)
    """
    ct = _control()

    def outfcn(t, x, u, params):
        return np.array([i_max if u[0] * u[1] > 0.0 else i_min])

    return ct.nlsys(None, outfcn, inputs=["beam_dot", "theta_dot"], outputs=["current"], name=name)


def closed_loop(damper: Any, rig: Any, controller: Any, name: str = "loop") -> Any:
    """The damper, the rig and the controller connected by their signal names.

    Returns
    -------
    control.InterconnectedSystem
        Inputs ``road, road_dot``; outputs ``beam, beam_dot, beam_ddot, wheel,
        theta_dot, current, torque``; the states of the three.

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> loop = closed_loop(to_control(Model("bouc-wen").to_terms(), "release"), sas_rig(),
    ...                    skyhook())
    >>> loop.input_labels, loop.nstates
    (['road', 'road_dot'], 5)
    """
    ct = _control()
    outputs = ["beam", "beam_dot", "beam_ddot", "wheel", "theta_dot", "current", "torque"]
    inputs = ["road", "road_dot"]
    return ct.interconnect(
        [damper, rig, controller],
        inplist=inputs,
        outlist=outputs,
        inputs=inputs,
        outputs=outputs,
        name=name,
    )
