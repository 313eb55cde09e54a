"""From columns read out of a file to a Dataset: the column map, the coil current of a run
(from a column, an argument or the file name), the experiment type the columns imply, and
the grouping of samples into runs. Shared by the CSV, table and MAT readers.

Examples
--------
>>> from hystdisc.data import current_from_name
>>> current_from_name("25mm0x25Hz0x75A.txt")
0.75
"""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc.data.dataset import (
    CANONICAL_COLUMNS,
    EXPERIMENTS,
    Dataset,
    Run,
    extra_column,
)
from hystdisc.errors import input_error

__all__ = [
    "DATA_SUFFIXES",
    "DEFAULT_CURRENT_PATTERN",
    "build_dataset",
    "check_column_map",
    "current_from_name",
    "given_current",
    "infer_experiment",
    "run_current",
    "valid_rate",
]

DATA_SUFFIXES = (".txt", ".dat", ".csv", ".mat")
"""File extensions :func:`hystdisc.data.load` picks up when given a folder."""

DEFAULT_CURRENT_PATTERN = r"(\d+(?:x\d+)?)A$"
"""Default pattern for :func:`current_from_name`: ``...0x75A`` -> 0.75 A."""


def given_current(value: Any, source: str, run: str) -> float:
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


def valid_rate(fs: Any) -> bool:
    """A sampling rate: a finite real number > 0 (not a bool)."""
    return (
        isinstance(fs, (int, float, np.floating, np.integer))
        and not isinstance(fs, (bool, np.bool_))
        and math.isfinite(fs)
        and fs > 0
    )


def check_column_map(columns: Mapping[str, Any] | None, source: str) -> dict[str, Any]:
    """The column map (canonical name -> file column name or 0-based index), checked."""
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


def current_from_name(
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


def run_condition(values: np.ndarray, linenos: np.ndarray | None, source: str, run: str) -> str:
    """The condition label of a run from its ``condition`` column (one number per run)."""
    v = np.asarray(values, dtype=float)
    if v.size and not np.all(v == v[0]):
        where = f" (line {int(linenos[int(np.argmax(v != v[0]))])})" if linenos is not None else ""
        raise input_error(
            source,
            f"the condition changes within the run{where}",
            "give every sample of a run the same condition number",
            run=run,
        )
    return f"{v[0]:g}" if v.size else ""


def run_current(values: np.ndarray, linenos: np.ndarray | None, source: str, run: str) -> float:
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


@np.errstate(all="ignore")  # huge currents overflow in the median; checked later
def build_dataset(
    cols: dict[str, np.ndarray],
    run_ids: Sequence[str] | None,
    linenos: np.ndarray | None,
    source: str,
    experiment: str,
    current: float | None = None,
    default_name: str = "0",
) -> Dataset:
    """Group per-sample columns by run id (order of first appearance) into a Dataset."""
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
            cur = run_current(cols["current"][idx], lines, source, name)
        elif current is not None:
            cur = given_current(current, source, name)
        else:
            raise input_error(
                source,
                "no coil current given",
                "add a 'current' column/variable or give the current (rig [current] value or from_name)",
                run=name,
            )
        kw = {k: cols[k][idx] for k in ("torque", "input", "theta_dot") if k in cols}
        if "condition" in cols:
            kw["condition"] = run_condition(cols["condition"][idx], lines, source, name)
        runs.append(
            Run(name, cols["t"][idx], cols["theta"][idx], cur, source=source, lines=lines, **kw)
        )
    return Dataset(runs, experiment, source)


def infer_experiment(has: Iterable[str], source: str) -> str:
    """The experiment type the columns ``has`` imply: the one whose extra column is there.

    Examples
    --------
    >>> infer_experiment(["t", "theta", "torque"], "x.csv"), infer_experiment(["theta"], "x")
    ('driven', 'release')
    """
    present = set(has)
    hits = [(name, extra_column(name)) for name in EXPERIMENTS]
    found = [(name, col) for name, col in hits if col is not None and col in present]
    if len(found) > 1:
        both = " and ".join(f"{_article(col)} {col}" for _, col in found)
        options = " or ".join(f"--experiment {name}" for name, _ in found)
        raise input_error(
            source,
            f"has both {both} column, so the experiment type is ambiguous",
            f"pass {options}",
        )
    if found:
        return found[0][0]
    return next(name for name, col in hits if col is None)


def _article(word: str) -> str:
    return "an" if word[:1] in "aeiou" else "a"
