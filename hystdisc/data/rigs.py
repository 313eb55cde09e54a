"""Rig descriptions (``rig.toml``): how to read a rig's header-less tables.

A rig description says the experiment type, which column holds what (``[columns]``), the
units (``[units]``), where the coil current comes from (``[current]``), how the recorded
signals were filtered before they reached hystdisc (``[filter]``), lines to skip and the
sampling rate. :func:`read_rig` reads one; :func:`normalize_rig` checks a dict of the
same settings; :func:`filter_windows` turns a ``[filter]`` into each run's window.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hystdisc.data.columns import check_column_map, valid_rate
from hystdisc.data.dataset import Run, check_experiment
from hystdisc.data.text import parse_toml, read_text
from hystdisc.data.units import unit_factor
from hystdisc.errors import input_error

__all__ = ["filter_windows", "motion_frequency", "normalize_rig", "read_rig"]

_RIG_KEYS = {
    "experiment",
    "columns",
    "units",
    "current",
    "skip_rows",
    "fs",
    "filter",
    "name",
    "description",
    "path",
}
_CURRENT_KEYS = {"from_name", "decimal", "value"}
_FILTER_KEYS = {"kind", "window", "period_fraction", "channels"}
#: Channels a ``[filter]`` may name: the motion, and the force (driven torque, forced input).
FILTER_CHANNELS = ("theta", "torque", "input")


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
        "filter": None,
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
    if rig.get("filter") is not None:
        out["filter"] = _rig_filter(rig["filter"], source)
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


def _rig_filter(filt: Any, source: str) -> dict[str, Any]:
    """The ``[filter]`` table, checked: a causal moving average of ``window`` samples or of
    ``period_fraction`` of each run's period, on ``channels``."""
    _check_settings(
        filt,
        _FILTER_KEYS,
        source,
        (
            "[filter] must be a table",
            "write window = 100 (or period_fraction = 0.1) under [filter]",
        ),
        ("[filter]", "use window or period_fraction, and channels"),
    )
    kind = filt.get("kind", "moving_average")
    if kind != "moving_average":
        raise input_error(
            source, f"[filter] kind {kind!r} is not known", 'use kind = "moving_average"'
        )
    window, frac = filt.get("window"), filt.get("period_fraction")
    if (window is None) == (frac is None):
        raise input_error(
            source,
            "[filter] needs exactly one of window and period_fraction",
            "give window = N (samples) or period_fraction = 0.1 (of each test's period)",
        )
    if window is not None and (
        isinstance(window, bool) or not isinstance(window, int) or window < 1
    ):
        raise input_error(
            source,
            f"[filter] window = {window!r} is invalid",
            "give a whole number of samples >= 1",
        )
    if frac is not None and (
        isinstance(frac, bool)
        or not isinstance(frac, (int, float))
        or not (math.isfinite(frac) and 0.0 < frac <= 1.0)
    ):
        raise input_error(
            source,
            f"[filter] period_fraction = {frac!r} is invalid",
            "give a fraction of the period in (0, 1], e.g. 0.1",
        )
    channels = filt.get("channels")
    if (
        not isinstance(channels, list)
        or not channels
        or any(c not in FILTER_CHANNELS for c in channels)
    ):
        raise input_error(
            source,
            f"[filter] channels = {channels!r} is invalid",
            f"list the filtered columns among {', '.join(FILTER_CHANNELS)}, e.g. "
            'channels = ["theta", "torque"]',
        )
    return {
        "kind": "moving_average",
        "window": None if window is None else int(window),
        "period_fraction": None if frac is None else float(frac),
        "channels": [str(c) for c in channels],
    }


def motion_frequency(t: np.ndarray, theta: np.ndarray) -> float:
    """Frequency of an oscillating record from the spacing of its mean-level crossings.

    A crossing counts only when the record goes from below to above a tenth of its
    amplitude about the mean level (or back), so a record that starts at that level or
    wiggles about it is not miscounted; the crossing time is interpolated. 0 when the
    record crosses fewer than three times.

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> round(motion_frequency(t, np.sin(2 * np.pi * 1.3 * t)), 6)
    1.3
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(theta, dtype=float)
    x = x - 0.5 * (x.max() + x.min())
    h = 0.1 * 0.5 * float(np.ptp(x))
    side = np.where(x > h, 1, np.where(x < -h, -1, 0))
    idx = np.flatnonzero(side)
    switch = np.flatnonzero(side[idx[1:]] != side[idx[:-1]])
    tc = []
    for j in switch:
        a, b = idx[j], idx[j + 1]
        seg = x[a : b + 1]
        k = a + np.flatnonzero(np.signbit(seg[1:]) != np.signbit(seg[:-1]))[-1]
        tc.append(t[k] + (t[k + 1] - t[k]) * x[k] / (x[k] - x[k + 1]))
    if len(tc) < 3:
        return 0.0
    return (len(tc) - 1) / (2.0 * float(tc[-1] - tc[0]))


def filter_windows(filt: Mapping[str, Any], runs: Sequence[Run], source: str = "") -> list[int]:
    """Each run's moving-average window in samples for a checked ``[filter]`` table.

    ``window`` is used as it is; ``period_fraction`` gives
    ``round(period_fraction / (Ts * f))`` samples, ``f`` the frequency of the run's motion
    (from its crossings of its mean level) and ``Ts`` its sampling interval. A filter read
    in the records (:meth:`hystdisc.data.filters.FilterFound.table`) gives each run's
    window in ``windows`` (0 for a run absent from it: not filtered).

    Examples
    --------
    >>> t = np.arange(3000) * 1e-3
    >>> run = Run("a", t, np.sin(2 * np.pi * 1.0 * t), 0.0)
    >>> filter_windows({"window": None, "period_fraction": 0.1}, [run])
    [100]
    """
    out = []
    for r in runs:
        if filt.get("windows") is not None:  # read in the records (a run absent: none)
            out.append(int(filt["windows"].get(r.name, 0)))
            continue
        if filt.get("window") is not None:
            out.append(int(filt["window"]))
            continue
        t = np.asarray(r.t, dtype=float)
        f = motion_frequency(t, r.theta)
        if f <= 0:
            raise input_error(
                source,
                "[filter] period_fraction needs a periodic motion, but the motion of this run "
                "does not oscillate",
                "give the window in samples (window = N) instead",
                run=r.name,
            )
        ts = float(np.median(np.diff(t)))
        out.append(max(1, int(round(float(filt["period_fraction"]) / (ts * f)))))
    return out


def read_rig(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a rig description (TOML) that says how to read header-less tables.

    The file may hold ``experiment``, ``[columns]`` (0-based indices for tables, names for
    CSV/MAT), ``[units]``, ``[current]`` (``value``, or ``from_name`` with ``decimal``),
    ``[filter]`` (a causal moving average applied before the data reached hystdisc:
    ``window = N`` samples or ``period_fraction = 0.1`` of each test's period, on
    ``channels = ["theta", "torque"]``), ``skip_rows``, ``fs`` and free-text ``name`` /
    ``description``.

    Returns
    -------
    dict
        Normalized settings with keys ``experiment, columns, units, current, skip_rows, fs,
        filter, path`` (``current`` is a dict with ``value, from_name, decimal``; ``filter``
        None or a dict with ``kind, window, period_fraction, channels``).

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
