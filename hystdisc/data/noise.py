"""The measurement, modelled: how much noise the measured signal carries, and of what kind.

Three estimates, per run, of the noise on the measured output (the angle of a release or
forced run, the torque of a driven run):

* **differences** (:func:`~hystdisc.data.estimate_noise`): high-order differences of the
  signal, exact for white noise on a smooth signal; coloured or band-limited noise has
  less power at high frequencies than white noise of the same RMS, so they read it low.
* **period-to-period differences** (:func:`period_noise`): when the run's excitation is
  periodic (a multisine repeated, a driven sine; the period is found by
  :func:`detect_period` on the input of a forced run or the imposed motion of a driven
  one), the steady-state output repeats too, and ``(y(t + P) - y(t)) / sqrt(2)`` is the
  noise alone, whatever its spectrum. The first period (start-up transient) is left out.
* **cycle-to-cycle repeatability** (:func:`cycle_noise`): when the period is no whole
  number of samples (any measured record), the cycles are cut at the motion's upward
  crossings and every sample compared with the mean cycle at its phase: the measurement's
  own floor, what no deterministic model of the motion can fit, also on records filtered
  before they were stored (where differences of neighbouring samples mean nothing).
  These differences are also a *sample of the noise* whose spectrum the residual's
  whiteness is judged against (:func:`hystdisc.closing.diagnostics.noise_whiteness`).
* **quantization floor** (:mod:`~hystdisc.data.quantization`): on a lattice of step
  ``q`` (an encoder) the error is at least ``q / sqrt(12)``, which is used when it is
  above the other estimate.

:func:`measurement_noise` combines them into a :class:`NoiseEstimate`: per run, the
period estimate when there is one, else the cycle estimate, else (a fallback, said to
be one) the differences, raised to the quantization floor; the median over runs is the
noise level the discovery uses.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> t = np.arange(8000) / 1000.0
>>> motion = 0.3 * np.sin(2 * np.pi * 1.0 * t)
>>> detect_period(motion)
1000
>>> y = np.tanh(20 * motion) + rng.normal(0, 0.01, t.size)
>>> round(period_noise(y, 1000)[0] / 0.01, 2)
1.0
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from hystdisc.data.dataset import Run
from hystdisc.data.preprocessing import estimate_noise, screened_rms
from hystdisc.data.quantization import Quantization, detect_quantization
from hystdisc.registry import get_experiment

__all__ = [
    "NoiseEstimate",
    "cycle_noise",
    "cycle_starts",
    "detect_period",
    "measurement_noise",
    "period_noise",
]

#: Periods a record must hold for the period estimate (the first is left out).
MIN_PERIODS = 3
#: A lag is a candidate period when the signal repeats to this fraction of its RMS.
REPEAT_TOL = 0.1


def _lag_mean_square(v: np.ndarray) -> np.ndarray:
    """``mean((v[P:] - v[:-P])**2)`` for every lag ``P`` in ``0..n-1`` (by FFT)."""
    n = v.size
    m = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(v, m)
    r = np.fft.irfft(f * np.conj(f), m)[:n]
    c = np.concatenate([[0.0], np.cumsum(v * v)])
    lag = np.arange(n)
    s = c[n - lag] + (c[n] - c[lag]) - 2.0 * r
    return np.maximum(s, 0.0) / (n - lag)


def detect_period(x: np.ndarray, noise_std: float | None = None) -> int | None:
    """The period of a repeated excitation, in samples, or None.

    The lag ``P`` (at most a :data:`MIN_PERIODS`-th of the record, beyond the signal's
    first decorrelation) at which the signal repeats best; the smallest such lag (the
    fundamental, not a multiple) is taken. It counts only when the signal repeats to
    within its own noise from its second period on (a start-up transient, such as a
    causal filter's, does not repeat): ``rms(x[2P:] - x[P:-P])`` at most ``1.5 sqrt(2)`` times
    ``noise_std`` (or 1e-6 of the signal's RMS for a noise-free input) and at most
    :data:`REPEAT_TOL` of the RMS. A period that is no whole number of samples (a 1.3 Hz
    sine at 1 kHz) does not repeat to that accuracy and gives None.

    Parameters
    ----------
    x : array_like
        The excitation: the input of a forced run, the imposed motion of a driven run.
    noise_std : float, optional
        Its noise (default: :func:`~hystdisc.data.estimate_noise`).

    Returns
    -------
    int or None

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> u = np.tile(rng.normal(size=512), 4)  # a random signal repeated four times
    >>> detect_period(u)
    512
    >>> detect_period(rng.normal(size=2048)) is None
    True
    """
    v = np.asarray(x, dtype=np.float64).reshape(-1)
    n = v.size
    if n < 3 * MIN_PERIODS or not np.all(np.isfinite(v)):
        return None
    v = v - v.mean()
    var = float(np.mean(v * v))
    if var == 0.0:
        return None
    ms = _lag_mean_square(v)
    hi = n // MIN_PERIODS
    gone = np.flatnonzero(ms[1 : hi + 1] >= var)  # decorrelated: mean square >= 2 var / 2
    if gone.size == 0:
        return None
    lo = int(gone[0]) + 1
    seg = ms[lo : hi + 1]
    if seg.size == 0:
        return None
    best = float(seg.min())
    if best > REPEAT_TOL**2 * var:
        return None
    k = lo + int(np.flatnonzero(seg <= max(2.25 * best, 1e-12 * var))[0])
    while k < hi and ms[k + 1] < ms[k]:  # to the bottom of its dip
        k += 1
    noise = estimate_noise(v) if noise_std is None else float(noise_std)
    # judged from the second period on: a start-up transient (a causal filter's, a
    # ramp's) does not repeat, the steady state does
    rms_diff = float(np.sqrt(np.mean((v[2 * k :] - v[k:-k]) ** 2)))
    if rms_diff > max(1.5 * math.sqrt(2.0) * noise, 1e-6 * math.sqrt(var)):
        return None
    return k


def period_noise(y: np.ndarray, period: int) -> tuple[float, np.ndarray] | None:
    """Noise standard deviation from period-to-period differences of a periodic output.

    ``d = (y[t + P] - y[t]) / sqrt(2)`` from the second period on (the first holds the
    start-up transient) is the noise alone when the steady-state output repeats; its
    5-sigma-screened RMS is returned (:func:`~hystdisc.data.preprocessing.screened_rms`),
    exact for white and coloured noise alike.

    Parameters
    ----------
    y : array_like
        The measured output of a run whose excitation repeats every ``period`` samples.
    period : int
        The period in samples (:func:`detect_period`).

    Returns
    -------
    (float, ndarray) or None
        The noise standard deviation and the differences (a sample of the noise, for its
        spectrum); None when the record holds fewer than :data:`MIN_PERIODS` periods.
    """
    v = np.asarray(y, dtype=np.float64).reshape(-1)
    p = int(period)
    if p < 1 or v.size < MIN_PERIODS * p:
        return None
    d = (v[2 * p :] - v[p:-p]) / math.sqrt(2.0)
    return screened_rms(d), d


def cycle_starts(x: np.ndarray) -> np.ndarray:
    """Fractional sample indices where the motion ``x`` crosses its mean upwards.

    A crossing counts only after the motion has been below ``-h`` and then above ``+h``
    since the last one (``h`` a tenth of its RMS), so noise at a crossing does not split a
    cycle.

    Examples
    --------
    >>> t = np.arange(4000) / 1000.0
    >>> np.round(cycle_starts(np.sin(2 * np.pi * (t - 0.25))), 1)
    array([ 250., 1250., 2250., 3250.])
    """
    v = np.asarray(x, dtype=np.float64).reshape(-1)
    v = v - v.mean()
    h = 0.1 * float(np.sqrt(np.mean(v * v)))
    if h == 0.0:
        return np.zeros(0)
    below = np.flatnonzero(v < -h)
    above = np.flatnonzero(v > h)
    out = []
    i = 0
    while below.size and above.size:
        # the first time above +h after having been below -h: the crossing just before it
        j = int(np.searchsorted(above, below[0]))
        if j == above.size:
            break
        k = int(above[j])
        c = int(np.flatnonzero(v[below[0] : k + 1] <= 0.0)[-1]) + int(below[0])
        out.append(c + v[c] / (v[c] - v[c + 1]))
        i = k
        below = below[below > i]
        above = above[above > i]
    return np.asarray(out)


def cycle_noise(x: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray] | None:
    """The output's cycle-to-cycle repeatability: cycles aligned on the imposed motion.

    The record is cut into cycles at the motion's upward crossings
    (:func:`cycle_starts`); every cycle from the second on (the first holds the start-up
    transient) is sampled at the same fractions of its length (linear interpolation), and
    every sample's deviation from the mean cycle at its phase, times ``sqrt(K / (K - 1))``
    for ``K`` cycles, is what no deterministic model of the motion can fit: the noise, filtered or
    not, plus what does not repeat. Unlike :func:`period_noise` it needs no period of a
    whole number of samples, so it holds for measured records (a rig's sine is never
    exactly a whole number of samples long). Its 5-sigma-screened RMS is returned.

    Parameters
    ----------
    x : array_like
        The imposed motion (or the input) of the run.
    y : array_like
        The measured output.

    Returns
    -------
    (float, ndarray) or None
        The repeatability (a standard deviation, data units) and the deviations (a sample
        of what does not repeat, in phase order cycle after cycle); None when there are
        fewer than :data:`MIN_PERIODS` cycles, or when the cycles differ in length by more
        than 5 %. Cycles whose motion does not repeat the median cycle's to
        :data:`REPEAT_TOL` of its RMS (a ramp, a stop) are left out; None when fewer than
        two are left.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(9000) / 1000.0
    >>> x = np.sin(2 * np.pi * 0.77 * t)  # 1298.7 samples a cycle
    >>> y = np.tanh(5 * np.cos(2 * np.pi * 0.77 * t)) + rng.normal(0, 0.02, t.size)
    >>> round(cycle_noise(x, y)[0] / 0.02, 1)
    1.0
    """
    xv = np.asarray(x, dtype=np.float64).reshape(-1)
    yv = np.asarray(y, dtype=np.float64).reshape(-1)
    if xv.size != yv.size or not (np.all(np.isfinite(xv)) and np.all(np.isfinite(yv))):
        return None
    c = cycle_starts(xv)
    if c.size < MIN_PERIODS + 1:  # MIN_PERIODS whole cycles
        return None
    c = c[1:]  # the first cycle holds the start-up transient
    lengths = np.diff(c)
    m = int(round(float(np.median(lengths))))
    if m < 8 or np.max(np.abs(lengths / np.median(lengths) - 1.0)) > 0.05:
        return None
    idx = np.arange(xv.size, dtype=np.float64)
    grid = c[:-1, None] + lengths[:, None] * (np.arange(m) / m)[None, :]
    # cycles whose motion departs from the median cycle (a ramp at the end of a test, a
    # stop) are left out; the others must repeat to REPEAT_TOL of the motion's RMS
    xs = np.interp(grid, idx, xv)
    dev = np.sqrt(np.mean((xs - np.median(xs, axis=0)) ** 2, axis=1))
    keep = dev <= REPEAT_TOL * np.sqrt(np.mean((xv - xv.mean()) ** 2))
    k = int(keep.sum())
    if k < MIN_PERIODS - 1:
        return None
    # the mean cycle on the phase grid (cubic: a linear interpolation's error at a sharp
    # corner of a hysteresis loop would read as noise)
    mean = CubicSpline(idx, yv)(grid[keep]).mean(axis=0)
    # every sample of the kept cycles against the mean cycle at its own phase (sampling
    # the cycles on a common grid instead would average neighbouring samples' noise)
    i = np.arange(int(np.ceil(c[0])), int(np.floor(c[-1])) + 1)
    i = i[i < yv.size]
    cyc = np.clip(np.searchsorted(c, i, side="right") - 1, 0, lengths.size - 1)
    i, cyc = i[keep[cyc]], cyc[keep[cyc]]
    phase = (i - c[cyc]) / lengths[cyc] * m
    ref = CubicSpline(np.arange(m + 1), np.append(mean, mean[0]), bc_type="periodic")(phase)
    d = (yv[i] - ref) * math.sqrt(k / (k - 1.0))
    return screened_rms(d), d


@dataclass
class NoiseEstimate:
    """The noise on the measured output, how it was estimated, and the encoder.

    Attributes
    ----------
    std : float
        The noise standard deviation the discovery uses (data units): the median over runs
        of each run's estimate.
    method : str
        How most runs were estimated: ``"period"`` (period-to-period differences),
        ``"cycles"`` (cycle-to-cycle repeatability, cycles aligned on the motion),
        ``"differences"`` (high-order differences, white noise: the fallback when no run
        repeats) or ``"quantization"``
        (the quantization floor ``q / sqrt(12)``, above the other estimate).
    signal : str
        The measured output (``theta`` or ``torque``).
    differences : float
        The median over runs of the difference estimate (what earlier versions used).
    runs : list of dict
        Per run: ``name``, ``differences``, ``period`` (estimate or None),
        ``period_samples``, ``cycles`` (repeatability or None), ``floor`` (quantization
        floor or None), ``used``, ``method``.
    encoder : Quantization or None
        The lattice of the angle (``theta``) shared by the runs: an encoder's step and
        counts per revolution; None when the angle is not quantized.
    output_quantization : Quantization or None
        The lattice of the measured output (the encoder for release and forced runs).
    samples : list of ndarray
        Period-to-period differences over ``sqrt(2)`` or deviations from the mean cycle:
        samples of the noise, for its spectrum (empty without a periodic run).
    """

    std: float
    method: str
    signal: str
    differences: float
    runs: list[dict] = field(default_factory=list)
    encoder: Quantization | None = None
    output_quantization: Quantization | None = None
    samples: list[np.ndarray] = field(default_factory=list, repr=False)

    @property
    def pooled(self) -> float | None:
        """The runs' repeatability pooled (RMS over the runs with a period or cycle
        estimate), None when no run repeats."""
        vals = [r["used"] for r in self.runs if r["method"] in ("period", "cycles")]
        return float(np.sqrt(np.mean(np.square(vals)))) if vals else None

    @property
    def period(self) -> float | None:
        """Median over the periodic runs of the period estimate (None: no periodic run)."""
        vals = [r["period"] for r in self.runs if r["period"] is not None]
        return float(np.median(vals)) if vals else None

    def to_dict(self) -> dict:
        """The ``results.json`` form (``noise`` key): ``std``, ``method``, ``signal``,
        ``differences``, ``period``, ``quantization_floor`` and ``runs``."""
        floor = self.output_quantization.floor if self.output_quantization else None
        return {
            "std": self.std,
            "method": self.method,
            "signal": self.signal,
            "differences": self.differences,
            "period": self.period,
            "pooled": self.pooled,
            "quantization_floor": floor,
            "runs": [dict(r) for r in self.runs],
        }

    def describe(self) -> str:
        """One line: the level and how it was estimated."""
        n_per = sum(r["period"] is not None for r in self.runs)
        n_cyc = sum(r.get("cycles") is not None for r in self.runs)
        how = {
            "period": (
                f"period-to-period differences ({n_per} of {len(self.runs)} runs periodic; "
                f"high-order differences give {self.differences:.3g})"
            ),
            "cycles": (
                f"the output's cycle-to-cycle repeatability ({n_cyc} of {len(self.runs)} runs, "
                f"cycles aligned on the motion; high-order differences give "
                f"{self.differences:.3g})"
            ),
            "differences": (
                "high-order differences (white noise assumed; a fallback: no run repeats)"
            ),
            "quantization": (
                f"the quantization floor q/sqrt(12) (differences give {self.differences:.3g})"
            ),
        }[self.method]
        return f"noise {self.std:.3g} from {how}"


def _reference(run: Run, exp) -> np.ndarray | None:
    if exp.has_input:
        return run.input
    if exp.motion_imposed:
        return run.theta
    return None


def _common(qs: Sequence[Quantization | None]) -> Quantization | None:
    """The lattice most runs share (same step within 1e-6), or None when most have none."""
    found = [q for q in qs if q is not None]
    if len(found) * 2 < len(qs) or not found:
        return None
    steps = Counter(round(q.step, int(6 - math.floor(math.log10(q.step)))) for q in found)
    step = steps.most_common(1)[0][0]
    return next(q for q in found if abs(q.step - step) <= 1e-6 * step)


def measurement_noise(runs: Sequence[Run], experiment) -> NoiseEstimate:
    """The noise on the measured output of ``runs`` (see the module).

    Parameters
    ----------
    runs : sequence of Run
        The runs of one dataset.
    experiment : str or Experiment
        Their experiment type: what is measured, and what repeats.

    Returns
    -------
    NoiseEstimate

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(6000) / 1000.0
    >>> q = 2 * np.pi / 4096
    >>> theta = np.round(0.3 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t) / q) * q
    >>> est = measurement_noise([Run("0", t, theta, 0.0)], "release")
    >>> est.method, est.encoder.counts_per_revolution, round(est.std / 1e-4, 3)
    ('quantization', 4096, 4.428)
    """
    exp = get_experiment(experiment)
    out = exp.output
    rows: list[dict] = []
    samples: list[np.ndarray] = []
    out_q: list[Quantization | None] = []
    theta_q: list[Quantization | None] = []
    for r in runs:
        y = np.asarray(getattr(r, out), dtype=np.float64)
        diff = estimate_noise(y, r.fs)
        ref = _reference(r, exp)
        period = detect_period(ref) if ref is not None else None
        per = period_noise(y, period) if period is not None else None
        cyc = cycle_noise(ref, y) if ref is not None and per is None else None
        tq = detect_quantization(r.theta, angle=True)
        oq = tq if out == "theta" else detect_quantization(y)
        theta_q.append(tq)
        out_q.append(oq)
        if per is not None:
            est, method = per[0], "period"
        elif cyc is not None:
            est, method = cyc[0], "cycles"
        else:
            est, method = diff, "differences"
        floor = oq.floor if oq is not None else None
        if floor is not None and floor > est:
            est, method = floor, "quantization"
        if per is not None or cyc is not None:
            samples.append(per[1] if per is not None else cyc[1])
        rows.append(
            {
                "name": r.name,
                "differences": diff,
                "period": None if per is None else per[0],
                "period_samples": period if per is not None else None,
                "cycles": None if cyc is None else cyc[0],
                "floor": floor,
                "used": est,
                "method": method,
            }
        )
    counts = Counter(row["method"] for row in rows)
    order = {"period": 0, "cycles": 1, "quantization": 2, "differences": 3}
    method = min(counts, key=lambda m: (-counts[m], order[m])) if rows else "differences"
    return NoiseEstimate(
        std=float(np.median([row["used"] for row in rows])) if rows else 0.0,
        method=method,
        signal=out,
        differences=float(np.median([row["differences"] for row in rows])) if rows else 0.0,
        runs=rows,
        encoder=_common(theta_q),
        output_quantization=_common(out_q),
        samples=samples,
    )
