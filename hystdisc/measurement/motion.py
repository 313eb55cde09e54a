"""Errors in the imposed motion: each driven run's motion estimate, and what its errors do
to the fitted parameters.

A driven run is simulated on the motion it was driven with, but only a measurement of that
motion is known. :func:`estimate_motion` makes the estimate the fit uses: the harmonic
series of a periodic run (:func:`hystdisc.data.motion.fit_harmonics`, unbiased, its
derivative analytic) when its residual is at the motion noise, else local seventh-order
polynomial fits over at most half the shortest cycle
(:func:`hystdisc.data.motion.local_motion`: nearly unbiased, noisier), and says why in its
``note``. The smoother of the equation-error stage (:func:`hystdisc.discovery.differentiate`,
what the fit used before issue 33, ``mode="legacy"``) passed 99.67 % of a 5 Hz velocity
at 500 Hz and biased the dashpots by 3 standard errors on issue 33's command (its
intervals then missed the truth of c_1, c_2, delta and k_s). Every estimate is a linear
operator ``S`` on the measured motion, so its random error is ``S`` applied to the motion
noise: :meth:`MotionEstimate.modes` writes it as independent unit-variance modes, exactly
(the series' ``2 K + 2`` parameters, the fundamental included) or from
:data:`MOTION_DRAWS` noise draws (local fits; seeded by :data:`MOTION_SEED` and the run).
A motion reconstructed from behind a rig's declared filter is reported, its errors not
propagated (:func:`filter_estimate`).

:func:`hystdisc.fitting.motion_error.motion_covariance` propagates the modes through the fitted model: each mode is added
to the run's motion (scaled up to :data:`MODE_STEP` of the run's peak velocity, so that the
integrator's own error does not show, and the force change scaled back), the model is
simulated on it (``par.simulate`` on a copy of the data whose ``theta``/``theta_dot`` are
perturbed: the compiled term kernels and the error-controlled integrator alike), and the
force change ``dF`` is mapped to the parameters by the Gauss-Newton step
``dv = -(J^T J)^-1 J^T dF``. The covariance of the parameters is then

``s_F^2 (J^T J)^-1 + sum_modes dv dv^T``,

with ``s_F^2`` the force noise: the residual variance less the part the motion errors put
into the residual (``|dF|^2 - dv^T J^T J dv`` per mode), which would otherwise be counted
twice.

Examples
--------
>>> import numpy as np
>>> t = np.arange(2000) / 500.0
>>> x = 0.05 * np.sin(2 * np.pi * 5.0 * t) + np.random.default_rng(0).normal(0, 1e-4, t.size)
>>> est = estimate_motion(t, x, seed=0)
>>> est.method, est.modes()[1].shape
('harmonic', (2000, 4))
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pysindy.differentiation import SmoothedFiniteDifference
from scipy.interpolate import CubicSpline

from hystdisc.data.motion import (
    HarmonicMotion,
    RunMotionNoise,
    fit_harmonics,
    local_motion,
    local_window,
    motion_noise,
)
from hystdisc.discovery import differentiate
from hystdisc.discovery.differentiation import POLYORDER, block_factor
from hystdisc.errors import HystdiscError
from hystdisc.measurement.chain import unfiltered_motion

#: Noise draws of a motion estimate whose error is not written out (local fits, the
#: legacy smoother): the covariance they add is known to about ``sqrt(2 / draws)`` of
#: itself (14 %).
MOTION_DRAWS = 100
#: Seed of those draws (with the run's index: the same draws on every call).
MOTION_SEED = 33
#: Samples simulated at once while propagating (bounds the memory of the copies).
CHUNK_SAMPLES = 2_000_000
#: How a driven run's motion may be estimated (``mode`` of :func:`estimate_motion`; the
#: pipeline's ``Options.motion``): ``"auto"`` (the harmonic series where it is accepted,
#: else local polynomial fits) or ``"legacy"`` (the equation-error stage's smoother, as
#: before issue 33: kept to measure the change against,
#: ``benchmarks/interval_coverage_driven.py``).
MOTION_MODES = ("auto", "legacy")


@dataclass
class MotionEstimate:
    """One driven run's motion as the fit uses it, and how it errs.

    Attributes
    ----------
    method : str
        ``"harmonic"`` (a Fourier series of a periodic motion), ``"local"`` (local
        polynomial fits, :func:`~hystdisc.data.motion.local_motion`), ``"filter"`` (the
        motion before a rig's declared filter,
        :func:`~hystdisc.measurement.chain.unfiltered_motion`) or ``"smoother"`` (the
        equation-error stage's, with ``mode="legacy"``).
    noise : RunMotionNoise
        The noise on the measured motion.
    theta, theta_dot, theta_ddot : ndarray
        The motion, velocity and acceleration the fit uses.
    window : int
        The smoother's window in samples (also for a harmonic run: the equation-error
        stage decimates by it).
    harmonic : HarmonicMotion or None
        The harmonic fit, when one was tried (accepted or not).
    operator : callable or None
        For the modes drawn at random: noise draws ``(samples, draws)`` -> the motion and
        velocity errors they cause, each ``(samples, draws)``.
    seed : int
        The run's seed of those draws (with :data:`MOTION_SEED`).
    note : str
        Why the harmonic series was not used (empty for a harmonic run).
    edge : int
        Samples at either end where the estimate is a one-sided fit (a smoother's half
        window; 0 for the series): they leave the residual.
    """

    method: str
    noise: RunMotionNoise
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    window: int
    harmonic: HarmonicMotion | None = None
    operator: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None
    seed: int = 0
    note: str = ""
    edge: int = 0
    _modes: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """The estimate's random error as independent unit-variance modes: the motion and
        velocity parts, each ``(samples, modes)`` (none without noise). Computed once when
        they are small (at most :data:`CHUNK_SAMPLES` values), else on every call."""
        if self._modes is not None:
            return self._modes
        n = self.theta.size
        if self.noise.std > 0 and self.method == "harmonic" and self.harmonic is not None:
            out = self.harmonic.error_modes()
        elif self.noise.std > 0 and self.operator is not None:
            rng = np.random.default_rng([MOTION_SEED, self.seed])
            e = rng.standard_normal((n, MOTION_DRAWS)) * (self.noise.std / np.sqrt(MOTION_DRAWS))
            out = self.operator(e)
        else:  # no noise, or errors that are not propagated (a declared filter's)
            out = np.zeros((n, 0)), np.zeros((n, 0))
        if out[0].size <= CHUNK_SAMPLES:
            self._modes = out
        return out

    @property
    def drawn(self) -> bool:
        """True when :meth:`modes` are random noise draws (exchangeable: any subset of
        ``m`` of them, scaled by ``MOTION_DRAWS / m``, estimates the same covariance),
        False for the exact modes of a harmonic series."""
        return not (self.method == "harmonic" and self.harmonic is not None)

    def summary(self) -> dict:
        """``estimate`` and, when a harmonic fit was tried, its ``harmonics``, ``frequency``
        and ``residual``; ``note`` when the series was not used (``results.json``)."""
        out: dict = {"estimate": self.method}
        if self.harmonic is not None:
            out.update(self.harmonic.summary())
        if self.note:
            out["note"] = self.note
        return out


def smoother_operator(t: np.ndarray, window: int) -> Callable:
    """The Savitzky-Golay smoothing and derivative of :func:`~hystdisc.discovery.differentiate`
    at a fixed ``window`` (block averages first above 1 kHz, as it does) as a linear map of
    columns of noise.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(1000) / 500.0
    >>> x = np.random.default_rng(2).normal(size=1000)
    >>> d = differentiate(t, x, 0.0, window=25)
    >>> th, w = smoother_operator(t, 25)(x[:, None])
    >>> bool(np.allclose(th[:, 0], d.theta) and np.allclose(w[:, 0], d.theta_dot))
    True
    """
    t = np.asarray(t, dtype=float)
    p = block_factor(t)
    if window % p:  # an explicit window is used at the record's own rate
        p = 1
    wb = int(window) // p

    def apply(E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n, m = E.shape
        if p == 1:
            tb, Eb = t, E
        else:
            nb = n // p
            tb = t[: nb * p].reshape(nb, p).mean(axis=1)
            Eb = E[: nb * p].reshape(nb, p, m).mean(axis=1)
        # as differentiate does it: the velocity is the smoothed difference of the
        # smoothed motion (smoothed twice)
        sfd = [
            SmoothedFiniteDifference(
                smoother_kws={"window_length": wb, "polyorder": POLYORDER}, save_smooth=True
            )
            for _ in range(2)
        ]
        w1 = np.asarray(sfd[0](Eb, tb)).reshape(-1, m)
        th = np.asarray(sfd[0].smoothed_x_).reshape(-1, m)
        sfd[1](w1, tb)
        w = np.asarray(sfd[1].smoothed_x_).reshape(-1, m)
        if p > 1:
            th, w = CubicSpline(tb, th, axis=0)(t), CubicSpline(tb, w, axis=0)(t)
        return th, w

    return apply


def estimate_motion(
    t: np.ndarray,
    theta: np.ndarray,
    smoother_noise: float | None = None,
    seed: int = 0,
    noise: RunMotionNoise | None = None,
    mode: str = "auto",
) -> MotionEstimate:
    """One driven run's motion estimate (see the module).

    Parameters
    ----------
    t, theta : ndarray
        Sample times and the measured motion.
    smoother_noise : float, optional
        The noise level the equation-error stage's smoother is chosen for (its window
        decimates that stage; default: the run's motion noise).
    seed : int
        The run's seed for drawn modes (its index in the dataset).
    noise : RunMotionNoise, optional
        The run's motion noise (default: :func:`~hystdisc.data.motion.motion_noise`).
    mode : {"auto", "legacy"}
        How the motion is estimated (:data:`MOTION_MODES`).

    Returns
    -------
    MotionEstimate
        ``harmonic`` when the series is accepted, else ``local`` (with ``mode="legacy"``:
        ``smoother``).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(2000) / 500.0
    >>> ramp = np.minimum(t, 1.0)  # the amplitude grows over the first second
    >>> x = 0.05 * ramp * np.sin(2 * np.pi * 5.0 * t)
    >>> est = estimate_motion(t, x + np.random.default_rng(0).normal(0, 1e-4, t.size))
    >>> est.method, est.edge, est.note.split(":")[0]
    ('local', 14, 'residual RMS 92 times the motion noise')
    """
    if mode not in MOTION_MODES:
        raise HystdiscError(f"unknown motion estimate '{mode}'; fix: use auto or legacy")
    t = np.asarray(t, dtype=float)
    x = np.asarray(theta, dtype=float)
    noise = motion_noise(t, x) if noise is None else noise
    d = differentiate(t, x, noise.std if smoother_noise is None else smoother_noise)
    if mode == "legacy":  # as before issue 33: the equation-error stage's smoother
        op = smoother_operator(t, d.window)
        return MotionEstimate(
            "smoother", noise, d.theta, d.theta_dot, d.theta_ddot, d.window, None, op, seed,
            "the smoother was asked for", d.window // 2,
        )  # fmt: skip
    h = fit_harmonics(t, x, noise.std, noise.period)
    if h is not None and h.accepted:
        th, w, a = h.evaluate()
        return MotionEstimate("harmonic", noise, th, w, a, d.window, h, seed=seed)
    note = h.note if h is not None else "the motion does not oscillate over enough cycles"
    win = local_window(t, x, noise.std)
    dt = float(t[-1] - t[0]) / max(t.size - 1, 1)
    th, w, a = local_motion(x, win, dt)

    def op(E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return local_motion(E, win, dt, derivatives=1)

    return MotionEstimate("local", noise, th, w, a, d.window, h, op, seed, note, win // 2)


def filter_estimate(
    est: MotionEstimate, t: np.ndarray, theta: np.ndarray, window: int
) -> MotionEstimate:
    """``est`` for a run whose recorded motion went through a rig's declared causal moving
    average of ``window`` samples: the fit's motion is then the one before the filter
    (:func:`~hystdisc.measurement.chain.unfiltered_motion`). Its errors are not
    propagated: the filter hides the motion's noise from the estimates (on the UTFSM
    records the differences read 1e-8 to 4e-7 m, and no record repeats every whole number
    of samples), and drawing them through the reconstruction cost 30 s per fit there."""
    th0, w0 = unfiltered_motion(np.asarray(t, dtype=float), np.asarray(theta, dtype=float), window)
    note = (
        "the motion before the rig's declared filter (its reconstruction); its errors are "
        "not propagated: the filter hides the motion's noise"
    )
    return MotionEstimate(
        "filter", est.noise, th0, w0, est.theta_ddot, est.window, est.harmonic, None, est.seed,
        note,
    )  # fmt: skip
