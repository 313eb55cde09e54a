"""Spencer et al.'s (1997) phenomenological MR-damper model: Bouc-Wen with an internal dashpot.

The damper's two ends are the measured motion ``x`` and an internal node ``y``; a
Bouc-Wen element, a dashpot ``c0`` and a spring ``k0`` act between them, a dashpot ``c1``
ties the node to the other end, and ``k1`` is the accumulator's spring::

    F      = c1 y' + k1 x
    y'     = (alpha z + c0 x' + k0 (x - y)) / (c0 + c1)
    z'     = A (x' - y') - beta (x' - y') |z|^n - gamma |x' - y'| z |z|^(n-1)
    alpha  = alpha_a + alpha_b i,   c0 = c0_a + c0_b i,   c1 = c1_a + c1_b i

(each a linear current law; a saturating or quadratic one when the model carries its
coefficient, ``alpha_i0`` or ``alpha_i2``, ...: :meth:`~hystdisc.models.Family.law_value`).

With ``asymmetric_yield`` (its share ``r_y``, :attr:`Spencer.scaled_effects`) the
Bouc-Wen element's force is ``alpha z (1 + r_y sign(z))``: a yield force of ``(1 + r_y)
alpha`` in tension and ``(1 - r_y) alpha`` in compression where ``z`` saturates.

For a rotary damper read angles and torques. The states are the stretch ``d = x - y`` of
the Bouc-Wen element and ``z`` (both start at 0: the node starts with the motion).

Identifiability. ``z`` is normalized to saturate at 1 (``A = beta + gamma``, as the
standard Bouc-Wen family): Spencer's ``A`` and the scale of ``alpha`` are one direction.
The free shape parameters are ``A > 0`` and ``beta`` (``gamma = A - beta`` is reported):
``A > 0`` keeps ``z`` bounded, which free ``beta`` and ``gamma`` would not.
Spencer's ``x0`` only adds the constant force ``-k1 x0``, which data with their mean
removed cannot tell from zero: it is left out. With ``c1`` much larger than ``c0`` the
model is standard Bouc-Wen (``y`` stands still): then ``c1`` is not determined and
the data identify the combinations :meth:`Spencer.derived` reports, the post-yield
damping ``c0 c1 / (c0 + c1)`` and the yield force ``alpha c1 / (c0 + c1)`` at 0 A and at
1 A. In a release or forced rig ``k1`` is the rig spring ``k_s`` and is left out.

Examples
--------
>>> import numpy as np
>>> from hystdisc.simulation import simulate_system
>>> sys = SPENCER.system("driven")
>>> sys.states, sys.inputs, sys.output
(('d', 'z'), ('theta', 'theta_dot'), 'torque')
>>> t = np.linspace(0.0, 2.0, 2001)
>>> x, v = 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)
>>> out = simulate_system(sys, t, sys.initial_state(), current=1.0,
...                       inputs={"theta": x, "theta_dot": v})
>>> bool(np.all(np.isfinite(out.y))), round(float(np.max(out.y)), 2)
(True, 3.52)
"""

from __future__ import annotations

from collections.abc import Mapping

import numba
import numpy as np

from hystdisc.models.compiled import N_BASE, rate_grad, term_rate, term_torque, torque_grad
from hystdisc.models.effects import ASYMMETRIC_YIELD
from hystdisc.models.families.base import SystemFamily
from hystdisc.models.params import param_table
from hystdisc.models.system import EPS_AT, FAMILY_AT, J_AT, KS_AT

# the family block: the 5 hysteresis coefficients of term_rate (A, 0, -beta, 0, -gamma),
# n, alpha, c0, c1, k0, k1 (current folded in), r_y (asymmetric_yield's share: 0 without it)
_B = FAMILY_AT
_N = _B + 5
_AL = _N + 1
_C0 = _N + 2
_C1 = _N + 3
_K0 = _N + 4
_K1 = _N + 5
_RY = _N + 6
#: The share of ``asymmetric_yield``, the one scaled effect Spencer's force carries.
(_R_Y,) = ASYMMETRIC_YIELD.shares


@numba.njit(cache=True, inline="always")
def _node_rate(p, x, v, d, z):
    """y' of the internal node for motion ``x, v``, stretch ``d = x - y`` and ``z``; the
    hysteretic force ``alpha z (1 + r_y sign(z))``."""
    return (p[_AL] * (z + p[_RY] * abs(z)) + p[_C0] * v + p[_K0] * d) / (p[_C0] + p[_C1])


