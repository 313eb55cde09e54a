"""A fitted model applied: predictions on new runs and the export to python-control.

:func:`~hystdisc.apply.predict.predict_dataset` simulates a fitted model on the runs of
a dataset as the fit would see them (the imposed motion estimated as the fit estimates
it, the measurement chain applied); :mod:`hystdisc.apply.control` builds a
python-control system of the damper and the SAS rig around it.
"""

from hystdisc.apply.predict import predict_dataset

__all__ = ["predict_dataset"]
