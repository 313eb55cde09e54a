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

#: Ljung-Box p-value below which a residual counts as not white.
WHITE_P = 0.01


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


def ljung_box_pooled(residuals: list[np.ndarray], lags: int = 20) -> float:
    """p-value of the Ljung-Box test pooled over runs (small p: structure remains).

    The Q statistics of the runs are summed and compared with a chi-square of the summed
    degrees of freedom, which uses every run rather than only the worst one.

    Parameters
    ----------
    residuals : list of ndarray
        One residual record per run (records shorter than 10 samples are ignored).
    lags : int
        Autocorrelation lags per run (fewer for a short run: at most a fifth of it).

    Returns
    -------
    float
        The pooled p-value (1.0 when no run is long enough).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> bool(ljung_box_pooled([rng.normal(size=2000) for _ in range(3)]) > 0.01)
    True
    >>> t = np.arange(2000) / 1000.0
    >>> bool(ljung_box_pooled([np.sin(2 * np.pi * 6 * t) + rng.normal(size=2000)]) < 1e-6)
    True
    """
    q_tot = 0.0
    df = 0
    for x in residuals:
        x = np.asarray(x, dtype=float)
        n = x.size
        if n <= 10:
            continue
        m = int(min(lags, max(n // 5, 1)))
        r = autocorrelation(x, m)
        q_tot += float(n * (n + 2) * np.sum(r**2 / (n - np.arange(1, m + 1))))
        df += m
    if df == 0:
        return 1.0
    return float(stats.chi2.sf(q_tot, df))


def residual_spectrum(
    residuals: list[np.ndarray], fs: float, nfft: int = 8192
) -> tuple[np.ndarray, np.ndarray, float]:
    """Welch power spectral density averaged over runs (weighted by their length).

    Every run gets its own segment length (the largest power of two up to half the run,
    at least 64 samples) and all share one zero-padded FFT length, so runs of different
    lengths average on one frequency grid and a peak is located to a fraction of the
    Welch resolution.

    Parameters
    ----------
    residuals : list of ndarray
        One residual record per run.
    fs : float
        Sampling rate in Hz.
    nfft : int
        FFT length (zero padding); raised to the longest segment when smaller.

    Returns
    -------
    f : ndarray
        Frequencies in Hz.
    p : ndarray
        Averaged power spectral density (data units squared per Hz).
    resolution : float
        Welch resolution ``fs / nperseg`` of the longest segment (Hz): features closer to
        0 Hz than this are not resolved from a drift.
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) >= 16]
    if not res:
        return np.zeros(0), np.zeros(0), float("nan")
    npers = [
        int(max(16, min(x.size, max(64, 2 ** int(np.log2(max(x.size // 2, 2))))))) for x in res
    ]
    nfft = int(max(nfft, 2 ** int(np.ceil(np.log2(max(npers))))))
    acc = None
    wsum = 0.0
    for x, nper in zip(res, npers, strict=True):
        f, p = signal.welch(x - x.mean(), fs=fs, nperseg=nper, nfft=nfft)
        acc = p * x.size if acc is None else acc + p * x.size
        wsum += x.size
    return f, acc / wsum, float(fs / max(npers))


def spectral_peak(f: np.ndarray, p: np.ndarray, f_min: float = 0.0) -> tuple[float, float]:
    """Frequency of the largest spectral peak above ``f_min`` and its quality factor.

    Parameters
    ----------
    f, p : ndarray
        Frequencies and power spectral density (e.g. from :func:`residual_spectrum`).
    f_min : float
        Peaks below this frequency (a drift, the DC leakage) are ignored.

    Returns
    -------
    f_peak : float
        Peak frequency in Hz (parabolic interpolation on log power); NaN without a peak.
    q : float
        ``f_peak`` divided by the half-power width of the peak (large: a resonance).
    """
    sel = np.flatnonzero(f > max(f_min, 0.0))
    if sel.size < 3 or not np.any(p[sel] > 0):
        return float("nan"), 0.0
    k = int(sel[np.argmax(p[sel])])
    fk = float(f[k])
    if 1 <= k < f.size - 1 and np.all(p[k - 1 : k + 2] > 0):
        a, b, c = np.log(p[k - 1 : k + 2])
        den = a - 2 * b + c
        off = 0.5 * (a - c) / den if den != 0 else 0.0
        fk = float(f[k] + np.clip(off, -0.5, 0.5) * (f[1] - f[0]))
    half = p[k] / 2.0
    lo = k
    while lo > 0 and p[lo] > half:
        lo -= 1
    hi = k
    while hi < f.size - 1 and p[hi] > half:
        hi += 1
    width = float(f[hi] - f[lo])
    q = fk / width if width > 0 else float("inf")
    return fk, float(q)


def dominant_frequency(x: np.ndarray, fs: float) -> float:
    """Frequency (Hz) of the largest peak of the Welch spectrum of ``x`` (DC excluded)."""
    f, p, res = residual_spectrum([np.asarray(x, dtype=float)], fs)
    if f.size < 3:
        return float("nan")
    return spectral_peak(f, p, f_min=res)[0]


def residual_summary(residuals: list[np.ndarray], fs: float, noise_std: float) -> dict:
    """``rms``, ``whiteness_p`` (Ljung-Box pooled over runs) and ``dominant_hz`` (None when
    the residual is white).

    Parameters
    ----------
    residuals : list of ndarray
        One output-error residual record per run.
    fs : float
        Sampling rate in Hz.
    noise_std : float
        Estimated measurement noise (data units).

    Returns
    -------
    dict
        ``{"rms", "whiteness_p", "dominant_hz", "rms_over_noise"}``.
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) > 10]
    allr = np.concatenate(res) if res else np.zeros(1)
    rms = float(np.sqrt(np.mean(allr**2)))
    p = ljung_box_pooled(res)
    dom = None
    if p < WHITE_P and res:
        f, psd, resolution = residual_spectrum(res, fs)
        fk = spectral_peak(f, psd, f_min=resolution)[0]
        dom = fk if np.isfinite(fk) else None
    return {
        "rms": rms,
        "whiteness_p": p,
        "dominant_hz": dom,
        "rms_over_noise": rms / noise_std if noise_std > 0 else None,
    }
