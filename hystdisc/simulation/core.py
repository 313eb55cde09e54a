"""Fast fixed-step simulation of the rig with any model in term form.

Three experiment types (doc/design.rst section 1):

``release``
    ``theta'' = -T(theta, theta', z, i)`` per unit inertia (the spring is the ``theta``
    torque term), from ``theta0`` at rest with ``z = 0``.
``forced``
    ``J theta'' = u(t) - T(...)`` with a known input ``u`` between samples: a cubic spline
    through the samples (``hold='cubic'``, the default: a sampled smooth force), linear
    (``'linear'``) or zero-order held (``'zoh'``, a DAC output).
``driven``
    ``theta(t)`` is imposed; only ``z`` is integrated and the torque ``T`` is returned.

The integrator is classical RK4 on the sample grid with a number of sub-steps chosen per
sample interval from the local stiffness of the state (``|theta'| dg/dz`` for the
hysteretic state, damping and spring rates for the mechanics), compiled with numba and
batched over runs; the kernels release the GIL, so independent fits can run on threads.
Divergence (NaN, overflow) is detected and reported as a
:class:`~hystdisc.errors.HystdiscError` naming the parameters.

Examples
--------
>>> import numpy as np
>>> from hystdisc.models import Model
>>> from hystdisc.simulation.core import simulate_release
>>> t = np.arange(0, 2.0, 1e-3)
>>> out = simulate_release(Model("dahl"), t, current=0.5, theta0=0.3)
>>> out.theta.shape, round(float(out.theta[0]), 3)
((2000,), 0.3)
>>> bool(abs(out.theta[-1]) < 0.3)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy.interpolate import CubicSpline

from hystdisc.errors import HystdiscError
from hystdisc.models import SIGN_EPS, Model, TermModel

# per-run base coefficients, after folding in the current
#   0 theta, 1 theta_dot, 2 z, 3 |theta_dot| z, 4 sign(theta_dot), 5 theta_dot|theta_dot|,
#   6 theta^3, 7 constant
N_BASE = 8

#: Target of ``h * lambda`` per RK4 sub-step (smaller is more accurate).
STEP_RATIO = 0.2
#: How a forced run's input is interpolated between samples (kernel codes).
HOLDS = {"linear": 0, "zoh": 1, "cubic": 2}
MIN_SUBSTEPS = 2
MAX_SUBSTEPS = 500


def base_coefficients(tm: TermModel, current: float) -> np.ndarray:
    """Fold the current into the torque coefficients of a run (see ``N_BASE`` layout)."""
    g = tm.torque.get
    i = float(current)
    c = np.zeros(N_BASE)
    c[0] = g("theta", 0.0)
    c[1] = g("theta_dot", 0.0) + i * g("i*theta_dot", 0.0) + i * i * g("i^2*theta_dot", 0.0)
    c[2] = g("z", 0.0) + i * g("i*z", 0.0) + i * i * g("i^2*z", 0.0)
    c[3] = g("|theta_dot|*z", 0.0)
    c[4] = g("sign(theta_dot)", 0.0) + i * g("i*sign(theta_dot)", 0.0)
    c[5] = g("theta_dot*|theta_dot|", 0.0)
    c[6] = g("theta^3", 0.0)
    c[7] = g("1", 0.0)
    return c


# ----------------------------------------------------------------------------- kernels


@numba.njit(cache=True, inline="always")
def _torque(c, th, w, z, eps):
    aw = abs(w)
    out = c[0] * th + c[1] * w + c[2] * z + c[3] * aw * z + c[5] * w * aw + c[7]
    if c[4] != 0.0:  # tanh and the cube are the costly terms: skip them when absent
        out += c[4] * math.tanh(w / eps)
    if c[6] != 0.0:
        out += c[6] * th * th * th
    return out


@numba.njit(cache=True, inline="always")
def _rate(b, n, w, z):
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


@numba.njit(cache=True, inline="always")
def _rate_stiffness(b, n, w, z):
    """|d(dz/dt)/dz| and |d(dz/dt)/dw| (for the sub-step choice)."""
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


@numba.njit(cache=True)
def _n_sub(c, b, n, J, th, w, z, h, eps, mech, u, ratio, min_sub, max_sub):
    dgdz, dgdw = _rate_stiffness(b, n, w, z)
    lam = dgdz  # already carries the |theta_dot| factor
    if mech:
        # the smoothed sign is stiff near w = 0: use the smallest |w| the interval may reach
        sech2 = 0.0
        acc = 0.0
        if c[4] != 0.0:
            acc = abs((u - _torque(c, th, w, z, eps)) / J)
            wmin = max(abs(w) - 1.5 * h * acc, 0.0)
            sech2 = 1.0 - math.tanh(wmin / eps) ** 2
        dtdw = abs(c[1] + c[3] * z * (1.0 if w >= 0 else -1.0)) + abs(c[4]) / eps * sech2
        dtdw += 2.0 * abs(c[5] * w)
        if c[4] != 0.0:
            # resolve the fast sign transition in time (its rate is acc / eps)
            lam += sech2 * acc / eps
        dtdth = abs(c[0] + 3.0 * c[6] * th * th)
        dtdz = abs(c[2] + c[3] * abs(w))
        lam += dtdw / J + math.sqrt(dtdth / J) + math.sqrt(dtdz * dgdw / J)
    m = int(math.ceil(h * lam / ratio))
    if m < min_sub:
        m = min_sub
    if m > max_sub:
        m = max_sub
    return m


@numba.njit(cache=True, inline="always")
def _input(ua, ub, ma, mb, f, hold):
    """Input at fraction ``f`` of a sample interval: linear (0), held (1) or cubic Hermite (2)
    with end slopes ``ma``, ``mb`` already multiplied by the interval length."""
    if hold == 2:
        f2 = f * f
        f3 = f2 * f
        return (
            (2.0 * f3 - 3.0 * f2 + 1.0) * ua
            + (f3 - 2.0 * f2 + f) * ma
            + (-2.0 * f3 + 3.0 * f2) * ub
            + (f3 - f2) * mb
        )
    return ua + (ub - ua) * f


@numba.njit(cache=True, nogil=True)
def _mech_batch(
    coef,
    bb,
    nn,
    JJ,
    t,
    u,
    du,
    offsets,
    th0,
    w0,
    z0,
    hold,
    eps,
    ratio,
    min_sub,
    max_sub,
    th_out,
    w_out,
    z_out,
    status,
    work,
):
    """RK4 for release/forced runs, concatenated with ``offsets``; one model per run
    (``max_sub``: each run's sub-step cap)."""
    nruns = offsets.shape[0] - 1
    for r in range(nruns):
        c = coef[r]
        b = bb[r]
        n = nn[r]
        J = JJ[r]
        k0 = offsets[r]
        k1 = offsets[r + 1]
        th = th0[r]
        w = w0[r]
        z = z0[r]
        th_out[k0] = th
        w_out[k0] = w
        z_out[k0] = z
        status[r] = 0
        work[r] = 0
        for k in range(k0, k1 - 1):
            h = t[k + 1] - t[k]
            ua = u[k]
            ub = u[k + 1] if hold != 1 else u[k]
            ma = h * du[k] if hold == 2 else 0.0
            mb = h * du[k + 1] if hold == 2 else 0.0
            m = _n_sub(c, b, n, J, th, w, z, h, eps, True, ua, ratio, min_sub, max_sub[r])
            work[r] += 2 * m + 1
            hs = h / m
            for s in range(m):
                u1 = _input(ua, ub, ma, mb, s / m, hold)
                u2 = _input(ua, ub, ma, mb, (s + 0.5) / m, hold)
                u3 = _input(ua, ub, ma, mb, (s + 1.0) / m, hold)
                k1t = w
                k1w = (u1 - _torque(c, th, w, z, eps)) / J
                k1z = _rate(b, n, w, z)
                tht = th + 0.5 * hs * k1t
                wt = w + 0.5 * hs * k1w
                zt = z + 0.5 * hs * k1z
                k2t = wt
                k2w = (u2 - _torque(c, tht, wt, zt, eps)) / J
                k2z = _rate(b, n, wt, zt)
                tht = th + 0.5 * hs * k2t
                wt = w + 0.5 * hs * k2w
                zt = z + 0.5 * hs * k2z
                k3t = wt
                k3w = (u2 - _torque(c, tht, wt, zt, eps)) / J
                k3z = _rate(b, n, wt, zt)
                tht = th + hs * k3t
                wt = w + hs * k3w
                zt = z + hs * k3z
                k4t = wt
                k4w = (u3 - _torque(c, tht, wt, zt, eps)) / J
                k4z = _rate(b, n, wt, zt)
                th += hs / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
                w += hs / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
                z += hs / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)
            th_out[k + 1] = th
            w_out[k + 1] = w
            z_out[k + 1] = z
            if not (abs(th) < 1e8 and abs(w) < 1e10 and abs(z) < 1e12):
                status[r] = 1
                for kk in range(k + 1, k1):
                    th_out[kk] = np.nan
                    w_out[kk] = np.nan
                    z_out[kk] = np.nan
                break


