"""Residual diagnostics: whiteness (Ljung-Box, or against the noise's own spectrum) and the
dominant frequency of what remains.

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
#: Longest segment of :func:`noise_whiteness` (its frequency resolution is fs / this).
MAX_NPERSEG = 256
#: Dynamic range of the noise spectrum that :func:`noise_whiteness` trusts (power ratio).
DYNAMIC_RANGE = 1e-7
#: ``whiteness_test`` of a residual judged against white noise (Ljung-Box, pooled).
WHITE_TEST = "ljung-box"
#: ``whiteness_test`` of a residual judged against the noise's own spectrum.
NOISE_TEST = "noise spectrum"


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


def _segment_power(records: list[np.ndarray], nper: int) -> tuple[np.ndarray, int]:
    """Mean Hann-windowed periodogram of the non-overlapping ``nper``-sample segments of
    every record (each segment's mean removed), and the number of segments."""
    win = signal.windows.hann(nper, sym=False)
    acc = np.zeros(nper // 2 + 1)
    count = 0
    for x in records:
        k = x.size // nper
        if k == 0:
            continue
        seg = x[: k * nper].reshape(k, nper)
        seg = (seg - seg.mean(axis=1, keepdims=True)) * win
        acc += np.sum(np.abs(np.fft.rfft(seg, axis=1)) ** 2, axis=0)
        count += k
    return (acc / count if count else acc), count


def noise_whiteness(
    residuals: list[np.ndarray],
    noise_samples: list[np.ndarray],
    fs: float,
    max_nperseg: int = MAX_NPERSEG,
) -> tuple[float, float | None, float | None]:
    """Test that the residual has the noise's own spectrum (coloured noise is no structure).

    Both the residual and a sample of the noise (period-to-period differences over
    ``sqrt(2)``, :func:`hystdisc.data.period_noise`) are cut into non-overlapping
    Hann-windowed segments of one length, and their mean periodograms are compared bin by
    bin: under the hypothesis that the residual is that noise, the ratio of the two in a
    bin follows an F distribution with ``2 K_res`` and ``2 K_noise`` degrees of freedom
    (``K`` segments each). The p-value is the smallest bin's, times the number of bins
    (Bonferroni); it is small when the residual has power the noise lacks at some
    frequency, whatever the noise's own spectrum (band-limited, coloured). Where the
    noise's power is more than 70 dB below its peak (:data:`DYNAMIC_RANGE`), the window's
    leakage dominates and the noise's power is taken at that floor.

    Parameters
    ----------
    residuals : list of ndarray
        One residual record per run.
    noise_samples : list of ndarray
        Samples of the noise on the same channel, at the same sampling rate.
    fs : float
        Sampling rate in Hz.
    max_nperseg : int
        Longest segment (frequency resolution ``fs / nperseg``); shorter when the records
        hold fewer than 8 segments of it.

    Returns
    -------
    p : float
        The p-value (1.0 when the records are too short to tell).
    f_excess : float or None
        Frequency (Hz) of the largest excess of the residual's power over the noise's.
    ratio : float or None
        The residual's power over the noise's at that frequency.

    Examples
    --------
    >>> rng = np.random.default_rng(2)
    >>> b, a = signal.butter(4, 0.3)  # noise band-limited to 30 % of the Nyquist frequency
    >>> coloured = lambda n: signal.lfilter(b, a, rng.normal(size=n))
    >>> res, sample = [coloured(8000)], [coloured(8000)]
    >>> ljung_box_pooled(res) < 1e-10  # "not white" by Ljung-Box
    True
    >>> noise_whiteness(res, sample, 1000.0)[0] > 0.01  # but it is the noise
    True
    >>> t = np.arange(8000) / 1000.0
    >>> p, f, r = noise_whiteness([res[0] + 0.5 * np.sin(2 * np.pi * 104 * t)], sample, 1000.0)
    >>> p < 1e-6, round(f)
    (True, 104)
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) >= 16]
    noi = [np.asarray(r, dtype=float) for r in noise_samples if len(r) >= 16]
    if not res or not noi:
        return 1.0, None, None
    n_res, n_noi = sum(x.size for x in res), sum(x.size for x in noi)
    longest = min(max(x.size for x in res), max(x.size for x in noi))
    cap = min(max_nperseg, longest, n_res // 8, n_noi // 8)
    if cap < 16:
        return 1.0, None, None
    nper = 2 ** int(np.log2(cap))
    p_res, k_res = _segment_power(res, nper)
    p_noi, k_noi = _segment_power(noi, nper)
    inner = slice(1, nper // 2)  # no DC (mean removed) and no Nyquist bin
    pr, pn = p_res[inner], p_noi[inner]
    if pr.size == 0 or not np.any(pn > 0):
        return 1.0, None, None
    # beyond DYNAMIC_RANGE below the noise's peak the window's leakage dominates both
    # estimates and their ratio is no longer F-distributed: the noise is floored there
    ratio = pr / np.maximum(pn, DYNAMIC_RANGE * float(np.max(pn)))
    p_bins = stats.f.sf(ratio, 2 * k_res, 2 * k_noi)
    p = float(min(1.0, pr.size * float(np.min(p_bins))))
    j = int(np.argmax(ratio))
    f = np.fft.rfftfreq(nper, 1.0 / fs)[inner]
    fj = float(f[j])
    if 1 <= j < ratio.size - 1 and np.all(ratio[j - 1 : j + 2] > 0):
        a, b, c = np.log(ratio[j - 1 : j + 2])  # parabolic interpolation on log power
        den = a - 2 * b + c
        fj += float(np.clip(0.5 * (a - c) / den if den != 0 else 0.0, -0.5, 0.5)) * fs / nper
    return p, fj, float(ratio[j])


def residual_summary(
    residuals: list[np.ndarray],
    fs: float,
    noise_std: float,
    noise_samples: list[np.ndarray] | None = None,
) -> dict:
    """``rms``, ``whiteness_p`` and ``dominant_hz`` (None when the residual is white).

    Parameters
    ----------
    residuals : list of ndarray
        One output-error residual record per run.
    fs : float
        Sampling rate in Hz.
    noise_std : float
        Estimated measurement noise (data units).
    noise_samples : list of ndarray, optional
        A sample of the noise (period-to-period differences): whiteness is then judged
        against its spectrum (:func:`noise_whiteness`) instead of white noise
        (Ljung-Box pooled over runs).

    Returns
    -------
    dict
        ``{"rms", "whiteness_p", "dominant_hz", "rms_over_noise", "whiteness_test",
        "ljung_box_p"}``.
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) > 10]
    allr = np.concatenate(res) if res else np.zeros(1)
    rms = float(np.sqrt(np.mean(allr**2)))
    lb = ljung_box_pooled(res)
    p, test, dom = lb, WHITE_TEST, None
    if noise_samples:
        p, f_excess, _ = noise_whiteness(res, noise_samples, fs)
        test = NOISE_TEST
        dom = f_excess if p < WHITE_P else None
    elif p < WHITE_P and res:
        f, psd, resolution = residual_spectrum(res, fs)
        fk = spectral_peak(f, psd, f_min=resolution)[0]
        dom = fk if np.isfinite(fk) else None
    return {
        "rms": rms,
        "whiteness_p": p,
        "dominant_hz": dom,
        "rms_over_noise": rms / noise_std if noise_std > 0 else None,
        "whiteness_test": test,
        "ljung_box_p": lb,
    }
