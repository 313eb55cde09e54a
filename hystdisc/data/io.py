"""Reading, checking and writing measured runs.

A :class:`Run` is one record at constant coil current; a :class:`Dataset` is several runs of
one rig and one experiment type (``release``, ``driven`` or ``forced``, see DESIGN.md
section 1). Data comes in as

* long-format CSV (:func:`read_csv`): ``run,t,theta,current`` plus ``torque`` (driven) or
  ``input`` (forced), optional ``theta_dot``;
* MATLAB ``.mat`` files (:func:`read_mat`);
* header-less whitespace tables described by a column map or a ``rig.toml`` file
  (:func:`read_table`, :func:`read_rig`).

:func:`load` is the single entry point used by the command line: it accepts files or folders
and dispatches on the file extension. Every reader checks what it read with
:func:`validate`; every problem with the input is raised as a one-line
:class:`~hystdisc.errors.HystdiscError` naming the file, the run, the problem and the fix.

Outputs are written with :func:`atomic_write_text` / :func:`atomic_write_bytes`, which never
overwrite an existing file unless ``force=True`` and never leave a half-written file.

Examples
--------
>>> import numpy as np
>>> from hystdisc.data.io import Run, Dataset
>>> t = np.arange(100) / 100.0
>>> ds = Dataset([Run("0", t, np.sin(t), 0.0), Run("1", t, np.sin(t), 0.5)], "release", "demo")
>>> len(ds), ds.measured(), ds.currents.tolist()
(2, 'theta', [0.0, 0.5])
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import math
import os
import re
import secrets
import signal
import struct
import warnings
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc.errors import HystdiscError, HystdiscWarning, input_error

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "HystdiscError",
    "CANONICAL_COLUMNS",
    "DATA_SUFFIXES",
    "DEFAULT_CURRENT_PATTERN",
    "EXPERIMENTS",
    "MIN_SAMPLES",
    "Dataset",
    "Run",
    "atomic_write_bytes",
    "atomic_write_text",
    "current_from_name",
    "distinct_currents",
    "estimate_noise",
    "load",
    "read_csv",
    "read_mat",
    "read_rig",
    "read_table",
    "trim_release",
    "unit_factor",
    "validate",
    "write_csv",
]

EXPERIMENTS = ("release", "driven", "forced")
"""Experiment types, see DESIGN.md section 1."""

CANONICAL_COLUMNS = ("run", "t", "theta", "current", "torque", "input", "theta_dot")
"""Names of the columns (variables) a data file may provide."""

DATA_SUFFIXES = (".txt", ".dat", ".csv", ".mat")
"""File extensions :func:`load` picks up when given a folder."""

DEFAULT_CURRENT_PATTERN = r"(\d+(?:x\d+)?)A$"
"""Default pattern for :func:`current_from_name`: ``...0x75A`` -> 0.75 A."""

MIN_SAMPLES = 20
"""Shortest run :func:`validate` accepts."""

_SIGNAL_COLUMNS = ("t", "theta", "torque", "input", "theta_dot")
_EXTRA_COLUMN = {"driven": "torque", "forced": "input", "release": None}
_COLUMN_FLAG = "--column"


# --------------------------------------------------------------------------------------
# data structures
# --------------------------------------------------------------------------------------


def _as_vector(value: Any, what: str, run: str, source: str | None) -> np.ndarray:
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

    Notes
    -----
    Arrays are converted to contiguous float64 1-D arrays; ``1 x N`` and ``N x 1`` inputs are
    flattened. Consistency (lengths, finiteness, sampling) is checked by :func:`validate`,
    not here.

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

    def __post_init__(self) -> None:
        self.name = str(self.name)
        for key in _SIGNAL_COLUMNS:
            value = getattr(self, key)
            if value is not None or key in ("t", "theta"):
                setattr(self, key, _as_vector(value, key, self.name, self.source))
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

    def __post_init__(self) -> None:
        self.runs = list(self.runs)
        self.experiment = _check_experiment(self.experiment, self.source)
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
        return "torque" if self.experiment == "driven" else "theta"

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
        return Dataset(list(runs), self.experiment, self.source)

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


# --------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------


def _given_current(value: Any, source: str, run: str) -> float:
    """A coil current given as an argument (not read from the file): one real number."""
    if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    ):
        return float(value)
    if isinstance(value, str):
        with contextlib.suppress(ValueError):
            return float(value)
    raise input_error(
        source,
        f"the coil current {value!r} is not a number",
        "give the current in A as a number (rig: [current] value = 0.5)",
        run=run,
    )


def _valid_rate(fs: Any) -> bool:
    """A sampling rate: a finite real number > 0 (not a bool)."""
    return (
        isinstance(fs, (int, float, np.floating, np.integer))
        and not isinstance(fs, (bool, np.bool_))
        and math.isfinite(fs)
        and fs > 0
    )


def _check_experiment(experiment: Any, source: str | None) -> str:
    text = str(experiment).strip().lower()
    if text not in EXPERIMENTS:
        raise input_error(
            source,
            f"unknown experiment type {experiment!r}",
            f"use one of {', '.join(EXPERIMENTS)} (--experiment)",
        )
    return text


def distinct_currents(currents: Iterable[float]) -> np.ndarray:
    """Distinct current levels, sorted.

    Two currents count as the same level when they differ by at most
    ``max(0.02 A, 5 % of the larger magnitude)``, the tolerance :func:`validate` allows
    within one run. Each level is reported as the median of its members.

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


def _norm_unit(unit: str) -> str:
    u = str(unit).strip().lower().replace("µ", "u").replace("μ", "u")
    for sep in ("·", "⋅", "-", "."):
        u = u.replace(sep, "*")
    u = u.replace(" ", "")
    u = re.sub(r"^degrees?\b|^degs?\b", "deg", u)
    u = re.sub(r"^radians?\b|^rads?\b", "rad", u)
    return u


_POSITION = {
    "rad": 1.0,
    "mrad": 1e-3,
    "deg": math.pi / 180.0,
    "m": 1.0,
    "cm": 1e-2,
    "mm": 1e-3,
    "um": 1e-6,
    "in": 0.0254,
}
_UNITS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "theta": dict(_POSITION),
    "theta_dot": {
        **{f"{k}/s": v for k, v in _POSITION.items()},
        "rpm": 2.0 * math.pi / 60.0,
        "mm/ms": 1.0,
    },
    "torque": {
        "n": 1.0,
        "kn": 1e3,
        "n*m": 1.0,
        "nm": 1.0,
        "kn*m": 1e3,
        "knm": 1e3,
        "n*cm": 1e-2,
        "n*mm": 1e-3,
        "nmm": 1e-3,
        "lbf": 4.4482216152605,
        "lbf*in": 0.1129848290276167,
        "lbf*ft": 1.3558179483314004,
    },
    "current": {"a": 1.0, "ma": 1e-3},
}
_UNITS["input"] = _UNITS["torque"]


def unit_factor(column: str, unit: str, source: str | None = None) -> float:
    """Factor that converts ``column`` given in ``unit`` to SI.

    Parameters
    ----------
    column : str
        Canonical column name (``t``, ``theta``, ``theta_dot``, ``torque``, ``input``,
        ``current``).
    unit : str
        Unit as written by the user, e.g. ``"deg"``, ``"mm/s"``, ``"kN"``, ``"N*m"``.
    source : str, optional
        File name for the error message.

    Examples
    --------
    >>> unit_factor("theta", "mm"), unit_factor("torque", "kN"), unit_factor("theta_dot", "mm/s")
    (0.001, 1000.0, 0.001)
    >>> round(unit_factor("theta", "deg"), 6)
    0.017453
    """
    if column not in _UNITS:
        raise input_error(
            source,
            f"units given for unknown column {column!r}",
            f"use units for {', '.join(sorted(_UNITS))}",
        )
    table = _UNITS[column]
    key = _norm_unit(unit)
    if key not in table:
        shown = sorted({k for k in table if "*" in k or len(k) <= 5})
        raise input_error(
            source,
            f"unknown unit {unit!r} for column {column!r}",
            f"use one of {', '.join(shown)}",
        )
    return table[key]


def _apply_units(cols: dict[str, np.ndarray], units: Mapping[str, str] | None, source: str) -> None:
    if not units:
        return
    if not isinstance(units, Mapping):
        raise input_error(
            source, "units must be a mapping column -> unit", "pass e.g. {'theta': 'deg'}"
        )
    for column, unit in units.items():
        factor = unit_factor(str(column), unit, source)
        if column in cols and factor != 1.0:
            with np.errstate(over="ignore"):  # an overflow to inf is reported by validate()
                cols[column] = cols[column] * factor