@numba.njit(cache=True, inline="always")
def _force(p, x, v, d, z):
    yd = _node_rate(p, x, v, d, z)
    return p[_C1] * yd + p[_K1] * x + term_torque(p[:N_BASE], x, v, z, p[EPS_AT])


@numba.njit(cache=True, nogil=True)
def _driven_rate(x, u, p, dx):
    d, z = x[0], x[1]
    rd = u[1] - _node_rate(p, u[0], u[1], d, z)
    dx[0] = rd
    dx[1] = term_rate(p[_B:_N], p[_N], rd, z)


@numba.njit(cache=True, nogil=True)
def _driven_output(x, u, p):
    return _force(p, u[0], u[1], x[0], x[1])


# behind a compliant mount (the ``series_compliance`` effect on a driven test): the mount's
# mass, stiffness and damping after the family block
_MW = _RY + 1
_KW = _RY + 2
_CW = _RY + 3


@numba.njit(cache=True, nogil=True)
def _mount_rate(x, u, p, dx):
    """States: the mount's deflection ``m = x - y``, the damper end's velocity ``y'``, the
    stretch ``d`` and ``z``; the damper moves with its end ``y``."""
    m, yd, d, z = x[0], x[1], x[2], x[3]
    y = u[0] - m
    rd = yd - _node_rate(p, y, yd, d, z)
    dx[0] = u[1] - yd
    dx[1] = (p[_KW] * m + p[_CW] * (u[1] - yd) - _force(p, y, yd, d, z)) / p[_MW]
    dx[2] = rd
    dx[3] = term_rate(p[_B:_N], p[_N], rd, z)


@numba.njit(cache=True, nogil=True)
def _mount_output(x, u, p):
    return _force(p, u[0] - x[0], x[1], x[2], x[3])


@numba.njit(cache=True, nogil=True)
def _mech_rate(x, u, p, dx):
    th, w, d, z = x[0], x[1], x[2], x[3]
    uu = u[0] if u.shape[0] > 0 else 0.0
    rd = w - _node_rate(p, th, w, d, z)
    dx[0] = w
    dx[1] = (uu - p[KS_AT] * th - _force(p, th, w, d, z)) / p[J_AT]
    dx[2] = rd
    dx[3] = term_rate(p[_B:_N], p[_N], rd, z)


@numba.njit(cache=True, nogil=True)
def _mech_output(x, u, p):
    return x[0]


# ---- partial derivatives, for the exact sensitivities (hystdisc.simulation.sensitivity_ode);
# work: dT/dc (N_BASE), then dR/d(b, n) (6, from _WR), then the node rate's partials in
# (alpha, c0, c1, k0, r_y) (5, from _WN)
_BLOCK = (_AL, _C0, _C1, _K0, _RY)
_WR = N_BASE
_WN = N_BASE + 6


@numba.njit(cache=True, inline="always")
def _node_grad(p, v, d, z, work):
    """The node rate and its partials in ``d``, ``z`` and the velocity ``v``; its partials
    in ``alpha, c0, c1, k0, r_y`` go to ``work[_WN : _WN + 5]``."""
    den = p[_C0] + p[_C1]
    az = abs(z)
    hz = z + p[_RY] * az  # the hysteretic force over alpha
    node = (p[_AL] * hz + p[_C0] * v + p[_K0] * d) / den
    sz = 1.0 if z > 0.0 else (-1.0 if z < 0.0 else 0.0)
    work[_WN] = hz / den
    work[_WN + 1] = (v - node) / den
    work[_WN + 2] = -node / den
    work[_WN + 3] = d / den
    work[_WN + 4] = p[_AL] * az / den
    return node, p[_K0] / den, p[_AL] * (1.0 + p[_RY] * sz) / den, p[_C0] / den


@numba.njit(cache=True, inline="always")
def _stretch_rows(jp, i, rw, work):
    """Rows ``i`` (the stretch rate ``x' - node``) and ``i + 1`` (``z' = R(x' - node, z)``)
    of ``d rate / d p``, from the partials in ``work`` and ``rw = dR/d(x' - node)``."""
    for q in range(5):
        jp[i, _BLOCK[q]] = -work[_WN + q]
        jp[i + 1, _BLOCK[q]] = -rw * work[_WN + q]
    for q in range(6):
        jp[i + 1, _B + q] = work[_WR + q]


