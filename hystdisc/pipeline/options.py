"""The settings of one discovery: :class:`Options`.

The :class:`~hystdisc.Discovery` estimator stores its parameters as scikit-learn asks; the
pipeline reads them from one frozen record, so that a stage can neither change a setting
nor depend on the estimator. A few settings are the pipeline's alone, for benchmarks and
numerical studies (:func:`hystdisc.pipeline.run` with ``Options(...)``): how the fits
integrate (``integration``), how a driven run's motion is estimated (``motion``) and
whether its errors enter the intervals (``motion_errors``). The settings of the fits
travel with their data (:class:`~hystdisc.measurement.FitData`), so every fit of a
discovery, its held-out folds and the closing loop's refits included, computes alike:
there are no module switches.

Examples
--------
>>> opts = Options(families=("dahl",), heldout=False)
>>> opts.family_list()
['dahl']
>>> opts.replace(model="lugre").family_list()
['lugre']
>>> Options().jacobian, Options().integration.rtol, Options().motion
('exact', 1e-10, 'auto')
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hystdisc.discovery import DEFAULT_SHAPES, DEFAULT_TORQUE_TERMS
from hystdisc.registry import family_names, get_family
from hystdisc.simulation import Integration


@dataclass(frozen=True)
class Options:
    """What a discovery is asked to do: the parameters of :class:`~hystdisc.Discovery`
    (documented there), and the pipeline's own settings below.

    Attributes
    ----------
    integration : Integration
        How the output-error fits integrate their candidates (the fits' own settings by
        default; :data:`~hystdisc.fitting.system_jacobian.LOCKSTEP_INTEGRATION` suits
        ``jacobian="lockstep"``).
    motion : {"auto", "legacy"}
        Driven data: how the imposed motion is estimated
        (:func:`~hystdisc.measurement.motion.estimate_motion`; ``"legacy"``: the
        equation-error stage's smoother, as before issue 33).
    motion_errors : bool
        Driven data: the motion estimate's errors enter the intervals
        (:mod:`hystdisc.fitting.motion_error`; False: as before issue 33).
    """

    experiment: str | None = None
    families: Sequence[str] | None = None
    model: str | None = None
    torque_terms: Sequence[str] = DEFAULT_TORQUE_TERMS
    shapes: Sequence[str] = DEFAULT_SHAPES
    threshold: float | None = None
    ensemble: bool = False
    heldout: bool = True
    seed: int = 0
    max_nfev: int = 40
    close_loop: bool = True
    input_hold: str = "cubic"
    single_current: bool = False
    n_jobs: int | None = None
    staged: bool = False
    n_starts: int = 4
    jacobian: str = "exact"
    detect_filter: bool = True
    # the pipeline's own (not parameters of Discovery)
    integration: Integration = field(default_factory=Integration)
    motion: str = "auto"
    motion_errors: bool = True

    @classmethod
    def of(cls, params: Mapping[str, Any]) -> Options:
        """The options among ``params`` (an estimator's ``get_params()``; others ignored)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in params.items() if k in names})

    def replace(self, **changes: Any) -> Options:
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)

    def family_list(self) -> list[str]:
        """The families asked for, by their registered names (the declared one alone)."""
        if self.model is not None:
            return [get_family(self.model).name]
        return [get_family(f).name for f in (self.families or family_names())]
