"""An undeclared moving average found in the records themselves.

Rigs and their software often smooth the recorded signals with a causal moving average
before the data leave the lab (the UTFSM damper's records went through one of a tenth of
each test's period). A fit that does not know it models the filter's lag as damper
physics, and any noise level read from the smoothed record means nothing. A moving
average of ``L`` samples leaves a mark no damper makes: its response
``sin(pi f L) / (L sin(pi f))`` is zero at every multiple of ``fs / L``, so the noise that
went through it has notches there, between sidelobes.

:func:`detect_window` reads that mark in one channel of one run: the Welch spectrum of
the record's first differences, and for every window ``L`` the median over its notches of
the contrast between the spectrum at the sidelobes half-way between notches and at the
notch (decades). A smooth low-pass (an anti-aliasing or Butterworth filter) has no
notches, and an even multiple of the true window puts half its notches on the true
sidelobes; a divisor ``L/m`` (``m`` odd) reads as well as the true window, so the filter
is the longest odd multiple of the best-read window, when that reads at least
:data:`MIN_CONTRAST`. :func:`detect_filter` does it for every run of a dataset and checks
a periodic run's motion too.

Examples
--------
>>> rng = np.random.default_rng(0)
>>> t = np.arange(20000) / 1000.0
>>> x = np.sin(2 * np.pi * 1.0 * t)
>>> y = np.tanh(4 * np.cos(2 * np.pi * 1.0 * t)) + rng.normal(0, 0.05, t.size)
>>> detect_window(y) is None  # not filtered
True
>>> from hystdisc.measurement.chain import causal_average
>>> detect_window(causal_average(y, 40)).window
40
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import welch

from hystdisc.data.dataset import Dataset, Run
from hystdisc.data.rigs import motion_frequency

#: A window counts as found when its notches lie this many decades (median over its
#: notches) below the sidelobes between them. Unfiltered noise read through a Welch
#: spectrum of at least eight segments varies by about 0.15 decades from bin to bin.
MIN_CONTRAST = 1.0
#: A window is read at this many notches at least (below Nyquist, with a sidelobe on
#: either side): one or two notches of a short window can be a periodic record's even
#: harmonics between its odd ones.
MIN_NOTCHES = 3
#: Of the odd multiples of the best-read window that read to this fraction of its contrast,
#: the longest is the filter.
SAME_CONTRAST = 0.5
#: A record that repeats every whole number of samples to this fraction of its RMS has no
#: noise to read a filter in (a simulation written to 7 digits repeats to about 3e-8).
NOISELESS = 1e-6
#: Runs of one test condition: their motions' frequencies agree to this fraction.
SAME_FREQUENCY = 0.02
#: Runs filtered over one fraction of their period: ``window * f * Ts`` agree to this.
SAME_FRACTION = 0.03
#: The longest window looked for, samples.
MAX_WINDOW = 1000
#: Welch segments at least (the spectrum's resolution is the record's length over this).
MIN_SEGMENTS = 8
#: Bins between a window's notches at least (its notches are resolved).
MIN_BINS_PER_NOTCH = 8


@dataclass
class WindowFound:
    """A moving average read in one channel (:func:`detect_window`).

    Attributes
    ----------
    window : int
        Its length, samples.
    contrast : float
        The median over its notches of sidelobe over notch, decades.
    notches : int
        The notches it was read at.
    """

    window: int
    contrast: float
    notches: int


@dataclass
class FilterFound:
    """A moving average read in a dataset's records (:func:`detect_filter`).

    Attributes
    ----------
    windows : dict of str to int
        Each run's window, samples (runs where none was read are absent).
    channels : list of str
        The channels it was read in (``"torque"`` and, when its motion shows the same
        window, ``"theta"``).
    contrast : dict of str to float
        Each run's contrast in the output, decades.
    inferred : list of str
        Runs whose window was not read in their own records but from the fixed window or
        the period fraction the others share (a short window has too few notches to be
        read).
    missing : list of str
        Runs with no window (their records are not filtered, or too short to tell).
    """

    windows: dict[str, int] = field(default_factory=dict)
    channels: list[str] = field(default_factory=list)
    contrast: dict[str, float] = field(default_factory=dict)
    inferred: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    def table(self) -> dict:
        """The ``[filter]`` table that declares it (:func:`~hystdisc.data.filter_windows`)."""
        return {
            "kind": "moving_average",
            "windows": dict(self.windows),
            "channels": list(self.channels),
        }

    def to_dict(self) -> dict:
        """The JSON form (``results.json``'s ``prefilter``)."""
        return {
            "windows": dict(self.windows),
            "channels": list(self.channels),
            "contrast": dict(self.contrast),
            "inferred": list(self.inferred),
            "missing": list(self.missing),
            "note": self.describe(),
        }

    def describe(self) -> str:
        """One sentence: what was found, where (and the runs where nothing was)."""
        w = sorted(set(self.windows.values()))
        span = f"{w[0]}" if len(w) == 1 else f"{w[0]}-{w[-1]}"
        lo = min(self.contrast.values())
        n, m = len(self.windows), len(self.missing)
        rest = (
            f"; none read in {m} run{'s' if m != 1 else ''} ({', '.join(self.missing[:3])}"
            f"{' ...' if m > 3 else ''}), taken as unfiltered"
            if m
            else ""
        )
        return (
            f"the records went through a causal moving average of {span} samples "
            f"({n} run{'s' if n != 1 else ''}, on {' and '.join(self.channels)}; its notches "
            f"lie {lo:.1f} decades or more below its sidelobes{rest})"
        )


def contrasts(
    r: np.ndarray, max_window: int = MAX_WINDOW, only: int | None = None
) -> dict[int, tuple[float, int]]:
    """Window -> (median contrast in decades, notches) of the signal ``r`` for every window
    the spectrum resolves (see the module docstring); ``only``: that window alone."""
    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r)]
    nper = 1 << int(np.floor(np.log2(max(r.size, 2) * 2 / (MIN_SEGMENTS + 1))))
    if nper < 64:
        return {}
    f, p = welch(r, fs=1.0, nperseg=nper, window="hann", detrend="constant")
    ok = p > 0
    if not ok.any():
        return {}
    logp = np.log10(np.where(ok, p, p[ok].min()))
    out = {}
    longest = min(max_window, nper // MIN_BINS_PER_NOTCH)
    if only is None:
        windows = range(3, longest + 1)
    else:
        windows = [only] if 3 <= only <= longest else []
    for L in windows:
        k = np.arange(1, L)
        notch, lo, hi = k / L, (k - 0.5) / L, (k + 0.5) / L
        use = hi < 0.5 - 2.0 / nper
        if not use.any():
            continue
        nb, lb, hb = (np.rint(v[use] * nper).astype(int) for v in (notch, lo, hi))
        # the notch's deepest bin within one of its frequency (its leakage is symmetric)
        at = np.minimum(np.minimum(logp[nb - 1], logp[nb]), logp[nb + 1])
        side = 0.5 * (logp[lb] + logp[hb])
        out[L] = (float(np.median(side - at)), int(use.sum()))
    return out


def detect_window(y: np.ndarray, max_window: int = MAX_WINDOW) -> WindowFound | None:
    """The causal moving average that the record ``y`` went through, or None (see the
    module docstring).

    Parameters
    ----------
    y : array_like
        The channel looked at.
    max_window : int
        The longest window looked for, samples.

    Returns
    -------
    WindowFound or None
    """
    found = {
        L: cn for L, cn in contrasts(np.diff(np.asarray(y, dtype=float)), max_window).items()
        if cn[1] >= MIN_NOTCHES
    }  # fmt: skip
    if not found:
        return None
    top = max(c for c, _ in found.values())
    if top < MIN_CONTRAST:
        return None
    lead = max(found, key=lambda L: found[L][0])
    # a divisor L/m (m odd) of the true window puts its notches on true notches and its
    # sidelobes on true sidelobes: it reads as well, with fewer notches (an even multiple
    # puts half its notches on sidelobes). The window is the longest odd multiple of the
    # best-read one that still reads to SAME_CONTRAST of it.
    best = max(
        L
        for L, (c, _) in found.items()
        if L % lead == 0 and (L // lead) % 2 and c >= SAME_CONTRAST * top
    )
    return WindowFound(best, *found[best])


def _consensus(runs: Sequence[Run], found: dict[str, WindowFound]) -> tuple[dict, list]:
    """Each run's window from the windows read run by run: a run takes the longest window
    read in a run of its own test condition (the same sampling interval, its motion's
    frequency within :data:`SAME_FREQUENCY`) that is an odd multiple of its own. A run
    where none was read takes the window the others share, when one window was read at
    several motion frequencies, or else the period fraction they share, when they share
    one (``window * f * Ts`` within :data:`SAME_FRACTION` of their median, in at least half
    the runs). Returns the windows by run and the runs whose window was inferred so."""
    freq, ts = {}, {}
    for r in runs:
        t = np.asarray(r.t, dtype=float)
        ts[r.name] = float(np.median(np.diff(t)))
        freq[r.name] = motion_frequency(t, r.theta)

    def same(a: str, b: str) -> bool:
        return abs(ts[a] / ts[b] - 1) < 1e-6 and (
            freq[a] == freq[b] or abs(freq[a] / max(freq[b], 1e-300) - 1) < SAME_FREQUENCY
        )

    out = {}
    for a, got in found.items():
        own = got.window
        out[a] = max(
            w.window for b, w in found.items()
            if same(a, b) and w.window % own == 0 and (w.window // own) % 2
        )  # fmt: skip
    inferred = []
    several = any(not same(a, b) for a in out for b in out)  # test conditions
    if len(set(out.values())) == 1 and several:
        # one window at several test frequencies: a fixed window
        w = next(iter(out.values()))
        for r in runs:
            if r.name not in out:
                out[r.name] = w
                inferred.append(r.name)
        return out, inferred
    frac = {a: w * freq[a] * ts[a] for a, w in out.items() if freq[a] > 0}
    if frac and 2 * len(frac) >= len(runs):
        mid = float(np.median(list(frac.values())))
        if all(abs(v / mid - 1) <= SAME_FRACTION for v in frac.values()):
            for r in runs:
                if r.name not in out and freq[r.name] > 0:
                    out[r.name] = max(1, int(round(mid / (freq[r.name] * ts[r.name]))))
                    inferred.append(r.name)
    return out, inferred


def _noiseless(nu: float, y) -> bool:
    """The record ``y`` repeats exactly, to :data:`NOISELESS` of its RMS, every whole
    number of samples of its motion's period (``1 / nu`` samples; over its second half,
    after the start-up):
    a simulation written without noise. All such a record has is its harmonics, and a
    window's notches and sidelobes can fall on them (a clean Bouc-Wen force and its sine
    motion at 200 samples a cycle read 20 samples). A period that is no whole number of
    samples leaves rounding that does not repeat, and no such mark."""
    p = int(round(1.0 / nu))
    yv = np.asarray(y, dtype=float)
    half = yv.size // 2
    if abs(p * nu - 1.0) > 1e-3 or half <= p:
        return False
    d = yv[-half:] - yv[-half - p : -p]
    scale = float(np.sqrt(np.mean((yv - yv.mean()) ** 2)))
    return float(np.sqrt(np.mean(d**2))) < NOISELESS * scale


def detect_filter(runs: Sequence[Run], output: str = "torque") -> FilterFound | None:
    """The moving average a dataset's records went through, run by run, or None when no
    run's ``output`` shows one.

    Each run's window is read in its ``output`` (:func:`detect_window`) and made
    consistent across the runs (:func:`_consensus`). In a periodic run it counts only
    when the motion shows its notches too (:data:`MIN_CONTRAST` decades): a force with
    sharp corners in a periodic test (Bingham's sign) has strong odd harmonics and no
    even ones, whose lines a window's notches and sidelobes can fall on (an unfiltered
    Bingham set read 9 to 87 samples in its force), while the imposed sine has no such
    harmonics; nor when the run has no noise at all (:func:`_noiseless`). A filter on the
    force alone of a periodic test is therefore not found.
    The motion (``theta``) is listed among the channels when its notches lie at those
    windows (median contrast over the runs at least :data:`MIN_CONTRAST`).
    """
    out = FilterFound()
    found = {}
    on_x = {}
    for r in runs:
        y = getattr(r, output, None)
        if y is None:
            return None
        got = detect_window(y)
        if got is None:
            continue
        c = contrasts(np.diff(np.asarray(r.theta, dtype=float)), only=got.window).get(got.window)
        on_x[r.name] = c[0] if c is not None else -np.inf
        t = np.asarray(r.t, dtype=float)
        nu = motion_frequency(t, r.theta) * float(np.median(np.diff(t)))  # cycles a sample
        if nu > 0 and (not on_x[r.name] >= MIN_CONTRAST or _noiseless(nu, r.theta)):
            continue
        found[r.name] = got
        out.contrast[r.name] = round(got.contrast, 3)
    if not found:
        return None
    out.windows, out.inferred = _consensus(runs, found)
    out.missing = [r.name for r in runs if r.name not in out.windows]
    motion_too = np.median([on_x[a] for a in found]) >= MIN_CONTRAST
    out.channels = [output, "theta"] if motion_too else [output]
    return out


def with_detected_filter(dataset: Dataset) -> tuple[Dataset, FilterFound | None]:
    """``dataset`` with the moving average its records went through declared, when it
    declares none and one is read in them (:func:`detect_filter`; driven experiments, whose
    output is the force), and what was read (None: nothing declared here).

    Examples
    --------
    >>> from hystdisc.data import Dataset, Run
    >>> t = np.arange(4000) / 1000.0
    >>> run = Run("a", t, np.sin(2 * np.pi * t), 0.0, torque=np.cos(2 * np.pi * t))
    >>> with_detected_filter(Dataset([run], "driven"))[1] is None
    True
    """
    if dataset.filter is not None or dataset.measured() != "torque":
        return dataset, None
    found = detect_filter(dataset.runs)
    if found is None:
        return dataset, None
    return Dataset(list(dataset.runs), dataset.experiment, dataset.source, found.table()), found
