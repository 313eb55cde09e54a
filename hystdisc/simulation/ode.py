"""One compiled integrator for every state-space model.

:func:`simulate_system` integrates any :class:`~hystdisc.models.system.StateSpaceModel`
(its compiled ``rate`` and ``observe`` functions) on a sample grid with the embedded
Dormand–Prince 5(4) pair and error control: steps end on every sample, the exogenous
inputs are linear between samples, and a step that crosses a kink of the rate (a
velocity reversal, ``|z|^n`` at zero) is rejected and retried smaller, so the error stays
within the tolerances there too; so is a trial step whose stages leave the finite numbers
(a long step past a sharp yield overflows ``|z|^n``). A run fails only when its step
budget is spent. numba compiles the integrator once per model class and caches it on disk
(:mod:`hystdisc.simulation.specialize`).

The seed's families have their own fixed-step kernels (:mod:`hystdisc.simulation.kernels`),
tuned for the many short simulations of a fit; both integrate the same compiled rate
equations, and the tests hold them to each other.

Examples
--------
>>> import numpy as np
>>> from hystdisc.models import Model
>>> from hystdisc.models.system import TermSystem
>>> sys = TermSystem(Model("dahl").to_terms(), "release")
>>> t = np.arange(0.0, 1.0, 1e-3)
>>> out = simulate_system(sys, t, sys.initial_state(theta=0.3), current=0.5)
>>> out.y.shape, round(float(out.y[0]), 3), sorted(out.x)
((1000,), 0.3, ['theta', 'theta_dot', 'z'])
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numba
import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.models.system import StateSpaceModel
from hystdisc.simulation.specialize import specialize

#: Default relative and absolute tolerances of :func:`simulate_system`.
RTOL = 1e-8
ATOL = 1e-11
#: Steps (accepted or rejected) allowed per sample interval, on average over the run,
#: before a run is given up.
MAX_STEPS_PER_SAMPLE = 1_000
#: One sample interval may take up to this many times that budget (a burst of small
#: steps at a kink: ``|z|^n`` with ``n < 1`` is not Lipschitz at ``z = 0``, and the step
#: control shrinks the step there without the state being stiff), as long as the run's
#: steps so far stay within the budget times the intervals passed.
BURST = 50

# Dormand–Prince 5(4): nodes, stages, 5th-order weights and the error weights (5th - 4th);
# public with the step helpers below: the sensitivities (sensitivity_ode.py) take the same steps
C = (0.2, 0.3, 0.8, 8.0 / 9.0, 1.0)
A2 = (0.2,)
A3 = (3.0 / 40.0, 9.0 / 40.0)
A4 = (44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0)
A5 = (19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0)
A6 = (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0)
B = (35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0)
E = (
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
)


@numba.njit(cache=True, nogil=True)
def input_at(U, k, f, out):
    for j in range(out.shape[0]):
        out[j] = U[k, j] + (U[k + 1, j] - U[k, j]) * f


@numba.njit(cache=True, inline="always")
def over_budget(steps, total, k, max_steps):
    """The step budget is spent: ``steps`` in interval ``k`` beyond :data:`BURST` times
    ``max_steps``, or ``total`` steps beyond ``max_steps`` per interval so far."""
    return steps > BURST * max_steps or total > max_steps * (k + 1)


@numba.njit(cache=True, inline="always")
def finite_error(err, x5):
    """``err``, or infinity when the trial step left the finite numbers (its error estimate
    or its solution is not finite): a step too long for a fast or stiff state (a
    Bouc-Wen ``z`` driven past saturation by a long trial step overflows ``|z|^n``) is
    rejected and retried shorter like any other, and a run that truly diverges ends by
    the step budget (:func:`over_budget`)."""
    if not np.isfinite(err):
        return np.inf
    for i in range(x5.shape[0]):
        if not np.isfinite(x5[i]):
            return np.inf
    return err


@numba.njit(cache=True, inline="always")
def next_step(err, h, hh, cut):
    """The step size to try after a step of size ``hh`` (``cut``: shortened from ``h`` to
    end on a sample) whose scaled error is ``err`` (accepted when ``err <= 1``): the one
    step-size rule of every loop here and of the sensitivities' (they must take the same
    steps)."""
    fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err**-0.2))
    # a step cut short at a sample does not shrink the next one
    return max(h, hh * fac) if (err <= 1.0 and cut) else hh * fac


def stages(x, U, k, tt, span, hh, p, ks, xt, u, x5):
    """The first six stages of a Dormand–Prince step of size ``hh`` from ``x`` at ``t[k] +
    tt`` into ``ks[:6]``, and the 5th-order solution into ``x5``."""
    n = x.shape[0]
    input_at(U, k, tt / span, u)
    rate(x, u, p, ks[0])  # noqa: F821
    for s in range(1, 6):
        for i in range(n):
            acc = 0.0
            if s == 1:
                acc = A2[0] * ks[0, i]
            elif s == 2:
                acc = A3[0] * ks[0, i] + A3[1] * ks[1, i]
            elif s == 3:
                acc = A4[0] * ks[0, i] + A4[1] * ks[1, i] + A4[2] * ks[2, i]
            elif s == 4:
                acc = A5[0] * ks[0, i] + A5[1] * ks[1, i] + A5[2] * ks[2, i] + A5[3] * ks[3, i]
            else:
                acc = (
                    A6[0] * ks[0, i]
                    + A6[1] * ks[1, i]
                    + A6[2] * ks[2, i]
                    + A6[3] * ks[3, i]
                    + A6[4] * ks[4, i]
                )
            xt[i] = x[i] + hh * acc
        input_at(U, k, (tt + C[s - 1] * hh) / span, u)
        rate(xt, u, p, ks[s])  # noqa: F821
    for i in range(n):
        acc = 0.0
        for s in range(6):
            acc += B[s] * ks[s, i]
        x5[i] = x[i] + hh * acc


def step_error(x, x5, U, k, tt, span, hh, p, ks, u, rtol, atol):
    """Scaled RMS error estimate of the step ``x -> x5`` whose first six stages are in
    ``ks`` (the seventh goes into ``ks[6]``)."""
    n = x.shape[0]
    input_at(U, k, (tt + hh) / span, u)
    rate(x5, u, p, ks[6])  # noqa: F821
    err = 0.0
    for i in range(n):
        e = 0.0
        for s in range(7):
            e += E[s] * ks[s, i]
        sc = atol + rtol * max(abs(x[i]), abs(x5[i]))
        err += (hh * e / sc) ** 2
    return np.sqrt(err / n) if n > 0 else 0.0  # a model without states (algebraic)


def _integrate(x0, t, U, p, rtol, atol, X, Y, max_steps):
    """Dormand–Prince 5(4) over the samples ``t``; returns 0 (ok) or 1 (failed)."""
    n = x0.shape[0]
    x = x0.copy()
    ks = np.zeros((7, n))
    xt = np.empty(n)
    x5 = np.empty(n)
    u = np.empty(U.shape[1])
    X[0] = x
    input_at(U, 0, 0.0, u)
    Y[0] = observe(x, u, p)  # noqa: F821
    h = (t[1] - t[0]) if t.shape[0] > 1 else 0.0
    total = 0
    for k in range(t.shape[0] - 1):
        span = t[k + 1] - t[k]
        tt = 0.0  # time since t[k]
        steps = 0
        while tt < span:
            hh = min(h, span - tt)
            cut = hh < h
            stages(x, U, k, tt, span, hh, p, ks, xt, u, x5)
            err = finite_error(step_error(x, x5, U, k, tt, span, hh, p, ks, u, rtol, atol), x5)
            steps += 1
            total += 1
            if over_budget(steps, total, k, max_steps):
                return 1
            if err <= 1.0:
                tt += hh
                x[:] = x5
            h = next_step(err, h, hh, cut)
        X[k + 1] = x
        input_at(U, k, 1.0, u)
        Y[k + 1] = observe(x, u, p)  # noqa: F821
    return 0


def _integrate_lockstep(X0, t, U, P, rtol, atol, Y, max_steps):
    """:func:`_integrate` of the nominal copy (row 0 of the initial states ``X0`` and of
    the parameter vectors ``P``) with every other copy taking exactly its steps.

    Step sizes, rejections (a kink of the rate among them) and the ends at the samples
    are decided by the nominal's error estimate alone; an accepted step is then taken by
    each other copy with the same size (its six stages, no error estimate). The outputs
    go into ``Y`` (copies x samples), the nominal's bit for bit those of
    :func:`_integrate`. Returns 0 (ok) or 1 (the nominal failed).
    """
    m, n = X0.shape
    x = X0.copy()
    ks = np.zeros((7, n))
    kc = np.zeros((7, n))
    xt = np.empty(n)
    x5 = np.empty(n)
    u = np.empty(U.shape[1])
    input_at(U, 0, 0.0, u)
    for c in range(m):
        Y[c, 0] = observe(x[c], u, P[c])  # noqa: F821
    h = (t[1] - t[0]) if t.shape[0] > 1 else 0.0
    total = 0
    for k in range(t.shape[0] - 1):
        span = t[k + 1] - t[k]
        tt = 0.0
        steps = 0
        while tt < span:
            hh = min(h, span - tt)
            cut = hh < h
            stages(x[0], U, k, tt, span, hh, P[0], ks, xt, u, x5)
            err = finite_error(
                step_error(x[0], x5, U, k, tt, span, hh, P[0], ks, u, rtol, atol), x5
            )
            steps += 1
            total += 1
            if over_budget(steps, total, k, max_steps):
                return 1
            if err <= 1.0:
                x[0] = x5
                for c in range(1, m):  # the copies take the accepted step as it is
                    stages(x[c], U, k, tt, span, hh, P[c], kc, xt, u, x5)
                    x[c] = x5
                tt += hh
            h = next_step(err, h, hh, cut)
        input_at(U, k, 1.0, u)
        for c in range(m):
            Y[c, k + 1] = observe(x[c], u, P[c])  # noqa: F821
    return 0


@dataclass
class SystemResult:
    """Simulated signals of one run of a state-space model.

    Attributes
    ----------
    t : ndarray
        Sample times.
    x : dict of str to ndarray
        Each state's trajectory at the samples.
    y : ndarray
        The output at the samples.
    """

    t: np.ndarray
    x: dict[str, np.ndarray]
    y: np.ndarray


def _kernel(template, model: StateSpaceModel):
    """``template`` (:func:`_integrate` or :func:`_integrate_lockstep`) compiled for the
    model's ``rate`` and ``observe`` and cached on disk (its step helpers with it)."""
    rate = model.rate
    return specialize(
        template,
        rate=rate,
        observe=model.observe,
        stages=specialize(stages, rate=rate),
        step_error=specialize(step_error, rate=rate),
    )


