"""The measurement as the fits see it: the runs prepared, glitches screened, the chain between
the damper and the record.

:func:`~hystdisc.measurement.prepare.prepare_data` turns a dataset into the equation-error
data of stage 1 and the :class:`FitData` of stage 2 (the runs as measured, the imposed
motion as estimated: :mod:`hystdisc.measurement.motion`); isolated glitches are screened
out (:mod:`hystdisc.measurement.outliers`); :mod:`hystdisc.measurement.chain` puts the
measurement chain (a channel delay, a rig's filter) between the simulated and the
recorded output.
"""

from hystdisc.measurement.chain import apply_filter
from hystdisc.measurement.fitdata import FitData
from hystdisc.measurement.outliers import Outliers, confirm_glitches, screen_runs
from hystdisc.measurement.prepare import prepare_data

__all__ = ["FitData", "Outliers", "apply_filter", "confirm_glitches", "prepare_data", "screen_runs"]