@numba.njit(cache=True, inline="always")
def _force_row(row, den, c1, node, work):
    """``-dF/dp / den`` into ``row`` (its entries in the term coefficients and in Spencer's
    block, ``k1``'s aside), from the partials in ``work``; ``den = -1``: ``dF/dp`` itself."""
    for i in range(N_BASE):
        row[i] = -work[i] / den
    for i in range(5):
        row[_BLOCK[i]] = -c1 * work[_WN + i] / den
    row[_C1] -= node / den


@numba.njit(cache=True, inline="always")
def _node_state_rows(jx, rw, rz, nv, nd, nz):
    """Rows 2 (the stretch rate ``v - node``) and 3 (``z'``) of ``d rate / d x`` for the
    states ``(., v, d, z)`` of a rig or a mount."""
    jx[2, 1] = 1.0 - nv
    jx[2, 2] = -nd
    jx[2, 3] = -nz
    jx[3, 1] = rw * (1.0 - nv)
    jx[3, 2] = -rw * nd
    jx[3, 3] = rz - rw * nz


@numba.njit(cache=True, nogil=True)
def _driven_rate_jac(x, u, p, need, jx, jp, work):
    d, z = x[0], x[1]
    node, nd, nz, _ = _node_grad(p, u[1], d, z, work)
    rw, rz = rate_grad(p[_B:_N], p[_N], u[1] - node, z, need[_B : _N + 1], work[_WR : _WR + 6])
    jx[0, 0] = -nd
    jx[0, 1] = -nz
    jx[1, 0] = -rw * nd
    jx[1, 1] = rz - rw * nz
    _stretch_rows(jp, 0, rw, work)


@numba.njit(cache=True, nogil=True)
def _driven_output_grad(x, u, p, need, gx, gp, work):
    d, z = x[0], x[1]
    node, nd, nz, _ = _node_grad(p, u[1], d, z, work)
    c1 = p[_C1]
    _, _, tz = torque_grad(p[:N_BASE], u[0], u[1], z, p[EPS_AT], need[:N_BASE], work[:N_BASE])
    gx[0] = c1 * nd
    gx[1] = c1 * nz + tz
    _force_row(gp, -1.0, c1, node, work)
    gp[_K1] = u[0]


@numba.njit(cache=True, nogil=True)
def _mech_rate_jac(x, u, p, need, jx, jp, work):
    th, w, d, z = x[0], x[1], x[2], x[3]
    uu = u[0] if u.shape[0] > 0 else 0.0
    node, nd, nz, nv = _node_grad(p, w, d, z, work)
    c1, J = p[_C1], p[J_AT]
    tth, tw, tz = torque_grad(p[:N_BASE], th, w, z, p[EPS_AT], need[:N_BASE], work[:N_BASE])
    rw, rz = rate_grad(p[_B:_N], p[_N], w - node, z, need[_B : _N + 1], work[_WR : _WR + 6])
    force = c1 * node + p[_K1] * th + term_torque(p[:N_BASE], th, w, z, p[EPS_AT])
    jx[0, 1] = 1.0
    # J theta'' = u - k_s theta - F(theta, w, d, z)
    jx[1, 0] = -(p[KS_AT] + p[_K1] + tth) / J
    jx[1, 1] = -(c1 * nv + tw) / J
    jx[1, 2] = -c1 * nd / J
    jx[1, 3] = -(c1 * nz + tz) / J
    jp[1, KS_AT] = -th / J
    jp[1, J_AT] = -(uu - p[KS_AT] * th - force) / (J * J)
    jp[1, _K1] = -th / J
    _force_row(jp[1], J, c1, node, work)
    # the stretch rate w - node and z' = R(w - node, z)
    _node_state_rows(jx, rw, rz, nv, nd, nz)
    _stretch_rows(jp, 2, rw, work)


@numba.njit(cache=True, nogil=True)
def _mech_output_grad(x, u, p, need, gx, gp, work):
    gx[0] = 1.0


