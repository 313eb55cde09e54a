"""Intervals of a fit to quantized data: the quantization error is not white.

An encoder reads ``Q(y) = q round(y / q)``: its error ``e = Q(y) - y`` is a fixed sawtooth
of the *true* output ``y`` (period ``q``, uniform over ``[-q/2, q/2]``, RMS
``q / sqrt(12)``). Two samples whose true outputs are close have nearly the same error,
whatever the time between them: a beam that dwells within one count for a second, or
passes the same angle again, repeats its error. Least-squares intervals that count every
sample as independent are then too narrow (and an effect's Wald test too confident).

With the encoder's zero at an unknown phase relative to the true output, the error has
the covariance ``(q^2 / 12) rho(y_t - y_s)`` where the sawtooth's autocorrelation is ::

    rho(d) = 1 - 6 u + 6 u^2,  u = frac(abs(d) / q)
           = (6 / pi^2) sum_k cos(2 pi k d / q) / k^2

The information matrix ``J' R J`` (``R_ts = rho(y_t - y_s)``) is then a sum of rank-two
terms ``Re(c_k c_k^H)`` with ``c_k = J' exp(2 pi i k y / q)`` (:func:`quantization_information`,
linear in the samples where the dense ``R`` is quadratic), and the fit's covariance is the
sandwich ``s^2 (J'J)^-1 J' R J (J'J)^-1``. The fitted output stands in for the true one.

Examples
--------
The Fourier form against the dense correlation matrix:

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> y, J, q = np.cumsum(rng.normal(0, 0.3, 400)), rng.normal(size=(400, 3)), 1.0
>>> u = np.abs(y[:, None] - y[None, :]) / q % 1.0
>>> dense = J.T @ (1 - 6 * u + 6 * u**2) @ J
>>> fast = quantization_information(J, y, q, harmonics=2000)
>>> bool(np.allclose(fast, dense, rtol=1e-3, atol=1e-3 * np.abs(dense).max()))
True
"""

from __future__ import annotations

import numpy as np

#: Harmonics of the sawtooth kept exactly; the rest (``6 / (pi^2 K)`` of the variance,
#: 1 % for 64) is counted as white.
HARMONICS = 64


def quantization_information(
    J: np.ndarray, y: np.ndarray, step: float, harmonics: int = HARMONICS
) -> np.ndarray:
    """``J' R J`` for the correlation ``R`` of quantization error (see the module docstring).

    Parameters
    ----------
    J : ndarray, shape (N, p)
        Jacobian of the residual (one row per sample).
    y : ndarray, shape (N,)
        The (fitted) true output at the same samples.
    step : float
        The quantization step ``q`` (output units).
    harmonics : int
        Sawtooth harmonics summed exactly.

    Returns
    -------
    ndarray, shape (p, p)
        Symmetric positive semi-definite; ``J' J`` for white noise of the same variance.
    """
    J = np.asarray(J, dtype=float)
    phase = (2.0 * np.pi / step) * np.asarray(y, dtype=float)
    ks = np.arange(1, harmonics + 1)
    weights = 6.0 / (np.pi**2 * ks.astype(float) ** 2)
    out = (1.0 - weights.sum()) * (J.T @ J)
    for k, w in zip(ks, weights, strict=True):
        c = J.T @ np.exp(1j * k * phase)
        out += w * np.real(np.outer(c, c.conj()))
    return out