def simulate_system(
    model: StateSpaceModel,
    t: np.ndarray,
    x0: Sequence[float],
    values: Mapping[str, float] | None = None,
    current: float = 0.0,
    inputs: Mapping[str, np.ndarray] | None = None,
    rtol: float = RTOL,
    atol: float = ATOL,
    max_steps_per_sample: int = MAX_STEPS_PER_SAMPLE,
) -> SystemResult:
    """Simulate one run of any state-space model.

    Parameters
    ----------
    model : StateSpaceModel
        The model (its compiled ``rate`` and ``observe``).
    t : ndarray
        Increasing sample times.
    x0 : sequence of float
        Initial state, in ``model.states`` order (see ``model.initial_state``).
    values : dict, optional
        Named parameter values (unset ones take their defaults).
    current : float
        The run's coil current.
    inputs : dict of str to ndarray, optional
        One array per name in ``model.inputs``, sampled at ``t``.
    rtol, atol : float
        Local error tolerances of the step control.
    max_steps_per_sample : int
        Steps (accepted or rejected) allowed per sample interval on average over the run
        (one interval may take :data:`BURST` times as many) before the run is given up as
        diverged or stalled (a fit caps it lower: a candidate too stiff to resolve is not
        worth resolving inside an optimizer).

    Returns
    -------
    SystemResult

    Raises
    ------
    HystdiscError
        When an input is missing or mis-sized, or the integration fails (the model
        diverges).
    """
    t = np.ascontiguousarray(t, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (len(model.states),):
        raise HystdiscError(
            f"{model.name}: the initial state has {x0.size} values for the states "
            f"{', '.join(model.states)}; fix: give one value per state"
        )
    U = input_matrix(model, t, inputs)
    p = np.ascontiguousarray(model.run_parameters(dict(values or {}), float(current)))
    X = np.full((t.size, x0.size), np.nan)
    Y = np.full(t.size, np.nan)
    status = _kernel(_integrate, model)(x0, t, U, p, rtol, atol, X, Y, int(max_steps_per_sample))
    if status:
        raise HystdiscError(
            f"{model.name}: the simulation diverged or stalled; fix: check the parameters"
        )
    return SystemResult(t, {s: X[:, j] for j, s in enumerate(model.states)}, Y)


def input_matrix(
    model: StateSpaceModel, t: np.ndarray, inputs: Mapping[str, np.ndarray] | None
) -> np.ndarray:
    """The exogenous inputs of ``model`` sampled at ``t``, one column per name in
    ``model.inputs``.

    Raises
    ------
    HystdiscError
        When an input is missing or not sampled at ``t``.
    """
    inputs = dict(inputs or {})
    missing = [k for k in model.inputs if k not in inputs]
    if missing:
        raise HystdiscError(
            f"{model.name}: input(s) {', '.join(missing)} missing; fix: pass inputs={{...}}"
        )
    U = np.zeros((t.size, len(model.inputs)))
    for j, k in enumerate(model.inputs):
        col = np.asarray(inputs[k], dtype=float)
        if col.shape != t.shape:
            raise HystdiscError(
                f"{model.name}: input '{k}' has {col.size} samples for {t.size} times; "
                "fix: sample it at t"
            )
        U[:, j] = col
    return U


def simulate_lockstep(
    model: StateSpaceModel,
    t: np.ndarray,
    x0: np.ndarray,
    p: np.ndarray,
    inputs: Mapping[str, np.ndarray] | None = None,
    rtol: float = RTOL,
    atol: float = ATOL,
    max_steps_per_sample: int = MAX_STEPS_PER_SAMPLE,
) -> np.ndarray | None:
    """Outputs of copies of one run integrated in lockstep with the nominal (the first).

    Internal numerical differentiation (Bock): every copy takes the steps the nominal's
    error control chose, so the outputs are one discrete solution map, smooth in the
    initial state and parameters, at several points, and their differences are
    derivatives of it whatever the tolerance (separately controlled runs would differ by
    their own step choices as well).

    Parameters
    ----------
    model : StateSpaceModel
        The model (its compiled ``rate`` and ``observe``).
    t : ndarray
        Increasing sample times.
    x0 : ndarray
        Each copy's initial state, shape ``(copies, states)``; row 0 is the nominal.
    p : ndarray
        Each copy's packed parameter vector (``model.run_parameters``), shape
        ``(copies, len(p))``.
    inputs : dict of str to ndarray, optional
        One array per name in ``model.inputs``, sampled at ``t``.
    rtol, atol : float
        Local error tolerances of the nominal's step control.
    max_steps_per_sample : int
        Steps allowed per sample interval (see :func:`simulate_system`).

    Returns
    -------
    ndarray or None
        The outputs, shape ``(copies, samples)``, row 0 bit for bit what
        :func:`simulate_system` gives; None when the nominal diverged or stalled. Another
        copy may hold non-finite values.
    """
    t = np.ascontiguousarray(t, dtype=float)
    x0 = np.ascontiguousarray(x0, dtype=float)
    p = np.ascontiguousarray(p, dtype=float)
    if x0.ndim != 2 or x0.shape[1] != len(model.states) or p.shape[0] != x0.shape[0]:
        raise HystdiscError(
            f"{model.name}: lockstep copies need initial states (copies, "
            f"{len(model.states)}) and parameters (copies, n); got {x0.shape}, {p.shape}"
        )
    U = input_matrix(model, t, inputs)
    Y = np.full((x0.shape[0], t.size), np.nan)
    with np.errstate(all="ignore"):
        status = _kernel(_integrate_lockstep, model)(
            x0, t, U, p, rtol, atol, Y, int(max_steps_per_sample)
        )
    return None if status else Y
