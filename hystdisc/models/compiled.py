"""The term form, compiled: torque and hysteretic rate of a term model as numba functions.

These are the rate and output equations of every model written in the term form (the
seed's families, a family plus effects, a discovered structure). The simulator's batch
kernels, stage 1's z integration, the output-error fit and every state-space system built
on the term form (:mod:`hystdisc.models.system`) call these same functions.

A run's coefficients are packed once per run with the current folded in
(:func:`base_coefficients`, layout :data:`N_BASE`) and the hysteresis side in
``TermModel.hysteresis_vector()`` order.

Examples
--------
>>> import numpy as np
>>> from hystdisc.models import Model
>>> tm = Model("dahl").to_terms()
>>> c = base_coefficients(tm, current=0.5)
>>> round(float(term_torque(c, 0.1, 2.0, 0.5, 1e-3)), 6)  # k_s*0.1 + k_x*2 + (k_wa + k_wb*0.5)*0.5
18.025
>>> float(term_rate(tm.hysteresis_vector(), tm.n, 2.0, 0.5))  # rho*(w - |w| z)
20.0
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hystdisc.models.terms import SHEAR_TERM, TermModel

# per-run base coefficients, after folding in the current
#   0 theta, 1 theta_dot, 2 z, 3 |theta_dot| z, 4 sign(theta_dot), 5 theta_dot|theta_dot|,
#   6 theta^3, 7 constant (its current law: the term i), 8 sign(theta_dot)|theta_dot|^m
#   (shear thinning), 9 its exponent m, 10 |theta_dot| (asymmetric damping), 11 |z|
#   (asymmetric yield)
# A change of this layout must change every module whose compiled functions use it too
# (models/system.py, wheel.py, families/spencer.py, families/tanh.py, simulation/kernels.py,
# sensitivity.py): numba keeps a function's cache by its own file's stamp, and a cache made
# before the change would be reused with the old layout (or delete the __pycache__/*.nb?)
N_BASE = 12


def base_coefficients(tm: TermModel, current: float) -> np.ndarray:
    """Fold the current into the torque coefficients of a run (see ``N_BASE`` layout).

    A group's ``i*`` term sees the current of its law (``i``, or ``i0 tanh(i / i0)`` for a
    saturating law, :meth:`~hystdisc.models.TermModel.current`); its ``i^2`` term is a
    quadratic law's.

    Examples
    --------
    >>> tm = TermModel({"z": 0.5, "i*z": 3.0}, saturation={"z": 0.3})
    >>> round(float(base_coefficients(tm, 2.0)[2]), 4)  # 0.5 + 3 * 0.3 tanh(2 / 0.3)
    1.4
    """
    g = tm.torque.get
    i = float(current)

    def law(group: str) -> float:
        return (
            g(group, 0.0)
            + tm.current(group, i) * g(f"i*{group}", 0.0)
            + i * i * g(f"i^2*{group}", 0.0)
        )

    c = np.zeros(N_BASE)
    c[0] = g("theta", 0.0)
    c[1] = law("theta_dot")
    c[2] = law("z")
    c[3] = g("|theta_dot|*z", 0.0)
    c[4] = law("sign(theta_dot)")
    c[5] = g("theta_dot*|theta_dot|", 0.0)
    c[6] = g("theta^3", 0.0)
    c[7] = g("1", 0.0) + i * g("i", 0.0)
    c[8] = g(SHEAR_TERM, 0.0)
    c[9] = tm.m
    c[10] = law("|theta_dot|")
    c[11] = law("|z|")
    return c


#: Length of :func:`term_vector`: the base coefficients, the 5 hysteresis coefficients and
#: ``n``. A compiled model's parameter vector starts with it; what the model adds follows.
TERM_SIZE = N_BASE + 6


def term_vector(tm: TermModel, current: float) -> np.ndarray:
    """The base coefficients of a run (current folded in), the hysteresis coefficients
    and the exponent ``n``: the start of a compiled model's parameter vector."""
    return np.concatenate([base_coefficients(tm, current), tm.hysteresis_vector(), [tm.n]])


@numba.njit(cache=True, inline="always")
def vector_rate(p, w, z):
    """:func:`term_rate` with the hysteresis coefficients and ``n`` of a :func:`term_vector`."""
    return term_rate(p[N_BASE : TERM_SIZE - 1], p[TERM_SIZE - 1], w, z)


@numba.njit(cache=True, inline="always")
def term_torque(c, th, w, z, eps):
    aw = abs(w)
    out = c[0] * th + c[1] * w + c[2] * z + c[3] * aw * z + c[5] * w * aw + c[7] + c[10] * aw
    out += c[11] * abs(z)
    if c[4] != 0.0:  # tanh and the cube are the costly terms: skip them when absent
        out += c[4] * math.tanh(w / eps)
    if c[6] != 0.0:
        out += c[6] * th * th * th
    if c[8] != 0.0:  # shear thinning: the smoothed sign(w)|w|^m of terms.smooth_power
        out += c[8] * w * (w * w + eps * eps) ** (0.5 * (c[9] - 1.0))
    return out


