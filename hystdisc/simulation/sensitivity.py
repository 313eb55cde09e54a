"""Forward sensitivities of the term kernels: a run's output and its derivatives in one pass.

The kernels here integrate exactly what the kernels of
:func:`~hystdisc.simulation.batch.mech_batch` and
:func:`~hystdisc.simulation.batch.driven_batch` integrate (the same arithmetic, so the
same output to the last bit) together with the derivative of the discrete scheme:
every RK4 stage differentiated by hand in forward mode, with the sub-step count of each
sample interval held at the value the plain kernel chooses (it is not differentiated).
The result is the exact derivative of the simulated output with respect to the run's
*directions*: the entries of its term vector and its initial state, numbered

========================  =====================================================
``0 .. 11``               base coefficients ``c`` (:data:`~hystdisc.models.compiled.N_BASE`)
``12 .. 16``              hysteresis coefficients ``b``
``17``, ``18``            the exponent ``n``, the inertia ``J``
``19``, ``20``, ``21``    the initial ``theta``, ``theta_dot`` and ``z``
========================  =====================================================

Only the directions listed in ``act`` are propagated, so the cost grows with the number
wanted (each adds a few multiplications per stage to one simulation's transcendental
functions).
"""

from __future__ import annotations

import numba
import numpy as np

from hystdisc.models.compiled import (
    N_BASE,
    rate_grad,
    term_rate,
    term_torque,
    torque_grad,
)
from hystdisc.simulation.kernels import interpolate_input, mech_rate, n_sub, z_segment

#: First direction of the hysteresis coefficients, then the exponent, the inertia and the
#: initial states (see the module docstring).
DIR_B = N_BASE
DIR_N = N_BASE + 5
DIR_J = N_BASE + 6
DIR_TH0 = N_BASE + 7
DIR_W0 = N_BASE + 8
DIR_Z0 = N_BASE + 9
#: Number of directions.
N_DIR = N_BASE + 10


@numba.njit(cache=True)
def _needs(act):
    """Flags of the directions in ``act``."""
    need = np.zeros(N_DIR, dtype=np.bool_)
    for j in range(act.shape[0]):
        need[act[j]] = True
    return need


@numba.njit(cache=True)
def _stage_sens(c, b, n, J, u, th, w, z, eps, kw, act, need, needr, gT, gR, sc, src, dst):
    """Derivative of one mechanical stage ``(theta', theta'', z')`` at ``(th, w, z)`` along
    each direction: the state's derivatives are rows ``src .. src + 2`` of ``sc``, the
    stage's go to rows ``dst .. dst + 2``; ``kw`` is the stage's ``theta''``; ``needr``
    flags the rate's directions. (Rows, not row views: a view per stage costs more than
    the stage.)"""
    tth, tw, tz = torque_grad(c, th, w, z, eps, need, gT)
    rw, rz = rate_grad(b, n, w, z, needr, gR)
    for j in range(act.shape[0]):
        d = act[j]
        xw = sc[src + 1, j]
        xz = sc[src + 2, j]
        a = -(tth * sc[src, j] + tw * xw + tz * xz)
        r = rw * xw + rz * xz
        if d < N_BASE:
            a -= gT[d]
        elif d < DIR_J:
            r += gR[d - DIR_B]
        elif d == DIR_J:
            a -= kw
        sc[dst, j] = xw
        sc[dst + 1, j] = a / J
        sc[dst + 2, j] = r


@numba.njit(cache=True, inline="always")
def _stage_state(sc, frac, dst):
    """Rows 3-5 of ``sc``: the state's derivatives (rows 0-2) plus ``frac`` times the
    stage derivatives in rows ``dst .. dst + 2``."""
    for i in range(3):
        for j in range(sc.shape[1]):
            sc[3 + i, j] = sc[i, j] + frac * sc[dst + i, j]


