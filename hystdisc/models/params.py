"""Named parameters with units, admissible bounds and demo defaults."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hystdisc.errors import HystdiscError


@dataclass(frozen=True)
class Param:
    """A named parameter with unit, physical bounds and a demo default."""

    name: str
    unit: str
    lower: float
    upper: float
    default: float
    doc: str = ""


#: Bound standing for 'unbounded' in parameter tables.
BIG = 1e9


def param_table(text: str) -> tuple[Param, ...]:
    """Parameters from a text table, one a line: ``name unit lower upper default doc``.

    Columns are separated by white space, the doc (the rest of the line) may contain it;
    a bound or default is a number, ``BIG`` or ``-BIG`` (:data:`BIG`), or a quotient
    ``a/b``. Blank lines and lines starting with ``#`` are skipped.

    Examples
    --------
    >>> param_table('''
    ...     # name  unit  lower  upper  default  doc
    ...     a_0     1/s   1e-9   BIG    2/3      rate (per second)
    ... ''')
    (Param(name='a_0', unit='1/s', lower=1e-09, upper=1000000000.0, default=0.6666666666666666, doc='rate (per second)'),)
    """

    def number(word: str) -> float:
        if word.lstrip("-") == "BIG":
            return -BIG if word.startswith("-") else BIG
        num, _, den = word.partition("/")
        return float(num) / float(den) if den else float(num)

    rows = (line.split(maxsplit=5) for line in text.splitlines())
    return tuple(
        Param(name, unit, number(lower), number(upper), number(default), doc)
        for name, unit, lower, upper, default, doc in (r for r in rows if r and r[0][0] != "#")
    )


RIG_PARAMS = (
    Param("k_s", "N*m/rad per unit J", 0.0, BIG, 158.0, "rig spring stiffness"),
    Param("J", "kg*m^2", 1e-12, BIG, 1.0, "inertia (forced experiments only)"),
)


def check_params(
    owner: str, specs: tuple[Param, ...], given: Mapping[str, float]
) -> dict[str, float]:
    """The values of ``specs`` by name: those ``given`` (checked against the bounds) and
    the defaults; an unknown name or a value out of bounds is a one-line HystdiscError
    that names ``owner``."""
    known = {p.name: p for p in specs}
    for k in given:
        if k not in known:
            raise HystdiscError(
                f"{owner}: unknown parameter '{k}'; fix: use one of {', '.join(known)}"
            )
    out = {}
    for p in specs:
        v = given.get(p.name, p.default)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise HystdiscError(
                f"{owner}: parameter {p.name}={v!r} is not a number; fix: give a number"
            ) from None
        if not np.isfinite(v):
            raise HystdiscError(f"{owner}: parameter {p.name} is {v}; fix: give a finite number")
        if not (p.lower <= v <= p.upper):
            raise HystdiscError(
                f"{owner}: parameter {p.name}={v:g} is outside its physical bounds "
                f"[{p.lower:g}, {p.upper:g}]; fix: give a value within them"
            )
        out[p.name] = v
    return out
