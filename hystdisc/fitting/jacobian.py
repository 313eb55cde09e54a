"""The output-error Jacobian: exact for a model in term form, else forward differences.

The compiled kernels integrate, with a run's output, its derivatives along the entries of
the run's term vector and its initial state (:func:`~hystdisc.fitting.simulate.simulate_sensitivities`,
:mod:`hystdisc.simulation.sensitivity`). The free parameters reach the term vectors
through the parametrization's algebra (the family's map, the current laws folded in per
run), whose derivative is taken here by central differences, no simulation; the chain
rule and the measurement chain (a fixed delay and a filter are linear in the output) give
the Jacobian's columns. A parameter that moves the channel delay adds the forward
difference of the measured output in the delay alone.

:func:`difference_jacobian` takes forward differences instead (any model: one simulation
per column, every column of a run in one batched call). :data:`JACOBIAN_MODES` are the
ways a fit may compute its Jacobian.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.fitting.parametrization import Parametrization
from hystdisc.fitting.simulate import kernel_vectors, simulate_sensitivities
from hystdisc.measurement.chain import measured_output
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import TermModel
from hystdisc.simulation.sensitivity import DIR_TH0, DIR_W0, DIR_Z0

#: Samples simulated per compiled call of a Jacobian (bounds its scratch memory).
JAC_CHUNK_SAMPLES = 2_000_000
#: Relative step of the central differences of the map from the free parameters to the
#: term vectors (algebra only, no simulation: most of it linear).
MAP_STEP = 1e-5
#: The sensitivity direction of each initial-state (nuisance) parameter.
START_DIRECTIONS = {"theta0": DIR_TH0, "theta_dot0": DIR_W0, "z0": DIR_Z0}

#: How a fit may compute its Jacobian (``jacobian_mode`` of
#: :class:`~hystdisc.fitting.output_error.OutputErrorFitter`;
#: by default the data's :attr:`~hystdisc.measurement.FitData.jacobian`, which the
#: pipeline sets from ``Options.jacobian``, ``"exact"`` unless told otherwise):
#:
#: - ``"exact"``: the forward sensitivities of the term kernels for a model in term form
#:   (2.3x faster per Jacobian than forward differences, tested against central
#:   differences) and of the error-controlled integrator for a state-space model with
#:   compiled partial derivatives (:mod:`~hystdisc.fitting.system_sensitivity`); forward
#:   differences for any other;
#: - ``"lockstep"``: as ``"exact"`` for a model in term form; every state-space model by
#:   lockstep internal differentiation (:mod:`~hystdisc.fitting.system_jacobian`, which
#:   also works at its looser tolerances,
#:   :data:`~hystdisc.fitting.system_jacobian.LOCKSTEP_INTEGRATION`);
#: - ``"terms"``: as ``"exact"`` for a model in term form; every state-space model by
#:   forward differences (the state-space sensitivities off: ``benchmarks/system_jacobian.py``
#:   measures them against this);
#: - ``"forward"``: forward differences for every model.
#:
#: Exact is the default since the families are compared again with every accepted effect
#: (:mod:`hystdisc.closing.reselect`): measured with ``benchmarks/check_unchanged.py``,
#: exact and forward give the same family, effects and parameters (to 0.01 standard
#: errors) on every ``data_synth/*.csv``. Before that, at 68d5560, the loop added
#: ``coulomb`` on ``effect_quadratic_damping.csv`` with the exact one: it trimmed the
#: misfit of the wrong Bouc-Wen form, which the table had selected and which now loses to
#: the true one.
JACOBIAN_MODES = ("exact", "lockstep", "terms", "forward")


def check_jacobian_mode(mode: str) -> str:
    """``mode`` when it is one of :data:`JACOBIAN_MODES`, else a one-line error.

    Examples
    --------
    >>> check_jacobian_mode("forward")
    'forward'
    """
    if mode not in JACOBIAN_MODES:
        raise HystdiscError(
            f"unknown Jacobian mode '{mode}'; fix: use {', '.join(JACOBIAN_MODES[:-1])} or "
            f"{JACOBIAN_MODES[-1]}"
        )
    return mode


def difference_steps(v: np.ndarray, rel_step: float) -> np.ndarray:
    """The forward-difference steps of the entries of ``v`` (relative, with a floor at
    ``1e-3`` of the largest entry)."""
    steps = rel_step * np.maximum(np.abs(v), 1e-3 * (np.abs(v).max() + 1e-12))
    return np.maximum(steps, 1e-10)


def inside_steps(x: np.ndarray, steps: np.ndarray, par: Parametrization) -> np.ndarray:
    """``steps`` signed and shortened so that ``x + step`` stays inside the bounds of
    ``par`` (forwards where there is room, else backwards; a step longer than the room on
    either side shrinks to half the larger room). A difference is never taken at a value
    the model would refuse as unphysical.

    Examples
    --------
    >>> from hystdisc.fitting import FamilySystemParametrization
    >>> par = FamilySystemParametrization("spencer", "driven", {"n": 9.999})
    >>> j = par.names.index("n")
    >>> x = par.x0
    >>> h = inside_steps(x, np.full(x.size, 5.0), par)
    >>> bool(par.lower[j] <= x[j] + h[j] <= par.upper[j])
    True
    """
    n = x.size
    up, down = par.upper - x, x - par.lower
    h = np.asarray(steps[:n], dtype=float)
    short = np.where(up >= down, 0.5 * up, -0.5 * down)
    return np.where(h <= up, h, np.where(h <= down, -h, short))


def map_stencil(x: np.ndarray, par: Parametrization) -> Iterator[tuple[int, np.ndarray, float]]:
    """The points and weights of the derivative of a parameter map at ``x``: for each free
    parameter ``j``, two points ``xj`` with weights ``w`` such that ``sum w (f(xj) - f(x))``
    is the derivative of ``f`` along ``j``. Central differences of relative step
    :data:`MAP_STEP` (floor 1e-3 of the largest entry); one-sided, second order, where a
    step would leave the bounds.

    Examples
    --------
    >>> from hystdisc.fitting import FamilyParametrization
    >>> par = FamilyParametrization("dahl", "release", {"k_x": 1.0})
    >>> x = par.x0
    >>> f = lambda v: float(v[0] ** 2)
    >>> d0 = sum(w * (f(xj) - f(x)) for j, xj, w in map_stencil(x, par) if j == 0)
    >>> bool(abs(d0 - 2 * x[0]) < 1e-8)
    True
    """
    scale = 1e-3 * (np.abs(x).max() + 1e-12)
    for j in range(x.size):
        h = MAP_STEP * max(abs(x[j]), scale)
        up, down = par.upper[j] - x[j], x[j] - par.lower[j]
        if 2 * h > max(up, down):
            # the floor (a share of the largest entry) can exceed a narrow box (an exponent
            # beside a large dashpot): the step shrinks to fit on the roomier side
            h = max(up, down) / 4
        if h <= up and h <= down:
            offs, weights = (h, -h), (0.5 / h, -0.5 / h)
        elif up >= down:
            offs, weights = (h, 2 * h), (2.0 / h, -0.5 / h)
        else:
            offs, weights = (-h, -2 * h), (-2.0 / h, 0.5 / h)
        for o, wgt in zip(offs, weights, strict=True):
            xj = x.copy()
            xj[j] += o
            yield j, xj, wgt


def map_derivative(
    data: FitData, par: Parametrization, x: np.ndarray, tm0: TermModel
) -> tuple[np.ndarray, np.ndarray]:
    """Derivative of every run's kernel vector with respect to the free parameters.

    Central differences of :func:`~hystdisc.fitting.simulate.kernel_vectors` of
    ``par.model(x)`` (one-sided, second order, where a step would leave the bounds); an
    entry the parameter does not move gets exactly 0.

    Returns
    -------
    D : ndarray
        Shape ``(runs, vector entries, parameters)``.
    delays : ndarray of bool
        The parameters that move the model's channel delay.
    plays : ndarray of bool
        The parameters that move the model's backlash (:attr:`TermModel.play`).
    """
    R = data.n_runs
    runs = list(range(R))
    V0 = kernel_vectors(data, [tm0] * R, runs)
    D = np.zeros((R, V0.shape[1], x.size))
    delays = np.zeros(x.size, dtype=bool)
    plays = np.zeros(x.size, dtype=bool)
    for j, xj, wgt in map_stencil(x, par):
        tm = par.model(xj)
        # the weights sum to 0 with x's own: differences from V0 keep unmoved entries 0
        D[:, :, j] += wgt * (kernel_vectors(data, [tm] * R, runs) - V0)
        delays[j] |= tm.delay != tm0.delay
        plays[j] |= tm.play != tm0.play
    return D, delays, plays


def run_groups(data: FitData, width: int) -> Iterator[list[int]]:
    """The runs in consecutive groups of about :data:`JAC_CHUNK_SAMPLES` samples times
    ``width`` (the simulated signals per sample), so the scratch memory of a Jacobian does
    not grow with the data."""
    group: list[int] = []
    size = 0
    for r in range(data.n_runs):
        group.append(r)
        size += data.t[r].size * width
        if size >= JAC_CHUNK_SAMPLES or r == data.n_runs - 1:
            yield group
            group, size = [], 0


def exact_jacobian(
    data: FitData,
    par: Parametrization,
    x: np.ndarray,
    nu: np.ndarray,
    state: bool,
    masks: list[np.ndarray],
    rel_step: float,
) -> np.ndarray | None:
    """The output-error Jacobian at the free parameters ``x`` and initial states ``nu``.

    Parameters
    ----------
    data : FitData
        The runs.
    par : Parametrization
        A parametrization of a term-form model (it simulates through
        :func:`~hystdisc.fitting.simulate.simulate_entries`).
    x : ndarray
        The free parameters.
    nu : ndarray
        Each run's initial-state parameters, shape ``(runs, nuisance)``.
    state : bool
        The model has a hysteretic state (its initial value may be a nuisance parameter).
    masks : list of ndarray
        Each run's samples that enter the residual.
    rel_step : float
        Relative forward-difference step of a parameter that moves the channel delay.

    Returns
    -------
    ndarray or None
        Rows: the masked samples, run after run; columns: ``x``, then each run's initial
        states. None when a run diverges (its sensitivities are then meaningless) or a
        sensitivity is so large that the Gram matrix would overflow.
    """
    R, k = data.n_runs, x.size
    nnu = nu.shape[1]
    tm0 = par.model(x)
    D, delays, plays = map_derivative(data, par, x, tm0)
    moving = [d for d in range(D.shape[1]) if np.any(D[:, d, :] != 0.0)]
    starts = [START_DIRECTIONS[p] for p in data.exp.initial_state(state)]
    act = np.array(moving + starts, dtype=np.int64)
    offsets = np.cumsum([0] + [int(m.sum()) for m in masks])
    Jm = np.zeros((offsets[-1], k + R * nnu))

    def delay_of(xj: np.ndarray) -> float:
        return par.model(xj).delay

    for group in run_groups(data, 1 + act.size):
        ys, sens, bad = simulate_sensitivities(data, tm0, group, [nu[q] for q in group], act)
        if any(bad):
            return None
        for q, y, S in zip(group, ys, sens, strict=True):
            cols = np.empty((y.size, k + nnu))
            cols[:, :k] = S[:, : len(moving)] @ D[q][moving]
            cols[:, k:] = S[:, len(moving) :]
            measured_columns(data, par, q, x, delay_of, y, cols, delays, rel_step,
                             lambda xj, q=q: par.simulate(data, [par.model(xj)], [q], [nu[q]])[0],
                             plays)  # fmt: skip
            rows = slice(offsets[q], offsets[q + 1])
            Jm[rows, :k] = cols[masks[q], :k]
            Jm[rows, k + q * nnu : k + (q + 1) * nnu] = cols[masks[q], k:]
    # a sensitivity can grow without bound where the output stays bounded (a stiff state
    # far from its fixed point): when J^T J would overflow, the caller takes forward
    # differences, which only see the output's own changes
    big = np.sqrt(np.finfo(float).max / max(Jm.shape[0], 1))
    return Jm if np.all(np.isfinite(Jm)) and np.abs(Jm).max(initial=0.0) < big else None


def measured_columns(
    data: FitData,
    par: Parametrization,
    r: int,
    x: np.ndarray,
    delay_of: Callable[[np.ndarray], float],
    y: np.ndarray,
    cols: np.ndarray,
    delays: np.ndarray,
    rel_step: float,
    resimulate: Callable[[np.ndarray], np.ndarray] | None = None,
    plays: np.ndarray | None = None,
) -> None:
    """Run ``r``'s derivative columns ``cols`` of the simulated output ``y`` through the
    measurement chain (in place), plus the delay's share of the ``delays`` columns and the
    backlash's of the ``plays`` columns.

    ``delay_of(x)`` is the channel delay at the free parameters ``x``; a parameter that
    moves it gets the forward difference of the measured output in the delay alone (the
    step rule of :func:`difference_jacobian`, its floor from the free parameters): the
    output delayed again, or, for a driven run (whose model sees the delay in its motion:
    :func:`~hystdisc.fitting.simulate.delayed_motion`), ``resimulate(xj)``, the run's
    measured output simulated at ``xj``. A parameter that moves a driven run's backlash
    (``plays``) gets differences of ``resimulate`` too, with a step of
    :data:`PLAY_STEP` of the run's motion amplitude.
    """
    t = data.t[r]
    window = data.run_filters()[r]
    step = data.run_steps()[r]
    driven = data.exp.motion_imposed
    tau = 0.0 if driven else delay_of(x)
    if tau != 0.0 or window > 1:
        for q in range(cols.shape[1]):
            cols[:, q] = measured_output(t, cols[:, q], tau, window, step)
    if driven and plays is not None and plays.any():
        if resimulate is None:
            raise ValueError("a driven run's backlash column needs resimulate")
        h = PLAY_STEP * 0.5 * float(np.ptp(data.theta[r]))
        for j in np.flatnonzero(plays & ~delays):
            cols[:, j] += _motion_column(x, j, par, h, resimulate)
    if not delays.any():
        return
    y0 = measured_output(t, y, tau, window, step)
    steps = inside_steps(x, difference_steps(x, rel_step), par)
    for j in np.flatnonzero(delays):
        if driven:  # central differences of runs simulated on the shifted motion
            if resimulate is None:
                raise ValueError("a driven run's delay column needs resimulate")
            h = DELAY_STEP * float(np.median(np.diff(t)))
            cols[:, j] += _motion_column(x, j, par, h, resimulate)
            continue
        h = steps[j]
        xj = x.copy()
        xj[j] += h
        yj = measured_output(t, y, delay_of(xj), window, step)
        cols[:, j] += (yj - y0) / h


#: The step of a driven run's delay column, as a share of its sample interval: the motion
#: is shifted by linear interpolation, smooth in the delay far below a sample, and the
#: integrator's tolerance needs a step well above its own error.
DELAY_STEP = 1e-3

#: The step of a driven run's backlash column, as a share of the run's motion amplitude
#: (the play's output is piecewise linear in its width, like the shifted motion in the
#: delay).
PLAY_STEP = 1e-4


def _motion_column(
    x: np.ndarray, j: int, par: Parametrization, h: float, resimulate: Callable
) -> np.ndarray:
    """The derivative of a driven run's measured output along parameter ``j`` (which
    moves the motion the model is driven by: its channel delay or backlash) by central
    differences of ``resimulate`` with step ``h`` (one-sided at a bound)."""
    up, down = x.copy(), x.copy()
    up[j] += h
    down[j] -= h
    if up[j] > par.upper[j]:
        up = x.copy()
    if down[j] < par.lower[j]:
        down = x.copy()
    return (resimulate(up) - resimulate(down)) / (up[j] - down[j])


def difference_jacobian(
    data: FitData,
    par: Parametrization,
    x: np.ndarray,
    nu: np.ndarray,
    masks: list[np.ndarray],
    rel_step: float,
    base: list[np.ndarray] | None = None,
) -> np.ndarray:
    """Forward-difference output-error Jacobian (arguments and result as
    :func:`exact_jacobian`; a step that would pass an upper bound is taken backwards).

    Every column of a run is simulated in one call with that run's base (a run's initial
    states touch only that run); the runs are simulated in groups of about
    :data:`JAC_CHUNK_SAMPLES` samples, so the memory beyond the Jacobian itself does not
    grow with the data. ``base``, when given, is every run's simulated output at ``x``
    and ``nu`` (``par.simulate`` of them, e.g. the residual just evaluated there): the
    base is then not simulated again. Each entry of a batched call is integrated on its
    own, so the result is the same to the last bit.
    """
    R, k, nnu = data.n_runs, x.size, nu.shape[1]
    steps = difference_steps(np.concatenate([x, nu.ravel()]), rel_step)
    steps[:k] = inside_steps(x, steps, par)
    tm0 = par.model(x)
    tms = []
    for j in range(k):
        xj = x.copy()
        xj[j] += steps[j]
        tms.append(par.model(xj))
    offsets = np.cumsum([0] + [int(m.sum()) for m in masks])
    Jm = np.zeros((offsets[-1], k + R * nnu))
    for group in run_groups(data, 1 + k + nnu):
        models, runs, nuis, cols = [], [], [], []
        base_of = {q: base[q] for q in group} if base is not None else {}
        for q in group:
            entries = [] if q in base_of else [(tm0, nu[q], -1)]
            entries += [(tms[j], nu[q], j) for j in range(k)]
            for i in range(nnu):
                nq = nu[q].copy()
                nq[i] += steps[k + q * nnu + i]
                entries.append((tm0, nq, k + q * nnu + i))
            for tm, nq, j in entries:
                models.append(tm)
                runs.append(q)
                nuis.append(nq)
                cols.append(j)
        preds = par.simulate(data, models, runs, nuis)
        for e, (q, j) in enumerate(zip(runs, cols, strict=True)):
            if j < 0:
                base_of[q] = preds[e]
                continue
            h = steps[j]
            Jm[offsets[q] : offsets[q + 1], j] = (preds[e] - base_of[q])[masks[q]] / h
    return Jm
