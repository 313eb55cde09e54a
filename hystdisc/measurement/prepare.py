"""The data as the two stages see them: noise model, glitches, derivatives, conditions.

:func:`prepare_data` turns a :class:`~hystdisc.data.Dataset` into the equation-error data
of stage 1 (:class:`~hystdisc.discovery.EqData`: smoothed angle, its derivatives, the
regression target, decimated to the smoothing's band) and the output-error data of stage 2
(:class:`~hystdisc.fitting.FitData`: the runs as measured, glitches masked, the rig's
filter and the encoder's step), with the measurement noise model
(:func:`~hystdisc.data.measurement_noise`) and the glitches screened out of both.
"""

from __future__ import annotations

import numpy as np

from hystdisc.data import (
    Dataset,
    estimate_noise,
    filter_windows,
    measurement_noise,
    trim_release,
)
from hystdisc.data.conditions import detect_conditions
from hystdisc.data.motion import motion_noise, pooled_motion_noise
from hystdisc.data.noise import NoiseEstimate
from hystdisc.discovery import EqData, differentiate
from hystdisc.errors import HystdiscError
from hystdisc.measurement.chain import apply_filter
from hystdisc.measurement.fitdata import FitData
from hystdisc.measurement.motion import estimate_motion, filter_estimate
from hystdisc.measurement.outliers import screen_runs
from hystdisc.registry import experiment_names, get_experiment
from hystdisc.simulation import Integration
from hystdisc.stats import samples_per_cycle