def _check_column_map(columns: Mapping[str, Any] | None, source: str) -> dict[str, Any]:
    if columns is None:
        return {}
    if not isinstance(columns, Mapping):
        raise input_error(
            source, "the column map must be a mapping", "pass e.g. {'theta': 'angle'}"
        )
    out: dict[str, Any] = {}
    for key, value in columns.items():
        if key not in CANONICAL_COLUMNS:
            raise input_error(
                source,
                f"unknown column key {key!r} in the column map",
                f"use the names {', '.join(CANONICAL_COLUMNS)}",
            )
        if isinstance(value, bool) or not isinstance(value, (str, int, np.integer)):
            raise input_error(
                source,
                f"column map entry {key}={value!r} is neither a name nor an index",
                f"map {key} to a column name or a 0-based column index",
            )
        if isinstance(value, (int, np.integer)) and value < 0:
            raise input_error(
                source,
                f"column map entry {key}={value} is negative",
                "use 0-based column indices",
            )
        out[key] = int(value) if isinstance(value, (int, np.integer)) else str(value)
    return out


def _current_from_name(
    name: str, pattern: str = DEFAULT_CURRENT_PATTERN, decimal: str = "x"
) -> float:
    """Coil current encoded in a file name.

    Parameters
    ----------
    name : str
        File name or stem (a directory part and the extension are ignored).
    pattern : str
        Regular expression searched in the stem; its first group (or the whole match if it
        has no group) is the current, with ``decimal`` standing for the decimal point.
    decimal : str
        Character(s) used for the decimal point in file names.

    Examples
    --------
    >>> current_from_name("25mm0x25Hz0x75A"), current_from_name("10mm1Hz1A.txt")
    (0.75, 1.0)
    >>> current_from_name("2mm5Hz0A")
    0.0
    """
    stem = (
        Path(str(name)).stem
        if Path(str(name)).suffix.lower() in DATA_SUFFIXES
        else Path(str(name)).name
    )
    try:
        regex = re.compile(pattern)
    except re.error as exc:
        raise input_error(
            str(name), f"invalid current pattern {pattern!r} ({exc})", "fix the regular expression"
        ) from None
    match = regex.search(stem)
    if match is None:
        raise input_error(
            str(name),
            f"file name {stem!r} does not match the current pattern '{pattern}'",
            "rename the file or set the current with [current] value = ... in the rig description",
        )
    text = match.group(1) if regex.groups else match.group(0)
    if text is None:
        text = match.group(0)
    if decimal:
        text = text.replace(decimal, ".")
    try:
        return float(text)
    except ValueError:
        raise input_error(
            str(name),
            f"the current pattern matched {text!r}, which is not a number",
            "adjust [current] from_name so that its group captures only the current",
        ) from None


current_from_name = _current_from_name  # public name; read_table has an argument of that name


# --------------------------------------------------------------------------------------
# text files
# --------------------------------------------------------------------------------------


def _read_bytes(path: str | os.PathLike[str]) -> bytes:
    source = str(path)
    p = Path(path)
    if not p.exists():
        raise input_error(source, "file does not exist", "check the path")
    if p.is_dir():
        raise input_error(
            source, "is a directory, not a file", "pass a file, or load the folder with load()"
        )
    try:
        return p.read_bytes()
    except OSError as exc:
        raise input_error(
            source, f"cannot be read ({exc.strerror or exc})", "check its permissions"
        ) from None


def _read_text(path: str | os.PathLike[str], hint: str = "") -> str:
    """Read a UTF-8 text file with one-line errors for every way this can fail."""
    source = str(path)
    data = _read_bytes(path)
    if not data.strip():
        raise input_error(source, "file is empty", "point to a file that holds the measured data")
    if b"\x00" in data:
        raise input_error(
            source,
            "is not a text file (it holds binary data)",
            hint or "export the data as CSV or a plain text table",
        )
    try:
        # a doubled byte-order mark (a file re-saved by two editors) is still a BOM
        return data.decode("utf-8-sig").lstrip("\ufeff")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise input_error(
            source,
            f"is not valid UTF-8 text (byte 0x{data[exc.start]:02x} on line {line})",
            "re-save the file with UTF-8 encoding",
        ) from None


def _data_lines(text: str, skip_rows: int = 0) -> list[tuple[int, str]]:
    """Non-blank, non-comment lines as ``(1-based line number, text)``.

    A byte-order mark at the start of a line (files concatenated after a comment block) is
    dropped: it is invisible, and would otherwise hide a comment or join a column name.
    """
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    out = []
    for i, line in enumerate(lines[skip_rows:], start=skip_rows + 1):
        line = line.lstrip("\ufeff")
        s = line.strip()
        if s and not s.startswith("#"):
            out.append((i, line))
    return out


def _floats(
    cells: Sequence[str], linenos: np.ndarray, source: str, label: str, fix_hint: str = ""
) -> np.ndarray:
    """Parse a column of text cells; report the first bad cell with its line number."""
    try:
        arr = np.array(cells, dtype=np.float64)
    except ValueError:
        for cell, line in zip(cells, linenos, strict=True):
            try:
                float(cell)
            except ValueError:
                shown = cell.strip()
                fix = "replace it by a number"
                if "," in shown:
                    fix = "use '.' as the decimal separator"
                elif fix_hint and line == linenos[0]:
                    fix = fix_hint
                raise input_error(
                    source,
                    f"non-numeric cell {shown!r} in column {label!r} on line {line}"
                    if shown
                    else f"empty cell in column {label!r} on line {line}",
                    fix,
                ) from None
        arr = np.array([float(c) for c in cells], dtype=np.float64)  # pragma: no cover
    bad = ~np.isfinite(arr)
    if bad.any():
        k = int(np.argmax(bad))
        kind = "NaN" if np.isnan(arr[k]) else "inf"
        raise input_error(
            source,
            f"column {label!r} holds {kind} on line {int(linenos[k])} ({_count(int(bad.sum()), 'bad value')})",
            "remove or fill the missing samples (e.g. interpolate) before loading",
        )
    return arr


def _split_rows(
    lines: list[tuple[int, str]], delimiter: str | None, source: str, width: int | None, what: str
) -> tuple[np.ndarray, list[list[str]]]:
    """Split data lines into fields; every row must have ``width`` fields."""
    linenos = np.fromiter((n for n, _ in lines), dtype=np.int64, count=len(lines))
    if delimiter is None:
        rows = [line.split() for _, line in lines]
    else:
        rows = []
        reader = csv.reader(
            (line for _, line in lines),
            delimiter=delimiter,
            strict=True,
            skipinitialspace=True,  # '"t", "theta"': quoted fields after ', ' are still quoted
        )
        try:
            for row in reader:
                rows.append(row)
        except csv.Error as exc:
            line = int(linenos[min(len(rows), len(linenos) - 1)])
            raise input_error(
                source, f"malformed CSV on line {line} ({exc})", "fix the quoting on that line"
            ) from None
        if len(rows) != len(lines):
            raise input_error(
                source,
                "malformed CSV (a quoted field spans several lines)",
                "remove line breaks inside quoted fields",
            )
    if width is None:
        width = len(rows[0])
    for row, line in zip(rows, linenos, strict=True):
        if len(row) != width:
            raise input_error(
                source,
                f"line {int(line)} has {len(row)} fields, expected {width} ({what})",
                "make every row the same length (ragged or truncated rows are not accepted)",
            )
    return linenos, rows


def _guess_delimiter(header: str) -> str | None:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] > 0 else None


def _run_current(values: np.ndarray, linenos: np.ndarray | None, source: str, run: str) -> float:
    """One current per run: the median, if the current is constant within tolerance."""
    lo, hi = float(np.min(values)), float(np.max(values))
    med = float(np.median(values))
    tol = max(0.02, 0.05 * abs(med))
    if hi - lo > tol:
        where = ""
        if linenos is not None:
            k = int(np.argmax(np.abs(values - values[0]) > tol))
            where = f", first change on line {int(linenos[k])}"
        raise input_error(
            source,
            f"current varies within the run from {lo:g} to {hi:g} A (more than {tol:g} A){where}",
            "split the record where the current changes and give each part its own run id",
            run=run,
        )
    return med


def _build_dataset(
    cols: dict[str, np.ndarray],
    run_ids: Sequence[str] | None,
    linenos: np.ndarray | None,
    source: str,
    experiment: str,
    current: float | None = None,
    default_name: str = "0",
) -> Dataset:
    """Group per-sample columns by run id (order of first appearance) into a Dataset."""
    with np.errstate(all="ignore"):  # huge currents overflow in the median; checked later
        return _group_runs(cols, run_ids, linenos, source, experiment, current, default_name)


def _group_runs(
    cols: dict[str, np.ndarray],
    run_ids: Sequence[str] | None,
    linenos: np.ndarray | None,
    source: str,
    experiment: str,
    current: float | None,
    default_name: str,
) -> Dataset:
    n = cols["theta"].size
    if n == 0:
        raise input_error(
            source, "holds no data rows", "point to a file that holds the measured data"
        )
    if run_ids is None:
        groups = [(default_name, np.arange(n))]
    else:
        ids = np.asarray([str(r).strip() for r in run_ids])
        uniq, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
        order = np.argsort(first, kind="stable")
        groups = [(str(uniq[g]), np.flatnonzero(inverse == g)) for g in order]
    runs = []
    for name, idx in groups:
        lines = linenos[idx] if linenos is not None else None
        if "current" in cols:
            cur = _run_current(cols["current"][idx], lines, source, name)
        elif current is not None:
            cur = _given_current(current, source, name)
        else:
            raise input_error(
                source,
                "no coil current given",
                "add a 'current' column/variable or give the current (rig [current] value or from_name)",
                run=name,
            )
        kw = {k: cols[k][idx] for k in ("torque", "input", "theta_dot") if k in cols}
        runs.append(
            Run(name, cols["t"][idx], cols["theta"][idx], cur, source=source, lines=lines, **kw)
        )
    return Dataset(runs, experiment, source)


