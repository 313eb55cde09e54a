"""Synthetic datasets: simulate a known model on the rig and measure it like a sensor would.

Three experiment types (doc/design.rst section 1):

``release``
    The SAS rig released from ``theta0`` at rest, one run per current, per unit inertia.
``driven``
    Imposed sines ``theta = A sin(2 pi f t)`` (one run per drive and current); ``theta`` and
    ``theta_dot`` are analytic, the torque is simulated and measured with noise.
``forced``
    A known input ``u(t)`` per run (a random-phase multisine or a sine) drives
    ``J theta'' + T = u``; ``J`` comes from the model.

Measurement model: additive Gaussian noise of standard deviation ``noise`` on the measured
signal (``theta`` for release/forced, ``torque`` for driven, plus ``theta_noise`` on the
driven ``theta``), drawn from ``np.random.default_rng(seed)``, then optional encoder
quantization of ``theta`` (``encoder_counts`` per turn: ``q = 2 pi / counts``), then
an optional prefilter (a rig's ``[filter]`` table: :mod:`hystdisc.simulation.prefilter`),
then optional glitches:
``spikes = (N, SIZE)`` adds ``+-SIZE`` to ``N`` single samples of the
measured signal drawn at random over all runs (a sensor's isolated spikes; their own
random stream, so the noise is the same with and without them).

A structural effect (``series_compliance``: the beam on a compliant wheel) makes the
model a state-space system; its runs are simulated by the error-controlled integrator
(:func:`~hystdisc.simulation.ode.simulate_system`) from rest at ``theta0``, the wheel at
rest at 0 (``--effect series_compliance:k_w=900,c_w=3,m_w=0.3`` on the command line,
``[effects.series_compliance]`` in a scenario; release and driven experiments: a driven
damper behind a compliant mount, the mount at rest).

The settings are checked by :mod:`hystdisc.simulation.synth_checks`. Scenarios are TOML
files with the same settings as ``hystdisc simulate``
(:mod:`hystdisc.simulation.scenarios`).

Examples
--------
>>> from hystdisc.models import Model
>>> from hystdisc.simulation.synth import generate
>>> ds = generate(Model("dahl"), currents=(0.0, 1.0), duration=1.0, seed=1)
>>> ds.names, ds.experiment, ds[0].n, float(ds[1].current)
(['0', '1'], 'release', 1000, 1.0)
>>> ds = generate(Model("dahl", {"k_s": 0.0}), "driven", currents=(0.5,), duration=1.0,
...               drives=[{"amplitude": 0.3, "frequency": 1.0}], noise=0.0)
>>> round(float(ds[0].theta_dot[0]), 4)  # 0.3 * 2 pi
1.885
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc import registry
from hystdisc.data import Dataset, Run, write_csv
from hystdisc.errors import HystdiscError
from hystdisc.models import Model, TermModel
from hystdisc.models.backlash import play_motion
from hystdisc.simulation import simulate_driven_runs, simulate_mech, simulate_system
from hystdisc.simulation.prefilter import apply_prefilter, check_prefilter
from hystdisc.simulation.synth_checks import (
    check_currents,
    check_input_spec,
    check_number,
    check_spikes,
    parse_drive,
)

__all__ = [
    "DEFAULT_CURRENTS",
    "generate",
    "make_input",
    "round_significant",
    "write_dataset",
]

DEFAULT_CURRENTS = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The seed's current steps, in A."""

MAX_SAMPLES = 10_000_000
"""Most samples :func:`generate` makes in all runs together (80 MB per signal)."""

CSV_DIGITS = 7
"""Significant digits kept when a synthetic dataset is written (:func:`write_dataset`)."""


# ----------------------------------------------------------------------------- input


