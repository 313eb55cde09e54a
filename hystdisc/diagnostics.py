"""Residual diagnostics: whiteness (Ljung-Box) and the dominant frequency of what remains.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> white = rng.normal(size=4000)
>>> bool(ljung_box(white) > 0.01)
True
>>> t = np.arange(4000) / 1000.0
>>> round(dominant_frequency(np.sin(2 * np.pi * 6.0 * t) + 0.1 * white, 1000.0), 1)
6.0
"""

from __future__ import annotations

import numpy as np
from scipy import signal, stats


def autocorrelation(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation at lags 1..max_lag."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    d = float(x @ x)
    if d == 0.0:
        return np.zeros(max_lag)
    return np.array([float(x[:-k] @ x[k:]) / d for k in range(1, max_lag + 1)])


def ljung_box(x: np.ndarray, lags: int = 20) -> float:
    """p-value of the Ljung-Box test that ``x`` is white (small p: structure remains)."""
    x = np.asarray(x, dtype=float)
    n = x.size
    lags = int(min(lags, max(n // 5, 1)))
    r = autocorrelation(x, lags)
    q = n * (n + 2) * np.sum(r**2 / (n - np.arange(1, lags + 1)))
    return float(stats.chi2.sf(q, lags))


def dominant_frequency(x: np.ndarray, fs: float) -> float:
    """Frequency (Hz) of the largest peak of the Welch spectrum of ``x`` (DC excluded)."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(256, 2 ** int(np.log2(max(x.size // 2, 2))))))
    f, p = signal.welch(x - x.mean(), fs=fs, nperseg=nper)
    if f.size < 3:
        return float("nan")
    k = 1 + int(np.argmax(p[1:]))
    # parabolic interpolation of the peak on log power
    if 1 <= k < f.size - 1 and np.all(p[k - 1 : k + 2] > 0):
        a, b, c = np.log(p[k - 1 : k + 2])
        den = a - 2 * b + c
        off = 0.5 * (a - c) / den if den != 0 else 0.0
        return float(f[k] + off * (f[1] - f[0]))
    return float(f[k])


def residual_summary(residuals: list[np.ndarray], fs: float, noise_std: float) -> dict:
    """``rms``, ``whiteness_p`` (pooled over runs, decimated to the noise bandwidth) and
    ``dominant_hz`` (None when the residual is white)."""
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) > 10]
    allr = np.concatenate(res) if res else np.zeros(1)
    rms = float(np.sqrt(np.mean(allr**2)))
    ps = [ljung_box(r) for r in res]
    # Fisher-free, conservative pooling: the smallest p times the number of runs
    p = float(min(1.0, min(ps) * len(ps))) if ps else 1.0
    structured = p < 0.01 and rms > 1.1 * noise_std
    dom = None
    if structured:
        longest = max(res, key=len)
        dom = dominant_frequency(longest, fs)
    return {"rms": rms, "whiteness_p": p, "dominant_hz": dom}
