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

Scenarios are TOML files with the same settings as ``hystdisc simulate`` (see
:func:`load_scenario`).

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
from hystdisc.data import Dataset, Run, parse_toml, write_csv
from hystdisc.errors import HystdiscError
from hystdisc.models import Model, TermModel
from hystdisc.simulation import simulate_driven_runs, simulate_mech, simulate_system
from hystdisc.simulation.prefilter import apply_prefilter, check_prefilter

__all__ = [
    "DEFAULT_CURRENTS",
    "DEFAULT_INPUT",
    "SCENARIO_KEYS",
    "generate",
    "generate_from_scenario",
    "load_scenario",
    "make_input",
    "normalize_scenario",
    "parse_drive",
    "round_significant",
    "scenario_model",
    "write_dataset",
]

DEFAULT_CURRENTS = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The seed's current steps, in A."""

DEFAULT_INPUT: dict[str, Any] = {"kind": "multisine", "rms": 10.0, "f_min": 0.5, "f_max": 5.0}
"""Input of a ``forced`` experiment when none is given (per unit inertia, N*m)."""

INPUT_KEYS = {
    "multisine": {"kind", "rms", "f_min", "f_max"},
    "sine": {"kind", "amplitude", "frequency"},
}

SCENARIO_KEYS = (
    "model",
    "declared",
    "description",
    "params",
    "effects",
    "currents",
    "experiment",
    "theta0",
    "duration",
    "fs",
    "noise",
    "theta_noise",
    "delay",
    "seed",
    "encoder_counts",
    "spikes",
    "prefilter",
    "drives",
    "input",
    "output",
)
"""Keys a scenario TOML may hold (``declared`` and ``description`` are informative only)."""

MAX_SAMPLES = 10_000_000
"""Most samples :func:`generate` makes in all runs together (80 MB per signal)."""

CSV_DIGITS = 7
"""Significant digits kept when a synthetic dataset is written (:func:`write_dataset`)."""


# ----------------------------------------------------------------------------- checks


def _number(value: Any, name: str, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool):
        raise HystdiscError(f"{name} = {value!r} is not a number; fix: give a number")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise HystdiscError(f"{name} = {value!r} is not a number; fix: give a number") from None
    if not math.isfinite(v):
        raise HystdiscError(f"{name} = {v} is not finite; fix: give a finite number")
    if positive and v <= 0:
        raise HystdiscError(f"{name} = {v:g} must be positive; fix: give a value > 0")
    if nonneg and v < 0:
        raise HystdiscError(f"{name} = {v:g} is negative; fix: give a value >= 0")
    return v


def _check_currents(currents: Any) -> list[float]:
    if isinstance(currents, (int, float)) and not isinstance(currents, bool):
        currents = [currents]
    try:
        items = list(currents)
    except TypeError:
        raise HystdiscError(
            f"currents = {currents!r} is not a list; fix: give e.g. 0,0.25,0.5,0.75,1"
        ) from None
    if not items:
        raise HystdiscError("no currents given; fix: give at least one coil current, e.g. 0,0.5,1")
    out = []
    for c in items:
        v = _number(c, "current")
        if v < 0:
            raise HystdiscError(
                f"current {v:g} A is negative; fix: give the coil current magnitude (>= 0 A)"
            )
        out.append(v)
    return out


