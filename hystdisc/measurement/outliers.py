"""Isolated glitches of a sensor (single-sample spikes): found, left out, reported.

A glitch is a sample (or two in a row, at most :data:`MAX_GLITCH`) that disagrees with
its neighbours while they agree with each other. Each sample is compared with its
*leave-one-out* prediction: a cubic fitted by least squares to its :data:`HALF` nearest
neighbours on each side (the sample itself and samples already flagged left out). On a
signal smooth at the sampling scale the prediction error is the noise times the
prediction's gain ``g = sqrt(1 + sum w^2)`` (about 1.1 inside a record, up to ~2 at its
ends, where the neighbours lie on one side); a sample whose error exceeds
:data:`THRESHOLD` (7) times ``g`` times the noise standard deviation is a candidate. A candidate is a glitch only if it also stands out of its neighbourhood (the
threshold is taken on the larger of the noise and the robust scale of its neighbours'
errors, so a signal bending faster than the samples follow is not flagged) and disagrees
with the quadratic extrapolation of each side (:data:`ONE_SIDED`; a kink agrees with one).
Candidates are taken one local maximum at a time, each left out of its neighbours'
predictions before they are judged again, so that one spike never makes its neighbours
look wrong. A group of more than :data:`MAX_GLITCH` consecutive candidates is not a
glitch but a feature of the signal (a step in a torque, a stick-slip transition): it is
kept, and so are the samples within :data:`HALF` of it.

Why a screen of the data and not of a fit's residual: stage 1 differentiates the angle,
and a 50-sigma spike smeared over a smoothing window poisons its derivatives before any
fit exists. The screen runs on the measured signals first (the angle, and the driven
torque), the glitches are replaced by their local prediction for stage 1 and left out of
the output-error residual (:attr:`FitData.mask <hystdisc.fitting.FitData>`); after the
selected family is fitted, :func:`confirm` keeps as outliers only those the model does
not explain either (a sample the model reproduces is a feature, and enters the fit again).

Limits: two glitches within :data:`HALF` samples of each other raise each other's local
scale and may both be kept (with 6 glitches in 30 000 samples this happens to about one
dataset in 250); a glitch within :data:`HALF` samples of a fast bend of the signal is kept
with it.

False alarms: a Gaussian sample exceeds 7 sigma with probability 2.6e-12, one in 1e6
records of 30 000 samples; a quantized signal's error is bounded well below the threshold
(its noise is uniform). Detection: a glitch larger than about 10 noise standard deviations is
found (the one-sided test's 4 x 2.4). Measured: no sample flagged in 4.5 million samples of
clean release data (6 families x 20 seeds, 1 mrad noise), nor in the 30 measured MR
damper runs and the Bouc-Wen benchmark record (404 000 samples); every one of 180
spikes of 50 noise std found at its sample.

Examples
--------
>>> import functools

import numpy as np
>>> rng = np.random.default_rng(0)
>>> t = np.arange(3000) / 1000.0
>>> x = 0.3 * np.exp(-t) * np.cos(2 * np.pi * 2 * t) + rng.normal(0, 1e-3, t.size)
>>> x[[100, 1500, 1510]] += [0.05, -0.02, 0.03]
>>> g = find_glitches(x, 1e-3)
>>> g.index.tolist(), np.round(g.size, 2).tolist()
([100, 1500, 1510], [0.05, -0.02, 0.03])
>>> find_glitches(np.where(t < 1.5, 0.0, 1.0) + rng.normal(0, 1e-3, t.size), 1e-3).index.size
0
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from hystdisc.data import Run

#: Neighbours on each side of a sample that predict it (leave-one-out cubic).
HALF = 4
#: Degree of the local polynomial.
DEGREE = 3
#: A sample is a candidate when its prediction error exceeds this many noise standard
#: deviations (times the prediction's gain).
THRESHOLD = 7.0
#: Samples of each side whose quadratic extrapolation must also disagree with a glitch.
SIDE = 5
#: ... by this many noise standard deviations (times the extrapolation's gain, 2.4).
ONE_SIDED = 4.0
#: Most consecutive samples one glitch may span; a longer group is a feature.
MAX_GLITCH = 2
#: A signal with more candidates than this fraction of its samples is not smooth at the
#: sampling scale: nothing is flagged in it.
MAX_FRACTION = 0.01
#: Floor of the noise scale, relative to the signal's range (no sensor resolves finer; a
#: noise-free simulation still has its integration error).
REL_FLOOR = 1e-6

__all__ = [
    "Glitches",
    "Outliers",
    "confirm",
    "confirm_glitches",
    "find_glitches",
    "screen_runs",
    "screen_signals",
]


@dataclass
class Glitches:
    """The glitches of one signal.

    Attributes
    ----------
    index : ndarray of int
        Their samples.
    size : ndarray
        Each one's deviation from its leave-one-out prediction (data units).
    clean : ndarray
        The signal with each glitch replaced by its prediction.
    features : int
        Samples in groups too long to be glitches (kept as features of the signal).
    """

    index: np.ndarray
    size: np.ndarray
    clean: np.ndarray
    features: int = 0


def _interior_weights() -> np.ndarray:
    off = np.r_[-HALF:0, 1 : HALF + 1] / HALF
    V = np.vander(off, DEGREE + 1, increasing=True)
    return np.linalg.pinv(V)[0]


@functools.lru_cache(maxsize=4096)
def _weights(offsets: tuple[int, ...], degree: int) -> tuple[np.ndarray, float]:
    """Weights of the value at offset 0 of the local polynomial of ``degree`` through the
    samples at ``offsets``, and the gain ``sqrt(1 + |w|^2)`` (a few patterns recur along
    a signal: each is solved once)."""
    V = np.vander(np.array(offsets) / HALF, degree + 1, increasing=True)
    w = np.linalg.pinv(V)[0]
    return w, float(np.sqrt(1.0 + w @ w))


def _loo_at(x: np.ndarray, i: int, out: np.ndarray) -> tuple[float, float]:
    """Prediction of ``x[i]`` from its nearest non-excluded neighbours and its gain."""
    n = x.size
    lo, hi = max(0, i - 3 * HALF), min(n, i + 3 * HALF + 1)
    j = np.arange(lo, hi)
    j = j[(j != i) & ~out[lo:hi]]
    if j.size < DEGREE + 2:
        return np.nan, np.nan
    j = j[np.argsort(np.abs(j - i), kind="stable")[: 2 * HALF]]
    w, gain = _weights(tuple((j - i).tolist()), DEGREE)
    return float(w @ x[j]), gain


def _local_scale(x: np.ndarray, i: int, out: np.ndarray) -> float:
    """Robust scale of the prediction errors of the :data:`HALF` samples on each side of
    ``i`` (each predicted with ``i`` and the flagged samples left out, divided by its
    gain): ``1.4826 * median |e / g|``, the noise std on a signal smooth at the sampling
    scale, larger where the signal itself bends faster than its neighbours can follow."""
    n = x.size
    ex = out.copy()
    ex[i] = True
    errs = []
    for k in range(max(0, i - HALF), min(n, i + HALF + 1)):
        if ex[k]:
            continue
        p, g = _loo_at(x, k, ex)
        if np.isfinite(p):
            errs.append(abs(x[k] - p) / g)
    return 1.4826 * float(np.median(errs)) if errs else np.inf


def _off_both_sides(x: np.ndarray, i: int, out: np.ndarray, level: float) -> bool:
    """``x[i]`` is off the quadratic extrapolation of each side's :data:`SIDE` nearest
    samples by more than ``level`` times that extrapolation's gain (a kink agrees with
    one side; a side without enough samples, at the end of a record, does not object)."""
    n = x.size
    for step in (-1, 1):
        j = np.arange(i + step, i + step * 3 * HALF, step)
        j = j[(j >= 0) & (j < n)]
        j = j[~out[j]][:SIDE]
        if j.size < SIDE:
            continue
        w, gain = _weights(tuple((j - i).tolist()), 2)
        if abs(x[i] - w @ x[j]) <= level * gain:
            return False
    return True


def _loo_all(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out prediction and gain of every sample (nothing excluded)."""
    n = x.size
    w = _interior_weights()
    pred = np.full(n, np.nan)
    gain = np.full(n, np.sqrt(1.0 + w @ w))
    if n > 2 * HALF:
        kern = np.r_[w[:HALF], 0.0, w[HALF:]]
        pred[HALF : n - HALF] = np.correlate(x, kern, mode="valid")
    none = np.zeros(n, dtype=bool)
    for i in [*range(min(HALF, n)), *range(max(HALF, n - HALF), n)]:
        pred[i], gain[i] = _loo_at(x, i, none)
    return pred, gain


