"""The verdict on the final residual: whiteness, spectrum and the simulator's floor.

:func:`assess_residual` tests the residual by a Ljung-Box test pooled over runs and
averages its spectrum over runs; when a sample of the noise is known (period-to-period
differences of a periodic excitation), the residual is judged against the noise's own
spectrum instead (:func:`~hystdisc.closing.diagnostics.noise_whiteness`), so that
band-limited or coloured noise is not taken for structure. When it is not white and its
RMS is clearly above the noise (:data:`NOISE_RATIO`), it is *unexplained*, with the
dominant frequency and a sentence such as "a resonance near 6.0 Hz that no catalogued
effect explains". A residual at the noise level (RMS at most :data:`NOISE_RATIO` times
the noise) is never unexplained, white or not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hystdisc.closing.diagnostics import (
    NOISE_TEST,
    WHITE_P,
    WHITE_TEST,
    ljung_box_pooled,
    noise_whiteness,
    residual_spectrum,
    spectral_peak,
)
from hystdisc.fitting import OEFit
from hystdisc.measurement import FitData
from hystdisc.registry import get_experiment

#: A final residual whose RMS exceeds the noise estimate by this factor is "clearly above".
NOISE_RATIO = 1.1
#: Relative accuracy floor of the fitting simulator (see :func:`accuracy_floor`).
SIM_FLOOR_REL = 1e-5


@dataclass
class ResidualVerdict:
    """The verdict on a residual's structure (:func:`assess_residual`).

    Attributes
    ----------
    rms : float
        Its RMS over the fitted samples, data units.
    whiteness_p : float
        p-value of the whiteness test named by :attr:`whiteness_test` (white when at
        least :data:`~hystdisc.closing.diagnostics.WHITE_P`).
    dominant_hz : float or None
        Dominant frequency of a structured residual (None when white; with a noise
        sample, the frequency of the largest excess over the noise's spectrum).
    rms_over_noise : float or None
        RMS over the noise (None when the noise is 0).
    peak_q : float or None
        Quality factor of the spectral peak at :attr:`dominant_hz`.
    whiteness_test : str
        ``ljung-box`` (pooled over runs) or ``noise spectrum`` (against the spectrum of
        a sample of the noise).
    ljung_box_p : float
        The Ljung-Box p-value, whichever test decided.
    noise_used : float or None
        The noise level the closing loop judged with (set by the loop; None otherwise).
    """

    rms: float
    whiteness_p: float
    dominant_hz: float | None
    rms_over_noise: float | None
    peak_q: float | None
    whiteness_test: str
    ljung_box_p: float
    noise_used: float | None = None


def natural_frequency(fit: OEFit, experiment: str) -> float | None:
    """Undamped rig frequency ``sqrt(k_s / J) / 2 pi`` in Hz.

    Parameters
    ----------
    fit : OEFit
        A fit whose parameters hold ``k_s`` (and ``J`` for forced experiments).
    experiment : str
        ``release``, ``forced`` or ``driven`` (no rig oscillation: None).

    Returns
    -------
    float or None
        The frequency, or None without a spring.
    """
    if get_experiment(experiment).motion_imposed:
        return None
    ks = fit.params.get("k_s", 0.0)
    J = fit.params.get("J", 1.0) or 1.0
    if not (np.isfinite(ks) and ks > 0 and J > 0):
        return None
    return float(np.sqrt(ks / J) / (2 * np.pi))


def assess_residual(
    residuals: list[np.ndarray],
    fs: float,
    noise_std: float,
    natural_hz: float | None = None,
    noise_samples: list[np.ndarray] | None = None,
) -> tuple[ResidualVerdict, bool, str | None]:
    """Whiteness and spectrum of the final residual.

    Parameters
    ----------
    residuals : list of ndarray
        Output-error residual of each run.
    fs : float
        Sampling rate in Hz.
    noise_std : float
        Estimated measurement noise.
    natural_hz : float, optional
        The rig's own frequency, to name a misfit of the main oscillation as such.
    noise_samples : list of ndarray, optional
        A sample of the noise on the same channel (period-to-period differences over
        ``sqrt(2)``): the whiteness is judged against its spectrum.

    Returns
    -------
    residual : ResidualVerdict
        Its RMS, whiteness and dominant frequency.
    unexplained : bool
        Not white and RMS above ``NOISE_RATIO`` times the noise.
    text : str or None
        The remaining structure in plain words.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(3000) / 1000.0
    >>> white = [1e-3 * rng.normal(size=t.size) for _ in range(3)]
    >>> assess_residual(white, 1000.0, 1e-3)[1]
    False
    >>> ring = [w + 3e-3 * np.exp(-0.5 * t) * np.sin(2 * np.pi * 6 * t) for w in white]
    >>> res, unexplained, text = assess_residual(ring, 1000.0, 1e-3)
    >>> unexplained, round(res.dominant_hz, 1)
    (True, 6.0)
    >>> text
    'a resonance near 6.0 Hz that no catalogued effect explains (residual RMS 1.6x the noise)'
    """
    res = [np.asarray(r, dtype=float) for r in residuals if len(r) > 10]
    allr = np.concatenate(res) if res else np.zeros(1)
    rms = float(np.sqrt(np.mean(allr**2)))
    lb = ljung_box_pooled(res)
    p, test, f_excess = lb, WHITE_TEST, None
    if noise_samples:
        p, f_excess, _ = noise_whiteness(res, noise_samples, fs)
        test = NOISE_TEST
    ratio = rms / noise_std if noise_std > 0 else float("inf")
    out = ResidualVerdict(
        rms=rms,
        whiteness_p=p,
        dominant_hz=None,
        rms_over_noise=ratio if np.isfinite(ratio) else None,
        peak_q=None,
        whiteness_test=test,
        ljung_box_p=lb,
    )
    structured = p < WHITE_P
    if structured and f_excess is not None:  # where the residual exceeds the noise
        out.dominant_hz = f_excess
    elif structured and res:
        f, psd, resolution = residual_spectrum(res, fs)
        fk, q = spectral_peak(f, psd, f_min=resolution)
        if np.isfinite(fk):
            out.dominant_hz = fk
            out.peak_q = q if np.isfinite(q) else None
    unexplained = bool(structured and ratio > NOISE_RATIO)
    if not unexplained:
        return out, False, None
    fk = out.dominant_hz
    tail = f"that no catalogued effect explains (residual RMS {ratio:.1f}x the noise)"
    if fk is None:
        text = f"structure {tail}"
    elif natural_hz and abs(fk - natural_hz) <= 0.15 * natural_hz:
        text = (
            f"a misfit of the rig's own oscillation near {fk:.1f} Hz {tail}: the damper law "
            "itself may be wrong (try another family, or discover without --model)"
        )
    elif test == NOISE_TEST:
        text = f"power above the noise's own spectrum, most near {fk:.1f} Hz, {tail}"
    elif (out.peak_q or 0.0) >= 2.0:
        text = f"a resonance near {fk:.1f} Hz {tail}"
    else:
        text = f"broadband structure (most power near {fk:.1f} Hz) {tail}"
    return out, True, text


def accuracy_floor(data: FitData) -> float:
    """The smallest residual RMS the fit can resolve: ``SIM_FLOOR_REL`` of the signal's peak.

    The fitting simulator is accurate to about 1e-6 of the signal; below this floor a
    residual is numerical (noise-free synthetic data) and is treated as noise of that size.

    Parameters
    ----------
    data : FitData
        The fitted data.

    Returns
    -------
    float
        The floor, in data units.
    """
    peak = max(
        (float(np.max(np.abs(y[m]))) for y, m in zip(data.y, data.mask, strict=True) if m.any()),
        default=0.0,
    )
    return SIM_FLOOR_REL * peak