@numba.njit(cache=True, inline="always")
def _z_rk4(b, n, z, wa, wb, fa, fc, h):
    """One RK4 step of z from fraction fa to fc of a sample interval (velocity linear)."""
    hs = h * (fc - fa)
    w1 = wa + (wb - wa) * fa
    w2 = wa + (wb - wa) * (0.5 * (fa + fc))
    w3 = wa + (wb - wa) * fc
    k1z = _rate(b, n, w1, z)
    k2z = _rate(b, n, w2, z + 0.5 * hs * k1z)
    k3z = _rate(b, n, w2, z + 0.5 * hs * k2z)
    k4z = _rate(b, n, w3, z + hs * k3z)
    return z + hs / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)


@numba.njit(cache=True)
def _z_segment(b, n, z, wa, wb, f0, f1, h, m):
    """RK4 for z over the fraction [f0, f1] of a sample interval, velocity linear in time.

    A sub-step in which z changes sign is redone in two parts split at the (secant) zero
    of z, since the |z|^n terms have a kink there.
    """
    kinked = b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0
    for s in range(m):
        fa = f0 + (f1 - f0) * (s / m)
        fc = f0 + (f1 - f0) * ((s + 1.0) / m)
        zn = _z_rk4(b, n, z, wa, wb, fa, fc, h)
        if kinked and z * zn < 0.0:
            fm = fa + (fc - fa) * (z / (z - zn))
            z1 = _z_rk4(b, n, z, wa, wb, fa, fm, h)
            zn = _z_rk4(b, n, z1, wa, wb, fm, fc, h)
        z = zn
    return z


