"""Simulate a fitted model on new runs (``hystdisc predict``).

Release runs start from the run's first (smoothed) angle at rest; driven runs use the
run's imposed motion (velocity by the same smoothed differentiation as discovery); forced
runs follow the run's input from an initial state (angle, velocity, z) fitted to the first
half second of the record, since a record may start mid-motion.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hystdisc.data import Dataset, estimate_noise, filter_windows, with_detected_filter
from hystdisc.data.envelope import Envelope, RunEnvelope
from hystdisc.discovery.differentiation import differentiate
from hystdisc.measurement.chain import measured_output, seen_motion, unfiltered_motion
from hystdisc.measurement.motion import estimate_motion
from hystdisc.models import TermModel
from hystdisc.models.term_columns import term_column
from hystdisc.registry import get_experiment
from hystdisc.simulation import simulate_driven_runs, simulate_mech, simulate_system


def beyond_envelope(
    envelope: Mapping[str, Any] | None, dataset: Dataset, unit: str = "rad"
) -> list[str]:
    """One line per way a record of ``dataset`` leaves the training envelope.

    ``envelope`` is the ``envelope`` entry of ``results.json`` (None: an older file, no
    check). The velocity is the smoothed derivative discovery uses.

    Examples
    --------
    >>> from hystdisc.simulation.synth import generate
    >>> env = {"runs": [{"name": "0", "current": 0.0, "theta_max": 0.1,
    ...                  "theta_dot_max": 5.0, "duration": 3.0}]}
    >>> data = generate("dahl", currents=(0.0,), duration=1.0, theta0=0.3, seed=0)
    >>> beyond_envelope(env, data)
    ['run 0: peak displacement 0.299 rad is 3x the largest in training (0.1 rad)']
    """
    if not envelope:
        return []
    env = Envelope.from_dict(envelope)
    new = []
    for r in dataset.runs:
        d = differentiate(r.t, r.theta, estimate_noise(r.theta, r.fs))
        new.append(RunEnvelope.measure(r.name, r.t, d.theta, d.theta_dot, r.current))
    return env.beyond(new, unit=unit)


#: Tolerances of a prediction's error-controlled integration (one simulation: accuracy
#: first; python-control's export integrates to the same, ``apply/control.py``).
PREDICT_RTOL = 1e-11
PREDICT_ATOL = 1e-13


def _predict_system(model, runs, ders, exp) -> list[np.ndarray]:
    """:func:`predict_dataset` for a state-space model with its values (a system family):
    driven runs follow their imposed motion, release and forced runs start from the first
    smoothed angle and velocity with the internal states at 0."""
    system, values = model
    out = []
    for r, d in zip(runs, ders, strict=True):
        if exp.motion_imposed:
            x0, inputs = system.initial_state(), {"theta": d.theta, "theta_dot": d.theta_dot}
        else:
            x0 = system.initial_state(
                theta=d.theta[0], theta_dot=0.0 if exp.starts_at_rest else d.theta_dot[0]
            )
            inputs = {"u": np.asarray(r.input, dtype=float)} if exp.has_input else {}
        y = simulate_system(
            system,
            r.t,
            x0,
            values,
            current=r.current,
            inputs=inputs,
            rtol=PREDICT_RTOL,
            atol=PREDICT_ATOL,
        ).y
        out.append(y)
    return out


def signals(dataset: Dataset, exp) -> list:
    """Each run's motion as a prediction takes it: a driven run's imposed motion and
    velocity as the fit estimates them (a periodic run's harmonic series, else local fits:
    :func:`~hystdisc.measurement.motion.estimate_motion`; the motion before a rig's
    declared filter when the filter acts on ``theta``), else the smoothed angle and its
    derivatives. Each item has ``theta``, ``theta_dot`` and ``theta_ddot``."""
    runs = list(dataset.runs)
    chans = tuple(dataset.filter["channels"]) if dataset.filter else ()
    windows = filter_windows(dataset.filter, runs, dataset.source) if chans else [0] * len(runs)
    out = []
    for k, (r, w) in enumerate(zip(runs, windows, strict=True)):
        noise = estimate_noise(r.theta, r.fs)
        if exp.motion_imposed and np.ptp(r.theta) > 0:
            d = estimate_motion(r.t, r.theta, noise, k)
            if "theta" in chans and w > 1:  # the motion the damper saw, rebuilt
                d.theta, d.theta_dot = unfiltered_motion(r.t, r.theta, w)
        else:
            d = differentiate(r.t, r.theta, noise)
        out.append(d)
    return out


def predict_dataset(
    tm,
    dataset: Dataset,
    experiment: str | None = None,
    input_hold: str = "cubic",
    detect_filter: bool = True,
    extra: Mapping[str, float] | None = None,
) -> list[np.ndarray]:
    """Predicted measured signal (theta, or torque for driven) of every run of ``dataset``.

    ``tm`` is a model in term form, or a state-space model with its parameter values (a
    system family's fit: ``OEFit.model``). Driven records that declare no filter but went
    through a moving average are predicted through it (``detect_filter``:
    :func:`~hystdisc.data.with_detected_filter`), as the fit saw its own. ``extra``
    (driven): the open library's accepted terms, name -> coefficient
    (:func:`~hystdisc.models.term_columns.term_column` of the motion and the current),
    added to the measured force as their refit added them.

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> from hystdisc.simulation.synth import generate
    >>> data = generate(Model("dahl"), currents=(0.5,), duration=1.0, noise=0.0, seed=0)
    >>> pred = predict_dataset(Model("dahl").to_terms(), data)
    >>> bool(np.max(np.abs(pred[0] - data.runs[0].theta)) < 1e-6)
    True
    """
    exp = get_experiment(experiment or dataset.experiment)
    if detect_filter:
        dataset = with_detected_filter(dataset)[0]
    runs = list(dataset.runs)
    ders = signals(dataset, exp)
    chans = tuple(dataset.filter["channels"]) if dataset.filter else ()
    windows = filter_windows(dataset.filter, runs, dataset.source) if chans else [0] * len(runs)
    out_windows = windows if exp.output in chans else [0] * len(runs)
    if isinstance(tm, TermModel):
        delay, gap = float(tm.delay), float(tm.play)
    else:
        delay, gap = tm[0].output_delay(tm[1]), tm[0].input_play(tm[1])
    added = [0.0] * len(runs)
    if extra and exp.motion_imposed:  # on the motion as the fit's data hold it
        added = [
            sum(c * term_column(n, d.theta, d.theta_dot, r.current, r.t) for n, c in extra.items())
            for r, d in zip(runs, ders, strict=True)
        ]
    if exp.motion_imposed and (delay != 0.0 or gap != 0.0):
        # the force channel lags: the damper answered the motion delay s earlier, through
        # its backlash (as the fit sees it: hystdisc.fitting.simulate.delayed_motion)
        for r, d in zip(runs, ders, strict=True):
            d.theta, d.theta_dot = seen_motion(r.t, d.theta, d.theta_dot, delay, gap)
        delay = 0.0
    preds = _predict(tm, runs, ders, exp, input_hold)
    return [
        measured_output(r.t, y, delay, w) + a
        for r, y, w, a in zip(runs, preds, out_windows, added, strict=True)
    ]


def _predict(tm, runs, ders, exp, input_hold: str) -> list[np.ndarray]:
    """The model's output on every run (before the measurement chain)."""
    if not isinstance(tm, TermModel):
        return _predict_system(tm, runs, ders, exp)
    if exp.motion_imposed:
        out, _ = simulate_driven_runs(
            tm,
            [r.t for r in runs],
            [r.current for r in runs],
            [d.theta for d in ders],
            [d.theta_dot for d in ders],
            raise_on_divergence=True,
        )
        return [o.torque for o in out]
    if exp.has_input:
        states = [initial_state(tm, r, d, input_hold) for r, d in zip(runs, ders, strict=True)]
        out, _ = simulate_mech(
            tm,
            [r.t for r in runs],
            [r.current for r in runs],
            [s[0] for s in states],
            inputs=[r.input for r in runs],
            theta_dot0=[s[1] for s in states],
            z0=[s[2] for s in states],
            hold=input_hold,
        )
        return [o.theta for o in out]
    out, _ = simulate_mech(
        tm, [r.t for r in runs], [r.current for r in runs], [d.theta[0] for d in ders]
    )
    return [o.theta for o in out]


#: Length of the start of a forced record used to estimate its initial state (s).
STATE_WINDOW = 0.5


def initial_state(tm: TermModel, run, der, input_hold: str = "cubic") -> tuple[float, float, float]:
    """Initial angle, velocity and z of a forced run, fitted to its first ``STATE_WINDOW`` s.

    A forced record may start mid-motion (a periodic excitation in steady state): the state
    there is the same nuisance that discovery estimates. The model's parameters stay fixed;
    only these three numbers are fitted, on the start of the record.
    """
    from scipy.optimize import least_squares

    n = int(min(run.t.size, max(50, round(STATE_WINDOW * run.fs))))
    t, u, y = run.t[:n], run.input[:n], run.theta[:n]
    start = np.array([der.theta[0], der.theta_dot[0], 0.0])
    free = 3 if tm.hysteresis else 2

    def resid(v):
        full = np.concatenate([v, start[free:]])
        (o,), status = simulate_mech(
            tm,
            [t],
            [run.current],
            [full[0]],
            inputs=[u],
            theta_dot0=[full[1]],
            z0=[full[2]],
            hold=input_hold,
            raise_on_divergence=False,
        )
        r = o.theta - y
        return r if not status[0] and np.all(np.isfinite(r)) else np.full(n, 1e6)

    with np.errstate(all="ignore"):
        sol = least_squares(resid, start[:free], x_scale="jac", max_nfev=50)
    # least_squares only accepts steps that lower the cost: its result is never worse
    v = sol.x if np.all(np.isfinite(sol.x)) else start[:free]
    full = np.concatenate([v, start[free:]])
    return float(full[0]), float(full[1]), float(full[2])
