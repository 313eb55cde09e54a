"""Forward sensitivities of a state-space model, in one error-controlled integration.

:func:`simulate_system_sensitivities` integrates a
:class:`~hystdisc.models.system.StateSpaceModel` exactly as
:func:`~hystdisc.simulation.ode.simulate_system` does (the same Dormand–Prince steps,
rejections and sample ends: the output is the same to the last bit) and, along each
accepted step, the derivative of that step: every stage differentiated by the chain rule
with the model's compiled partial derivatives (``rate_jac``, ``observe_grad``), the step
sizes held at the values the error control chose (they are not differentiated). The
result is the exact derivative of the discrete solution (internal differentiation,
without the difference steps) with respect to chosen entries of the packed parameter
vector ``p`` and the initial state.

A direction costs a few multiplications per stage and state, against a whole simulation
per parameter for differences; rejected steps cost nothing extra.

Examples
--------
>>> import numpy as np
>>> from hystdisc.models.families.spencer import SPENCER
>>> sys = SPENCER.system("driven")
>>> t = np.linspace(0.0, 1.0, 201)
>>> x, v = 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)
>>> p = sys.run_parameters(SPENCER.defaults(), 1.0)
>>> a = len(p) - 5  # alpha (at 1 A) in the packed vector
>>> y, dy = simulate_system_sensitivities(sys, t, sys.initial_state(), p, [a],
...                                       inputs={"theta": x, "theta_dot": v})
>>> def out(q):  # a run integrated tightly, to check against
...     return simulate_system_sensitivities(sys, t, sys.initial_state(), q, [],
...         inputs={"theta": x, "theta_dot": v}, rtol=1e-12, atol=1e-15)[0]
>>> e = np.zeros(p.size); e[a] = 1e-5
>>> fd = (out(p + e) - out(p - e)) / 2e-5  # within the default tolerance's error
>>> bool(np.abs(fd - dy[:, 0]).max() < 1e-3 * np.abs(fd).max())
True
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numba
import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.models.system import StateSpaceModel
from hystdisc.simulation.ode import (
    A2,
    A3,
    A4,
    A5,
    A6,
    ATOL,
    MAX_STEPS_PER_SAMPLE,
    RTOL,
    B,
    C,
    finite_error,
    input_at,
    input_matrix,
    next_step,
    over_budget,
    stages,
    step_error,
)
from hystdisc.simulation.specialize import specialize

#: Floats of scratch a model's ``rate_jac`` and ``observe_grad`` may use.
WORK_SIZE = 32


@numba.njit(cache=True, inline="always")
def _stage_state(x, ks, s, hh, xt):
    """Stage ``s``'s state ``x + hh * sum_j a_sj ks[j]`` into ``xt`` (the arithmetic of
    :func:`~hystdisc.simulation.ode.stages`)."""
    for i in range(x.shape[0]):
        acc = 0.0
        if s == 1:
            acc = A2[0] * ks[0, i]
        elif s == 2:
            acc = A3[0] * ks[0, i] + A3[1] * ks[1, i]
        elif s == 3:
            acc = A4[0] * ks[0, i] + A4[1] * ks[1, i] + A4[2] * ks[2, i]
        elif s == 4:
            acc = A5[0] * ks[0, i] + A5[1] * ks[1, i] + A5[2] * ks[2, i] + A5[3] * ks[3, i]
        elif s == 5:
            acc = (
                A6[0] * ks[0, i]
                + A6[1] * ks[1, i]
                + A6[2] * ks[2, i]
                + A6[3] * ks[3, i]
                + A6[4] * ks[4, i]
            )
        xt[i] = x[i] + hh * acc


@numba.njit(cache=True, inline="always")
def _coef(s, j):
    """The Butcher coefficient ``a_sj`` (``j < s``)."""
    if s == 1:
        return A2[j]
    if s == 2:
        return A3[j]
    if s == 3:
        return A4[j]
    if s == 4:
        return A5[j]
    return A6[j]


def _sens_step(x, S, U, k, tt, span, hh, p, act, need, ks, xt, u, dk, dX, jx, jp, work):
    """Advance the sensitivities ``S`` (states x directions) over the accepted step of size
    ``hh`` from ``x`` whose stages are in ``ks``: each stage's derivative is
    ``jx (S + hh sum_j a_sj dk_j) + jp[:, act]``, the step's ``S + hh sum_s b_s dk_s``."""
    n, m = S.shape
    mp = act.shape[0]
    for s in range(6):
        if s == 0:
            for i in range(n):
                xt[i] = x[i]
            input_at(U, k, tt / span, u)
        else:
            _stage_state(x, ks, s, hh, xt)
            input_at(U, k, (tt + C[s - 1] * hh) / span, u)
        rate_jac(xt, u, p, need, jx, jp, work)  # noqa: F821
        for i in range(n):
            for c in range(m):
                acc = S[i, c]
                for j in range(s):
                    acc += hh * _coef(s, j) * dk[j, i, c]
                dX[i, c] = acc
        for i in range(n):
            for c in range(m):
                acc = 0.0
                for q in range(n):
                    acc += jx[i, q] * dX[q, c]
                if c < mp:
                    acc += jp[i, act[c]]
                dk[s, i, c] = acc
    for i in range(n):
        for c in range(m):
            acc = 0.0
            for s in range(6):
                acc += B[s] * dk[s, i, c]
            S[i, c] += hh * acc