@numba.njit(cache=True, nogil=True)
def mech_sens_batch_kernel(
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
    act,
    th_out,
    w_out,
    z_out,
    sens,
    status,
    work,
):
    """:func:`~hystdisc.simulation.kernels.mech_batch_kernel` with the derivative of ``theta``
    along the directions ``act``: ``sens[k, j]`` at sample ``k``, direction ``act[j]``."""
    na = act.shape[0]
    need = _needs(act)
    needr = need[DIR_B:DIR_J].copy()
    gT = np.zeros(N_BASE)
    gR = np.zeros(6)
    # rows: the state's derivatives (0-2: theta, theta_dot, z), a stage's state (3-5), the
    # four stages' derivatives (6-8, 9-11, 12-14, 15-17)
    sc = np.zeros((18, na))
    for r in range(offsets.shape[0] - 1):
        c, b, n, J = coef[r], bb[r], nn[r], JJ[r]
        k0, k1 = offsets[r], offsets[r + 1]
        th, w, z = th0[r], w0[r], z0[r]
        for j in range(na):
            sc[0, j] = 1.0 if act[j] == DIR_TH0 else 0.0
            sc[1, j] = 1.0 if act[j] == DIR_W0 else 0.0
            sc[2, j] = 1.0 if act[j] == DIR_Z0 else 0.0
            sens[k0, j] = sc[0, j]
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
                # the plain kernel's stages, operation for operation
                k1t, k1w, k1z = mech_rate(c, b, n, J, u1, th, w, z, eps)
                th2, w2, z2 = th + 0.5 * hs * k1t, w + 0.5 * hs * k1w, z + 0.5 * hs * k1z
                k2t, k2w, k2z = mech_rate(c, b, n, J, u2, th2, w2, z2, eps)
                th3, w3, z3 = th + 0.5 * hs * k2t, w + 0.5 * hs * k2w, z + 0.5 * hs * k2z
                k3t, k3w, k3z = mech_rate(c, b, n, J, u2, th3, w3, z3, eps)
                th4, w4, z4 = th + hs * k3t, w + hs * k3w, z + hs * k3z
                k4t, k4w, k4z = mech_rate(c, b, n, J, u3, th4, w4, z4, eps)
                # and their derivatives
                _stage_sens(c, b, n, J, u1, th, w, z, eps, k1w, act, need, needr, gT, gR, sc, 0, 6)
                _stage_state(sc, 0.5 * hs, 6)
                _stage_sens(
                    c, b, n, J, u2, th2, w2, z2, eps, k2w, act, need, needr, gT, gR, sc, 3, 9
                )
                _stage_state(sc, 0.5 * hs, 9)
                _stage_sens(
                    c, b, n, J, u2, th3, w3, z3, eps, k3w, act, need, needr, gT, gR, sc, 3, 12
                )
                _stage_state(sc, hs, 12)
                _stage_sens(
                    c, b, n, J, u3, th4, w4, z4, eps, k4w, act, need, needr, gT, gR, sc, 3, 15
                )
                th += hs / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
                w += hs / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
                z += hs / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)
                for i in range(3):
                    for j in range(na):
                        sc[i, j] += (
                            hs
                            / 6.0
                            * (
                                sc[6 + i, j]
                                + 2.0 * sc[9 + i, j]
                                + 2.0 * sc[12 + i, j]
                                + sc[15 + i, j]
                            )
                        )
            th_out[k + 1] = th
            w_out[k + 1] = w
            z_out[k + 1] = z
            for j in range(na):
                sens[k + 1, j] = sc[0, j]
            if not (abs(th) < 1e8 and abs(w) < 1e10 and abs(z) < 1e12):
                status[r] = 1
                th_out[k + 1 : k1] = np.nan
                w_out[k + 1 : k1] = np.nan
                z_out[k + 1 : k1] = np.nan
                sens[k + 1 : k1] = np.nan
                break