def parse_drive(spec: Any) -> dict[str, float]:
    """Check one sine drive: ``{"amplitude": A, "frequency": f}`` or the text ``"A@f"``.

    Examples
    --------
    >>> parse_drive("0.3@1.0")
    {'amplitude': 0.3, 'frequency': 1.0}
    >>> parse_drive({"amplitude": 0.1, "frequency": 3})
    {'amplitude': 0.1, 'frequency': 3.0}
    """
    if isinstance(spec, str):
        parts = spec.split("@")
        if len(parts) != 2:
            raise HystdiscError(
                f"drive {spec!r} is not AMPLITUDE@FREQUENCY; fix: write e.g. --drive 0.3@1.0 "
                "(0.3 rad at 1 Hz)"
            )
        spec = {"amplitude": parts[0].strip(), "frequency": parts[1].strip()}
    if not isinstance(spec, Mapping):
        raise HystdiscError(
            f"drive {spec!r} is not a table; fix: write {{amplitude = 0.3, frequency = 1.0}}"
        )
    unknown = sorted(set(spec) - {"amplitude", "frequency"})
    if unknown:
        raise HystdiscError(
            f"unknown drive setting '{unknown[0]}'; fix: use only amplitude and frequency"
        )
    if "amplitude" not in spec or "frequency" not in spec:
        raise HystdiscError(
            f"drive {dict(spec)!r} lacks amplitude or frequency; fix: give both, e.g. 0.3@1.0"
        )
    return {
        "amplitude": _number(spec["amplitude"], "drive amplitude", positive=True),
        "frequency": _number(spec["frequency"], "drive frequency", positive=True),
    }


def _check_input_spec(spec: Mapping[str, Any] | None) -> dict[str, Any]:
    if spec is None:
        return dict(DEFAULT_INPUT)
    if not isinstance(spec, Mapping):
        raise HystdiscError(
            f"input {spec!r} is not a table; fix: give e.g. "
            '{kind = "multisine", rms = 10, f_min = 0.5, f_max = 5}'
        )
    kind = str(spec.get("kind", "multisine")).strip().lower()
    if kind not in INPUT_KEYS:
        raise HystdiscError(f"unknown input kind {kind!r}; fix: use one of {', '.join(INPUT_KEYS)}")
    unknown = sorted(set(spec) - INPUT_KEYS[kind])
    if unknown:
        raise HystdiscError(
            f"unknown {kind} input setting '{unknown[0]}'; fix: use only "
            f"{', '.join(sorted(INPUT_KEYS[kind] - {'kind'}))}"
        )
    out: dict[str, Any] = {"kind": kind}
    if kind == "multisine":
        out["rms"] = _number(spec.get("rms", DEFAULT_INPUT["rms"]), "input rms", nonneg=True)
        out["f_min"] = _number(
            spec.get("f_min", DEFAULT_INPUT["f_min"]), "input f_min", nonneg=True
        )
        out["f_max"] = _number(
            spec.get("f_max", DEFAULT_INPUT["f_max"]), "input f_max", positive=True
        )
        if out["f_max"] < out["f_min"]:
            raise HystdiscError(
                f"input f_max = {out['f_max']:g} Hz is below f_min = {out['f_min']:g} Hz; "
                "fix: give f_min <= f_max"
            )
    else:
        if "amplitude" not in spec or "frequency" not in spec:
            raise HystdiscError(
                "a sine input needs amplitude and frequency; fix: give both, e.g. "
                '{kind = "sine", amplitude = 10, frequency = 1.5}'
            )
        out["amplitude"] = _number(spec["amplitude"], "input amplitude", nonneg=True)
        out["frequency"] = _number(spec["frequency"], "input frequency", positive=True)
    return out


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
    s = _check_input_spec(spec)
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
        :data:`DEFAULT_INPUT`) or ``{"kind": "sine", "amplitude", "frequency"}``; every run
        gets its own random phases.
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
    cur = _check_currents(currents)
    duration = _number(duration, "duration", positive=True)
    fs = _number(fs, "fs", positive=True)
    noise = _number(noise, "noise", nonneg=True)
    theta_noise = _number(theta_noise, "theta_noise", nonneg=True)
    delay = _number(delay, "delay")
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
    n_spikes, spike_size = _check_spikes(spikes, n * len(cur) * max(per_current, 1))
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
        th0 = [_number(theta0, "theta0")] * len(cur)
    else:
        th0 = [_number(v, "theta0") for v in theta0]
        if len(th0) != len(cur):
            raise HystdiscError(
                f"{len(th0)} theta0 values for {len(cur)} currents; fix: give one theta0, or "
                "one per current"
            )
    inputs = None
    if kind.has_input:
        spec = _check_input_spec(input_spec)
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


