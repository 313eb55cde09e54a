"""The 95 % intervals and identifiability of a fit at its optimum: :func:`fit_intervals`.

At the optimum of an output-error fit the Jacobian gives the covariance ``s^2 (J^T J)^-1``
of the fit's vector (its free parameters, then each run's initial states), computed from
the eigen-decomposition of the column-scaled Gram matrix; a declared filter widens it by
the correlation of neighbouring residuals, an encoder's quantization makes it a sandwich
(:func:`~hystdisc.fitting.quantized.quantization_information_by_dwell`), and the errors of
a driven run's motion estimate are added
(:func:`~hystdisc.fitting.motion_error.motion_covariance`). It is propagated to every
reported parameter (free and derived) by differences of the parametrization's map. A
direction the data leave flat gives its parameters no finite interval; a parameter whose
interval is wider than its value, or that lies along a near-singular direction of the
scaled Jacobian, is reported as not identifiable, with a note in plain words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hystdisc.fitting.motion_error import motion_covariance
from hystdisc.fitting.parametrization import Parametrization
from hystdisc.fitting.quantized import quantization_information_by_dwell
from hystdisc.measurement.fitdata import FitData

Z95 = 1.959963984540054
#: A parameter whose scaled loading on a flat direction of the Gram matrix (a singular
#: value below 1e-10 of the largest) exceeds this has no finite interval.
FLAT_LOADING = 0.1


@dataclass
class Intervals:
    """What the data say of a fit's reported parameters (the fields of
    :class:`~hystdisc.fitting.output_error.OEFit` of the same names).

    Attributes
    ----------
    params : dict
        Every reported parameter (free and derived) by name.
    ci95, stderr : dict
        95 % interval and standard error of each.
    identifiable : dict
        False for a parameter whose interval is wider than its value, or that lies along
        a near-singular direction of the scaled Jacobian.
    notes : list of str
        The identifiability notes in plain words.
    """

    params: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    stderr: dict[str, float]
    identifiable: dict[str, bool]
    notes: list[str]


def fit_intervals(
    data: FitData,
    par: Parametrization,
    x: np.ndarray,
    nu: np.ndarray,
    res: np.ndarray,
    J: np.ndarray,
    gram: np.ndarray,
    row_offsets: np.ndarray,
    n_eff: float,
) -> Intervals:
    """The intervals and identifiability at a fit's optimum (see the module).

    Parameters
    ----------
    data : FitData
        The runs fitted.
    par : Parametrization
        What was fitted.
    x, nu : ndarray
        The free parameters and each run's initial states at the optimum.
    res : ndarray
        The residual there (masked rows, runs concatenated).
    J, gram : ndarray
        The residual's Jacobian there (all of the fit's vector) and ``J^T J``.
    row_offsets : ndarray
        Where each run's rows start (and the last one ends) in the residual.
    n_eff : float
        The independent residuals (:meth:`FitData.n_eff`; ``res.size`` without a
        declared filter).

    Returns
    -------
    Intervals
    """
    N, k, npar = res.size, J.shape[1], x.size
    rss = float(res @ res)
    s2 = rss / max(N - k, 1)
    # covariance with column scaling for conditioning: the small Gram matrix, column-scaled
    # (no scaled copy of the tall Jacobian)
    scale = np.sqrt(np.clip(np.diag(gram), 0.0, None))
    scale[scale == 0] = 1.0
    # eigen-decomposition of the small Gram matrix (much cheaper than an SVD of J)
    ev, V = np.linalg.eigh(gram / np.outer(scale, scale))
    order = np.argsort(-ev)
    S = np.sqrt(np.clip(ev[order], 0.0, None))
    Vt = V[:, order].T
    tol = S.max() * 1e-10 if S.size else 0.0
    Sinv = np.where(S > tol, 1.0 / np.where(S > tol, S, 1.0), 0.0)
    cov_s = (Vt.T * Sinv**2) @ Vt
    ainv = cov_s / np.outer(scale, scale)
    cov = s2 * ainv * (N / n_eff)  # a declared filter's correlation widens them
    if data.quantum > 0:  # quantization error: correlated, a sandwich
        sizes = [int(np.count_nonzero(m)) for m in data.mask]
        measured = np.concatenate([y[m] for y, m in zip(data.y, data.mask, strict=True)])
        B = quantization_information_by_dwell(J, measured + res, data.quantum, sizes)
        cov = s2 * ainv @ B @ ainv
    # errors in the imposed motion: the force noise's part plus the motion's
    motion = motion_covariance(data, par, x, nu, J, gram, ainv, row_offsets, cov, rss)
    if motion is not None:
        cov = cov * motion.force_scale(rss) + motion.cov
    covx = cov[:npar, :npar]
    # propagate to reported (incl. derived) parameters
    p = par.params(x)
    keys = list(p)
    G = np.zeros((len(keys), npar))
    for j in range(npar):
        h = 1e-7 * max(abs(x[j]), 1e-6)
        xj = x.copy()
        xj[j] += h
        pj = par.params(xj)
        G[:, j] = [(pj[kk] - p[kk]) / h for kk in keys]
    covp = G @ covx @ G.T
    se = np.sqrt(np.clip(np.diag(covp), 0, None))
    # the pseudo-inverse gives a direction the data leave flat (a singular value below
    # tol) no variance; its parameters are not bounded at all: infinite intervals
    flat = np.abs(Vt[S <= tol][:, :npar]) > FLAT_LOADING
    if flat.size:
        free = flat.any(axis=0)
        se[(np.abs(G[:, free]) > 0).any(axis=1)] = np.inf
    ci = {kk: (p[kk] - Z95 * s, p[kk] + Z95 * s) for kk, s in zip(keys, se, strict=True)}
    stderr = dict(zip(keys, map(float, se), strict=True))
    ident = {kk: bool(Z95 * stderr[kk] <= abs(p[kk])) for kk in keys}
    notes = _singular_notes(par, S, Vt, ident)
    for kk in keys:
        if not np.isfinite(stderr[kk]):
            notes.append(
                f"{kk} is not identifiable (the data leave a direction of the fit flat: "
                "no finite interval)"
            )
        elif not ident[kk]:
            notes.append(
                f"{kk} is not identifiable (95 % interval [{ci[kk][0]:.4g}, {ci[kk][1]:.4g}] "
                f"is wider than its value {p[kk]:.4g})"
            )
    return Intervals(p, ci, stderr, ident, notes)


def _singular_notes(
    par: Parametrization, S: np.ndarray, Vt: np.ndarray, ident: dict[str, bool]
) -> list[str]:
    """The note on a near-singular direction of the scaled Jacobian (singular values
    ``S``, right singular vectors ``Vt``), its main parameters marked in ``ident``."""
    npar = len(par.names)
    cond = S[0] / S[-1] if S.size and S[-1] > 0 else np.inf
    if not (cond > 1e6 and S.size):
        return []
    vec = Vt[-1][:npar]
    order = np.argsort(-np.abs(vec))[:3]
    combo = " ".join(
        f"{vec[j] * np.sign(vec[order[0]]):+.2f}*{par.names[j]}" for j in order if abs(vec[j]) > 0.1
    )
    for j in order:
        if abs(vec[j]) > 0.3 and par.names[j] in ident:
            ident[par.names[j]] = False
    return [
        f"near-singular direction (condition {cond:.1e}): {combo} (scaled) is not "
        "determined by the data"
    ]
