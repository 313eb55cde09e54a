"""Stage 2: output-error fits of a structure over all runs jointly.

A :class:`Parametrization` (:class:`FamilyParametrization`, :class:`TermParametrization`,
and :class:`SystemParametrization` for any state-space model,
:class:`StructuralParametrization` for a family with a structural effect) maps free
parameters to a model and simulates it on the runs as the fit sees them
(:class:`~hystdisc.measurement.FitData`, :mod:`hystdisc.fitting.simulate`);
:class:`OutputErrorFitter` fits it with :func:`levenberg_marquardt` and returns an
:class:`OEFit` (parameters, 95 % intervals and identifiability:
:mod:`~hystdisc.fitting.intervals`, BIC, held-out error: :mod:`~hystdisc.fitting.heldout`);
how it takes its Jacobian is
:data:`~hystdisc.fitting.jacobian.JACOBIAN_MODES`;
:mod:`hystdisc.fitting.multistart` makes the fits global (several starts, nesting kept
consistent). What the fits are given is made in :mod:`hystdisc.measurement`, what they
are used for in :mod:`hystdisc.apply` (predictions, control export) and
:mod:`hystdisc.selection` (family choice, current laws, the staged flowchart).
"""

from hystdisc.fitting.lm import levenberg_marquardt
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
from hystdisc.fitting.simulate import simulate_entries, simulate_systems

__all__ = [
    "FamilyParametrization",
    "FamilySystemParametrization",
    "OEFit",
    "OutputErrorFitter",
    "Parametrization",
    "StructuralParametrization",
    "SystemParametrization",
    "TermParametrization",
    "family_parametrization",
    "levenberg_marquardt",
    "simulate_entries",
    "simulate_systems",
]