def _check_spikes(spikes: Any, total: int) -> tuple[int, float]:
    """``(N, SIZE)`` checked (N whole and at most the samples, SIZE > 0); (0, 0) for None."""
    if spikes is None:
        return 0, 0.0
    try:
        count, size = spikes
    except (TypeError, ValueError):
        raise HystdiscError(
            f"spikes = {spikes!r} is not (N, SIZE); fix: give e.g. (6, 0.05)"
        ) from None
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise HystdiscError(f"spikes: N = {count!r} is invalid; fix: give a whole number >= 0")
    if count > total:
        raise HystdiscError(f"spikes: N = {count} exceeds the {total} samples; fix: give fewer")
    return int(count), _number(size, "spike size", positive=True)


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


# ----------------------------------------------------------------------------- scenarios


def _scenario_error(source: str, problem: str, fix: str) -> HystdiscError:
    return HystdiscError(f"{source}: {problem}; fix: {fix}")


def _effect_params(name: str, ep: Any, source: str) -> dict[str, float]:
    """One ``[effects.<name>]`` table of a scenario, its values as numbers."""
    if not isinstance(ep, Mapping):
        raise _scenario_error(
            source,
            f"effects.{name} must be a table",
            f"write [effects.{name}] and its parameters below it",
        )
    return {str(k): _number(v, f"effect {name} parameter {k}") for k, v in ep.items()}


def load_scenario(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a scenario TOML file (the settings of ``hystdisc simulate``).

    Keys: ``model`` (family), ``[params]``, ``[effects.<name>]`` tables (an empty table
    takes the effect's defaults), ``currents``, ``experiment``, ``theta0``, ``duration``,
    ``fs``, ``noise``, ``theta_noise``, ``delay`` (s), ``seed``, ``encoder_counts``,
    ``spikes`` (``[N, SIZE]``), ``[prefilter]`` (a rig's ``[filter]`` table), ``drives`` (tables
    ``{amplitude, frequency}`` or ``"A@f"`` strings), ``[input]``, ``output`` (CSV file
    name, relative to the scenario file) and the informative ``declared`` (the family a
    user would declare for these data) and ``description``. Unknown keys are an error.

    Returns
    -------
    dict
        The settings, plus ``path`` (the scenario file) and ``output`` resolved against the
        scenario's folder. Settings not given are absent (the :func:`generate` defaults
        apply).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d, "s.toml")
    ...     _ = p.write_text('model = "dahl"\\noutput = "dahl.csv"\\n[params]\\nrho = 15\\n')
    ...     sc = load_scenario(p)
    ...     print(sc["model"], sc["params"], pathlib.Path(sc["output"]).name)
    dahl {'rho': 15.0} dahl.csv
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise _scenario_error(source, "file does not exist", "check the path") from None
    except UnicodeDecodeError as exc:
        raise _scenario_error(
            source,
            f"is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})",
            "save the scenario as UTF-8 text (TOML)",
        ) from None
    except OSError as exc:
        raise _scenario_error(
            source, f"cannot be read ({exc.strerror or exc})", "check the path"
        ) from None
    sc = normalize_scenario(parse_toml(text, source), source)
    sc["path"] = source
    if "output" in sc:
        sc["output"] = str(Path(path).parent / sc["output"])
    return sc


