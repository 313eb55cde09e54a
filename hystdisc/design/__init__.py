"""Experiment design: which runs to record next to shrink a fit's intervals.

:func:`design` takes a fit (:class:`~hystdisc.results.Results`), computes the Fisher
information of candidate runs from the fitted model's output sensitivities and chooses
the runs that most shrink the widest 95 % interval (:class:`DesignResult`). The modules:
:mod:`~hystdisc.design.runs` (the candidate runs), :mod:`~hystdisc.design.information`
(the information of a run), :mod:`~hystdisc.design.select` (the choice) and
:mod:`~hystdisc.design.plan` (the whole design).
"""

from hystdisc.design.base import DesignResult
from hystdisc.design.plan import Information, design, expected_widths, information_in_hand
from hystdisc.design.runs import RunSpec, candidate_runs, recorded_runs

__all__ = [
    "DesignResult",
    "Information",
    "RunSpec",
    "candidate_runs",
    "design",
    "expected_widths",
    "information_in_hand",
    "recorded_runs",
]