@numba.njit(cache=True)
def _z_rk4_sens(b, n, z, wa, wb, fa, fc, h, cols, act, sc, src, moving, ra, rc, dst, need, g):
    """:func:`~hystdisc.simulation.kernels._z_rk4` with the derivative of the new ``z``
    along the directions ``act[cols]``: the start's derivatives are row ``src`` of ``sc``,
    the result's go to row ``dst``; ``moving``: the ends ``fa``, ``fc`` move too (their
    derivatives in rows ``ra``, ``rc``). ``g``: four scratch arrays of 6."""
    hs = h * (fc - fa)
    w1 = wa + (wb - wa) * fa
    w2 = wa + (wb - wa) * (0.5 * (fa + fc))
    w3 = wa + (wb - wa) * fc
    k1z = term_rate(b, n, w1, z)
    z2 = z + 0.5 * hs * k1z
    k2z = term_rate(b, n, w2, z2)
    z3 = z + 0.5 * hs * k2z
    k3z = term_rate(b, n, w2, z3)
    z4 = z + hs * k3z
    k4z = term_rate(b, n, w3, z4)
    ksum = k1z + 2.0 * k2z + 2.0 * k3z + k4z
    zn = z + hs / 6.0 * ksum
    if cols.shape[0] == 0:
        return zn
    g1, g2, g3, g4 = g
    rw1, rz1 = rate_grad(b, n, w1, z, need, g1)
    rw2, rz2 = rate_grad(b, n, w2, z2, need, g2)
    rw3, rz3 = rate_grad(b, n, w2, z3, need, g3)
    rw4, rz4 = rate_grad(b, n, w3, z4, need, g4)
    for jj in range(cols.shape[0]):
        j = cols[jj]
        d = act[j] - DIR_B
        p1 = p2 = p3 = p4 = 0.0
        if 0 <= d < 6:
            p1, p2, p3, p4 = g1[d], g2[d], g3[d], g4[d]
        dh = 0.0
        if moving:
            dfa, dfc = sc[ra, j], sc[rc, j]
            dh = h * (dfc - dfa)
            dw2 = (wb - wa) * (0.5 * (dfa + dfc))
            p1 += rw1 * (wb - wa) * dfa
            p2 += rw2 * dw2
            p3 += rw3 * dw2
            p4 += rw4 * (wb - wa) * dfc
        dz = sc[src, j]
        d1 = rz1 * dz + p1
        d2 = rz2 * (dz + 0.5 * (dh * k1z + hs * d1)) + p2
        d3 = rz3 * (dz + 0.5 * (dh * k2z + hs * d2)) + p3
        d4 = rz4 * (dz + dh * k3z + hs * d3) + p4
        sc[dst, j] = dz + dh / 6.0 * ksum + hs / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
    return zn


@numba.njit(cache=True)
def _z_segment_sens(b, n, z, wa, wb, f0, f1, h, m, cols, act, sc, need, g):
    """:func:`~hystdisc.simulation.kernels.z_segment` with the derivatives of z along
    ``act[cols]``, row 4 of the scratch ``sc`` (updated in place; rows 0-2 are work space,
    row 3 zeros); ``g``: four scratch arrays of 6.

    Where a sub-step is split at the secant zero of z, the split point moves with the
    parameters: its derivative enters the two parts."""
    kinked = b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0
    for s in range(m):
        fa = f0 + (f1 - f0) * (s / m)
        fc = f0 + (f1 - f0) * ((s + 1.0) / m)
        zn = _z_rk4_sens(b, n, z, wa, wb, fa, fc, h, cols, act, sc, 4, False, 3, 3, 0, need, g)
        if kinked and z * zn < 0.0:
            fm = fa + (fc - fa) * (z / (z - zn))
            for jj in range(cols.shape[0]):
                j = cols[jj]
                sc[2, j] = (fc - fa) * (z * sc[0, j] - zn * sc[4, j]) / ((z - zn) * (z - zn))
            z1 = _z_rk4_sens(b, n, z, wa, wb, fa, fm, h, cols, act, sc, 4, True, 3, 2, 1, need, g)
            zn = _z_rk4_sens(b, n, z1, wa, wb, fm, fc, h, cols, act, sc, 1, True, 2, 3, 0, need, g)
        z = zn
        for jj in range(cols.shape[0]):
            sc[4, cols[jj]] = sc[0, cols[jj]]
    return z


