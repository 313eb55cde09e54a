"""Batched simulation of term models: many runs (and parameter sets) in one compiled call.

The low-level entry points of the output-error fit (:func:`mech_batch`,
:func:`driven_batch`, :func:`driven_shared`; with forward sensitivities
:func:`mech_sens_batch`, :func:`driven_sens_batch`) and of stage 1 (:func:`integrate_z_flat`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from hystdisc.errors import HystdiscError
from hystdisc.models import SIGN_EPS
from hystdisc.models.compiled import N_BASE
from hystdisc.simulation.kernels import (
    HOLDS,
    MAX_SUBSTEPS,
    MIN_SUBSTEPS,
    STEP_RATIO,
    driven_batch_kernel,
    mech_batch_kernel,
    torque_series,
)
from hystdisc.simulation.parallel import chunk_bounds, map_entries
from hystdisc.simulation.sensitivity import driven_sens_batch_kernel, mech_sens_batch_kernel


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


#: A batch is split across threads only into chunks of at least this many samples.
CHUNK_SAMPLES = 20_000


def _call_kernel(
    kernel, model, inputs, outputs, nruns, steps, work, per_entry=(), offsets_at=None
) -> np.ndarray:
    """Call a batch kernel: ``model`` (``coef, b, n``) and ``inputs``, the step controls
    ``steps`` (``eps, ratio, min_sub, max_sub``), ``outputs``, a fresh status and ``work``
    (zeros when None); returns the per-run status.

    ``per_entry`` names the positions in ``inputs`` of the per-entry arrays and
    ``offsets_at`` the position of the entries' sample offsets. A large batch is then cut into contiguous chunks of entries
    integrated side by side on threads (:func:`~hystdisc.simulation.parallel.map_entries`):
    every entry is integrated on its own, into its own samples of the outputs, so the
    result is the same to the last bit.
    """
    coef, b, n = model
    eps, ratio, min_sub, max_sub = steps
    coef = np.ascontiguousarray(coef, dtype=float)
    b = np.ascontiguousarray(b, dtype=float)
    n = np.ascontiguousarray(n, dtype=float)
    max_sub = _per_run(max_sub, nruns)
    status = np.zeros(nruns, dtype=np.int64)
    work = np.zeros(nruns, dtype=np.int64) if work is None else work
    at = offsets_at

    def call(a: int, z: int) -> None:
        ins = list(inputs)
        if at is not None:
            for i in per_entry:
                ins[i] = inputs[i][a:z]
            ins[at] = inputs[at][a : z + 1]
        kernel(coef[a:z], b[a:z], n[a:z], *ins, eps, ratio, min_sub, max_sub[a:z], *outputs,
               status[a:z], work[a:z])  # fmt: skip

    if at is None:
        call(0, nruns)
    else:
        bounds = chunk_bounds(np.asarray(inputs[at]), CHUNK_SAMPLES)
        map_entries(lambda ab: call(*ab), list(zip(bounds[:-1], bounds[1:], strict=True)))
    return status


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
    if hold != "cubic":
        du = np.zeros(1)
    elif du is None:
        du = input_slopes(t, u, offsets)
    J, theta0, theta_dot0, z0 = (np.asarray(a, dtype=float) for a in (J, theta0, theta_dot0, z0))
    th, w, z = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    status = _call_kernel(
        mech_batch_kernel,
        (coef, b, n),
        (J, t, u, du, offsets, theta0, theta_dot0, z0, HOLDS[hold]),
        (th, w, z),
        len(offsets) - 1,
        (eps, ratio, min_sub, max_sub),
        work,
        per_entry=(0, 5, 6, 7),  # J, theta0, theta_dot0, z0
        offsets_at=4,
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
    tq, z = np.empty_like(t), np.empty_like(t)
    status = _call_kernel(
        driven_batch_kernel,
        (coef, b, n),
        (t, theta, theta_dot, offsets, np.asarray(z0, dtype=float)),
        (tq, z),
        len(offsets) - 1,
        (eps, ratio, min_sub, max_sub),
        work,
        per_entry=(4,),  # z0
        offsets_at=3,
    )
    return tq, z, status


def _directions(act) -> np.ndarray:
    """The sensitivity directions as the kernels take them (see
    :mod:`hystdisc.simulation.sensitivity`)."""
    return np.ascontiguousarray(act, dtype=np.int64).reshape(-1)


def mech_sens_batch(
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
    act: np.ndarray,
    hold: str = "cubic",
    eps: float = SIGN_EPS,
    ratio: float = STEP_RATIO,
    min_sub: int = MIN_SUBSTEPS,
    max_sub: int | np.ndarray = MAX_SUBSTEPS,
    du: np.ndarray | None = None,
    work: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`mech_batch` with the forward sensitivities of ``theta``.

    ``act`` lists the directions wanted (term-vector entries and initial states, numbered as
    in :mod:`hystdisc.simulation.sensitivity`). Returns flat ``theta, theta_dot, z`` (the
    same to the last bit as :func:`mech_batch`'s), ``dtheta`` of shape
    ``(samples, len(act))`` and the per-run status.
    """
    if hold not in HOLDS:
        raise HystdiscError(f"unknown input hold '{hold}'; fix: use one of {', '.join(HOLDS)}")
    if hold != "cubic":
        du = np.zeros(1)
    elif du is None:
        du = input_slopes(t, u, offsets)
    act = _directions(act)
    J, theta0, theta_dot0, z0 = (np.asarray(a, dtype=float) for a in (J, theta0, theta_dot0, z0))
    th, w, z = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    sens = np.empty((t.size, act.size))
    status = _call_kernel(
        mech_sens_batch_kernel,
        (coef, b, n),
        (J, t, u, du, offsets, theta0, theta_dot0, z0, HOLDS[hold]),
        (act, th, w, z, sens),
        len(offsets) - 1,
        (eps, ratio, min_sub, max_sub),
        work,
        per_entry=(0, 5, 6, 7),  # J, theta0, theta_dot0, z0
        offsets_at=4,
    )
    return th, w, z, sens, status


