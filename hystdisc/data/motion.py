"""The imposed motion of a driven test, measured: its noise, and an unbiased estimate of it.

A driven test imposes the motion and measures it too, so the motion the model is driven
with carries measurement errors of its own (errors in variables). Here:

* **its noise** (:func:`motion_noise`), per run: from cycle-to-cycle differences when the
  motion repeats every whole number of samples (:func:`~hystdisc.data.detect_period`,
  :func:`~hystdisc.data.period_noise`, from the second cycle on), else from high-order
  differences (:func:`~hystdisc.data.estimate_noise`, white noise on a smooth motion),
  raised to the quantization floor ``q / sqrt(12)`` when the motion sits on a lattice the
  detector recognizes (:func:`~hystdisc.data.detect_quantization`: an encoder). The
  differences are used on a periodic run too when they are clearly larger than the cycles'
  spread: an error that is a fixed function of the motion repeats with it (a lattice too
  fine to be recognized, a 16-bit displacement channel whose error at a whole-sample period
  is the same every cycle) and is invisible from cycle to cycle, not in the differences;
* **an unbiased motion estimate for periodic runs** (:func:`fit_harmonics`): a least-squares
  Fourier series at the motion's fundamental (refined by least squares), with the harmonics
  the data show (each kept when its Wald statistic is significant at :data:`HARMONIC_ALPHA`
  over all the candidates), and its analytic derivative as the velocity. A smoother
  attenuates what it passes: the equation-error stage's (Savitzky-Golay of third order,
  its window chosen to leave a residual of 1.2 times the noise, the velocity differenced
  and smoothed again) took 0.33 % off the velocity of a 5 Hz sine sampled at 500 Hz, which
  biased the dashpot coefficients by 3 standard errors. The series has no such bias, and
  its random error is the projection of the noise on its few columns
  (:meth:`HarmonicMotion.error_modes`). It is *accepted* only when its residual is at the
  motion noise: overall RMS at most :data:`ACCEPT_RMS` times the noise, and no cycle (or
  block) whose mean square is beyond the chi-square bound of the noise
  (:data:`BLOCK_ALPHA`, Bonferroni over the blocks) — a start-up ramp, a drift or a
  history that is not periodic fails;
* **a motion that does not repeat** (a start-up ramp, a drift, a random or swept input) is
  estimated by local polynomial fits (:func:`local_motion`: Savitzky-Golay of order
  :data:`LOCAL_ORDER`, the velocity the fits' own slope) over a window of at most
  :data:`LOCAL_CYCLES` of the shortest cycle the motion holds (:func:`signal_band`: the
  highest periodogram bin above the noise). Its random error is larger than a wider
  window's, and is propagated; its bias is not, and is what the window is chosen against:
  where the smoother passed 99.67 % of a 5 Hz velocity at 500 Hz, these fits pass
  100.00 %.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> t = np.arange(2000) / 500.0
>>> x = 0.05 * np.sin(2 * np.pi * 5.0 * t) + rng.normal(0, 1e-4, t.size)
>>> est = motion_noise(t, x)
>>> est.method, round(est.std / 1e-4, 1)
('cycle-to-cycle', 1.0)
>>> h = fit_harmonics(t, x, est.std)
>>> h.accepted, h.harmonics, round(h.frequency, 4)
(True, (1,), 5.0)
>>> th, w, _ = h.evaluate()
>>> bool(abs(np.max(w) / (0.05 * 2 * np.pi * 5.0) - 1) < 1e-3)
True
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import savgol_filter
from scipy.stats import chi2

from hystdisc.data.noise import detect_period, period_noise
from hystdisc.data.preprocessing import estimate_noise
from hystdisc.data.quantization import detect_quantization
from hystdisc.data.rigs import motion_frequency

__all__ = [
    "HarmonicMotion",
    "MotionNoise",
    "RunMotionNoise",
    "fit_harmonics",
    "local_motion",
    "local_window",
    "motion_noise",
    "pooled_motion_noise",
    "signal_band",
]

#: Cycles a record must hold for its harmonic fit.
MIN_CYCLES = 1.5
#: Harmonics of the fundamental considered, at most (and below 0.45 of the sampling rate).
MAX_HARMONICS = 50
#: Family-wise level of the harmonics' selection: the chance that a harmonic the motion
#: does not hold is kept. A spurious high harmonic costs much (its random slope grows with
#: its order) and the intervals, computed given the harmonics kept, would not see it: at
#: the BIC penalty ``2 ln N``, 5 % of the fits of a 1000-sample 5 Hz record kept one, and
#: the velocity varied over the fits 21 times as much (in variance) as the series' error
#: predicted; at 1e-3, 1.1 times.
HARMONIC_ALPHA = 1e-3
#: The harmonic fit is accepted when its residual RMS is at most this times the motion
#: noise (besides the per-block test): what is left unmodelled is then below about half the
#: noise RMS (``sqrt(1.1**2 - 1) = 0.46``), where the smoother's discrepancy principle
#: (1.2 times the noise) lets it distort the motion by up to 0.66 of the noise.
ACCEPT_RMS = 1.1
#: Family-wise level of the per-block chi-square test of the harmonic residual (a block is
#: a cycle, or an eighth of the record when it holds fewer cycles than that).
BLOCK_ALPHA = 1e-3
#: The cycle-to-cycle estimate is used unless the differences exceed it by more than this
#: many of its relative standard errors (``1 / sqrt(differences)``).
C2C_MARGIN = 4.0
#: Polynomial order of the local fits of a motion that is not periodic (the fallback).
LOCAL_ORDER = 7
#: Their window spans at most this share of the shortest cycle the motion holds (a
#: seventh-order fit over half a cycle passes a sine's slope to 1e-5).
LOCAL_CYCLES = 0.5
#: Their window in samples, at most (the Savitzky-Golay smoother's cap).
LOCAL_MAX_WINDOW = 151
#: A periodogram bin holds signal when its power is above this many times the noise's.
SIGNAL_POWER = 30.0
#: A noise level below this fraction of the motion's RMS counts as noise-free (synthetic
#: motion): the tests then use this floor instead of zero.
NOISE_FLOOR = 1e-10


@dataclass(frozen=True)
class RunMotionNoise:
    """One run's motion noise.

    Attributes
    ----------
    std : float
        The noise standard deviation (motion units).
    method : str
        ``"cycle-to-cycle"``, ``"differences"`` or ``"quantization"``.
    period : int or None
        The motion's period in samples when it repeats every whole number of samples.
    differences : float
        The high-order-difference estimate (white noise on a smooth motion).
    floor : float or None
        The quantization floor ``q / sqrt(12)`` of a quantized motion (else None).
    """

    std: float
    method: str
    period: int | None
    differences: float
    floor: float | None = None


def motion_noise(t: np.ndarray, theta: np.ndarray) -> RunMotionNoise:
    """The noise on one run's measured motion (see the module).

    Parameters
    ----------
    t, theta : ndarray
        Sample times and the measured motion.

    Returns
    -------
    RunMotionNoise

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4000) / 1000.0
    >>> x = 0.2 * np.sin(2 * np.pi * 1.3 * t)  # 1.3 Hz: no whole period in samples
    >>> q = 0.4 / 2**10  # a coarse lattice, recognized
    >>> est = motion_noise(t, q * np.round(x / q))
    >>> est.method, est.period, round(float(est.std / (q / np.sqrt(12))), 3)
    ('quantization', None, 1.0)
    >>> q = 0.4 / 2**16  # too fine to be recognized: its error reads as white noise
    >>> est = motion_noise(t, q * np.round(x / q))
    >>> est.method, round(float(est.std / (q / np.sqrt(12))), 2)
    ('differences', 1.03)
    """
    x = np.asarray(theta, dtype=np.float64).reshape(-1)
    diff = estimate_noise(x)
    period = detect_period(x)
    per = period_noise(x, period) if period is not None else None
    std, method = diff, "differences"
    # an error that repeats with the motion (a fine lattice whose error is a fixed function
    # of the motion, a sensor's nonlinearity) does not show from cycle to cycle, but it is
    # an error of the measured motion all the same: the differences see it
    if per is not None and diff <= per[0] * (1.0 + C2C_MARGIN / math.sqrt(per[1].size)):
        std, method = per[0], "cycle-to-cycle"
    q = detect_quantization(x, angle=True)
    floor = q.floor if q is not None else None
    if floor is not None and floor > std:
        std, method = floor, "quantization"
    return RunMotionNoise(float(std), method, period if per is not None else None, diff, floor)


@dataclass
class MotionNoise:
    """The noise on the measured motion of a driven dataset (``results.json``:
    ``motion_noise``).

    Attributes
    ----------
    std : float
        Pooled over the runs: the root of the sample-weighted mean of their variances.
    method : str
        How most runs were estimated (``"cycle-to-cycle"``, ``"differences"`` or
        ``"quantization"``).
    runs : dict of str to RunMotionNoise
        Each run's estimate.
    estimates : dict of str to dict
        How each run's motion was estimated for the fit: ``estimate`` (``"harmonic"``,
        ``"local"``, ``"filter"`` or ``"smoother"``), and ``harmonics``, ``frequency``,
        ``residual`` (the harmonic fit's, when one was tried) and ``note`` (why a harmonic
        fit was not used).
    """

    std: float
    method: str
    runs: dict[str, RunMotionNoise]
    estimates: dict[str, dict] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The ``results.json`` form: ``std``, ``method``, ``runs`` (name -> std),
        ``methods`` (name -> method) and ``estimates``."""
        return {
            "std": self.std,
            "method": self.method,
            "runs": {k: r.std for k, r in self.runs.items()},
            "methods": {k: r.method for k, r in self.runs.items()},
            "estimates": {k: dict(v) for k, v in self.estimates.items()},
        }

    def describe(self) -> str:
        """One line: the level, how it was estimated and how the motion was estimated."""
        kinds = Counter(v.get("estimate") for v in self.estimates.values())
        how = ", ".join(f"{n} {k}" for k, n in kinds.items())
        return f"motion noise {self.std:.3g} from {self.method}" + (
            f" (motion estimates: {how})" if how else ""
        )


