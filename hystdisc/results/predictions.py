"""Labelled predictions: what :meth:`hystdisc.Discovery.predict` returns.

A prediction of a run is only useful with the run it belongs to: its name, times,
current and the measured signal it is compared with. :class:`RunPrediction` keeps them
together; it also behaves as the array of predicted values in arithmetic and in numpy
functions (``np.max(np.abs(p - r.torque))``, ``np.concatenate(preds)``), which is what
``predict`` returned before. :class:`Predictions` is the list of them, one per run, with
the long table ``hystdisc predict`` writes (``run, t, current, measured, predicted``).

Examples
--------
>>> import numpy as np
>>> from hystdisc.data import Dataset, Run
>>> t = np.arange(4) * 0.1
>>> ds = Dataset([Run("a", t, np.array([0.3, 0.2, 0.1, 0.0]), 0.5)], "release", "x.csv")
>>> preds = label_predictions(ds, [np.array([0.3, 0.21, 0.1, 0.01])])
>>> p = preds[0]
>>> p.run, p.current, p.signal, round(p.rms, 4)
('a', 0.5, 'theta', 0.0071)
>>> float(np.max(np.abs(p - ds.runs[0].theta)))  # arithmetic on the predicted values
0.01
>>> sorted(preds.table())
['current', 'measured', 'predicted', 'run', 't']
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.mixins import NDArrayOperatorsMixin

from hystdisc.data import Dataset
from hystdisc.registry import get_experiment

__all__ = ["Predictions", "RunPrediction", "label_predictions"]


@dataclass(frozen=True, eq=False)
class RunPrediction(NDArrayOperatorsMixin):
    """The simulated output of one run, with the run it belongs to.

    In arithmetic and numpy functions it is the array :attr:`predicted`.

    Attributes
    ----------
    run : str
        The run's name.
    t : ndarray
        Sample times, s.
    current : float
        Coil current, A.
    measured : ndarray
        The measured output (angle; torque for a driven run).
    predicted : ndarray
        The simulated output on the same samples.
    signal : str
        Which output: ``"theta"`` or ``"torque"``.
    """

    run: str
    t: np.ndarray
    current: float
    measured: np.ndarray
    predicted: np.ndarray
    signal: str

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        return np.asarray(self.predicted, dtype=dtype)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        plain = [x.predicted if isinstance(x, RunPrediction) else x for x in inputs]
        return getattr(ufunc, method)(*plain, **kwargs)

    def __len__(self) -> int:
        return len(self.predicted)

    def __getitem__(self, key):
        return self.predicted[key]

    @property
    def residual(self) -> np.ndarray:
        """Predicted minus measured, per sample."""
        return np.asarray(self.predicted) - np.asarray(self.measured)

    @property
    def rms(self) -> float:
        """RMS of :attr:`residual`, in data units."""
        return float(np.sqrt(np.mean(self.residual**2)))

    def __repr__(self) -> str:
        return (
            f"RunPrediction(run={self.run!r}, current={self.current:g} A, "
            f"{len(self.predicted)} samples of {self.signal}, RMS error {self.rms:.4g})"
        )


class Predictions(list):
    """The predictions of every run of a dataset (a list of :class:`RunPrediction`)."""

    def table(self) -> dict[str, np.ndarray]:
        """The long table, one row per sample: ``run, t, current, measured, predicted``.

        Returns
        -------
        dict of str to ndarray
            Equal-length columns (``pandas.DataFrame(preds.table())`` makes a frame).
        """
        cols: dict[str, list[np.ndarray]] = {k: [] for k in ("run", "t", "current")}
        cols.update(measured=[], predicted=[])
        for p in self:
            n = len(p.predicted)
            cols["run"].append(np.full(n, p.run, dtype=object))
            cols["t"].append(np.asarray(p.t, dtype=float))
            cols["current"].append(np.full(n, float(p.current)))
            cols["measured"].append(np.asarray(p.measured, dtype=float))
            cols["predicted"].append(np.asarray(p.predicted, dtype=float))
        return {
            k: np.concatenate(v) if v else np.array([], dtype=object if k == "run" else float)
            for k, v in cols.items()
        }

    def __repr__(self) -> str:
        return "Predictions([\n" + "".join(f"  {p!r},\n" for p in self) + "])"


def label_predictions(dataset: Dataset, predicted: Sequence[np.ndarray]) -> Predictions:
    """Put each run's simulated output together with the run.

    Parameters
    ----------
    dataset : Dataset
        The runs that were simulated.
    predicted : sequence of ndarray
        The simulated output of each run, in the dataset's order.

    Returns
    -------
    Predictions
        One :class:`RunPrediction` per run.
    """
    signal = get_experiment(dataset.experiment).output
    return Predictions(
        RunPrediction(
            run=r.name,
            t=r.t,
            current=float(r.current),
            measured=getattr(r, signal),
            predicted=np.asarray(p),
            signal=signal,
        )
        for r, p in zip(dataset.runs, predicted, strict=True)
    )
