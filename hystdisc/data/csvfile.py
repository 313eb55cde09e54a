"""The long-format CSV reader: a header row, then one row per sample.

See :func:`read_csv`; :func:`hystdisc.data.write_csv` writes the same format.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping

import numpy as np

from hystdisc.data.columns import build_dataset, check_column_map, infer_experiment
from hystdisc.data.dataset import (
    CANONICAL_COLUMNS,
    COLUMN_FLAG,
    Dataset,
    check_experiment,
    extra_column,
    needed_columns,
)
from hystdisc.data.text import data_lines, guess_delimiter, parse_floats, read_text, split_rows
from hystdisc.data.units import apply_units
from hystdisc.data.validation import check_one_current, validate
from hystdisc.errors import HystdiscWarning, input_error

__all__ = ["read_csv"]


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
        appearance. Without a ``current`` column every run is at 0 A (a rig without a
        coil), with a warning.

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
    text = read_text(path)
    colmap = check_column_map(columns, source)
    lines = data_lines(text)
    if not lines:
        raise input_error(source, "file is empty", "point to a file that holds the measured data")
    delimiter, header = _read_header(lines, source)
    where = {c: _locate(c, header, colmap, source) for c in CANONICAL_COLUMNS}
    present = [c for c, i in where.items() if i is not None]
    exp = (
        check_experiment(experiment, source)
        if experiment is not None
        else infer_experiment(present, source)
    )
    _check_needed(where, header, exp, source)
    current = None if where["current"] is not None else 0.0  # a rig without a coil: 0 A
    linenos, rows = split_rows(lines[1:], delimiter, source, len(header), "as many as the header")
    wanted = [c for c in needed_columns(exp) + ["theta_dot"] if where[c] is not None]
    cols: dict[str, np.ndarray] = {}
    for canon in wanted:
        i = where[canon]
        assert i is not None
        cols[canon] = parse_floats([r[i] for r in rows], linenos, source, header[i])
    run_ids = [r[where["run"]] for r in rows] if where["run"] is not None else None
    apply_units(cols, units, source)
    ds = build_dataset(cols, run_ids, linenos, source, exp, current=current)
    validate(ds, need_currents=1)
    if current is not None:  # runs that differ as currents do are an error, not 0 A
        check_one_current(ds, source)
        warnings.warn(
            f"{source}: no 'current' column: every run is taken at 0 A (a rig without a "
            f"coil); fix: add a 'current' column, or map yours with {COLUMN_FLAG} current=NAME",
            HystdiscWarning,
            stacklevel=2,
        )
    return ds


def _read_header(lines: list[tuple[int, str]], source: str) -> tuple[str | None, list[str]]:
    """The delimiter and the column names; the file must have data rows after them."""
    delimiter = guess_delimiter(lines[0][1])
    _, hdr = split_rows(lines[:1], delimiter, source, None, "header")
    # a byte-order mark that is not at the start of the file (a comment line was put in
    # front of a UTF-8-BOM file) is invisible in the messages: drop it from the names
    header = [h.replace("\ufeff", "").strip().strip('"').strip() for h in hdr[0]]
    if not lines[1:]:
        raise input_error(
            source, "has a header but no data rows", "point to a file that holds the measured data"
        )
    return delimiter, header


def _locate(
    canon: str, header: list[str], colmap: Mapping[str, str | int], source: str
) -> int | None:
    """Position of the column ``canon`` in the header (None if absent and not mapped)."""
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
            f"correct the mapping {COLUMN_FLAG} {canon}=NAME",
        )
    return hits[0] if hits else None


def _check_needed(
    where: Mapping[str, int | None], header: list[str], exp: str, source: str
) -> None:
    """Every column the experiment needs is in the header."""
    for canon in needed_columns(exp):
        if where[canon] is None and canon != "current":  # no current: 0 A, with a warning
            why = f" (a {exp} experiment needs it)" if canon == extra_column(exp) else ""
            raise input_error(
                source,
                f"column {canon!r} is missing{why} (found: {', '.join(header[:12])})",
                f"add it or map yours with {COLUMN_FLAG} {canon}=NAME",
            )
