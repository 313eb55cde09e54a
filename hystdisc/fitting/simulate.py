"""Simulating candidate models on the fit's runs, many at once.

:func:`simulate_entries` runs (term model, run) pairs on the fixed-step term kernels in
one compiled call (the seed's families, effects, discovered structures);
:func:`simulate_systems` runs any :class:`~hystdisc.models.system.StateSpaceModel` with
the error-controlled integrator. Both return each entry's predicted output as the
acquisition records it (a channel delay and a declared filter applied:
:func:`~hystdisc.measurement.chain.measured_output`), with a diverged entry's non-finite
samples replaced by a large finite value the optimizer backs away from. Both integrate as
the data's :attr:`~hystdisc.measurement.FitData.integration` says
(:class:`~hystdisc.simulation.Integration`: the fits' settings by default).
:func:`simulate_sensitivities` runs one term model with the exact derivatives of its
output (the output-error Jacobian).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.measurement.chain import measured_output, seen_motion
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import TermModel
from hystdisc.models.compiled import N_BASE, base_coefficients
from hystdisc.models.system import StateSpaceModel
from hystdisc.simulation import driven_shared, mech_batch, simulate_system
from hystdisc.simulation.batch import driven_sens_batch, mech_sens_batch
from hystdisc.simulation.parallel import map_entries

#: What a diverged prediction is replaced by.
DIVERGED = 1e6


def kernel_vectors(data: FitData, models: list[TermModel], runs: list[int]) -> np.ndarray:
    """Each (model, run) entry's vector as the term kernels take it: the base coefficients
    (current folded in), the hysteresis coefficients, ``n`` and ``J`` (1 where the
    experiment does not identify it), numbered as the sensitivity directions
    (:mod:`hystdisc.simulation.sensitivity`). Shape ``(entries, N_BASE + 7)``."""
    out = np.empty((len(runs), N_BASE + 7))
    inertia = data.exp.inertia_identifiable
    for e, (tm, r) in enumerate(zip(models, runs, strict=True)):
        out[e, :N_BASE] = base_coefficients(tm, data.currents[r])
        out[e, N_BASE : N_BASE + 5] = tm.hysteresis_vector()
        out[e, N_BASE + 5] = tm.n
        out[e, N_BASE + 6] = tm.J if inertia else 1.0
    return out


def _split_vectors(vec: np.ndarray) -> tuple[np.ndarray, ...]:
    """The kernels' ``coef, b, n, J`` (contiguous) from :func:`kernel_vectors` rows."""
    parts = (vec[:, :N_BASE], vec[:, N_BASE : N_BASE + 5], vec[:, -2], vec[:, -1])
    return tuple(np.ascontiguousarray(a) for a in parts)


def _kernel_inputs(
    data: FitData,
    runs: list[int],
    nuis: list[np.ndarray],
    delays: list[float] | None = None,
    plays: list[float] | None = None,
) -> dict:
    """The samples of the entries' runs, concatenated, and the step controls of a fit: the
    arguments of the batch kernels besides the model (and, driven, the entries' runs).
    ``delays``: each entry's channel delay, which a driven run's model sees as its motion
    that much earlier; ``plays``: each entry's backlash, through which a driven run's model
    sees its motion (:func:`delayed_motion`)."""
    exp = data.exp
    steps = data.run_steps()
    how = data.integration
    # the sub-step cap is per measured sample interval: a decimated run gets q times more
    max_sub = np.array([how.max_sub * steps[r] for r in runs], dtype=np.int64)
    offsets = np.zeros(len(runs) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(data.t[r]) for r in runs])
    out: dict = {
        "t": np.concatenate([data.t[r] for r in runs]),
        "offsets": offsets,
        "steps": {"ratio": how.ratio, "min_sub": how.min_sub, "max_sub": max_sub},
    }
    if exp.motion_imposed:
        taus = delays if delays is not None else [0.0] * len(runs)
        gaps = plays if plays is not None else [0.0] * len(runs)
        motion = [
            delayed_motion(data, r, tau, gap) for r, tau, gap in zip(runs, taus, gaps, strict=True)
        ]
        out["theta"] = np.concatenate([m[0] for m in motion])
        out["theta_dot"] = np.concatenate([m[1] for m in motion])
        return out
    du = None
    if exp.has_input and data.hold == "cubic":
        slopes = data.input_slopes()
        du = np.concatenate([slopes[r] for r in runs])
    out["u"] = np.concatenate([data.u[r] for r in runs])
    out["start"] = (
        np.array([v[0] for v in nuis]),
        np.array([v[1] if len(v) > 1 else 0.0 for v in nuis]),
        np.array([v[2] if len(v) > 2 else 0.0 for v in nuis]),
    )
    out["mech"] = {"hold": data.hold, "du": du}
    return out


