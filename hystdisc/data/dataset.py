"""The data structures: a :class:`Run` (one record at constant current) and a :class:`Dataset`.

A :class:`Dataset` is several runs of one rig and one experiment type (``release``,
``driven`` or ``forced``; the experiment objects in :mod:`hystdisc.experiments` say what
each one measures). This module also holds the column names every reader uses and the
grouping of currents into levels (:func:`distinct_currents`). The package's docstring
(:mod:`hystdisc.data`) shows a dataset built by hand.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hystdisc import registry
from hystdisc.errors import input_error

__all__ = [
    "CANONICAL_COLUMNS",
    "EXPERIMENTS",
    "Dataset",
    "Run",
    "distinct_currents",
]

EXPERIMENTS: tuple[str, ...] = registry.experiment_names()
"""Experiment types (``release``, ``driven``, ``forced``), from :mod:`hystdisc.registry`."""

CANONICAL_COLUMNS = (
    "run",
    "t",
    "theta",
    "current",
    "torque",
    "input",
    "theta_dot",
    "condition",
)
"""Names of the columns (variables) a data file may provide."""

#: the per-sample signals of a run
SIGNAL_COLUMNS = ("t", "theta", "torque", "input", "theta_dot")
#: the column-mapping option named in the fixes of the messages
COLUMN_FLAG = "--column"


def extra_column(experiment: str) -> str | None:
    """The column a record of ``experiment`` needs besides ``t``, ``theta`` and ``current``.

    Examples
    --------
    >>> extra_column("driven"), extra_column("forced"), extra_column("release")
    ('torque', 'input', None)
    """
    return registry.get_experiment(experiment).extra_column


def extra_columns() -> tuple[str, ...]:
    """Every experiment's extra column (``torque``, ``input``), in registry order."""
    found = (extra_column(name) for name in EXPERIMENTS)
    return tuple(c for c in found if c is not None)


def needed_columns(experiment: str) -> list[str]:
    """The columns a record of ``experiment`` must have."""
    extra = extra_column(experiment)
    return ["t", "theta", "current"] + ([extra] if extra else [])


def as_vector(value: Any, what: str, run: str, source: str | None) -> np.ndarray:
    """Convert ``value`` to a contiguous float64 1-D array, or raise a HystdiscError."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise input_error(
            source,
            f"{what} is not numeric ({type(exc).__name__}: {exc})",
            f"pass {what} as an array of numbers",
            run=run,
        ) from None
    if arr.ndim != 1:
        if arr.ndim == 0 or arr.size != max(arr.shape):
            raise input_error(
                source,
                f"{what} has shape {arr.shape}, expected a vector",
                f"pass {what} as a 1-D array (one value per sample)",
                run=run,
            )
        arr = arr.reshape(-1)
    return np.ascontiguousarray(arr)


def check_experiment(experiment: Any, source: str | None) -> str:
    """The experiment type as its registered name, or a one-line error."""
    text = str(experiment).strip().lower()
    if text not in EXPERIMENTS:
        raise input_error(
            source,
            f"unknown experiment type {experiment!r}",
            f"use one of {', '.join(EXPERIMENTS)} (--experiment)",
        )
    return text


@dataclass(eq=False)
class Run:
    """One record at constant coil current.

    Parameters
    ----------
    name : str
        Run id as text (``"0"``, ``"1"`` or a file stem such as ``"10mm1Hz0x5A"``).
    t : array_like
        Time in seconds, strictly increasing.
    theta : array_like
        Angle in rad (or displacement in m for linear dampers).
    current : float
        Coil current of the run in A (constant per run).
    torque : array_like, optional
        Measured torque / force (driven experiments), N·m or N.
    input : array_like, optional
        Known input torque / force (forced experiments).
    theta_dot : array_like, optional
        Measured velocity, rad/s or m/s.
    source : str, optional
        File the run was read from (used in error messages).
    lines : array_like of int, optional
        1-based line number in ``source`` of every sample (used in error messages).
    condition : str, optional
        The test condition the run belongs to (runs that share an input: a sine, a release
        angle, an input record); detected from the data when not given (see
        :mod:`hystdisc.data.conditions`).

    Notes
    -----
    Arrays are converted to contiguous float64 1-D arrays; ``1 x N`` and ``N x 1`` inputs are
    flattened. Consistency (lengths, finiteness, sampling) is checked by
    :func:`hystdisc.data.validate`, not here.

    Examples
    --------
    >>> import numpy as np
    >>> r = Run("0", np.arange(5) * 0.01, [[0.0, 1.0, 0.0, -1.0, 0.0]], 0.5)
    >>> r.theta.shape, r.n, round(r.fs, 6), round(r.duration, 6)
    ((5,), 5, 100.0, 0.04)
    """

    name: str
    t: np.ndarray
    theta: np.ndarray
    current: float
    torque: np.ndarray | None = None
    input: np.ndarray | None = None
    theta_dot: np.ndarray | None = None
    source: str | None = field(default=None, repr=False)
    lines: np.ndarray | None = field(default=None, repr=False)
    condition: str | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.name = str(self.name)
        for key in SIGNAL_COLUMNS:
            value = getattr(self, key)
            if value is not None or key in ("t", "theta"):
                setattr(self, key, as_vector(value, key, self.name, self.source))
        try:
            self.current = float(np.asarray(self.current, dtype=np.float64).reshape(()))
        except (TypeError, ValueError):
            raise input_error(
                self.source,
                f"current {self.current!r} is not a single number",
                "give the run one coil current in A",
                run=self.name,
            ) from None
        if self.lines is not None:
            self.lines = np.asarray(self.lines, dtype=np.int64).reshape(-1)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def fs(self) -> float:
        """Sampling rate ``1 / median(dt)`` in Hz (``nan`` for fewer than two samples)."""
        if self.t.size < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` in seconds (0 for an empty run)."""
        if self.t.size == 0:
            return 0.0
        return float(self.t[-1] - self.t[0])

    def __repr__(self) -> str:
        extra = [k for k in ("torque", "input", "theta_dot") if getattr(self, k) is not None]
        more = f", with {'/'.join(extra)}" if extra else ""
        return (
            f"Run({self.name!r}, {self.n} samples, {self.duration:.4g} s, {self.current:g} A{more})"
        )