def find_glitches(x: np.ndarray, noise_std: float, threshold: float = THRESHOLD) -> Glitches:
    """The isolated glitches of one uniformly sampled signal (see the module docstring).

    Parameters
    ----------
    x : array_like
        The signal.
    noise_std : float
        Its white-noise standard deviation (:func:`hystdisc.data.estimate_noise` is robust
        to the glitches themselves).
    threshold : float
        Candidate level in noise standard deviations of the prediction error.

    Returns
    -------
    Glitches
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    none = Glitches(np.zeros(0, dtype=int), np.zeros(0), x.copy())
    if n < 2 * HALF + 2 or not np.all(np.isfinite(x)):
        return none
    sigma = max(float(noise_std), REL_FLOOR * float(np.ptp(x)), 1e-300)
    pred, gain = _loo_all(x)
    bad = np.zeros(n, dtype=bool)  # flagged glitches (left out of the predictions)
    kept = np.zeros(n, dtype=bool)  # features: never flagged
    for _ in range(max(8, int(MAX_FRACTION * n) + 2)):
        ratio = np.abs(x - pred) / (threshold * sigma * gain)
        ratio[bad | kept | ~np.isfinite(ratio)] = 0.0
        cand = np.flatnonzero(ratio > 1.0)
        if cand.size == 0:
            break
        # the local maxima of the ratio (within HALF) are judged this round: a glitch
        # stands out of its neighbourhood, which is smooth without it (a fast bend of the
        # signal is not: its neighbours' errors are large too)
        new = [i for i in cand if ratio[i] >= ratio[max(0, i - HALF) : i + HALF + 1].max()]
        for i in new:
            scale = max(sigma, _local_scale(x, i, bad))
            if abs(x[i] - pred[i]) > threshold * gain[i] * scale and _off_both_sides(
                x, i, bad, ONE_SIDED * scale
            ):
                bad[i] = True
            else:
                kept[i] = True
        if bad.sum() > MAX_FRACTION * n:
            return Glitches(none.index, none.size, none.clean, int(bad.sum()))
        # groups longer than MAX_GLITCH are features: kept, with their neighbourhood
        edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            if b - a > MAX_GLITCH:
                bad[a:b] = False
                kept[max(0, a - HALF) : b + HALF] = True
        touched = set()
        for i in np.flatnonzero(bad):
            touched.update(range(max(0, i - 3 * HALF), min(n, i + 3 * HALF + 1)))
        for i in sorted(touched):
            pred[i], gain[i] = _loo_at(x, i, bad)
    idx = np.flatnonzero(bad)
    clean = x.copy()
    for i in idx:
        clean[i] = _loo_at(x, int(i), bad)[0]
    return Glitches(idx, x[idx] - clean[idx], clean, int(kept.sum()))


@dataclass
class Outliers:
    """The glitches of a dataset's measured signals (the ``outliers`` of ``results.json``).

    Attributes
    ----------
    items : list of dict
        One per glitch: ``run`` (name), ``signal`` (``theta`` or ``torque``), ``sample``
        (index in the run as measured), ``t`` (s), ``size`` (deviation from the local
        prediction, data units), ``residual`` (measured minus the selected model, when
        it was fitted there; None otherwise), ``fitted`` (the sample lies in the part of
        the run the fit used).
    explained : list of dict
        Candidates the selected model reproduces (features, not glitches: they enter
        the fit again); same keys.
    threshold : float
        The screen's level in noise standard deviations.
    left_out : bool
        The glitches were left out of every fit (False: only reported).
    """

    items: list[dict] = field(default_factory=list)
    explained: list[dict] = field(default_factory=list)
    threshold: float = THRESHOLD
    left_out: bool = True

    @property
    def count(self) -> int:
        """Number of glitches."""
        return len(self.items)

    @property
    def runs(self) -> list[str]:
        """Names of the runs that hold glitches (in data order, once each)."""
        return list(dict.fromkeys(g["run"] for g in self.items))

    def to_dict(self) -> dict:
        """The ``outliers`` table of ``results.json``."""
        return {
            "count": self.count,
            "runs": self.runs,
            "threshold_sigma": self.threshold,
            "left_out": self.left_out,
            "items": [dict(g) for g in self.items],
            "explained": [dict(g) for g in self.explained],
        }

    def summary(self) -> str:
        """One line for the console (``"no outliers"`` when there are none).

        Examples
        --------
        >>> Outliers([{"run": "2", "signal": "theta", "sample": 7, "t": 0.007,
        ...            "size": 0.05, "residual": 0.049, "fitted": True}]).summary()
        'outliers: 1 isolated glitch left out of the fit (run 2: t = 0.007 s, theta +0.05)'
        """
        if not self.items:
            return f"outliers: none (screen at {self.threshold:g} noise std)"
        per = {}
        for g in self.items:
            per.setdefault(g["run"], []).append(
                f"t = {g['t']:.4g} s, {g['signal']} {g['size']:+.3g}"
            )
        shown = "; ".join(f"run {r}: {', '.join(v)}" for r, v in per.items())
        what = "left out of the fit" if self.left_out else "reported only"
        s = "" if self.count == 1 else "es"
        return f"outliers: {self.count} isolated glitch{s} {what} ({shown})"


def screen_signals(
    names: list[str],
    times: list[np.ndarray],
    signals: list[np.ndarray],
    noise_std: float,
    signal: str,
) -> tuple[list[np.ndarray], list[np.ndarray], list[dict]]:
    """Screen one signal of every run.

    Returns
    -------
    clean : list of ndarray
        Each run's signal with its glitches replaced by their local prediction.
    flags : list of ndarray of bool
        Each run's glitch samples.
    items : list of dict
        The glitches (keys of :attr:`Outliers.items`; ``residual`` None, ``fitted`` True).

    Examples
    --------
    >>> t = np.arange(500) / 100.0
    >>> x = np.sin(t) + np.random.default_rng(1).normal(0, 1e-3, t.size)
    >>> x[250] += 0.02
    >>> clean, flags, items = screen_signals(["a"], [t], [x], 1e-3, "theta")
    >>> items[0]["run"], items[0]["sample"], items[0]["t"], round(items[0]["size"], 3)
    ('a', 250, 2.5, 0.02)
    """
    clean, flags, items = [], [], []
    for name, t, x in zip(names, times, signals, strict=True):
        g = find_glitches(x, noise_std)
        clean.append(g.clean)
        f = np.zeros(np.asarray(x).size, dtype=bool)
        f[g.index] = True
        flags.append(f)
        for i, s in zip(g.index, g.size, strict=True):
            items.append(
                {
                    "run": name,
                    "signal": signal,
                    "sample": int(i),
                    "t": float(t[i]),
                    "size": float(s),
                    "residual": None,
                    "fitted": True,
                }
            )
    return clean, flags, items


def confirm(
    items: list[dict],
    names: list[str],
    y: list[np.ndarray],
    predictions: list[np.ndarray],
    noise_std: float,
    threshold: float = THRESHOLD,
) -> tuple[list[dict], list[dict]]:
    """Split the glitches of the output into those the fitted model does not explain
    (outliers) and those it reproduces (features).

    A glitch stays an outlier when its residual (measured minus simulated) exceeds
    ``threshold`` times the larger of ``noise_std`` and the robust scale of the residual
    of the :data:`HALF` * 3 samples on each side (``1.4826 * median |r|``: an imperfect
    model's residual is larger than the noise everywhere, a glitch stands out of it).
    ``y`` and ``predictions`` are each run's measured and simulated output over the
    samples of the fit (a glitch beyond them, in a trimmed tail, stays an outlier with
    ``fitted`` False and ``residual`` None).

    Examples
    --------
    >>> y, p = [np.zeros(30)], [np.zeros(30)]
    >>> y[0][10] = 0.05
    >>> g = {"run": "a", "signal": "theta", "sample": 10, "t": 0.1, "size": 0.05}
    >>> out, feat = confirm([g], ["a"], y, p, 1e-3)
    >>> len(out), len(feat), out[0]["residual"]
    (1, 0, 0.05)
    >>> out, feat = confirm([g], ["a"], y, y, 1e-3)  # the model reproduces it
    >>> len(out), len(feat)
    (0, 1)
    """
    where = {n: k for k, n in enumerate(names)}
    out, feat = [], []
    for g in items:
        k, i = where.get(g["run"]), g["sample"]
        g = dict(g)
        if k is None or i >= y[k].size:
            g["residual"], g["fitted"] = None, False
            out.append(g)
            continue
        r = np.asarray(y[k], dtype=float) - np.asarray(predictions[k], dtype=float)
        g["residual"] = float(r[i])
        near = np.r_[r[max(0, i - 3 * HALF) : i], r[i + 1 : i + 3 * HALF + 1]]
        near = near[np.isfinite(near)]
        local = 1.4826 * float(np.median(np.abs(near))) if near.size else 0.0
        (out if abs(r[i]) > threshold * max(noise_std, local) else feat).append(g)
    return out, feat


def screen_runs(
    runs: list[Run], experiment, noise_std: float, theta_noise: float
) -> tuple[list[Run], list[np.ndarray], list[np.ndarray], list[dict]]:
    """Screen the measured signals of every run (the angle, and the output when it is
    another signal: a driven torque) before anything is fitted.

    Parameters
    ----------
    runs : list of Run
        The runs as measured.
    experiment : Experiment
        Their experiment type (its ``output`` names the fitted signal).
    noise_std, theta_noise : float
        Noise standard deviation of the output and of the angle.

    Returns
    -------
    clean : list of Run
        The runs with every glitch replaced by its local prediction (stage 1 works on them).
    raw_output : list of ndarray
        Each run's output as measured (the output-error fit compares with it).
    flags : list of ndarray of bool
        Each run's output samples that are glitches (left out of the residual).
    items : list of dict
        Every glitch (:attr:`Outliers.items` keys; not yet confirmed by a fit).
    """
    names, times = [r.name for r in runs], [r.t for r in runs]
    raw = [np.asarray(getattr(r, experiment.output), dtype=float) for r in runs]
    th, th_flags, items = screen_signals(
        names, times, [r.theta for r in runs], theta_noise, "theta"
    )
    clean = [dataclasses.replace(r, theta=x) for r, x in zip(runs, th, strict=True)]
    if experiment.output == "theta":
        return clean, raw, th_flags, items
    out, flags, more = screen_signals(names, times, raw, noise_std, experiment.output)
    clean = [
        dataclasses.replace(r, **{experiment.output: x}) for r, x in zip(clean, out, strict=True)
    ]
    return clean, raw, flags, items + more


def confirm_glitches(items: list[dict], data, predictions: list[np.ndarray]) -> Outliers:
    """The outliers of a dataset once the selected family is fitted.

    Glitches of the output the model reproduces (:func:`confirm`) are features: they
    enter the residual again (``data.mask`` is set back in place). Glitches of the angle
    of a driven experiment were replaced in the imposed motion and are reported as such.

    Parameters
    ----------
    items : list of dict
        From :func:`screen_runs`.
    data : FitData
        The runs as the fit saw them (``names``, ``y``, ``mask``, ``noise_std``).
    predictions : list of ndarray
        Each run's simulated output of the selected fit.

    Returns
    -------
    Outliers
    """
    output = data.exp.output
    mine = [g for g in items if g["signal"] == output]
    other = [g for g in items if g["signal"] != output]
    out, feat = confirm(mine, data.names, data.y, predictions, data.noise_std)
    where = {n: k for k, n in enumerate(data.names)}
    for g in feat:
        data.mask[where[g["run"]]][g["sample"]] = True
    order = {n: k for k, n in enumerate(data.names)}
    every = sorted(out + other, key=lambda g: (order.get(g["run"], -1), g["sample"]))
    return Outliers(every, feat)