@numba.njit(cache=True, nogil=True)
def _driven_batch(
    coef,
    bb,
    nn,
    t,
    th_in,
    w_in,
    offsets,
    z0,
    eps,
    ratio,
    min_sub,
    max_sub,
    tq_out,
    z_out,
    status,
    work,
):
    """Integrate z under an imposed velocity (linear between samples) and return torque
    (``max_sub``: each run's sub-step cap)."""
    nruns = offsets.shape[0] - 1
    for r in range(nruns):
        c = coef[r]
        b = bb[r]
        n = nn[r]
        k0 = offsets[r]
        k1 = offsets[r + 1]
        z = z0[r]
        z_out[k0] = z
        tq_out[k0] = _torque(c, th_in[k0], w_in[k0], z, eps)
        status[r] = 0
        work[r] = 0
        for k in range(k0, k1 - 1):
            h = t[k + 1] - t[k]
            wa = w_in[k]
            wb = w_in[k + 1]
            wmax = max(abs(wa), abs(wb))
            m = _n_sub(c, b, n, 1.0, 0.0, wmax, z, h, eps, False, 0.0, ratio, min_sub, max_sub[r])
            work[r] += 2 * m + 1
            if wa * wb < 0.0:
                # |theta_dot| has a kink where the velocity reverses: split the interval there
                f = wa / (wa - wb)
                z = _z_segment(b, n, z, wa, wb, 0.0, f, h, m)
                z = _z_segment(b, n, z, wa, wb, f, 1.0, h, m)
            else:
                z = _z_segment(b, n, z, wa, wb, 0.0, 1.0, h, m)
            z_out[k + 1] = z
            tq_out[k + 1] = _torque(c, th_in[k + 1], w_in[k + 1], z, eps)
            if not abs(z) < 1e12:
                status[r] = 1
                for kk in range(k + 1, k1):
                    tq_out[kk] = np.nan
                    z_out[kk] = np.nan
                break