def driven_sens_batch(
    coef: np.ndarray,
    b: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    offsets: np.ndarray,
    z0: np.ndarray,
    act: np.ndarray,
    eps: float = SIGN_EPS,
    ratio: float = STEP_RATIO,
    min_sub: int = MIN_SUBSTEPS,
    max_sub: int | np.ndarray = MAX_SUBSTEPS,
    work: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`driven_batch` with the forward sensitivities of the torque along the
    directions ``act`` (as :func:`mech_sens_batch`): flat ``torque, z``, ``dtorque`` of
    shape ``(samples, len(act))`` and the status."""
    act = _directions(act)
    tq, z = np.empty_like(t), np.empty_like(t)
    sens = np.empty((t.size, act.size))
    status = _call_kernel(
        driven_sens_batch_kernel,
        (coef, b, n),
        (t, theta, theta_dot, offsets, np.asarray(z0, dtype=float)),
        (act, tq, z, sens),
        len(offsets) - 1,
        (eps, ratio, min_sub, max_sub),
        work,
        per_entry=(4,),  # z0
        offsets_at=3,
    )
    return tq, z, sens, status


def driven_shared(
    coef: np.ndarray,
    b: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    offsets: np.ndarray,
    run: np.ndarray,
    **options: Any,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`driven_batch` from ``z = 0`` for entries that may share their hysteresis.

    Entries ``e`` on the same run (``run[e]``, the samples ``offsets[e]:offsets[e+1]``) with
    the same rate coefficients and exponent have the same ``z``: it is integrated once and
    only the torque is evaluated for the others (in a driven experiment the torque-side
    parameters do not act on ``z``, so most columns of a finite-difference Jacobian need no
    integration). The keyword ``options`` (``eps``, ``ratio``, ``min_sub``, ``max_sub``,
    ``work``) are as for :func:`driven_batch`, entries taking the place of runs. Returns
    exactly what :func:`driven_batch` returns; ``work`` receives the integration work, 0
    for the entries that reuse another's z.

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
    max_sub = _per_run(options.pop("max_sub", MAX_SUBSTEPS), ne)
    work = options.pop("work", None)
    first: dict[tuple, int] = {}
    owner = np.empty(ne, dtype=np.int64)
    for e in range(ne):
        key = (int(run[e]), float(n[e]), *map(float, b[e]))
        owner[e] = first.setdefault(key, e)
    lead = np.array(sorted(first.values()), dtype=np.int64)
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
        max_sub=max_sub[lead],
        work=work_l,
        **options,
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
    eps = options.get("eps", SIGN_EPS)
    torque_series(
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
