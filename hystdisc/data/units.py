"""Units: the factor that converts a column given in a user's unit to SI.

Examples
--------
>>> from hystdisc.data import unit_factor
>>> unit_factor("theta", "mm"), unit_factor("current", "mA")
(0.001, 0.001)
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np

from hystdisc.errors import input_error

__all__ = ["apply_units", "unit_factor"]


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


def apply_units(cols: dict[str, np.ndarray], units: Mapping[str, str] | None, source: str) -> None:
    """Convert the columns ``cols`` in place from ``units`` (column -> unit) to SI."""
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