@numba.njit(cache=True, nogil=True)
def _mount_rate_jac(x, u, p, need, jx, jp, work):
    m, yd, d, z = x[0], x[1], x[2], x[3]
    y = u[0] - m
    mw, kw, cw = p[_MW], p[_KW], p[_CW]
    node, nd, nz, nv = _node_grad(p, yd, d, z, work)
    c1 = p[_C1]
    ty, tv, tz = torque_grad(p[:N_BASE], y, yd, z, p[EPS_AT], need[:N_BASE], work[:N_BASE])
    rw, rz = rate_grad(p[_B:_N], p[_N], yd - node, z, need[_B : _N + 1], work[_WR : _WR + 6])
    force = c1 * node + p[_K1] * y + term_torque(p[:N_BASE], y, yd, z, p[EPS_AT])
    jx[0, 1] = -1.0
    # m_w y'' = k_w m + c_w (x' - y') - F(y, y', d, z), y = x - m
    jx[1, 0] = (kw + p[_K1] + ty) / mw
    jx[1, 1] = -(cw + c1 * nv + tv) / mw
    jx[1, 2] = -c1 * nd / mw
    jx[1, 3] = -(c1 * nz + tz) / mw
    _force_row(jp[1], mw, c1, node, work)
    jp[1, _K1] = -y / mw
    jp[1, _MW] = -(kw * m + cw * (u[1] - yd) - force) / (mw * mw)
    jp[1, _KW] = m / mw
    jp[1, _CW] = (u[1] - yd) / mw
    # the stretch rate y' - node and z' = R(y' - node, z)
    _node_state_rows(jx, rw, rz, nv, nd, nz)
    _stretch_rows(jp, 2, rw, work)


@numba.njit(cache=True, nogil=True)
def _mount_output_grad(x, u, p, need, gx, gp, work):
    m, yd, d, z = x[0], x[1], x[2], x[3]
    y = u[0] - m
    node, nd, nz, nv = _node_grad(p, yd, d, z, work)
    c1 = p[_C1]
    ty, tv, tz = torque_grad(p[:N_BASE], y, yd, z, p[EPS_AT], need[:N_BASE], work[:N_BASE])
    gx[0] = -(p[_K1] + ty)
    gx[1] = c1 * nv + tv
    gx[2] = c1 * nd
    gx[3] = c1 * nz + tz
    _force_row(gp, -1.0, c1, node, work)
    gp[_K1] = y


_PARAMS = """
    # name    unit           lower  upper  default  doc
    alpha_a   N*m            0      BIG    0.5      passive hysteretic torque
    alpha_b   N*m/A          0      BIG    1.5      current-dependent hysteretic torque
    c0_a      N*m*s/rad      0      BIG    0.5      passive damping beside the Bouc-Wen element
    c0_b      N*m*s/(rad*A)  0      BIG    0.6      its current dependence
    c1_a      N*m*s/rad      1e-9   BIG    5.0      passive damping of the internal node
    c1_b      N*m*s/(rad*A)  0      BIG    2.0      its current dependence
    k0        N*m/rad        0      BIG    0.5      stiffness beside the Bouc-Wen element
    k1        N*m/rad        0      BIG    0.0      accumulator stiffness (driven only)
    A         1/rad          1e-9   BIG    20       initial slope of z (z_sat = 1: A = beta + gamma)
    beta      1/rad          -BIG   BIG    5        shape (x_dot |z|^n term; gamma = A - beta)
    n         -              1e-4   10     2        exponent
"""

#: Ratios c1 / c0 of the starts from a Bouc-Wen fit; 13.5 is Spencer et al.'s (283/21).
START_RATIOS = (3.0, 13.5, 60.0)
#: The ratio of the start that is the Bouc-Wen fit itself (the node all but still): Spencer
#: contains standard Bouc-Wen as c1 / c0 grows, so it starts no worse than that fit.
LIMIT_RATIO = 1e3
#: A Bouc-Wen shape with ``|beta|`` or ``|gamma|`` above this many times ``A = beta + gamma`` is a
#: sharp reversal: Spencer is also started from the symmetric shape.
SHARP_SHAPE = 10.0
#: The sharpest yield a start keeps: the inner motion that saturates ``z`` (``1 / A``) is
#: at least this share of the motion in one sample (median peak velocity times the
#: sampling interval). A Bouc-Wen fit to a Coulomb-like damper can have ``A`` of 1e5
#: (a Bingham damper's driven set 11: every start mapped from it diverged at once, where
#: the explicit integrator needs thousands of steps per sample); the published start
#: is then also tried with ``A`` and ``beta`` softened to this, and the fit sharpens it
#: as far as the data want.
YIELD_PER_SAMPLE = 0.1


