"""Derivatives of measured angles for the equation-error stage, chosen on the data.

pysindy's :class:`~pysindy.differentiation.SmoothedFiniteDifference` (Savitzky-Golay
smoothing, then centred differences) does the work; the window is chosen on the data by the
discrepancy principle: the widest window whose smoothing residual is still at the level of
the estimated measurement noise (wider windows would start to remove signal).

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
from scipy.signal import savgol_filter

POLYORDER = 3


@dataclass
class Derivatives:
    """Smoothed angle and its first two derivatives for one run."""

    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    window: int


def choose_window(theta: np.ndarray, noise_std: float, max_window: int = 151) -> int:
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


def differentiate(
    t: np.ndarray, theta: np.ndarray, noise_std: float, window: int | None = None
) -> Derivatives:
    """Smoothed ``theta``, ``theta_dot`` and ``theta_ddot`` with a data-chosen window."""
    theta = np.asarray(theta, dtype=float)
    t = np.asarray(t, dtype=float)
    w = choose_window(theta, noise_std) if window is None else int(window)
    d1 = _sfd(w)
    theta_dot = np.asarray(d1(theta.reshape(-1, 1), t)).ravel()
    smooth = np.asarray(d1.smoothed_x_).ravel()
    d2 = _sfd(w)
    theta_ddot = np.asarray(d2(theta_dot.reshape(-1, 1), t)).ravel()
    return Derivatives(smooth, np.asarray(d2.smoothed_x_).ravel(), theta_ddot, w)


def velocity(t: np.ndarray, theta: np.ndarray, noise_std: float) -> np.ndarray:
    """Smoothed first derivative only (driven experiments)."""
    return differentiate(t, theta, noise_std).theta_dot