def make_input(
    spec: Mapping[str, Any] | None, t: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Input signal of a forced run.

    ``multisine``: random-phase sum of equal-amplitude cosines at the frequencies ``k / T``
    (``T`` the record length) within ``[f_min, f_max]``, scaled to the requested RMS.
    ``sine``: ``amplitude * sin(2 pi frequency t)``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4000) / 1000.0
    >>> u = make_input({"kind": "multisine", "rms": 2.0, "f_min": 1, "f_max": 5}, t,
    ...                np.random.default_rng(0))
    >>> round(float(np.sqrt(np.mean(u**2))), 6)
    2.0
    """
    s = check_input_spec(spec)
    t = np.asarray(t, dtype=float)
    if s["kind"] == "sine":
        return s["amplitude"] * np.sin(2.0 * np.pi * s["frequency"] * (t - t[0]))
    n = t.size
    span = n * float(np.median(np.diff(t))) if n > 1 else 1.0
    k_lo = max(1, math.ceil(s["f_min"] * span - 1e-9))
    k_hi = math.floor(s["f_max"] * span + 1e-9)
    if k_hi < k_lo:
        raise HystdiscError(
            f"the multisine band {s['f_min']:g}-{s['f_max']:g} Hz holds no frequency of a "
            f"{span:g} s record (resolution {1 / span:.3g} Hz); fix: widen the band or "
            "lengthen the record"
        )
    freqs = np.arange(k_lo, k_hi + 1) / span
    phases = rng.uniform(0.0, 2.0 * np.pi, freqs.size)
    tt = t - t[0]
    u = np.zeros(n)
    for f, ph in zip(freqs, phases, strict=True):
        u += np.cos(2.0 * np.pi * f * tt + ph)
    rms = float(np.sqrt(np.mean(u * u)))
    return u * (s["rms"] / rms) if rms > 0 else u


# ----------------------------------------------------------------------------- generate


def _as_model(model: Model | TermModel | str) -> Model | TermModel:
    if isinstance(model, str):
        return Model(model)
    if isinstance(model, (Model, TermModel)):
        return model
    raise HystdiscError(
        f"model {model!r} is not a Model; fix: pass hystdisc.models.Model('bouc-wen', ...) "
        "or a family name"
    )


def _is_system(model: Model | TermModel) -> bool:
    """The model is a system family's (simulated by the error-controlled integrator)."""
    return isinstance(model, Model) and model.family.is_system


def _measure_theta(
    theta: np.ndarray, std: float, q: float | None, rng: np.random.Generator
) -> np.ndarray:
    # the noise draw is made even when std = 0 so that the stream stays the same
    out = theta + std * rng.standard_normal(theta.size)
    if q is not None:
        out = np.round(out / q) * q
    return out


