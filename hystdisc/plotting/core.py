"""Plots of hysteresis loops and of measured against simulated runs.

Conventions (those of python-control): every function takes an ``ax=`` (or ``axes=``) to draw
into and returns the :class:`~matplotlib.figure.Figure`; without one it opens a new pyplot
figure. Nothing here calls ``plt.show()`` or changes ``rcParams``.

Examples
--------
>>> import numpy as np
>>> from hystdisc.plotting.core import plot_loops
>>> t = np.linspace(0, 1, 200)
>>> th, w = 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)
>>> fig = plot_loops(t, th, w, 2 * np.tanh(5 * w), current=0.5)
>>> len(fig.axes[0].lines), fig.axes[0].get_xlabel()
(1, 'velocity [rad/s]')
>>> import matplotlib.pyplot as plt; plt.close(fig)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

__all__ = [
    "loops_figure",
    "plot_family_comparison",
    "plot_fit",
    "plot_inclusion",
    "plot_loops",
    "plot_residual_spectrum",
    "plot_runs",
    "plot_selection_path",
]

_XLABEL = {"velocity": "velocity [rad/s]", "displacement": "angle [rad]"}
_YLABEL = {"theta": "angle [rad]", "torque": "torque [N*m]"}


def _new_axes(nrows: int = 1, ncols: int = 1, **kw: Any) -> list[Axes]:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=kw.pop("figsize", None))
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return list(np.asarray(axes).ravel())


def plot_loops(
    t: np.ndarray,
    theta: np.ndarray,
    theta_dot: np.ndarray | None,
    torque: np.ndarray,
    current: float | None = None,
    ax: Axes | None = None,
    kind: str = "velocity",
    label: str | None = None,
    **style: Any,
) -> Figure:
    """Draw one hysteresis loop: torque against velocity or against displacement.

    Parameters
    ----------
    t, theta, theta_dot, torque : array_like
        Samples of the loop (``theta_dot`` may be None: it is then ``np.gradient(theta, t)``).
    current : float, optional
        Coil current, used for the default label ``"<i> A"``.
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.
    kind : {"velocity", "displacement"}
        Horizontal axis: ``theta_dot`` or ``theta``.
    label : str, optional
        Legend label (default from ``current``).
    **style
        Passed to ``Axes.plot`` (color, linestyle, ...).

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    if kind not in _XLABEL:
        raise ValueError(f"kind must be 'velocity' or 'displacement', not {kind!r}")
    theta = np.asarray(theta, dtype=float)
    if theta_dot is None:
        theta_dot = np.gradient(theta, np.asarray(t, dtype=float))
    x = np.asarray(theta_dot if kind == "velocity" else theta, dtype=float)
    if ax is None:
        ax = _new_axes()[0]
    if label is None and current is not None:
        label = f"{current:g} A"
    ax.plot(x, np.asarray(torque, dtype=float), label=label, **style)
    ax.set_xlabel(_XLABEL[kind])
    ax.set_ylabel(_YLABEL["torque"])
    return ax.figure


def _loop_items(loops: Any) -> list[dict[str, Any]]:
    if isinstance(loops, Mapping):
        return [dict(loops)]
    if hasattr(loops, "runs") and hasattr(loops, "experiment"):  # a Dataset with torque
        items = []
        for r in loops.runs:
            if r.torque is None:
                raise ValueError("loops_figure needs torque; this dataset has none (not driven)")
            items.append(
                {
                    "t": r.t,
                    "theta": r.theta,
                    "theta_dot": r.theta_dot,
                    "torque": r.torque,
                    "current": r.current,
                    "label": f"run {r.name}, {r.current:g} A",
                }
            )
        return items
    return [dict(item) for item in loops]