@dataclass(eq=False)
class Dataset:
    """Several runs of one rig and one experiment type.

    Parameters
    ----------
    runs : list of Run
        The runs, usually one per current step.
    experiment : str
        One of :data:`EXPERIMENTS`.
    source : str
        The file path(s) as text, used in messages.
    filter : dict, optional
        How the recorded signals were filtered before they reached hystdisc (a rig's
        checked ``[filter]`` table, see :func:`hystdisc.data.read_rig`); None: not filtered.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(50) * 1e-3
    >>> ds = Dataset([Run(str(i), t, np.cos(t), 0.25 * i) for i in range(3)], "release", "x.csv")
    >>> ds
    Dataset(release, 3 runs, currents [0, 0.25, 0.5] A, 150 samples, source='x.csv')
    >>> ds.subset([0, 2]).currents.tolist(), [r.name for r in ds]
    ([0.0, 0.5], ['0', '1', '2'])
    """

    runs: list[Run]
    experiment: str
    source: str = ""
    filter: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        self.runs = list(self.runs)
        self.experiment = check_experiment(self.experiment, self.source)
        self.source = str(self.source)

    @property
    def currents(self) -> np.ndarray:
        """Coil current of every run, in A."""
        return np.array([r.current for r in self.runs], dtype=np.float64)

    @property
    def names(self) -> list[str]:
        """Run names, in order."""
        return [r.name for r in self.runs]

    def measured(self) -> str:
        """Name of the measured output: ``"torque"`` for driven, else ``"theta"``."""
        return registry.get_experiment(self.experiment).output

    def subset(self, indices: int | slice | Iterable[int | str | bool]) -> Dataset:
        """Dataset with the selected runs (indices, run names, a slice or a boolean mask)."""
        if isinstance(indices, slice):
            runs = self.runs[indices]
        elif isinstance(indices, (int, np.integer, str)):
            runs = [self._pick(indices)]
        else:
            items = list(indices)
            if items and all(isinstance(i, (bool, np.bool_)) for i in items):
                if len(items) != len(self.runs):
                    raise input_error(
                        self.source,
                        f"boolean mask has {len(items)} entries for {len(self.runs)} runs",
                        "pass one True/False per run",
                    )
                runs = [r for r, keep in zip(self.runs, items, strict=True) if keep]
            else:
                runs = [self._pick(i) for i in items]
        return Dataset(list(runs), self.experiment, self.source, self.filter)

    def _pick(self, key: int | str) -> Run:
        if isinstance(key, str):
            for r in self.runs:
                if r.name == key:
                    return r
            raise input_error(
                self.source,
                f"no run named {key!r}",
                f"use one of {', '.join(self.names[:10])}",
            )
        try:
            return self.runs[int(key)]
        except IndexError:
            raise input_error(
                self.source,
                f"run index {int(key)} is out of range ({len(self.runs)} runs)",
                f"use an index from 0 to {len(self.runs) - 1}",
            ) from None

    def __getitem__(self, key: int | str) -> Run:
        return self._pick(key)

    def __len__(self) -> int:
        return len(self.runs)

    def __iter__(self) -> Iterator[Run]:
        return iter(self.runs)

    def __repr__(self) -> str:
        cur = ", ".join(f"{c:g}" for c in distinct_currents(self.currents))
        samples = sum(r.n for r in self.runs)
        return (
            f"Dataset({self.experiment}, {len(self.runs)} runs, currents [{cur}] A, "
            f"{samples} samples, source={self.source!r})"
        )


def distinct_currents(currents: Iterable[float]) -> np.ndarray:
    """Distinct current levels, sorted.

    Two currents count as the same level when they differ by at most
    ``max(0.02 A, 5 % of the larger magnitude)``, the tolerance
    :func:`hystdisc.data.validate` allows within one run. Each level is reported as the
    median of its members.

    Examples
    --------
    >>> distinct_currents([0.5, 0.0, 0.501, 1.0, 0.25]).tolist()
    [0.0, 0.25, 0.5005, 1.0]
    """
    values = np.sort(np.asarray(list(currents), dtype=np.float64).reshape(-1))
    values = values[np.isfinite(values)]
    groups: list[list[float]] = []
    for v in values:
        if groups:
            first = groups[-1][0]
            if abs(v - first) <= max(0.02, 0.05 * max(abs(v), abs(first))):
                groups[-1].append(float(v))
                continue
        groups.append([float(v)])
    return np.array([float(np.median(g)) for g in groups], dtype=np.float64)
