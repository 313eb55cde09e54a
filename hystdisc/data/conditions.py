"""Test conditions: which runs share an input, so that a model can be judged on one it has not seen.

A *condition* is a set of runs that share their input across currents: one sine (its
amplitude and frequency) on a characterization machine, one release angle on the SAS
rig, one input record on a forced rig. Leaving a whole condition out of a fit and
predicting it is the test of whether a conclusion holds beyond the training data (a
model that only interpolates between currents of the same sine has not been tested).

Conditions are detected from the data (:func:`detect_conditions`) unless a run carries
its own label (a ``condition`` column, or the rig description).

Examples
--------
>>> import numpy as np
>>> t = np.arange(0, 2, 1e-3)
>>> runs = [np.sin(2 * np.pi * f * t) * a for a, f in [(1, 1), (1, 1), (2, 3), (1.02, 1)]]
>>> detect_conditions("driven", [t] * 4, runs)
['1 @ 1 Hz', '1 @ 1 Hz', '2 @ 3 Hz', '1 @ 1 Hz']
>>> condition_folds(['a', 'a', 'b', 'a'])
[[0, 1, 3], [2]]
>>> condition_folds(['a', 'a'])  # one condition: leave one run out instead
[[0], [1]]
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hystdisc.registry import get_experiment

#: Relative tolerance within which two runs' amplitudes (or release angles) are the same.
AMPLITUDE_TOL = 0.1
#: Relative tolerance within which two runs' frequencies are the same.
FREQUENCY_TOL = 0.1
#: Relative RMS difference below which two input records are the same.
INPUT_TOL = 1e-6


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def driven_signature(t: np.ndarray, theta: np.ndarray) -> tuple[float, float]:
    """Amplitude and frequency of an imposed oscillation (frequency from the spacing of
    its interpolated zero crossings, so a record of a few cycles is measured as well)."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(theta, dtype=float) - 0.5 * (np.max(theta) + np.min(theta))
    amplitude = 0.5 * float(np.ptp(x))
    k = np.flatnonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))
    if k.size < 2:
        return amplitude, 0.0
    tc = t[k] + (t[k + 1] - t[k]) * x[k] / (x[k] - x[k + 1])
    frequency = (k.size - 1) / (2.0 * float(tc[-1] - tc[0]))
    return amplitude, frequency


def relatively_close(a: float, b: float, tol: float) -> bool:
    """Whether ``a`` and ``b`` agree within the relative tolerance ``tol``."""
    return abs(a - b) <= tol * max(abs(a), abs(b), 1e-300)


def detect_conditions(
    experiment: str,
    t: Sequence[np.ndarray],
    theta: Sequence[np.ndarray],
    inputs: Sequence[np.ndarray | None] | None = None,
) -> list[str]:
    """A condition label per run, from what the runs share.

    Parameters
    ----------
    experiment : str or Experiment
        ``release``: runs share a condition when they start from the same angle (within
        :data:`AMPLITUDE_TOL`); ``driven``: the same amplitude and frequency of the
        imposed motion (:data:`AMPLITUDE_TOL`, :data:`FREQUENCY_TOL`); ``forced``: the
        same input record (:data:`INPUT_TOL`).
    t, theta : sequences of ndarray
        Each run's times and angle (or displacement).
    inputs : sequence of ndarray, optional
        Each run's input (forced experiments).

    Returns
    -------
    list of str
        One label per run, in run order; runs with equal labels share a condition.
    """
    exp = get_experiment(experiment)
    labels: list[str] = []
    reps: list[tuple[str, tuple]] = []  # (label, signature) of each condition found
    for k in range(len(t)):
        if exp.motion_imposed:
            sig: tuple = driven_signature(t[k], theta[k])
            match = [
                lab
                for lab, s in reps
                if relatively_close(s[0], sig[0], AMPLITUDE_TOL)
                and relatively_close(s[1], sig[1], FREQUENCY_TOL)
            ]
            label = f"{_fmt(sig[0])} @ {_fmt(sig[1])} Hz"
        elif exp.has_input and inputs is not None and inputs[k] is not None:
            u = np.asarray(inputs[k], dtype=float)
            sig = (u,)
            scale = float(np.sqrt(np.mean(u**2))) or 1.0
            match = [
                lab
                for lab, s in reps
                if s[0].shape == u.shape
                and float(np.sqrt(np.mean((s[0] - u) ** 2))) <= INPUT_TOL * scale
            ]
            label = f"input record {len(reps) + 1}"
        else:
            sig = (float(theta[k][0]),)
            match = [lab for lab, s in reps if relatively_close(s[0], sig[0], AMPLITUDE_TOL)]
            label = f"start at {_fmt(sig[0])}"
        if match:
            labels.append(match[0])
        else:
            reps.append((label, sig))
            labels.append(label)
    return labels


def condition_folds(labels: Sequence[str]) -> list[list[int]]:
    """The runs each held-out fold leaves out: one fold per condition, in order of first
    appearance, or one per run when all runs share one condition.

    Parameters
    ----------
    labels : sequence of str
        A condition label per run (:func:`detect_conditions`).
    """
    order: dict[str, list[int]] = {}
    for k, lab in enumerate(labels):
        order.setdefault(lab, []).append(k)
    if len(order) < 2:
        return [[k] for k in range(len(labels))]
    return list(order.values())
