"""The exact output-error Jacobian of a state-space model with compiled partial derivatives.

A model whose ``rate_jac`` and ``observe_grad`` are compiled (Spencer's family, the tanh
family on imposed motion: :func:`~hystdisc.simulation.sensitivity_ode.has_sensitivities`)
is integrated once per run with its forward sensitivities
(:func:`~hystdisc.simulation.sensitivity_ode.simulate_system_sensitivities`): the same
steps and the same output as the fit's own simulation, and the exact derivative of that
discrete solution along the entries of the run's packed parameter vector and its initial
state. The free parameters reach the packed vector through the model's algebra
(``run_parameters``: the current laws folded in, the effects' terms), whose derivative is
taken by central differences, no simulation, as for the term models
(:func:`~hystdisc.fitting.jacobian.map_derivative`). The measurement chain (a fixed delay,
a filter) is linear in the output; a parameter that moves the delay adds the forward
difference of the measured output in the delay alone.

Forward differences of separately simulated runs need one simulation per column, at a
tolerance far below the difference step; here a column costs a few multiplications per
stage and state.
"""

from __future__ import annotations

import numpy as np

import hystdisc.fitting.simulate as _sim
from hystdisc.fitting.jacobian import map_stencil, measured_columns
from hystdisc.fitting.parametrization import Parametrization, SystemParametrization
from hystdisc.measurement.fitdata import FitData
from hystdisc.simulation.parallel import map_entries
from hystdisc.simulation.sensitivity_ode import has_sensitivities, simulate_system_sensitivities


def exact_applies(par: Parametrization) -> bool:
    """Whether the Jacobian of a fit of ``par`` can be computed here (a state-space model
    with compiled partial derivatives; the fitter asks it with ``jacobian_mode="exact"``)."""
    return isinstance(par, SystemParametrization) and has_sensitivities(par.model(par.x0)[0])


def _packed(data: FitData, par: SystemParametrization, x: np.ndarray) -> np.ndarray:
    system, values = par.model(x)
    return np.array([system.run_parameters(values, float(i)) for i in data.currents])


def packed_derivative(
    data: FitData, par: SystemParametrization, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every run's packed parameter vector at ``x`` and its derivative in ``x``.

    Differences at the points of :func:`~hystdisc.fitting.jacobian.map_stencil` (those of
    the term models' map); an entry a parameter does not move gets exactly 0.

    Returns
    -------
    P : ndarray
        Shape ``(runs, len(p))``.
    D : ndarray
        Shape ``(runs, len(p), parameters)``.
    delays : ndarray of bool
        The parameters that move the output's delay.
    plays : ndarray of bool
        The parameters that move the backlash of a driven run's motion.
    """
    P = _packed(data, par, x)
    D = np.zeros((*P.shape, x.size))
    delays = np.zeros(x.size, dtype=bool)
    plays = np.zeros(x.size, dtype=bool)
    system, values = par.model(x)
    tau0, play0 = system.output_delay(values), system.input_play(values)
    for j, xj, wgt in map_stencil(x, par):
        D[:, :, j] += wgt * (_packed(data, par, xj) - P)
        sj, vj = par.model(xj)
        delays[j] |= sj.output_delay(vj) != tau0
        plays[j] |= sj.input_play(vj) != play0
    return P, D, delays, plays


def system_exact_jacobian(
    data: FitData,
    par: SystemParametrization,
    x: np.ndarray,
    nu: np.ndarray,
    masks: list[np.ndarray],
    rel_step: float,
) -> np.ndarray | None:
    """The output-error Jacobian at the free parameters ``x`` and initial states ``nu``.

    Arguments and result as :func:`~hystdisc.fitting.jacobian.exact_jacobian`: rows are
    the masked samples, run after run; columns ``x``, then each run's initial states.
    None when a run diverges or a sensitivity is so large that the Gram matrix would
    overflow (the caller then takes differences).
    """
    R, k, nnu = data.n_runs, x.size, nu.shape[1]
    system, values0 = par.model(x)
    P, D, delays, plays = packed_derivative(data, par, x)
    moving = [d for d in range(P.shape[1]) if np.any(D[:, d, :] != 0.0)]
    names = data.exp.initial_state(has_z="z" in system.states)
    # each initial-state parameter's state (theta0 -> theta), or none
    of_state = [system.states.index(n[:-1]) if n[:-1] in system.states else -1 for n in names]
    starts = [i for i in of_state if i >= 0]
    steps = data.run_steps()
    how = data.integration

    def delay_of(xj: np.ndarray) -> float:
        s, v = par.model(xj)
        return s.output_delay(v)

    def one(r: int):
        out = simulate_system_sensitivities(
            system,
            data.t[r],
            _sim.system_start(data, system, nu[r]),
            P[r],
            moving,
            starts,
            inputs=_sim.system_inputs(
                data, r, system, system.output_delay(values0), system.input_play(values0)
            ),
            rtol=how.rtol,
            atol=how.atol,
            max_steps_per_sample=how.max_steps * steps[r],
        )
        if out is None or not np.all(np.isfinite(out[0])) or not np.all(np.isfinite(out[1])):
            return None
        y, dY = out
        cols = np.zeros((y.size, k + nnu))
        cols[:, :k] = dY[:, : len(moving)] @ D[r][moving]
        c = len(moving)
        for i, s in enumerate(of_state):
            if s >= 0:
                cols[:, k + i] = dY[:, c]
                c += 1
        measured_columns(data, par, r, x, delay_of, y, cols, delays, rel_step,
                         lambda xj: par.simulate(data, [par.model(xj)], [r], [nu[r]])[0],
                         plays)  # fmt: skip
        return cols

    done = map_entries(one, list(range(R)))
    if any(c is None for c in done):
        return None
    offsets = np.cumsum([0] + [int(m.sum()) for m in masks])
    Jm = np.zeros((offsets[-1], k + R * nnu))
    for q, cols in enumerate(done):
        rows = slice(offsets[q], offsets[q + 1])
        Jm[rows, :k] = cols[masks[q], :k]
        Jm[rows, k + q * nnu : k + (q + 1) * nnu] = cols[masks[q], k:]
    big = np.sqrt(np.finfo(float).max / max(Jm.shape[0], 1))
    return Jm if np.abs(Jm).max(initial=0.0) < big else None
