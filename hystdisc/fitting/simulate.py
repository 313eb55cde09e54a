"""Simulating candidate models on the fit's runs, many at once.

:func:`simulate_entries` runs (term model, run) pairs on the fixed-step term kernels in
one compiled call (the seed's families, effects, discovered structures);
:func:`simulate_systems` runs any :class:`~hystdisc.models.system.StateSpaceModel` with
the error-controlled integrator. Both return each entry's predicted output as the
acquisition records it (a channel delay and a declared filter applied:
:func:`~hystdisc.fitting.measurement.measured_output`), with a diverged entry's non-finite
samples replaced by a large finite value the optimizer backs away from.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.fitting.data import FitData
from hystdisc.fitting.measurement import measured_output
from hystdisc.models import TermModel
from hystdisc.models.compiled import N_BASE, base_coefficients
from hystdisc.models.system import StateSpaceModel
from hystdisc.simulation import driven_shared, mech_batch, simulate_system

#: Sub-step ratio used while fitting (errors ~1e-6 of the signal, far below any noise).
FIT_RATIO = 0.4
#: Sub-step cap while fitting: a candidate with a near-discontinuous state (a Dahl rate
#: fitted to Bingham data) is not worth resolving exactly inside the optimizer.
FIT_MAX_SUB = 8
#: Tolerances of the error-controlled integrator inside a fit. The Jacobian integrates the
#: perturbed copies in lockstep with the nominal (:mod:`hystdisc.fitting.system_jacobian`),
#: so the tolerance serves the output error only: on the MR damper set (Spencer) 1e-8
#: keeps the simulated force within 8e-4 N of a 1e-12 integration (RMS 2e-5 N; the noise
#: is 0.04 N) and the cost within 3e-8 of it (the Levenberg-Marquardt stops at 1e-6).
#: Forward differences of separately controlled runs (``system_jacobian.METHOD =
#: "forward"``) need 1e-10 / 1e-13, as before.
SYSTEM_RTOL = 1e-8
SYSTEM_ATOL = 1e-11
#: Steps of the error-controlled integrator per measured sample interval while fitting: a
#: candidate whose dynamics need more (a series mass driven towards zero, a stiff wheel)
#: counts as diverged, and the optimizer backs away.
SYSTEM_MAX_STEPS = 200
#: What a diverged prediction is replaced by.
DIVERGED = 1e6


def simulate_entries(
    data: FitData,
    models: list[TermModel],
    runs: list[int],
    nuis: list[np.ndarray],
    status_out: list | None = None,
    work_out: list | None = None,
) -> list[np.ndarray]:
    """Simulate (model, run) pairs in one compiled call; return the predicted outputs.

    A diverged entry is returned with its non-finite samples replaced by 1e6 (a large,
    finite residual the optimizer backs away from); ``status_out`` receives the flags and
    ``work_out`` the integration work of each entry (see :func:`~hystdisc.simulation.mech_batch`).
    """
    ne = len(runs)
    exp = data.exp
    steps = data.run_steps()
    # the sub-step cap is per measured sample interval: a decimated run gets q times more
    max_sub = np.array([FIT_MAX_SUB * steps[r] for r in runs], dtype=np.int64)
    coef = np.empty((ne, N_BASE))
    b = np.empty((ne, 5))
    n = np.empty(ne)
    J = np.empty(ne)
    for e, (tm, r) in enumerate(zip(models, runs, strict=True)):
        coef[e] = base_coefficients(tm, data.currents[r])
        b[e] = tm.hysteresis_vector()
        n[e] = tm.n
        J[e] = tm.J if exp.inertia_identifiable else 1.0
    offsets = np.zeros(ne + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(data.t[r]) for r in runs])
    work = np.zeros(ne, dtype=np.int64)
    t = np.concatenate([data.t[r] for r in runs])
    with np.errstate(all="ignore"):
        if exp.motion_imposed:
            th = np.concatenate([data.theta[r] for r in runs])
            w = np.concatenate([data.theta_dot[r] for r in runs])
            out, _, status = driven_shared(
                coef,
                b,
                n,
                t,
                th,
                w,
                offsets,
                np.asarray(runs),
                ratio=FIT_RATIO,
                min_sub=1,
                max_sub=max_sub,
                work=work,
            )
        else:
            u = np.concatenate([data.u[r] for r in runs])
            du = None
            if exp.has_input and data.hold == "cubic":
                slopes = data.input_slopes()
                du = np.concatenate([slopes[r] for r in runs])
            th0 = np.array([v[0] for v in nuis])
            w0 = np.array([v[1] if len(v) > 1 else 0.0 for v in nuis])
            z0 = np.array([v[2] if len(v) > 2 else 0.0 for v in nuis])
            out, _, _, status = mech_batch(
                coef,
                b,
                n,
                J,
                t,
                u,
                offsets,
                th0,
                w0,
                z0,
                hold=data.hold,
                ratio=FIT_RATIO,
                min_sub=1,
                max_sub=max_sub,
                du=du,
                work=work,
            )
    res = [out[offsets[e] : offsets[e + 1]] for e in range(ne)]
    bad = []
    windows = data.run_filters()
    for e, (tm, r) in enumerate(zip(models, runs, strict=True)):
        diverged = bool(status[e]) or not np.all(np.isfinite(res[e]))
        if diverged:
            res[e] = np.where(np.isfinite(res[e]), res[e], DIVERGED)
        res[e] = measured_output(data.t[r], res[e], tm.delay, windows[r], steps[r])
        bad.append(diverged)
    if status_out is not None:
        status_out.extend(bad)
    if work_out is not None:
        work_out.extend(int(w) for w in work)
    return res


def _system_inputs(data: FitData, r: int, model: StateSpaceModel) -> dict[str, np.ndarray]:
    """Run ``r``'s exogenous signals by the names the model asks for."""
    have = {"theta": data.theta[r], "theta_dot": data.theta_dot[r], "u": data.u[r]}
    return {k: have[k] for k in model.inputs}