@numba.njit(cache=True, nogil=True)
def _torque_series(coef, rows, offsets, th_in, w_in, z, eps, out):
    """Torque of the entries ``rows`` (samples ``offsets[e]:offsets[e+1]``) for a given ``z``
    (the same arithmetic as :func:`_driven_batch`)."""
    for j in range(rows.shape[0]):
        e = rows[j]
        c = coef[e]
        for k in range(offsets[e], offsets[e + 1]):
            out[k] = _torque(c, th_in[k], w_in[k], z[k], eps)


# ----------------------------------------------------------------------------- python API


@dataclass
class SimResult:
    """Simulated signals of one run."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    z: np.ndarray
    torque: np.ndarray
    current: float


def _as_terms(model: Model | TermModel) -> TermModel:
    if isinstance(model, Model):
        return model.to_terms()
    if isinstance(model, TermModel):
        return model
    raise TypeError(f"expected a Model or TermModel, got {type(model).__name__}")


def _describe(model: Model | TermModel) -> str:
    if isinstance(model, Model):
        return repr(model)
    return model.equations().replace("\n", "; ")


def _diverged(model, runs: list[str]) -> HystdiscError:
    return HystdiscError(
        f"simulation diverged (NaN or overflow) in run(s) {', '.join(runs)} with "
        f"{_describe(model)}; fix: check the parameters (a negative damping or a very large "
        "rate makes the model unstable)"
    )


def _per_run(max_sub, nruns: int) -> np.ndarray:
    """A sub-step cap per run from one value or one per run."""
    out = np.empty(nruns, dtype=np.int64)
    out[:] = np.asarray(max_sub, dtype=np.int64)
    return out


def concat_runs(arrays: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate per-run arrays; return the flat array and the run offsets."""
    offsets = np.zeros(len(arrays) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(a) for a in arrays])
    flat = np.concatenate([np.asarray(a, dtype=float) for a in arrays]) if arrays else np.zeros(0)
    return flat, offsets


