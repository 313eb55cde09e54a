"""Candidate runs: what a new experiment would impose, and the runs already recorded.

A :class:`RunSpec` describes one run to record: a release from an angle at a current, a
driven sine (amplitude, frequency, current) or a driven multisine (a frequency band, an
RMS amplitude, a current). :func:`candidate_runs` lays out the default grid around the
training envelope of a ``results.json``; :func:`recorded_runs` rebuilds the runs the fit
saw from that envelope (a release from its peak angle; a driven run as the sine with its
peak displacement and velocity), since ``results.json`` keeps no signals.

Examples
--------
>>> spec = RunSpec("release", current=0.5, amplitude=0.2, duration=3.0, fs=500.0)
>>> spec.label()
'release from 0.2 rad at 0.5 A'
>>> t, theta, theta_dot = RunSpec("sine", 1.0, 0.1, frequency=2.0, duration=1.0).motion()
>>> round(float(theta.max()), 3), t.size
(0.1, 1000)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Kinds of candidate run.
KINDS = ("release", "sine", "multisine")
#: Release angles of the default grid, in multiples of the largest angle in training.
ANGLE_FACTORS = (0.5, 1.0, 2.0, 4.0)
#: Largest release angle the default grid proposes (rad).
MAX_ANGLE = 1.0
#: Sine amplitudes (multiples of the largest trained displacement) and frequencies
#: (multiples of the trained frequency) of the default driven grid.
AMPLITUDE_FACTORS = (0.5, 1.0, 2.0)
FREQUENCY_FACTORS = (0.5, 1.0, 2.0, 4.0)
#: Largest peak velocity of the default driven grid, in multiples of the trained one (a
#: model says little far beyond its envelope, and the rig has its limits).
MAX_SPEED_FACTOR = 2.0
#: Multisine bands of the default driven grid, multiples of the trained frequency.
BANDS = ((0.25, 1.0), (0.5, 2.0), (1.0, 4.0))
#: Lines of a multisine (Schroeder phases).
MULTISINE_LINES = 8


@dataclass(frozen=True)
class RunSpec:
    """One run to record (or one the fit saw, rebuilt).

    Attributes
    ----------
    kind : str
        ``"release"``, ``"sine"`` or ``"multisine"`` (:data:`KINDS`).
    current : float
        Coil current, A.
    amplitude : float
        Release angle (rad), sine amplitude, or multisine peak displacement (data units).
    frequency : float
        Sine frequency, Hz (0 for the others).
    band : tuple of float
        Multisine band ``(f_low, f_high)``, Hz (empty for the others).
    duration : float
        Length of the record, s.
    fs : float
        Sampling rate, Hz.
    """

    kind: str
    current: float
    amplitude: float
    frequency: float = 0.0
    band: tuple[float, ...] = ()
    duration: float = 3.0
    fs: float = 1000.0

    def label(self) -> str:
        """The run in words (what to record)."""
        if self.kind == "release":
            return f"release from {self.amplitude:.3g} rad at {self.current:.3g} A"
        if self.kind == "sine":
            return f"sine {self.amplitude:.3g} at {self.frequency:.3g} Hz, {self.current:.3g} A"
        lo, hi = self.band
        return f"multisine {lo:.3g}-{hi:.3g} Hz, peak {self.amplitude:.3g}, {self.current:.3g} A"

    def times(self) -> np.ndarray:
        """The sample times, ``round(duration * fs)`` samples from 0."""
        return np.arange(int(round(self.duration * self.fs))) / self.fs

    def motion(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, imposed displacement and velocity of a driven run (zeros for a release)."""
        t = self.times()
        if self.kind == "release":
            return t, np.zeros_like(t), np.zeros_like(t)
        if self.kind == "sine":
            w = 2 * np.pi * self.frequency
            return t, self.amplitude * np.sin(w * t), self.amplitude * w * np.cos(w * t)
        freqs = np.linspace(self.band[0], self.band[1], MULTISINE_LINES)
        k = np.arange(1, MULTISINE_LINES + 1)
        phases = -np.pi * k * (k - 1) / MULTISINE_LINES  # Schroeder: a low crest factor
        arg = 2 * np.pi * freqs[:, None] * t[None, :] + phases[:, None]
        x = np.sin(arg).sum(axis=0)
        v = (2 * np.pi * freqs[:, None] * np.cos(arg)).sum(axis=0)
        peak = float(np.max(np.abs(x))) or 1.0
        return t, self.amplitude * x / peak, self.amplitude * v / peak