def normalize_scenario(raw: Mapping[str, Any], source: str = "scenario") -> dict[str, Any]:
    """Check the keys and value types of a scenario table (see :func:`load_scenario`)."""
    for key in raw:
        if key not in SCENARIO_KEYS:
            raise _scenario_error(
                source, f"unknown key '{key}'", f"use only {', '.join(SCENARIO_KEYS)}"
            )
    sc: dict[str, Any] = {}
    for key in ("model", "declared", "description", "experiment", "output"):
        if key in raw:
            if not isinstance(raw[key], str):
                raise _scenario_error(source, f"{key} = {raw[key]!r} is not text", "quote it")
            sc[key] = raw[key]
    if "output" in sc and (not sc["output"].strip() or "\x00" in sc["output"]):
        raise _scenario_error(
            source,
            f"output = {sc['output']!r} is not a usable file name",
            'name the CSV file, e.g. output = "dahl.csv"',
        )
    params = raw.get("params", {})
    if not isinstance(params, Mapping):
        raise _scenario_error(source, "params must be a table", "write [params] then k_s = 158")
    try:
        sc["params"] = {str(k): _number(v, f"parameter {k}") for k, v in params.items()}
        effects = raw.get("effects", {})
        if isinstance(effects, list):  # effects = ["coulomb", ...] takes the defaults
            effects = {str(e): {} for e in effects}
        if not isinstance(effects, Mapping):
            raise _scenario_error(
                source, "effects must be a table", "write [effects.coulomb] then f_c = 0.3"
            )
        sc["effects"] = {
            str(name): _effect_params(name, ep, source) for name, ep in effects.items()
        }
        if "currents" in raw:
            sc["currents"] = _check_currents(raw["currents"])
        for key in ("duration", "fs", "noise", "theta_noise", "delay"):
            if key in raw:
                sc[key] = _number(raw[key], key)
        if "theta0" in raw:
            v = raw["theta0"]
            sc["theta0"] = (
                [_number(x, "theta0") for x in v] if isinstance(v, list) else _number(v, "theta0")
            )
        if "spikes" in raw:
            v = raw["spikes"]
            if not (isinstance(v, list) and len(v) == 2):
                raise _scenario_error(
                    source, f"spikes = {v!r} is not [N, SIZE]", "write spikes = [6, 0.05]"
                )
            sc["spikes"] = (v[0], _number(v[1], "spike size", positive=True))
        for key in ("seed", "encoder_counts"):
            if key in raw:
                v = raw[key]
                if isinstance(v, bool) or not isinstance(v, int):
                    raise _scenario_error(
                        source, f"{key} = {v!r} is not a whole number", "give an integer"
                    )
                sc[key] = v
        if "prefilter" in raw:  # checked by generate (simulation.prefilter)
            sc["prefilter"] = raw["prefilter"]
        if "drives" in raw:
            if not isinstance(raw["drives"], list):
                raise _scenario_error(
                    source,
                    "drives must be a list",
                    'write drives = [{amplitude = 0.3, frequency = 1.0}] or ["0.3@1.0"]',
                )
            sc["drives"] = [parse_drive(d) for d in raw["drives"]]
        if "input" in raw:
            sc["input"] = _check_input_spec(raw["input"])
    except HystdiscError as exc:
        msg = str(exc)
        raise HystdiscError(msg if msg.startswith(source) else f"{source}: {msg}") from None
    return sc


def scenario_model(scenario: Mapping[str, Any]) -> Model:
    """The :class:`~hystdisc.models.Model` a scenario describes (demo defaults if unset)."""
    if "model" not in scenario:
        raise HystdiscError(
            f'{scenario.get("path", "scenario")}: no model given; fix: add model = "bouc-wen" '
            "(or pass --model)"
        )
    return Model(scenario["model"], scenario.get("params") or {}, scenario.get("effects") or {})


def generate_from_scenario(scenario: Mapping[str, Any]) -> Dataset:
    """Generate the dataset a scenario (from :func:`load_scenario`) describes.

    Examples
    --------
    >>> ds = generate_from_scenario({"model": "lugre", "currents": [0, 1], "duration": 1.0})
    >>> len(ds), ds[0].n
    (2, 1000)
    """
    model = scenario_model(scenario)
    kw: dict[str, Any] = {}
    for key in (
        "experiment",
        "currents",
        "duration",
        "fs",
        "theta0",
        "noise",
        "seed",
        "encoder_counts",
        "drives",
        "theta_noise",
        "delay",
        "spikes",
        "prefilter",
    ):
        if scenario.get(key) is not None:
            kw[key] = scenario[key]
    if scenario.get("input") is not None:
        kw["input_spec"] = scenario["input"]
    try:
        return generate(model, **kw)
    except HystdiscError as exc:
        where = scenario.get("path")
        msg = str(exc)
        raise HystdiscError(
            f"{where}: {msg}" if where and not msg.startswith(where) else msg
        ) from None