class Spencer(SystemFamily):
    """Spencer et al. (1997): Bouc-Wen with an internal dashpot (module docstring)."""

    name = "spencer"
    title = "Spencer (Bouc-Wen with an internal dashpot)"
    color = "tab:cyan"
    # its rows are its post-yield damping and yield torque (the combinations through the
    # internal dashpot that match the others' terms)
    correspondence = {"theta_dot": "c_post_0", "z": "alpha_a", "i*z": "alpha_b",
                      "i*theta_dot": "c0_b"}  # fmt: skip
    params = param_table(_PARAMS)
    normalization = "z_sat = 1 (gamma = A - beta)"
    current_params = ("alpha_b", "c0_b", "c1_b")
    current_laws = {"alpha": ("alpha_a", "alpha_b"), "c0": ("c0_a", "c0_b"), "c1": ("c1_a", "c1_b")}
    #: Parameters a release or forced rig does not have (k1 is the rig spring there).
    mech_drop = ("k1",)
    driven_states = ("d", "z")
    mech_states = ("d", "z")
    driven_rate = staticmethod(_driven_rate)
    driven_output = staticmethod(_driven_output)
    mech_rate = staticmethod(_mech_rate)
    mech_output = staticmethod(_mech_output)
    mount_states = ("m", "y_dot", "d", "z")
    mount_rate = staticmethod(_mount_rate)
    mount_output = staticmethod(_mount_output)
    mount_rate_jac = staticmethod(_mount_rate_jac)
    mount_output_grad = staticmethod(_mount_output_grad)
    #: A yield force that differs in tension and compression, at the internal node
    #: (``alpha z (1 + r_y sign(z))``); a damping that does is not built (``c0`` acts on
    #: the node's relative velocity, which the node rate itself sets).
    scaled_effects = (ASYMMETRIC_YIELD.name,)
    driven_rate_jac = staticmethod(_driven_rate_jac)
    driven_output_grad = staticmethod(_driven_output_grad)
    mech_rate_jac = staticmethod(_mech_rate_jac)
    mech_output_grad = staticmethod(_mech_output_grad)

    def block(self, p: Mapping[str, float], current: float) -> np.ndarray:
        """The family's part of the parameter vector at ``current`` (see the module; the
        current laws folded in by :meth:`~hystdisc.models.Family.law_value`, a saturating
        or quadratic law when ``p`` has its coefficient), ``asymmetric_yield``'s share
        last (0 when ``p`` has none).

        Examples
        --------
        >>> p = {**SPENCER.defaults(), "alpha_a": 0.5, "alpha_b": 3.0, "alpha_i0": 0.3}
        >>> round(float(SPENCER.block(p, 2.0)[6]), 4)  # alpha = 0.5 + 3 * 0.3 tanh(2 / 0.3)
        1.4
        """
        i = float(current)
        b, g = p["beta"], p["A"] - p["beta"]  # z saturates at 1: gamma = A - beta
        return np.array(
            [
                p["A"],
                0.0,
                -b,
                0.0,
                -g,
                p["n"],
                self.law_value(p, "alpha", i),
                self.law_value(p, "c0", i),
                self.law_value(p, "c1", i),
                p["k0"],
                p.get("k1", 0.0),
                p.get(_R_Y, 0.0),
            ]
        )

    def saturation_torque(self, p, which):
        """Through the internal dashpot: the yield torque ``alpha c1 / (c0 + c1)`` at 0 A
        and its increase to 1 A."""
        a0, a1 = p.get("alpha_yield_0"), p.get("alpha_yield_1")
        if a0 is None:
            return None
        return a0 if which == "a" else (None if a1 is None else a1 - a0)

    def derived(self, p: Mapping[str, float]) -> dict[str, float]:
        """Combinations the data identify when ``c1`` is not: the post-yield damping
        ``c0 c1 / (c0 + c1)`` and the yield torque ``alpha c1 / (c0 + c1)``, at 0 A
        (``_0``) and 1 A (``_1``); and ``gamma = A - beta`` (``z`` saturates at 1).

        Examples
        --------
        >>> d = SPENCER.derived(SPENCER.defaults())
        >>> round(d["c_post_0"], 4), round(d["alpha_yield_1"], 4), d["gamma"]
        (0.4545, 1.7284, 15.0)
        """
        out = {"gamma": p["A"] - p["beta"]}
        for i in (0, 1):
            c0 = self.law_value(p, "c0", i)
            c1 = self.law_value(p, "c1", i)
            out[f"c_post_{i}"] = c0 * c1 / (c0 + c1)
            out[f"alpha_yield_{i}"] = self.law_value(p, "alpha", i) * c1 / (c0 + c1)
        return out

    def starts(
        self, base: Mapping[str, float], velocity: float = 1.0, dt: float | None = None
    ) -> list[tuple[str, dict[str, float]]]:
        """Starts from a standard Bouc-Wen fit ``base``: the internal dashpot ``c1`` at
        :data:`START_RATIOS` times ``c0`` (Spencer et al.'s published ratio among them),
        with ``alpha``, ``c0`` and ``A`` scaled so that the loop is Bouc-Wen's at the start.
        With the sampling interval ``dt``, a published start sharper than the sampling
        resolves (:data:`YIELD_PER_SAMPLE`) is also given softened.

        Examples
        --------
        >>> bw = {"alpha_1": 1.0, "alpha_2": 2.0, "c_1": 0.5, "c_2": 0.5, "beta": 5.0,
        ...       "gamma": 15.0, "n": 2.0, "k_s": 0.0}
        >>> [label for label, _ in SPENCER.starts(bw)]  # doctest: +NORMALIZE_WHITESPACE
        ['c1/c0 = 3, beta = gamma, n = 2', 'c1/c0 = 13.5, beta = gamma, n = 2', 'c1/c0 = 13.5',
         'c1/c0 = 60, beta = gamma, n = 2', 'c1/c0 = 1000 (the Bouc-Wen fit)']
        >>> SPENCER.starts(bw)[1][1]["c1_a"] > SPENCER.starts(bw)[1][1]["c0_a"]
        True
        >>> sharp = {**bw, "beta": 6e4, "gamma": 9e4}  # a Coulomb-like yield
        >>> label, soft = SPENCER.starts(sharp, velocity=1.0, dt=2e-3)[-1]
        >>> label, soft["A"], soft["beta"]
        ('c1/c0 = 13.5, beta = gamma, n = 2, A softened to 5000', 5000.0, 2500.0)
        """
        out = []
        A = max(base["beta"] + base["gamma"], 1e-6)
        # a Bouc-Wen fit to a sharp reversal has |beta|, |gamma| >> A (z snaps back when the
        # motion reverses, a stiff rate): in Spencer's model the internal dashpot makes that
        # reversal, so such a fit starts Spencer from the symmetric shape beta = gamma = A/2
        # Spencer et al.'s shape (beta = gamma, n = 2) at every ratio; the Bouc-Wen fit's
        # own shape at the published ratio unless it is sharp
        sharp = max(abs(base["beta"]), abs(base["gamma"])) > SHARP_SHAPE * A
        for m in (*START_RATIOS, LIMIT_RATIO):
            s = (1.0 + m) / m  # c0 c1/(c0+c1) = c_bw and alpha c1/(c0+c1) = alpha_bw
            c0a, c0b = base["c_1"] * s, base["c_2"] * s
            floor = 1e-3 * max(c0a + c0b, 1e-12)  # a node dashpot is never 0
            shapes = [(", beta = gamma, n = 2", A / 2, 2.0)]
            if m == LIMIT_RATIO:  # the Bouc-Wen fit as it is
                shapes = [(" (the Bouc-Wen fit)", base["beta"], base["n"])]
            elif m == START_RATIOS[1] and not sharp:
                shapes.append(("", base["beta"], base["n"]))
            for label, beta, n in shapes:
                start = {
                    "alpha_a": base["alpha_1"] * s,
                    "alpha_b": base["alpha_2"] * s,
                    "c0_a": c0a,
                    "c0_b": c0b,
                    "c1_a": max(m * c0a, floor),
                    "c1_b": m * c0b,
                    "k0": 0.0,
                    "k1": base.get("k_s", 0.0),
                    "A": A * s,
                    "beta": beta * s,
                    "n": n,
                }
                out.append((f"c1/c0 = {m:g}{label}", start))
        if dt is not None and dt > 0 and velocity > 0:
            a_max = 1.0 / (YIELD_PER_SAMPLE * velocity * dt)
            label, start = out[1]  # the published ratio and shape
            if start["A"] > a_max:
                f = a_max / start["A"]
                soft = {**start, "A": start["A"] * f, "beta": start["beta"] * f}
                out.append((f"{label}, A softened to {a_max:.4g}", soft))
        return out

    def equations(self) -> str:
        return (
            "T = c1*y_dot + k1*x,  c_j = c_j_a + c_j_b*i,  alpha = alpha_a + alpha_b*i\n"
            "y_dot = (alpha*z + c0*x_dot + k0*(x - y)) / (c0 + c1)\n"
            "dz/dt = A*(x_dot - y_dot) - beta*(x_dot - y_dot)*|z|^n "
            "- gamma*|x_dot - y_dot|*z*|z|^(n-1),  A = beta + gamma"
        )


SPENCER = Spencer()
