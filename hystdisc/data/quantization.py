"""Quantized signals: values on a lattice ``offset + k q`` (an encoder, an ADC).

An encoder of N counts per revolution records the angle in steps ``q = 2 pi / N``; when
the motion is slow against the step, the quantization error is a deterministic sawtooth
of the signal, not white noise, and the difference-based noise estimate
(:func:`~hystdisc.data.estimate_noise`) falls below the error's own RMS ``q / sqrt(12)``
(the RMS of a uniform error over one step). :func:`detect_quantization` finds the lattice
so that this floor can be used instead.

The test (all of it must hold):

1. **a step** ``q``: the gaps between consecutive distinct values, sorted; the typical
   small gap (the median of the gaps up to 1.5 times their 10 % quantile) is a first
   ``q``, and the gaps that are within :data:`LATTICE_TOL` of 1, 2 or 3 steps refine it
   (total gap over total steps);
2. **on the lattice**: the offset is the circular mean of every sample's position within a
   step, and at least :data:`MIN_ON_LATTICE` of the samples lie within
   :data:`LATTICE_TOL` of a step of the lattice (isolated glitches may be off it);
   ``q`` and the offset are then fitted by least squares to every sample on the lattice;
3. **a filled lattice, not a float format**: at least :data:`MIN_LEVELS` distinct levels,
   and the levels visited fill at least :data:`MIN_OCCUPANCY` of the lattice between the
   smallest and the largest. Values printed with a few significant digits sit on a fine
   decimal lattice too, but fill a negligible part of it; noise-free floats fill none.

For an angle in rad, ``2 pi / q`` within :data:`COUNTS_TOL` of a whole number is an
encoder's counts per revolution, and ``q`` is then taken as exactly ``2 pi / counts``.

Examples
--------
>>> import numpy as np
>>> t = np.arange(6000) / 1000.0
>>> theta = 0.3 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t)
>>> enc = detect_quantization(np.round(theta / (2 * np.pi / 4096)) * (2 * np.pi / 4096),
...                           angle=True)
>>> enc.counts_per_revolution, round(enc.floor / 1e-4, 3)
(4096, 4.428)
>>> detect_quantization(theta) is None  # noise-free floats
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Quantization", "detect_quantization"]

#: A sample is on the lattice when it is within this fraction of a step of a level.
LATTICE_TOL = 0.05
#: Share of the samples that must be on the lattice.
MIN_ON_LATTICE = 0.99
#: Distinct levels needed at least (two or three values make any signal a "lattice").
MIN_LEVELS = 8
#: Share of the lattice levels between the extremes that the signal must visit.
MIN_OCCUPANCY = 0.2
#: ``2 pi / q`` within this of a whole number is read as counts per revolution.
COUNTS_TOL = 1e-3


@dataclass(frozen=True)
class Quantization:
    """A signal's lattice.

    Attributes
    ----------
    step : float
        The step ``q`` (signal units).
    offset : float
        The lattice's offset: the levels are ``offset + k * step`` (``|offset| <= step / 2``).
    levels : int
        Distinct levels the signal visits.
    on_lattice : float
        Share of the samples on the lattice.
    counts_per_revolution : int or None
        ``2 pi / step`` when the signal is an angle in rad and that is a whole number.
    """

    step: float
    offset: float
    levels: int
    on_lattice: float
    counts_per_revolution: int | None = None

    @property
    def floor(self) -> float:
        """RMS of the quantization error, ``step / sqrt(12)`` (uniform over one step)."""
        return self.step / math.sqrt(12.0)

    def to_dict(self) -> dict:
        """The ``results.json`` form: ``step``, ``counts_per_revolution``, ``floor``,
        ``offset``, ``levels``, ``on_lattice``."""
        return {
            "step": self.step,
            "counts_per_revolution": self.counts_per_revolution,
            "floor": self.floor,
            "offset": self.offset,
            "levels": self.levels,
            "on_lattice": self.on_lattice,
        }

    def describe(self) -> str:
        """One line: ``encoder of 4096 counts per revolution (step 0.001534 rad, floor ...)``."""
        if self.counts_per_revolution is not None:
            return (
                f"encoder of {self.counts_per_revolution} counts per revolution (step "
                f"{self.step:.4g} rad, quantization floor q/sqrt(12) = {self.floor:.3g} rad)"
            )
        return f"quantized in steps of {self.step:.4g} (quantization floor {self.floor:.3g})"


def _phase(x: np.ndarray, step: float) -> tuple[float, np.ndarray]:
    """Offset (circular mean of the positions within a step) and each sample's distance
    from its level, in steps."""
    frac = np.mod(x / step, 1.0)
    ang = float(np.angle(np.mean(np.exp(2j * np.pi * frac))))
    off = ang / (2 * np.pi)
    r = x / step - off
    return off * step, r - np.round(r)


def detect_quantization(x: np.ndarray, angle: bool = False) -> Quantization | None:
    """The lattice a signal's values lie on, or None when they do not (see the module).

    Parameters
    ----------
    x : array_like
        The recorded signal (any order; NaN and inf are ignored).
    angle : bool
        The signal is an angle in rad: report the counts per revolution.

    Returns
    -------
    Quantization or None
        None when the signal is not on a lattice (noise-free or noisy floats, too few
        distinct values, a lattice only a float format makes).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x = np.cumsum(rng.normal(size=5000))  # a random walk
    >>> q = detect_quantization(0.25 + 0.01 * np.round(x))  # on a lattice with an offset
    >>> round(q.step, 12), round(q.offset, 12), q.counts_per_revolution
    (0.01, 0.0, None)
    >>> detect_quantization(x) is None
    True
    """
    v = np.asarray(x, dtype=np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size < MIN_LEVELS:
        return None
    u = np.unique(v)
    span = float(u[-1] - u[0])
    if u.size < MIN_LEVELS or span <= 0.0:
        return None
    d = np.diff(u)
    d = d[d > 1e-12 * max(span, float(np.max(np.abs(u))))]
    if d.size < MIN_LEVELS - 1:
        return None
    small = d[d <= 1.5 * np.quantile(d, 0.1)]
    q = float(np.median(small))
    k = np.round(d / q)
    ok = (k >= 1) & (k <= 3) & (np.abs(d / q - k) <= LATTICE_TOL)
    if not ok.any():
        return None
    q = float(np.sum(d[ok]) / np.sum(k[ok]))
    if not (q > 0 and span / q >= MIN_LEVELS - 1):
        return None
    off, r = _phase(v, q)
    on = np.abs(r) <= LATTICE_TOL
    if np.mean(on) < MIN_ON_LATTICE:
        return None
    # least squares of the samples on the lattice: x = offset + q * level
    lev = np.round((v[on] - off) / q)
    lev -= lev.min()
    n_levels = np.unique(lev).size
    if n_levels < MIN_LEVELS or n_levels < MIN_OCCUPANCY * (lev.max() + 1):
        return None
    a = np.column_stack([np.ones(lev.size), lev])
    q = float(np.linalg.lstsq(a, v[on], rcond=None)[0][1])
    counts = None
    if angle:
        c = 2 * np.pi / q
        if abs(c - round(c)) <= COUNTS_TOL:
            counts = int(round(c))
            q = 2 * np.pi / counts
    off, r = _phase(v, q)
    on_share = float(np.mean(np.abs(r) <= LATTICE_TOL))
    return Quantization(float(q), float(off), int(n_levels), on_share, counts)
