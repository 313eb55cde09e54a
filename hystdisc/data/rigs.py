"""Rig descriptions (``rig.toml``): how to read a rig's header-less tables.

A rig description says the experiment type, which column holds what (``[columns]``), the
units (``[units]``), where the coil current comes from (``[current]``), lines to skip and
the sampling rate. :func:`read_rig` reads one; :func:`normalize_rig` checks a dict of the
same settings.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from typing import Any

from hystdisc.data.columns import check_column_map, valid_rate
from hystdisc.data.dataset import check_experiment
from hystdisc.data.text import parse_toml, read_text
from hystdisc.data.units import unit_factor
from hystdisc.errors import input_error

__all__ = ["normalize_rig", "read_rig"]

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


def _check_settings(
    table: Any,
    allowed: set[str],
    source: str,
    not_table: tuple[str, str],
    unknown: tuple[str, str],
) -> None:
    """``table`` is a mapping with only ``allowed`` keys; else the error ``not_table``
    (problem, fix), or an "unknown <unknown[0]> setting(s)" error with fix ``unknown[1]``."""
    if not isinstance(table, Mapping):
        raise input_error(source, *not_table)
    bad = sorted(set(table) - allowed)
    if bad:
        raise input_error(
            source, f"unknown {unknown[0]} setting(s) {', '.join(map(repr, bad))}", unknown[1]
        )


def normalize_rig(rig: Mapping[str, Any], source: str) -> dict[str, Any]:
    """Check a rig description; the settings with defaults (see :func:`read_rig`)."""
    _check_settings(
        rig,
        _RIG_KEYS,
        source,
        ("the rig description must be a table of settings", "see the rig.toml example in the docs"),
        ("rig", f"use only {', '.join(sorted(_RIG_KEYS - {'path'}))}"),
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
        out["experiment"] = check_experiment(rig["experiment"], source)
    out["columns"] = check_column_map(rig.get("columns") or {}, source)
    out["units"] = _rig_units(rig.get("units") or {}, source)
    cur = rig.get("current")
    if cur is not None:
        out["current"].update(_rig_current(cur, source))
    skip = rig.get("skip_rows", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise input_error(source, f"skip_rows = {skip!r} is invalid", "use a whole number >= 0")
    out["skip_rows"] = skip
    fs = rig.get("fs")
    if fs is not None:
        if not valid_rate(fs):
            raise input_error(
                source, f"fs = {fs!r} is invalid", "give the sampling rate in Hz (> 0)"
            )
        out["fs"] = float(fs)
    for key in ("name", "description"):
        if key in rig:
            out[key] = str(rig[key])
    return out


def _rig_units(units: Any, source: str) -> dict[str, str]:
    """The ``[units]`` table, every unit checked now."""
    if not isinstance(units, Mapping):
        raise input_error(
            source, "[units] must be a table", 'write e.g. theta = "mm" under [units]'
        )
    for column, unit in units.items():
        unit_factor(str(column), str(unit), source)  # validate now
    return {str(k): str(v) for k, v in units.items()}


def _rig_current(cur: Any, source: str) -> dict[str, Any]:
    """The ``[current]`` settings given (``value``, ``from_name``, ``decimal``), checked."""
    if isinstance(cur, (int, float)) and not isinstance(cur, bool):
        cur = {"value": cur}
    _check_settings(
        cur,
        _CURRENT_KEYS,
        source,
        ("[current] must be a table or a number", "write value = 0.5 or from_name = '...'"),
        ("[current]", "use value, from_name and decimal"),
    )
    out: dict[str, Any] = {}
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
        out["value"] = float(value)
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
        out["from_name"] = pattern
    if cur.get("decimal") is not None:
        out["decimal"] = str(cur["decimal"])
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
    return normalize_rig(parse_toml(read_text(path), source), source)
