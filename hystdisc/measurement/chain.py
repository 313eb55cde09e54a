"""The measurement chain between the damper and the recorded signals.

What a model predicts is what the damper does; what the data hold went through the
acquisition first. Two parts of that chain are modelled here and applied to every
simulated output (:mod:`hystdisc.fitting.simulate`):

* a **delay between the channels** (the ``channel_delay`` effect, ``TermModel.delay``):
  the recorded output is the model's ``y(t - tau_d)``, shifted by fractional samples
  (:func:`delayed`); a driven test's model is driven by its motion ``tau_d`` earlier
  instead (:func:`seen_motion`, a cubic between samples: :func:`smoothly_delayed`);
* a **filter applied before the data reached hystdisc** (a rig's ``[filter]`` table, see
  :func:`hystdisc.data.read_rig`): a causal moving average of ``N`` samples applied to
  the simulated output as it was to the recorded one (:func:`causal_average`), and, when
  the motion channel was filtered too, the motion the damper saw reconstructed from the
  recorded one (:func:`unfiltered_motion`). :func:`apply_filter` prepares a
  :class:`~hystdisc.fitting.FitData` for both.

Examples
--------
>>> import numpy as np
>>> t = np.arange(6) * 0.1
>>> delayed(t, t**2, 0.05).round(3).tolist()
[0.0, 0.005, 0.025, 0.065, 0.125, 0.205]
>>> causal_average(np.arange(6.0), 3).tolist()
[0.0, 0.3333333333333333, 1.0, 2.0, 3.0, 4.0]
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from hystdisc.data import motion_frequency
from hystdisc.measurement.fitdata import FitData
from hystdisc.models.backlash import play_motion

#: Harmonics of the fundamental used to reconstruct a periodic motion, at most.
MAX_HARMONICS = 15
#: A harmonic is reconstructed only where the filter passes at least this share of it
#: (dividing by a smaller gain only amplifies noise).
MIN_GAIN = 0.2
#: A record counts as periodic when its harmonic fit explains all but this share of it.
PERIODIC_TOL = 1e-3
#: Tikhonov weight of the frequency-domain inverse of a non-periodic record.
INVERSE_REG = 1e-2


def delayed(t: np.ndarray, y: np.ndarray, tau: float) -> np.ndarray:
    """``y`` delayed by ``tau`` seconds on its own time grid: ``y(t - tau)``.

    Linear interpolation between samples (fractional delays); before the first sample
    (after the last) the first (last) value is held.

    Parameters
    ----------
    t : ndarray
        Sample times (increasing).
    y : ndarray
        The signal at ``t``.
    tau : float
        Delay in s (negative: an advance).

    Returns
    -------
    ndarray
        ``y(t - tau)`` at ``t``.
    """
    if tau == 0.0:
        return y
    return np.interp(t - tau, t, y)


def smoothly_delayed(t: np.ndarray, y: np.ndarray, tau: float) -> np.ndarray:
    """A smooth signal ``y`` delayed by ``tau`` seconds: ``y(t - tau)``, interpolated by a
    cubic.

    The cubic through the four samples around each point (Lagrange) on an even time grid,
    a cubic spline on an uneven one; the first (last) value is held outside the record.
    Linear interpolation (:func:`delayed`) shrinks a sine of ``k`` samples per radian by
    up to ``1/(8 k^2)`` between samples: half a sample late, a 5 Hz motion sampled at
    500 Hz loses 5e-4 of its amplitude, several standard errors of a parameter fitted to
    a few thousand samples. The cubic's error is of order ``1/k^4`` (4e-7 there).

    Parameters
    ----------
    t : ndarray
        Sample times (increasing).
    y : ndarray
        The signal at ``t`` (shape ``(..., len(t))``: several signals on the same grid
        are shifted at once).
    tau : float
        Delay in s (negative: an advance).

    Returns
    -------
    ndarray
        ``y(t - tau)`` at ``t``, the shape of ``y``.

    Examples
    --------
    >>> t = np.arange(8.0)
    >>> smoothly_delayed(t, t**3, 0.5)[2:6].tolist()
    [3.375, 15.625, 42.875, 91.125]
    """
    if tau == 0.0:
        return y
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(t)
    if n < 4:
        return np.apply_along_axis(lambda v: delayed(t, v, tau), -1, y)
    dt = (t[-1] - t[0]) / (n - 1)
    if np.max(np.abs(np.diff(t) - dt)) > 1e-6 * dt:
        out = CubicSpline(t, y, axis=-1)(t - tau)
    else:
        s = (t - tau - t[0]) / dt
        i = np.clip(np.floor(s).astype(int), 1, n - 3)
        p = s - i
        out = (
            -p * (p - 1) * (p - 2) / 6 * y[..., i - 1]
            + (p + 1) * (p - 1) * (p - 2) / 2 * y[..., i]
            - (p + 1) * p * (p - 2) / 2 * y[..., i + 1]
            + (p + 1) * p * (p - 1) / 6 * y[..., i + 2]
        )
    out[..., t - tau <= t[0]] = y[..., :1]
    out[..., t - tau >= t[-1]] = y[..., -1:]
    return out


def seen_motion(
    t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray, tau: float, play: float
) -> tuple[np.ndarray, np.ndarray]:
    """A driven test's measured motion and velocity as the damper saw them: ``tau`` s
    earlier (:func:`smoothly_delayed`: the force channel lags the motion's), then
    through a play of half-width ``play`` (:func:`~hystdisc.models.backlash.play_motion`).

    Examples
    --------
    >>> t = np.arange(5.0)
    >>> seen_motion(t, t, np.ones(5), 1.0, 0.0)[0].tolist()
    [0.0, 0.0, 1.0, 2.0, 3.0]
    """
    if tau != 0.0:  # both signals on the same grid: one set of interpolation weights
        theta, theta_dot = smoothly_delayed(t, np.vstack([theta, theta_dot]), tau)
    return play_motion(theta, theta_dot, play)


def causal_average(y: np.ndarray, window: int, step: int = 1) -> np.ndarray:
    """Causal moving average of ``window`` samples, zero initial state.

    ``out[k] = (y[k] + y[k-1] + ... + y[k-window+1]) / window`` with ``y`` = 0 before the
    record (as a filter started at the first sample). On data decimated by ``step``
    (every ``step``-th measured sample), the signal is linearly interpolated back to the
    measured grid, averaged there, and decimated again.

    Parameters
    ----------
    y : ndarray
        The signal.
    window : int
        Window length in measured samples (1 or less: no filter).
    step : int
        Decimation of ``y`` against the measured grid.

    Returns
    -------
    ndarray
        The filtered signal, same shape as ``y``.
    """
    if window <= 1:
        return y
    y = np.asarray(y, dtype=float)
    fine = y
    if step > 1:
        idx = np.arange(y.size) * step
        fine = np.interp(np.arange(idx[-1] + 1), idx, y)
    c = np.concatenate([np.zeros(window), np.cumsum(fine)])
    out = (c[window:] - c[:-window]) / window
    return out[::step] if step > 1 else out


def average_response(f: np.ndarray, window: int, dt: float) -> np.ndarray:
    """Complex frequency response of the causal moving average of ``window`` samples.

    ``H(f) = sum_j exp(-2 pi i f j dt) / window``, ``j = 0 .. window-1``.

    Examples
    --------
    >>> abs(average_response(np.array([0.0, 10.0]), 10, 0.01)).round(12).tolist()
    [1.0, 0.0]
    """
    f = np.asarray(f, dtype=float)
    j = np.arange(max(int(window), 1))
    return np.exp(-2j * np.pi * np.outer(f, j) * dt).mean(axis=1)


def unfiltered_motion(t: np.ndarray, x: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """The motion before a causal moving average of ``window`` samples, and its velocity.

    A periodic record (a sine test) is fitted by a Fourier series of its fundamental
    (least squares, a non-integer number of cycles is fine); each harmonic is divided by
    the filter's response there (harmonics the filter all but removes are left out), and
    the velocity is the series' derivative. Any other record is inverted in the frequency
    domain with Tikhonov regularization (:data:`INVERSE_REG`), its velocity the spectral
    derivative.

    Parameters
    ----------
    t, x : ndarray
        Sample times (uniform) and the filtered motion.
    window : int
        The moving average's length in samples.

    Returns
    -------
    theta, theta_dot : ndarray
        The reconstructed motion and velocity at ``t``.

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> x = np.sin(2 * np.pi * 1.3 * t)
    >>> th, w = unfiltered_motion(t, causal_average(x, 77), 77)
    >>> bool(np.abs(th - x)[77:].max() < 1e-3), bool(np.abs(w / (2 * np.pi * 1.3) - np.cos(2 * np.pi * 1.3 * t))[77:].max() < 1e-3)
    (True, True)
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    dt = float(np.median(np.diff(t)))
    f0 = motion_frequency(t, x)
    skip = min(int(window), x.size // 2)  # the filter's start-up is not a filtered record
    if f0 > 0:
        ks = np.arange(1, MAX_HARMONICS + 1)
        H = average_response(ks * f0, window, dt)
        ks = ks[(np.abs(H) >= MIN_GAIN) & (ks * f0 < 0.25 / dt)]
        if ks.size:
            tt = t[skip:] - t[0]
            cols = [np.ones_like(tt)]
            for k in ks:
                cols += [np.cos(2 * np.pi * k * f0 * tt), np.sin(2 * np.pi * k * f0 * tt)]
            A = np.column_stack(cols)
            c = np.linalg.lstsq(A, x[skip:], rcond=None)[0]
            res = x[skip:] - A @ c
            if res @ res <= PERIODIC_TOL * float(np.sum((x[skip:] - c[0]) ** 2)):
                ta = t - t[0]
                th = np.full(t.size, c[0])
                w = np.zeros(t.size)
                for m, k in enumerate(ks):
                    amp = (c[1 + 2 * m] - 1j * c[2 + 2 * m]) / average_response(
                        np.array([k * f0]), window, dt
                    )[0]
                    ph = np.exp(2j * np.pi * k * f0 * ta)
                    th += np.real(amp * ph)
                    w += np.real(2j * np.pi * k * f0 * amp * ph)
                return th, w
    # any other record: the regularized inverse, on a linearly detrended copy
    n = x.size
    trend = np.linspace(x[0], x[-1], n)
    f = np.fft.rfftfreq(n, dt)
    H = average_response(f, window, dt)
    X = np.fft.rfft(x - trend) * np.conj(H) / (np.abs(H) ** 2 + INVERSE_REG)
    th = np.fft.irfft(X, n) + trend
    w = np.fft.irfft(2j * np.pi * f * X, n) + (x[-1] - x[0]) / (t[-1] - t[0])
    return th, w


def measured_output(
    t: np.ndarray, y: np.ndarray, delay: float = 0.0, window: int = 0, step: int = 1
) -> np.ndarray:
    """A simulated output as the acquisition records it: delayed by ``delay`` s, then
    averaged over ``window`` measured samples (data decimated by ``step``)."""
    return causal_average(delayed(t, y, delay), window, step)


def apply_filter(
    data: FitData,
    windows: Sequence[int],
    channels: Sequence[str],
    recorded_motion: Sequence[np.ndarray] | None = None,
) -> FitData:
    """``data`` prepared for records filtered by causal moving averages (in place).

    The simulated output of run ``k`` will be averaged over ``windows[k]`` samples when the
    output channel (``torque`` of a driven experiment, ``theta`` of the others) is in
    ``channels``; for a driven experiment whose motion channel (``theta``) was filtered,
    the imposed motion and velocity are reconstructed from ``recorded_motion`` (default:
    ``data.theta``) by :func:`unfiltered_motion`, and a forced experiment's filtered
    ``input`` likewise. The first window of every run leaves the
    residual (the filter's state there is unknown).

    Parameters
    ----------
    data : FitData
        The runs (changed in place and returned).
    windows : sequence of int
        Each run's window in samples (0 or 1: not filtered).
    channels : sequence of str
        The filtered channels, by canonical column name (``theta``, ``torque``, ``input``).
    recorded_motion : sequence of ndarray, optional
        Each run's recorded (filtered) motion.

    Returns
    -------
    FitData
        ``data``.
    """
    exp = data.exp
    windows = [int(w) for w in windows]
    out_channel = exp.output
    if out_channel in channels:
        data.filter_windows = windows
    motion = recorded_motion if recorded_motion is not None else data.theta
    for k, w in enumerate(windows):
        if w <= 1:
            continue
        if exp.motion_imposed and "theta" in channels:
            data.theta[k], data.theta_dot[k] = unfiltered_motion(data.t[k], motion[k], w)
        if exp.has_input and "input" in channels:
            data.u[k] = unfiltered_motion(data.t[k], data.u[k], w)[0]
            data.du = None  # the input's spline slopes are recomputed
        data.mask[k] = data.mask[k].copy()
        data.mask[k][:w] = False
    return data
