"""Shared parsing of text files: reading with one-line errors, data lines, fields, numbers.

The CSV reader, the table reader and the rig reader use these; every way a file can fail
(missing, a folder, binary, not UTF-8, ragged rows, a non-numeric cell, NaN) becomes a
one-line :class:`~hystdisc.errors.HystdiscError` naming the file and the line.

Examples
--------
>>> data_lines("# comment\\n\\n1 2\\n3 4\\n")
[(3, '1 2'), (4, '3 4')]
>>> guess_delimiter("t;theta;current"), guess_delimiter("t theta current") is None
(';', True)
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc.errors import input_error

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "check_finite",
    "count",
    "data_lines",
    "guess_delimiter",
    "parse_floats",
    "parse_toml",
    "read_bytes",
    "read_text",
    "split_rows",
]


def count(n: int, noun: str) -> str:
    """``n`` and ``noun``, in the plural unless ``n`` is 1 (``"3 bad values"``)."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def check_finite(
    arr: np.ndarray,
    source: str,
    what: str,
    where: Callable[[int], str],
    run: str | None = None,
) -> None:
    """Raise the one-line error for the first NaN or inf of ``arr``, if it holds any.

    ``what`` names the signal (``"column 'theta'"``), ``where(k)`` the place of sample
    ``k`` (``"on line 7"``).

    Examples
    --------
    >>> check_finite(np.array([0.0, np.nan]), "a.csv", "column 'theta'", lambda k: f"at {k}")
    Traceback (most recent call last):
    hystdisc.errors.HystdiscError: a.csv: column 'theta' holds NaN at 1 (1 bad value); fix: ...
    """
    bad = ~np.isfinite(arr)
    if bad.any():
        k = int(np.argmax(bad))
        kind = "NaN" if np.isnan(arr[k]) else "inf"
        raise input_error(
            source,
            f"{what} holds {kind} {where(k)} ({count(int(bad.sum()), 'bad value')})",
            "remove or fill the missing samples (e.g. interpolate) before loading",
            run=run,
        )


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    """The bytes of a file, or a one-line error (missing, a folder, unreadable)."""
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


def read_text(path: str | os.PathLike[str], hint: str = "") -> str:
    """Read a UTF-8 text file with one-line errors for every way this can fail."""
    source = str(path)
    data = read_bytes(path)
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


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """The table of a TOML text, or a one-line error that points at the syntax error.

    Examples
    --------
    >>> parse_toml('fs = 1000', "rig.toml")
    {'fs': 1000}
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise input_error(
            source, f"is not valid TOML ({exc})", "fix the syntax at the place shown"
        ) from None


def data_lines(text: str, skip_rows: int = 0) -> list[tuple[int, str]]:
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


def parse_floats(
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
    check_finite(arr, source, f"column {label!r}", lambda k: f"on line {int(linenos[k])}")
    return arr


def split_rows(
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


def guess_delimiter(header: str) -> str | None:
    """The most frequent of ``,`` ``;`` and tab in ``header``; None for whitespace."""
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] > 0 else None
