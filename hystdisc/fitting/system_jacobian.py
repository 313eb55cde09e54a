"""The output-error Jacobian of a state-space model by internal numerical differentiation.

A state-space model (a system family, a structural effect:
:class:`~hystdisc.fitting.parametrization.SystemParametrization`) is simulated by the
error-controlled Dormand–Prince integrator. Forward differences of separately simulated
runs are only consistent when that integration is far tighter than the difference step,
because each perturbed run chooses its own steps. Here (Bock's internal numerical
differentiation) the nominal run and its perturbed copies (one per free parameter, one
per initial state of the run) are integrated in lockstep
(:func:`~hystdisc.simulation.ode.simulate_lockstep`): every copy takes the steps, the
rejections and the sample ends that the nominal's error control chose, so the copies
sample one discrete solution map that is smooth in the parameters, and their forward
differences are its derivatives at any tolerance. One compiled call per run gives the
run's output and all its columns. A fit uses it with ``jacobian_mode="lockstep"``
(:class:`~hystdisc.fitting.output_error.OutputErrorFitter`).

The columns follow :meth:`~hystdisc.fitting.output_error.OutputErrorFitter.jacobian`
exactly: the same steps, a step flipped below a parameter at its upper bound, masked rows
left out, a run's initial-state columns zero outside its rows, the output as the
acquisition records it (:func:`~hystdisc.measurement.chain.measured_output`, applied to
each copy with its own channel delay, so a delay parameter gets an ordinary forward
difference of the delayed output). A run whose nominal diverges is differenced as before
(separate simulations, the diverged samples replaced by a large value).

Measured on the MR damper set (Spencer, 30 runs, 168 k residual rows, one process): a
Jacobian takes 2.3 s against 4.1 s by separate runs at 1e-10, and its columns are within
5e-4 of a 1e-12 integration's (the separate runs' within 6e-2). The copies take six rate
evaluations per accepted step each, so the gain is what the nominal's rejections, its
error stage and the looser tolerance save; on smooth records the steps already sit near
one per sample.
"""

from __future__ import annotations

import numpy as np

import hystdisc.fitting.simulate as _sim
from hystdisc.fitting.jacobian import difference_steps
from hystdisc.fitting.parametrization import SystemParametrization
from hystdisc.measurement.chain import measured_output
from hystdisc.measurement.fitdata import FitData
from hystdisc.simulation import Integration
from hystdisc.simulation.ode import simulate_lockstep

#: The integration tolerances the lockstep Jacobian needs (measured on the MR damper set:
#: the force within 8e-4 N of a 1e-12 integration, noise 0.04 N); a fit with
#: ``jacobian_mode="lockstep"`` may integrate at them (:data:`LOCKSTEP_INTEGRATION`) where
#: forward differences of separately controlled runs need the fits' default 1e-10 / 1e-13.
#: The lockstep is not the default: with it, the compliant wheel's refit ends in another
#: basin (``tests/test_compliance.py``).
LOCKSTEP_RTOL = 1e-8
LOCKSTEP_ATOL = 1e-11
#: The fits' integration with the lockstep Jacobian's tolerances (the pipeline's
#: ``Options(jacobian="lockstep", integration=LOCKSTEP_INTEGRATION)``).
LOCKSTEP_INTEGRATION = Integration(rtol=LOCKSTEP_RTOL, atol=LOCKSTEP_ATOL)
#: A perturbed copy may move the output by at most this fraction of the nominal output's
#: range (a parameter step of ``rel_step`` moves it by about that much of it); a copy
#: beyond it has excited a fast mode the nominal's steps do not resolve (a perturbed
#: initial angle against a stiff wheel), and its run is differenced by separate runs.
LOCKSTEP_MAX_MOVE = 1e-2


