"""Simulate a fitted model on new runs (``hystdisc predict``).

Release runs start from the run's first (smoothed) angle at rest; driven runs use the
run's imposed motion (velocity by the same smoothed differentiation as discovery); forced
runs start from the first angle and smoothed velocity and follow the run's input.
"""

from __future__ import annotations

import numpy as np

from hystdisc.differentiation import differentiate
from hystdisc.io import Dataset, estimate_noise
from hystdisc.models import TermModel
from hystdisc.simulation import simulate_driven_runs, simulate_mech


def predict_dataset(
    tm: TermModel, dataset: Dataset, experiment: str | None = None, input_hold: str = "cubic"
) -> list[np.ndarray]:
    """Predicted measured signal (theta, or torque for driven) of every run of ``dataset``.

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> from hystdisc.synth import generate
    >>> data = generate(Model("dahl"), currents=(0.5,), duration=1.0, noise=0.0, seed=0)
    >>> pred = predict_dataset(Model("dahl").to_terms(), data)
    >>> bool(np.max(np.abs(pred[0] - data.runs[0].theta)) < 1e-6)
    True
    """
    exp = experiment or dataset.experiment
    runs = list(dataset.runs)
    ders = []
    for r in runs:
        noise = estimate_noise(r.theta, r.fs)
        ders.append(differentiate(r.t, r.theta, noise))
    if exp == "driven":
        out, _ = simulate_driven_runs(
            tm,
            [r.t for r in runs],
            [r.current for r in runs],
            [d.theta for d in ders],
            [d.theta_dot for d in ders],
            raise_on_divergence=True,
        )
        return [o.torque for o in out]
    if exp == "forced":
        out, _ = simulate_mech(
            tm,
            [r.t for r in runs],
            [r.current for r in runs],
            [d.theta[0] for d in ders],
            inputs=[r.input for r in runs],
            theta_dot0=[d.theta_dot[0] for d in ders],
            hold=input_hold,
        )
        return [o.theta for o in out]
    out, _ = simulate_mech(
        tm, [r.t for r in runs], [r.current for r in runs], [d.theta[0] for d in ders]
    )
    return [o.theta for o in out]
