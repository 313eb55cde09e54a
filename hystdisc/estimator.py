"""The estimator: :class:`Discovery` runs the pipeline on a dataset.

Stage 1 (:mod:`hystdisc.discovery`) discovers the torque terms and the hysteresis shape
by sparse equation-error regression; stage 2 (:mod:`hystdisc.fitting`) fits each
family's own structure by simulating every run (output error), started from a stage-1
fit of that structure; the families are compared by BIC and by held-out
RMS (leave one test condition out), and one is selected (or the declared one kept); the closing loop
(:mod:`hystdisc.closing`) adds the catalogued effects the residual asks for; the
results layer writes the record.

Selection: a conclusion counts only if it predicts data the fit did not see, with
physically admissible parameters. The candidates are the families that are admissible
(they dissipate energy and their spring stiffens over twice the training envelope; all
families when none is) and whose held-out error (leave one test condition out, or one
run) is not clearly worse than the best one's; among them the lowest BIC wins, ties
resolved towards the fewest parameters (:func:`~hystdisc.selection.families.select_family`).
When BIC alone would have chosen another family, ``selection_note_`` says so; when the
loop accepts effects with a term form, the families are compared again with them
(``reselection_``, :mod:`hystdisc.closing.reselect`); when the selected family's
intervals hold the values at which it is a smaller family plus effects (LuGre at
``sigma_1 = 0`` is Dahl with a current-dependent viscous term), the smaller model is
fitted and selected by the same rule (``reduction_``, :mod:`hystdisc.closing.reduction`).
Families whose BIC lies within :data:`EQUAL_FIT_BIC` (6) of the selected one are reported as
fitting equally well (``equal_fits_``).

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
import threading
import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator, clone
from threadpoolctl import threadpool_limits

from hystdisc.apply import predict_dataset
from hystdisc.closing import LoopResult, close_loop
from hystdisc.closing.again import compare_again
from hystdisc.closing.measured import add_to_fits
from hystdisc.closing.measured import judge as judge_measured
from hystdisc.closing.reduction import Reduction
from hystdisc.closing.reselect import Context, Reselection
from hystdisc.closing.residual import NOISE_RATIO
from hystdisc.closing.shift import shift_restart
from hystdisc.data import (
    Dataset,
    distinct_currents,
    validate,
)
from hystdisc.data.envelope import Envelope
from hystdisc.discovery import (
    DEFAULT_TORQUE_TERMS,
    FAMILY_SHAPE,
    SHAPES,
    EqData,
    describe_structure,
    family_start,
    fit_shape,
)
from hystdisc.discovery.delay import scan_delay
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.faults import Failures
from hystdisc.fitting import FamilyParametrization, OEFit, OutputErrorFitter, TermParametrization
from hystdisc.fitting.multistart import (
    best_of_starts,
    drop_diverged,
    helper_families,
    mapped_starts,
    nesting_pass,
    poor_predictions,
    system_fit,
    term_starts,
)
from hystdisc.fitting.parametrization import z_scale
from hystdisc.measurement import FitData, confirm_glitches
from hystdisc.measurement.prepare import prepare_data
from hystdisc.models import FAMILIES, format_equation, get_family
from hystdisc.registry import family_names, get_experiment
from hystdisc.results import build_results
from hystdisc.selection import MIN_STAGED_LEVELS, staged_fit
from hystdisc.selection.families import select_family
from hystdisc.selection.staged import levels_start
from hystdisc.simulation.admissibility import check_admissible
from hystdisc.simulation.parallel import limit_threads, map_tasks, map_tasks_after

_SAY_LOCK = threading.Lock()
#: Families whose BIC lies within this of the selected one "fit equally well".
EQUAL_FIT_BIC = 6.0


def _stderr_printer() -> Callable[[str], None]:
    """Progress on stderr as ``[  1.2 s] message`` (the command line's form)."""
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


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
        Declares that all runs share one current, which silences the warning about it;
        nothing else changes. Runs that all share one current (a rig without a coil, such
        as the hysteretic benchmark) are always accepted: the families are compared at
        that current, with a one-line warning that the current dependence is not
        identifiable; the current-dependent parameters are fixed at 0, marked not
        identifiable, and ``results_.current_dependence`` says so. With several currents
        it has no effect.
    input_hold : {'cubic', 'linear', 'zoh'}
        Forced experiments: how the input is interpolated between its samples (a cubic
        spline for a sampled smooth force; ``zoh`` for a DAC output held between samples).
    n_jobs : int, optional
        Threads for the independent fits (stage-1 shapes, stage-2 families) and for the
        simulations of a state-space model's batch (:mod:`hystdisc.simulation.parallel`);
        default: the usable CPUs, at most :data:`MAX_THREADS`. The results do not depend
        on it.
    staged : bool
        After the selection, the seed's flowchart (:mod:`hystdisc.selection.staged`): the
        selected family fitted at each current level, each current law chosen by leaving
        one level out, the joint fit with the chosen laws (``staged_``; needs 3 levels);
        a chosen law that is not linear is carried into the final model.
    n_starts : int
        Starts of each term family's output-error fit (:mod:`hystdisc.fitting.multistart`):
        stage 1's, up to :data:`~hystdisc.fitting.multistart.GRID_BASINS` other basins of its shape's stage-1 grid, then
        random perturbations of stage 1's inside the admissible box; when the first ends
        above the noise floor, these, a start from the per-level fits and the optima of
        the related families (``Family.start_from``: Dahl in LuGre, the other Bouc-Wen
        form...) each run a few iterations and the best continues; the fit's notes say
        how many reached the optimum.
        1: stage 1's start alone. Every family is then refitted from another family's
        optimum when that fits better inside it (nesting consistency).

    Attributes
    ----------
    experiment_ : str
        The experiment type the data were read as.
    noise_std_ : float
        Estimated measurement noise of the output (data units): ``noise_.std``.
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
        Other families that fit equally well (BIC within :data:`EQUAL_FIT_BIC`).
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
        The staged fit (``staged=True`` and 3 current levels or more), else None; its
        ``current_laws`` table is in ``results.json``. When it chose a law that is not
        linear (and its joint fit predicts the held-out conditions better than the linear
        laws), that joint fit replaces the selected family's fit in ``family_fits_``: the
        closing loop, the final model, ``results.json`` and ``predict`` carry the laws (a
        saturating law's ``<law>_i0``, a quadratic law's ``<law>_i2`` among the
        parameters).
    failed_ : dict of str to str
        The tasks that failed and were dropped (a family, a start, held-out folds, an
        effect, the staged fit), each with its one-line reason: the run went on without
        them (``failed`` in ``results.json``).
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
        shapes: Sequence[str] = ("none", "dahl", "bouc-wen", "bouc-wen-std"),
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

    # -- helpers
    def _sayer(self, progress: Callable[[str], None] | None) -> Callable[[str], None]:
        """The progress function of one fit: ``progress``, else stderr when verbose."""
        if progress is None and self.verbose > 0:
            progress = _stderr_printer()
        if progress is None:
            return lambda msg: None

        def say(msg: str) -> None:
            with _SAY_LOCK:
                progress(msg)

        return say

    def _map(self, fn, items: list, serial: bool = False) -> list:
        """``fn`` over ``items`` (independent fits) on up to ``n_jobs`` threads, in order
        (:func:`~hystdisc.simulation.parallel.map_tasks`)."""
        return map_tasks(fn, items, self.n_jobs, serial)

    def _shape0(self, name: str) -> np.ndarray | None:
        """The stage-1 shape constants of ``name``'s shape (None before stage 1)."""
        shape = FAMILY_SHAPE[name]
        return self.stage1_[shape].s if shape in getattr(self, "stage1_", {}) else None

    def _system_fit(self, name: str, base: OEFit, fd: FitData, say, failures) -> OEFit:
        """A system family from its starts mapped from ``base`` (:func:`system_fit`)."""
        fixed = {p: 0.0 for p in FAMILIES[name].current_params} if self.single_current_ else {}
        fit = system_fit(
            name, base, fd, self.max_nfev, fixed, mapper=self._map, say=say, failures=failures
        )
        if self.heldout:
            fit = OutputErrorFitter(fd, fit.par, max_nfev=self.max_nfev).heldout_at(fit)
        return fit

    def _decided_by_staged(self) -> dict[str, str]:
        """Effects the staged fit decided: the current law of the hysteretic torque is
        chosen there (``current_saturation`` is one of its outcomes, not a guess), and the
        chosen laws are the selected family's model."""
        if self.staged_ is None:
            return {}
        laws = self.staged_.laws
        chosen = ", ".join(f"{d['parameter']} {d['law']}" for d in laws.values())
        return {"current_saturation": f"the staged fit chose the current laws ({chosen})"}

    def _stage1_shape(self, fit: OEFit) -> np.ndarray | None:
        """The stage-1 shape constants of the fitted family's hysteresis shape."""
        found = self.stage1_.get(FAMILY_SHAPE.get(fit.par.family.name))
        return None if found is None else np.asarray(found.s, dtype=float)

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
        """
        say = self._sayer(progress)
        # small dense algebra on tall matrices: extra BLAS threads only add overhead
        # the simulations of a batch run side by side on up to n_jobs threads
        with np.errstate(all="ignore"), threadpool_limits(limits=1), limit_threads(self.n_jobs):
            return self._fit(dataset, say)

    def _fit(self, dataset: Dataset, say: Callable[[str], None]) -> Discovery:
        # a task that fails (a family, a start, a fold, an effect) is recorded and dropped
        failures = Failures()
        measured_effects: list[str] = []  # measurement effects every family carries
        measured: dict[str, float] = {}  # and their parameters' starts
        if not isinstance(dataset, Dataset):
            raise TypeError("Discovery.fit expects a hystdisc.data.Dataset (see hystdisc.load)")
        if self.model is not None:
            fams = [get_family(self.model).name]
        else:
            fams = [get_family(f).name for f in (self.families or family_names())]
        # one current (a rig without a coil, the hysteretic benchmark): the families are
        # compared at it, and the current dependence is reported as not identifiable
        validate(dataset, need_currents=1)
        levels = distinct_currents(dataset.currents)
        self.single_current_ = len(levels) < 2
        if self.single_current_ and not self.single_current:  # declared: no warning needed
            check = (
                " (if the runs were recorded at different currents, check the current column "
                "and its unit: --column current=NAME, --units current=mA)"
                if levels[0] == 0.0 and len(dataset.runs) > 1
                else ""
            )
            what = "the family is fitted" if self.model is not None else "the families are compared"
            warnings.warn(
                f"{dataset.source}: all runs share one current ({levels[0]:g} A); {what} at "
                "it, and the current dependence is not identifiable: the current-dependent "
                f"parameters are fixed at 0 and the i* terms left out of the library{check}",
                HystdiscWarning,
                stacklevel=2,
            )
        say("preparing data (noise, derivatives)")
        eq, fd, glitches, self.noise_ = prepare_data(dataset, self.experiment, self.input_hold)
        exp = get_experiment(eq.experiment)
        self.experiment_ = eq.experiment
        self.noise_std_ = fd.noise_std
        self.n_runs_ = fd.n_runs
        self.currents_ = fd.currents
        self.window_ = eq.window
        self.eq_data_, self.fit_data_ = eq, fd
        self.conditions_ = list(fd.conditions)

        # stage 1
        terms = list(self.torque_terms)
        if exp.motion_imposed and "theta" not in terms:
            terms = ["theta", *terms]
        if self.single_current_:
            terms = [t for t in terms if not t.startswith("i")]
        # the lazily built arrays the workers share are built before they start
        eq.row_index  # noqa: B018
        fd.bulk()
        if exp.has_input and fd.hold == "cubic":
            fd.input_slopes()

        def shape_fit(shape):
            say(f"stage 1: sparse regression with hysteresis shape '{shape}'")
            return failures.guard(
                f"stage 1 shape {shape}",
                fit_shape, eq, shape, terms, self.threshold, self.ensemble, self.seed,
            )  # fmt: skip

        # stage 2: each family by output error (and the discovered structure when it is not
        # one of them), each fit on its own
        sys_fams = [n for n in fams if FAMILIES[n].is_system]
        if self.model is None and self.families is None and not exp.motion_imposed:
            # by default the state-space families are compared on driven data, where the
            # force shows their internal state; name them to compare them on a rig
            sys_fams = []
        fams = [n for n in fams if not FAMILIES[n].is_system]
        shapes = list(self.shapes)

        def same_structure(best) -> list[str]:
            """The families whose structure stage 1 discovered (``best``)."""
            return [
                n
                for n in fams
                if FAMILY_SHAPE[n] == best.shape
                and set(FAMILIES[n].torque_terms) == set(best.terms) - {"theta"}
            ]

        def family_par(name, start):
            """``name`` started at ``start``: its z scale chosen there, the current terms
            held at 0 at a single current."""
            start, norm = z_scale(name, {**start, **measured})
            fixed = {p: 0.0 for p in FAMILIES[name].current_params} if self.single_current_ else {}
            return FamilyParametrization(name, eq.experiment, start, tuple(measured_effects),
                                         fixed, norm)  # fmt: skip

        def first_fit(name, s0):
            """``name`` fitted from its stage-1 start: the search of its shape from the
            shape's stage-1 constants ``s0`` (no second grid search); None when it
            fails (recorded)."""

            def fit():
                start, _ = family_start(eq, name, s0=s0, one_level=self.single_current_)
                par = family_par(name, start)
                return OutputErrorFitter(fd, par, max_nfev=self.max_nfev).fit(heldout=False)

            return failures.guard(name, fit)

        def family_fit(k, ready):
            """The first fit of family ``k`` from its shape's stage-1 search (``ready``:
            the stage-1 fits, waited for), or (``k = len(fams)``) of the discovered
            structure when no family has it."""
            if k == len(fams):
                done = [f for f in (ready(j) for j in range(len(shapes))) if f is not None]
                if not done:
                    return None
                best = min(done, key=lambda f: f.bic)
                if same_structure(best):
                    return None
                say("stage 2: output-error fit of the discovered structure")
                tpar = TermParametrization(
                    best.terms, best.shape, best.coefs, best.s, best.J, eq.experiment
                )
                return failures.guard(
                    "discovered structure",
                    OutputErrorFitter(fd, tpar, max_nfev=self.max_nfev).fit,
                    heldout=False,
                )
            name = fams[k]
            shape = FAMILY_SHAPE[name]
            say(f"stage 2: output-error fit of {name} ({k + 1}/{len(fams)})")
            own = ready(shapes.index(shape)) if shape in shapes else None
            return first_fit(name, None if own is None else own.s)

        # a family's first fit starts once its shape's stage-1 search has ended, on the
        # threads the other shapes leave free; the ensemble draws from numpy's global
        # generator: one shape after the other
        fits, firsts = map_tasks_after(
            shape_fit, shapes, family_fit, list(range(len(fams) + 1)), self.n_jobs, self.ensemble
        )
        self.stage1_ = {s: f for s, f in zip(shapes, fits, strict=True) if f is not None}
        if not self.stage1_:
            raise HystdiscError(
                f"{dataset.source}: stage 1 failed for every hysteresis shape "
                f"({failures.summary()}); fix: check that the runs move and the output "
                "responds to the motion"
            )
        best = min(self.stage1_.values(), key=lambda f: f.bic)
        self.discovered_shape_ = best.shape
        self.discovered_ = best.term_model()
        self.terms_ = {
            "torque": [t for t in best.terms if not (t == "theta" and not exp.motion_imposed)],
            "hysteresis": list(SHAPES[best.shape].terms),
        }
        self.discovered_name_ = describe_structure(best.terms, best.shape)
        same = same_structure(best)
        # a delay between the recorded channels enters every family before they are
        # compared: compared without it, the one that best absorbs the lag would win
        self.delay_scan_ = None
        if exp.motion_imposed and not any(fd.run_filters()):  # (stage 1 sees no filter)
            self.delay_scan_ = failures.guard(
                "delay scan", scan_delay, eq, best.terms, best.s, best.shape
            )
        if self.delay_scan_ is not None and self.delay_scan_.found:
            say(f"stage 2: a channel delay of {self.delay_scan_.tau:.3g} s enters every family")
            measured_effects.append("channel_delay")
            measured["tau_d"] = self.delay_scan_.tau
            firsts = list(add_to_fits(fd, dict(enumerate(firsts)), "channel_delay", measured,
                                      self.max_nfev, self._map, failures).values())  # fmt: skip

        def more_starts(name, mapper=None):
            """The family from its other starts (its stage-1 fit is the first), screened
            on the threads of ``mapper`` when given; its first fit when they fail."""
            first = self.family_fits_[name]
            found = failures.guard(f"{name} more starts", starts_of, name, first, mapper)
            return first if found is None else found  # its first fit stands

        def starts_of(name, first, mapper):
            pars = []
            n = max(int(self.n_starts), 1)
            for label, start in term_starts(
                eq,
                name,
                n,
                self.seed,
                self._shape0(name),
                self.single_current_,
                first.par.params(first.par.x0),
            ):
                pars.append((label, family_par(name, start)))
            if (lv := levels_start(fd, first.par, first.params)) is not None:
                pars.append(("current levels", first.par.like(lv, first.par.effects)))
            # the optima of the related families, read in this one (no stage 1 involved)
            for other in FAMILIES[name].start_from:
                ofit = self.family_fits_.get(other)
                readings = [] if ofit is None else mapped_starts(name, ofit)
                for k, reading in enumerate(readings):
                    label = f"{other}'s optimum" + (f" {k + 1}" if len(readings) > 1 else "")
                    pars.append((label, family_par(name, reading)))
            # a first start at the floor that predicts poorly is not trusted (no good_rms)
            good = None if name in poor else NOISE_RATIO * fd.noise_std
            return best_of_starts(fd, pars, self.max_nfev, mapper=mapper, say=say, name=name,
                                  good_rms=good, first=first, failures=failures)  # fmt: skip

        def with_heldout(name):
            fit = self.family_fits_[name]
            if not self.heldout or fit.heldout_rms is not None:
                return fit
            fitter = OutputErrorFitter(fd, fit.par, max_nfev=self.max_nfev)
            found = failures.guard(f"{name} held-out folds", fitter.heldout_at, fit)
            return fit if found is None else found  # no held-out error: said in failed

        # a family whose first fit failed is dropped (its reason is in failed_)
        pairs = [(n, f) for n, f in zip(fams, firsts, strict=False) if f is not None]
        fams, same = [n for n, _ in pairs], [n for n in same if n in dict(pairs)]
        self.family_fits_: dict[str, OEFit] = dict(pairs)
        good = NOISE_RATIO * fd.noise_std
        # a first fit at the floor that does not predict the held-out runs is no proof of
        # the optimum: a seed-form Bouc-Wen at 1.009x the noise with n = 0.01 predicted
        # them at 164x, where its true optimum (66 sigma^2 lower RSS) predicts them at 1x
        poor = {}
        if self.n_starts > 1 and self.heldout and fd.n_runs >= 2:
            poor = poor_predictions(self.family_fits_, good, with_heldout, self._map)
        # a family above the floor whose related families were not asked for (a declared
        # family, a short --families list) gets them fitted too, as its starts only
        helping = helper_families(self.family_fits_, good, poor) if self.n_starts > 1 else {}
        helpers = list(dict.fromkeys(h for hs in helping.values() for h in hs))
        if helpers:
            say(f"stage 2: {', '.join(helpers)} fitted as starts (not compared)")
            fitted = self._map(lambda h: first_fit(h, self._shape0(h)), helpers)
            self.family_fits_.update(
                (h, f) for h, f in zip(helpers, fitted, strict=True) if f is not None
            )
        nest = len(self.family_fits_) > 1  # no family ends worse than a model it contains
        if nest:
            self.family_fits_ = nesting_pass(
                fd, self.family_fits_, self.max_nfev, say, failures=failures
            )
        # every family still above the noise is fitted from more starts: however far it is
        # from the best family, it may be the true one in a wrong basin (a Bingham release
        # on an encoder stopped at 4.9x LuGre's RMS from stage 1's start and reached the
        # floor from its current-levels start)
        more = [n for n, f in self.family_fits_.items() if f.rms > good or n in poor]
        if self.n_starts > 1:
            if len(more) == 1:
                # one family alone: its starts are screened on the threads (independent
                # fits; the same answer as in turn)
                self.family_fits_[more[0]] = more_starts(more[0], self._map)
            elif more:
                refits = self._map(more_starts, more)
                self.family_fits_.update(zip(more, refits, strict=True))
        if nest and more:
            # after the starts: a family still above the floor screens the mapped optima too
            self.family_fits_ = nesting_pass(
                fd, self.family_fits_, self.max_nfev, say, screen_above=good, failures=failures
            )
        for name, heldout_rms in poor.items():
            self.family_fits_[name].notes.append(
                f"its first start fitted at the noise floor but predicted the held-out runs "
                f"at RMS {heldout_rms:.4g} ({heldout_rms / fd.noise_std:.3g}x the noise): "
                "a wrong basin can fit the data it saw, so its other starts were run too"
            )
        for name, hs in helping.items():  # the helpers' fits only served as starts
            self.family_fits_[name].notes.append(
                f"its first start ended above the noise floor: {', '.join(hs)} were fitted "
                "too, their optima as further starts (not compared)"
            )
        self.family_fits_ = dict(zip(fams, self._map(with_heldout, fams), strict=True))
        if sys_fams:
            if (base := self.family_fits_.get("bouc-wen-std")) is None:
                say("stage 2: output-error fit of bouc-wen-std (the start of the system families)")
                base = first_fit("bouc-wen-std", self._shape0("bouc-wen-std"))
            for name in sys_fams:
                fit = None
                if base is None:
                    failures.record(name, "no start: the bouc-wen-std fit its starts map failed")
                else:
                    fit = failures.guard(name, self._system_fit, name, base, fd, say, failures)
                if fit is not None:
                    self.family_fits_[name] = fit
        self.family_fits_ = drop_diverged(self.family_fits_, failures)  # none is a result
        fams = [n for n in fams if n in self.family_fits_]
        same = [n for n in same if n in self.family_fits_]
        if not self.family_fits_:
            raise HystdiscError(
                f"{dataset.source}: every family failed ({failures.summary()}); fix: check "
                "the data (hystdisc report shows them) or name other families"
            )
        self.discovered_fit_ = (
            self.family_fits_[same[0]]
            if same
            else firsts[-1]
            if firsts[-1] is not None
            else min(self.family_fits_.values(), key=lambda f: f.bic)
        )

        self.envelope_ = Envelope.from_runs(fd.names, fd.t, fd.theta, fd.theta_dot, fd.currents)
        self.admissibility_ = {
            n: check_admissible(f.model, self.envelope_) for n, f in self.family_fits_.items()
        }
        self.family_, self.selection_note_ = self._select()
        self.declared_ = self.model is not None
        selected = self.family_fits_[self.family_]
        self.measured_ = []  # each measurement effect judged on the selected family
        for name in measured_effects:
            why = "found by the delay scan of stage 1, in every family of the table"
            found = failures.guard(f"effect {name}", judge_measured, fd, selected, name,
                                   self.max_nfev, self.heldout, why)  # fmt: skip
            if found is not None:
                selected, verdict = found
                self.family_fits_[self.family_] = selected
                self.measured_.append(verdict)
        # a glitch the selected model reproduces is a feature: it enters the fits again
        self.outliers_ = confirm_glitches(glitches, fd, selected.predictions)
        if self.outliers_.count:
            say(self.outliers_.summary())
        self.staged_ = None
        n_levels = distinct_currents(fd.currents).size
        if self.staged and n_levels >= MIN_STAGED_LEVELS:
            self.staged_ = failures.guard(
                "staged fit", staged_fit, fd, selected, self.max_nfev, self.heldout, say
            )
            if self.staged_ is not None and self.staged_.changed:
                # the chosen laws predict the held-out conditions better: they are the
                # selected family's model from here on (loop, results.json, predict)
                selected = self.staged_.joint
                self.family_fits_[self.family_] = selected
                self.admissibility_[self.family_] = check_admissible(selected.model, self.envelope_)
        elif self.staged:
            warnings.warn(
                f"{dataset.source}: {n_levels} current level(s); the staged fit needs "
                f"{MIN_STAGED_LEVELS} and did not run (fix: record runs at more currents)",
                HystdiscWarning,
                stacklevel=2,
            )
        self.loop_: LoopResult | None = None
        if self.close_loop:
            restart = shift_restart(dataset, self._fit_family, say, min_shift=fd.noise_std)
            self.loop_ = self._close_loop(selected, eq, fd, say, restart, failures)
        self.reselection_: Reselection | None = None
        self.reduction_: Reduction | None = None
        bics = {n: f.bic for n, f in self.family_fits_.items()}
        # the staged laws belong to the selected family alone: no other family replaces it
        staged_changed = self.staged_ is not None and self.staged_.changed
        if self.model is None and len(fams) > 1 and not staged_changed and self.loop_ is not None:
            close = lambda fit: self._close_loop(fit, eq, fd, say, restart, failures)  # noqa: E731
            ctx = Context(fd, eq, self.envelope_, close, self._stage1_shape, self.max_nfev,
                          self.heldout, self._map, say)  # fmt: skip
            again = failures.guard("comparison with the effects", compare_again,
                                   dict(self.family_fits_), self.family_, self.loop_,
                                   ctx)  # fmt: skip
            if again is not None:
                self.reselection_, self.reduction_ = again.reselection, again.reduction
            if again is not None and again.bics is not None:  # outliers as first confirmed
                self.family_, self.selection_note_ = again.family, again.note
                self.loop_, bics = again.loop, again.bics
                selected = self.family_fits_[self.family_]
        # equal fits: among the fits of the comparison that made the selection
        ref = bics[self.family_]
        self.equal_fits_ = sorted(
            n for n, b in bics.items() if b - ref < EQUAL_FIT_BIC and n != self.family_
        )
        self.final_fit_ = selected if self.loop_ is None else self.loop_.fit
        kept = [v["entry"]["name"] for v in self.measured_ if v["entry"] is not None]
        self.effects_ = kept + ([] if self.loop_ is None else list(self.loop_.effects))
        self.final_admissibility_ = (
            self.admissibility_[self.family_]
            if self.final_fit_ is selected  # the loop accepted nothing: already checked
            else check_admissible(
                self.final_fit_.model if self.final_fit_.is_system else self.final_fit_.term_part,
                self.envelope_,
            )
        )
        if not self.final_admissibility_.ok:
            warnings.warn(
                f"{dataset.source}: THE RESULT IS NOT PHYSICAL: "
                f"{'; '.join(self.final_admissibility_.violations)}; do not use the model "
                "beyond the training data (fix: see the family table for an admissible family)",
                HystdiscWarning,
                stacklevel=2,
            )
        self.failed_ = failures.items()
        self.results_ = build_results(self, dataset)
        return self

    def _fit_family(self, dataset: Dataset, family: str) -> OEFit | None:
        """``family`` fitted on ``dataset`` with this discovery's settings and all its
        starts, without the loop (the offset's restart: :mod:`hystdisc.closing.shift`)."""
        sub = clone(self).set_params(
            model=family, close_loop=False, staged=False, ensemble=False, verbose=0
        )
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return sub.fit(dataset).selected_fit_
        except (HystdiscError, np.linalg.LinAlgError, ValueError, FloatingPointError):
            return None

    def _close_loop(
        self, selected: OEFit, eq: EqData, fd: FitData, say, restart=None, failures=None
    ) -> LoopResult:
        say("closing the loop: residual -> catalogued effects")
        return close_loop(
            selected,
            fd,
            self.noise_std_,
            eq,
            self._stage1_shape(selected),
            max_nfev=self.max_nfev,
            heldout=True,
            progress=say,
            envelope=self.envelope_,
            decided=self._decided_by_staged(),
            noise_samples=self.noise_.samples,
            restart=restart,
            failures=failures,
        )

    def _select(self) -> tuple[str, str | None]:
        """The selected family and, when BIC alone would have chosen another, why not
        (:func:`~hystdisc.selection.families.select_family` on the family table)."""
        return select_family(self.family_fits_, self.admissibility_)

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
            A family's own fit; by default the selected family with the accepted effects.

        Returns
        -------
        Predictions
            Per run, a labelled ``RunPrediction`` (``run, t, current, measured, predicted``).
        """
        from hystdisc.results.predictions import label_predictions

        self._check_fitted()
        fit = self.final_fit_ if family is None else self.family_fits_[family or self.family_]
        preds = predict_dataset(fit.model, dataset, self.experiment_, self.input_hold)
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
        tm = self.discovered_fit_.term_model
        lines = [format_equation("T", tm.torque)]
        if tm.hysteresis:
            lines.append(tm.equations().splitlines()[1])
        if get_experiment(self.experiment_).inertia_identifiable:
            lines.insert(0, f"J = {tm.J:.4g}")
        return "\n".join(lines)

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