def generate(
    model: Model | TermModel | str,
    experiment: str = "release",
    currents: Sequence[float] = DEFAULT_CURRENTS,
    duration: float = 6.0,
    fs: float = 1000.0,
    theta0: float | Sequence[float] | None = None,
    noise: float = 0.001,
    seed: int = 0,
    encoder_counts: int | None = None,
    drives: Sequence[Mapping[str, float] | str] | None = None,
    input_spec: Mapping[str, Any] | None = None,
    theta_noise: float = 0.0,
    delay: float = 0.0,
    spikes: tuple[int, float] | None = None,
    prefilter: Mapping[str, Any] | None = None,
) -> Dataset:
    """Simulate a model on the rig and measure it with noise and quantization.

    Parameters
    ----------
    model : Model, TermModel or str
        The truth (a family name means its demo defaults).
    experiment : {"release", "driven", "forced"}
        Experiment type (module docstring).
    currents : sequence of float
        Coil currents in A, one run each (``driven``: one run per drive and current).
    duration : float
        Length of every run in s; a run has ``round(duration * fs)`` samples from ``t = 0``.
    fs : float
        Sampling rate in Hz.
    theta0 : float or sequence of float, optional
        Initial angle in rad, one for all runs or one per run: default 0.3 for release,
        0 for forced (at rest); unused by driven experiments.
    noise : float
        Standard deviation of the Gaussian noise on the measured signal (rad for
        release/forced, N*m for the driven torque).
    seed : int
        Seed of ``np.random.default_rng`` (noise and multisine phases).
    encoder_counts : int, optional
        Encoder counts per turn; ``theta`` is rounded to multiples of ``2 pi / counts``.
    drives : sequence, optional
        Driven only: sines ``{"amplitude": rad, "frequency": Hz}`` or ``"A@f"``; runs are
        ordered drive by drive, each at every current. Default ``0.3@1.0``.
    input_spec : dict, optional
        Forced only: ``{"kind": "multisine", "rms", "f_min", "f_max"}`` (default
        :data:`~hystdisc.simulation.synth_checks.DEFAULT_INPUT`) or
        ``{"kind": "sine", "amplitude", "frequency"}``; every run gets its own random phases.
    theta_noise : float
        Driven only: noise standard deviation on the measured ``theta`` (rad).
    delay : float
        Delay of the output channel behind the other, in s (driven and forced; the
        ``channel_delay`` effect): the measured torque (driven) or angle (forced) is the
        true one at ``t - delay``. Driven runs are simulated on the motion shifted by
        ``delay`` (exact); forced outputs are shifted by linear interpolation.
    spikes : (int, float), optional
        ``(N, SIZE)``: ``N`` isolated glitches of ``+-SIZE`` (random sign) on single samples
        of the measured signal (``theta``, or the driven ``torque``), at distinct samples
        drawn uniformly over all runs by ``np.random.default_rng([seed, 1])``. The noise
        draws do not change with them.
    prefilter : dict, optional
        A filter the recorded signals passed through, as a rig's ``[filter]`` table:
        ``{"window": N}`` samples or ``{"period_fraction": F}`` of each run's motion
        period, and ``channels`` (default: every recorded channel, ``theta`` and the
        driven ``torque`` or the forced ``input``). Each channel is replaced by its causal
        moving average with zero initial state, after the noise and the quantization and
        before the spikes (a filtered ``theta`` filters the stored ``theta_dot`` too).

    Returns
    -------
    Dataset
        Runs named ``"0"``, ``"1"``, ...; ``driven`` runs carry ``torque`` and the analytic
        ``theta_dot``; ``forced`` runs carry the (noise-free) ``input``.

    Raises
    ------
    HystdiscError
        For a bad argument, or when the simulation diverges.

    Examples
    --------
    >>> ds = generate("bouc-wen", currents=(0, 1), duration=2.0, encoder_counts=4096, seed=3)
    >>> q = 2 * np.pi / 4096
    >>> bool(np.allclose(ds[0].theta / q, np.round(ds[0].theta / q)))
    True
    >>> clean = generate("dahl", currents=(0, 1), duration=1.0, seed=2)
    >>> spiky = generate("dahl", currents=(0, 1), duration=1.0, seed=2, spikes=(3, 0.05))
    >>> d = np.concatenate([s.theta - c.theta for s, c in zip(spiky, clean)])
    >>> int(np.count_nonzero(d)), np.round(np.abs(d[d != 0]), 12).tolist()
    (3, [0.05, 0.05, 0.05])
    >>> generate("dahl", duration=-1)
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: duration = -1 must be positive; fix: give a value > 0
    """
    mdl = _as_model(model)
    exp = str(experiment).strip().lower()
    if exp not in registry.experiment_names():
        raise HystdiscError(
            f"unknown experiment {experiment!r}; fix: use "
            f"{', '.join(registry.experiment_names()[:-1])} or {registry.experiment_names()[-1]}"
        )
    kind = registry.get_experiment(exp)
    cur = check_currents(currents)
    duration = check_number(duration, "duration", positive=True)
    fs = check_number(fs, "fs", positive=True)
    noise = check_number(noise, "noise", nonneg=True)
    theta_noise = check_number(theta_noise, "theta_noise", nonneg=True)
    delay = check_number(delay, "delay")
    if delay and not (kind.motion_imposed or kind.has_input):
        raise HystdiscError(
            f"a delay between channels needs two channels, a {exp} experiment records one; "
            "fix: drop the delay or use a driven or forced experiment"
        )
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise HystdiscError(f"seed = {seed!r} is invalid; fix: give a whole number >= 0")
    q = None
    if encoder_counts is not None:
        if (
            isinstance(encoder_counts, bool)
            or not isinstance(encoder_counts, (int, np.integer))
            or encoder_counts <= 0
        ):
            raise HystdiscError(
                f"encoder_counts = {encoder_counts!r} is invalid; fix: give the counts per "
                "turn as a whole number > 0"
            )
        q = 2.0 * np.pi / int(encoder_counts)
    per_current = len(drives) if kind.motion_imposed and isinstance(drives, (list, tuple)) else 1
    total = duration * fs * len(cur) * max(per_current, 1)
    if not total <= MAX_SAMPLES:  # also catches an overflow to inf
        raise HystdiscError(
            f"duration {duration:g} s at fs {fs:g} Hz gives {total:.3g} samples in all, more "
            f"than {MAX_SAMPLES:.0e}; fix: shorten the duration, lower fs or use fewer runs"
        )
    n = int(round(duration * fs))
    if n < 2:
        raise HystdiscError(
            f"duration {duration:g} s at fs {fs:g} Hz gives {n} sample(s); fix: record longer "
            "or sample faster"
        )
    if not kind.motion_imposed and drives:
        raise HystdiscError(
            f"drives are only used by driven experiments, not {exp}; fix: drop them"
        )
    if not kind.has_input and input_spec is not None:
        raise HystdiscError(f"an input is only used by forced experiments, not {exp}; fix: drop it")
    n_spikes, spike_size = check_spikes(spikes, n * len(cur) * max(per_current, 1))
    filt = check_prefilter(prefilter, kind)
    t = np.arange(n) / fs
    rng = np.random.default_rng(int(seed))
    label = repr(mdl) if isinstance(mdl, Model) else "a term model"
    source = f"synthetic {exp} data of {label}"

    if kind.motion_imposed:
        if theta0 is not None:
            raise HystdiscError(
                "theta0 is not used by driven experiments (theta is imposed); fix: drop it"
            )
        dlist = [parse_drive(d) for d in (drives or ["0.3@1.0"])]
        cases = [(d, c) for d in dlist for c in cur]
        ths = [d["amplitude"] * np.sin(2 * np.pi * d["frequency"] * t) for d, _ in cases]
        ws = [
            d["amplitude"] * 2 * np.pi * d["frequency"] * np.cos(2 * np.pi * d["frequency"] * t)
            for d, _ in cases
        ]
        if delay:  # the force the damper makes at t - delay, recorded at t
            ts = t - delay
            mot = [(d["amplitude"], 2 * np.pi * d["frequency"]) for d, _ in cases]
            shifted = [a * np.sin(om * ts) for a, om in mot]
            wshift = [a * om * np.cos(om * ts) for a, om in mot]
        else:
            shifted, wshift = ths, ws
        gap = _play(mdl, exp)
        if gap:  # a backlash between the actuator and the damper
            seen = [play_motion(th, w, gap) for th, w in zip(shifted, wshift, strict=True)]
            shifted, wshift = [s for s, _ in seen], [w for _, w in seen]
        structural = None if _is_system(mdl) else _structural(mdl, exp)
        if _is_system(mdl) or structural is not None:
            if structural is not None:
                sys = registry.get_effect(structural).system_model(mdl.to_terms(), exp)
                values = mdl.effects[structural]
            else:
                sys, values = mdl.system(exp)
            torques = [
                simulate_system(
                    sys, t, sys.initial_state(), values, c, {"theta": th, "theta_dot": w}
                ).y
                for (_, c), th, w in zip(cases, shifted, wshift, strict=True)
            ]
        else:
            sims, _ = simulate_driven_runs(
                mdl, [t] * len(cases), [c for _, c in cases], shifted, wshift
            )
            torques = [sim.torque for sim in sims]
        runs = []
        for k, ((_, c), torque, th, w) in enumerate(zip(cases, torques, ths, ws, strict=True)):
            torque = torque + noise * rng.standard_normal(n)
            theta_m = _measure_theta(th, theta_noise, q, rng)
            runs.append(Run(str(k), t.copy(), theta_m, c, torque=torque, theta_dot=w.copy()))
        apply_prefilter(runs, filt, source)
        _add_spikes([r.torque for r in runs], n_spikes, spike_size, int(seed))
        return Dataset(runs, exp, source)

    if theta0 is None:
        th0 = [0.3 if kind.starts_at_rest else 0.0] * len(cur)
    elif isinstance(theta0, (int, float, np.floating)) and not isinstance(theta0, bool):
        th0 = [check_number(theta0, "theta0")] * len(cur)
    else:
        th0 = [check_number(v, "theta0") for v in theta0]
        if len(th0) != len(cur):
            raise HystdiscError(
                f"{len(th0)} theta0 values for {len(cur)} currents; fix: give one theta0, or "
                "one per current"
            )
    inputs = None
    if kind.has_input:
        spec = check_input_spec(input_spec)
        inputs = [make_input(spec, t, rng) for _ in cur]
    structural = None if _is_system(mdl) else _structural(mdl, exp)
    if _is_system(mdl):
        sys, values = mdl.system(exp)
        thetas = [
            simulate_system(
                sys,
                t,
                sys.initial_state(theta=th0[k]),
                values,
                c,
                {"u": inputs[k]} if inputs is not None else {},
            ).y
            for k, c in enumerate(cur)
        ]
    elif structural is None:
        thetas = [s.theta for s in simulate_mech(mdl, [t] * len(cur), cur, th0, inputs=inputs)[0]]
    else:
        thetas = _simulate_structural(mdl, structural, t, cur, th0)
    runs = []
    for k, (c, theta) in enumerate(zip(cur, thetas, strict=True)):
        theta_m = _measure_theta(np.interp(t - delay, t, theta), noise, q, rng)
        extra = {"input": inputs[k]} if inputs is not None else {}
        runs.append(Run(str(k), t.copy(), theta_m, c, **extra))
    apply_prefilter(runs, filt, source)
    _add_spikes([r.theta for r in runs], n_spikes, spike_size, int(seed))
    return Dataset(runs, exp, source)


