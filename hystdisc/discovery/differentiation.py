"""Derivatives of measured angles for the equation-error stage, chosen on the data.

pysindy's :class:`~pysindy.differentiation.SmoothedFiniteDifference` (Savitzky-Golay
smoothing, then centred differences) does the work; the window is chosen on the data by the
discrepancy principle: the widest window whose smoothing residual is still at the level of
the estimated measurement noise (wider windows would start to remove signal).

The window is capped at :data:`MAX_WINDOW_S` seconds (151 samples at 1 kHz; never fewer
than :data:`MAX_WINDOW` samples). A record sampled faster than that cap needs is first
averaged over blocks of ``p`` samples (an anti-alias filter whose noise is ``sqrt(p)``
smaller), the window is chosen and the derivatives are taken at that rate, and they are
interpolated back to the samples by cubic splines: the cost stays linear in the samples and
the smoothing refers to a duration, not to a sample count.

Examples
--------
>>> import numpy as np
>>> t = np.arange(0, 2, 1e-3)
>>> theta = 0.3 * np.cos(2 * np.pi * t) + np.random.default_rng(0).normal(0, 1e-3, t.size)
>>> d = differentiate(t, theta, noise_std=1e-3)
>>> bool(abs(d.theta_dot[1000] - 0.0) < 0.05), d.window > 5
(True, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pysindy.differentiation import SmoothedFiniteDifference
from scipy.interpolate import CubicSpline
from scipy.signal import savgol_filter

POLYORDER = 3
#: Window cap in samples at (and below) 1 kHz.
MAX_WINDOW = 151
#: Window cap as a duration (seconds): faster records are block-averaged down to it.
MAX_WINDOW_S = 0.151
#: Fewest block averages a run keeps (shorter runs are differentiated as sampled).
MIN_BLOCKS = 64


@dataclass
class Derivatives:
    """Smoothed angle and its first two derivatives for one run."""

    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    window: int


def choose_window(theta: np.ndarray, noise_std: float, max_window: int = MAX_WINDOW) -> int:
    """Widest odd Savitzky-Golay window whose residual RMS stays within 1.2x the noise."""
    n = len(theta)
    wmin = 2 * POLYORDER + 3
    best = wmin
    hi = min(max_window, n - 1 if n % 2 == 0 else n - 2)
    if noise_std <= 0 or hi < wmin:
        return max(min(best, hi), POLYORDER + 2 | 1)
    for w in range(wmin, hi + 1, 4):
        res = theta - savgol_filter(theta, w, POLYORDER)
        if np.sqrt(np.mean(res[w:-w] ** 2 if n > 3 * w else res**2)) > 1.2 * noise_std:
            break
        best = w
    return best


def _sfd(window: int) -> SmoothedFiniteDifference:
    # fresh dict each time: pysindy shares a mutable default for smoother_kws
    return SmoothedFiniteDifference(
        smoother_kws={"window_length": window, "polyorder": POLYORDER}, save_smooth=True
    )


def block_factor(t: np.ndarray) -> int:
    """Samples averaged per block before differentiating: 1 up to 1 kHz, ``ceil(fs / 1 kHz)``
    above (so the window cap :data:`MAX_WINDOW_S` spans at most :data:`MAX_WINDOW` blocks).

    Examples
    --------
    >>> block_factor(np.arange(0, 1, 1e-3)), block_factor(np.arange(0, 1, 1e-4))
    (1, 10)
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        return 1
    fs = 1.0 / float(np.median(np.diff(t)))
    p = int(np.ceil(MAX_WINDOW_S * fs / MAX_WINDOW - 1e-9))
    if p <= 1 or t.size // p < MIN_BLOCKS:
        return 1
    return p


def _derivatives(t, theta, noise_std, window):
    w = choose_window(theta, noise_std) if window is None else int(window)
    d1 = _sfd(w)
    theta_dot = np.asarray(d1(theta.reshape(-1, 1), t)).ravel()
    smooth = np.asarray(d1.smoothed_x_).ravel()
    d2 = _sfd(w)
    theta_ddot = np.asarray(d2(theta_dot.reshape(-1, 1), t)).ravel()
    return smooth, np.asarray(d2.smoothed_x_).ravel(), theta_ddot, w


def differentiate(
    t: np.ndarray, theta: np.ndarray, noise_std: float, window: int | None = None
) -> Derivatives:
    """Smoothed ``theta``, ``theta_dot`` and ``theta_ddot`` with a data-chosen window.

    Records sampled above 1 kHz are block-averaged first (see the module docstring); the
    returned ``window`` is then the span in samples of the record as given. An explicit
    ``window`` is used at the record's own rate.
    """
    theta = np.asarray(theta, dtype=float)
    t = np.asarray(t, dtype=float)
    p = block_factor(t) if window is None else 1
    if p == 1:
        return Derivatives(*_derivatives(t, theta, noise_std, window))
    nb = theta.size // p
    tb = t[: nb * p].reshape(nb, p).mean(axis=1)
    xb = theta[: nb * p].reshape(nb, p).mean(axis=1)
    smooth, w1, w2, w = _derivatives(tb, xb, noise_std / np.sqrt(p), None)
    back = [CubicSpline(tb, v)(t) for v in (smooth, w1, w2)]
    return Derivatives(*back, w * p)


def velocity(t: np.ndarray, theta: np.ndarray, noise_std: float) -> np.ndarray:
    """Smoothed first derivative only (driven experiments)."""
    return differentiate(t, theta, noise_std).theta_dot
