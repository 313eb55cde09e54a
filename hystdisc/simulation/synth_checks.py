"""The settings of a synthetic dataset checked: numbers, currents, drives, inputs, glitches.

Each check returns the setting in the form :func:`~hystdisc.simulation.synth.generate`
uses, or raises a one-line :class:`~hystdisc.errors.HystdiscError` that says the fix; a
scenario's values (:mod:`hystdisc.simulation.scenarios`) pass the same checks.

Examples
--------
>>> check_currents([0, 0.5, 1])
[0.0, 0.5, 1.0]
>>> check_number("-2", "noise", nonneg=True)
Traceback (most recent call last):
...
hystdisc.errors.HystdiscError: noise = -2 is negative; fix: give a value >= 0
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from hystdisc.errors import HystdiscError

__all__ = [
    "DEFAULT_INPUT",
    "check_currents",
    "check_input_spec",
    "check_number",
    "check_spikes",
    "parse_drive",
]

DEFAULT_INPUT: dict[str, Any] = {"kind": "multisine", "rms": 10.0, "f_min": 0.5, "f_max": 5.0}
"""Input of a ``forced`` experiment when none is given (per unit inertia, N*m)."""

INPUT_KEYS = {
    "multisine": {"kind", "rms", "f_min", "f_max"},
    "sine": {"kind", "amplitude", "frequency"},
}
"""The settings of each kind of input (``kind`` included)."""


def check_number(value: Any, name: str, *, positive: bool = False, nonneg: bool = False) -> float:
    """One numeric setting as a finite float.

    Parameters
    ----------
    value : Any
        The setting as given (a number or its text; a bool is refused).
    name : str
        Its name in the error message.
    positive : bool
        Require ``value > 0``.
    nonneg : bool
        Require ``value >= 0``.

    Returns
    -------
    float
        The value.

    Raises
    ------
    HystdiscError
        When the value is not a finite number, or breaks ``positive`` or ``nonneg``.

    Examples
    --------
    >>> check_number("0.5", "duration", positive=True)
    0.5
    """
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


def check_currents(currents: Any) -> list[float]:
    """The coil currents of a dataset, one run each.

    Parameters
    ----------
    currents : float or sequence of float
        One current or several, in A.

    Returns
    -------
    list of float
        The currents, at least one, each finite and >= 0.

    Raises
    ------
    HystdiscError
        When none is given, or one is not a number or is negative.

    Examples
    --------
    >>> check_currents(0.25)
    [0.25]
    """
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
        v = check_number(c, "current")
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
        "amplitude": check_number(spec["amplitude"], "drive amplitude", positive=True),
        "frequency": check_number(spec["frequency"], "drive frequency", positive=True),
    }


def check_input_spec(spec: Mapping[str, Any] | None) -> dict[str, Any]:
    """The input of a forced experiment, its missing settings filled in.

    Parameters
    ----------
    spec : Mapping or None
        ``{"kind": "multisine", "rms", "f_min", "f_max"}`` (settings not given take those
        of :data:`DEFAULT_INPUT`) or ``{"kind": "sine", "amplitude", "frequency"}``; None
        means :data:`DEFAULT_INPUT`.

    Returns
    -------
    dict
        The input's settings, every one given, as numbers (``kind`` lower-case).

    Raises
    ------
    HystdiscError
        For an unknown kind or setting, a bad value, or ``f_max < f_min``.

    Examples
    --------
    >>> check_input_spec({"kind": "Sine", "amplitude": 2, "frequency": 1})
    {'kind': 'sine', 'amplitude': 2.0, 'frequency': 1.0}
    """
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
        out["rms"] = check_number(spec.get("rms", DEFAULT_INPUT["rms"]), "input rms", nonneg=True)
        out["f_min"] = check_number(
            spec.get("f_min", DEFAULT_INPUT["f_min"]), "input f_min", nonneg=True
        )
        out["f_max"] = check_number(
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
        out["amplitude"] = check_number(spec["amplitude"], "input amplitude", nonneg=True)
        out["frequency"] = check_number(spec["frequency"], "input frequency", positive=True)
    return out


def check_spikes(spikes: Any, total: int) -> tuple[int, float]:
    """The glitches ``(N, SIZE)`` of a dataset checked.

    Parameters
    ----------
    spikes : (int, float) or None
        ``N`` glitches of ``+-SIZE``; None for none.
    total : int
        Samples of the measured signal in all runs.

    Returns
    -------
    (int, float)
        ``(N, SIZE)``, N whole and at most ``total``, SIZE > 0; ``(0, 0.0)`` for None.

    Raises
    ------
    HystdiscError
        When ``spikes`` is not a pair, ``N`` is not a whole number in ``[0, total]`` or
        ``SIZE`` is not positive.

    Examples
    --------
    >>> check_spikes((3, 0.05), 1000)
    (3, 0.05)
    """
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
    return int(count), check_number(size, "spike size", positive=True)
