"""A delay between the two recorded channels, found before the families are compared.

A driven or forced test records two channels (the motion or input, and the output); a
delay between them (an anti-alias filter on one channel, a transport lag) makes every
family miss, and the families compared without it pick the one that best absorbs the lag,
not the damper's. Stage 1 sees it cheaply: with the discovered structure's columns fixed,
the equation error of the output shifted by ``tau`` is one least-squares solve per
``tau``. :func:`scan_delay` scans a grid of delays, refines the best by a parabola, and
calls the delay found when it lowers the equation-error BIC by more than
:data:`MIN_DBIC` for its one parameter. The discovery then fits every family with the
``channel_delay`` effect started there, and judges the delay like any effect.

Examples
--------
>>> import numpy as np
>>> t = np.arange(0.0, 4.0, 1e-3)
>>> w = np.cos(2 * np.pi * t)
>>> y = 2.0 * np.cos(2 * np.pi * (t - 0.004))  # the output 4 ms behind the motion
>>> eq = EqData("driven", [t], [np.sin(2 * np.pi * t)], [w], [0 * t], [y], np.zeros(1),
...             [np.ones(t.size, dtype=bool)])
>>> found = scan_delay(eq, ["theta_dot"], np.zeros(0), "none", [t], [y])
>>> found.found, round(found.tau * 1e3, 2)
(True, 4.0)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hystdisc.discovery.data import EqData
from hystdisc.discovery.design import Design
from hystdisc.discovery.shapes import SHAPES
from hystdisc.discovery.varpro import scaled_lstsq
from hystdisc.stats import bic_change

#: The delay lowers the equation-error BIC by more than this to be called found.
MIN_DBIC = 10.0
#: Delays scanned: this many per side of zero.
GRID = 20
#: The scan reaches this fraction of the shortest cycle of the motion (and at most
#: :data:`MAX_DELAY` s).
MAX_CYCLE_FRACTION = 0.05
#: The largest delay scanned, s.
MAX_DELAY = 0.05


@dataclass
class DelayScan:
    """What :func:`scan_delay` found.

    Attributes
    ----------
    tau : float
        The delay of the output behind the motion (or input), s; 0 when none was found.
    dbic : float
        The change of the equation-error BIC at ``tau`` against no delay (negative: better).
    found : bool
        ``dbic`` is below ``-MIN_DBIC``.
    reach : float
        The largest delay scanned, s.
    """

    tau: float
    dbic: float
    found: bool
    reach: float

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        return {"tau": self.tau, "dbic": self.dbic, "found": self.found, "reach": self.reach}


def _shifted_target(eq: EqData, times: Sequence[np.ndarray], outputs: Sequence[np.ndarray],
                    tau: float) -> np.ndarray:  # fmt: skip
    """The measured output ``tau`` later than each equation-error row (linear between the
    recorded samples), on the rows, runs concatenated."""
    cols = []
    for r, m in enumerate(eq.rows):
        cols.append(np.interp(eq.t[r][m] + tau, times[r], outputs[r]))
    return np.concatenate(cols)


def scan_delay(
    eq: EqData,
    terms: Sequence[str],
    s: np.ndarray,
    shape: str,
    times: Sequence[np.ndarray],
    outputs: Sequence[np.ndarray],
) -> DelayScan:
    """Scan the delay of the recorded output behind the motion (module docstring).

    Parameters
    ----------
    eq : EqData
        The equation-error data (its rows, times and regressors).
    terms : sequence of str
        The discovered torque terms.
    s : ndarray
        The discovered shape's constants.
    shape : str
        The discovered hysteresis shape.
    times, outputs : sequence of ndarray
        Each run's recorded times and output at the full rate.

    Returns
    -------
    DelayScan
    """
    sh = SHAPES[shape]
    F, y0 = Design(eq, terms).build_flat(eq.z_flat(sh, s))
    cycle = min(
        (float(t[-1] - t[0]) for t in eq.t), default=1.0
    )  # no shorter than a run, at most its shortest cycle below
    for t, w in zip(eq.t, eq.theta_dot, strict=True):
        crossings = np.count_nonzero(np.diff(np.signbit(w - np.median(w))))
        if crossings >= 2:
            cycle = min(cycle, 2.0 * float(t[-1] - t[0]) / crossings)
    reach = min(MAX_DELAY, MAX_CYCLE_FRACTION * cycle)
    taus = np.linspace(-reach, reach, 2 * GRID + 1)
    rss = np.array([scaled_lstsq(F, _shifted_target(eq, times, outputs, tau))[1] for tau in taus])
    k = int(np.argmin(rss))
    tau = float(taus[k])
    if 0 < k < taus.size - 1:  # the parabola through the best and its neighbours
        a, b, c = rss[k - 1], rss[k], rss[k + 1]
        den = a - 2 * b + c
        if den > 0:
            tau += 0.5 * (a - c) / den * (taus[1] - taus[0])
    best = scaled_lstsq(F, _shifted_target(eq, times, outputs, tau))[1]
    base = rss[GRID]  # tau = 0
    n = eq.n_eff(y0.size)
    dbic = bic_change(best, base, n, 1)
    found = bool(dbic < -MIN_DBIC and best < base)
    return DelayScan(float(tau) if found else 0.0, float(dbic), found, float(reach))