def _add_spikes(signals: list[np.ndarray], count: int, size: float, seed: int) -> None:
    """Add ``+-size`` to ``count`` distinct samples of ``signals`` (in place), drawn over
    all runs by their own generator (the noise stream does not change)."""
    if count == 0:
        return
    rng = np.random.default_rng([seed, 1])
    sizes = np.array([s.size for s in signals])
    flat = rng.choice(int(sizes.sum()), size=count, replace=False)
    signs = rng.choice([-1.0, 1.0], size=count)
    bounds = np.cumsum(sizes)
    for f, sign in zip(flat, signs, strict=True):
        k = int(np.searchsorted(bounds, f, side="right"))
        signals[k][f - (bounds[k] - sizes[k])] += sign * size


def _play(mdl: Model | TermModel, exp: str) -> float:
    """The backlash half-width of ``mdl`` (0 without one)."""
    if isinstance(mdl, TermModel):
        return float(mdl.play)
    if _is_system(mdl):
        sys, values = mdl.system(exp)
        return sys.input_play(values)
    return float(mdl.to_terms().play)


def _structural(mdl: Model | TermModel, exp: str) -> str | None:
    """The structural effect of ``mdl`` (None without one), checked against ``exp``."""
    if not isinstance(mdl, Model):
        return None
    names = [e for e in mdl.effects if registry.get_effect(e).structural]
    if not names:
        return None
    if len(names) > 1:
        raise HystdiscError(
            f"effects {', '.join(names)} each add states; fix: simulate one of them at a time"
        )
    eff = registry.get_effect(names[0])
    if eff.experiments and exp not in eff.experiments:
        raise HystdiscError(
            f"{eff.name} is built for {', '.join(eff.experiments)} experiments, not {exp}; "
            f"fix: drop it or use --experiment {eff.experiments[0]}"
        )
    return names[0]


