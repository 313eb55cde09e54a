"""The operating envelope of the training data, and how far a new record goes beyond it.

A model identified on sine tests up to 88 mm/s says nothing reliable at 126 mm/s. The
envelope records what the training runs covered (displacement, velocity, current,
frequency, duration), travels with the model in ``results.json`` under ``envelope``, and
:meth:`Envelope.beyond` says, run by run, where a new record leaves it.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0.0, 2.0, 2001)
>>> x = 0.01 * np.sin(2 * np.pi * t)
>>> env = Envelope.from_runs(["a"], [t], [x], [2 * np.pi * 0.01 * np.cos(2 * np.pi * t)], [0.5])
>>> round(env.theta_dot_max, 4), env.current_range
(0.0628, (0.5, 0.5))
>>> new = RunEnvelope.measure("b", t, 2 * x, 4 * np.pi * 0.01 * np.cos(2 * np.pi * t), 1.0)
>>> for line in env.beyond([new], unit="m"):
...     print(line)
run b: peak displacement 0.02 m is 2x the largest in training (0.01 m)
run b: peak velocity 0.126 m/s is 2x the largest in training (0.0628 m/s)
run b: current 1 A is outside the training range 0.5 to 0.5 A
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

#: A record counts as beyond the envelope when it exceeds it by more than this fraction.
MARGIN = 0.05


def _peak(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(x))) if x.size else 0.0


@dataclass
class RunEnvelope:
    """What one run covers.

    Attributes
    ----------
    name : str
        The run's name.
    current : float
        Its coil current.
    theta_max : float
        Largest absolute displacement (angle), data units.
    theta_dot_max : float
        Largest absolute velocity, data units per second.
    duration : float
        Length of the record, s.
    """

    name: str
    current: float
    theta_max: float
    theta_dot_max: float
    duration: float

    @classmethod
    def measure(
        cls, name: str, t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray, current: float
    ) -> RunEnvelope:
        """The envelope of one run from its (smoothed) displacement and velocity."""
        t = np.asarray(t, dtype=float)
        return cls(
            str(name),
            float(current),
            _peak(theta),
            _peak(theta_dot),
            float(t[-1] - t[0]) if t.size else 0.0,
        )


@dataclass
class Envelope:
    """The training envelope: every run's and the overall extremes.

    Attributes
    ----------
    runs : list of RunEnvelope
        Each training run.
    theta_max : float
        Largest absolute displacement over the runs.
    theta_dot_max : float
        Largest absolute velocity over the runs.
    current_range : tuple of float
        Smallest and largest current.
    """

    runs: list[RunEnvelope] = field(default_factory=list)

    @classmethod
    def from_runs(
        cls,
        names: Sequence[str],
        t: Sequence[np.ndarray],
        theta: Sequence[np.ndarray],
        theta_dot: Sequence[np.ndarray],
        currents: Sequence[float],
    ) -> Envelope:
        """Measure every run (see :meth:`RunEnvelope.measure`)."""
        return cls(
            [
                RunEnvelope.measure(*args)
                for args in zip(names, t, theta, theta_dot, currents, strict=True)
            ]
        )

    @property
    def theta_max(self) -> float:
        """The largest ``|theta|`` over the runs."""
        return max((r.theta_max for r in self.runs), default=0.0)

    @property
    def theta_dot_max(self) -> float:
        """The largest ``|theta_dot|`` over the runs."""
        return max((r.theta_dot_max for r in self.runs), default=0.0)

    @property
    def current_range(self) -> tuple[float, float]:
        """The lowest and highest current of the runs."""
        cs = [r.current for r in self.runs] or [0.0]
        return (min(cs), max(cs))

    def to_dict(self) -> dict[str, Any]:
        """The ``envelope`` entry of ``results.json``."""
        lo, hi = self.current_range
        return {
            "theta_max": self.theta_max,
            "theta_dot_max": self.theta_dot_max,
            "current_min": lo,
            "current_max": hi,
            "runs": [asdict(r) for r in self.runs],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Envelope:
        """Read the ``envelope`` entry of ``results.json``."""
        return cls([RunEnvelope(**r) for r in d.get("runs", [])])

    def beyond(self, runs: Sequence[RunEnvelope], unit: str = "rad") -> list[str]:
        """One line per way a run leaves the envelope (nothing when all stay inside).

        Parameters
        ----------
        runs : sequence of RunEnvelope
            The new records.
        unit : str
            Unit of the displacement column, for the messages.
        """
        out = []
        lo, hi = self.current_range
        for r in runs:
            for what, val, ref, u in (
                ("displacement", r.theta_max, self.theta_max, unit),
                ("velocity", r.theta_dot_max, self.theta_dot_max, f"{unit}/s"),
            ):
                if ref > 0 and val > (1.0 + MARGIN) * ref:
                    out.append(
                        f"run {r.name}: peak {what} {val:.3g} {u} is {val / ref:.2g}x the "
                        f"largest in training ({ref:.3g} {u})"
                    )
            span = max(hi - lo, abs(hi), 1e-12)
            if r.current < lo - MARGIN * span or r.current > hi + MARGIN * span:
                out.append(
                    f"run {r.name}: current {r.current:.3g} A is outside the training range "
                    f"{lo:.3g} to {hi:.3g} A"
                )
        return out