def loops_figure(
    loops: Mapping[str, Any] | Sequence[Mapping[str, Any]] | Any,
    axes: Sequence[Axes] | None = None,
    title: str | None = None,
    legend: bool = True,
) -> Figure:
    """Two panels, torque against velocity (left) and against displacement (right).

    Parameters
    ----------
    loops : dict, list of dicts, or Dataset
        Each loop has ``t, theta, theta_dot, torque`` and optionally ``current``, ``label``
        and ``style`` (a dict for ``Axes.plot``); a driven Dataset gives one loop per run.
    axes : pair of Axes, optional
        Where to draw; a new 1 x 2 figure when omitted.
    title : str, optional
        Figure title.
    legend : bool
        Draw a legend when the loops have labels.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 100)
    >>> loop = {"t": t, "theta": np.sin(6.28 * t), "theta_dot": 6.28 * np.cos(6.28 * t),
    ...         "torque": np.cos(6.28 * t), "label": "a"}
    >>> fig = loops_figure([loop, loop])
    >>> [len(a.lines) for a in fig.axes]
    [2, 2]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    items = _loop_items(loops)
    if axes is None:
        axes = _new_axes(1, 2, figsize=(10, 4))
    if len(axes) != 2:
        raise ValueError(f"loops_figure needs two axes, got {len(axes)}")
    for item in items:
        style = dict(item.get("style") or {})
        for ax, kind in zip(axes, ("velocity", "displacement"), strict=True):
            plot_loops(
                item["t"],
                item["theta"],
                item.get("theta_dot"),
                item["torque"],
                current=item.get("current"),
                ax=ax,
                kind=kind,
                label=item.get("label"),
                **style,
            )
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig = axes[0].figure
    if legend and any(ax.get_legend_handles_labels()[1] for ax in axes):
        axes[0].legend(fontsize="small")
    if title:
        fig.suptitle(title)
    return fig


def _prediction_for(predictions: Any, k: int, name: str, measured: str) -> np.ndarray | None:
    if predictions is None:
        return None
    if isinstance(predictions, Mapping):
        p = predictions.get(name)
    else:
        p = predictions[k]
    if p is None:
        return None
    if hasattr(p, measured) and not isinstance(p, np.ndarray):  # a SimResult
        p = getattr(p, measured)
    return np.asarray(p, dtype=float)


def plot_runs(
    dataset: Any,
    predictions: Sequence[Any] | Mapping[str, Any] | None = None,
    ax: Axes | Sequence[Axes] | None = None,
    label: str = "model",
) -> Figure:
    """Measured signal of every run against time, with the simulated one beside it.

    Parameters
    ----------
    dataset : hystdisc.data.Dataset
        The runs; ``theta`` is drawn (``torque`` for driven datasets).
    predictions : sequence or dict, optional
        One simulated signal per run (arrays, or objects with a ``theta``/``torque``
        attribute such as :class:`~hystdisc.simulation.SimResult`), in run order or keyed
        by run name. Drawn dashed in the colour of the measurement.
    ax : Axes or sequence of Axes, optional
        A single Axes overlays all runs; a sequence gives one Axes per run; by default a
        new figure with one row per run.
    label : str
        Legend label of the predictions.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from hystdisc.simulation.synth import generate
    >>> ds = generate("dahl", currents=(0, 1), duration=1.0)
    >>> fig = plot_runs(ds, predictions=[r.theta for r in ds])
    >>> [len(a.lines) for a in fig.axes]
    [2, 2]
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    runs = list(dataset.runs)
    measured = dataset.measured() if hasattr(dataset, "measured") else "theta"
    if ax is None:
        axes = _new_axes(len(runs), 1, sharex=True, figsize=(8, 1.6 + 1.4 * len(runs)))
    elif isinstance(ax, Axes):
        axes = [ax] * len(runs)
    else:
        axes = list(ax)
        if len(axes) != len(runs):
            raise ValueError(f"{len(axes)} axes for {len(runs)} runs; pass one per run")
    single = len({id(a) for a in axes}) == 1
    for k, (run, a) in enumerate(zip(runs, axes, strict=True)):
        y = getattr(run, measured)
        (line,) = a.plot(run.t, y, lw=0.8, label=f"run {run.name} ({run.current:g} A)")
        p = _prediction_for(predictions, k, run.name, measured)
        if p is not None:
            a.plot(
                run.t,
                p,
                "--",
                color=line.get_color(),
                lw=1.0,
                label=label if (not single or k == 0) else None,
            )
        a.set_ylabel(_YLABEL.get(measured, measured))
        if not single:
            a.legend(fontsize="x-small", loc="upper right")
    axes[-1].set_xlabel("time [s]")
    if single:
        axes[0].legend(fontsize="x-small", loc="upper right")
    return axes[0].figure