def prepare_data(
    dataset: Dataset,
    experiment: str | None = None,
    input_hold: str = "cubic",
    *,
    motion: str = "auto",
    motion_errors: bool = True,
    jacobian: str = "exact",
    integration: Integration | None = None,
) -> tuple[EqData, FitData, list[dict], NoiseEstimate]:
    """The stage-1 and stage-2 data of ``dataset``.

    Parameters
    ----------
    dataset : Dataset
        The runs.
    experiment : str, optional
        The experiment type (default: the dataset's).
    input_hold : {"cubic", "linear", "zoh"}
        Forced experiments: the input between samples.
    motion : {"auto", "legacy"}
        Driven: how the imposed motion is estimated (``mode`` of
        :func:`~hystdisc.measurement.motion.estimate_motion`).
    motion_errors : bool
        Driven: the motion estimate's errors enter the fits' intervals
        (:attr:`FitData.motion_errors`; False: none, as before issue 33).
    jacobian : str
        How the fits of these data compute their Jacobian (:attr:`FitData.jacobian`).
    integration : Integration, optional
        How the fits of these data integrate (:attr:`FitData.integration`; default: the
        fits' own settings).

    Returns
    -------
    eq : EqData
        Equation-error data (stage 1).
    fd : FitData
        Output-error data (stage 2).
    glitches : list of dict
        The isolated glitches screened out (:func:`~hystdisc.fitting.screen_runs`).
    noise : NoiseEstimate
        The measurement noise model (:func:`~hystdisc.data.measurement_noise`).

    Examples
    --------
    >>> from hystdisc.simulation.synth import generate
    >>> eq, fd, glitches, noise = prepare_data(generate("dahl", currents=(0, 1), duration=2.0))
    >>> fd.n_runs, eq.experiment, glitches, bool(0.5e-3 < noise.std < 2e-3)
    (2, 'release', [], True)
    """
    name = experiment or dataset.experiment
    if name not in experiment_names():
        raise HystdiscError(
            f"{dataset.source}: unknown experiment type '{name}'; fix: use "
            f"{', '.join(experiment_names()[:-1])} or {experiment_names()[-1]}"
        )
    exp = get_experiment(name)
    runs = list(dataset.runs)
    col = exp.extra_column
    if col is not None and any(getattr(r, col) is None for r in runs):
        raise HystdiscError(
            f"{dataset.source}: a {exp.name} experiment needs {'an' if col[0] in 'aeiou' else 'a'}"
            f" {col} column; fix: add it or use --experiment release"
        )
    # the measurement, modelled: period-to-period differences of a periodic excitation,
    # the quantization floor of an encoder (the differentiation keeps theta_noise)
    model = measurement_noise(runs, exp)
    noise = model.std
    theta_noise = float(np.median([estimate_noise(r.theta, r.fs) for r in runs]))
    # isolated glitches: replaced by their local prediction for stage 1 (derivatives,
    # regression target), left out of the output-error residual (measurement/outliers.py)
    runs, raw_y, flags, glitches = screen_runs(runs, exp, noise, theta_noise)
    if exp.starts_at_rest:
        runs = [trim_release(r, theta_noise) for r in runs]
    eq_t, eq_th, eq_w, eq_a, eq_y, rows = [], [], [], [], [], []
    fd = FitData(
        exp.name,
        [r.name for r in runs],
        [],
        [],
        np.array([r.current for r in runs]),
        [],
        [],
        [],
        [],
        noise,
        input_hold,
        integration=Integration() if integration is None else integration,
        jacobian=jacobian,
    )
    windows = []
    # driven: the measured motion is estimated (a harmonic series of a periodic run, else
    # local fits), its noise and the estimate's errors carried to the intervals
    motion_estimates = []
    # a motion recorded through a declared filter: the fit's is reconstructed below, and
    # the equation-error stage keeps the smoothed record, as before the estimates
    filtered = dataset.filter is not None and "theta" in dataset.filter["channels"]
    for k, r in enumerate(runs):
        est = None
        if exp.motion_imposed and np.ptp(r.theta) > 0:
            est = estimate_motion(
                r.t, r.theta, theta_noise, k, motion_noise(r.t, r.theta), mode=motion
            )
            motion_estimates.append(est)
        d = est if est is not None and not filtered else differentiate(r.t, r.theta, theta_noise)
        windows.append(d.window)
        if not np.all(np.isfinite(d.theta_dot)) or np.ptp(r.theta) == 0:
            raise HystdiscError(
                f"{dataset.source}, run {r.name}: the run never moves; fix: remove the run"
            )
        m = np.ones(r.t.size, dtype=bool)
        edge = getattr(d, "edge", d.window // 2)  # a smoother's one-sided ends
        if edge > 0:
            m[:edge] = False
            m[-edge:] = False
        if exp.motion_imposed:
            # forget the unknown initial z: skip until the motion has swept its range once
            travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(d.theta)))])
            m &= travel >= np.ptp(d.theta)
            if m.sum() < 20:
                m[:] = True
        eq_t.append(r.t)
        eq_th.append(d.theta)
        eq_w.append(d.theta_dot)
        eq_a.append(d.theta_ddot)
        if exp.target == "-theta_ddot":
            eq_y.append(-d.theta_ddot)
        else:
            eq_y.append(np.asarray(getattr(r, exp.target), dtype=float))
        rows.append(m)
        fd.t.append(r.t)
        fd.y.append(raw_y[len(fd.y)][: r.t.size])  # as measured, glitches masked
        fd.theta.append(d.theta if exp.motion_imposed else np.asarray(r.theta, dtype=float))
        fd.theta_dot.append(d.theta_dot)
        fd.u.append(np.asarray(r.input, dtype=float) if exp.has_input else np.zeros(r.t.size))
        keep = m if exp.motion_imposed else np.ones(r.t.size, dtype=bool)
        fd.mask.append(keep & ~flags[len(fd.mask)][: r.t.size])
    if dataset.filter is not None:  # the fit sees the damper through the rig's filter
        windows = filter_windows(dataset.filter, runs, dataset.source)
        apply_filter(fd, windows, dataset.filter["channels"], [r.theta for r in runs])
        if motion_estimates and filtered:
            motion_estimates = [
                filter_estimate(est, r.t, r.theta, w) if w > 1 else est
                for est, r, w in zip(motion_estimates, runs, windows, strict=True)
            ]
    if motion_estimates:
        if motion_errors:
            fd.motion_errors = motion_estimates
        fd.motion_noise = pooled_motion_noise(
            [r.name for r in runs], [r.t.size for r in runs], [e.noise for e in motion_estimates]
        )
        fd.motion_noise.estimates = {
            r.name: est.summary() for r, est in zip(runs, motion_estimates, strict=True)
        }
    if model.method == "quantization" and model.output_quantization:
        fd.quantum = float(model.output_quantization.step)
    given = [r.condition for r in runs]
    if all(c is not None for c in given):
        fd.conditions = [str(c) for c in given]
    else:  # from the smoothed motion (or the input record) of each run
        fd.conditions = detect_conditions(exp, eq_t, eq_th, [r.input for r in runs])
    scale = float(np.median([np.ptp(th) / 2 for th in eq_th])) or 1.0
    # the smoothed signals are band-limited by the window: decimate the equation-error
    # stage (z is still integrated with sub-steps on the decimated grid)
    q = max(1, int(np.median(windows)) // 16)
    qs = [q] * len(runs)
    if exp.motion_imposed:
        # torque is not differentiated; keep ~200 samples per cycle of each run's motion
        qs = [max(1, int(samples_per_cycle(w) // 200)) for w in eq_w]
        q = max(1, int(np.median(qs)))
    dec = lambda xs: [x[::qk] for x, qk in zip(xs, qs, strict=True)]  # noqa: E731
    eq = EqData(
        exp.name,
        dec(eq_t),
        dec(eq_th),
        dec(eq_w),
        dec(eq_a),
        dec(eq_y),
        fd.currents,
        dec(rows),
        max(1, int(np.median(windows)) // q),
        scale,
    )
    return eq, fd, glitches, model
