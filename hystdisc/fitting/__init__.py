"""Stage 2: output-error fits of a structure over all runs jointly.

:class:`FitData` holds the runs as the fit sees them; a :class:`Parametrization`
(:class:`FamilyParametrization`, :class:`TermParametrization`, and
:class:`SystemParametrization` for any state-space model, :class:`StructuralParametrization`
for a family with a structural effect) maps free parameters to a model
and simulates it (:mod:`hystdisc.fitting.simulate`); :class:`OutputErrorFitter` fits it with :func:`levenberg_marquardt` and returns
an :class:`OEFit` (parameters, 95 % intervals, identifiability, BIC, held-out error);
:func:`predict_dataset` simulates a fitted model on new runs;
:mod:`hystdisc.fitting.measurement` puts the measurement chain (a channel delay, a rig's
filter) between the simulated and the recorded output.
"""

from hystdisc.fitting.data import FitData
from hystdisc.fitting.lm import levenberg_marquardt
from hystdisc.fitting.measurement import apply_filter
from hystdisc.fitting.outliers import Outliers, confirm_glitches, screen_runs
from hystdisc.fitting.output_error import OEFit, OutputErrorFitter
from hystdisc.fitting.parametrization import (
    FamilyParametrization,
    FamilySystemParametrization,
    Parametrization,
    StructuralParametrization,
    SystemParametrization,
    TermParametrization,
    family_parametrization,
)
from hystdisc.fitting.predict import predict_dataset
from hystdisc.fitting.simulate import simulate_entries, simulate_systems
from hystdisc.fitting.staged import MIN_STAGED_LEVELS, StagedFit, staged_fit

__all__ = [
    "apply_filter",
    "MIN_STAGED_LEVELS",
    "FamilyParametrization",
    "FamilySystemParametrization",
    "FitData",
    "OEFit",
    "OutputErrorFitter",
    "Outliers",
    "Parametrization",
    "StructuralParametrization",
    "StagedFit",
    "SystemParametrization",
    "TermParametrization",
    "family_parametrization",
    "confirm_glitches",
    "levenberg_marquardt",
    "predict_dataset",
    "screen_runs",
    "simulate_entries",
    "simulate_systems",
    "staged_fit",
]