# ----------------------------------------------------------------------------- fit and selection


def plot_fit(
    t: np.ndarray,
    measured: np.ndarray,
    simulated: np.ndarray | None = None,
    ax: Axes | None = None,
    residual_ax: Axes | None = None,
    label: str = "model",
    ylabel: str = _YLABEL["theta"],
    title: str | None = None,
    draw_measured: bool = True,
    legend: bool = True,
    **style: Any,
) -> Figure:
    """Measured signal of one run against time, the simulated one over it, and the residual.

    Call it once per model on the same axes to overlay several models (``draw_measured=False``
    after the first).

    Parameters
    ----------
    t, measured : array_like
        Time [s] and the measured signal (angle, or torque of a driven run).
    simulated : array_like, optional
        The model's output on the same samples, drawn dashed.
    ax : Axes, optional
        Where to draw the signals; a new figure (with a residual panel below) when omitted.
    residual_ax : Axes, optional
        Where to draw ``simulated - measured`` (nothing is drawn when None and ``ax`` is given).
    label : str
        Legend label of ``simulated``.
    ylabel : str
        Label of the signal axis.
    title : str, optional
        Title of ``ax``.
    draw_measured : bool
        Draw the measured signal (grey).
    legend : bool
        Draw a legend on ``ax``.
    **style
        Passed to ``Axes.plot`` for the simulated line (and the residual).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 100)
    >>> fig = plot_fit(t, np.sin(6 * t), np.sin(6 * t) + 0.01, label="dahl")
    >>> [len(a.lines) for a in fig.axes], fig.axes[1].get_ylabel()  # residual and its zero
    ([2, 2], 'residual')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(measured, dtype=float)
    if ax is None:
        ax, residual_ax = _new_axes(2, 1, sharex=True, figsize=(8, 4.5), height_ratios=[3, 1])
    if draw_measured:
        ax.plot(t, y, color="0.35", lw=0.8, label="measured")
        if residual_ax is not None:
            residual_ax.axhline(0.0, color="0.6", lw=0.5)
    if simulated is not None:
        p = np.asarray(simulated, dtype=float)
        style = {"ls": "--", "lw": 1.1, **style}
        ax.plot(t, p, label=label, **style)
        if residual_ax is not None:
            rstyle = {k: v for k, v in style.items() if k not in ("ls", "linestyle")}
            rstyle["lw"] = 0.6
            residual_ax.plot(t, p - y, label=label, **rstyle)
    if residual_ax is not None:
        residual_ax.set_ylabel("residual")
        residual_ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    if residual_ax is None:
        ax.set_xlabel("time [s]")
    if title:
        ax.set_title(title, fontsize="medium")
    if legend:
        ax.legend(fontsize="x-small", loc="upper right")
    return ax.figure


def _path_x(thresholds: np.ndarray) -> tuple[np.ndarray, float | None]:
    """Positions on a log axis; a threshold of 0 goes one decade-step left of the smallest."""
    pos = thresholds[thresholds > 0]
    if pos.size == 0:
        return np.ones_like(thresholds), 1.0
    lo = float(pos.min())
    ratio = float(np.exp(np.median(np.diff(np.log(np.unique(pos)))))) if pos.size > 1 else 10.0
    zero_at = lo / max(ratio, 1.5) ** 2 if np.any(thresholds <= 0) else None
    x = np.where(thresholds > 0, thresholds, zero_at if zero_at is not None else lo)
    return x, zero_at


def plot_selection_path(
    path: Sequence[Mapping[str, Any]],
    ax: Axes | Sequence[Axes] | None = None,
    title: str | None = None,
) -> Figure:
    """Term-selection path of the sparse regression: coefficients against the STLSQ threshold.

    Every coefficient is divided by its largest magnitude along the path, so terms of very
    different size (the spring ``theta`` and a damping term) share one axis; a term drops
    to 0 where the threshold removes it. The BIC of each threshold is drawn below (or on a
    second y axis when a single Axes is given) and the threshold with the lowest BIC, the
    one selected, is marked.

    Parameters
    ----------
    path : list of dict
        ``{"threshold", "coefs", "bic"}`` per threshold (``Discovery.stage1_[shape].path``).
        A threshold of 0 (plain least squares) is drawn left of the others, labelled ``0``.
    ax : Axes or pair of Axes, optional
        One Axes (coefficients, BIC on a twin axis), a pair (coefficients, BIC), or None
        for a new two-panel figure.
    title : str, optional
        Title of the coefficient panel.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> path = [{"threshold": 0.0, "coefs": {"z": 1.0, "theta_dot": 0.1}, "bic": -10.0},
    ...         {"threshold": 0.01, "coefs": {"z": 1.0, "theta_dot": 0.1}, "bic": -12.0},
    ...         {"threshold": 0.3, "coefs": {"z": 1.1, "theta_dot": 0.0}, "bic": 5.0}]
    >>> fig = plot_selection_path(path)
    >>> [a.get_xscale() for a in fig.axes], [a.get_label() for a in fig.axes[0].lines[:2]]
    (['log', 'log'], ['z', 'theta_dot'])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if not path:
        raise ValueError("the selection path is empty")
    th = np.array([float(p["threshold"]) for p in path])
    order = np.argsort(th, kind="stable")
    th = th[order]
    steps = [path[k] for k in order]
    bic = np.array([float(p["bic"]) for p in steps])
    names: list[str] = []
    for p in steps:
        names += [k for k in p["coefs"] if k not in names]
    x, zero_at = _path_x(th)
    if ax is None:
        ax_c, ax_b = _new_axes(2, 1, sharex=True, figsize=(8, 5.5), height_ratios=[3, 1.4])
    elif isinstance(ax, Axes):
        ax_c, ax_b = ax, ax.twinx()
    else:
        ax_c, ax_b = list(ax)
    for name in names:
        c = np.array([float(p["coefs"].get(name, 0.0)) for p in steps])
        scale = np.max(np.abs(c))
        ax_c.plot(x, c / scale if scale > 0 else c, marker=".", ms=4, lw=1.2, label=name)
    ax_c.axhline(0.0, color="0.6", lw=0.5)
    ax_c.set_ylabel("coefficient / max |coefficient|")
    ax_c.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    best = int(np.argmin(bic))
    twin = ax_b is not ax_c and isinstance(ax, Axes)
    ax_b.plot(x, bic, color="k", lw=1.0, ls=":" if twin else "-", marker="." if not twin else None)
    ax_b.set_ylabel("BIC (equation error)")
    for a in {id(ax_c): ax_c, id(ax_b): ax_b}.values():
        a.axvline(x[best], color="tab:red", lw=1.0, ls="--")
        a.set_xscale("log")
    ax_b.plot([x[best]], [bic[best]], "o", color="tab:red", ms=5)
    ax_b.annotate(
        f"selected: {th[best]:.3g}" if th[best] > 0 else "selected: 0",
        (x[best], bic[best]),
        textcoords="offset points",
        xytext=(6, 6),
        fontsize="x-small",
        color="tab:red",
    )
    bottom = ax_c if twin else ax_b
    bottom.set_xlabel("STLSQ threshold (normalized columns)")
    if zero_at is not None:
        ticks = [v for v in bottom.get_xticks() if v > zero_at * 1.5]
        bottom.set_xticks([zero_at, *ticks], ["0", *[f"{v:.0e}" for v in ticks]])
        bottom.set_xlim(zero_at / 1.5, x.max() * 1.5)
    if title:
        ax_c.set_title(title, fontsize="medium")
    return ax_c.figure