def _simulate_structural(
    mdl: Model, name: str, t: np.ndarray, cur: Sequence[float], th0: Sequence[float]
) -> list[np.ndarray]:
    """The measured angle of each run of ``mdl`` realized with its structural effect."""
    system = registry.get_effect(name).system_model(mdl.to_terms(), "release")
    out = []
    for c, a in zip(cur, th0, strict=True):
        sim = simulate_system(system, t, system.initial_state(theta=a), mdl.effects[name], c)
        out.append(sim.y)
    return out


# ----------------------------------------------------------------------------- writing


def round_significant(x: np.ndarray, digits: int = CSV_DIGITS) -> np.ndarray:
    """Round to ``digits`` significant digits (zeros stay zero).

    Examples
    --------
    >>> round_significant(np.array([0.123456789, -98765.4321, 0.0, 1.5e-9]), 3).tolist()
    [0.123, -98800.0, 0.0, 1.5e-09]
    """
    x = np.asarray(x, dtype=float)
    out = x.copy()
    nz = np.isfinite(x) & (x != 0)
    e = np.floor(np.log10(np.abs(x[nz])))
    scale = 10.0 ** (digits - 1 - e)
    out[nz] = np.round(x[nz] * scale) / scale
    return out


def write_dataset(
    dataset: Dataset, path: str | os.PathLike[str], force: bool = False, digits: int = CSV_DIGITS
) -> Path:
    """Write a synthetic dataset as long CSV with ``digits`` significant digits per value.

    The values are rounded here (far below the simulated noise) and written by
    :func:`hystdisc.data.write_csv`, which refuses to overwrite without ``force``.
    """
    runs = []
    for r in dataset.runs:
        kw = {
            k: round_significant(getattr(r, k), digits)
            for k in ("torque", "input", "theta_dot")
            if getattr(r, k) is not None
        }
        runs.append(Run(r.name, r.t, round_significant(r.theta, digits), r.current, **kw))
    return write_csv(Dataset(runs, dataset.experiment, dataset.source), path, force=force)
