"""The runs as the output-error fit sees them: :class:`FitData`.

Each run's time, measured output (the angle, or the torque of a driven run), imposed or
smoothed motion, input and the mask of the samples that enter the residual, plus what the
fit derives from them: the per-run initial-state (nuisance) parameters of the experiment
type and a decimated copy for the bulk of a long fit.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0.0, 1.0, 5)
>>> fd = FitData("release", ["a"], [t], [np.cos(t)], np.array([0.5]), [np.cos(t)],
...              [-np.sin(t)], [np.zeros(5)], [np.ones(5, dtype=bool)])
>>> fd.nuisance_names(), fd.nuisance_start().tolist()
(['theta0[a]'], [1.0])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hystdisc.data.conditions import condition_folds
from hystdisc.registry import get_experiment
from hystdisc.simulation import Integration, input_slopes
from hystdisc.stats import samples_per_cycle

if TYPE_CHECKING:
    from hystdisc.data.motion import MotionNoise
    from hystdisc.measurement.motion import MotionEstimate

#: Samples per cycle of the motion kept by the bulk of an output-error fit (the fit then
#: finishes on the full data, so the optimum, intervals and BIC refer to every sample).
BULK_PER_CYCLE = 100
#: A run is decimated for the bulk only if it keeps at least this many samples.
BULK_MIN_SAMPLES = 200


@dataclass
class FitData:
    """Runs prepared for the output-error fit (all arrays per run)."""

    experiment: str
    names: list[str]
    t: list[np.ndarray]
    y: list[np.ndarray]  # measured output: theta (release/forced) or torque (driven)
    currents: np.ndarray
    theta: list[np.ndarray]  # driven: imposed motion (smoothed); else measured theta
    theta_dot: list[np.ndarray]  # driven: imposed velocity; else smoothed estimate
    u: list[np.ndarray]  # forced: input; else zeros
    mask: list[np.ndarray]  # samples that enter the residual
    noise_std: float = 0.0
    hold: str = "cubic"
    du: list[np.ndarray] | None = None  # forced: spline slopes of the input (cached)
    steps: list[int] | None = None  # decimation factor of each run (sub-step caps scale)
    conditions: list[str] | None = None  # each run's test condition (None: one per run)
    #: each run's causal moving-average window (measured samples) of the recorded output,
    #: applied to the simulated output too (None: not filtered; see measurement/chain.py)
    filter_windows: list[int] | None = None
    #: the lattice step of the measured output when its noise is quantization (an encoder
    #: without noise above its floor); 0: the noise is independent from sample to sample.
    #: Quantization error is a fixed sawtooth of the true output, correlated wherever the
    #: output dwells within a step, and the fit's intervals account for it
    quantum: float = 0.0
    #: driven: each run's motion estimate and how it errs (None: the motion is exact, not
    #: imposed, or its errors are not to be propagated); its errors enter the intervals
    #: (fitting/motion_error.py). A decimated copy has none: only a fit's final,
    #: full-data intervals propagate them
    motion_errors: list[MotionEstimate | None] | None = None
    #: driven: the noise on the measured motion (``results.json``: ``motion_noise``)
    motion_noise: MotionNoise | None = None
    #: how the fits of these data integrate their candidates (the pipeline's
    #: ``Options.integration``); every copy (a subset, the bulk) integrates alike
    integration: Integration = field(default_factory=Integration)
    #: how a fit of these data computes its Jacobian unless its fitter is told otherwise
    #: (``jacobian_mode`` of :class:`~hystdisc.fitting.OutputErrorFitter`; the pipeline's
    #: ``Options.jacobian``)
    jacobian: str = "exact"
    _bulk: FitData | None = field(default=None, init=False, repr=False, compare=False)
    _bulk_done: bool = field(default=False, init=False, repr=False, compare=False)

    def input_slopes(self) -> list[np.ndarray]:
        """Per-run slopes of the input's cubic spline (computed once)."""
        if self.du is None:
            self.du = [
                input_slopes(t, u, np.array([0, t.size]))
                for t, u in zip(self.t, self.u, strict=True)
            ]
        return self.du

    @property
    def exp(self):
        """The experiment object of :attr:`experiment` (see :mod:`hystdisc.experiments`)."""
        return get_experiment(self.experiment)

    @property
    def n_runs(self) -> int:
        """Number of runs."""
        return len(self.t)

    def run_filters(self) -> list[int]:
        """Each run's output filter window in measured samples (0: not filtered)."""
        return list(self.filter_windows) if self.filter_windows is not None else [0] * self.n_runs

    def correlation_lengths(self) -> np.ndarray:
        """Each run's correlation length of its measurement noise, in fit samples: the sum
        of the autocorrelation of white noise passed through the run's declared filter
        (a causal moving average of ``w`` samples: ``w``), over the run's decimation; 1
        for an unfiltered run. The samples of a filtered run are not independent: ``w``
        of them carry the information of one (:meth:`n_eff`), and the intervals of a fit
        widen by ``sqrt(w)``.

        Examples
        --------
        >>> t = np.linspace(0.0, 1.0, 5)
        >>> fd = FitData("driven", ["a", "b"], [t, t], [t, t], np.zeros(2), [t, t], [t, t],
        ...              [t, t], [t > 0, t > 0], filter_windows=[10, 0])
        >>> fd.correlation_lengths().tolist(), fd.n_eff()
        ([10.0, 1.0], 4.4)
        """
        steps = self.run_steps()
        return np.array(
            [max(1.0, w / max(s, 1)) for w, s in zip(self.run_filters(), steps, strict=True)]
        )

    def n_eff(self) -> float:
        """The effective number of independent residuals: each run's masked samples over
        its :meth:`correlation_lengths`."""
        lengths = self.correlation_lengths()
        return float(sum(m.sum() / c for m, c in zip(self.mask, lengths, strict=True)))

    def run_steps(self) -> list[int]:
        """Each run's decimation factor against the data it was measured as (1: all)."""
        return list(self.steps) if self.steps is not None else [1] * self.n_runs

    def bulk_factors(self) -> list[int]:
        """Per-run decimation factor of the bulk of an output-error fit.

        Every run keeps about :data:`BULK_PER_CYCLE` samples per cycle of its motion (and of
        a forced run's input); the simulator's sub-steps keep the integration as accurate
        as on the full grid.
        """
        out = []
        for k in range(self.n_runs):
            per = samples_per_cycle(self.theta_dot[k])
            if self.exp.has_input:
                per = min(per, samples_per_cycle(self.u[k] - np.mean(self.u[k])))
            q = int(per // BULK_PER_CYCLE)
            # a short run or one whose residual rows would thin out is kept as it is
            if self.t[k].size // max(q, 1) < BULK_MIN_SAMPLES:
                q = 1
            out.append(max(q, 1))
        return out

    def bulk(self) -> FitData | None:
        """The data decimated by :meth:`bulk_factors` (computed once), or None when that
        would not save at least half of the samples."""
        if not self._bulk_done:
            self._bulk_done = True
            qs = self.bulk_factors()
            n_full = sum(t.size for t in self.t)
            n_bulk = sum(-(-t.size // q) for t, q in zip(self.t, qs, strict=True))
            if n_bulk <= n_full / 2:
                self._bulk = self.decimated(qs)
        if self._bulk is not None:  # the fit settings as they are now (set after the copy)
            self._bulk.integration, self._bulk.jacobian = self.integration, self.jacobian
        return self._bulk

    def decimated(self, qs: list[int]) -> FitData:
        """Every ``qs[k]``-th sample of run ``k`` (a forced run keeps its full-rate spline
        slopes at the samples kept)."""
        dec = lambda xs: [x[::q] for x, q in zip(xs, qs, strict=True)]  # noqa: E731
        du = None
        if self.exp.has_input and self.hold == "cubic":
            du = dec(self.input_slopes())
        return FitData(
            self.experiment,
            list(self.names),
            dec(self.t),
            dec(self.y),
            self.currents,
            dec(self.theta),
            dec(self.theta_dot),
            dec(self.u),
            dec(self.mask),
            self.noise_std,
            self.hold,
            du,
            [q * s for q, s in zip(qs, self.run_steps(), strict=True)],
            self.conditions,
            self.filter_windows,
            self.quantum,
            None,
            self.motion_noise,
            self.integration,
            self.jacobian,
        )

    def subset(self, idx: list[int]) -> FitData:
        """The runs ``idx`` only (in that order)."""
        pick = lambda xs: [xs[k] for k in idx]  # noqa: E731
        return FitData(
            self.experiment,
            pick(self.names),
            pick(self.t),
            pick(self.y),
            self.currents[idx],
            pick(self.theta),
            pick(self.theta_dot),
            pick(self.u),
            pick(self.mask),
            self.noise_std,
            self.hold,
            None if self.du is None else pick(self.du),
            None if self.steps is None else pick(self.steps),
            None if self.conditions is None else pick(self.conditions),
            None if self.filter_windows is None else pick(self.filter_windows),
            self.quantum,
            None if self.motion_errors is None else pick(self.motion_errors),
            self.motion_noise,
            self.integration,
            self.jacobian,
        )

    def folds(self) -> list[list[int]]:
        """The runs each held-out fold leaves out: one fold per test condition, or one per
        run when every run is its own condition or all runs share one (see
        :func:`hystdisc.data.conditions.condition_folds`)."""
        labels = self.conditions or [str(k) for k in range(self.n_runs)]
        return condition_folds(labels)

    @property
    def heldout_by(self) -> str:
        """``"condition"`` when the folds leave out whole conditions, else ``"run"``."""
        folds = self.folds()
        return "condition" if any(len(f) > 1 for f in folds) else "run"

    def n_nuisance(self, state: bool = False) -> int:
        """Nuisance parameters per run (initial state; ``state``: the model has a z)."""
        return len(self.exp.initial_state(state))

    def nuisance_names(self, state: bool = False) -> list[str]:
        """Names of every run's nuisance parameters, ``name[run]``, run after run."""
        return [f"{p}[{n}]" for n in self.names for p in self.exp.initial_state(state)]

    def nuisance_start(self, state: bool = False) -> np.ndarray:
        """Start of the nuisance parameters: each run's first sample (z at 0)."""
        names = self.exp.initial_state(state)
        out = []
        for k in range(self.n_runs):
            first = {"theta0": self.theta[k][0], "theta_dot0": self.theta_dot[k][0], "z0": 0.0}
            out.extend(first[p] for p in names)
        return np.array(out, dtype=float)
