"""A bounded Levenberg-Marquardt on the normal equations (the optimizer of stage 2).

The output-error problems have many more residuals than parameters, so the small Gram
matrix ``J^T J`` is far cheaper to factor than the tall Jacobian that scipy's
trust-region solvers decompose; the fitter also knows the Gram matrix's block structure
(each run's initial state touches only that run's rows).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hystdisc.errors import HystdiscError

#: The predicted-gain stop of the Levenberg-Marquardt applies while the damping is below
#: this (a heavily damped step predicts little because it is short, not because the
#: optimum is reached).
PRED_MAX_LAMBDA = 1e-2


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    max_iter: int = 60,
    tol: float = 1e-6,
    return_jac: bool = False,
    jac0: np.ndarray | None = None,
    r0: np.ndarray | None = None,
    gram: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple:
    """Bounded Levenberg-Marquardt on the normal equations (N >> p, so the p x p Gram matrix
    is far cheaper than the SVD of the tall Jacobian that scipy's trust-region solvers use).

    Steps are clipped to the bounds, and variables held at a bound by the gradient are left
    out of the step; Marquardt's diagonal scaling makes it scale-invariant. It stops when a
    step lowers the cost by less than ``tol`` (relative), or before taking a step that the
    local (damped Gauss-Newton) model predicts to do so, which saves the Jacobian
    evaluation such a step would be followed by.

    Parameters
    ----------
    fun : callable
        Residual vector of the parameters.
    jac : callable
        Its Jacobian (rows: residuals, columns: parameters).
    x0 : ndarray
        Start (clipped to the bounds).
    lower, upper : ndarray
        Bounds (``-inf``/``inf`` for none).
    max_iter : int
        Jacobian evaluations at most.
    tol : float
        Relative cost change at which it stops.
    return_jac : bool
        Also return the Jacobian at the solution.
    jac0 : ndarray, optional
        An approximation of the Jacobian at ``x0`` (e.g. interpolated from a coarser
        grid), used for the first step instead of evaluating ``jac``; every later step
        and the convergence test after it use ``jac``.
    r0 : ndarray, optional
        ``fun(x0)``, when already known.
    gram : callable, optional
        ``gram(J)`` computes ``J.T @ J`` (e.g. from a known block structure).

    Returns
    -------
    x : ndarray
        The solution.
    njev : int
        Jacobian evaluations.
    converged : bool
        Whether a stopping test was met (else ``max_iter`` ran out).
    J : ndarray or None
        With ``return_jac`` only: the Jacobian at ``x`` when it was evaluated there.

    Raises
    ------
    HystdiscError
        When the residual is not finite at the start.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 50)
    >>> fun = lambda p: p[0] * np.exp(-p[1] * t) - 2.0 * np.exp(-3.0 * t)
    >>> jac = lambda p: np.column_stack([np.exp(-p[1] * t), -p[0] * t * np.exp(-p[1] * t)])
    >>> x, n, ok = levenberg_marquardt(fun, jac, np.array([1.0, 1.0]), np.zeros(2), np.full(2, 9.0))
    >>> np.round(x, 6).tolist(), ok
    ([2.0, 3.0], True)
    """
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    r = r0 if r0 is not None and np.array_equal(x, x0) else fun(x)
    if not np.all(np.isfinite(r)):
        raise HystdiscError(
            "the output-error fit cannot start: the model diverges at its starting parameters; "
            "fix: check the data for motion and the starting parameters"
        )
    cost = float(r @ r)
    lam = 1e-3
    njev = 0
    converged = False
    J_at_x = None
    for it in range(max_iter):
        if it == 0 and jac0 is not None:
            J = jac0
            J_at_x = None  # an approximation: never handed out as the Jacobian at x
        else:
            J = jac(x)
            njev += 1
            J_at_x = J
        A = J.T @ J if gram is None else gram(J)
        g = J.T @ r
        d = np.diag(A).copy()
        d[d <= 0] = 1.0
        # variables held at a bound by the gradient are left out of the step (projection)
        free = ~(((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0)))
        if not free.any():
            converged = True
            break
        Af = A[np.ix_(free, free)]
        gf = g[free]
        if lam <= PRED_MAX_LAMBDA:
            # the step the model predicts to gain less than tol is not worth a Jacobian
            try:
                sf = np.linalg.solve(Af + lam * np.diag(d[free]), gf)
            except np.linalg.LinAlgError:
                sf = None
            if sf is not None and np.all(np.isfinite(sf)):
                pred = float(2.0 * gf @ sf - sf @ Af @ sf)
                if pred < tol * cost:
                    converged = True
                    break
        improved = False
        while lam < 1e12:
            step = np.zeros_like(x)
            try:
                step[free] = -np.linalg.solve(Af + lam * np.diag(d[free]), gf)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = np.clip(x + step, lower, upper)
            rn = fun(xn)
            cn = float(rn @ rn) if np.all(np.isfinite(rn)) else np.inf
            if cn < cost:
                rel = (cost - cn) / max(cost, 1e-300)
                small = np.all(np.abs(xn - x) <= 1e-9 * (np.abs(x) + 1e-9))
                x, r, cost = xn, rn, cn
                J_at_x = None
                lam = max(lam / 5.0, 1e-12)
                improved = True
                if rel < tol or small:
                    converged = True
                break
            lam *= 8.0
        if not improved:
            converged = True  # no downhill step left: a (local) minimum
            break
        if converged:
            break
    if return_jac:
        return x, njev, converged, J_at_x
    return x, njev, converged