@numba.njit(cache=True, inline="always")
def term_rate(b, n, w, z):
    aw = abs(w)
    r = b[0] * w + b[1] * aw * z
    if b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0:
        az = abs(z)
        if n == 1.0:
            p = az
        elif n == 2.0:
            p = az * az
        else:
            p = az**n if az > 0.0 else 0.0
        r += b[2] * w * p + b[3] * aw * z * p
        if b[4] != 0.0:
            if z > 0.0:
                r += b[4] * aw * p
            elif z < 0.0:
                r -= b[4] * aw * p
    return r


@numba.njit(cache=True)
def rate_stiffness(b, n, w, z):
    """``|d(dz/dt)/dz|`` and ``|d(dz/dt)/dw|`` (for the sub-step choice)."""
    aw = abs(w)
    az = abs(z)
    dz = abs(b[1]) * aw
    dw = abs(b[0]) + abs(b[1]) * az
    if b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0:
        azf = max(az, 1e-3)  # |z|^n is not Lipschitz at 0; do not chase it
        pm1 = 1.0 if n == 1.0 else azf ** (n - 1.0)
        p = pm1 * azf
        dz += aw * (n * abs(b[2]) * pm1 + (n + 1.0) * abs(b[3]) * p + n * abs(b[4]) * pm1)
        dw += abs(b[2]) * p + abs(b[3]) * az * p + abs(b[4]) * p
    return dz, dw


# ----------------------------------------------------------------------------- derivatives
# Partial derivatives of term_torque and term_rate, for the forward sensitivities of the
# simulation kernels (hystdisc.simulation.sensitivity). Every partial with respect to a
# coefficient is written to ``g``; ``need`` flags the ones wanted even where the term is
# absent (a zero coefficient whose costly function is otherwise skipped).
# Where a function has a kink (|w| at w = 0, |z|^n at z = 0) the one-sided slopes are
# averaged (sign(0) = 0): the kernels evaluate there on a set of measure zero.


@numba.njit(cache=True, inline="always")
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@numba.njit(cache=True)
def torque_grad(c, th, w, z, eps, need, g):
    """Partials of :func:`term_torque`: returns ``(dT/dtheta, dT/dtheta_dot, dT/dz)`` and
    writes ``dT/dc[i]`` to ``g[i]`` (``need``: :data:`N_BASE` flags)."""
    aw = abs(w)
    sw = _sign(w)
    dth = c[0]
    dw = c[1] + c[3] * sw * z + 2.0 * c[5] * aw + c[10] * sw
    dz = c[2] + c[3] * aw + c[11] * _sign(z)
    g[4] = 0.0
    if c[4] != 0.0 or need[4]:
        tnh = math.tanh(w / eps)
        dw += c[4] * (1.0 - tnh * tnh) / eps
        g[4] = tnh
    if c[6] != 0.0:
        dth += 3.0 * c[6] * th * th
    if c[8] != 0.0 or need[8]:
        q = w * w + eps * eps
        a = 0.5 * (c[9] - 1.0)
        qa = q**a
        dw += c[8] * qa * (1.0 + 2.0 * a * w * w / q)
        g[8] = w * qa
        g[9] = c[8] * w * qa * 0.5 * math.log(q)
    else:
        g[8] = 0.0
        g[9] = 0.0
    g[0] = th
    g[1] = w
    g[2] = z
    g[3] = aw * z
    g[5] = w * aw
    g[6] = th * th * th
    g[7] = 1.0
    g[10] = aw
    g[11] = abs(z)
    return dth, dw, dz


@numba.njit(cache=True)
def rate_grad(b, n, w, z, need, g):
    """Partials of :func:`term_rate`: returns ``(dR/dtheta_dot, dR/dz)`` and writes
    ``dR/db[0..4]`` to ``g[0..4]``, ``dR/dn`` to ``g[5]`` (``need``: 6 flags, same order)."""
    aw = abs(w)
    sw = _sign(w)
    dw = b[0] + b[1] * sw * z
    dz = b[1] * aw
    g[0] = w
    g[1] = aw * z
    if b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0 or need[2] or need[3] or need[4] or need[5]:
        az = abs(z)
        sz = _sign(z)
        p = 0.0
        pm1 = 0.0  # |z|^(n-1); its value at 0 is the slope's mean there (a kink for n = 1)
        lz = 0.0
        if az > 0.0:
            if n == 1.0:
                p = az
                pm1 = 1.0
            elif n == 2.0:
                p = az * az
                pm1 = az
            else:
                p = az**n
                pm1 = p / az
            if need[5]:
                lz = math.log(az)
        dw += b[2] * p + b[3] * sw * z * p + b[4] * sw * sz * p
        dz += b[2] * w * n * pm1 * sz + b[3] * aw * (1.0 + n) * p + b[4] * aw * n * pm1
        g[2] = w * p
        g[3] = aw * z * p
        g[4] = aw * sz * p
        g[5] = (b[2] * w + b[3] * aw * z + b[4] * aw * sz) * p * lz
    else:
        g[2] = 0.0
        g[3] = 0.0
        g[4] = 0.0
        g[5] = 0.0
    return dw, dz