def recorded_runs(envelope: Mapping[str, Any], driven: bool, fs: float) -> list[RunSpec]:
    """The runs the fit saw, rebuilt from the training envelope of ``results.json``.

    A release run is the release from its peak angle; a driven run the sine of its peak
    displacement and velocity (``f = v_max / (2 pi x_max)``).

    Parameters
    ----------
    envelope : dict
        The ``envelope`` entry (each run's ``current``, ``theta_max``, ``theta_dot_max``,
        ``duration``).
    driven : bool
        The experiment imposes the motion.
    fs : float
        Sampling rate, Hz.

    Examples
    --------
    >>> env = {"runs": [{"name": "0", "current": 0.5, "theta_max": 0.01,
    ...                  "theta_dot_max": 0.0628, "duration": 2.0}]}
    >>> recorded_runs(env, False, 500.0)[0].label()
    'release from 0.01 rad at 0.5 A'
    >>> recorded_runs(env, True, 500.0)[0].label()
    'sine 0.01 at 0.999 Hz, 0.5 A'
    """
    out = []
    for r in envelope.get("runs") or []:
        a, i, d = float(r["theta_max"]), float(r["current"]), float(r["duration"])
        if not driven:
            out.append(RunSpec("release", i, a, 0.0, (), d, fs))
            continue
        f = float(r["theta_dot_max"]) / (2 * np.pi * a) if a > 0 else 1.0
        out.append(RunSpec("sine", i, a, f, (), d, fs))
    return out


def default_currents(envelope: dict) -> list[float]:
    """Currents of the default grid: 0 to the largest trained current, 5 levels.

    The current laws are identified only up to the largest current the fit saw (an MR
    damper saturates, and the coil has its own limit): a run beyond it is suggested only
    when its currents are named (``--currents``).

    Examples
    --------
    >>> default_currents({"current_min": 0.0, "current_max": 1.0})
    [0.0, 0.25, 0.5, 0.75, 1.0]
    """
    top = float(envelope.get("current_max") or 0.0)
    if top <= 0:
        return [0.0]
    return [round(float(c), 6) for c in np.linspace(0.0, top, 5)]


def candidate_runs(
    envelope: dict,
    driven: bool,
    fs: float,
    duration: float,
    currents: list[float] | None = None,
) -> list[RunSpec]:
    """The default candidate grid around the training envelope.

    A release set gets every angle of :data:`ANGLE_FACTORS` times the largest trained
    angle (at most :data:`MAX_ANGLE`) at every current; a driven set every sine of
    :data:`AMPLITUDE_FACTORS` x :data:`FREQUENCY_FACTORS` and every multisine of
    :data:`BANDS` (peak displacement the trained one) at every current, none faster than
    :data:`MAX_SPEED_FACTOR` times the trained peak velocity (a multisine is scaled down
    to it). Currents default to :func:`default_currents`.

    Examples
    --------
    >>> env = {"theta_max": 0.1, "theta_dot_max": 1.0, "current_max": 0.5}
    >>> len(candidate_runs(env, False, 500.0, 3.0)), len(candidate_runs(env, True, 500.0, 3.0))
    (20, 60)
    """
    cur = currents if currents is not None else default_currents(envelope)
    amax = float(envelope.get("theta_max") or 0.1)
    out = []
    if not driven:
        angles = sorted({min(MAX_ANGLE, round(f * amax, 6)) for f in ANGLE_FACTORS})
        for i in cur:
            out.extend(RunSpec("release", i, a, 0.0, (), duration, fs) for a in angles)
        return out
    vmax = float(envelope.get("theta_dot_max") or 2 * np.pi * amax)
    f0 = vmax / (2 * np.pi * amax)
    sines = [
        (fa * amax, ff * f0)
        for fa in AMPLITUDE_FACTORS
        for ff in FREQUENCY_FACTORS
        if fa * ff <= MAX_SPEED_FACTOR * (1 + 1e-9)
    ]
    multi = []
    for lo, hi in BANDS:
        spec = RunSpec("multisine", 0.0, amax, 0.0, (lo * f0, hi * f0), duration, fs)
        peak = float(np.max(np.abs(spec.motion()[2])))
        multi.append((amax * min(1.0, MAX_SPEED_FACTOR * vmax / peak), spec.band))
    for i in cur:
        out.extend(RunSpec("sine", i, a, f, (), duration, fs) for a, f in sines)
        out.extend(RunSpec("multisine", i, a, 0.0, b, duration, fs) for a, b in multi)
    return out