def _infer_experiment(has: Iterable[str], source: str) -> str:
    present = set(has)
    if "torque" in present and "input" in present:
        raise input_error(
            source,
            "has both a torque and an input column, so the experiment type is ambiguous",
            "pass --experiment driven or --experiment forced",
        )
    if "torque" in present:
        return "driven"
    if "input" in present:
        return "forced"
    return "release"


def _needed(experiment: str) -> list[str]:
    extra = _EXTRA_COLUMN[experiment]
    return ["t", "theta", "current"] + ([extra] if extra else [])


def read_csv(
    path: str | os.PathLike[str],
    experiment: str | None = None,
    columns: Mapping[str, str | int] | None = None,
    units: Mapping[str, str] | None = None,
) -> Dataset:
    """Read a long-format CSV file (header row, one row per sample).

    Parameters
    ----------
    path : path-like
        The file. Comma, semicolon, tab or whitespace separated; ``#`` starts a comment line.
    experiment : {"release", "driven", "forced"}, optional
        Experiment type. Inferred when omitted: a ``torque`` column means driven, an
        ``input`` column forced, else release.
    columns : dict, optional
        Maps canonical names (``run, t, theta, current, torque, input, theta_dot``) to the
        file's column names (or 0-based positions), e.g. ``{"theta": "angle"}``.
    units : dict, optional
        Units of the file's columns, converted to SI, e.g. ``{"theta": "deg"}``.

    Returns
    -------
    Dataset
        Checked with ``validate(dataset, need_currents=1)``. Without a ``run`` column the
        whole file is one run named ``"0"``; rows are grouped by run id in order of first
        appearance.

    Raises
    ------
    HystdiscError
        One-line message naming the file, the run, the problem and the fix.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d, "run.csv")
    ...     rows = [f"{k * 0.01},{(-1) ** k * 1.5},0.5" for k in range(30)]
    ...     _ = p.write_text("time,angle,current\\n" + "\\n".join(rows))
    ...     ds = read_csv(p, columns={"t": "time", "theta": "angle"}, units={"theta": "deg"})
    >>> ds.experiment, ds.names, round(float(ds[0].theta[0]), 5)
    ('release', ['0'], 0.02618)
    """
    source = str(path)
    text = _read_text(path)
    colmap = _check_column_map(columns, source)
    lines = _data_lines(text)
    if not lines:
        raise input_error(source, "file is empty", "point to a file that holds the measured data")
    header_line = lines[0][1]
    delimiter = _guess_delimiter(header_line)
    _, hdr = _split_rows(lines[:1], delimiter, source, None, "header")
    # a byte-order mark that is not at the start of the file (a comment line was put in
    # front of a UTF-8-BOM file) is invisible in the messages: drop it from the names
    header = [h.replace("\ufeff", "").strip().strip('"').strip() for h in hdr[0]]
    if not lines[1:]:
        raise input_error(
            source, "has a header but no data rows", "point to a file that holds the measured data"
        )

    def locate(canon: str) -> int | None:
        wanted = colmap.get(canon, canon)
        if isinstance(wanted, int):
            if wanted >= len(header):
                raise input_error(
                    source,
                    f"column index {wanted} for {canon!r} is out of range ({len(header)} columns)",
                    f"use an index from 0 to {len(header) - 1}",
                )
            return wanted
        hits = [i for i, h in enumerate(header) if h == wanted]
        if not hits:
            hits = [i for i, h in enumerate(header) if h.lower() == wanted.lower()]
        if len(hits) > 1:
            raise input_error(
                source,
                f"column {wanted!r} appears {len(hits)} times in the header",
                "rename the duplicates",
            )
        if not hits and canon in colmap:
            raise input_error(
                source,
                f"column {wanted!r} (mapped to {canon}) is not in the header "
                f"(found: {', '.join(header[:12])})",
                f"correct the mapping {_COLUMN_FLAG} {canon}=NAME",
            )
        return hits[0] if hits else None

    where = {c: locate(c) for c in CANONICAL_COLUMNS}
    present = [c for c, i in where.items() if i is not None]
    exp = (
        _check_experiment(experiment, source)
        if experiment is not None
        else _infer_experiment(present, source)
    )
    for canon in _needed(exp):
        if where[canon] is None:
            why = f" (a {exp} experiment needs it)" if canon in ("torque", "input") else ""
            raise input_error(
                source,
                f"column {canon!r} is missing{why} (found: {', '.join(header[:12])})",
                f"add it or map yours with {_COLUMN_FLAG} {canon}=NAME",
            )
    linenos, rows = _split_rows(lines[1:], delimiter, source, len(header), "as many as the header")
    wanted = [c for c in _needed(exp) + ["theta_dot"] if where[c] is not None]
    cols: dict[str, np.ndarray] = {}
    for canon in wanted:
        i = where[canon]
        assert i is not None
        cols[canon] = _floats([r[i] for r in rows], linenos, source, header[i])
    run_ids = [r[where["run"]] for r in rows] if where["run"] is not None else None
    _apply_units(cols, units, source)
    ds = _build_dataset(cols, run_ids, linenos, source, exp)
    validate(ds, need_currents=1)
    return ds


def read_table(
    path: str | os.PathLike[str],
    columns: Mapping[str, int],
    experiment: str,
    units: Mapping[str, str] | None = None,
    current: float | None = None,
    current_from_name: str | None = None,
    skip_rows: int = 0,
    *,
    decimal: str = "x",
    fs: float | None = None,
) -> Dataset:
    """Read a header-less whitespace-separated table: one file, one run.

    Parameters
    ----------
    path : path-like
        The file; ``#`` starts a comment line, blank lines are ignored.
    columns : dict
        Canonical name -> 0-based column index, e.g. ``{"t": 0, "theta": 1, "torque": 3}``.
        A ``current`` index reads a per-sample current column.
    experiment : {"release", "driven", "forced"}
        Experiment type.
    units : dict, optional
        Units of the columns, converted to SI, e.g. ``{"theta": "mm"}``.
    current : float, optional
        Coil current of the run, in A.
    current_from_name : str, optional
        Regular expression with one group applied to the file stem, ``decimal`` standing
        for the decimal point; see :func:`current_from_name`.
    skip_rows : int
        Lines to skip at the top (e.g. a text header).
    decimal : str
        Decimal-point stand-in for ``current_from_name``.
    fs : float, optional
        Sampling rate in Hz, used to build ``t`` when there is no time column.

    Returns
    -------
    Dataset
        One run named by the file stem, checked with ``validate(dataset, need_currents=1)``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d, "10mm1Hz0x5A.txt")
    ...     _ = p.write_text("".join(f"{k / 100} {k % 3} {(-1) ** k}\\n" for k in range(40)))
    ...     ds = read_table(p, {"t": 0, "theta": 1, "torque": 2}, "driven",
    ...                     units={"theta": "mm"}, current_from_name=r"(\\d+(?:x\\d+)?)A$")
    >>> ds[0].name, ds[0].current, float(ds[0].theta.max())
    ('10mm1Hz0x5A', 0.5, 0.002)
    """
    source = str(path)
    exp = _check_experiment(experiment, source)
    colmap = _check_column_map(columns, source)
    for key, value in colmap.items():
        if not isinstance(value, int):
            raise input_error(
                source,
                f"column map entry {key}={value!r} is a name, but the table has no header",
                f"map {key} to a 0-based column index",
            )
    needed = [c for c in _needed(exp) if c != "current"]
    if fs is not None:
        needed.remove("t")
    for canon in needed:
        if canon not in colmap:
            fix = f"add {canon} = <0-based index> to the [columns] of the rig description"
            if canon == "t":
                fix += " or give the sampling rate fs"
            raise input_error(source, f"no column given for {canon!r}", fix)
    if not isinstance(skip_rows, (int, np.integer)) or skip_rows < 0:
        raise input_error(source, f"skip_rows={skip_rows!r} is invalid", "use a whole number >= 0")
    text = _read_text(path)
    lines = _data_lines(text, int(skip_rows))
    if not lines:
        raise input_error(
            source, "holds no data rows", "point to a file that holds the measured data"
        )
    linenos, rows = _split_rows(lines, None, source, None, "as many as the first data row")
    width = len(rows[0])
    cols: dict[str, np.ndarray] = {}
    for canon, i in colmap.items():
        if canon == "run":
            continue
        if i >= width:
            raise input_error(
                source,
                f"column index {i} for {canon!r} is out of range (the table has {width} columns)",
                f"use an index from 0 to {width - 1}",
            )
        hint = "skip header lines with skip_rows (rig: skip_rows = 1)"
        cols[canon] = _floats([r[i] for r in rows], linenos, source, f"{canon} (column {i})", hint)
    if "t" not in cols:
        if not _valid_rate(fs):
            raise input_error(
                source,
                "no time column and no valid sampling rate"
                + ("" if fs is None else f" (fs = {fs!r})"),
                "give the sampling rate fs in Hz (a finite number > 0) or map a time column",
            )
        cols["t"] = np.arange(len(rows), dtype=np.float64) / float(fs)
    if "current" not in cols and current is None:
        if current_from_name is not None:
            current = _current_from_name(source, current_from_name, decimal)
        else:
            raise input_error(
                source,
                "no coil current given",
                "set [current] value = ... or from_name = '<regex>' in the rig description",
            )
    _apply_units(cols, units, source)
    ds = _build_dataset(
        cols, None, linenos, source, exp, current=current, default_name=Path(source).stem
    )
    validate(ds, need_currents=1)
    return ds


