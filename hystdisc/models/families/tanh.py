"""Kwok et al.'s (2006) hyperbolic-tangent MR-damper model.

A viscous and a spring force and a yield force that follows the velocity through a
hyperbolic tangent, its branch shifted by the sign of the displacement (that shift is the
model's hysteresis)::

    F     = c x' + k x + alpha tanh(beta x' + delta sign(x))
    c     = c_a + c_b i,   alpha = alpha_a + alpha_b i

With ``asymmetric_damping`` (share ``r_c``) and ``asymmetric_yield`` (share ``r_y``),
:attr:`Tanh.scaled_effects`, the two forces differ in tension and compression: ``c x' (1 +
r_c sign(x'))`` and ``alpha h (1 + r_y sign(h))`` with ``h`` the hyperbolic tangent.

For a rotary damper read angles and torques. The model has no internal state: in a
driven experiment it is a map of the imposed motion, in a release or forced rig the
states are the rig's (``k`` is the rig spring ``k_s`` there and is left out). Kwok et
al.'s force offset ``f0`` is left out (data with their mean removed cannot tell it from 0).

Examples
--------
>>> import numpy as np
>>> from hystdisc.simulation import simulate_system
>>> sys = TANH.system("driven")
>>> sys.states, sys.output
((), 'torque')
>>> t = np.linspace(0.0, 1.0, 5)
>>> x, v = 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)
>>> out = simulate_system(sys, t, [], {"k": 1.0}, 0.0, {"theta": x, "theta_dot": v})
>>> ref = 0.8 * v + 1.0 * x + 0.5 * np.tanh(5.0 * v + 0.5 * np.sign(x))
>>> bool(np.allclose(out.y, ref))
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numba
import numpy as np

from hystdisc.models.compiled import N_BASE, term_torque, torque_grad
from hystdisc.models.effects import ASYMMETRIC_DAMPING, ASYMMETRIC_YIELD
from hystdisc.models.families.base import SystemFamily
from hystdisc.models.params import param_table
from hystdisc.models.system import EPS_AT, FAMILY_AT, J_AT, KS_AT

# the family block, after the effects' N_BASE coefficients, eps, k_s and J: c, alpha
# (current folded in), beta, delta, k, and the shares r_c, r_y of the asymmetric damping
# and yield (0 without them)
_C = FAMILY_AT
_AL = _C + 1
_BE = _C + 2
_DE = _C + 3
_K = _C + 4
_RC = _C + 5
_RY = _C + 6
(_R_C,) = ASYMMETRIC_DAMPING.shares
(_R_Y,) = ASYMMETRIC_YIELD.shares


@numba.njit(cache=True, inline="always")
def _force(p, x, v):
    s = 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)
    h = math.tanh(p[_BE] * v + p[_DE] * s)
    out = p[_C] * (v + p[_RC] * abs(v)) + p[_K] * x + p[_AL] * (h + p[_RY] * abs(h))
    return out + term_torque(p[:N_BASE], x, v, 0.0, p[EPS_AT])


@numba.njit(cache=True, nogil=True)
def _driven_rate(x, u, p, dx):
    pass


@numba.njit(cache=True, nogil=True)
def _driven_output(x, u, p):
    return _force(p, u[0], u[1])


@numba.njit(cache=True, nogil=True)
def _mech_rate(x, u, p, dx):
    th, w = x[0], x[1]
    uu = u[0] if u.shape[0] > 0 else 0.0
    dx[0] = w
    dx[1] = (uu - p[KS_AT] * th - _force(p, th, w)) / p[J_AT]


@numba.njit(cache=True, nogil=True)
def _mech_output(x, u, p):
    return x[0]


# ---- partial derivatives of the driven model's torque, for the exact sensitivities
# (hystdisc.simulation.sensitivity_ode); work: 0..9 the effects' dT/dc


@numba.njit(cache=True, nogil=True)
def _driven_rate_jac(x, u, p, need, jx, jp, work):
    pass


@numba.njit(cache=True, nogil=True)
def _driven_output_grad(x, u, p, need, gx, gp, work):
    xx, v = u[0], u[1]
    s = 1.0 if xx > 0.0 else (-1.0 if xx < 0.0 else 0.0)
    th = math.tanh(p[_BE] * v + p[_DE] * s)
    sech2 = 1.0 - th * th
    sh = 1.0 if th > 0.0 else (-1.0 if th < 0.0 else 0.0)
    torque_grad(p[:N_BASE], xx, v, 0.0, p[EPS_AT], need[:N_BASE], work[:N_BASE])
    for i in range(N_BASE):
        gp[i] = work[i]
    gp[_C] = v + p[_RC] * abs(v)
    gp[_K] = xx
    gp[_AL] = th + p[_RY] * abs(th)
    a = p[_AL] * (1.0 + p[_RY] * sh)  # d(alpha h (1 + r_y sign(h))) / dh
    gp[_BE] = a * sech2 * v
    gp[_DE] = a * sech2 * s
    gp[_RC] = p[_C] * abs(v)
    gp[_RY] = p[_AL] * abs(th)


_PARAMS = """
    # name    unit           lower  upper  default  doc
    c_a       N*m*s/rad      0      BIG    0.8      passive viscous damping
    c_b       N*m*s/(rad*A)  0      BIG    0.6      current-dependent viscous damping
    alpha_a   N*m            0      BIG    0.5      passive yield torque
    alpha_b   N*m/A          0      BIG    1.5      current-dependent yield torque
    beta      s/rad          1e-9   BIG    5        inverse of the yield velocity
    delta     -              0      BIG    0.5      branch shift with the sign of x (hysteresis)
    k         N*m/rad        0      BIG    0        spring (driven only)
