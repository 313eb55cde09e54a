"""The reader of header-less whitespace tables (one file, one run), as many test rigs
write them; a column map or a rig description (:func:`hystdisc.data.read_rig`) says what
the columns are.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from hystdisc.data.columns import build_dataset, check_column_map, valid_rate
from hystdisc.data.columns import current_from_name as _current_in_name
from hystdisc.data.dataset import Dataset, check_experiment, needed_columns
from hystdisc.data.text import data_lines, parse_floats, read_text, split_rows
from hystdisc.data.units import apply_units
from hystdisc.data.validation import validate
from hystdisc.errors import input_error

__all__ = ["read_table"]


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
        for the decimal point; see :func:`hystdisc.data.current_from_name`.
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
    exp = check_experiment(experiment, source)
    colmap = _check_table_map(columns, exp, fs, source)
    if not isinstance(skip_rows, (int, np.integer)) or skip_rows < 0:
        raise input_error(source, f"skip_rows={skip_rows!r} is invalid", "use a whole number >= 0")
    text = read_text(path)
    lines = data_lines(text, int(skip_rows))
    if not lines:
        raise input_error(
            source, "holds no data rows", "point to a file that holds the measured data"
        )
    linenos, rows = split_rows(lines, None, source, None, "as many as the first data row")
    cols = _table_columns(colmap, rows, linenos, source)
    if "t" not in cols:
        if not valid_rate(fs):
            raise input_error(
                source,
                "no time column and no valid sampling rate"
                + ("" if fs is None else f" (fs = {fs!r})"),
                "give the sampling rate fs in Hz (a finite number > 0) or map a time column",
            )
        cols["t"] = np.arange(len(rows), dtype=np.float64) / float(fs)
    if "current" not in cols and current is None:
        if current_from_name is None:
            raise input_error(
                source,
                "no coil current given",
                "set [current] value = ... or from_name = '<regex>' in the rig description",
            )
        current = _current_in_name(source, current_from_name, decimal)
    apply_units(cols, units, source)
    ds = build_dataset(
        cols, None, linenos, source, exp, current=current, default_name=Path(source).stem
    )
    validate(ds, need_currents=1)
    return ds


def _check_table_map(
    columns: Mapping[str, int], exp: str, fs: float | None, source: str
) -> dict[str, int]:
    """The column map: indices only, and every column the experiment needs."""
    colmap = check_column_map(columns, source)
    for key, value in colmap.items():
        if not isinstance(value, int):
            raise input_error(
                source,
                f"column map entry {key}={value!r} is a name, but the table has no header",
                f"map {key} to a 0-based column index",
            )
    needed = [c for c in needed_columns(exp) if c != "current"]
    if fs is not None:
        needed.remove("t")
    for canon in needed:
        if canon not in colmap:
            fix = f"add {canon} = <0-based index> to the [columns] of the rig description"
            if canon == "t":
                fix += " or give the sampling rate fs"
            raise input_error(source, f"no column given for {canon!r}", fix)
    return colmap


def _table_columns(
    colmap: Mapping[str, int], rows: list[list[str]], linenos: np.ndarray, source: str
) -> dict[str, np.ndarray]:
    """The mapped columns (all but ``run``) as numbers."""
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
        cols[canon] = parse_floats(
            [r[i] for r in rows], linenos, source, f"{canon} (column {i})", hint
        )
    return cols
