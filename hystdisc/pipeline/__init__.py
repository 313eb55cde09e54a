"""The pipeline of one discovery: named stages over one typed state.

:func:`run` runs the stages (:mod:`hystdisc.pipeline.run`) on a dataset with
:class:`Options` and returns the :class:`State`; :func:`build_results` writes its
``results.json`` record. :class:`hystdisc.Discovery` is the scikit-learn face of it.
"""

from hystdisc.pipeline.options import Options
from hystdisc.pipeline.record import build_results
from hystdisc.pipeline.run import fit_family, run, stderr_printer
from hystdisc.pipeline.state import FITTED, State

__all__ = ["FITTED", "Options", "State", "build_results", "fit_family", "run", "stderr_printer"]