def _system_start(model: StateSpaceModel, names: list[str], nu: np.ndarray) -> np.ndarray:
    """The initial state from a run's nuisance values (named like the experiment's)."""
    given = {n[:-1]: float(v) for n, v in zip(names, nu, strict=True)}  # theta0 -> theta
    return model.initial_state(**{k: v for k, v in given.items() if k in model.states})


def simulate_systems(
    data: FitData,
    systems: list[tuple[StateSpaceModel, Mapping[str, float]]],
    runs: list[int],
    nuis: list[np.ndarray],
    status_out: list | None = None,
    work_out: list | None = None,
) -> list[np.ndarray]:
    """Simulate (state-space model with parameter values, run) pairs.

    Parameters
    ----------
    data : FitData
        The runs (their times, imposed motion or input, currents).
    systems : list of (StateSpaceModel, dict)
        Each entry's model and named parameter values.
    runs : list of int
        Each entry's run.
    nuis : list of ndarray
        Each entry's initial-state values, named by the experiment
        (``data.exp.initial_state``: ``theta0``, ``theta_dot0``, ``z0``).
    status_out, work_out : list, optional
        Receive each entry's divergence flag and integration work (0: not counted).
    """
    out = []
    windows = data.run_filters()
    steps = data.run_steps()
    for (model, values), r, nu in zip(systems, runs, nuis, strict=True):
        names = data.exp.initial_state(has_z="z" in model.states)
        x0 = _system_start(model, names, nu)
        try:
            y = simulate_system(
                model,
                data.t[r],
                x0,
                values,
                current=float(data.currents[r]),
                inputs=_system_inputs(data, r, model),
                rtol=SYSTEM_RTOL,
                atol=SYSTEM_ATOL,
                max_steps_per_sample=SYSTEM_MAX_STEPS * steps[r],
            ).y
            bad = not np.all(np.isfinite(y))
        except HystdiscError:
            y, bad = np.full(data.t[r].size, np.nan), True
        if bad:
            y = np.where(np.isfinite(y), y, DIVERGED)
        tau = model.output_delay(values)
        out.append(measured_output(data.t[r], y, tau, windows[r], steps[r]))
        if status_out is not None:
            status_out.append(bad)
        if work_out is not None:
            work_out.append(0)
    return out
