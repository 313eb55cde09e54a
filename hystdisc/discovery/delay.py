"""A delay between the two recorded channels, found before the families are compared.

A driven or forced test records two channels (the motion or input, and the output); a
delay between them (an anti-alias filter on one channel, a transport lag) makes every
family miss, and the families compared without it pick the one that best absorbs the lag,
not the damper's. Stage 1 sees it cheaply: with the discovered structure's shape and terms fixed,
the equation error of the output against the motion ``tau`` earlier is one ``z``
integration and one least-squares solve per ``tau``. The motion is shifted, not the
recorded output: the motion is smooth, while the output carries the noise, which a
shift between samples would average (a third of a sample's shift halves white noise's
variance, and lowered the equation error of a set without any delay by 40 %). :func:`scan_delay` scans a grid of delays, refines the best by a parabola, and
calls the delay found when it lowers the equation-error BIC by more than
:data:`MIN_DBIC` for its one parameter and removes at least :data:`MIN_SHARE` of the
equation-error residual: a lag large enough to mislead the comparison of the families (a
shift of the output also absorbs a little of any misfit of the structure, as a current
law it lacks: on a Spencer damper with a saturating law, a 2.4 ms "delay" lowered the
equation error by 2 %; a 3 ms lag behind a Bingham damper's Coulomb torque, by 93 %).
When found, the discovery fits every family with the ``channel_delay`` effect started
there, and judges the delay like any effect. A delay that lowers the BIC but not by that
share goes to the closing loop, which refits it in its first round whatever its rank
(:func:`hystdisc.pipeline.close.seen_delay`): a structure's own misfit can remove as large
a share (a tanh or Spencer damper's, without any delay: 8-23 % on the driven suite's sets,
where a 2 ms delay behind a tanh damper removed 18-25 %), so only the held-out error can
tell them apart.

Examples
--------
>>> import numpy as np
>>> t = np.arange(0.0, 4.0, 1e-3)
>>> w = np.cos(2 * np.pi * t)
>>> y = 2.0 * np.cos(2 * np.pi * (t - 0.004))  # the output 4 ms behind the motion
>>> eq = EqData("driven", [t], [np.sin(2 * np.pi * t)], [w], [0 * t], [y], np.zeros(1),
...             [np.ones(t.size, dtype=bool)])
>>> found = scan_delay(eq, ["theta_dot"], np.zeros(0), "none")
>>> found.found, round(found.tau * 1e3, 2)
(True, 4.0)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hystdisc.discovery.data import EqData
from hystdisc.discovery.design import Design
from hystdisc.discovery.varpro import scaled_lstsq
from hystdisc.models.shapes import SHAPES
from hystdisc.stats import bic_change

#: The delay lowers the equation-error BIC by more than this to be called found.
MIN_DBIC = 10.0
#: And removes at least this share of the equation-error residual.
MIN_SHARE = 0.25
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
    share : float
        The share of the equation-error residual the delay removes.
    found : bool
        ``dbic`` is below ``-MIN_DBIC`` and ``share`` at least :data:`MIN_SHARE`.
    reach : float
        The largest delay scanned, s.
    best : float
        The scanned optimum, s, called found or not (``dbic`` and ``share`` are its):
        the start of the delay when the families are compared again with it
        (:func:`hystdisc.closing.again.compare_again`).
    """

    tau: float
    dbic: float
    share: float
    found: bool
    reach: float
    best: float = 0.0

    def to_dict(self) -> dict:
        """The ``results.json`` form."""
        return {
            "tau": self.tau, "dbic": self.dbic, "share": self.share, "found": self.found,
            "reach": self.reach, "best": self.best,
        }  # fmt: skip


def _delayed(eq: EqData, tau: float) -> EqData:
    """``eq`` with its motion ``tau`` s earlier (linear between samples): the regressors of
    an output recorded ``tau`` behind the motion."""
    if tau == 0.0:
        return eq
    shift = lambda xs: [np.interp(t - tau, t, x) for t, x in zip(eq.t, xs, strict=True)]  # noqa: E731
    return dataclasses.replace(eq, theta=shift(eq.theta), theta_dot=shift(eq.theta_dot))


def _rss(eq: EqData, terms: Sequence[str], s: np.ndarray, shape: str, tau: float) -> float:
    """Equation-error RSS of the structure against the motion ``tau`` earlier."""
    shifted = _delayed(eq, tau)
    F, y = Design(shifted, terms).build_flat(shifted.z_flat(SHAPES[shape], s))
    return scaled_lstsq(F, y)[1]


def scan_delay(eq: EqData, terms: Sequence[str], s: np.ndarray, shape: str) -> DelayScan:
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

    Returns
    -------
    DelayScan
    """
    cycle = min(
        (float(t[-1] - t[0]) for t in eq.t), default=1.0
    )  # no shorter than a run, at most its shortest cycle below
    for t, w in zip(eq.t, eq.theta_dot, strict=True):
        crossings = np.count_nonzero(np.diff(np.signbit(w - np.median(w))))
        if crossings >= 2:
            cycle = min(cycle, 2.0 * float(t[-1] - t[0]) / crossings)
    reach = min(MAX_DELAY, MAX_CYCLE_FRACTION * cycle)
    taus = np.linspace(-reach, reach, 2 * GRID + 1)
    rss = np.array([_rss(eq, terms, s, shape, float(tau)) for tau in taus])
    k = int(np.argmin(rss))
    tau = float(taus[k])
    if 0 < k < taus.size - 1:  # the parabola through the best and its neighbours
        a, b, c = rss[k - 1], rss[k], rss[k + 1]
        den = a - 2 * b + c
        if den > 0:
            tau += 0.5 * (a - c) / den * (taus[1] - taus[0])
    best = min(_rss(eq, terms, s, shape, tau), float(rss[k]))
    base = rss[GRID]  # tau = 0
    n = eq.n_eff(int(sum(m.sum() for m in eq.rows)))
    dbic = bic_change(best, base, n, 1)
    share = float(1.0 - best / base) if base > 0 else 0.0
    found = bool(dbic < -MIN_DBIC and share >= MIN_SHARE)
    tau = float(tau)
    return DelayScan(tau if found else 0.0, float(dbic), share, found, float(reach), tau)