@numba.njit(cache=True)
def _torque_sens(c, th, w, z, eps, act, need, gT, sc, sens, k):
    """Derivative of the torque at an imposed motion along each direction (z's: row 4 of
    ``sc``), written to ``sens[k]``."""
    _, _, tz = torque_grad(c, th, w, z, eps, need, gT)
    for j in range(act.shape[0]):
        d = act[j]
        sens[k, j] = tz * sc[4, j] + (gT[d] if d < N_BASE else 0.0)


@numba.njit(cache=True, nogil=True)
def driven_sens_batch_kernel(
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
    act,
    tq_out,
    z_out,
    sens,
    status,
    work,
):
    """:func:`~hystdisc.simulation.kernels.driven_batch_kernel` with the derivative of the torque
    along the directions ``act``: ``sens[k, j]`` at sample ``k``, direction ``act[j]``.

    Only the rate's directions (``b``, ``n``, the initial z) move z; the torque's
    coefficients act on the output directly."""
    na = act.shape[0]
    need = _needs(act)
    gT = np.zeros(N_BASE)
    needr = need[DIR_B:DIR_J].copy()
    g = (np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6))
    # rows: work space (0-2), zeros (3), the derivatives of z (4)
    sc = np.zeros((5, na))
    nz = 0
    for j in range(na):
        if DIR_B <= act[j] < DIR_J or act[j] == DIR_Z0:
            nz += 1
    cols = np.empty(nz, dtype=np.int64)
    nz = 0
    for j in range(na):
        if DIR_B <= act[j] < DIR_J or act[j] == DIR_Z0:
            cols[nz] = j
            nz += 1
    for r in range(offsets.shape[0] - 1):
        c, b, n = coef[r], bb[r], nn[r]
        k0, k1 = offsets[r], offsets[r + 1]
        z = z0[r]
        for j in range(na):
            sc[4, j] = 1.0 if act[j] == DIR_Z0 else 0.0
        z_out[k0] = z
        tq_out[k0] = term_torque(c, th_in[k0], w_in[k0], z, eps)
        _torque_sens(c, th_in[k0], w_in[k0], z, eps, act, need, gT, sc, sens, k0)
        status[r] = 0
        work[r] = 0
        for k in range(k0, k1 - 1):
            h = t[k + 1] - t[k]
            wa = w_in[k]
            wb = w_in[k + 1]
            wmax = max(abs(wa), abs(wb))
            m = n_sub(c, b, n, 1.0, 0.0, wmax, z, h, eps, False, 0.0, ratio, min_sub, max_sub[r])
            work[r] += 2 * m + 1
            if cols.shape[0] == 0:  # nothing moves z: the plain integration
                if wa * wb < 0.0:
                    f = wa / (wa - wb)
                    z = z_segment(b, n, z, wa, wb, 0.0, f, h, m)
                    z = z_segment(b, n, z, wa, wb, f, 1.0, h, m)
                else:
                    z = z_segment(b, n, z, wa, wb, 0.0, 1.0, h, m)
            elif wa * wb < 0.0:
                # |theta_dot| has a kink where the velocity reverses: split the interval there
                f = wa / (wa - wb)
                z = _z_segment_sens(b, n, z, wa, wb, 0.0, f, h, m, cols, act, sc, needr, g)
                z = _z_segment_sens(b, n, z, wa, wb, f, 1.0, h, m, cols, act, sc, needr, g)
            else:
                z = _z_segment_sens(b, n, z, wa, wb, 0.0, 1.0, h, m, cols, act, sc, needr, g)
            z_out[k + 1] = z
            tq_out[k + 1] = term_torque(c, th_in[k + 1], w_in[k + 1], z, eps)
            _torque_sens(c, th_in[k + 1], w_in[k + 1], z, eps, act, need, gT, sc, sens, k + 1)
            if not abs(z) < 1e12:
                status[r] = 1
                tq_out[k + 1 : k1] = np.nan
                z_out[k + 1 : k1] = np.nan
                sens[k + 1 : k1] = np.nan
                break
