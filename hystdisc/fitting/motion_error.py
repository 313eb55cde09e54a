"""What the errors of the imposed motion's estimate do to a driven fit's parameters.

Each driven run's motion estimate (:mod:`hystdisc.measurement.motion`) writes its random
error as independent unit-variance modes. :func:`motion_covariance` propagates them
through the fitted model: each mode is added to the run's motion (scaled up to
:data:`MODE_STEP` of the run's peak velocity, so that the integrator's own error does not
show, and the force change scaled back), the model is simulated on it (``par.simulate`` on
a copy of the data whose ``theta``/``theta_dot`` are perturbed: the compiled term kernels
and the error-controlled integrator alike), and the force change ``dF`` is mapped to the
parameters by the Gauss-Newton step ``dv = -(J^T J)^-1 J^T dF``. The covariance of the
parameters is then

``s_F^2 (J^T J)^-1 + sum_modes dv dv^T``,

with ``s_F^2`` the force noise: the residual variance less the part the motion errors put
into the residual (``|dF|^2 - dv^T J^T J dv`` per mode), which would otherwise be counted
twice.

Random draws (local fits' modes) are exchangeable: when the force noise's covariance is
given, :data:`PILOT_DRAWS` of each run go first, and when what they predict for all the
draws is :data:`NEGLIGIBLE` beside it, that prediction is the answer and the rest are not
simulated (:attr:`MotionCovariance.pilot`).

Data whose ``motion_errors`` are None (release or forced data, an exact motion, or
prepared with ``motion_errors=False``:
:func:`~hystdisc.measurement.prepare.prepare_data`, the pipeline's
``Options.motion_errors``) add nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hystdisc.measurement.motion import CHUNK_SAMPLES

#: Random draws of each run propagated first (:attr:`MotionEstimate.drawn
#: <hystdisc.measurement.motion.MotionEstimate.drawn>` modes; a harmonic series' exact
#: modes are always all propagated).
PILOT_DRAWS = 10
#: When what the pilot draws predict for the whole set adds less than this share to every
#: parameter's variance from the force noise (and to the residual), the other draws are
#: not propagated: the standard errors then move by less than half of it (0.05 %), far
#: inside the draws' own sampling error (:data:`~hystdisc.measurement.motion.MOTION_DRAWS`:
#: 14 %). On records whose motion is smooth (the UTFSM damper's, filtered) this was 34 % of
#: a discovery's CPU.
NEGLIGIBLE = 1e-3
#: Each mode is propagated as a perturbation of this share of the run's peak velocity (and
#: scaled back): far above the fixed-step kernels' error (about 1e-6 of the signal), far
#: below where the model's response to the motion bends.
MODE_STEP = 1e-3


@dataclass
class MotionCovariance:
    """What the motion estimates' errors do to a fit (:func:`motion_covariance`).

    Attributes
    ----------
    cov : ndarray
        Their covariance of the fit's vector (free parameters, then initial states).
    rss : float
        Their expected share of the residual sum of squares (the part the fit cannot
        absorb).
    modes : int
        Modes propagated.
    pilot : bool
        True when ``cov`` and ``rss`` are the pilot draws' prediction for all of them
        (it was :data:`NEGLIGIBLE` beside the force noise's).
    """

    cov: np.ndarray
    rss: float
    modes: int
    pilot: bool = False

    def force_scale(self, rss: float) -> float:
        """The factor that takes the residual variance to the force noise's alone."""
        return float(np.clip((rss - self.rss) / rss, 0.0, 1.0)) if rss > 0 else 1.0


def motion_covariance(
    data,
    par,
    x: np.ndarray,
    nu: np.ndarray,
    J: np.ndarray,
    gram: np.ndarray,
    ainv: np.ndarray,
    row_offsets: np.ndarray,
    force_cov: np.ndarray | None = None,
    rss: float | None = None,
) -> MotionCovariance | None:
    """The covariance the motion estimates' errors add to a fit's vector (see the module).

    Parameters
    ----------
    data : FitData
        The runs (their ``motion_errors``; None: nothing to add, the errors are not
        propagated).
    par : Parametrization
        The fitted structure.
    x, nu : ndarray
        The free parameters and each run's initial states at the optimum.
    J, gram, ainv : ndarray
        The residual's Jacobian there, ``J^T J`` and its (pseudo-)inverse.
    row_offsets : ndarray
        Where each run's rows start in the residual.
    force_cov : ndarray, optional
        The fit vector's covariance from the residual alone (before the motion's part is
        taken out of it), and ``rss`` the residual sum of squares: with both, random draws
        are propagated in a pilot first (see the module).
        Without them, every mode is.
    rss : float, optional
        See ``force_cov``.

    Returns
    -------
    MotionCovariance or None
        None when no run carries a motion estimate with noise.
    """
    ests = getattr(data, "motion_errors", None)
    if ests is None or not data.exp.motion_imposed:
        return None
    model = par.model(x)
    runs = list(range(data.n_runs))
    base = par.simulate(data, [model] * len(runs), runs, [nu[r] for r in runs])
    k = J.shape[1]
    todo = []  # (run, its modes, exchangeable draws)
    for r, est in enumerate(ests):
        if est is None:
            continue
        dth, dw = est.modes()
        if dth.shape[1] > 0:
            todo.append((r, dth, dw, bool(est.drawn)))

    # each run's propagated modes, in mode order: (dv, its part of the RSS)
    done: dict[int, list[tuple[np.ndarray, float]]] = {r: [] for r, *_ in todo}

    def propagate(r, dth, dw, cols) -> None:
        """Run ``r``'s modes ``cols`` through the model, into ``done``."""
        rows = slice(row_offsets[r], row_offsets[r + 1])
        Jr = J[rows]
        mask = data.mask[r]
        peak = float(np.max(np.abs(data.theta_dot[r]))) or 1.0
        size = np.max(np.abs(dw), axis=0)
        step = MODE_STEP * peak / np.where(size > 0, size, 1.0)
        per = max(1, CHUNK_SAMPLES // max(dth.shape[0], 1))
        for lo in range(cols.start, cols.stop, per):
            chunk = range(lo, min(lo + per, cols.stop))
            sub = data.subset([r] * len(chunk))
            sub.motion_errors = None
            sub.theta = [data.theta[r] + step[j] * dth[:, j] for j in chunk]
            sub.theta_dot = [data.theta_dot[r] + step[j] * dw[:, j] for j in chunk]
            bad: list = []
            preds = par.simulate(
                sub, [model] * len(chunk), list(range(len(chunk))), [nu[r]] * len(chunk), bad
            )
            for j, pred, diverged in zip(chunk, preds, bad, strict=True):
                if not diverged:
                    dF = (pred - base[r])[mask] / step[j]
                    dv = -ainv @ (Jr.T @ dF)
                    done[r].append((dv, float(dF @ dF - dv @ gram @ dv)))

    def total(scaled: bool) -> tuple[np.ndarray, float]:
        """The modes in ``done`` summed in run and mode order; ``scaled``: each run's
        draws scaled up to all of its modes (the pilot's prediction)."""
        cov, rss_m = np.zeros((k, k)), 0.0
        for r, dth, _, drawn in todo:
            w = dth.shape[1] / len(done[r]) if scaled and drawn and done[r] else 1.0
            for dv, q in done[r]:
                cov += w * np.outer(dv, dv)
                rss_m += w * q
        return cov, rss_m

    pilot = force_cov is not None and rss is not None and any(d for *_, d in todo)
    for r, dth, dw, drawn in todo:
        m = dth.shape[1]
        propagate(r, dth, dw, range(min(PILOT_DRAWS, m) if pilot and drawn else m))
    count = sum(map(len, done.values()))
    if pilot and count:
        est_cov, est_rss = total(scaled=True)
        fvar = np.diag(force_cov)
        if (
            np.all(np.isfinite(fvar))
            and np.all(np.abs(np.diag(est_cov)) <= NEGLIGIBLE * fvar)
            and abs(est_rss) <= NEGLIGIBLE * rss
        ):
            return MotionCovariance(est_cov, max(est_rss, 0.0), count, pilot=True)
        for r, dth, dw, drawn in todo:  # not decisive: every other draw
            if drawn and dth.shape[1] > PILOT_DRAWS:
                propagate(r, dth, dw, range(PILOT_DRAWS, dth.shape[1]))
    count = sum(map(len, done.values()))
    if count == 0:
        return None
    cov, rss_m = total(scaled=False)
    return MotionCovariance(cov, max(rss_m, 0.0), count)
