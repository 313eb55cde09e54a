"""The estimator: :class:`Discovery`, the scikit-learn face of the pipeline.

:meth:`Discovery.fit` runs the pipeline's stages (:mod:`hystdisc.pipeline`: stage 1's
sparse regression, every family's output-error fit, the selection judged on held-out
conditions with physically admissible parameters, the closing loop) and keeps the state
they fill as its fitted attributes; :meth:`~Discovery.predict` simulates the fitted model
on new runs.

:class:`Discovery` follows the scikit-learn contract: ``__init__`` only stores its
arguments (``get_params``/``set_params``/``sklearn.base.clone`` work), :meth:`~Discovery.fit`
returns ``self``, fitted attributes end in ``_`` and a fitted estimator pickles.

Examples
--------
>>> from sklearn.base import clone
>>> d = Discovery(families=["dahl"], verbose=1)
>>> clone(d).get_params() == d.get_params()
True
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator

from hystdisc.apply import predict_dataset
from hystdisc.data import Dataset
from hystdisc.discovery import DEFAULT_SHAPES, DEFAULT_TORQUE_TERMS
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OEFit
from hystdisc.pipeline import Options, build_results, run, stderr_printer
from hystdisc.pipeline.record import equations
from hystdisc.registry import get_experiment


class Discovery(BaseEstimator):
    """Discover the hysteresis model of an MR damper from runs at several currents.

    Parameters
    ----------
    experiment : {'release', 'driven', 'forced'}, optional
        Overrides the dataset's experiment type.
    families : sequence of str, optional
        Families fitted and compared by output error (default: every registered family,
        :func:`hystdisc.registry.family_names`; the state-space families such as
        ``spencer`` only on driven data, where the measured force shows their internal
        state: name them to compare them on release or forced data).
    model : str, optional
        Declare the family instead of selecting one (it is still compared to no others).
    torque_terms : sequence of str
        Torque-side library (section 3 of ``doc/design.rst``).
    shapes : sequence of str
        Hysteresis-side candidates for stage 1.
    threshold : float, optional
        Fixed STLSQ threshold (on normalized columns); default: chosen by BIC on a path.
    ensemble : bool
        Also estimate inclusion probabilities with pysindy's ``EnsembleOptimizer``.
    heldout : bool
        Compute each family's held-out RMS (leave one test condition out, or one run)
        for the family table and the selection. The closing loop judges effects on
        held-out data whatever this says.
    seed : int
        Seed for the ensemble resampling.
    verbose : int
        Above 0, progress messages go to stderr as ``[  1.2 s] message`` (the form the
        command line prints). A callback passed to :meth:`fit` receives them instead.
    max_nfev : int
        Limit of simulations of the output-error fit per family.
    close_loop : bool
        After the fit, diagnose the residual against the effect catalogue, add effects
        that improve BIC and test the final residual for whiteness (:mod:`hystdisc.closing`).
    single_current : bool
        Declares that all runs share one current (a rig without a coil), which silences
        the warning about it. Such runs are always accepted: the current-dependent
        parameters are fixed at 0 and ``results_.current_dependence`` says so.
    input_hold : {'cubic', 'linear', 'zoh'}
        Forced experiments: how the input is interpolated between its samples (a cubic
        spline for a sampled smooth force; ``zoh`` for a DAC output held between samples).
    n_jobs : int, optional
        Threads for the independent fits (stage-1 shapes, stage-2 families) and for the
        simulations of a state-space model's batch (:mod:`hystdisc.simulation.parallel`);
        default: the usable CPUs, at most
        :data:`~hystdisc.simulation.parallel.MAX_THREADS`. The results do not depend on it.
        With ``scheduler``, the threads of each task's batches on its worker (and of the
        work done here).
    staged : bool
        After the selection, the seed's flowchart (:mod:`hystdisc.selection.staged`): the
        selected family fitted at each current level, each current law chosen by leaving
        one level out, the joint fit with the chosen laws (``staged_``; needs 3 levels);
        a chosen law that is not linear is carried into the final model.
    n_starts : int
        Starts of each term family's output-error fit when its first ends above the
        noise floor (:mod:`hystdisc.fitting.multistart`): stage 1's, other basins of its
        shape's grid, random perturbations, the per-level fits and the related families'
        optima; 1: stage 1's start alone. No family ends worse than a model it contains.
    jacobian : {'exact', 'lockstep', 'terms', 'forward'}
        How the output-error fits compute their Jacobian: the simulators' exact
        sensitivities where they have them, else forward differences (the default); see
        :data:`~hystdisc.fitting.jacobian.JACOBIAN_MODES` for the others.
    detect_filter : bool
        Driven data that declare no filter (no rig file's ``[filter]``): look in the
        records for a causal moving average they went through (its notches,
        :mod:`hystdisc.data.filters`) and, when one is read, fit the model through it as
        through a declared one (``prefilter_``; a warning says so). False: the records
        are taken as unfiltered.
    scheduler : str or distributed.Client, optional
        Run this discovery's independent tasks (stage-1 shapes, every family's first fit,
        its starts and held-out folds, the families refitted with a measurement effect or
        with the loop's effects for the comparison again) on a Dask cluster
        instead of this process's threads: a scheduler's address (``tcp://host:8786``,
        connected at :meth:`fit` and closed after it) or a connected
        ``distributed.Client`` (used as given). The workers need this version of hystdisc
        (``pip install hystdisc[dask]``), not the data: each task carries its own. The
        results are those of the threaded run (:mod:`hystdisc.pipeline.tasks`); the
        stages themselves (and the closing loop's rounds) run here. An address keeps the
        estimator clonable and picklable (a ``Client`` can be neither copied nor pickled).
        A missing dask, an unreachable address and a worker without this hystdisc are
        one-line :class:`~hystdisc.errors.HystdiscError` (:mod:`hystdisc.cluster`).

    Attributes
    ----------
    experiment_ : str
        The experiment type the data were read as.
    noise_std_ : float
        Estimated measurement noise of the output (data units): ``noise_.std``.
    prefilter_ : FilterFound or None
        The moving average read in the records and fitted through (``detect_filter``);
        None when the data declare their filter, none was read, or it was not looked for.
    noise_ : NoiseEstimate
        How it was estimated (period-to-period differences, high-order differences or the
        quantization floor), each run's estimates, the encoder of the angle
        (:func:`hystdisc.data.measurement_noise`).
    n_runs_ : int
        Number of runs (after trimming).
    currents_ : ndarray
        Each run's current.
    single_current_ : bool
        All runs share one current (the current-dependent parameters are fixed at 0 and
        the current dependence is reported as not identifiable).
    window_ : int
        Smoothing window of the derivatives, in samples of the decimated stage-1 grid.
    fit_data_ : FitData
        The runs as the output-error fits saw them (with each run's test condition).
    conditions_ : list of str
        Each run's test condition: given by the data (a ``condition`` column) or detected
        (runs that share a sine, a release angle or an input record). Held-out errors
        leave one condition out at a time (one run when all runs share one condition).
    envelope_ : Envelope
        What the training runs covered (displacement, velocity, current, duration).
    admissibility_ : dict of str to Admissibility
        Each family's physical admissibility over twice the envelope.
    selection_note_ : str or None
        Why the selected family is not the one BIC alone would have chosen.
    eq_data_ : EqData
        The equation-error (stage 1) data.
    stage1_ : dict of str to ShapeFit
        Stage-1 fit of each hysteresis shape.
    discovered_shape_, discovered_name_ : str
        The discovered structure's hysteresis shape and its name.
    discovered_ : TermModel
        The discovered structure with its stage-1 coefficients.
    terms_ : dict
        Its ``torque`` and ``hysteresis`` terms.
    family_fits_ : dict of str to OEFit
        Output-error fit of each family.
    discovered_fit_ : OEFit
        Output-error fit of the discovered structure.
    family_ : str
        The selected (or declared) family.
    declared_ : bool
        The family was declared (``model``), not selected.
    equal_fits_ : list of str
        Other families that fit equally well (BIC within
        :data:`~hystdisc.pipeline.close.EQUAL_FIT_BIC`).
    loop_ : LoopResult or None
        The closing loop's outcome (None with ``close_loop=False``).
    final_fit_ : OEFit
        The selected family with every accepted effect (its own fit without the loop).
    reselection_ : Reselection or None
        The families compared again with the effects the loop accepted (None: none).
    reduction_ : Reduction or None
        The selected family reduced to a smaller one plus effects, when its intervals
        hold the values where it is that model (None: no reduction applied).
    effects_ : list of str
        The accepted effects.
    final_admissibility_ : Admissibility
        The final model's admissibility (a loud warning when it fails).
    outliers_ : Outliers
        The isolated glitches of the measured signals (:mod:`hystdisc.measurement.outliers`):
        left out of every fit, reported under ``outliers`` in ``results.json``.
    staged_ : StagedFit or None
        The staged fit (``staged=True`` and 3 current levels or more), else None. When it
        chose a law that is not linear and its joint fit predicts the held-out conditions
        better, that fit is the selected family's from then on (loop, results, predict).
    delay_scan_ : DelayScan or None
        Driven data: the delay between the channels that stage 1 scanned
        (:mod:`hystdisc.discovery.delay`); None when not scanned.
    measured_ : list of MeasuredVerdict
        Each measurement effect found before the comparison, judged on the selected
        family: its ``note`` and, when accepted, its ``entry`` among the effects
        (:class:`~hystdisc.closing.measured.MeasuredVerdict`).
    failed_ : dict of str to str
        The tasks that failed and were dropped (a family, a start, held-out folds, an
        effect, the staged fit), each with its one-line reason: the run went on without
        them (``failed`` in ``results.json``).
    open_library_ : ResidualTerms or None
        The open library's terms in a residual the catalogue left (None: none left).
    results_ : Results
        The ``results.json`` contract.

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> from hystdisc.simulation.synth import generate
    >>> data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3, noise=1e-3, seed=1)
    >>> d = Discovery(families=["dahl", "bingham"], heldout=False).fit(data)
    >>> d.family_
    'dahl'
    >>> bool(d.results_.families["dahl"]["rms"] < 1.2e-3)
    True
    """

    def __init__(
        self,
        experiment: str | None = None,
        families: Sequence[str] | None = None,
        model: str | None = None,
        torque_terms: Sequence[str] = DEFAULT_TORQUE_TERMS,
        shapes: Sequence[str] = DEFAULT_SHAPES,
        threshold: float | None = None,
        ensemble: bool = False,
        heldout: bool = True,
        seed: int = 0,
        verbose: int = 0,
        max_nfev: int = 40,
        close_loop: bool = True,
        input_hold: str = "cubic",
        single_current: bool = False,
        n_jobs: int | None = None,
        staged: bool = False,
        n_starts: int = 4,
        jacobian: str = "exact",
        detect_filter: bool = True,
        scheduler: Any = None,
    ) -> None:
        self.experiment = experiment
        self.families = families
        self.model = model
        self.torque_terms = torque_terms
        self.shapes = shapes
        self.threshold = threshold
        self.ensemble = ensemble
        self.heldout = heldout
        self.seed = seed
        self.verbose = verbose
        self.max_nfev = max_nfev
        self.close_loop = close_loop
        self.input_hold = input_hold
        self.single_current = single_current
        self.n_jobs = n_jobs
        self.n_starts = n_starts
        self.staged = staged
        self.jacobian = jacobian
        self.detect_filter = detect_filter
        self.scheduler = scheduler

    # -- public API
    def fit(
        self, dataset: Dataset, y: None = None, *, progress: Callable[[str], None] | None = None
    ) -> Discovery:
        """Discover terms, fit the families, select one and close the loop.

        Parameters
        ----------
        dataset : Dataset
            The runs (see :func:`hystdisc.load`).
        y : None
            Ignored (the scikit-learn signature; the output is in ``dataset``).
        progress : callable, optional
            Receives short progress messages (``str``); default: stderr when
            ``verbose > 0``, else none.

        Returns
        -------
        Discovery
            ``self``, fitted.

        Raises
        ------
        HystdiscError
            Bad data, or a ``scheduler`` that cannot be used (dask missing, no scheduler
            answering at the address, a worker without this version of hystdisc).
        """
        if progress is None and self.verbose > 0:
            progress = stderr_printer()
        state = run(dataset, Options.of(self.get_params()), progress, self.scheduler)
        for name, value in state.fitted().items():
            setattr(self, name + "_", value)
        self.results_ = build_results(state)
        return self

    def _check_fitted(self):
        if not hasattr(self, "results_"):
            raise HystdiscError("this Discovery is not fitted yet; fix: call fit(dataset) first")

    @property
    def selected_fit_(self) -> OEFit:
        """The output-error fit of the selected family (without the accepted effects)."""
        self._check_fitted()
        return self.family_fits_[self.family_]

    def predict(self, dataset: Dataset, family: str | None = None) -> list:
        """Simulate the fitted model on the runs of ``dataset``.

        Parameters
        ----------
        dataset : Dataset
            Runs of the same experiment type (their motion, input and current).
        family : str, optional
            A family's own fit; by default the selected family with the accepted effects
            (and the open library's terms, when their refit was accepted).

        Returns
        -------
        Predictions
            Per run, a labelled ``RunPrediction`` (``run, t, current, measured, predicted``).
        """
        from hystdisc.results.predictions import label_predictions

        self._check_fitted()
        fit = self.final_fit_ if family is None else self.family_fits_[family or self.family_]
        refit = self.open_library_.refit if self.open_library_ is not None else None
        extra = None
        if family is None and refit is not None and refit.accepted and refit.fit is not None:
            fit, extra = refit.fit, refit.coefficients  # with the library's accepted terms
        preds = predict_dataset(
            fit.model, dataset, self.experiment_, self.input_hold, self.detect_filter, extra
        )
        return label_predictions(dataset, preds)

    def score(self, dataset: Dataset) -> float:
        """Coefficient of determination R^2 of the simulated output on ``dataset``.

        Parameters
        ----------
        dataset : Dataset
            Runs of the same experiment type.

        Returns
        -------
        float
            ``1 - SS_res / SS_tot`` over every sample of every run.
        """
        preds = self.predict(dataset)
        output = get_experiment(self.experiment_).output
        meas = [getattr(r, output) for r in dataset.runs]
        y = np.concatenate(meas)
        p = np.concatenate(preds)
        return float(1.0 - np.sum((y - p) ** 2) / np.sum((y - y.mean()) ** 2))

    def equations(self) -> str:
        """pysindy-style text of the discovered equations.

        Returns
        -------
        str
            The torque equation, the hysteresis equation (and ``J`` when identifiable).
        """
        if not hasattr(self, "discovered_fit_"):
            self._check_fitted()
        return equations(self.discovered_fit_.term_model, self.experiment_)

    def print(self, file=None) -> None:
        """Print the discovered equations (like ``pysindy.SINDy.print``).

        Parameters
        ----------
        file : file-like, optional
            Where to print (standard output by default).
        """
        print(self.equations(), file=file or sys.stdout)

    def _repr_html_(self) -> str:
        if not hasattr(self, "results_"):
            return "<p>Discovery (not fitted)</p>"
        return self.results_._repr_html_()