def input_slopes(t: np.ndarray, u: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Slopes ``du/dt`` at the samples of the not-a-knot cubic spline through each run's input.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> s = input_slopes(t, t**2, np.array([0, 11]))
    >>> bool(np.allclose(s, 2 * t))
    True
    """
    du = np.zeros_like(u)
    for a, b in zip(offsets[:-1], offsets[1:], strict=True):
        if not np.any(u[a:b]):
            continue
        if b - a >= 4:
            du[a:b] = CubicSpline(t[a:b], u[a:b])(t[a:b], 1)
        elif b - a >= 2:
            du[a:b] = np.gradient(u[a:b], t[a:b])
    return du


def mech_batch(
    coef: np.ndarray,
    b: np.ndarray,
    n: np.ndarray,
    J: np.ndarray,
    t: np.ndarray,
    u: np.ndarray,
    offsets: np.ndarray,
    theta0: np.ndarray,
    theta_dot0: np.ndarray,
    z0: np.ndarray,
    hold: str = "cubic",
    eps: float = SIGN_EPS,
    ratio: float = STEP_RATIO,
    min_sub: int = MIN_SUBSTEPS,
    max_sub: int | np.ndarray = MAX_SUBSTEPS,
    du: np.ndarray | None = None,
    work: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Low-level batched release/forced simulation, one model per run (rows of ``coef``, ``b``).

    Returns flat ``theta, theta_dot, z`` and the per-run status (0 ok, 1 diverged).
    ``du`` are the input's spline slopes (:func:`input_slopes`) when already known;
    ``max_sub`` caps the sub-steps per sample interval (one value, or one per run).
    ``work`` (int64, one per run), when given, receives the integration work of each run:
    ``2 m + 1`` per sample interval integrated in ``m`` sub-steps.
    """
    if hold not in HOLDS:
        raise HystdiscError(f"unknown input hold '{hold}'; fix: use one of {', '.join(HOLDS)}")
    th = np.empty_like(t)
    w = np.empty_like(t)
    z = np.empty_like(t)
    status = np.zeros(len(offsets) - 1, dtype=np.int64)
    if hold != "cubic":
        du = np.zeros(1)
    elif du is None:
        du = input_slopes(t, u, offsets)
    _mech_batch(
        np.ascontiguousarray(coef, dtype=float),
        np.ascontiguousarray(b, dtype=float),
        np.asarray(n, dtype=float),
        np.asarray(J, dtype=float),
        t,
        u,
        du,
        offsets,
        np.asarray(theta0, dtype=float),
        np.asarray(theta_dot0, dtype=float),
        np.asarray(z0, dtype=float),
        HOLDS[hold],
        eps,
        ratio,
        min_sub,
        _per_run(max_sub, len(offsets) - 1),
        th,
        w,
        z,
        status,
        np.zeros(len(offsets) - 1, dtype=np.int64) if work is None else work,
    )
    return th, w, z, status


def driven_batch(
    coef: np.ndarray,
    b: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    offsets: np.ndarray,
    z0: np.ndarray,
    eps: float = SIGN_EPS,
    ratio: float = STEP_RATIO,
    min_sub: int = MIN_SUBSTEPS,
    max_sub: int | np.ndarray = MAX_SUBSTEPS,
    work: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Low-level batched driven simulation; returns flat ``torque, z`` and the status
    (``max_sub``: one sub-step cap, or one per run; ``work`` as in :func:`mech_batch`)."""
    tq = np.empty_like(t)
    z = np.empty_like(t)
    status = np.zeros(len(offsets) - 1, dtype=np.int64)
    _driven_batch(
        np.ascontiguousarray(coef, dtype=float),
        np.ascontiguousarray(b, dtype=float),
        np.asarray(n, dtype=float),
        t,
        theta,
        theta_dot,
        offsets,
        np.asarray(z0, dtype=float),
        eps,
        ratio,
        min_sub,
        _per_run(max_sub, len(offsets) - 1),
        tq,
        z,
        status,
        np.zeros(len(offsets) - 1, dtype=np.int64) if work is None else work,
    )
    return tq, z, status


def driven_shared(
    coef: np.ndarray,
    b: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    offsets: np.ndarray,
    run: np.ndarray,
    eps: float = SIGN_EPS,
    ratio: float = STEP_RATIO,
    min_sub: int = MIN_SUBSTEPS,
    max_sub: int | np.ndarray = MAX_SUBSTEPS,
    work: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`driven_batch` from ``z = 0`` for entries that may share their hysteresis.

    Entries ``e`` on the same run (``run[e]``, the samples ``offsets[e]:offsets[e+1]``) with
    the same rate coefficients and exponent have the same ``z``: it is integrated once and
    only the torque is evaluated for the others (in a driven experiment the torque-side
    parameters do not act on ``z``, so most columns of a finite-difference Jacobian need no
    integration). Returns exactly what :func:`driven_batch` returns; ``work`` (one per
    entry) receives the integration work, 0 for the entries that reuse another's z.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 50)
    >>> w = np.cos(6 * t)
    >>> coef = np.zeros((2, N_BASE)); coef[:, 2] = (1.0, 2.0)
    >>> b = np.tile([10.0, -10.0, 0, 0, 0], (2, 1))
    >>> tq, z, st = driven_shared(coef, b, np.ones(2), np.r_[t, t], np.zeros(100), np.r_[w, w],
    ...                           np.array([0, 50, 100]), np.array([0, 0]))
    >>> bool(np.array_equal(tq[50:], 2 * tq[:50]))
    True
    """
    ne = len(offsets) - 1
    max_sub = _per_run(max_sub, ne)
    first: dict[tuple, int] = {}
    owner = np.empty(ne, dtype=np.int64)
    for e in range(ne):
        key = (int(run[e]), float(n[e]), *map(float, b[e]))
        owner[e] = first.setdefault(key, e)
    lead = np.array(sorted(first.values()), dtype=np.int64)
    if lead.size == ne:
        return driven_batch(
            coef,
            b,
            n,
            t,
            theta,
            theta_dot,
            offsets,
            np.zeros(ne),
            eps,
            ratio,
            min_sub,
            max_sub,
            work,
        )
    lens = np.diff(offsets)
    sub_off = np.zeros(lead.size + 1, dtype=np.int64)
    sub_off[1:] = np.cumsum(lens[lead])
    idx = np.concatenate([np.arange(offsets[e], offsets[e + 1]) for e in lead])
    work_l = np.zeros(lead.size, dtype=np.int64)
    tq_l, z_l, st_l = driven_batch(
        coef[lead],
        b[lead],
        n[lead],
        t[idx],
        theta[idx],
        theta_dot[idx],
        sub_off,
        np.zeros(lead.size),
        eps,
        ratio,
        min_sub,
        max_sub[lead],
        work_l,
    )
    pos = {int(e): j for j, e in enumerate(lead)}
    if work is not None:
        work[:] = 0
        work[lead] = work_l
    tq = np.empty_like(t)
    z = np.empty_like(t)
    status = np.zeros(ne, dtype=np.int64)
    for e in range(ne):
        j = pos[int(owner[e])]
        z[offsets[e] : offsets[e + 1]] = z_l[sub_off[j] : sub_off[j + 1]]
        status[e] = st_l[j]
        if owner[e] == e:
            tq[offsets[e] : offsets[e + 1]] = tq_l[sub_off[j] : sub_off[j + 1]]
    rest = np.array([e for e in range(ne) if owner[e] != e], dtype=np.int64)
    _torque_series(
        np.ascontiguousarray(coef, dtype=float), rest, offsets, theta, theta_dot, z, eps, tq
    )
    return tq, z, status


def integrate_z_flat(
    b: np.ndarray,
    n: float,
    t: np.ndarray,
    w: np.ndarray,
    offsets: np.ndarray,
    eps: float = SIGN_EPS,
) -> np.ndarray:
    """z(t) of runs concatenated with ``offsets`` (see :func:`concat_runs`), from z = 0.

    The sub-step rule of the output-error fit (ratio 0.4, at most 8 sub-steps per sample).

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 101)
    >>> z = integrate_z_flat(np.array([1.0, 0, 0, 0, 0]), 1.0, t, np.ones(101), np.array([0, 101]))
    >>> round(float(z[-1]), 6)
    1.0
    """
    nr = len(offsets) - 1
    _, z, _ = driven_batch(
        np.zeros((nr, N_BASE)),
        np.tile(np.asarray(b, dtype=float), (nr, 1)),
        np.full(nr, n),
        t,
        np.zeros_like(t),
        w,
        offsets,
        np.zeros(nr),
        eps,
        ratio=0.4,
        min_sub=1,
        max_sub=8,
    )
    return z


def integrate_z(
    b: np.ndarray,
    n: float,
    t_list: list[np.ndarray],
    w_list: list[np.ndarray],
    eps: float = SIGN_EPS,
) -> list[np.ndarray]:
    """z(t) of each run under its velocity record, from z = 0 (equation-error stage)."""
    t, offsets = concat_runs(t_list)
    w, _ = concat_runs(w_list)
    z = integrate_z_flat(b, n, t, w, offsets, eps)
    return [z[offsets[k] : offsets[k + 1]] for k in range(len(t_list))]


def simulate_mech(
    model: Model | TermModel,
    t_list: list[np.ndarray],
    currents: list[float],
    theta0: list[float],
    inputs: list[np.ndarray] | None = None,
    theta_dot0: list[float] | None = None,
    z0: list[float] | None = None,
    hold: str = "cubic",
    eps: float = SIGN_EPS,
    raise_on_divergence: bool = True,
) -> tuple[list[SimResult], np.ndarray]:
    """Simulate several release/forced runs in one compiled call.

    ``inputs=None`` is a release (per unit inertia, no input); otherwise the runs are
    forced with the model's ``J``. Returns the per-run results and the per-run status
    (0 ok, 1 diverged). The ``torque`` of each result is the damper torque (spring excluded).
    """
    tm = _as_terms(model)
    nr = len(t_list)
    t, offsets = concat_runs(t_list)
    if inputs is None:
        u = np.zeros_like(t)
        J = 1.0
    else:
        u, _ = concat_runs(inputs)
        J = tm.J
    coef = np.array([base_coefficients(tm, i) for i in currents]).reshape(nr, N_BASE)
    b = np.tile(tm.hysteresis_vector(), (nr, 1))
    w0 = np.zeros(nr) if theta_dot0 is None else np.asarray(theta_dot0, dtype=float)
    zz0 = np.zeros(nr) if z0 is None else np.asarray(z0, dtype=float)
    th, w, z, status = mech_batch(
        coef,
        b,
        np.full(nr, tm.n),
        np.full(nr, J),
        t,
        u,
        offsets,
        np.asarray(theta0, float),
        w0,
        zz0,
        hold,
        eps,
    )
    if raise_on_divergence and status.any():
        raise _diverged(model, [str(k) for k in np.flatnonzero(status)])
    out = []
    ks = tm.torque.get("theta", 0.0)
    for r in range(nr):
        sl = slice(offsets[r], offsets[r + 1])
        tq = tm.eval_torque(th[sl], w[sl], z[sl], currents[r]) - ks * th[sl]
        out.append(SimResult(t[sl], th[sl], w[sl], z[sl], tq, float(currents[r])))
    return out, status


def simulate_driven_runs(
    model: Model | TermModel,
    t_list: list[np.ndarray],
    currents: list[float],
    theta_list: list[np.ndarray],
    theta_dot_list: list[np.ndarray],
    z0: list[float] | None = None,
    eps: float = SIGN_EPS,
    raise_on_divergence: bool = True,
) -> tuple[list[SimResult], np.ndarray]:
    """Torque of several driven runs (imposed theta, theta_dot) in one compiled call.

    The returned torque includes every torque term of the model, the ``theta`` (spring)
    term too, since a characterization machine measures the total force on the rod.
    """
    tm = _as_terms(model)
    nr = len(t_list)
    t, offsets = concat_runs(t_list)
    th, _ = concat_runs(theta_list)
    w, _ = concat_runs(theta_dot_list)
    coef = np.array([base_coefficients(tm, i) for i in currents]).reshape(nr, N_BASE)
    b = np.tile(tm.hysteresis_vector(), (nr, 1))
    zz0 = np.zeros(nr) if z0 is None else np.asarray(z0, dtype=float)
    tq, z, status = driven_batch(coef, b, np.full(nr, tm.n), t, th, w, offsets, zz0, eps)
    if raise_on_divergence and status.any():
        raise _diverged(model, [str(k) for k in np.flatnonzero(status)])
    out = []
    for r in range(nr):
        sl = slice(offsets[r], offsets[r + 1])
        out.append(SimResult(t[sl], th[sl], w[sl], z[sl], tq[sl], float(currents[r])))
    return out, status


def simulate_release(
    model: Model | TermModel, t: np.ndarray, current: float, theta0: float, **kw
) -> SimResult:
    """Simulate one release of the SAS rig (per unit inertia) from ``theta0`` at rest."""
    return simulate_mech(model, [t], [current], [theta0], **kw)[0][0]


def simulate_forced(
    model: Model | TermModel,
    t: np.ndarray,
    current: float,
    u: np.ndarray,
    theta0: float = 0.0,
    theta_dot0: float = 0.0,
    **kw,
) -> SimResult:
    """Simulate one forced run ``J theta'' + T = u`` from rest (or the given state)."""
    return simulate_mech(
        model, [t], [current], [theta0], inputs=[u], theta_dot0=[theta_dot0], **kw
    )[0][0]


def simulate_driven(
    model: Model | TermModel,
    t: np.ndarray,
    current: float,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    **kw,
) -> SimResult:
    """Torque of one driven run with imposed ``theta(t)`` and ``theta_dot(t)``."""
    return simulate_driven_runs(model, [t], [current], [theta], [theta_dot], **kw)[0][0]
