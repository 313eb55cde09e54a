"""Checks of a dataset before anything is fitted.

:func:`validate` raises a one-line :class:`~hystdisc.errors.HystdiscError` naming the file,
the run, the problem and the fix: missing signals, unequal lengths, NaN/inf, too few
samples, time that does not increase, irregular sampling, a run that never moves or a
locked damper, too few distinct currents. A clipped sensor, a release that does not
decay and a column whose magnitudes are implausible for its unit
(:mod:`hystdisc.data.plausibility`) are warned about
(:class:`~hystdisc.errors.HystdiscWarning`).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from hystdisc import registry
from hystdisc.data.dataset import COLUMN_FLAG, Dataset, Run, distinct_currents
from hystdisc.data.plausibility import ImplausibleUnitsWarning, implausible_units
from hystdisc.data.preprocessing import estimate_noise
from hystdisc.data.text import check_finite
from hystdisc.errors import HystdiscWarning, input_error

__all__ = ["LOCKED_RATIO", "MIN_SAMPLES", "check_one_current", "validate"]

MIN_SAMPLES = 20
"""Shortest run :func:`validate` accepts."""

#: a run whose angle varies less than this many noise standard deviations is locked
LOCKED_RATIO = 3.0
#: samples needed for the motion checks (the noise estimate needs 26)
_MOTION_MIN = 26


def validate(dataset: Dataset, need_currents: int = 1) -> Dataset:
    """Check a dataset; raise a one-line HystdiscError naming the run and the fix on a problem.

    Checks, per run: required signals present (torque for driven, input for forced), equal
    lengths, no NaN/inf (naming the column and the first bad line or sample), at least
    :data:`MIN_SAMPLES` samples, strictly increasing time, regular sampling (every step
    within 1 % of the median step), a run that moves. Per dataset: at least one run, unique
    run names, at least ``need_currents`` distinct currents (see :func:`distinct_currents`).

    Parameters
    ----------
    dataset : Dataset
        The data to check.
    need_currents : int
        Number of distinct currents the caller needs (2 or more to identify the current
        dependence of a model).

    Returns
    -------
    Dataset
        The same object, for chaining.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(100) * 1e-3
    >>> ds = Dataset([Run("a", t, np.sin(50 * t), 0.5)], "release", "x.csv")
    >>> validate(ds) is ds
    True
    >>> validate(ds, need_currents=2)
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: x.csv: a single current (0.5 A) where 2 are needed; fix: ...
    """
    # huge values may overflow in the checks (std, differences); every check below tests
    # finiteness itself, so numpy's overflow warnings would only be noise for the user
    with np.errstate(all="ignore"):
        return _validate(dataset, need_currents)


def _validate(dataset: Dataset, need_currents: int) -> Dataset:
    if not isinstance(dataset, Dataset):
        raise input_error(
            None,
            f"expected a Dataset, got {type(dataset).__name__}",
            "load data with hystdisc.data.load",
        )
    source = dataset.source
    if not dataset.runs:
        raise input_error(source, "holds no runs", "point to a file that holds the measured data")
    exp = registry.get_experiment(dataset.experiment)
    seen: set[str] = set()
    for run in dataset.runs:
        src = run.source or source
        if run.name in seen:
            raise input_error(
                src,
                f"two runs are named {run.name!r}",
                "give every run its own id in the run column",
                run=run.name,
            )
        seen.add(run.name)
        _check_signals(run, src, exp)
        _check_time(run, src)
        _check_moves(run, src, exp)
        _check_motion(run, src, exp)
    _check_currents(dataset, need_currents)
    _check_units(dataset)
    return dataset


#: Runs that start alike (release angle, sine amplitude and frequency) within this
#: relative tolerance must repeat when they share a current.
SAME_START = 0.02
#: Two such runs "clearly differ" when the RMS of their difference exceeds this many
#: times their combined noise and :data:`DIFFER_FRACTION` of the signal's RMS.
DIFFER_NOISE = 10.0
DIFFER_FRACTION = 0.1


def check_one_current(dataset: Dataset, source: str | None = None) -> None:
    """Refuse runs taken at one current (no current column) that clearly differ.

    A file without a current column is read as a rig without a coil: every run at 0 A.
    Runs that start alike (the same release angle, the same imposed sine, the same input
    record, within :data:`SAME_START`) must then repeat each other up to the noise; when
    two of them differ by more than :data:`DIFFER_NOISE` times their noise and
    :data:`DIFFER_FRACTION` of the signal (of a driven test's torque, the part that is not
    elastic), they were not taken at one current (an MR
    damper's runs at several currents, the current column lost), and fitting them at 0 A
    would run for minutes and give a wrong answer.

    Parameters
    ----------
    dataset : Dataset
        Runs read without a current column.
    source : str, optional
        The file named in the message (default ``dataset.source``).

    Raises
    ------
    HystdiscError
        ``FILE: no 'current' column, but runs A and B start alike and differ ...; fix: ...``

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(2000) * 1e-3
    >>> runs = [Run(str(k), t, 0.3 * np.exp(-c * t) * np.cos(20 * t), 0.0)
    ...         for k, c in enumerate((0.5, 0.5, 3.0))]
    >>> check_one_current(Dataset(runs[:2], "release", "same.csv"))
    >>> check_one_current(Dataset(runs, "release", "lost.csv"))
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: lost.csv: no 'current' column, so every run is taken at 0 A, but runs 0 and 2 start alike and then differ by ...
    """
    from hystdisc.data.conditions import driven_signature, relatively_close

    exp = registry.get_experiment(dataset.experiment)
    runs = dataset.runs
    y = [np.asarray(getattr(r, exp.output), dtype=float) for r in runs]
    worst = None
    for a in range(len(runs)):
        for b in range(a + 1, len(runs)):
            ra, rb = runs[a], runs[b]
            n = min(ra.n, rb.n)
            if n < _MOTION_MIN or not relatively_close(ra.t[1] - ra.t[0], rb.t[1] - rb.t[0], 1e-6):
                continue
            if exp.motion_imposed:
                sa, sb = driven_signature(ra.t, ra.theta), driven_signature(rb.t, rb.theta)
                alike = all(relatively_close(p, q, SAME_START) for p, q in zip(sa, sb, strict=True))
            elif exp.has_input:
                ua, ub = np.asarray(ra.input[:n]), np.asarray(rb.input[:n])
                alike = bool(np.sqrt(np.mean((ua - ub) ** 2)) <= SAME_START * np.std(ua))
            else:
                alike = relatively_close(float(ra.theta[0]), float(rb.theta[0]), SAME_START)
            if not alike:
                continue
            d = float(np.sqrt(np.mean((y[a][:n] - y[b][:n]) ** 2)))
            noise = math.hypot(estimate_noise(y[a][:n]), estimate_noise(y[b][:n]))
            scale = math.hypot(_varying(ra, y[a][:n], exp), _varying(rb, y[b][:n], exp))
            scale /= math.sqrt(2)
            if d > DIFFER_NOISE * noise and d > DIFFER_FRACTION * scale:
                if worst is None or d / scale > worst[0]:
                    worst = (d / scale, ra.name, rb.name, d, noise)
    if worst is None:
        return
    rel, na, nb, d, noise = worst
    times = f", {d / noise:.0f}x their noise" if noise > 0 else ""
    raise input_error(
        source or dataset.source,
        f"no 'current' column, so every run is taken at 0 A, but runs {na} and {nb} start "
        f"alike and then differ by {d:.3g} RMS in {exp.output} ({100 * rel:.0f} % of the "
        f"signal{times}), as runs at different coil currents do",
        "add a 'current' column with each run's coil current in A (or map yours with "
        f"{COLUMN_FLAG} current=NAME); if the runs truly share one current, give it as a "
        "column of that value",
    )


def _varying(run: Run, y: np.ndarray, exp: Any) -> float:
    """RMS of the part of ``y`` a current can change: all of a released angle, the torque
    less its elastic part (the best ``a + b theta``) when the motion is imposed."""
    if not exp.motion_imposed:
        return float(np.sqrt(np.mean(y**2)))
    A = np.column_stack([np.ones(y.size), run.theta[: y.size]])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(np.sqrt(np.mean((y - A @ coef) ** 2)))


def _check_units(dataset: Dataset) -> None:
    """One warning per column whose magnitudes are implausible for its declared unit (the
    bounds: :mod:`hystdisc.data.plausibility`); the run goes on, the user may know better,
    and the message names the ``--units`` fix."""
    for message in implausible_units(dataset):
        _warn_unit(message)


def _warn_unit(message: str) -> None:
    warnings.warn(message, ImplausibleUnitsWarning, stacklevel=_STACKLEVEL)


def _where(run: Run, k: int) -> str:
    if run.lines is not None and run.lines.size == run.n:
        return f"line {int(run.lines[k])}"
    return f"sample {k}"


def _check_signals(run: Run, src: str, exp: Any) -> None:
    """The signals the experiment needs are there, equally long, finite and long enough."""
    name, n = run.name, run.n
    extra = exp.extra_column
    if extra is not None and getattr(run, extra) is None:
        raise input_error(
            src,
            f"a {exp.name} experiment needs the measured {extra}, which is missing",
            f"add a {extra!r} column or map yours with {COLUMN_FLAG} {extra}=NAME",
            run=name,
        )
    for key in ("theta", "torque", "input", "theta_dot"):
        arr = getattr(run, key)
        if arr is not None and arr.size != n:
            raise input_error(
                src,
                f"{key} has {arr.size} samples but t has {n}",
                "give every signal one value per time sample",
                run=name,
            )
    _check_finite(run, src)
    if not math.isfinite(run.current):
        raise input_error(
            src,
            f"current is {run.current}",
            "give the run a finite coil current in A",
            run=name,
        )
    if n < MIN_SAMPLES:
        raise input_error(
            src,
            f"run is too short ({n} samples, at least {MIN_SAMPLES} needed)",
            "record longer runs, or check that the run column groups the samples as intended",
            run=name,
        )


def _check_finite(run: Run, src: str) -> None:
    for key in ("t", "theta", "torque", "input", "theta_dot"):
        arr = getattr(run, key)
        if arr is None:
            continue
        check_finite(arr, src, f"column {key!r}", lambda k: f"on {_where(run, k)}", run.name)


def _check_time(run: Run, src: str) -> None:
    """Time increases strictly, in steps within 1 % of the median step."""
    dt = np.diff(run.t)
    if not np.all(np.isfinite(dt)):
        k = int(np.argmax(~np.isfinite(dt)))
        raise input_error(
            src,
            f"time steps overflow on {_where(run, k + 1)} "
            f"(t = {run.t[k + 1]:.10g} s after {run.t[k]:.10g} s)",
            "check the time column and its unit (--units t=...)",
            run=run.name,
        )
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise input_error(
            src,
            f"time does not increase on {_where(run, k + 1)} "
            f"(t = {run.t[k + 1]:.10g} s after {run.t[k]:.10g} s)",
            "sort the samples by time and drop duplicates, or give each record its own run id",
            run=run.name,
        )
    step = float(np.median(dt))
    dev = np.abs(dt - step)
    if dev.max() > 0.01 * step:
        k = int(np.argmax(dev > 0.01 * step))
        raise input_error(
            src,
            f"irregular sampling: the time step ranges from {dt.min():.6g} to {dt.max():.6g} s "
            f"(median {step:.6g} s; first off by more than 1 % on {_where(run, k + 1)})",
            "resample the run onto a uniform time grid (e.g. numpy.interp onto numpy.arange) "
            "before loading",
            run=run.name,
        )


def _check_moves(run: Run, src: str, exp: Any) -> None:
    """The angle, and a measured torque, are not constant."""
    if np.ptp(run.theta) == 0 or np.std(run.theta) < 1e-12:
        raise input_error(
            src,
            "theta never moves (it is constant)",
            "check the column mapping, or remove the run",
            run=run.name,
        )
    if exp.output != "theta" and np.ptp(getattr(run, exp.output)) == 0:
        raise input_error(
            src,
            f"the measured {exp.output} never changes (it is constant)",
            "check the column mapping, or remove the run",
            run=run.name,
        )


def _check_currents(dataset: Dataset, need_currents: int) -> None:
    """At least ``need_currents`` distinct current levels."""
    levels = distinct_currents(dataset.currents)
    if len(levels) >= need_currents:
        return
    shown = ", ".join(f"{c:g}" for c in levels)
    if len(levels) == 1 and levels[0] == 0.0 and len(dataset.runs) > 1:
        problem = (
            f"every run has current 0 A (the current column is all zero) where "
            f"{need_currents} distinct currents are needed"
        )
        raise input_error(
            dataset.source,
            problem,
            f"check the current column ({COLUMN_FLAG} current=NAME) and its unit "
            "(--units current=mA), add runs at other currents, or declare a family with "
            "--model so that only its current-independent part is fitted",
        )
    if len(levels) == 1:
        problem = f"a single current ({shown} A) where {need_currents} are needed"
    else:
        problem = (
            f"only {len(levels)} distinct currents ({shown} A) where {need_currents} are needed"
        )
    raise input_error(
        dataset.source,
        problem,
        "add runs at other currents, or declare a family with --model so that only its "
        "current-independent part is fitted",
    )


# --------------------------------------------------------------------------------------
# faults of the motion
# --------------------------------------------------------------------------------------

#: warnings name the caller of validate(): validate > _validate > _check_motion > _warn_*
_STACKLEVEL = 5


def _check_motion(run: Run, src: str, exp: Any) -> None:
    """Numerical faults of a run's motion: locked, clipped, not decaying.

    A locked damper (the angle never leaves its noise band, and what is left is white) is
    an error naming the run.
    A signal held at its extreme value as by a saturated sensor, and a free release whose
    motion does not decay, are warned about (:class:`~hystdisc.errors.HystdiscWarning`);
    the run is kept as it is.
    """
    if run.n < _MOTION_MIN:
        return
    noise = estimate_noise(run.theta)
    spread = float(np.std(run.theta))
    if spread <= LOCKED_RATIO * noise and _flatness(run.theta) >= 0.3:
        raise input_error(
            src,
            f"theta never moves beyond its noise (std {spread:.3g} against noise "
            f"{noise:.3g}): the damper seems locked in this run",
            "remove the run (or check the column mapping and that the damper was free)",
            run=run.name,
        )
    signals = [("theta", run.theta, noise)]
    measured = None if exp.output == "theta" else getattr(run, exp.output)
    if measured is not None:
        signals.append((exp.output, measured, estimate_noise(measured)))
    for key, x, sd in signals:
        _warn_clipped(run, src, key, x, sd)
    if not exp.motion_imposed and not exp.has_input:  # a free motion must decay
        _warn_no_decay(run, src, noise)


def _warn_clipped(run: Run, src: str, key: str, x: np.ndarray, noise: float) -> None:
    clip = _clipped(x, noise)
    if clip is None:
        return
    side, value, longest, total = clip
    warnings.warn(
        f"{src}, run {run.name}: {key} stays at its {side} {value:.6g} for {longest} "
        f"samples in a row ({total} in all), as a saturated or clipped sensor does; "
        "the run was kept as it is, so the fit is biased there (re-record within the "
        "sensor's range, or cut the clipped part)",
        HystdiscWarning,
        stacklevel=_STACKLEVEL,
    )


def _warn_no_decay(run: Run, src: str, noise: float) -> None:
    ratio = _decay_ratio(run.theta, noise)
    if ratio is None or not ratio > 0.9:
        return
    verb = "grows" if ratio > 1.1 else "does not decay"
    warnings.warn(
        f"{src}, run {run.name}: the motion {verb} (RMS of the last quarter is "
        f"{100 * ratio:.0f} % of the first), which a free release of a damper cannot "
        "do; the run was kept as it is, but its damping parameters will not be "
        "identifiable (check that it is a release, not a driven or forced record)",
        HystdiscWarning,
        stacklevel=_STACKLEVEL,
    )


def _flatness(x: np.ndarray) -> float:
    """Spectral flatness of ``x``: about 0.56 for white noise, near 0 for a signal.

    Guards the locked-damper check against signals that are merely rough at the sample
    level (a tone near the Nyquist frequency looks like noise to :func:`estimate_noise`).
    """
    power = np.abs(np.fft.rfft(x - np.mean(x)))[1:] ** 2
    mean = float(np.mean(power)) if power.size else 0.0
    if not mean > 0:
        return 0.0
    return float(np.exp(np.mean(np.log(np.maximum(power, mean * 1e-30)))) / mean)


def _clipped(x: np.ndarray, noise: float) -> tuple[str, float, int, int] | None:
    """``(side, value, longest stretch, samples)`` when ``x`` looks clipped at an extreme.

    A saturated sensor repeats its limit exactly for as long as the true signal lies
    beyond it. A natural turning point of a quantized signal repeats its level too, but
    only for as long as the curvature allows: the signal moves about four quantization
    steps from the vertex within twice the half-width of the plateau. A plateau at the
    maximum (or minimum) of at least 5 samples whose flank, half a plateau further on, lies
    more than ``10 steps + 6 noise`` away is taken as clipped.
    """
    n = x.size
    for side, value in (("maximum", float(np.max(x))), ("minimum", float(np.min(x)))):
        at = x == value
        total = int(at.sum())
        if total < 5:
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[0], at.view(np.int8), [0]])))
        starts, ends = edges[::2], edges[1::2]
        k = int(np.argmax(ends - starts))
        a, b = int(starts[k]), int(ends[k])
        longest = b - a
        if longest < 5:
            continue
        others = x[~at]
        if others.size == 0:
            continue
        step = float(np.min(np.abs(others - value)))
        if a == 0:  # a release starts at rest: the vertex is the first sample
            probes = [2 * longest] if 2 * longest < n else []
        else:
            half = max(1, longest // 2)
            probes = [i for i in (a - half - 1, b + half) if 0 <= i < n]
        if not probes:
            continue
        drop = min(abs(float(x[i]) - value) for i in probes)
        if drop > 10.0 * step + 6.0 * noise:
            return side, value, longest, total
    return None


def _decay_ratio(theta: np.ndarray, noise: float) -> float | None:
    """RMS of the last quarter over that of the first, if the run holds 4+ oscillations."""
    x = theta - float(np.mean(theta))
    h = 3.0 * noise
    side = np.sign(x) * (np.abs(x) > h)  # crossings with hysteresis: noise does not count
    side = side[side != 0]
    crossings = int(np.count_nonzero(np.diff(side)))
    if crossings < 8:
        return None
    q = theta.size // 4
    first = float(np.std(theta[:q]))
    last = float(np.std(theta[-q:]))
    return last / first if first > 0 else None


# --------------------------------------------------------------------------------------
# noise and trimming
# --------------------------------------------------------------------------------------