def _output_sens(x, u, p, act, need, S, gx, gp, work, out):
    """The output's derivative along every direction into ``out``."""
    observe_grad(x, u, p, need, gx, gp, work)  # noqa: F821
    n, m = S.shape
    for c in range(m):
        acc = gp[act[c]] if c < act.shape[0] else 0.0
        for i in range(n):
            acc += gx[i] * S[i, c]
        out[c] = acc


def _integrate_sens(x0, S0, t, U, p, act, need, rtol, atol, Y, dY, max_steps):
    """:func:`~hystdisc.simulation.ode._integrate` (the same steps, the same outputs into
    ``Y``) with the sensitivities from ``S0`` along ``act`` (then the initial-state
    directions) into ``dY`` (samples x directions); returns 0 (ok) or 1 (failed)."""
    n = x0.shape[0]
    m = S0.shape[1]
    x = x0.copy()
    S = S0.copy()
    ks = np.zeros((7, n))
    xt = np.empty(n)
    x5 = np.empty(n)
    u = np.empty(U.shape[1])
    dk = np.zeros((6, n, m))
    dX = np.empty((n, m))
    jx = np.zeros((n, n))
    jp = np.zeros((n, p.shape[0]))
    gx = np.zeros(n)
    gp = np.zeros(p.shape[0])
    work = np.zeros(WORK_SIZE)
    input_at(U, 0, 0.0, u)
    Y[0] = observe(x, u, p)  # noqa: F821
    _output_sens(x, u, p, act, need, S, gx, gp, work, dY[0])
    h = (t[1] - t[0]) if t.shape[0] > 1 else 0.0
    total = 0
    for k in range(t.shape[0] - 1):
        span = t[k + 1] - t[k]
        tt = 0.0
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
                _sens_step(x, S, U, k, tt, span, hh, p, act, need, ks, xt, u, dk, dX, jx, jp, work)
                tt += hh
                x[:] = x5
            h = next_step(err, h, hh, cut)
        input_at(U, k, 1.0, u)
        Y[k + 1] = observe(x, u, p)  # noqa: F821
        _output_sens(x, u, p, act, need, S, gx, gp, work, dY[k + 1])
    return 0


def has_sensitivities(model: StateSpaceModel) -> bool:
    """Whether ``model`` has the compiled partial derivatives this module needs."""
    return model.rate_jac is not None and model.observe_grad is not None


def _kernel(model: StateSpaceModel):
    rate, jac = model.rate, model.rate_jac
    return specialize(
        _integrate_sens,
        rate=rate,
        observe=model.observe,
        observe_grad=model.observe_grad,
        stages=specialize(stages, rate=rate),
        step_error=specialize(step_error, rate=rate),
        _sens_step=specialize(_sens_step, rate_jac=jac),
        _output_sens=specialize(_output_sens, observe_grad=model.observe_grad),
    )


def simulate_system_sensitivities(
    model: StateSpaceModel,
    t: np.ndarray,
    x0: Sequence[float],
    p: np.ndarray,
    act: Sequence[int],
    start_states: Sequence[int] = (),
    inputs: Mapping[str, np.ndarray] | None = None,
    rtol: float = RTOL,
    atol: float = ATOL,
    max_steps_per_sample: int = MAX_STEPS_PER_SAMPLE,
) -> tuple[np.ndarray, np.ndarray] | None:
    """One run of ``model`` with the derivatives of its output.

    Parameters
    ----------
    model : StateSpaceModel
        A model with ``rate_jac`` and ``observe_grad`` (:func:`has_sensitivities`).
    t : ndarray
        Increasing sample times.
    x0 : sequence of float
        Initial state, in ``model.states`` order.
    p : ndarray
        The run's packed parameter vector (``model.run_parameters``).
    act : sequence of int
        Entries of ``p`` to differentiate along.
    start_states : sequence of int
        States whose initial values to differentiate along (after ``act``).
    inputs : dict of str to ndarray, optional
        One array per name in ``model.inputs``, sampled at ``t``.
    rtol, atol, max_steps_per_sample
        As for :func:`~hystdisc.simulation.ode.simulate_system` (the same steps follow).

    Returns
    -------
    (ndarray, ndarray) or None
        The output (bit for bit that of ``simulate_system``) and its derivatives, shape
        ``(samples, len(act) + len(start_states))``; None when the run diverged or
        stalled.
    """
    if not has_sensitivities(model):
        raise HystdiscError(f"{model.name}: no compiled partial derivatives; fix: take differences")
    t = np.ascontiguousarray(t, dtype=float)
    x0 = np.ascontiguousarray(x0, dtype=float)
    p = np.ascontiguousarray(p, dtype=float)
    act_a = np.asarray(act, dtype=np.int64).reshape(-1)
    need = np.zeros(p.size, dtype=np.bool_)
    need[act_a] = True
    S0 = np.zeros((x0.size, act_a.size + len(start_states)))
    for c, i in enumerate(start_states):
        S0[int(i), act_a.size + c] = 1.0
    U = input_matrix(model, t, inputs)
    Y = np.full(t.size, np.nan)
    dY = np.full((t.size, S0.shape[1]), np.nan)
    with np.errstate(all="ignore"):
        status = _kernel(model)(
            x0, S0, t, U, p, act_a, need, rtol, atol, Y, dY, int(max_steps_per_sample)
        )
    return None if status else (Y, dY)
