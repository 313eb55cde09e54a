"""Small statistics shared by every stage: the BIC, sampling rates, masked residuals.

One formula each, so stage 1, stage 2, the closing loop and the report cannot disagree.

Examples
--------
>>> import numpy as np
>>> round(bic(rss=2.0, n=100, k=3), 6)
-377.38679
>>> float(samples_per_cycle(np.cos(np.linspace(0, 4 * np.pi, 400, endpoint=False))))
200.0
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: Smallest residual sum of squares the logarithms see (an exact fit is not -inf).
RSS_FLOOR = 1e-300


def bic(rss: float, n: int, k: int, n_eff: float | None = None, floor: float = 0.0) -> float:
    """Bayesian information criterion of a Gaussian least-squares fit.

    ``n_eff * log(rss / n) + k * log(n_eff)``, with ``rss`` floored at ``floor``.

    Parameters
    ----------
    rss : float
        Residual sum of squares over ``n`` samples.
    n : int
        Number of residuals.
    k : int
        Number of free parameters.
    n_eff : float, optional
        Effective number of independent samples (default ``n``): stage 1 counts the
        samples of a smoothed, decimated signal as fewer.
    floor : float
        Smallest ``rss`` taken as it is (a fit below it is exact).
    """
    ne = n if n_eff is None else n_eff
    return float(ne * np.log(max(rss, floor, RSS_FLOOR) / n) + k * np.log(ne))


def bic_change(rss_after: float, rss_before: float, n: float, dk: int) -> float:
    """Change of the BIC when ``dk`` parameters take the RSS from ``rss_before`` to
    ``rss_after`` (negative: the added parameters pay for themselves)."""
    return float(
        n * np.log(max(rss_after, RSS_FLOOR) / max(rss_before, RSS_FLOOR)) + dk * np.log(n)
    )


def samples_per_cycle(w: np.ndarray) -> float:
    """Samples per cycle of a signal oscillating about zero (from its zero crossings)."""
    sgn = np.signbit(np.asarray(w))
    crossings = np.count_nonzero(sgn[1:] != sgn[:-1])
    return 2.0 * sgn.size / max(crossings, 1)


def sampling_rate(times: Sequence[np.ndarray]) -> float:
    """Median sampling rate of several runs (1.0 when no run has two samples)."""
    dts = [np.median(np.diff(t)) for t in times if len(t) > 1]
    return float(1.0 / np.median(dts)) if dts else 1.0


def masked(values: Sequence[np.ndarray], masks: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Each run's values at the samples its mask keeps (the residual the fit uses)."""
    return [np.asarray(v)[m] for v, m in zip(values, masks, strict=True)]
