"""Backlash: a play (dead zone) between the measured motion and the damper.

A driven test measures the actuator's motion ``x``; the damper sees it through a linkage,
an eye bushing or a loose pin with a gap of ``2 r_b``. The damper's end ``y`` stays put
while the actuator crosses the gap after each reversal and follows it, ``r_b`` behind,
once the gap is closed: the play operator (Krasnosel'skii and Pokrovskii)::

    y(t) = min(max(y(t-), x(t) - r_b), x(t) + r_b)

so the force reverses late, by the time the actuator needs to cross ``2 r_b`` (a
constant *distance*, not a constant time as a channel delay is: at a low velocity the
lag is long, at a high one short). The damper's velocity is the actuator's while the gap
is closed and 0 while it is open. The model in term form is driven by ``y`` and its
velocity instead of the measured motion (:meth:`~hystdisc.models.effects.Effect.apply`
writes ``r_b`` into the term model's ``play``; a state-space model reads it from its
values: :meth:`~hystdisc.models.system.StateSpaceModel.input_play`).

Examples
--------
>>> x = np.array([0.0, 1.0, 2.0, 1.5, 0.5, -1.0])
>>> play(x, 0.5).tolist()
[0.0, 0.5, 1.5, 1.5, 1.0, -0.5]
>>> th, w = play_motion(x, np.array([1.0, 1.0, 1.0, -1.0, -1.0, -1.0]), 0.5)
>>> th.tolist(), w.tolist()
([-0.5, 0.5, 1.5, 1.5, 1.0, -0.5], [1.0, 1.0, 1.0, 0.0, -0.5, -1.0])
"""

from __future__ import annotations

import numpy as np
from numba import njit

from hystdisc.models.effects import Effect
from hystdisc.models.params import BIG, Param


@njit(cache=True)
def play(x, r):  # pragma: no cover - compiled
    """The play (backlash) operator: ``y`` follows ``x`` only once ``|x - y| > r``,
    starting centred (``y[0] = x[0]``)."""
    y = np.empty_like(x)
    if x.size == 0:
        return y
    y[0] = x[0]
    for k in range(1, x.size):
        y[k] = min(max(y[k - 1], x[k] - r), x[k] + r)
    return y


@njit(cache=True)
def _play_with_velocity(x, v, r):  # pragma: no cover - compiled
    """:func:`play` of ``x`` and the velocity of its output: ``v`` times the share of the
    sample interval's motion the output followed (1 with the gap closed and pushing, 0
    with it open, between the two in the interval where the gap closes), so that the
    velocity moves continuously with ``r`` as the engagement moves within a sample."""
    y = np.empty_like(x)
    w = np.zeros_like(v)
    if x.size == 0:
        return y, w
    # the gap starts closed in the direction the motion starts in (centred at rest): the
    # play of a vanishing width is then the motion itself, at every sample
    if v[0] > 0.0:
        y[0], w[0] = x[0] - r, v[0]
    elif v[0] < 0.0:
        y[0], w[0] = x[0] + r, v[0]
    else:
        y[0] = x[0]
    for k in range(1, x.size):
        y[k] = min(max(y[k - 1], x[k] - r), x[k] + r)
        dx = x[k] - x[k - 1]
        if dx != 0.0:
            w[k] = v[k] * min(max((y[k] - y[k - 1]) / dx, 0.0), 1.0)
    return y, w


def play_motion(
    theta: np.ndarray, theta_dot: np.ndarray, r_b: float
) -> tuple[np.ndarray, np.ndarray]:
    """The motion and velocity of the damper's end behind a play of half-width ``r_b``
    (the measured motion's unit) driven by ``theta``: :func:`play` of the motion, and the
    velocity where the gap is closed and pushing, 0 where it is open (in the sample
    interval where the gap closes, the share of the motion the damper followed).
    ``r_b = 0``: the measured motion itself."""
    if r_b == 0.0:
        return theta, theta_dot
    x = np.ascontiguousarray(theta, dtype=np.float64)
    v = np.ascontiguousarray(theta_dot, dtype=np.float64)
    return _play_with_velocity(x, v, float(r_b))


BACKLASH = Effect(
    "backlash",
    (
        Param(
            "r_b",
            "rad",
            0.0,
            BIG,
            0.002,
            "half-width of the play between the measured motion and the damper (the "
            "motion's unit: rad, or m on a linear rig)",
        ),
    ),
    (),
    "a play (backlash, dead zone) of 2 r_b between the measured motion and the damper: "
    "the damper's end follows the actuator only once the gap is crossed, so the force "
    "reverses late by a distance, not a time",
    lambda p, ks: {},
    lambda c, ks: {"r_b": 0.0},
    "",
    experiments=("driven",),
    rig=True,
    roles=("measurement",),
    play_param="r_b",
)
"""The play effect (driven experiments: on a released beam the damper's end is the beam,
and a gap there is a structural state of its own). It belongs to the rig, so every family
carries it alike (``rig``), and it moves the motion every model is driven by, as a channel
delay does (``play_param``): its Jacobian column is a difference of simulations."""
