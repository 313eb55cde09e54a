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
>>> from hystdisc.simulation import simulate_release
>>> t = np.arange(0, 2.0, 1e-3)
>>> out = simulate_release(Model("dahl"), t, current=0.5, theta0=0.3)
>>> out.theta.shape, round(float(out.theta[0]), 3)
((2000,), 0.3)
>>> bool(abs(out.theta[-1]) < 0.3)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.models import SIGN_EPS, Model, TermModel
from hystdisc.models.compiled import N_BASE, base_coefficients
from hystdisc.simulation.batch import concat_runs, driven_batch, mech_batch


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
