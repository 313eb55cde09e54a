"""Preprocessing of measured runs: the noise level of a signal, and trimming a release.

Examples
--------
>>> import numpy as np
>>> from hystdisc.data import estimate_noise
>>> estimate_noise(np.linspace(0.0, 1.0, 100) ** 2)  # a noiseless polynomial
0.0
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from hystdisc.data.dataset import Run
from hystdisc.errors import input_error

__all__ = ["estimate_noise", "screened_rms", "trim_release"]


def screened_rms(d: np.ndarray) -> float:
    """RMS of ``d`` after iterative 5-sigma clipping (drops spikes, keeps the noise).

    Unlike a MAD scale, this stays exact for uniform (quantization) noise and does not
    collapse when most differences of a quantized signal are exactly zero.

    Examples
    --------
    >>> d = np.ones(1000)
    >>> d[::100] = 1e3  # ten spikes
    >>> screened_rms(d)
    1.0
    """
    keep = np.ones(d.size, dtype=bool)
    s = float(np.sqrt(np.mean(d * d)))
    for _ in range(20):
        new = np.abs(d) <= 5.0 * s
        if not new.any() or np.array_equal(new, keep):
            break
        keep = new
        s = float(np.sqrt(np.mean(d[keep] ** 2)))
    return s


def estimate_noise(theta: np.ndarray, fs: float | None = None) -> float:
    """Standard deviation of the white measurement noise on a smooth signal.

    Differences of order k = 2..6 of the signal cancel a locally polynomial signal (they
    are the residuals of a local polynomial fit of degree k-1); divided by
    ``sqrt(binom(2k, k))`` they have the noise standard deviation for white noise. The scale
    of each is a 5-sigma-clipped RMS (spikes dropped), which is exact for Gaussian and for
    uniform (quantization) noise alike, where a MAD scale is 28 % high for uniform noise and
    collapses to zero when most differences of a quantized signal are exactly zero. The
    smallest of the five is returned, since what is left of the signal only adds to it.

    Parameters
    ----------
    theta : array_like
        Sampled signal (at least 26 samples), uniformly sampled.
    fs : float, optional
        Sampling rate in Hz; not needed by the estimator and accepted for symmetry with the
        rest of the API.

    Returns
    -------
    float
        Noise standard deviation in the units of ``theta``; 0.0 for a noiseless polynomial.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(6000) / 1000.0
    >>> theta = 0.2 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t) + rng.normal(0, 1e-3, t.size)
    >>> round(estimate_noise(theta, 1000.0) / 1e-3, 1)
    1.0
    """
    x = np.asarray(theta, dtype=np.float64).reshape(-1)
    if x.size < 26:
        raise input_error(
            None,
            f"only {x.size} samples, too few to estimate the noise level",
            "pass at least 26 samples",
        )
    if not np.all(np.isfinite(x)):
        raise input_error(
            None,
            "the signal holds NaN or inf",
            "remove or fill the bad samples before estimating the noise",
        )
    estimates = []
    for k in range(2, 7):
        d = np.diff(x, k) / math.sqrt(math.comb(2 * k, k))
        estimates.append(screened_rms(d))
    return float(min(estimates))


def trim_release(
    run: Run,
    noise_std: float,
    threshold: float = 3.0,
    min_samples: int = 200,
    window: int | None = None,
) -> Run:
    """Cut the tail of a release record where the motion has died into the noise.

    The envelope of ``theta - final`` (``final`` = mean of the last tenth of the record) is
    taken as ``sqrt(2)`` times its moving RMS over ``window`` samples (the amplitude of an
    oscillation, about 1.4 noise std for pure noise). The record is cut after the last
    sample whose envelope reaches ``threshold * noise_std`` (plus half a window), keeping at
    least ``min_samples`` samples.

    Parameters
    ----------
    run : Run
        A release run.
    noise_std : float
        Measurement noise standard deviation (see :func:`estimate_noise`); 0 keeps all.
    threshold : float
        Envelope level, in noise standard deviations, below which the motion counts as dead.
    min_samples : int
        Samples kept at least.
    window : int, optional
        Moving-RMS window in samples; default ``max(25, n // 200)``.

    Returns
    -------
    Run
        A new run (the input is not modified); all signals are cut alike.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> t = np.arange(10000) / 1000.0
    >>> theta = np.exp(-2.0 * t) * np.cos(2 * np.pi * 2 * t) + rng.normal(0, 1e-3, t.size)
    >>> short = trim_release(Run("0", t, theta, 0.0), 1e-3)
    >>> 2.5 < short.duration < 4.0
    True
    """
    if not (math.isfinite(noise_std) and noise_std >= 0):
        raise input_error(
            run.source,
            f"noise level {noise_std!r} is invalid",
            "pass a noise std >= 0",
            run=run.name,
        )
    n = run.n
    if noise_std == 0 or n <= min_samples:
        return dataclasses.replace(run)
    w = int(window) if window is not None else max(25, n // 200)
    w = max(1, min(w, n))
    tail = max(1, n // 10)
    dev = run.theta - float(np.mean(run.theta[-tail:]))
    power = np.convolve(dev * dev, np.ones(w) / w, mode="same")
    envelope = np.sqrt(2.0 * np.maximum(power, 0.0))
    alive = np.flatnonzero(envelope >= threshold * noise_std)
    cut = int(alive[-1]) + 1 + w // 2 if alive.size else 0
    cut = min(n, max(cut, min_samples))
    if cut >= n:
        return dataclasses.replace(run)
    return _slice_run(run, slice(0, cut))


def _slice_run(run: Run, sl: slice) -> Run:
    """A copy of ``run`` with every signal (and the line numbers) cut to ``sl``."""
    kw: dict[str, Any] = {}
    for key in ("t", "theta", "torque", "input", "theta_dot", "lines"):
        value = getattr(run, key)
        kw[key] = None if value is None else value[sl].copy()
    return dataclasses.replace(run, **kw)