def delayed_motion(
    data: FitData, r: int, tau: float, play: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``r``'s imposed motion and velocity as the damper saw them: ``tau`` s earlier,
    ``theta(t - tau)``, and through a play of half-width ``play``.

    A driven test whose force channel lags the motion channel by ``tau`` records the
    force the damper made at ``t - tau``, the damper's answer to the motion then: the
    model is driven by the delayed motion, which is smooth, rather than its output
    delayed (a jump of the force, a Coulomb or yield reversal, falls between samples and
    would be smeared by the interpolation of the output). A backlash between the actuator
    and the damper (:func:`~hystdisc.models.backlash.play_motion`) acts on that motion.
    ``tau = 0`` and ``play = 0``: the run's own.
    """
    return seen_motion(data.t[r], data.theta[r], data.theta_dot[r], tau, play)


def output_delay(data: FitData, tau: float) -> float:
    """The delay applied to a simulated output: ``tau``, except for a driven run, whose
    model is driven by the delayed motion instead (:func:`delayed_motion`)."""
    return 0.0 if data.exp.motion_imposed else tau


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
    steps = data.run_steps()
    vec = kernel_vectors(data, models, runs)
    coef, b, n, J = _split_vectors(vec)
    delays = [float(tm.delay) for tm in models]
    plays = [float(tm.play) for tm in models]
    k = _kernel_inputs(data, runs, nuis, delays, plays)
    t, offsets = k["t"], k["offsets"]
    work = np.zeros(ne, dtype=np.int64)
    with np.errstate(all="ignore"):
        if data.exp.motion_imposed:
            # entries share z only on the same run seen with the same delay and play
            seen = list(zip(delays, plays, strict=True))
            which = {d: j for j, d in enumerate(dict.fromkeys(seen))}
            keys = np.array([r + data.n_runs * which[d] for r, d in zip(runs, seen, strict=True)])
            out, _, status = driven_shared(
                coef,
                b,
                n,
                t,
                k["theta"],
                k["theta_dot"],
                offsets,
                keys,
                work=work,
                **k["steps"],
            )
        else:
            out, _, _, status = mech_batch(
                coef, b, n, J, t, k["u"], offsets, *k["start"], **k["mech"], **k["steps"], work=work
            )
    res = [out[offsets[e] : offsets[e + 1]] for e in range(ne)]
    bad = []
    windows = data.run_filters()
    for e, (tm, r) in enumerate(zip(models, runs, strict=True)):
        diverged = bool(status[e]) or not np.all(np.isfinite(res[e]))
        if diverged:
            res[e] = np.where(np.isfinite(res[e]), res[e], DIVERGED)
        tau = output_delay(data, tm.delay)
        res[e] = measured_output(data.t[r], res[e], tau, windows[r], steps[r])
        bad.append(diverged)
    if status_out is not None:
        status_out.extend(bad)
    if work_out is not None:
        work_out.extend(int(w) for w in work)
    return res


def simulate_sensitivities(
    data: FitData,
    model: TermModel,
    runs: list[int],
    nuis: list[np.ndarray],
    act: np.ndarray,
) -> tuple[list[np.ndarray], list[np.ndarray], list[bool]]:
    """One term model on the runs ``runs`` with its forward sensitivities, in one compiled
    call (:func:`~hystdisc.simulation.batch.mech_sens_batch`,
    :func:`~hystdisc.simulation.batch.driven_sens_batch`).

    Parameters
    ----------
    data : FitData
        The runs.
    model : TermModel
        The model.
    runs : list of int
        The runs to simulate.
    nuis : list of ndarray
        Each run's initial-state values (as for :func:`simulate_entries`).
    act : ndarray of int
        The directions wanted: entries of :func:`kernel_vectors` and the initial states
        (numbered as in :mod:`hystdisc.simulation.sensitivity`).

    Returns
    -------
    outputs : list of ndarray
        Each run's simulated output before the measurement chain (the model's ``theta``,
        or a driven run's torque, its channel delay in the motion it was driven by;
        :func:`~hystdisc.measurement.chain.measured_output` is linear in it at a fixed
        delay).
    sensitivities : list of ndarray
        Each run's derivatives of the output, shape ``(samples, len(act))``.
    diverged : list of bool
        Each run's divergence flag (its output and sensitivities are then not finite).
    """
    vec = kernel_vectors(data, [model] * len(runs), runs)
    coef, b, n, J = _split_vectors(vec)
    k = _kernel_inputs(
        data, runs, nuis, [float(model.delay)] * len(runs), [float(model.play)] * len(runs)
    )
    t, offsets = k["t"], k["offsets"]
    with np.errstate(all="ignore"):
        if data.exp.motion_imposed:
            motion = (k["theta"], k["theta_dot"], offsets, np.zeros(len(runs)))
            out, _, sens, status = driven_sens_batch(coef, b, n, t, *motion, act, **k["steps"])
        else:
            out, _, _, sens, status = mech_sens_batch(
                coef, b, n, J, t, k["u"], offsets, *k["start"], act, **k["mech"], **k["steps"]
            )
    cut = [slice(offsets[e], offsets[e + 1]) for e in range(len(runs))]
    bad = [
        bool(status[e]) or not (np.all(np.isfinite(out[c])) and np.all(np.isfinite(sens[c])))
        for e, c in enumerate(cut)
    ]
    return [out[c] for c in cut], [sens[c] for c in cut], bad


def system_inputs(
    data: FitData, r: int, model: StateSpaceModel, tau: float = 0.0, play: float = 0.0
) -> dict[str, np.ndarray]:
    """Run ``r``'s exogenous signals by the names the model asks for (a driven run's
    motion delayed by the channel delay ``tau`` and through a backlash ``play``:
    :func:`delayed_motion`)."""
    theta, theta_dot = delayed_motion(data, r, tau, play) if data.exp.motion_imposed else (
        data.theta[r], data.theta_dot[r]
    )  # fmt: skip
    have = {"theta": theta, "theta_dot": theta_dot, "u": data.u[r]}
    return {k: have[k] for k in model.inputs}


def system_start(data: FitData, model: StateSpaceModel, nu: np.ndarray) -> np.ndarray:
    """The initial state of a run of ``model`` from the run's nuisance values (named like
    the experiment's: ``theta0``, ``theta_dot0``, ``z0``)."""
    names = data.exp.initial_state(has_z="z" in model.states)
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
    windows = data.run_filters()
    steps = data.run_steps()
    how = data.integration

    def one(entry) -> tuple[np.ndarray, bool]:
        (model, values), r, nu = entry
        x0 = system_start(data, model, nu)
        tau = model.output_delay(values)
        try:
            y = simulate_system(
                model,
                data.t[r],
                x0,
                values,
                current=float(data.currents[r]),
                inputs=system_inputs(data, r, model, tau, model.input_play(values)),
                rtol=how.rtol,
                atol=how.atol,
                max_steps_per_sample=how.max_steps * steps[r],
            ).y
            bad = not np.all(np.isfinite(y))
        except HystdiscError:
            y, bad = np.full(data.t[r].size, np.nan), True
        if bad:
            y = np.where(np.isfinite(y), y, DIVERGED)
        return measured_output(data.t[r], y, output_delay(data, tau), windows[r], steps[r]), bad

    # every entry is integrated on its own: side by side on threads, the same to the bit
    done = map_entries(one, list(zip(systems, runs, nuis, strict=True)))
    if status_out is not None:
        status_out.extend(bad for _, bad in done)
    if work_out is not None:
        work_out.extend(0 for _ in done)
    return [y for y, _ in done]
