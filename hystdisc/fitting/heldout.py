"""Held-out errors of an output-error fit: leave one fold out, refit, predict it.

Each fold (one test condition, or one run when all runs share one:
:meth:`~hystdisc.measurement.FitData.folds`) is left out; the fit without it is estimated by
a Gauss-Newton step from the joint optimum (the Jacobian and residual of the joint fit,
without the fold's rows) and :data:`HELDOUT_STEPS` Levenberg-Marquardt iterations on the
other runs, and the fold's runs are simulated with it. A fold whose quick estimate
diverges, whose step fits the other runs worse than the joint optimum does (the linear
step went the wrong way), or that predicts the fold more than :data:`FOLD_RECHECK` times
worse than the joint fit fits it, is refitted fully from the joint optimum (before the
fit is called unstable, or its error is read); a verdict that rests on the held-out error
can ask for complete refits of every fold (:meth:`HeldOutFolds.heldout_at`, ``full``).
The runs of the folds refitted fully are kept (``heldout_refitted``): a fit whose folds
all need it sits in a curved, flat valley, the mark of a degenerate basin, which the
held-out error itself may not show (:func:`~hystdisc.fitting.multistart.poor_predictions`).

:class:`HeldOutFolds` is the part of
:class:`~hystdisc.fitting.output_error.OutputErrorFitter` that does this; it uses the
fitter's own residuals, Jacobian, data and parametrization.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from hystdisc.errors import HystdiscError
from hystdisc.fitting.lm import levenberg_marquardt

#: Levenberg-Marquardt iterations of each held-out fold after its Gauss-Newton step
#: (a fold that leaves out a whole test condition moves the fit beyond what one linear
#: step predicts).
HELDOUT_STEPS = 2
#: A fold's Gauss-Newton step is its refit, without the Levenberg-Marquardt iterations,
#: when the training runs' RSS at the step exceeds the linear prediction by less than this
#: many noise variances (the step is then where the iterations would end, to a small part
#: of one parameter's chi-square; measured on data_synth, the held-out RMS agrees to 4-6
#: digits in those folds, while a fit at a bound misses by thousands of variances).
HELDOUT_GN_TRUST = 0.1
#: A fold whose quick estimate predicts it this many times worse than the joint fit fits
#: it is refitted fully from the joint optimum, and that refit predicts it instead: the
#: quick estimate is an approximation of the refit, and a state-space family's step can
#: leave its basin (Spencer on a driven set with backlash: the quick estimate put one
#: condition at 15.2, 119 times its in-sample error, the full refit at 0.175, 1.2 times).
FOLD_RECHECK = 3.0


class HeldOutFolds:
    """Leave-one-fold-out refits and predictions of an output-error fitter (a mixin of
    :class:`~hystdisc.fitting.output_error.OutputErrorFitter`, which provides ``data``,
    ``par``, ``npar``, ``nnu``, ``masks``, ``row_offsets``, ``max_nfev``, ``rel_step``,
    ``jacobian_mode``, ``residuals``, ``jacobian``, ``gram`` and ``_split``)."""

    #: Why the held-out error is missing, when a fold's prediction diverged.
    heldout_note: str = ""
    #: The runs of the folds whose quick estimate was not trusted and that were refitted
    #: fully (set by the last quick held-out error).
    heldout_refitted: tuple[str, ...] = ()

    def heldout_at(self, fit: Any, full: bool = False) -> Any:
        """``fit`` (of this parametrization to this data) with its held-out error, computed
        at its optimum when it has none (one Jacobian, then :meth:`_heldout`).

        ``full``: every fold fitted completely on the other runs from the joint optimum
        (up to ``max_nfev`` iterations) instead of the quick estimate, even when ``fit``
        has a held-out error: the leave-one-out refit itself, for a verdict the quick
        estimate may have misjudged (it is a few steps from a linear step, and a step
        that leaves the basin predicts nothing about the model)."""
        if (fit.heldout_rms is not None and not full) or self.data.n_runs < 2:
            return fit
        v = np.concatenate([np.asarray(fit.x, dtype=float), np.asarray(fit.nuisance).ravel()])
        refitted = fit.heldout_refitted
        if full:
            rms, preds = self._heldout(v, None, None, full=True)
        else:
            rms, preds = self._heldout(v, self.residuals(v), self.jacobian(v))
            refitted = self.heldout_refitted
        # why there is none (a fold's prediction diverged) is said, as fit() says it
        notes = fit.notes if rms is not None else [*fit.notes, self.heldout_note]
        return dataclasses.replace(
            fit,
            heldout_rms=rms,
            heldout_predictions=preds,
            notes=notes,
            heldout_refitted=refitted,
        )

    def _at_bounds(self, v: np.ndarray) -> np.ndarray:
        """Mask of the entries of ``v`` (parameters, then initial states) at a bound."""
        out = np.zeros(len(v), dtype=bool)
        x, lo, hi = v[: self.npar], self.par.lower, self.par.upper
        tol = 1e-6 * np.maximum(np.abs(x), 1e-6)
        with np.errstate(invalid="ignore"):
            out[: self.npar] = (x - lo <= tol) | (hi - x <= tol)
        return out

    def _fold_refit(
        self,
        fold: list[int],
        v_gn: np.ndarray,
        rss_gn: float | None,
        full: bool = False,
        rss_joint: float = np.inf,
    ) -> np.ndarray | None:
        """The parameters fitted without the runs ``fold``: the Gauss-Newton estimate
        ``v_gn`` when the other runs' RSS there is its linear prediction ``rss_gn`` (within
        :data:`HELDOUT_GN_TRUST` noise variances), else :data:`HELDOUT_STEPS`
        Levenberg-Marquardt iterations on the other runs from it (the linear step alone
        misjudges a fold that moves the fit far). None when the other runs' RSS at the
        step is above ``rss_joint`` (theirs at the joint optimum, a point of the same
        problem) by more than that tolerance: the step went the wrong way, and a few
        iterations from it are no estimate of the refit. ``full``: a complete fit on the
        other runs from ``v_gn`` (up to ``max_nfev`` iterations; ``rss_gn`` is not used),
        for a fold whose quick estimate did not predict it."""
        x = np.clip(v_gn[: self.npar], self.par.lower, self.par.upper)
        if HELDOUT_STEPS < 1 and not full:
            return x
        train = [r for r in range(self.data.n_runs) if r not in fold]
        sub = type(self)(
            self.data.subset(train), self.par, self.max_nfev, self.rel_step, self.jacobian_mode
        )
        _, nu = self._split(v_gn)
        v0 = np.concatenate([x, nu[train].ravel()])
        with np.errstate(all="ignore"):
            r0 = sub.residuals(v0)
        if not full:
            trust = HELDOUT_GN_TRUST * self.data.noise_std**2
            rss0 = float(r0 @ r0)
            if not (np.all(np.isfinite(r0)) and rss0 <= rss_joint + trust):
                return None
            if abs(rss0 - rss_gn) < trust:
                return x
        free = np.full(sub.nnu * len(train), np.inf)
        lo = np.concatenate([self.par.lower, -free])
        hi = np.concatenate([self.par.upper, free])
        try:
            with np.errstate(all="ignore"):
                vs, *_ = levenberg_marquardt(
                    sub.residuals,
                    sub.jacobian,
                    v0,
                    lo,
                    hi,
                    max_iter=self.max_nfev if full else HELDOUT_STEPS,
                    gram=sub.gram,
                    r0=r0,  # the trust test's simulation is the first iteration's
                )
        except (HystdiscError, np.linalg.LinAlgError, ValueError):
            return x
        return vs[: self.npar] if np.all(np.isfinite(vs)) else x

    def _predict_fold(
        self, x: np.ndarray, fold: list[int], nu: np.ndarray
    ) -> tuple[list[np.ndarray], list]:
        """The fold's runs simulated with the free parameters ``x``, and each run's
        divergence status."""
        tm = self.par.model(x)
        st: list = []
        out = self.par.simulate(self.data, [tm] * len(fold), fold, [nu[r] for r in fold], st)
        return out, st

    def _heldout(self, v, res, Jm, gram=None, full: bool = False):
        """Leave one fold out (a test condition, or a run: :meth:`FitData.folds`): one
        Gauss-Newton step from the joint optimum without the fold's rows, then simulate the
        fold's runs (``full``: a complete refit without the fold from the joint optimum;
        ``res`` and ``Jm`` are not used). Returns the pooled held-out RMS and each run's
        prediction."""
        x, nu = self._split(v)
        sq = 0.0
        cnt = 0
        preds: list[np.ndarray | None] = [None] * self.data.n_runs
        G = g = None
        self.heldout_refitted = ()
        if not full:
            G = self.gram(Jm) if gram is None else gram
            g = Jm.T @ res
        for fold in self.data.folds():
            if full:
                out, st = self._predict_fold(self._fold_refit(fold, v, None, True), fold, nu)
                sq, cnt, bad = self._pool(fold, out, st, preds, sq, cnt)
                if bad:
                    return None, None
                continue
            rows = np.concatenate(
                [np.arange(self.row_offsets[r], self.row_offsets[r + 1]) for r in fold]
            )
            own = np.concatenate(
                [np.arange(self.npar + r * self.nnu, self.npar + (r + 1) * self.nnu) for r in fold]
            ).astype(int)
            cols = ~self._at_bounds(v)  # a parameter held at a bound stays there
            cols[own] = False
            # the fold's rows touch the parameters and its runs' own initial states only
            nz = np.r_[: self.npar, own]
            Jr = Jm[rows][:, nz] if len(fold) > 1 else Jm[rows[0] : rows[-1] + 1, nz]
            Go = G.copy()
            Go[np.ix_(nz, nz)] -= Jr.T @ Jr
            Go = Go[np.ix_(cols, cols)]
            go = g.copy()
            go[nz] -= Jr.T @ res[rows]
            go = go[cols]
            scale = np.sqrt(np.clip(np.diag(Go), 0, None))
            scale[scale == 0] = 1.0
            Gs = Go / np.outer(scale, scale)
            delta = -np.linalg.lstsq(Gs, go / scale, rcond=1e-12)[0] / scale
            vr = v.copy()
            vr[cols] += delta
            # the other runs' RSS at the step, as the linear model predicts it
            keep = np.ones(len(res), dtype=bool)
            keep[rows] = False
            rss_joint = float(res[keep] @ res[keep])
            rss_gn = float(rss_joint + 2 * go @ delta + delta @ Go @ delta)
            xr = self._fold_refit(fold, vr, rss_gn, rss_joint=rss_joint)
            if xr is not None:
                out, st = self._predict_fold(xr, fold, nu)
            if xr is None or any(st) or self._far_off(fold, out, res[rows]):
                # the quick estimate can leave the stable region or its basin on its own:
                # the fold is fitted fully from the joint optimum (before the fit is
                # called unstable, or its error is read)
                vj = np.concatenate([x, nu.ravel()])
                out, st = self._predict_fold(self._fold_refit(fold, vj, None, True), fold, nu)
                self.heldout_refitted += tuple(self.data.names[r] for r in fold)
            sq, cnt, bad = self._pool(fold, out, st, preds, sq, cnt)
            if bad:
                return None, None
        return float(np.sqrt(sq / max(cnt, 1))), preds

    def _far_off(self, fold, out, res_fold: np.ndarray) -> bool:
        """The fold's predictions ``out`` miss it by more than :data:`FOLD_RECHECK` times
        the joint fit's residual ``res_fold`` on its rows."""
        e = np.concatenate(
            [(pr - self.data.y[r])[self.masks[r]] for r, pr in zip(fold, out, strict=True)]
        )
        inside = float(np.sqrt(np.mean(res_fold**2))) if res_fold.size else 0.0
        return bool(e.size and np.sqrt(np.mean(e**2)) > FOLD_RECHECK * inside)

    def _pool(self, fold, out, st, preds, sq: float, cnt: int) -> tuple[float, int, bool]:
        """Add the fold's held-out errors to ``sq`` and ``cnt`` and its predictions to
        ``preds``; True (and :attr:`heldout_note` said) when a prediction diverged."""
        for r, pr, bad in zip(fold, out, st, strict=True):
            if bad:
                self.heldout_note = (
                    f"the held-out prediction of run {self.data.names[r]} diverged, also "
                    "after a full refit without it from the joint optimum: the fit without "
                    "that run is unstable there (held-out RMS not reported)"
                )
                return sq, cnt, True
            e = (pr - self.data.y[r])[self.masks[r]]
            sq += float(e @ e)
            cnt += e.size
            preds[r] = pr
        return sq, cnt, False
