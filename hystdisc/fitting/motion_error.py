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

Data whose ``motion_errors`` are None (release or forced data, an exact motion, or
prepared with ``motion_errors=False``:
:func:`~hystdisc.measurement.prepare.prepare_data`, the pipeline's
``Options.motion_errors``) add nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hystdisc.measurement.motion import CHUNK_SAMPLES

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
    """

    cov: np.ndarray
    rss: float
    modes: int

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
    cov = np.zeros((k, k))
    rss = 0.0
    count = 0
    for r, est in enumerate(ests):
        if est is None:
            continue
        dth, dw = est.modes()
        if dth.shape[1] == 0:
            continue
        rows = slice(row_offsets[r], row_offsets[r + 1])
        Jr = J[rows]
        mask = data.mask[r]
        peak = float(np.max(np.abs(data.theta_dot[r]))) or 1.0
        size = np.max(np.abs(dw), axis=0)
        step = MODE_STEP * peak / np.where(size > 0, size, 1.0)
        per = max(1, CHUNK_SAMPLES // max(dth.shape[0], 1))
        for lo in range(0, dth.shape[1], per):
            cols = range(lo, min(lo + per, dth.shape[1]))
            sub = data.subset([r] * len(cols))
            sub.motion_errors = None
            sub.theta = [data.theta[r] + step[j] * dth[:, j] for j in cols]
            sub.theta_dot = [data.theta_dot[r] + step[j] * dw[:, j] for j in cols]
            bad: list = []
            preds = par.simulate(
                sub, [model] * len(cols), list(range(len(cols))), [nu[r]] * len(cols), bad
            )
            for j, pred, diverged in zip(cols, preds, bad, strict=True):
                if diverged:
                    continue
                dF = (pred - base[r])[mask] / step[j]
                dv = -ainv @ (Jr.T @ dF)
                cov += np.outer(dv, dv)
                rss += float(dF @ dF - dv @ gram @ dv)
                count += 1
    if count == 0:
        return None
    return MotionCovariance(cov, max(rss, 0.0), count)
