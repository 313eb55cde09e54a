"""One discovery's typed state: :class:`State`, filled stage after stage.

Each stage of :mod:`hystdisc.pipeline.run` reads what the stages before it wrote and
writes its own fields; :meth:`State.fitted` hands the results to the estimator (its
fitted attributes, named as the fields with a trailing ``_``) and
:func:`~hystdisc.pipeline.record.build_results` writes ``results.json`` from it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hystdisc.closing import LoopResult
from hystdisc.closing.measured import MeasuredVerdict
from hystdisc.closing.open_library import ResidualTerms
from hystdisc.closing.reduction import Reduction
from hystdisc.closing.reselect import Reselection
from hystdisc.data import Dataset, FilterFound
from hystdisc.data.envelope import Envelope
from hystdisc.data.noise import NoiseEstimate
from hystdisc.discovery import FAMILY_SHAPE, EqData, ShapeFit
from hystdisc.discovery.delay import DelayScan
from hystdisc.faults import Failures
from hystdisc.fitting import OEFit
from hystdisc.measurement import FitData, Outliers
from hystdisc.models import TermModel
from hystdisc.pipeline.options import Options
from hystdisc.pipeline.tasks import Tasks, ThreadTasks
from hystdisc.selection import StagedFit

#: The fields the estimator exposes as fitted attributes (each with a trailing ``_``).
FITTED = (
    "experiment", "noise_std", "noise", "n_runs", "currents", "single_current", "window",
    "fit_data", "conditions", "envelope", "admissibility", "selection_note", "eq_data",
    "stage1", "discovered_shape", "discovered_name", "discovered", "terms", "family_fits",
    "discovered_fit", "family", "declared", "equal_fits", "loop", "final_fit",
    "reselection", "reduction", "effects", "final_admissibility", "outliers", "staged",
    "delay_scan", "measured", "failed", "open_library", "prefilter",
)  # fmt: skip


@dataclass
class State:
    """Everything one discovery knows, in the order the stages learn it.

    The fields named in :data:`FITTED` are documented as the fitted attributes of
    :class:`~hystdisc.Discovery`; the others are the stages' working state.
    """

    dataset: Dataset
    options: Options
    say: Callable[[str], None] = field(repr=False)
    failures: Failures = field(default_factory=Failures, repr=False)
    # where the independent tasks run (default: ThreadTasks(options.n_jobs))
    tasks: Tasks | None = field(default=None, repr=False)
    # prepare
    prefilter: FilterFound | None = None  # a moving average read in the records
    single_current: bool = False
    experiment: str = ""
    noise: NoiseEstimate | None = None
    eq_data: EqData | None = None
    fit_data: FitData | None = None
    glitches: list[dict] = field(default_factory=list, repr=False)
    library: list[str] = field(default_factory=list)  # stage 1's torque terms
    compared: list[str] = field(default_factory=list)  # the term families compared
    systems: list[str] = field(default_factory=list)  # the state-space families compared
    # stage 1 and the first fits
    stage1: dict[str, ShapeFit] = field(default_factory=dict)
    discovered_shape: str = ""
    discovered_name: str = ""
    discovered: TermModel | None = None
    terms: dict[str, list[str]] = field(default_factory=dict)
    same: list[str] = field(default_factory=list)  # the families stage 1 discovered
    first_discovered: OEFit | None = None  # the discovered structure's own fit (or None)
    delay_scan: DelayScan | None = None
    # the measurement effects every family carries (a channel delay stage 1 found) and
    # the starts of their parameters
    chain_effects: list[str] = field(default_factory=list)
    chain: dict[str, float] = field(default_factory=dict)
    # stage 2
    family_fits: dict[str, OEFit] = field(default_factory=dict)
    discovered_fit: OEFit | None = None
    # selection
    envelope: Envelope | None = None
    admissibility: dict[str, Any] = field(default_factory=dict)
    family: str = ""
    selection_note: str | None = None
    declared: bool = False
    measured: list[MeasuredVerdict] = field(default_factory=list)
    outliers: Outliers | None = None
    staged: StagedFit | None = None
    # the closing loop and the comparison again
    loop: LoopResult | None = None
    reselection: Reselection | None = None
    reduction: Reduction | None = None
    bics: dict[str, float] = field(default_factory=dict)
    equal_fits: list[str] = field(default_factory=list)
    final_fit: OEFit | None = None
    effects: list[str] = field(default_factory=list)
    final_admissibility: Any = None
    # what the open library finds in a residual the catalogue leaves (or None)
    open_library: ResidualTerms | None = None
    open_library_of: OEFit | None = field(default=None, repr=False)  # the fit it regressed
    failed: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.tasks is None:
            self.tasks = ThreadTasks(self.options.n_jobs)

    # -- what the stages derive
    @property
    def eq(self) -> EqData:
        """The equation-error data (after the preparation)."""
        assert self.eq_data is not None, "the data are not prepared yet"
        return self.eq_data

    @property
    def fd(self) -> FitData:
        """The output-error data (after the preparation)."""
        assert self.fit_data is not None, "the data are not prepared yet"
        return self.fit_data

    @property
    def noise_std(self) -> float:
        """The estimated noise of the output, data units."""
        return self.fd.noise_std

    @property
    def n_runs(self) -> int:
        """Runs fitted."""
        return self.fd.n_runs

    @property
    def currents(self) -> np.ndarray:
        """Each run's current."""
        return self.fd.currents

    @property
    def window(self) -> int:
        """The smoothing window of stage 1's derivatives, in its samples."""
        return self.eq.window

    @property
    def conditions(self) -> list[str]:
        """Each run's test condition."""
        return list(self.fd.conditions)

    def map(self, fn: Callable, items: list, serial: bool = False) -> list:
        """``fn`` over ``items`` (independent fits) on the discovery's engine
        (:attr:`tasks`: its threads or a Dask cluster), in order; ``serial``: in turn."""
        return self.tasks.map(fn, items, serial)

    def map_after(
        self, before: Callable, before_items: list, after: Callable, after_items: list,
        serial_before: bool = False,
    ) -> tuple[list, list]:  # fmt: skip
        """``before`` over ``before_items``, then ``after(item, ready)`` over
        ``after_items`` (``ready(k)``: the ``k``-th ``before`` result) on the discovery's
        engine (:func:`~hystdisc.simulation.parallel.map_after` on its threads)."""
        return self.tasks.map_after(before, before_items, after, after_items, serial_before)

    def shape0(self, name: str) -> np.ndarray | None:
        """The stage-1 shape constants of family ``name``'s shape (None before stage 1 or
        for a family without one)."""
        found = self.stage1.get(FAMILY_SHAPE.get(name, ""))
        return None if found is None else np.asarray(found.s, dtype=float)

    def stage1_shape(self, fit: OEFit) -> np.ndarray | None:
        """The stage-1 shape constants of the fitted family's hysteresis shape."""
        return self.shape0(fit.par.family.name)

    def fitted(self) -> dict[str, Any]:
        """The estimator's fitted attributes: field name (without the ``_``) -> value."""
        return {name: getattr(self, name) for name in FITTED}