def plot_inclusion(
    inclusion: Mapping[str, float],
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """Inclusion probability of each library term over bootstrap resamples (horizontal bars).

    Parameters
    ----------
    inclusion : dict
        Term -> probability in [0, 1] (``Discovery(ensemble=True)``: ``stage1_[shape].inclusion``).
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = plot_inclusion({"z": 1.0, "i*z": 0.95, "sign(theta_dot)": 0.1})
    >>> len(fig.axes[0].patches), [float(v) for v in fig.axes[0].get_xlim()]
    (3, [0.0, 1.0])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    if ax is None:
        ax = _new_axes(figsize=(6, 0.8 + 0.35 * max(len(inclusion), 1)))[0]
    names = list(inclusion)
    p = np.array([float(inclusion[k]) for k in names])
    y = np.arange(len(names))[::-1]
    colors = ["tab:blue" if v >= 0.5 else "0.7" for v in p]
    ax.barh(y, p, color=colors)
    ax.set_yticks(y, names)
    ax.set_xlim(0.0, 1.0)
    ax.axvline(0.5, color="0.4", lw=0.6, ls=":")
    ax.set_xlabel("inclusion probability (bagged STLSQ)")
    if title:
        ax.set_title(title, fontsize="medium")
    return ax.figure


def plot_residual_spectrum(
    residuals: np.ndarray | Sequence[np.ndarray],
    fs: float,
    ax: Axes | None = None,
    noise_std: float | None = None,
    dominant_hz: float | None = None,
    label: str | None = None,
    **style: Any,
) -> Figure:
    """Welch spectrum of the output-error residual, averaged over runs.

    Parameters
    ----------
    residuals : array or list of arrays
        The residual of one run or of each run (:func:`hystdisc.closing.diagnostics.residual_spectrum`).
    fs : float
        Sampling rate in Hz.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    noise_std : float, optional
        Estimated measurement noise: its white level ``2 noise_std**2 / fs`` is drawn.
    dominant_hz : float, optional
        A frequency to mark (the dominant frequency of a structured residual).
    label : str, optional
        Legend label of the spectrum.
    **style
        Passed to ``Axes.loglog``.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> fig = plot_residual_spectrum([rng.normal(0, 1e-3, 2000)], 1000.0, noise_std=1e-3)
    >>> len(fig.axes[0].lines), fig.axes[0].get_xscale()
    (2, 'log')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    from hystdisc.closing.diagnostics import residual_spectrum

    if isinstance(residuals, np.ndarray) and residuals.ndim == 1:
        residuals = [residuals]
    f, p, _ = residual_spectrum([np.asarray(r, dtype=float) for r in residuals], fs)
    if ax is None:
        ax = _new_axes(figsize=(7, 3.5))[0]
    sel = (f > 0) & (p > 0)
    ax.loglog(f[sel], p[sel], lw=0.9, label=label, **style)
    if noise_std is not None and noise_std > 0:
        ax.axhline(
            2.0 * noise_std**2 / fs,
            color="0.4",
            lw=0.8,
            ls="--",
            label=f"white noise, std {noise_std:.3g}",
        )
    if dominant_hz is not None and np.isfinite(dominant_hz):
        ax.axvline(dominant_hz, color="tab:red", lw=0.8, ls=":", label=f"{dominant_hz:.3g} Hz")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("PSD [unit^2/Hz]")
    if ax.get_legend_handles_labels()[1]:
        ax.legend(fontsize="x-small")
    return ax.figure


def _family_rows(families: Any) -> dict[str, dict[str, Any]]:
    if hasattr(families, "summary") and callable(families.summary):  # a Results
        families = families.summary()
    if isinstance(families, Mapping) and "families" in families:  # a results.json dict
        families = families["families"]
    rows = {}
    for name, f in dict(families).items():
        get = f.get if isinstance(f, Mapping) else lambda k, d=None, f=f: getattr(f, k, d)
        rows[name] = {"rms": get("rms"), "bic": get("bic"), "heldout_rms": get("heldout_rms")}
    return rows


def plot_family_comparison(
    families: Any,
    ax: Axes | Sequence[Axes] | None = None,
    noise_std: float | None = None,
    selected: str | None = None,
) -> Figure:
    """Output-error RMS (and held-out RMS) of every family, and their BIC differences.

    Parameters
    ----------
    families : dict, Results or results dict
        Family name -> entry with ``rms``, ``bic`` and ``heldout_rms`` (a dict of
        ``results.json``, or the ``OEFit`` objects of ``Discovery.family_fits_``), or a
        :class:`~hystdisc.results.core.Results` / ``results.json`` dict holding ``families``.
    ax : Axes or pair of Axes, optional
        A pair gives RMS bars and BIC-difference bars; a single Axes the RMS bars with the
        BIC differences written above them; None a new two-panel figure.
    noise_std : float, optional
        The noise level, drawn as a line on the RMS panel (a perfect model reaches it).
    selected : str, optional
        Family to highlight.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fams = {"dahl": {"rms": 1.0e-3, "bic": -500.0, "heldout_rms": 1.1e-3},
    ...         "bingham": {"rms": 1.4e-2, "bic": -300.0, "heldout_rms": None}}
    >>> fig = plot_family_comparison(fams, noise_std=1e-3, selected="dahl")
    >>> len(fig.axes), [t.get_text() for t in fig.axes[1].get_xticklabels()]
    (2, ['dahl', 'bingham'])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    rows = _family_rows(families)
    if not rows:
        raise ValueError("no families to compare")
    names = list(rows)
    rms = np.array([float(rows[n]["rms"]) for n in names])
    ho = np.array(
        [np.nan if rows[n]["heldout_rms"] is None else float(rows[n]["heldout_rms"]) for n in names]
    )
    bic = np.array([float(rows[n]["bic"]) for n in names])
    dbic = bic - np.nanmin(bic)
    if ax is None:
        ax_r, ax_b = _new_axes(1, 2, figsize=(10, 3.8))
    elif isinstance(ax, Axes):
        ax_r, ax_b = ax, None
    else:
        ax_r, ax_b = list(ax)
    x = np.arange(len(names))
    has_ho = bool(np.any(np.isfinite(ho)))
    w = 0.38 if has_ho else 0.6
    edge = ["tab:red" if n == selected else "none" for n in names]
    ax_r.bar(x - (w / 2 if has_ho else 0), rms, w, label="RMS (fit)", edgecolor=edge, lw=1.5)
    if has_ho:
        ax_r.bar(x + w / 2, np.nan_to_num(ho), w, label="held-out RMS", color="tab:orange")
    if noise_std is not None and noise_std > 0:
        ax_r.axhline(noise_std, color="0.3", ls="--", lw=0.8, label="noise")
    ax_r.set_yscale("log")
    ax_r.set_xticks(x, names)
    ax_r.set_ylabel("output-error RMS")
    ax_r.legend(fontsize="x-small")
    if ax_b is None:
        for xi, r, d in zip(x, rms, dbic, strict=True):
            ax_r.annotate(
                f"ΔBIC {d:.0f}",
                (xi, r),
                textcoords="offset points",
                xytext=(0, 3),
                ha="center",
                fontsize="x-small",
            )
    else:
        colors = ["tab:red" if n == selected else "tab:blue" for n in names]
        ax_b.bar(x, np.maximum(dbic, 0.5), 0.6, color=colors)
        ax_b.set_yscale("log")
        ax_b.set_xticks(x, names)
        ax_b.set_ylabel("BIC - min BIC (0 shown as 0.5)")
        ax_b.axhline(6.0, color="0.3", ls=":", lw=0.8)
    for a in (ax_r, ax_b):
        if a is not None:
            for lab in a.get_xticklabels():
                lab.set_rotation(20)
    return ax_r.figure
