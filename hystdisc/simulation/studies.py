"""Parameter studies of the damper models under a driven sine (the seed's figures 4-6, 15-22).

:func:`loop` gives the steady-state torque loop of a model under an imposed sine;
:func:`parameter_study` repeats it while one parameter (or the current) takes several
values; :func:`hystdisc.plotting.plot_study` overlays the loops in a velocity panel and a
displacement panel.

The torque of a study is the **damper** torque: the rig terms (the spring ``k_s theta``, the
``cubic_stiffness`` and ``offset`` effects) are left out, as on a characterization machine.

Examples
--------
>>> from hystdisc.simulation.studies import parameter_study
>>> study = parameter_study("dahl", "rho", [2, 15], frequency=1.0)
>>> [s["label"] for s in study], len(study[0]["t"])
(['rho = 2', 'rho = 15'], 2001)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.models import EFFECTS, RIG_PARAMS, Model, TermModel, get_family
from hystdisc.simulation import simulate_driven

__all__ = ["CURRENT_NAMES", "damper_terms", "loop", "parameter_study"]

#: Names that make :func:`parameter_study` vary the coil current (or voltage).
CURRENT_NAMES = ("current", "i", "v")

_RIG_TERMS = ("theta", "theta^3", "1")


def damper_terms(model: Model | TermModel | str) -> TermModel:
    """The model's term form without the rig terms (spring, cubic stiffness, offset)."""
    if isinstance(model, str):
        model = Model(model)
    tm = model.to_terms() if isinstance(model, Model) else model
    torque = {k: v for k, v in tm.torque.items() if k not in _RIG_TERMS}
    return TermModel(torque, dict(tm.hysteresis), tm.n, tm.J, tm.m, saturation=dict(tm.saturation))


def loop(
    model: Model | TermModel | str,
    current: float = 0.0,
    amplitude: float = 0.3,
    frequency: float = 1.0,
    cycles: int = 3,
    fs: float = 2000.0,
) -> dict[str, Any]:
    """Steady-state damper torque loop under ``theta = amplitude * sin(2 pi frequency t)``.

    The sine starts at ``theta = 0`` with ``z = 0``; after ``cycles - 1`` cycles the
    transient of the virgin loading has died out and the last cycle is returned.

    Parameters
    ----------
    model : Model, TermModel or str
        The model (a family name means its demo defaults).
    current : float
        Coil current in A.
    amplitude, frequency : float
        The imposed sine (rad, Hz).
    cycles : int
        Number of simulated cycles (at least 2).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    dict
        ``t, theta, theta_dot, torque, z`` over the last cycle (``fs / frequency + 1``
        samples, both ends included) and ``current``, ``amplitude``, ``frequency``.

    Examples
    --------
    >>> lp = loop("bouc-wen", current=1.0)
    >>> round(float(lp["torque"].max()), 2)  # (alpha_1 + alpha_2) + (c_1 + c_2) * max|theta_dot|
    4.07
    """
    if not (np.isfinite(amplitude) and amplitude > 0):
        raise HystdiscError(f"amplitude = {amplitude} must be positive; fix: give a value > 0")
    if not (np.isfinite(frequency) and frequency > 0):
        raise HystdiscError(f"frequency = {frequency} must be positive; fix: give a value > 0")
    if not (np.isfinite(fs) and fs > 0):
        raise HystdiscError(f"fs = {fs} must be positive; fix: give a value > 0")
    if int(cycles) < 2:
        raise HystdiscError(f"cycles = {cycles} is below 2; fix: simulate at least 2 cycles")
    if not np.isfinite(current):
        raise HystdiscError(f"current = {current} is not finite; fix: give a number")
    tm = damper_terms(model)
    per = int(round(fs / frequency))
    n = per * int(cycles) + 1
    t = np.arange(n) / fs
    om = 2.0 * np.pi * frequency
    theta = amplitude * np.sin(om * t)
    theta_dot = amplitude * om * np.cos(om * t)
    sim = simulate_driven(tm, t, float(current), theta, theta_dot)
    sl = slice(n - per - 1, n)
    return {
        "t": t[sl] - t[sl][0],
        "theta": theta[sl],
        "theta_dot": theta_dot[sl],
        "torque": sim.torque[sl],
        "z": sim.z[sl],
        "current": float(current),
        "amplitude": float(amplitude),
        "frequency": float(frequency),
    }


def parameter_study(
    family: str,
    param: str,
    values: Sequence[float],
    current: float = 0.0,
    base: Mapping[str, float] | None = None,
    effects: Mapping[str, Mapping[str, float]] | None = None,
    amplitude: float = 0.3,
    frequency: float = 1.0,
    cycles: int = 3,
    fs: float = 2000.0,
) -> list[dict[str, Any]]:
    """Loops of one family while one parameter takes several values.

    Parameters
    ----------
    family : str
        Family name.
    param : str
        A parameter of the family, of one of ``effects``, or ``"current"`` (also ``"i"``,
        ``"v"``) to vary the coil current.
    values : sequence of float
        The values, one loop each.
    current : float
        Coil current of every loop (unless ``param`` is the current).
    base : dict, optional
        The other parameters (unset ones take the demo defaults).
    effects : dict, optional
        Effects to add (name -> parameters).
    amplitude, frequency, cycles, fs
        As in :func:`loop`.

    Returns
    -------
    list of dict
        One :func:`loop` result per value, with ``param``, ``value``, ``label`` and ``model``.
    """
    fam = get_family(family)
    values = [float(v) for v in values]
    if not values:
        raise HystdiscError(f"no values given for {param}; fix: give e.g. {param}=2,15")
    base = dict(base or {})
    effects = {k: dict(v or {}) for k, v in (effects or {}).items()}
    known = set(fam.param_names()) | {p.name for p in RIG_PARAMS}
    where: str
    if param in CURRENT_NAMES:
        where = "current"
    elif param in known:
        where = "params"
    else:
        owners = [e for e in effects if any(p.name == param for p in EFFECTS[e].params)]
        if not owners:
            names = sorted(known | set(CURRENT_NAMES))
            raise HystdiscError(
                f"{fam.name}: unknown parameter '{param}' to vary; fix: use one of "
                f"{', '.join(names)} (or a parameter of an added effect)"
            )
        where = owners[0]
    out = []
    for v in values:
        params, effs, cur = dict(base), {k: dict(e) for k, e in effects.items()}, current
        if where == "current":
            cur = v
        elif where == "params":
            params[param] = v
        else:
            effs[where][param] = v
        model = Model(fam.name, params, effs)
        res = loop(model, cur, amplitude, frequency, cycles, fs)
        res.update({"param": param, "value": v, "label": f"{param} = {v:g}", "model": model})
        out.append(res)
    return out