def pooled_motion_noise(
    names: Sequence[str], sizes: Sequence[int], runs: Sequence[RunMotionNoise]
) -> MotionNoise:
    """The dataset's :class:`MotionNoise` from each run's estimate.

    Examples
    --------
    >>> a = RunMotionNoise(1.0, "differences", None, 1.0)
    >>> b = RunMotionNoise(2.0, "cycle-to-cycle", 100, 2.1)
    >>> m = pooled_motion_noise(["a", "b", "c"], [100, 100, 200], [a, b, b])
    >>> round(m.std, 4), m.method
    (1.8028, 'cycle-to-cycle')
    """
    w = np.asarray(sizes, dtype=float)
    var = np.array([r.std**2 for r in runs])
    std = float(np.sqrt(np.sum(w * var) / np.sum(w))) if w.sum() > 0 else 0.0
    counts = Counter(r.method for r in runs)
    order = {"cycle-to-cycle": 0, "quantization": 1, "differences": 2}
    method = min(counts, key=lambda m: (-counts[m], order[m])) if runs else "differences"
    return MotionNoise(std, method, dict(zip(names, runs, strict=True)))


@dataclass
class HarmonicMotion:
    """A least-squares Fourier series of one run's motion (:func:`fit_harmonics`).

    Attributes
    ----------
    t : ndarray
        The sample times it was fitted at.
    frequency : float
        The fundamental (Hz), refined by least squares.
    harmonics : tuple of int
        The harmonics kept (1: the fundamental).
    coef : ndarray
        Mean, then the cosine and sine coefficient of each harmonic.
    noise_std : float
        The motion noise the fit was judged against.
    residual_rms : float
        RMS of the measured motion minus the series.
    accepted : bool
        The residual is at the motion noise (the series may replace the measured motion).
    note : str
        Why it was not accepted (empty when it was).
    """

    t: np.ndarray
    frequency: float
    harmonics: tuple[int, ...]
    coef: np.ndarray
    noise_std: float
    residual_rms: float
    accepted: bool
    note: str = ""

    def basis(self) -> tuple[np.ndarray, np.ndarray]:
        """The series' columns at :attr:`t` and their time derivatives."""
        return _basis(self.t, self.frequency, self.harmonics)

    def evaluate(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fitted motion and its first two analytic derivatives at :attr:`t`."""
        B, dB = self.basis()
        om2 = np.repeat((2.0 * np.pi * self.frequency * np.asarray(self.harmonics)) ** 2, 2)
        return B @ self.coef, dB @ self.coef, -(B[:, 1:] @ (om2 * self.coef[1:]))

    def error_modes(self) -> tuple[np.ndarray, np.ndarray]:
        """The random error of the series as independent unit-variance modes.

        The series is linear in its coefficients and, to first order, in a change of the
        fundamental ``f`` (``d theta / d f = tau theta' / f``, ``d theta' / d f = (theta' +
        tau theta'') / f``, ``tau`` the time from the first sample). White motion noise of
        :attr:`noise_std` gives these parameters the covariance ``s^2 (X^T X)^-1`` (``X``:
        the columns and the fundamental's derivative); with ``L`` its Cholesky factor, the
        error of the motion and of the velocity is ``sum_j xi_j (X L)_j`` and
        ``sum_j xi_j (X' L)_j`` with independent standard normal ``xi_j``.

        Returns
        -------
        dtheta, dtheta_dot : ndarray
            Shape ``(samples, modes)``, one column per mode (``2 K + 2`` of them for
            ``K`` harmonics).
        """
        B, dB = self.basis()
        _, w, a = self.evaluate()
        tau = self.t - self.t[0]
        X = np.column_stack([B, tau * w / self.frequency])
        dX = np.column_stack([dB, (w + tau * a) / self.frequency])
        L = np.linalg.cholesky(np.linalg.inv(X.T @ X)) * self.noise_std
        return X @ L, dX @ L

    def summary(self) -> dict:
        """``harmonics`` (how many), ``frequency``, ``residual`` (RMS) for ``results.json``."""
        return {
            "harmonics": len(self.harmonics),
            "frequency": self.frequency,
            "residual": self.residual_rms,
        }


def _basis(t: np.ndarray, f: float, ks: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    tt = np.asarray(t, dtype=float) - float(t[0])
    B = np.empty((tt.size, 1 + 2 * len(ks)))
    dB = np.zeros_like(B)
    B[:, 0] = 1.0
    # exp(i k w t) by powers of exp(i w t): one pair of trigonometric calls per record
    # (the round-off grows as k times the machine epsilon)
    e1 = np.exp(1j * 2.0 * np.pi * f * tt)
    ek, k0 = np.ones_like(e1), 0
    for j, k in enumerate(ks):
        ek = ek * e1 ** (k - k0) if k - k0 > 1 else ek * e1
        k0 = k
        om = 2.0 * np.pi * k * f
        c, s = ek.real, ek.imag
        B[:, 1 + 2 * j], B[:, 2 + 2 * j] = c, s
        dB[:, 1 + 2 * j], dB[:, 2 + 2 * j] = -om * s, om * c
    return B, dB


def _lstsq(t, x, f, ks):
    B, _ = _basis(t, f, ks)
    # normal equations: the columns are all but orthogonal over 1.5 cycles or more
    c = np.linalg.solve(B.T @ B, B.T @ x)
    r = x - B @ c
    return c, float(r @ r), B


def _refine(t, x, f0, ks, span):
    """The fundamental minimizing the residual of the series ``ks`` within ``f0 +- span``."""
    res = minimize_scalar(
        lambda f: _lstsq(t, x, f, ks)[1],
        bounds=(f0 - span, f0 + span),
        method="bounded",
        options={"xatol": 1e-10 * f0},
    )
    f = float(res.x)
    return f if _lstsq(t, x, f, ks)[1] <= _lstsq(t, x, f0, ks)[1] else f0


def _significant(c: np.ndarray, B: np.ndarray, s: float, ks: Sequence[int]) -> list[int]:
    """The harmonics whose Wald statistic (chi-square, two degrees of freedom, where the
    harmonic is absent) is beyond the level :data:`HARMONIC_ALPHA` over all candidates."""
    cov = np.linalg.inv(B.T @ B) * s * s
    bound = 2.0 * math.log(len(ks) / HARMONIC_ALPHA)  # P(chi2_2 > b) = exp(-b / 2)
    keep = []
    for j, k in enumerate(ks):
        sl = slice(1 + 2 * j, 3 + 2 * j)
        ck = c[sl]
        if float(ck @ np.linalg.solve(cov[sl, sl], ck)) > bound:
            keep.append(int(k))
    return keep


def fit_harmonics(
    t: np.ndarray, theta: np.ndarray, noise_std: float, period: int | None = None
) -> HarmonicMotion | None:
    """A least-squares Fourier series of a periodic motion, judged against its noise.

    Parameters
    ----------
    t, theta : ndarray
        Sample times and the measured motion of one run.
    noise_std : float
        The motion noise (:func:`motion_noise`).
    period : int, optional
        The period in samples when known (else the fundamental comes from the motion's
        mean-level crossings, :func:`~hystdisc.data.motion_frequency`).

    Returns
    -------
    HarmonicMotion or None
        None when the motion does not oscillate over :data:`MIN_CYCLES` cycles; else the
        fit, ``accepted`` when its residual is at the noise.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(3000) / 1000.0
    >>> ramp = np.minimum(t / 1.0, 1.0)  # the amplitude grows over the first second
    >>> x = 0.1 * ramp * np.sin(2 * np.pi * 2.0 * t)
    >>> h = fit_harmonics(t, x + np.random.default_rng(1).normal(0, 1e-4, t.size), 1e-4)
    >>> h.accepted, h.note.split(":")[0]
    (False, 'residual RMS 2e+02 times the motion noise')
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(theta, dtype=float)
    n = x.size
    if n < 16 or not t[-1] > t[0]:
        return None
    dt = float(t[-1] - t[0]) / (n - 1)
    dur = n * dt
    f0 = 1.0 / (period * dt) if period else motion_frequency(t, x)
    if not (f0 > 0 and f0 * dur >= MIN_CYCLES):
        return None
    scale = float(np.sqrt(np.mean((x - x.mean()) ** 2)))
    s = max(float(noise_std), NOISE_FLOOR * scale)
    kmax = max(1, min(MAX_HARMONICS, int(0.45 / (f0 * dt))))
    span = 0.5 / dur  # half a Fourier bin: the crossings' estimate is well within it
    # the fundamental, refined on the first few harmonics, then the harmonics the data show
    f = _refine(t, x, f0, list(range(1, min(kmax, 5) + 1)), span)
    ks = list(range(1, kmax + 1))
    c, _, B = _lstsq(t, x, f, ks)
    keep = _significant(c, B, s, ks) or [1]
    f = _refine(t, x, f, keep, span)
    c, rss, _ = _lstsq(t, x, f, keep)
    rms = math.sqrt(rss / n)
    ratio = rms / s
    note = ""
    if ratio > ACCEPT_RMS:
        note = (
            f"residual RMS {ratio:.2g} times the motion noise: the motion is not one "
            "periodic series (a start-up ramp, a drift or a history that does not repeat)"
        )
    else:
        note = _block_note(x - _basis(t, f, keep)[0] @ c, s, max(1, round(1.0 / (f * dt))))
    return HarmonicMotion(t, f, tuple(keep), c, float(noise_std), rms, not note, note)


def _block_note(r: np.ndarray, s: float, per: int) -> str:
    """Empty when no block of the residual ``r`` (a cycle of ``per`` samples, or an eighth
    of the record) has a mean square beyond the noise's chi-square bound; else why."""
    size = min(per, max(r.size // 8, 1))
    nb = r.size // size
    if nb < 1:
        return ""
    ms = np.mean(r[: nb * size].reshape(nb, size) ** 2, axis=1) / (s * s)
    bound = chi2.isf(BLOCK_ALPHA / nb, size) / size
    worst = int(np.argmax(ms))
    if ms[worst] > bound:
        return (
            f"block {worst + 1} of {nb} has a residual mean square {ms[worst]:.3g} times the "
            f"motion noise's (bound {bound:.3g}): the motion does not repeat there"
        )
    return ""


def signal_band(t: np.ndarray, x: np.ndarray, noise_std: float) -> float:
    """The highest frequency (Hz) at which a record holds power above its noise.

    The periodogram of the mean-removed, Hann-windowed record; a bin holds signal when
    its power exceeds :data:`SIGNAL_POWER` times what white noise of ``noise_std`` puts
    there. The Nyquist frequency when even the highest bin does (a noise-free record).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4000) / 1000.0
    >>> x = np.sin(2 * np.pi * 3.0 * t) + np.random.default_rng(0).normal(0, 1e-3, t.size)
    >>> bool(3.0 <= signal_band(t, x, 1e-3) < 6.0)
    True
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    dt = float(t[-1] - t[0]) / max(n - 1, 1)
    win = np.hanning(n)
    power = np.abs(np.fft.rfft((x - x.mean()) * win)) ** 2
    floor = SIGNAL_POWER * float(noise_std) ** 2 * float(np.sum(win**2))
    above = np.flatnonzero(power > floor)
    f = np.fft.rfftfreq(n, dt)
    return float(f[above[-1]]) if above.size and above[-1] > 0 else float(f[-1])


def local_window(t: np.ndarray, x: np.ndarray, noise_std: float) -> int:
    """The window (odd, samples) of :func:`local_motion` for a record: :data:`LOCAL_CYCLES`
    of the shortest cycle it holds (:func:`signal_band`), within ``LOCAL_ORDER + 2`` and
    :data:`LOCAL_MAX_WINDOW` samples (and the record).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(2000) / 500.0
    >>> x = 0.05 * np.sin(2 * np.pi * 5.0 * t) + np.random.default_rng(0).normal(0, 1e-4, t.size)
    >>> local_window(t, x, 1e-4)
    47
    """
    n = np.asarray(x).size
    dt = float(t[-1] - t[0]) / max(n - 1, 1)
    w = int(LOCAL_CYCLES / (signal_band(t, x, noise_std) * dt))
    hi = min(LOCAL_MAX_WINDOW, n if n % 2 else n - 1)
    w = max(LOCAL_ORDER + 2, min(w, hi))
    return w if w % 2 else w - 1


def local_motion(x: np.ndarray, window: int, dt: float, derivatives: int = 2) -> tuple:
    """The motion, velocity and acceleration of local polynomial fits (Savitzky-Golay of
    order :data:`LOCAL_ORDER`, the derivatives the fits' own). Linear in ``x``, and
    column by column for a 2-D ``x`` (samples along the first axis); ``derivatives``: how
    many derivatives to return (the motion first).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(1000) / 500.0
    >>> th, w, a = local_motion(0.05 * np.sin(2 * np.pi * 5.0 * t), 47, 1 / 500.0)
    >>> round(float(np.max(np.abs(w[50:-50])) / (0.05 * 2 * np.pi * 5.0)), 6)
    1.0
    """
    x = np.asarray(x, dtype=float)
    return tuple(
        savgol_filter(x, window, LOCAL_ORDER, deriv=k, delta=dt, axis=0)
        for k in range(derivatives + 1)
    )