def system_jacobian(
    data: FitData,
    par: SystemParametrization,
    v: np.ndarray,
    rel_step: float,
    masks: list[np.ndarray],
    row_offsets: np.ndarray,
) -> np.ndarray:
    """The output-error Jacobian of ``par`` at ``v`` by lockstep internal differentiation.

    Parameters
    ----------
    data : FitData
        The runs.
    par : SystemParametrization
        What is fitted.
    v : ndarray
        The free parameters, then each run's initial-state (nuisance) parameters.
    rel_step : float
        Relative step of the differences.
    masks : list of ndarray
        Each run's samples that enter the residual.
    row_offsets : ndarray
        Where each run's rows start (and the last one ends) in the residual.

    Returns
    -------
    ndarray
        The Jacobian, shape ``(row_offsets[-1], len(v))``.
    """
    v = np.asarray(v, dtype=float)
    npar = len(par.names)
    R = data.n_runs
    nnu = (v.size - npar) // R if R else 0
    x = v[:npar]
    nu = v[npar:].reshape(R, nnu)
    steps = difference_steps(v, rel_step)
    signed = np.empty(npar)
    perturbed = []
    for j in range(npar):
        xj = x.copy()
        xj[j] += steps[j]
        signed[j] = steps[j]
        if xj[j] > par.upper[j]:
            xj[j] -= 2 * steps[j]
            signed[j] = -steps[j]
        perturbed.append(par.model(xj))
    nominal = par.model(x)
    Jm = np.zeros((row_offsets[-1], v.size))
    for r in range(R):
        hs = np.concatenate([signed, steps[npar + r * nnu : npar + (r + 1) * nnu]])
        outs = _lockstep_run(data, r, nominal, perturbed, nu[r], hs[npar:])
        if outs is None:
            outs = _separate_run(data, par, r, nominal, perturbed, nu[r], hs[npar:])
        d = (outs[1:] - outs[0])[:, masks[r]] / hs[:, None]
        rows = slice(row_offsets[r], row_offsets[r + 1])
        Jm[rows, :npar] = d[:npar].T
        Jm[rows, npar + r * nnu : npar + (r + 1) * nnu] = d[npar:].T
    return Jm


def _lockstep_run(data, r, nominal, perturbed, nu, nu_steps) -> np.ndarray | None:
    """Run ``r``'s measured outputs of the nominal, each perturbed parameter vector and
    each perturbed initial state (rows), integrated in lockstep; None when the nominal
    diverges, a perturbed model is not the nominal's system with other values, or a copy
    moves the output by more than :data:`LOCKSTEP_MAX_MOVE` of its range."""
    system, values = nominal
    for s, _ in perturbed:
        if (s.rate, s.observe, s.states, s.inputs) != (
            system.rate,
            system.observe,
            system.states,
            system.inputs,
        ):
            return None
    play = system.input_play(values)
    if any(s.input_play(vals) != play for s, vals in perturbed):
        return None  # a copy sees another motion (its backlash): separate runs
    tau = system.output_delay(values)
    driven = data.exp.motion_imposed
    if driven and any(s.output_delay(vals) != tau for s, vals in perturbed):
        return None  # a driven copy sees its delay in its motion: separate runs
    current = float(data.currents[r])
    p0 = system.run_parameters(values, current)
    x0 = _sim.system_start(data, system, nu)
    P = [p0] + [s.run_parameters(vals, current) for s, vals in perturbed] + [p0] * nu.size
    X0 = [x0] * (1 + len(perturbed))
    delays = [system.output_delay(values)] + [s.output_delay(vals) for s, vals in perturbed]
    for q in range(nu.size):
        nq = nu.copy()
        nq[q] += nu_steps[q]
        X0.append(_sim.system_start(data, system, nq))
        delays.append(delays[0])
    t = data.t[r]
    how = data.integration
    Y = simulate_lockstep(
        system,
        t,
        np.array(X0),
        np.array(P),
        _sim.system_inputs(data, r, system, tau if driven else 0.0, play),
        rtol=how.rtol,
        atol=how.atol,
        max_steps_per_sample=how.max_steps * data.run_steps()[r],
    )
    if Y is None or not np.all(np.isfinite(Y[0])):
        return None
    if driven:  # the delay is in the motion (as simulate_systems has it), not the output
        delays = [0.0] * len(delays)
    with np.errstate(invalid="ignore", over="ignore"):
        move = np.abs(Y[1:] - Y[0]).max(axis=1) if len(Y) > 1 else np.zeros(0)
    if not np.all(move <= LOCKSTEP_MAX_MOVE * (np.ptp(Y[0]) + 1e-300)):
        return None  # a copy left the nominal's steps behind (or diverged): separate runs
    window, step = data.run_filters()[r], data.run_steps()[r]
    return np.array(
        [measured_output(t, y, tau, window, step) for y, tau in zip(Y, delays, strict=True)]
    )


def _separate_run(data, par, r, nominal, perturbed, nu, nu_steps) -> np.ndarray:
    """Run ``r``'s outputs as :func:`_lockstep_run` gives them, each simulated on its own
    (the fitter's forward differences)."""
    nuis = [nu] * (1 + len(perturbed))
    for q in range(nu.size):
        nq = nu.copy()
        nq[q] += nu_steps[q]
        nuis.append(nq)
    models = [nominal, *perturbed] + [nominal] * nu.size
    return np.array(par.simulate(data, models, [r] * len(models), nuis))
