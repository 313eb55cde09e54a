"""Stage 2: output-error refinement of a structure over all runs jointly.

Every run is simulated with the candidate model (release from its own initial angle,
estimated as a nuisance parameter; forced from its input; driven from its imposed motion)
and the measured signal is fitted by the package's own bounded Levenberg-Marquardt
(:func:`~hystdisc.fitting.lm.levenberg_marquardt`, on the normal equations). The Jacobian
of a model in term form is exact: the compiled kernels integrate the forward sensitivities
of the output with respect to each run's term vector and initial state in the same pass as
the output (:func:`~hystdisc.fitting.simulate.simulate_sensitivities`), and the chain rule
through the (cheap) map from the free parameters to the term vectors gives the columns. A
state-space model with compiled partial derivatives (Spencer's family) gets its exact
Jacobian the same way from the error-controlled integrator
(:mod:`~hystdisc.fitting.system_sensitivity`). Any other state-space model's Jacobian, a
diverged simulation's and, on request (``jacobian_mode``, one of
:data:`~hystdisc.fitting.jacobian.JACOBIAN_MODES`), any model's are forward differences,
all columns in one batched simulation call (a run's nuisance parameters only touch that
run, so only that run is re-simulated).

At the optimum the Jacobian gives 95 % intervals and an identifiability check
(:func:`~hystdisc.fitting.intervals.fit_intervals`), BIC, and held-out errors: each fold
(one test condition, or one run when all runs share one) is left out, the fit without it
is estimated by a Gauss-Newton step from the joint optimum and a few Levenberg-Marquardt
iterations on the other runs, and the fold's runs are simulated with it
(:mod:`~hystdisc.fitting.heldout`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from hystdisc.errors import HystdiscError
from hystdisc.fitting.heldout import HeldOutFolds
from hystdisc.fitting.intervals import fit_intervals
from hystdisc.fitting.jacobian import check_jacobian_mode, difference_jacobian, exact_jacobian
from hystdisc.fitting.lm import levenberg_marquardt
from hystdisc.fitting.parametrization import Parametrization, SystemParametrization
from hystdisc.fitting.system_jacobian import system_jacobian
from hystdisc.fitting.system_sensitivity import exact_applies, system_exact_jacobian
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import TermModel
from hystdisc.stats import bic as _bic

#: Levenberg-Marquardt iterations on the full data after the bulk fit, at least.
POLISH_MIN_ITER = 2
#: The bulk fit is used when the full data take this many times its integration work.
BULK_MIN_GAIN = 2.0
#: Relative cost change at which the bulk fit hands over to the full data.
BULK_TOL = 1e-5


@dataclass
class OEFit:
    """Result of an output-error fit.

    Attributes
    ----------
    par : Parametrization
        What was fitted (free parameters <-> term model).
    x : ndarray
        The free parameters at the optimum.
    nuisance : ndarray
        Each run's initial-state parameters, shape ``(n_runs, n_nuisance)``.
    params : dict
        Every reported parameter (free and derived) by name.
    ci95, stderr : dict
        95 % interval and standard error of each reported parameter.
    identifiable : dict
        False for a parameter whose interval is wider than its value, or that lies along
        a near-singular direction of the scaled Jacobian.
    notes : list of str
        Identifiability and held-out notes in plain words.
    rms, rss : float
        Residual RMS and sum of squares over the ``n_obs`` samples that enter the fit.
    n_obs, n_params : int
        Residuals, and free parameters including the initial states.
    bic : float
        :func:`hystdisc.stats.bic` of the fit.
    predictions, residuals : list of ndarray
        Each run's simulated output and its residual (all samples).
    heldout_rms : float or None
        Leave-one-run-out RMS (None when not computed or a held-out run diverged).
    heldout_predictions : list of ndarray or None
        The held-out predictions.
    nfev : int
        Jacobian evaluations spent.
    success : bool
        The Levenberg-Marquardt converged.
    diverged : list of str
        The runs whose simulation diverged (or could not be resolved) at the optimum:
        such a fit is no model of those runs (its residual there holds a placeholder).
    starts : dict of str to float or None
        A fit from several starts (:func:`~hystdisc.fitting.multistart.best_of_starts`):
        the RMS each start ended at, by its label; None for a fit from one start.
    starts_note : str or None
        That fit's note on how the starts ended (also among ``notes``).
    nested_from : str or None
        The family whose optimum this fit was refitted from (a family never ends worse
        than a model it contains), if any.
    heldout_refitted : tuple of str
        The runs of the held-out folds whose quick estimate was not trusted (its
        Gauss-Newton step fitted the other runs worse than the joint optimum, diverged,
        or predicted far off) and that were refitted fully: the fit sits where the data
        leave a curved, flat valley that a linear step does not describe.
    """

    par: Parametrization
    x: np.ndarray
    nuisance: np.ndarray
    params: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    stderr: dict[str, float]
    identifiable: dict[str, bool]
    notes: list[str]
    rms: float
    rss: float
    n_obs: int
    n_params: int
    bic: float
    predictions: list[np.ndarray]
    residuals: list[np.ndarray]
    heldout_rms: float | None = None
    heldout_predictions: list[np.ndarray] | None = None
    nfev: int = 0
    success: bool = True
    diverged: list[str] = field(default_factory=list)
    starts: dict[str, float] | None = None
    starts_note: str | None = None
    nested_from: str | None = None
    heldout_refitted: tuple[str, ...] = ()

    @property
    def term_model(self) -> TermModel:
        """The fitted model in term form (a system family has none: see :attr:`model`)."""
        return self.par.terms(self.x)

    @property
    def model(self):
        """The fitted model as the simulator takes it: a :class:`TermModel`, or a
        state-space model with its parameter values (a system family)."""
        return self.par.model(self.x)

    @property
    def is_system(self) -> bool:
        """The fitted model is a state-space family's (no term form, not even a term part
        around a structural effect)."""
        # decided by the parametrization's kind: no model needs to be built for it
        return isinstance(self.par, SystemParametrization) and not hasattr(self.par, "rigid_terms")

    @property
    def term_part(self) -> TermModel:
        """The term form of the fitted model without the internal states of a structural
        effect (the damper, rig spring and term effects; the whole model when it has no
        structural effect). Raises for a state-space model that has no term part."""
        rigid = getattr(self.par, "rigid_terms", None)
        return rigid(self.x) if rigid is not None else self.par.terms(self.x)


class OutputErrorFitter(HeldOutFolds):
    """Fit a :class:`Parametrization` to :class:`FitData` by output error.

    Parameters
    ----------
    data : FitData
        The runs.
    par : Parametrization
        The structure and its start.
    max_nfev : int
        Limit of Jacobian evaluations (Levenberg-Marquardt iterations).
    rel_step : float
        Relative step of the forward differences (and of a channel delay's column).
    jacobian_mode : {"exact", "lockstep", "terms", "forward"}, optional
        How :meth:`jacobian` is computed (:data:`~hystdisc.fitting.jacobian.JACOBIAN_MODES`;
        default: the data's :attr:`~hystdisc.measurement.FitData.jacobian`, ``"exact"``
        unless set). The fits inside this one (the bulk, the held-out folds) compute
        theirs alike.
    """

    def __init__(
        self,
        data: FitData,
        par: Parametrization,
        max_nfev: int = 60,
        rel_step: float = 1e-6,
        jacobian_mode: str | None = None,
    ) -> None:
        mode = check_jacobian_mode(data.jacobian if jacobian_mode is None else jacobian_mode)
        self.data = data
        self.par = par
        self.max_nfev = max_nfev
        self.rel_step = rel_step
        self.jacobian_mode = mode
        system = isinstance(par, SystemParametrization)
        #: The Jacobian is taken from the kernels' sensitivities (a term-form model).
        self.exact = mode != "forward" and not system
        #: The Jacobian is the integrator's sensitivities (a state-space model with
        #: compiled partial derivatives).
        self.exact_system = mode == "exact" and exact_applies(par)
        #: The Jacobian is the lockstep internal differentiation (a state-space model).
        self.lockstep = mode == "lockstep" and system
        self.npar = len(par.names)
        self.state = par.has_state()
        self.nnu = data.n_nuisance(self.state)
        self.masks = data.mask
        #: Where each run's residual rows start (and the last one ends) in the residual.
        self.row_offsets = np.cumsum([0] + [int(m.sum()) for m in data.mask])
        #: The vector of the last :meth:`residuals` call and every run's output there.
        self._last: tuple[np.ndarray, list[np.ndarray]] | None = None

    def gram(self, J: np.ndarray) -> np.ndarray:
        """``J.T @ J`` of this fit's Jacobian from its blocks: a run's initial-state columns
        are zero outside the run's rows (linear in the runs, where the dense product is
        cubic)."""
        k, nn = self.npar, self.nnu
        if nn == 0 or self.data.n_runs < 2:
            return J.T @ J
        A = np.zeros((J.shape[1], J.shape[1]))
        Jg = J[:, :k]
        A[:k, :k] = Jg.T @ Jg
        for r in range(self.data.n_runs):
            rows = slice(self.row_offsets[r], self.row_offsets[r + 1])
            c = slice(k + r * nn, k + (r + 1) * nn)
            Jn = J[rows, c]
            B = Jg[rows].T @ Jn
            A[:k, c] = B
            A[c, :k] = B.T
            A[c, c] = Jn.T @ Jn
        return A

    # split the full vector
    def _split(self, v):
        x = v[: self.npar]
        nu = (
            v[self.npar :].reshape(self.data.n_runs, self.nnu)
            if self.nnu
            else np.zeros((self.data.n_runs, 0))
        )
        return x, nu

    def _resid_from(self, preds, runs):
        return np.concatenate(
            [(p - self.data.y[r])[self.masks[r]] for p, r in zip(preds, runs, strict=True)]
        )

    def residuals(self, v, work_out: list | None = None):
        """Simulated minus measured output of every run at the vector ``v`` (the model's
        parameters, then each run's nuisance ones), masked samples left out, runs
        concatenated; ``work_out``, when given, receives the integration work."""
        x, nu = self._split(v)
        tm = self.par.model(x)
        runs = list(range(self.data.n_runs))
        preds = self.par.simulate(
            self.data, [tm] * len(runs), runs, [nu[r] for r in runs], work_out=work_out
        )
        # the Levenberg-Marquardt asks for the Jacobian where it last evaluated the
        # residual: its forward differences reuse these outputs as their base
        self._last = (np.array(v, dtype=float), preds)
        return self._resid_from(preds, runs)

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`residuals` (masked rows, all of ``v``).

        As the fitter's ``jacobian_mode`` says
        (:data:`~hystdisc.fitting.jacobian.JACOBIAN_MODES`): the kernels' sensitivities
        for a model in term form
        (:func:`~hystdisc.fitting.jacobian.exact_jacobian`), the integrator's for a
        state-space model with compiled partial derivatives
        (:func:`~hystdisc.fitting.system_sensitivity.system_exact_jacobian`), lockstep
        differences for a state-space model
        (:func:`~hystdisc.fitting.system_jacobian.system_jacobian`), else forward
        differences (:meth:`difference_jacobian`), which are also taken where the
        simulation diverges.
        """
        if self.lockstep:
            return system_jacobian(
                self.data, self.par, v, self.rel_step, self.masks, self.row_offsets
            )
        if self.exact_system:
            x, nu = self._split(v)
            Jm = system_exact_jacobian(self.data, self.par, x, nu, self.masks, self.rel_step)
            if Jm is not None:
                return Jm
        if self.exact:
            x, nu = self._split(v)
            Jm = exact_jacobian(self.data, self.par, x, nu, self.state, self.masks, self.rel_step)
            if Jm is not None:
                return Jm
        return self.difference_jacobian(v)

    def difference_jacobian(self, v: np.ndarray) -> np.ndarray:
        """Forward-difference Jacobian of :meth:`residuals` (masked rows, all of ``v``; see
        :func:`~hystdisc.fitting.jacobian.difference_jacobian`)."""
        x, nu = self._split(v)
        last = self._last
        base = last[1] if last is not None and np.array_equal(last[0], v) else None
        return difference_jacobian(self.data, self.par, x, nu, self.masks, self.rel_step, base)

    def fit(self, heldout: bool = True) -> OEFit:
        """Levenberg-Marquardt from the parametrization's start; intervals, BIC and (with
        ``heldout``) held-out errors at the optimum (leave one test condition out, or one run).

        Long records are fitted on the decimated data (:meth:`FitData.bulk`) first; the
        fit then continues on every sample until it converges there too, so the result
        refers to the full data whichever way it got there.
        """
        p0 = np.concatenate([self.par.x0, self.data.nuisance_start(self.state)])
        lo = np.concatenate([self.par.lower, np.full(self.nnu * self.data.n_runs, -np.inf)])
        hi = np.concatenate([self.par.upper, np.full(self.nnu * self.data.n_runs, np.inf)])
        used = 0
        jac0 = r0 = None
        bulk = self.data.bulk()
        coarse = None
        if bulk is not None:
            coarse = OutputErrorFitter(
                bulk, self.par, self.max_nfev, self.rel_step, self.jacobian_mode
            )
            # a stiff model needs as many sub-steps per second on either grid: the bulk
            # only pays when it integrates with clearly less work (deterministic count)
            w_full: list = []
            w_bulk: list = []
            with np.errstate(all="ignore"):
                r0 = self.residuals(p0, w_full)
                coarse.residuals(p0, w_bulk)
            # (a state-space model counts no work: it is fitted on every sample, since its
            # decimated fit was measured to wander off on the filtered MR records)
            if not sum(w_bulk) or sum(w_full) < BULK_MIN_GAIN * sum(w_bulk):
                coarse = None
        if coarse is not None:
            try:
                p0, used, _, Jb = levenberg_marquardt(
                    coarse.residuals,
                    coarse.jacobian,
                    p0,
                    lo,
                    hi,
                    max_iter=self.max_nfev,
                    tol=BULK_TOL,
                    return_jac=True,
                    gram=coarse.gram,
                )
                # the sensitivities are smooth in time: the coarse Jacobian, splined to every
                # sample, makes the first full-data step (the final Jacobian checks it)
                jac0 = self._interpolated(coarse, coarse.jacobian(p0) if Jb is None else Jb)
            except HystdiscError:
                used = 0  # the start diverges on the coarse grid: fit the full data directly
            r0 = None  # the full fit starts elsewhere
        v, nfev, ok, Jv = levenberg_marquardt(
            self.residuals,
            self.jacobian,
            p0,
            lo,
            hi,
            max_iter=max(self.max_nfev - used, POLISH_MIN_ITER),
            return_jac=True,
            jac0=jac0,
            r0=r0,
            gram=self.gram,
        )
        return self._finish(v, nfev + used, ok, heldout, Jv)

    def screen(self, max_nfev: int) -> tuple[np.ndarray, float]:
        """A few Levenberg-Marquardt iterations from the parametrization's start, on the
        decimated data when the record is long (:meth:`FitData.bulk`): the free parameters
        reached and the RSS there on every sample (inf when the simulation diverges). No
        intervals: a screen of starts, not a fit."""
        p0 = np.concatenate([self.par.x0, self.data.nuisance_start(self.state)])
        lo = np.concatenate([self.par.lower, np.full(self.nnu * self.data.n_runs, -np.inf)])
        hi = np.concatenate([self.par.upper, np.full(self.nnu * self.data.n_runs, np.inf)])
        # a state-space model is screened on every sample, as it is fitted (see fit)
        bulk = None if isinstance(self.par, SystemParametrization) else self.data.bulk()
        fitter = (
            self
            if bulk is None
            else OutputErrorFitter(bulk, self.par, max_nfev, jacobian_mode=self.jacobian_mode)
        )
        try:
            with np.errstate(all="ignore"):
                v, _, _ = levenberg_marquardt(
                    fitter.residuals,
                    fitter.jacobian,
                    p0,
                    lo,
                    hi,
                    max_iter=max_nfev,
                    gram=fitter.gram,
                )
        except HystdiscError:
            return self.par.x0, float("inf")
        with np.errstate(all="ignore"):  # the decimation keeps the runs and their starts
            r = self.residuals(v)
        return v[: self.npar], float(r @ r) if np.all(np.isfinite(r)) else float("inf")

    def _interpolated(self, coarse: OutputErrorFitter, Jc: np.ndarray) -> np.ndarray | None:
        """The Jacobian of ``coarse`` (a decimation of this fit's data) at every sample."""
        if not np.all(np.isfinite(Jc)):
            return None
        out = np.empty((self.row_offsets[-1], Jc.shape[1]))
        for r in range(self.data.n_runs):
            tf = self.data.t[r][self.masks[r]]
            tc = coarse.data.t[r][coarse.masks[r]]
            Jr = Jc[coarse.row_offsets[r] : coarse.row_offsets[r + 1]]
            rows = slice(self.row_offsets[r], self.row_offsets[r + 1])
            if tc.size == tf.size:
                out[rows] = Jr
            elif tc.size >= 4:
                out[rows] = CubicSpline(tc, Jr, axis=0)(tf)
            else:
                return None
        return out

    def _finish(self, v, nfev, success, heldout, Jm=None) -> OEFit:
        x, nu = self._split(v)
        res = self.residuals(v)
        if Jm is None:
            Jm = self.jacobian(v)
        N = res.size
        k = len(v)
        rss = float(res @ res)
        rms = float(np.sqrt(rss / N))
        # a declared filter makes neighbouring residuals one measurement: BIC counts the
        # independent ones, and the intervals widen by the correlation (both as before
        # without a filter)
        n_eff = self.data.n_eff() if any(self.data.run_filters()) else float(N)
        bic = _bic(rss, N, k, n_eff=n_eff)
        gram = self.gram(Jm)
        iv = fit_intervals(self.data, self.par, x, nu, res, Jm, gram, self.row_offsets, n_eff)
        runs = list(range(self.data.n_runs))
        tm = self.par.model(x)
        status: list = []
        preds = self.par.simulate(self.data, [tm] * len(runs), runs, [nu[r] for r in runs], status)
        resid = [preds[r] - self.data.y[r] for r in runs]
        fit = OEFit(
            par=self.par,
            x=x,
            nuisance=nu,
            params=iv.params,
            ci95=iv.ci95,
            stderr=iv.stderr,
            identifiable=iv.identifiable,
            notes=iv.notes,
            rms=rms,
            rss=rss,
            n_obs=N,
            n_params=k,
            bic=bic,
            predictions=preds,
            residuals=resid,
            nfev=nfev,
            success=success,
            diverged=[self.data.names[r] for r in runs if status[r]],
        )
        if heldout and self.data.n_runs >= 2:
            fit.heldout_rms, fit.heldout_predictions = self._heldout(v, res, Jm, gram)
            fit.heldout_refitted = self.heldout_refitted
            if fit.heldout_rms is None:
                fit.notes.append(self.heldout_note)
        return fit