# --------------------------------------------------------------------------------------
# MATLAB files
# --------------------------------------------------------------------------------------


def _mat_needs_probe(path: str) -> bool:
    """False for files the compiled reader is safe on: v4, v7.3 and all-compressed v5.

    The crashes seen come from uncompressed v5 variables (a damaged class, flag or
    data-type field); compressed variables are checked by zlib first. Walking the
    top-level tags costs microseconds, a fork tens of milliseconds.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(128)
            # scipy: v4 when a zero is among the first 4 bytes; v5 when the major version
            # byte (chosen by the endian indicator 'IM' / 'MI') is 1
            if len(head) < 128 or 0 in head[:4] or head[124 + (head[126] == 0x49)] != 1:
                return False  # v4, too short or not v5: scipy's own checks stop it cleanly
            endian = "<" if head[126:128] == b"IM" else ">"
            size = os.fstat(fh.fileno()).st_size
            pos = 128
            while pos < size:
                fh.seek(pos)
                tag = fh.read(8)
                if len(tag) < 8:
                    return True
                mdtype, nbytes = struct.unpack(endian + "II", tag)
                if mdtype != 15:  # not miCOMPRESSED
                    return True
                pos += 8 + nbytes
    except OSError:
        return False
    return False


def _probe_loadmat(path: str) -> str | None:
    """Try ``scipy.io.loadmat`` in a forked child first; the signal's name if it crashed.

    scipy's compiled MAT reader can kill the interpreter (segmentation fault) on some
    damaged files, e.g. one flipped class or flag byte of a variable (found by fuzzing,
    ``tests/fuzz_corpus/mat_*``). A crash of the child becomes a one-line error instead.
    Python errors are left to the real load. Without ``os.fork`` (Windows) nothing is
    probed.
    """
    if not hasattr(os, "fork") or not _mat_needs_probe(path):
        return None
    import scipy.io

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork() of a threaded process
        pid = os.fork()
    if pid == 0:  # pragma: no cover - the child (coverage does not follow it)
        code = 0
        try:
            import faulthandler

            faulthandler.disable()  # the crash is expected here: no dump on stderr
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            warnings.simplefilter("ignore")
            scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False)
        except BaseException:
            code = 1
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            return signal.Signals(sig).name
        except ValueError:  # pragma: no cover
            return f"signal {sig}"
    return None


def _load_mat(path: str | os.PathLike[str]) -> dict[str, Any]:
    import scipy.io

    source = str(path)
    data = _read_bytes(path)
    if not data:
        raise input_error(source, "file is empty", "point to a file that holds the measured data")
    if data[:128].find(b"MATLAB 7.3") >= 0 or data[:8] == b"\x89HDF\r\n\x1a\n":
        raise input_error(
            source,
            "is a MATLAB v7.3 (HDF5) file, which cannot be read",
            "re-save it in MATLAB with save(name, '-v7')",
        )
    crash = _probe_loadmat(str(path))
    if crash:
        raise input_error(
            source,
            f"is a damaged MATLAB .mat file (the MAT reader crashed on it: {crash})",
            "re-save it in MATLAB with save(name, '-v7'), or export the data as CSV",
        )
    try:
        raw = scipy.io.loadmat(str(path), squeeze_me=False, mat_dtype=False)
    except Exception as exc:  # scipy raises many types for damaged files
        raise input_error(
            source,
            f"is not a readable MATLAB .mat file ({type(exc).__name__}: {exc})",
            "check the file, or re-save it in MATLAB with save(name, '-v7')",
        ) from None
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def _mat_lookup(variables: Mapping[str, Any], name: str) -> str | None:
    if name in variables:
        return name
    hits = [k for k in variables if k.lower() == name.lower()]
    return hits[0] if len(hits) == 1 else None


def _mat_numeric(value: Any, name: str, source: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        kind = "complex" if arr.dtype.kind == "c" else "not a numeric array"
        raise input_error(
            source,
            f"variable {name!r} is {kind} ({arr.dtype})",
            "store the signal as a real numeric vector",
        )
    return arr.astype(np.float64)


def read_mat(
    path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    experiment: str | None = None,
    columns: Mapping[str, str | int] | None = None,
    units: Mapping[str, str] | None = None,
    current: float | None = None,
    fs: float | None = None,
) -> Dataset:
    """Read a MATLAB ``.mat`` file (v4 to v7; not v7.3).

    Parameters
    ----------
    path : path-like or list of path-likes
        The file. Several files are merged into one set of variables (e.g. input and
        output saved separately, as in the Bouc-Wen benchmark).
    experiment : {"release", "driven", "forced"}, optional
        Inferred when omitted: a ``torque`` variable means driven, ``input`` forced.
    columns : dict, optional
        Canonical name -> variable name (defaults to the canonical names, matched
        case-insensitively), or -> 0-based column index into the single 2-D matrix the file
        holds (``{"matrix": ...}`` is not needed; a ``1 x N`` / ``N x 1`` vector is fine).
    units : dict, optional
        Units of the variables, converted to SI.
    current : float, optional
        Coil current when the file has no ``current`` variable.
    fs : float, optional
        Sampling rate in Hz when the file has no ``t`` variable: ``t = arange(n) / fs``.

    Returns
    -------
    Dataset
        One run named ``"0"``, or several when a per-sample ``run`` variable is present;
        checked with ``validate(dataset, need_currents=1)``.

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np, scipy.io
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = str(pathlib.Path(d, "rig.mat"))
    ...     scipy.io.savemat(p, {"y": np.sin(np.arange(50) / 5.0)[None, :], "u": np.ones(50)})
    ...     ds = read_mat(p, "forced", columns={"theta": "y", "input": "u"}, current=0.0, fs=100.0)
    >>> ds[0].n, ds[0].fs, ds.experiment
    (50, 100.0, 'forced')
    """
    paths = [path] if isinstance(path, (str, os.PathLike)) else list(path)
    source = ", ".join(str(p) for p in paths)
    variables: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for p in paths:
        for key, value in _load_mat(p).items():
            if key in variables:
                raise input_error(
                    source,
                    f"variable {key!r} is in both {origin[key]} and {p}",
                    "merge files that hold different variables only",
                )
            variables[key] = value
            origin[key] = str(p)
    if not variables:
        raise input_error(
            source, "holds no variables", "point to a file that holds the measured data"
        )
    colmap = _check_column_map(columns, source)

    matrix_name: str | None = None
    matrix: np.ndarray | None = None
    if any(isinstance(v, int) for v in colmap.values()):
        mats = []
        for k, v in variables.items():
            a = np.asarray(v)
            if a.ndim == 2 and min(a.shape) > 1 and a.dtype.kind in "biuf":
                mats.append(k)
        if len(mats) != 1:
            found = ", ".join(mats) if mats else "none"
            raise input_error(
                source,
                f"a column map with indices needs exactly one 2-D matrix in the file (found: {found})",
                "map the columns to variable names instead",
            )
        matrix_name = mats[0]
        matrix = _mat_numeric(variables[matrix_name], matrix_name, source)
        top = max(v for v in colmap.values() if isinstance(v, int))
        if matrix.shape[1] <= top or (matrix.shape[0] < matrix.shape[1] and matrix.shape[0] > top):
            matrix = matrix.T  # channels stored as rows
        if matrix.shape[1] <= top:
            raise input_error(
                source,
                f"column index {top} is out of range for matrix {matrix_name!r} of shape {matrix.shape}",
                f"use indices from 0 to {matrix.shape[1] - 1}",
            )

    def fetch(canon: str) -> tuple[np.ndarray | None, str]:
        wanted = colmap.get(canon, canon)
        if isinstance(wanted, int):
            assert matrix is not None
            return matrix[:, wanted], f"{matrix_name}[:, {wanted}]"
        key = _mat_lookup(variables, wanted)
        if key is None:
            if canon in colmap:
                raise input_error(
                    source,
                    f"variable {wanted!r} (mapped to {canon}) is not in the file "
                    f"(found: {', '.join(sorted(variables)[:12])})",
                    f"correct the mapping {_COLUMN_FLAG} {canon}=NAME",
                )
            return None, wanted
        arr = _mat_numeric(variables[key], key, source)
        if arr.size > 1 and arr.ndim > 1 and arr.size != max(arr.shape):
            raise input_error(
                source,
                f"variable {key!r} has shape {arr.shape}, expected a vector",
                "store each signal as a 1 x N or N x 1 vector, or map matrix columns by index",
            )
        return arr.reshape(-1), key

    found = {c: fetch(c) for c in CANONICAL_COLUMNS}
    present = [c for c, (a, _) in found.items() if a is not None]
    exp = (
        _check_experiment(experiment, source)
        if experiment is not None
        else _infer_experiment(present, source)
    )
    need = [c for c in _needed(exp) if c not in ("t", "current")]
    for canon in need:
        if found[canon][0] is None:
            why = f" (a {exp} experiment needs it)" if canon in ("torque", "input") else ""
            raise input_error(
                source,
                f"variable {canon!r} is missing{why} (found: {', '.join(sorted(variables)[:12])})",
                f"add it or map yours with {_COLUMN_FLAG} {canon}=NAME",
            )
    n = found["theta"][0].size  # type: ignore[union-attr]
    cols: dict[str, np.ndarray] = {}
    run_ids = None
    for canon in CANONICAL_COLUMNS:
        arr, label = found[canon]
        if arr is None:
            continue
        if (canon == "torque" and exp != "driven") or (canon == "input" and exp != "forced"):
            continue
        if canon == "current" and arr.size == 1:
            current = float(arr[0])
            continue
        if arr.size != n:
            raise input_error(
                source,
                f"variable {label!r} has {arr.size} samples but theta has {n}",
                "store signals of equal length",
            )
        if canon == "run":
            run_ids = [f"{v:g}" for v in arr]
            continue
        bad = ~np.isfinite(arr)
        if bad.any():
            k = int(np.argmax(bad))
            kind = "NaN" if np.isnan(arr[k]) else "inf"
            raise input_error(
                source,
                f"variable {label!r} holds {kind} at sample {k} ({_count(int(bad.sum()), 'bad value')})",
                "remove or fill the missing samples (e.g. interpolate) before loading",
            )
        cols[canon] = arr
    if "t" not in cols:
        if fs is None:
            raise input_error(
                source,
                f"no time variable (found: {', '.join(sorted(variables)[:12])})",
                f"add a 't' variable, map it with {_COLUMN_FLAG} t=NAME, or give the sampling rate fs",
            )
        if not _valid_rate(fs):
            raise input_error(source, f"sampling rate fs={fs!r} is invalid", "give fs > 0 in Hz")
        cols["t"] = np.arange(n, dtype=np.float64) / float(fs)
    _apply_units(cols, units, source)
    ds = _build_dataset(cols, run_ids, None, source, exp, current=current)
    validate(ds, need_currents=1)
    return ds


# --------------------------------------------------------------------------------------
# checks
# --------------------------------------------------------------------------------------


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _where(run: Run, k: int) -> str:
    if run.lines is not None and run.lines.size == run.n:
        return f"line {int(run.lines[k])}"
    return f"sample {k}"


def validate(dataset: Dataset, need_currents: int = 1) -> Dataset:
    """Check a dataset (DESIGN.md section 7); raise a one-line HystdiscError on a problem.

    Checks, per run: required signals present (torque for driven, input for forced), equal
    lengths, no NaN/inf (naming the column and the first bad line or sample), at least
    :data:`MIN_SAMPLES` samples, strictly increasing time, regular sampling (every step
    within 1 % of the median step), a run that moves. Per dataset: at least one run, unique
    run names, at least ``need_currents`` distinct currents (see :func:`distinct_currents`).

    Parameters
    ----------
    dataset : Dataset
        The data to check.
    need_currents : int
        Number of distinct currents the caller needs (2 or more to identify the current
        dependence of a model).

    Returns
    -------
    Dataset
        The same object, for chaining.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(100) * 1e-3
    >>> ds = Dataset([Run("a", t, np.sin(50 * t), 0.5)], "release", "x.csv")
    >>> validate(ds) is ds
    True
    >>> validate(ds, need_currents=2)
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: x.csv: a single current (0.5 A) where 2 are needed; fix: ...
    """
    # huge values may overflow in the checks (std, differences); every check below tests
    # finiteness itself, so numpy's overflow warnings would only be noise for the user
    with np.errstate(all="ignore"):
        return _validate(dataset, need_currents)


def _validate(dataset: Dataset, need_currents: int) -> Dataset:
    if not isinstance(dataset, Dataset):
        raise input_error(
            None,
            f"expected a Dataset, got {type(dataset).__name__}",
            "load data with hystdisc.data.io.load",
        )
    source = dataset.source
    if not dataset.runs:
        raise input_error(source, "holds no runs", "point to a file that holds the measured data")
    exp = dataset.experiment
    extra = _EXTRA_COLUMN[exp]
    seen: dict[str, int] = {}
    for run in dataset.runs:
        src = run.source or source
        name = run.name
        if name in seen:
            raise input_error(
                src,
                f"two runs are named {name!r}",
                "give every run its own id in the run column",
                run=name,
            )
        seen[name] = 1
        if extra is not None and getattr(run, extra) is None:
            raise input_error(
                src,
                f"a {exp} experiment needs the measured {extra}, which is missing",
                f"add a {extra!r} column or map yours with {_COLUMN_FLAG} {extra}=NAME",
                run=name,
            )
        n = run.n
        for key in ("theta", "torque", "input", "theta_dot"):
            arr = getattr(run, key)
            if arr is not None and arr.size != n:
                raise input_error(
                    src,
                    f"{key} has {arr.size} samples but t has {n}",
                    "give every signal one value per time sample",
                    run=name,
                )
        for key in ("t", "theta", "torque", "input", "theta_dot"):
            arr = getattr(run, key)
            if arr is None:
                continue
            bad = ~np.isfinite(arr)
            if bad.any():
                k = int(np.argmax(bad))
                kind = "NaN" if np.isnan(arr[k]) else "inf"
                raise input_error(
                    src,
                    f"column {key!r} holds {kind} on {_where(run, k)} ({_count(int(bad.sum()), 'bad value')})",
                    "remove or fill the missing samples (e.g. interpolate) before loading",
                    run=name,
                )
        if not math.isfinite(run.current):
            raise input_error(
                src,
                f"current is {run.current}",
                "give the run a finite coil current in A",
                run=name,
            )
        if n < MIN_SAMPLES:
            raise input_error(
                src,
                f"run is too short ({n} samples, at least {MIN_SAMPLES} needed)",
                "record longer runs, or check that the run column groups the samples as intended",
                run=name,
            )
        dt = np.diff(run.t)
        if not np.all(np.isfinite(dt)):
            k = int(np.argmax(~np.isfinite(dt)))
            raise input_error(
                src,
                f"time steps overflow on {_where(run, k + 1)} "
                f"(t = {run.t[k + 1]:.10g} s after {run.t[k]:.10g} s)",
                "check the time column and its unit (--units t=...)",
                run=name,
            )
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0))
            raise input_error(
                src,
                f"time does not increase on {_where(run, k + 1)} "
                f"(t = {run.t[k + 1]:.10g} s after {run.t[k]:.10g} s)",
                "sort the samples by time and drop duplicates, or give each record its own run id",
                run=name,
            )
        step = float(np.median(dt))
        dev = np.abs(dt - step)
        if dev.max() > 0.01 * step:
            k = int(np.argmax(dev > 0.01 * step))
            raise input_error(
                src,
                f"irregular sampling: the time step ranges from {dt.min():.6g} to {dt.max():.6g} s "
                f"(median {step:.6g} s; first off by more than 1 % on {_where(run, k + 1)})",
                "resample the run onto a uniform time grid (e.g. numpy.interp onto numpy.arange) "
                "before loading",
                run=name,
            )
        if np.ptp(run.theta) == 0 or np.std(run.theta) < 1e-12:
            raise input_error(
                src,
                "theta never moves (it is constant)",
                "check the column mapping, or remove the run",
                run=name,
            )
        if exp == "driven" and np.ptp(run.torque) == 0:  # type: ignore[arg-type]
            raise input_error(
                src,
                "the measured torque never changes (it is constant)",
                "check the column mapping, or remove the run",
                run=name,
            )
        _check_motion(run, src, exp)
    levels = distinct_currents(dataset.currents)
    if len(levels) < need_currents:
        shown = ", ".join(f"{c:g}" for c in levels)
        if len(levels) == 1 and levels[0] == 0.0 and len(dataset.runs) > 1:
            problem = (
                f"every run has current 0 A (the current column is all zero) where "
                f"{need_currents} distinct currents are needed"
            )
            raise input_error(
                source,
                problem,
                f"check the current column ({_COLUMN_FLAG} current=NAME) and its unit "
                "(--units current=mA), add runs at other currents, or declare a family with "
                "--model so that only its current-independent part is fitted",
            )
        if len(levels) == 1:
            problem = f"a single current ({shown} A) where {need_currents} are needed"
        else:
            problem = (
                f"only {len(levels)} distinct currents ({shown} A) where {need_currents} are needed"
            )
        raise input_error(
            source,
            problem,
            "add runs at other currents, declare a family with --model so that only its "
            "current-independent part is fitted, or compare the families at this one current "
            "with --single-current",
        )
    return dataset


#: a run whose angle varies less than this many noise standard deviations is locked
LOCKED_RATIO = 3.0
#: samples needed for the motion checks (the noise estimate needs 26)
_MOTION_MIN = 26


def _check_motion(run: Run, src: str, exp: str) -> None:
    """Numerical faults of a run's motion (issue 8): locked, clipped, not decaying.

    A locked damper (the angle never leaves its noise band, and what is left is white) is
    an error naming the run.
    A signal held at its extreme value as by a saturated sensor, and a release whose motion
    does not decay, are warned about (:class:`~hystdisc.errors.HystdiscWarning`); the run
    is kept as it is.
    """
    if run.n < _MOTION_MIN:
        return
    noise = estimate_noise(run.theta)
    spread = float(np.std(run.theta))
    if spread <= LOCKED_RATIO * noise and _flatness(run.theta) >= 0.3:
        raise input_error(
            src,
            f"theta never moves beyond its noise (std {spread:.3g} against noise "
            f"{noise:.3g}): the damper seems locked in this run",
            "remove the run (or check the column mapping and that the damper was free)",
            run=run.name,
        )
    signals = [("theta", run.theta, noise)]
    if exp == "driven" and run.torque is not None:
        signals.append(("torque", run.torque, estimate_noise(run.torque)))
    for key, x, sd in signals:
        clip = _clipped(x, sd)
        if clip is not None:
            side, value, longest, total = clip
            warnings.warn(
                f"{src}, run {run.name}: {key} stays at its {side} {value:.6g} for {longest} "
                f"samples in a row ({total} in all), as a saturated or clipped sensor does; "
                "the run was kept as it is, so the fit is biased there (re-record within the "
                "sensor's range, or cut the clipped part)",
                HystdiscWarning,
                stacklevel=4,
            )
    if exp == "release":
        ratio = _decay_ratio(run.theta, noise)
        if ratio is not None and ratio > 0.9:
            verb = "grows" if ratio > 1.1 else "does not decay"
            warnings.warn(
                f"{src}, run {run.name}: the motion {verb} (RMS of the last quarter is "
                f"{100 * ratio:.0f} % of the first), which a free release of a damper cannot "
                "do; the run was kept as it is, but its damping parameters will not be "
                "identifiable (check that it is a release, not a driven or forced record)",
                HystdiscWarning,
                stacklevel=4,
            )


def _flatness(x: np.ndarray) -> float:
    """Spectral flatness of ``x``: about 0.56 for white noise, near 0 for a signal.

    Guards the locked-damper check against signals that are merely rough at the sample
    level (a tone near the Nyquist frequency looks like noise to :func:`estimate_noise`).
    """
    power = np.abs(np.fft.rfft(x - np.mean(x)))[1:] ** 2
    mean = float(np.mean(power)) if power.size else 0.0
    if not mean > 0:
        return 0.0
    return float(np.exp(np.mean(np.log(np.maximum(power, mean * 1e-30)))) / mean)


def _clipped(x: np.ndarray, noise: float) -> tuple[str, float, int, int] | None:
    """``(side, value, longest stretch, samples)`` when ``x`` looks clipped at an extreme.

    A saturated sensor repeats its limit exactly for as long as the true signal lies
    beyond it. A natural turning point of a quantized signal repeats its level too, but
    only for as long as the curvature allows: the signal moves about four quantization
    steps from the vertex within twice the half-width of the plateau. A plateau at the
    maximum (or minimum) of at least 5 samples whose flank, half a plateau further on, lies
    more than ``10 steps + 6 noise`` away is taken as clipped.
    """
    n = x.size
    for side, value in (("maximum", float(np.max(x))), ("minimum", float(np.min(x)))):
        at = x == value
        total = int(at.sum())
        if total < 5:
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[0], at.view(np.int8), [0]])))
        starts, ends = edges[::2], edges[1::2]
        k = int(np.argmax(ends - starts))
        a, b = int(starts[k]), int(ends[k])
        longest = b - a
        if longest < 5:
            continue
        others = x[~at]
        if others.size == 0:
            continue
        step = float(np.min(np.abs(others - value)))
        if a == 0:  # a release starts at rest: the vertex is the first sample
            probes = [2 * longest] if 2 * longest < n else []
        else:
            half = max(1, longest // 2)
            probes = [i for i in (a - half - 1, b + half) if 0 <= i < n]
        if not probes:
            continue
        drop = min(abs(float(x[i]) - value) for i in probes)
        if drop > 10.0 * step + 6.0 * noise:
            return side, value, longest, total
    return None


def _decay_ratio(theta: np.ndarray, noise: float) -> float | None:
    """RMS of the last quarter over that of the first, if the run holds 4+ oscillations."""
    x = theta - float(np.mean(theta))
    h = 3.0 * noise
    side = np.sign(x) * (np.abs(x) > h)  # crossings with hysteresis: noise does not count
    side = side[side != 0]
    crossings = int(np.count_nonzero(np.diff(side)))
    if crossings < 8:
        return None
    q = theta.size // 4
    first = float(np.std(theta[:q]))
    last = float(np.std(theta[-q:]))
    return last / first if first > 0 else None


# --------------------------------------------------------------------------------------
# noise and trimming
# --------------------------------------------------------------------------------------


def _screened_rms(d: np.ndarray) -> float:
    """RMS of ``d`` after iterative 5-sigma clipping (drops spikes, keeps the noise).

    Unlike a MAD scale, this stays exact for uniform (quantization) noise and does not
    collapse when most differences of a quantized signal are exactly zero.
    """
    keep = np.ones(d.size, dtype=bool)
    s = float(np.sqrt(np.mean(d * d)))
    for _ in range(20):
        new = np.abs(d) <= 5.0 * s
        if not new.any() or np.array_equal(new, keep):
            break
        keep = new
        s = float(np.sqrt(np.mean(d[keep] ** 2)))
    return s


def estimate_noise(theta: np.ndarray, fs: float | None = None) -> float:
    """Standard deviation of the white measurement noise on a smooth signal.

    Differences of order k = 2..6 of the signal cancel a locally polynomial signal (they
    are the residuals of a local polynomial fit of degree k-1); divided by
    ``sqrt(binom(2k, k))`` they have the noise standard deviation for white noise. The scale
    of each is a 5-sigma-clipped RMS (spikes dropped), which is exact for Gaussian and for
    uniform (quantization) noise alike, where a MAD scale is 28 % high for uniform noise and
    collapses to zero when most differences of a quantized signal are exactly zero. The
    smallest of the five is returned, since what is left of the signal only adds to it.

    Parameters
    ----------
    theta : array_like
        Sampled signal (at least 26 samples), uniformly sampled.
    fs : float, optional
        Sampling rate in Hz; not needed by the estimator and accepted for symmetry with the
        rest of the API.

    Returns
    -------
    float
        Noise standard deviation in the units of ``theta``; 0.0 for a noiseless polynomial.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(6000) / 1000.0
    >>> theta = 0.2 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t) + rng.normal(0, 1e-3, t.size)
    >>> round(estimate_noise(theta, 1000.0) / 1e-3, 1)
    1.0
    """
    x = np.asarray(theta, dtype=np.float64).reshape(-1)
    if x.size < 26:
        raise input_error(
            None,
            f"only {x.size} samples, too few to estimate the noise level",
            "pass at least 26 samples",
        )
    if not np.all(np.isfinite(x)):
        raise input_error(
            None,
            "the signal holds NaN or inf",
            "remove or fill the bad samples before estimating the noise",
        )
    estimates = []
    for k in range(2, 7):
        d = np.diff(x, k) / math.sqrt(math.comb(2 * k, k))
        estimates.append(_screened_rms(d))
    return float(min(estimates))


def trim_release(
    run: Run,
    noise_std: float,
    threshold: float = 3.0,
    min_samples: int = 200,
    window: int | None = None,
) -> Run:
    """Cut the tail of a release record where the motion has died into the noise.

    The envelope of ``theta - final`` (``final`` = mean of the last tenth of the record) is
    taken as ``sqrt(2)`` times its moving RMS over ``window`` samples (the amplitude of an
    oscillation, about 1.4 noise std for pure noise). The record is cut after the last
    sample whose envelope reaches ``threshold * noise_std`` (plus half a window), keeping at
    least ``min_samples`` samples.

    Parameters
    ----------
    run : Run
        A release run.
    noise_std : float
        Measurement noise standard deviation (see :func:`estimate_noise`); 0 keeps all.
    threshold : float
        Envelope level, in noise standard deviations, below which the motion counts as dead.
    min_samples : int
        Samples kept at least.
    window : int, optional
        Moving-RMS window in samples; default ``max(25, n // 200)``.

    Returns
    -------
    Run
        A new run (the input is not modified); all signals are cut alike.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> t = np.arange(10000) / 1000.0
    >>> theta = np.exp(-2.0 * t) * np.cos(2 * np.pi * 2 * t) + rng.normal(0, 1e-3, t.size)
    >>> short = trim_release(Run("0", t, theta, 0.0), 1e-3)
    >>> 2.5 < short.duration < 4.0
    True
    """
    if not (math.isfinite(noise_std) and noise_std >= 0):
        raise input_error(
            run.source,
            f"noise level {noise_std!r} is invalid",
            "pass a noise std >= 0",
            run=run.name,
        )
    n = run.n
    if noise_std == 0 or n <= min_samples:
        return dataclasses.replace(run)
    w = int(window) if window is not None else max(25, n // 200)
    w = max(1, min(w, n))
    tail = max(1, n // 10)
    dev = run.theta - float(np.mean(run.theta[-tail:]))
    power = np.convolve(dev * dev, np.ones(w) / w, mode="same")
    envelope = np.sqrt(2.0 * np.maximum(power, 0.0))
    alive = np.flatnonzero(envelope >= threshold * noise_std)
    cut = int(alive[-1]) + 1 + w // 2 if alive.size else 0
    cut = min(n, max(cut, min_samples))
    if cut >= n:
        return dataclasses.replace(run)
    return _slice_run(run, slice(0, cut))


def _slice_run(run: Run, sl: slice) -> Run:
    kw: dict[str, Any] = {}
    for key in ("t", "theta", "torque", "input", "theta_dot", "lines"):
        value = getattr(run, key)
        kw[key] = None if value is None else value[sl].copy()
    return dataclasses.replace(run, **kw)


# --------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, force: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically, refusing to overwrite without ``force``.

    The data goes to a temporary file in the same folder, is flushed to disk and then
    renamed over ``path`` (``os.replace``), so readers see either the old file or the
    complete new one. Missing parent folders are created.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    target = Path(path)
    source = str(path)
    if target.is_dir():
        raise input_error(source, "is a directory", "choose a file name with -o")
    if target.exists() and not force:
        raise input_error(
            source, "already exists", "pass --force to overwrite or choose another -o"
        )
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise input_error(
            source, f"cannot create its folder ({exc.strerror or exc})", "choose another -o"
        ) from None
    tmp = parent / f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise input_error(
            source,
            f"cannot be written ({exc.strerror or exc})",
            "choose a writable location with -o",
        ) from None
    except BaseException:  # Ctrl-C (KeyboardInterrupt) between the write and the rename
        tmp.unlink(missing_ok=True)
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str, force: bool = False) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) atomically; see :func:`atomic_write_bytes`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = atomic_write_text(pathlib.Path(d, "out.json"), "{}\\n")
    ...     atomic_write_text(p, "{}\\n")
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: .../out.json: already exists; fix: pass --force to overwrite or choose another -o
    """
    return atomic_write_bytes(path, text.encode("utf-8"), force=force)


def _csv_name(name: str) -> str:
    if any(c in name for c in ',"\n\r') or name != name.strip():
        return '"' + name.replace('"', '""') + '"'
    return name


def write_csv(
    dataset: Dataset,
    path: str | os.PathLike[str],
    predictions: Mapping[str, Sequence[np.ndarray]] | Sequence[np.ndarray] | None = None,
    force: bool = False,
) -> Path:
    """Write a dataset as long-format CSV (SI units), atomically.

    Columns: ``run,t,theta,current`` plus ``torque`` (driven) or ``input`` (forced), plus
    ``theta_dot`` when every run has it, plus prediction columns. Numbers use ``%.10g``.

    Parameters
    ----------
    dataset : Dataset
        The runs to write.
    path : path-like
        Output file; an existing file is only replaced with ``force=True``.
    predictions : sequence of arrays or dict, optional
        Model output to write beside the data: one array per run (column
        ``<measured>_model``, e.g. ``theta_model``), or a dict ``column name -> one array
        per run``.
    force : bool
        Overwrite an existing file.

    Returns
    -------
    pathlib.Path
        The path written.

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> t = np.arange(30) * 0.01
    >>> ds = Dataset([Run("a", t, np.sin(t), 0.5, torque=np.cos(t))], "driven", "mem")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = write_csv(ds, pathlib.Path(d, "out.csv"))
    ...     print(p.read_text().splitlines()[:2])
    ['run,t,theta,current,torque', 'a,0,0,0.5,1']
    """
    if not isinstance(dataset, Dataset):
        raise input_error(
            str(path), f"expected a Dataset, got {type(dataset).__name__}", "pass a Dataset"
        )
    if Path(path).exists() and not force:  # fail before formatting a large file
        raise input_error(
            str(path), "already exists", "pass --force to overwrite or choose another -o"
        )
    extra = _EXTRA_COLUMN[dataset.experiment]
    keys = ["t", "theta"]
    names = ["run", "t", "theta", "current"]
    if extra:
        keys.append(extra)
        names.append(extra)
    if dataset.runs and all(r.theta_dot is not None for r in dataset.runs):
        keys.append("theta_dot")
        names.append("theta_dot")
    pred_cols: dict[str, list[np.ndarray]] = {}
    if predictions is not None:
        if isinstance(predictions, Mapping):
            items = dict(predictions)
        else:
            items = {f"{dataset.measured()}_model": predictions}
        for col, per_run in items.items():
            col = str(col)
            if col in names or not col or any(c in col for c in ',"\n'):
                raise input_error(
                    str(path),
                    f"prediction column name {col!r} is not allowed",
                    "choose another name",
                )
            arrays = list(per_run.values()) if isinstance(per_run, Mapping) else list(per_run)
            if len(arrays) != len(dataset.runs):
                raise input_error(
                    str(path),
                    f"prediction {col!r} has {len(arrays)} arrays for {len(dataset.runs)} runs",
                    "give one prediction array per run",
                )
            checked = []
            for run, arr in zip(dataset.runs, arrays, strict=True):
                a = _as_vector(arr, col, run.name, str(path))
                if a.size != run.n:
                    raise input_error(
                        str(path),
                        f"prediction {col!r} has {a.size} samples but the run has {run.n}",
                        "give one predicted value per sample",
                        run=run.name,
                    )
                checked.append(a)
            pred_cols[col] = checked
            names.append(col)
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    for i, run in enumerate(dataset.runs):
        arrs = [run.t, run.theta, np.full(run.n, run.current)]
        arrs += [getattr(run, k) for k in keys[2:]]
        arrs += [pred_cols[c][i] for c in pred_cols]
        body = io.StringIO()
        np.savetxt(body, np.column_stack(arrs), fmt="%.10g", delimiter=",")
        head = f"{_csv_name(run.name)},"
        buf.write("".join(head + line + "\n" for line in body.getvalue().splitlines()))
    return atomic_write_text(path, buf.getvalue(), force=force)


# --------------------------------------------------------------------------------------
# rig descriptions and the single entry point
# --------------------------------------------------------------------------------------

_RIG_KEYS = {
    "experiment",
    "columns",
    "units",
    "current",
    "skip_rows",
    "fs",
    "name",
    "description",
    "path",
}
_CURRENT_KEYS = {"from_name", "decimal", "value"}


def _normalize_rig(rig: Mapping[str, Any], source: str) -> dict[str, Any]:
    if not isinstance(rig, Mapping):
        raise input_error(
            source,
            "the rig description must be a table of settings",
            "see the rig.toml example in the docs",
        )
    unknown = sorted(set(rig) - _RIG_KEYS)
    if unknown:
        raise input_error(
            source,
            f"unknown rig setting(s) {', '.join(map(repr, unknown))}",
            f"use only {', '.join(sorted(_RIG_KEYS - {'path'}))}",
        )
    out: dict[str, Any] = {
        "experiment": None,
        "columns": {},
        "units": {},
        "current": {"value": None, "from_name": None, "decimal": "x"},
        "skip_rows": 0,
        "fs": None,
        "path": str(rig.get("path", source)),
    }
    if rig.get("experiment") is not None:
        out["experiment"] = _check_experiment(rig["experiment"], source)
    out["columns"] = _check_column_map(rig.get("columns") or {}, source)
    units = rig.get("units") or {}
    if not isinstance(units, Mapping):
        raise input_error(
            source, "[units] must be a table", 'write e.g. theta = "mm" under [units]'
        )
    for column, unit in units.items():
        unit_factor(str(column), str(unit), source)  # validate now
    out["units"] = {str(k): str(v) for k, v in units.items()}
    cur = rig.get("current")
    if cur is not None:
        if isinstance(cur, (int, float)) and not isinstance(cur, bool):
            cur = {"value": cur}
        if not isinstance(cur, Mapping):
            raise input_error(
                source,
                "[current] must be a table or a number",
                "write value = 0.5 or from_name = '...'",
            )
        bad = sorted(set(cur) - _CURRENT_KEYS)
        if bad:
            raise input_error(
                source,
                f"unknown [current] setting(s) {', '.join(map(repr, bad))}",
                "use value, from_name and decimal",
            )
        if cur.get("value") is not None:
            value = cur["value"]
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
            ):
                raise input_error(
                    source, f"[current] value {value!r} is not a number", "give the current in A"
                )
            out["current"]["value"] = float(value)
        if cur.get("from_name") is not None:
            pattern = str(cur["from_name"])
            try:
                re.compile(pattern)
            except re.error as exc:
                raise input_error(
                    source,
                    f"[current] from_name {pattern!r} is not a valid regex ({exc})",
                    "fix the pattern",
                ) from None
            out["current"]["from_name"] = pattern
        if cur.get("decimal") is not None:
            out["current"]["decimal"] = str(cur["decimal"])
    skip = rig.get("skip_rows", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise input_error(source, f"skip_rows = {skip!r} is invalid", "use a whole number >= 0")
    out["skip_rows"] = skip
    fs = rig.get("fs")
    if fs is not None:
        if not _valid_rate(fs):
            raise input_error(
                source, f"fs = {fs!r} is invalid", "give the sampling rate in Hz (> 0)"
            )
        out["fs"] = float(fs)
    for key in ("name", "description"):
        if key in rig:
            out[key] = str(rig[key])
    return out


def read_rig(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a rig description (TOML) that says how to read header-less tables.

    The file may hold ``experiment``, ``[columns]`` (0-based indices for tables, names for
    CSV/MAT), ``[units]``, ``[current]`` (``value``, or ``from_name`` with ``decimal``),
    ``skip_rows``, ``fs`` and free-text ``name`` / ``description``.

    Returns
    -------
    dict
        Normalized settings with keys ``experiment, columns, units, current, skip_rows, fs,
        path`` (``current`` is a dict with ``value, from_name, decimal``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d, "rig.toml")
    ...     _ = p.write_text('experiment = "driven"\\n[columns]\\nt = 0\\ntheta = 1\\ntorque = 3\\n'
    ...                      "[current]\\nfrom_name = '(\\\\d+(?:x\\\\d+)?)A$'\\n")
    ...     rig = read_rig(p)
    >>> rig["experiment"], rig["columns"], rig["current"]["from_name"]
    ('driven', {'t': 0, 'theta': 1, 'torque': 3}, '(\\\\d+(?:x\\\\d+)?)A$')
    """
    source = str(path)
    text = _read_text(path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise input_error(
            source, f"is not valid TOML ({exc})", "fix the syntax at the place shown"
        ) from None
    return _normalize_rig(raw, source)


def _expand(paths: Any) -> tuple[list[Path], Path | None, str]:
    """Files to read, the rig.toml found in a given folder, and a source label."""
    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if not items:
        raise input_error(None, "no input files given", "pass a data file or a folder")
    files: list[Path] = []
    rig_file: Path | None = None
    for item in items:
        p = Path(item)
        if not p.exists():
            raise input_error(str(item), "file does not exist", "check the path")
        if p.is_dir():
            found = sorted(
                (q for q in p.iterdir() if q.is_file() and q.suffix.lower() in DATA_SUFFIXES),
                key=lambda q: q.name,
            )
            if not found:
                raise input_error(
                    str(item),
                    f"folder holds no data files ({', '.join('*' + s for s in DATA_SUFFIXES)})",
                    "point to the folder with the measured runs",
                )
            files.extend(found)
            if (p / "rig.toml").is_file() and rig_file is None:
                rig_file = p / "rig.toml"
        else:
            files.append(p)
    if len(items) == 1:
        label = str(items[0])
    elif len(files) <= 3:
        label = ", ".join(str(f) for f in files)
    else:
        label = f"{files[0]} and {len(files) - 1} more files"
    return files, rig_file, label


def load(
    paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    experiment: str | None = None,
    rig: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    columns: Mapping[str, str | int] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    current: float | None = None,
    fs: float | None = None,
) -> Dataset:
    """Load one or several data files (or folders) into one checked Dataset.

    Dispatches on the extension: ``.csv`` -> :func:`read_csv`, ``.mat`` -> :func:`read_mat`,
    anything else -> :func:`read_table`, which needs a rig description (``rig=``, or a
    ``rig.toml`` inside a folder given as input). A folder means all its ``*.txt, *.dat,
    *.csv, *.mat`` files, sorted by name. Several files are concatenated; when run names
    collide every run is renamed ``<file stem>:<run>``. All files must hold the same
    experiment type. Several ``.mat`` files that each lack ``theta`` are merged into one run
    (input and output saved separately).

    Parameters
    ----------
    paths : path-like or list of path-likes
        Files and/or folders.
    experiment : {"release", "driven", "forced"}, optional
        Overrides the rig description and the inference from columns.
    rig : path-like or dict, optional
        Rig description (see :func:`read_rig`).
    columns, units : dict, optional
        Override (per key) the rig's ``[columns]`` and ``[units]``.
    current : float, optional
        Coil current for files that do not record it (overrides the rig's ``value``).
    fs : float, optional
        Sampling rate for files without a time column/variable.

    Returns
    -------
    Dataset
        Checked with ``validate(dataset, need_currents=1)``.
    """
    files, found_rig, label = _expand(paths)
    if rig is None and found_rig is not None:
        rig = found_rig
    if rig is None:
        settings = _normalize_rig({}, label)
    elif isinstance(rig, Mapping):
        settings = _normalize_rig(rig, "rig description")
    else:
        settings = read_rig(rig)
    exp = _check_experiment(experiment, label) if experiment is not None else settings["experiment"]
    colmap = dict(settings["columns"])
    colmap.update(_check_column_map(columns, label))
    unit_map = dict(settings["units"])
    unit_map.update(dict(units or {}))
    cur_value = current if current is not None else settings["current"]["value"]
    rate = fs if fs is not None else settings["fs"]

    mats = [f for f in files if f.suffix.lower() == ".mat"]
    merge_mats = False
    if len(mats) > 1:
        theta_name = colmap.get("theta", "theta")
        if isinstance(theta_name, str):
            import scipy.io

            def has_theta(f: Path) -> bool:
                try:
                    names = [w[0] for w in scipy.io.whosmat(str(f))]
                except Exception:
                    return True  # let read_mat report the problem
                return _mat_lookup(dict.fromkeys(names), theta_name) is not None

            merge_mats = not all(has_theta(f) for f in mats)

    datasets: list[tuple[Path, Dataset]] = []
    done_mats = False
    for f in files:
        suffix = f.suffix.lower()
        if suffix == ".csv":
            ds = read_csv(f, exp, colmap or None, unit_map or None)
        elif suffix == ".mat":
            if merge_mats:
                if done_mats:
                    continue
                done_mats = True
                ds = read_mat(
                    mats, exp, colmap or None, unit_map or None, current=cur_value, fs=rate
                )
            else:
                ds = read_mat(f, exp, colmap or None, unit_map or None, current=cur_value, fs=rate)
        else:
            if not colmap:
                raise input_error(
                    str(f),
                    "is a table without header and no rig description says what its columns are",
                    "describe the columns in a rig.toml (experiment, [columns], [units], [current]) "
                    "and pass --rig rig.toml, or put it in the data folder",
                )
            table_exp = exp
            if table_exp is None:
                table_exp = _infer_experiment([k for k in colmap], str(f))
            ds = read_table(
                f,
                colmap,
                table_exp,
                units=unit_map or None,
                current=cur_value,
                current_from_name=settings["current"]["from_name"],
                skip_rows=settings["skip_rows"],
                decimal=settings["current"]["decimal"],
                fs=rate,
            )
        datasets.append((f, ds))

    if len(datasets) == 1:
        ds = datasets[0][1]
        ds.source = label
        return ds
    kinds = {ds.experiment for _, ds in datasets}
    if len(kinds) > 1:
        shown = "; ".join(f"{f.name}: {ds.experiment}" for f, ds in datasets[:6])
        raise input_error(
            label,
            f"the files hold different experiment types ({shown})",
            "load them separately, or pass --experiment to read them all the same way",
        )
    runs = [r for _, ds in datasets for r in ds.runs]
    names = [r.name for r in runs]
    if len(set(names)) != len(names):
        renamed = []
        for f, ds in datasets:
            for r in ds.runs:
                renamed.append(dataclasses.replace(r, name=f"{f.stem}:{r.name}"))
        count: dict[str, int] = {}
        runs = []
        for r in renamed:
            count[r.name] = count.get(r.name, 0) + 1
            runs.append(
                r
                if count[r.name] == 1
                else dataclasses.replace(r, name=f"{r.name}#{count[r.name]}")
            )
    out = Dataset(runs, kinds.pop(), label)
    validate(out, need_currents=1)
    return out