"""

#: Yield velocities of the starts, as fractions of the median peak velocity of the runs.
START_FRACTIONS = (0.03, 0.1, 0.3)


class Tanh(SystemFamily):
    """Kwok et al. (2006): a hyperbolic-tangent yield force (module docstring)."""

    name = "tanh"
    title = "hyperbolic tangent (Kwok et al.)"
    color = "tab:pink"
    # its yield torque multiplies tanh(...), which saturates at 1 like z
    correspondence = {"theta_dot": "c_a", "z": "alpha_a", "i*z": "alpha_b", "i*theta_dot": "c_b"}

    params = param_table(_PARAMS)
    normalization = "none (tanh saturates at 1)"
    current_params = ("c_b", "alpha_b")
    current_laws = {"c": ("c_a", "c_b"), "alpha": ("alpha_a", "alpha_b")}
    mech_drop = ("k",)
    driven_states: tuple[str, ...] = ()
    mech_states: tuple[str, ...] = ()
    driven_rate = staticmethod(_driven_rate)
    driven_output = staticmethod(_driven_output)
    mech_rate = staticmethod(_mech_rate)
    mech_output = staticmethod(_mech_output)
    driven_rate_jac = staticmethod(_driven_rate_jac)
    driven_output_grad = staticmethod(_driven_output_grad)
    #: A damping and a yield force that differ in tension and compression.
    scaled_effects = (ASYMMETRIC_DAMPING.name, ASYMMETRIC_YIELD.name)
    # none in a release or forced rig: the rate jumps with sign(theta), and the
    # sensitivities would need the jump's saltation at every zero crossing

    def block(self, p: Mapping[str, float], current: float) -> np.ndarray:
        """The family's part of the parameter vector at ``current``, the shares of the
        asymmetric damping and yield last (0 when ``p`` has none)."""
        i = float(current)
        return np.array(
            [
                self.law_value(p, "c", i),
                self.law_value(p, "alpha", i),
                p["beta"],
                p["delta"],
                p.get("k", 0.0),
                p.get(_R_C, 0.0),
                p.get(_R_Y, 0.0),
            ]
        )

    def starts(
        self, base: Mapping[str, float], velocity: float = 1.0, dt: float | None = None
    ) -> list[tuple[str, dict[str, float]]]:
        """Starts from a standard Bouc-Wen fit ``base``: its viscous and hysteretic
        torques, and yield velocities at :data:`START_FRACTIONS` of ``velocity`` (the
        runs' median peak velocity; ``dt`` is not needed: a yield velocity is no
        stiffer than the sampling).

        Examples
        --------
        >>> bw = {"alpha_1": 1.0, "alpha_2": 2.0, "c_1": 0.5, "c_2": 0.5, "k_s": 3.0}
        >>> [(label, round(s["beta"], 3)) for label, s in TANH.starts(bw, velocity=2.0)]
        [('v_yield = 0.03 v_peak', 16.667), ('v_yield = 0.1 v_peak', 5.0), ('v_yield = 0.3 v_peak', 1.667)]
        """
        out = []
        for f in START_FRACTIONS:
            start = {
                "c_a": base["c_1"],
                "c_b": base["c_2"],
                "alpha_a": base["alpha_1"],
                "alpha_b": base["alpha_2"],
                "beta": 1.0 / (f * velocity),
                "delta": 0.5,
                "k": base.get("k_s", 0.0),
            }
            out.append((f"v_yield = {f:g} v_peak", start))
        return out

    def saturation_torque(self, p, which):
        """``tanh`` saturates at 1: ``alpha_a`` (0 A) and ``alpha_b`` (per A)."""
        return p.get("alpha_a") if which == "a" else p.get("alpha_b")

    def equations(self) -> str:
        return (
            "T = c*x_dot + k*x + alpha*tanh(beta*x_dot + delta*sign(x)),  "
            "c = c_a + c_b*i,  alpha = alpha_a + alpha_b*i"
        )


TANH = Tanh()
