"""Fixed-step compiled kernels of the term form: release/forced and driven runs, batched.

Classical RK4 on the sample grid with a number of sub-steps chosen per sample interval
from the local stiffness of the state (``|theta'| dg/dz`` for the hysteretic state, or
its rate over its saturated scale where that is larger: a sub-step moves ``z`` by at
most ``STEP_RATIO`` of it; damping and spring rates for the mechanics), compiled with
numba and batched over runs; the kernels release the GIL, so independent fits can run on
threads. The batch kernels take runs concatenated with ``offsets``, one model (row of
``coef``, ``bb``) and one sub-step cap (``max_sub``) per run. The rate and torque
equations are the models layer's (:mod:`hystdisc.models.compiled`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hystdisc.models.compiled import rate_stiffness, term_rate, term_torque

#: Target of ``h * lambda`` per RK4 sub-step (smaller is more accurate).
STEP_RATIO = 0.2
#: How a forced run's input is interpolated between samples (kernel codes).
HOLDS = {"linear": 0, "zoh": 1, "cubic": 2}
MIN_SUBSTEPS = 2
MAX_SUBSTEPS = 500


# ----------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def n_sub(c, b, n, J, th, w, z, h, eps, mech, u, ratio, min_sub, max_sub):
    dgdz, dgdw = rate_stiffness(b, n, w, z)
    # already carries the |theta_dot| factor; and a sub-step moves z by at most ``ratio`` of
    # its saturated scale (1, or |z| beyond it): dg/dz vanishes at z = 0 (n > 1), where a
    # sharp yield (A |theta_dot| h >> 1) carries z from 0 to saturation within one sample
    lam = max(dgdz, abs(term_rate(b, n, w, z)) / max(abs(z), 1.0))
    if mech:
        # the smoothed sign is stiff near w = 0: use the smallest |w| the interval may reach
        sech2 = 0.0
        acc = 0.0
        if c[4] != 0.0:
            acc = abs((u - term_torque(c, th, w, z, eps)) / J)
            wmin = max(abs(w) - 1.5 * h * acc, 0.0)
            sech2 = 1.0 - math.tanh(wmin / eps) ** 2
        dtdw = abs(c[1] + c[3] * z * (1.0 if w >= 0 else -1.0)) + abs(c[4]) / eps * sech2
        dtdw += 2.0 * abs(c[5] * w) + abs(c[10])
        if c[8] != 0.0:
            # shear thinning: its slope (w^2 + eps^2)^((m-1)/2) is largest at the smallest
            # |w| the interval may reach (eps^(m-1) at w = 0)
            if c[4] == 0.0:
                acc = abs((u - term_torque(c, th, w, z, eps)) / J)
            wlo = max(abs(w) - 1.5 * h * acc, 0.0)
            dtdw += abs(c[8]) * (wlo * wlo + eps * eps) ** (0.5 * (c[9] - 1.0))
        if c[4] != 0.0:
            # resolve the fast sign transition in time (its rate is acc / eps)
            lam += sech2 * acc / eps
        dtdth = abs(c[0] + 3.0 * c[6] * th * th)
        dtdz = abs(c[2] + c[3] * abs(w)) + abs(c[11])
        lam += dtdw / J + math.sqrt(dtdth / J) + math.sqrt(dtdz * dgdw / J)
    m = int(math.ceil(h * lam / ratio))
    if m < min_sub:
        m = min_sub
    if m > max_sub:
        m = max_sub
    return m


@numba.njit(cache=True, inline="always")
def interpolate_input(ua, ub, ma, mb, f, hold):
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


@numba.njit(cache=True, inline="always")
def mech_rate(c, b, n, J, u, th, w, z, eps):
    """Rates ``(theta', theta'', z')`` of a release/forced rig: ``J theta'' = u - T``."""
    return w, (u - term_torque(c, th, w, z, eps)) / J, term_rate(b, n, w, z)


@numba.njit(cache=True, nogil=True)
def mech_batch_kernel(
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
    """RK4 for release/forced runs, concatenated with ``offsets``; one model per run."""
    for r in range(offsets.shape[0] - 1):
        c, b, n, J = coef[r], bb[r], nn[r], JJ[r]
        k0, k1 = offsets[r], offsets[r + 1]
        th, w, z = th0[r], w0[r], z0[r]
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
            m = n_sub(c, b, n, J, th, w, z, h, eps, True, ua, ratio, min_sub, max_sub[r])
            work[r] += 2 * m + 1
            hs = h / m
            for s in range(m):
                u1 = interpolate_input(ua, ub, ma, mb, s / m, hold)
                u2 = interpolate_input(ua, ub, ma, mb, (s + 0.5) / m, hold)
                u3 = interpolate_input(ua, ub, ma, mb, (s + 1.0) / m, hold)
                k1t, k1w, k1z = mech_rate(c, b, n, J, u1, th, w, z, eps)
                k2t, k2w, k2z = mech_rate(
                    c, b, n, J, u2, th + 0.5 * hs * k1t, w + 0.5 * hs * k1w, z + 0.5 * hs * k1z, eps
                )
                k3t, k3w, k3z = mech_rate(
                    c, b, n, J, u2, th + 0.5 * hs * k2t, w + 0.5 * hs * k2w, z + 0.5 * hs * k2z, eps
                )
                k4t, k4w, k4z = mech_rate(
                    c, b, n, J, u3, th + hs * k3t, w + hs * k3w, z + hs * k3z, eps
                )
                th += hs / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
                w += hs / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
                z += hs / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)
            th_out[k + 1] = th
            w_out[k + 1] = w
            z_out[k + 1] = z
            if not (abs(th) < 1e8 and abs(w) < 1e10 and abs(z) < 1e12):
                status[r] = 1
                th_out[k + 1 : k1] = np.nan
                w_out[k + 1 : k1] = np.nan
                z_out[k + 1 : k1] = np.nan
                break


@numba.njit(cache=True)
def _z_rk4(b, n, z, wa, wb, fa, fc, h):
    """One RK4 step of z from fraction fa to fc of a sample interval (velocity linear)."""
    hs = h * (fc - fa)
    w1 = wa + (wb - wa) * fa
    w2 = wa + (wb - wa) * (0.5 * (fa + fc))
    w3 = wa + (wb - wa) * fc
    k1z = term_rate(b, n, w1, z)
    k2z = term_rate(b, n, w2, z + 0.5 * hs * k1z)
    k3z = term_rate(b, n, w2, z + 0.5 * hs * k2z)
    k4z = term_rate(b, n, w3, z + hs * k3z)
    return z + hs / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)


@numba.njit(cache=True)
def z_segment(b, n, z, wa, wb, f0, f1, h, m):
    """RK4 for z over the fraction [f0, f1] of a sample interval, velocity linear in time.

    A sub-step in which z changes sign is redone in two parts split at the (secant) zero
    of z, since the ``|z|^n`` terms have a kink there.
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
def driven_batch_kernel(
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
    """Integrate z under an imposed velocity (linear between samples) and return torque."""
    for r in range(offsets.shape[0] - 1):
        c, b, n = coef[r], bb[r], nn[r]
        k0, k1 = offsets[r], offsets[r + 1]
        z = z0[r]
        z_out[k0] = z
        tq_out[k0] = term_torque(c, th_in[k0], w_in[k0], z, eps)
        status[r] = 0
        work[r] = 0
        for k in range(k0, k1 - 1):
            h = t[k + 1] - t[k]
            wa = w_in[k]
            wb = w_in[k + 1]
            wmax = max(abs(wa), abs(wb))
            m = n_sub(c, b, n, 1.0, 0.0, wmax, z, h, eps, False, 0.0, ratio, min_sub, max_sub[r])
            work[r] += 2 * m + 1
            if wa * wb < 0.0:
                # |theta_dot| has a kink where the velocity reverses: split the interval there
                f = wa / (wa - wb)
                z = z_segment(b, n, z, wa, wb, 0.0, f, h, m)
                z = z_segment(b, n, z, wa, wb, f, 1.0, h, m)
            else:
                z = z_segment(b, n, z, wa, wb, 0.0, 1.0, h, m)
            z_out[k + 1] = z
            tq_out[k + 1] = term_torque(c, th_in[k + 1], w_in[k + 1], z, eps)
            if not abs(z) < 1e12:
                status[r] = 1
                tq_out[k + 1 : k1] = np.nan
                z_out[k + 1 : k1] = np.nan
                break


@numba.njit(cache=True, nogil=True)
def torque_series(coef, rows, offsets, th_in, w_in, z, eps, out):
    """Torque of the entries ``rows`` (samples ``offsets[e]:offsets[e+1]``) for a given ``z``
    (the same arithmetic as :func:`driven_batch_kernel`)."""
    for j in range(rows.shape[0]):
        e = rows[j]
        c = coef[e]
        for k in range(offsets[e], offsets[e + 1]):
            out[k] = term_torque(c, th_in[k], w_in[k], z[k], eps)
