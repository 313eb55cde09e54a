"""The model-comparison report: one self-contained HTML file and a Markdown summary beside it.

:func:`write_report` turns a fitted :class:`~hystdisc.estimator.Discovery` into
``report.html`` (figures embedded as base64 PNG, inline CSS, no script and no external
resource, so it opens offline in any browser) and ``report.md`` (the tables, for version
control and issue trackers). The sections, each an ``<h2>`` with the id in
:data:`SECTIONS`:

``summary``
    Input, experiment, discovered structure and equations, selected family, verdict.
``data``
    Runs, currents, samples, noise; the measured signals.
``time-series``
    Measured against simulated output over time, one figure per family, with residuals.
``loops``
    Hysteresis loops, torque against velocity and against displacement per current, data
    and every family overlaid (the seed's figures 15, 16, 23, 24, 30, 31 for the user's
    data). For a release the "measured" damper torque is reconstructed as
    ``-theta'' - k_s theta`` from the smoothed angle and each family's torque is simulated
    with its fitted initial angle; for a driven test it is the measured torque against the
    smoothed imposed motion.
``families``
    RMS, BIC and held-out RMS of every family.
``parameters``
    Each family's parameters with 95 % intervals, identifiability and notes.
``correspondence``
    The seed's section-5 term correspondence (Dahl, Bouc-Wen, LuGre) with fitted values.
``selection``
    Stage 1: the hysteresis shapes compared and the STLSQ term-selection path.
``closing``
    The closing loop: effects tried, before/after RMS, the residual spectrum and whiteness.

Figures are drawn on :class:`matplotlib.figure.Figure` objects (no pyplot state, no change
to ``rcParams``) with the ``ax=`` functions of :mod:`hystdisc.plotting.core`.

Examples
--------
>>> import tempfile, pathlib
>>> from hystdisc.estimator import Discovery
>>> from hystdisc.simulation.synth import generate
>>> data = generate("dahl", currents=(0, 0.5, 1), duration=2.0, seed=1)
>>> disc = Discovery(families=["dahl", "bingham"], heldout=False, close_loop=False).fit(data)
>>> with tempfile.TemporaryDirectory() as d:
...     path = write_report(disc, data, pathlib.Path(d, "report.html"), max_runs=1, dpi=40)
...     html_text = path.read_text()
...     md_text = path.with_suffix(".md").read_text()
>>> all(f'id="{sid}"' in html_text for sid, _ in SECTIONS), "| dahl *" in md_text
(True, True)
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
import textwrap
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc import __version__
from hystdisc.data.io import Dataset, atomic_write_text, estimate_noise
from hystdisc.errors import HystdiscError
from hystdisc.models import FAMILIES

__all__ = [
    "FAMILY_COLORS",
    "SECTIONS",
    "check_report_path",
    "fit_residuals",
    "fit_signals",
    "markdown_path",
    "model_loops",
    "render_report",
    "shown_runs",
    "write_report",
]

#: (id, title) of every section, in order; each is an ``<h2 id=...>`` of the HTML.
SECTIONS: tuple[tuple[str, str], ...] = (
    ("summary", "Summary"),
    ("data", "Data"),
    ("time-series", "Measured and simulated output"),
    ("loops", "Hysteresis loops"),
    ("families", "Family comparison"),
    ("parameters", "Parameters"),
    ("correspondence", "Term correspondence (seed, section 5)"),
    ("selection", "Term selection (stage 1)"),
    ("closing", "Closing the loop"),
)

#: Colours of the families in every figure (the seed's: Dahl blue, Bouc-Wen green, LuGre red).
FAMILY_COLORS = {
    "bingham": "tab:purple",
    "dahl": "tab:blue",
    "lugre": "tab:red",
    "bouc-wen": "tab:green",
    "bouc-wen-std": "tab:olive",
    "discovered": "tab:brown",
    "final": "tab:orange",
}

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0 auto;
max-width:1150px;padding:1em 2em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.3em;border-bottom:1px solid #bbb;margin-top:2em;padding-bottom:.15em}
h3{font-size:1.05em;margin-top:1.3em}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right;vertical-align:top}
th{background:#f0f0f0}td.l,th.l{text-align:left}
tr.sel td{background:#fff6d8;font-weight:600}
pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:.88em}
img{max-width:100%;height:auto;display:block;margin:.6em 0}
.note{color:#555;font-size:.9em}.bad{color:#a00}.good{color:#070}
nav a{margin-right:1em}code{font-size:.92em}
"""


# ----------------------------------------------------------------------------- helpers


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(x: Any, fmt: str = ".4g") -> str:
    if x is None:
        return "–"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(v):
        return "–"
    return format(v, fmt)


def _ci(ci: Any, fmt: str = ".4g") -> str:
    if not ci or len(ci) != 2 or ci[0] is None or ci[1] is None:
        return "–"
    return f"[{_num(ci[0], fmt)}, {_num(ci[1], fmt)}]"


def _md(x: Any) -> str:
    """A Markdown table cell: pipes escaped, one line."""
    return " ".join(str(x).split()).replace("|", "\\|")


def _html_table(
    header: Sequence[str], rows: Sequence[Sequence[Any]], left: int | set[int] = 1, sel=None
) -> str:
    """An HTML table; ``left``: the first n columns, or a set of columns, left-aligned (text);
    ``sel``: indices of highlighted rows."""
    sel = set(sel or ())
    lcols = set(range(left)) if isinstance(left, int) else set(left)

    def cls(k: int) -> str:
        return ' class="l"' if k in lcols else ""

    out = ["<table><tr>"]
    out += [f"<th{cls(k)}>{_e(h)}</th>" for k, h in enumerate(header)]
    out.append("</tr>")
    for i, row in enumerate(rows):
        out.append('<tr class="sel">' if i in sel else "<tr>")
        out += [f"<td{cls(k)}>{_e(c)}</td>" for k, c in enumerate(row)]
        out.append("</tr>")
    out.append("</table>")
    return "".join(out)


def _md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(_md(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(_md(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _new_figure(nrows: int, ncols: int, width: float, height: float, **kw: Any):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def _png(fig, dpi: int) -> str:
    """Render a figure to a base64 ``<img>`` and release it."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    fig.clear()
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="figure">'


def _fit_data(disc):
    fd = getattr(disc, "_fd", None)
    if fd is None:
        raise HystdiscError(
            "this Discovery holds no fitted data (not fitted, or loaded from results.json); "
            "fix: fit it on the dataset before writing a report"
        )
    return fd


def _check_fitted(disc) -> None:
    if not hasattr(disc, "results_") or not hasattr(disc, "family_fits_"):
        raise HystdiscError("this Discovery is not fitted yet; fix: call fit(dataset) first")


def _final_fit(disc):
    """The selected family's fit with accepted effects (None when no effect was accepted)."""
    fit = getattr(disc, "final_fit_", None)
    if fit is None or not getattr(disc, "effects_", None):
        return None
    return fit


def _fits(disc) -> dict[str, Any]:
    """Fits to show: every family, the discovered structure when it is no family, the final."""
    fits = dict(disc.family_fits_)
    dfit = getattr(disc, "discovered_fit_", None)
    if dfit is not None and all(dfit is not f for f in fits.values()):
        fits["discovered"] = dfit
    final = _final_fit(disc)
    if final is not None:
        fits["final"] = final
    return fits


def _fit_label(disc, key: str) -> str:
    if key == "discovered":
        return f"discovered ({disc.discovered_name_})"
    if key == "final":
        return f"{disc.family_} + {' + '.join(disc.effects_)}"
    return key


def _masked(fit, fd) -> list[np.ndarray]:
    return [np.asarray(r)[m] for r, m in zip(fit.residuals, fd.mask, strict=True)]


def _fs(fd) -> float:
    dts = [np.median(np.diff(t)) for t in fd.t if len(t) > 1]
    return float(1.0 / np.median(dts)) if dts else 1.0


# ----------------------------------------------------------------------------- signals


def shown_runs(currents: Sequence[float], max_runs: int = 5) -> list[int]:
    """Indices of the runs to draw: the first run of each current, then the others, in order.

    Examples
    --------
    >>> shown_runs([0, 0, 0.5, 0.5, 1, 1], max_runs=4)
    [0, 2, 4, 1]
    """
    seen: list[float] = []
    first, rest = [], []
    for k, c in enumerate(currents):
        if any(abs(c - s) <= 1e-9 * max(1.0, abs(s)) for s in seen):
            rest.append(k)
        else:
            seen.append(float(c))
            first.append(k)
    return (first + rest)[: max(int(max_runs), 1)]


def fit_signals(disc, runs: Sequence[int] | None = None) -> list[dict[str, Any]]:
    """Measured and simulated output of each run, as fitted.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    runs : sequence of int, optional
        Run indices (default: all).

    Returns
    -------
    list of dict
        Per run: ``name``, ``current``, ``t``, ``measured`` (angle, or torque when driven;
        release runs trimmed as fitted), ``mask`` (samples in the fit) and ``predictions``
        (key -> simulated output; keys are the families, ``"discovered"`` when the
        discovered structure is no family, ``"final"`` with accepted effects).
    """
    _check_fitted(disc)
    fd = _fit_data(disc)
    fits = _fits(disc)
    idx = range(fd.n_runs) if runs is None else runs
    return [
        {
            "name": fd.names[k],
            "current": float(fd.currents[k]),
            "t": fd.t[k],
            "measured": fd.y[k],
            "mask": fd.mask[k],
            "predictions": {key: f.predictions[k] for key, f in fits.items()},
        }
        for k in idx
    ]


def fit_residuals(disc, key: str | None = None) -> list[np.ndarray]:
    """Output-error residual (simulated - measured) of every run, on the fitted samples.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    key : str, optional
        A family, ``"discovered"`` or ``"final"``; default: the final model (with the
        accepted effects) when there is one, else the selected family.

    Returns
    -------
    list of ndarray
        One residual per run (for :func:`hystdisc.plotting.core.plot_residual_spectrum`).
    """
    _check_fitted(disc)
    fd = _fit_data(disc)
    fits = _fits(disc)
    if key is None:
        key = "final" if "final" in fits else disc.family_
    if key not in fits:
        raise HystdiscError(f"no fit named {key!r}; fix: use one of {', '.join(fits)}")
    return _masked(fits[key], fd)


def _simulated_damper(fit, fd, runs: Sequence[int]) -> list[Any]:
    """Simulated theta, theta_dot and damper torque of release/forced runs (SimResults)."""
    from hystdisc.simulation.core import simulate_mech

    nu = np.asarray(fit.nuisance)
    kw: dict[str, Any] = {}
    if fd.experiment == "forced":
        kw = {"inputs": [fd.u[r] for r in runs], "theta_dot0": [nu[r, 1] for r in runs]}
        if nu.shape[1] > 2:
            kw["z0"] = [nu[r, 2] for r in runs]
    out, status = simulate_mech(
        fit.term_model,
        [fd.t[r] for r in runs],
        [float(fd.currents[r]) for r in runs],
        [float(nu[r, 0]) for r in runs],
        raise_on_divergence=False,
        **kw,
    )
    return [None if s else o for o, s in zip(out, status, strict=True)]


def model_loops(
    disc,
    runs: Sequence[int] | None = None,
    fits: Sequence[str] | None = None,
) -> list[dict[str, Any]]:
    """Hysteresis loops of the data and of the fitted models, ready for ``loops_figure``.

    For a driven test the data loop is the measured torque against the smoothed imposed
    motion, and each model's loop its simulated torque on the same motion. For a release
    (or forced) test the damper torque is not measured: the data loop is the torque the
    rig equation implies, ``-theta'' - k_s theta`` (``+ u`` and ``J theta''`` when forced),
    from the smoothed angle and the selected family's ``k_s``; each model's loop is the
    damper torque of its own simulation (fitted initial angle) against its simulated
    velocity and angle.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    runs : sequence of int, optional
        Run indices (default: all).
    fits : sequence of str, optional
        Which fits (default: every family, ``"discovered"`` when it is no family and
        ``"final"`` when effects were accepted).

    Returns
    -------
    list of dict
        Loop dicts (``t, theta, theta_dot, torque, current, label, style``) plus ``run``
        (index) and ``kind`` (``"data"`` or the fit key), data first for every run.
    """
    from hystdisc.discovery.differentiation import differentiate

    _check_fitted(disc)
    fd = _fit_data(disc)
    all_fits = _fits(disc)
    keys = list(all_fits) if fits is None else [k for k in fits if k in all_fits]
    idx = list(range(fd.n_runs)) if runs is None else list(runs)
    loops: list[dict[str, Any]] = []
    sims: dict[str, list[Any]] = {}
    if fd.experiment != "driven" and idx:
        for key in keys:
            sims[key] = _simulated_damper(all_fits[key], fd, idx)
    ref = _final_fit(disc) or disc.family_fits_[disc.family_]
    k_s = float(ref.params.get("k_s", 0.0))
    J = float(ref.params.get("J", 1.0)) if fd.experiment == "forced" else 1.0
    for j, r in enumerate(idx):
        cur = float(fd.currents[r])
        base = {"current": cur, "run": r}
        if fd.experiment == "driven":
            th, w, tq, data_t = fd.theta[r], fd.theta_dot[r], fd.y[r], fd.t[r]
            data_label = f"measured ({cur:g} A)"
        else:
            y = np.asarray(fd.y[r], dtype=float)
            d = differentiate(fd.t[r], y, estimate_noise(y, 1.0 / np.median(np.diff(fd.t[r]))))
            # the smoothed derivatives are unreliable within half a window of the ends
            h = min(d.window // 2 + 1, max(y.size // 4, 0))
            keep = slice(h, y.size - h)
            th, w = d.theta[keep], d.theta_dot[keep]
            tq = -J * d.theta_ddot[keep] - k_s * th
            if fd.experiment == "forced":
                tq = tq + fd.u[r][keep]
            data_t = fd.t[r][keep]
            data_label = f"data: rig equation ({cur:g} A)"
        loops.append(
            {
                **base,
                "t": data_t,
                "theta": th,
                "theta_dot": w,
                "torque": tq,
                "label": data_label,
                "kind": "data",
                "style": {"color": "0.55", "lw": 0.8},
            }
        )
        for key in keys:
            style = {"color": FAMILY_COLORS.get(key, None), "lw": 1.1, "ls": "--"}
            label = _fit_label(disc, key)
            if fd.experiment == "driven":
                item = {
                    "t": fd.t[r],
                    "theta": th,
                    "theta_dot": w,
                    "torque": all_fits[key].predictions[r],
                }
            else:
                sim = sims[key][j]
                if sim is None:
                    continue
                item = {
                    "t": sim.t,
                    "theta": sim.theta,
                    "theta_dot": sim.theta_dot,
                    "torque": sim.torque,
                }
            loops.append({**base, **item, "label": label, "kind": key, "style": style})
    return loops


# ----------------------------------------------------------------------------- sections


class _Report:
    """Collects the HTML and Markdown of every section."""

    def __init__(self, disc, dataset: Dataset, max_runs: int, dpi: int) -> None:
        self.disc = disc
        self.ds = dataset
        self.res = disc.results_._data
        self.fd = _fit_data(disc)
        self.max_runs = max_runs
        self.dpi = dpi
        self.html: list[str] = []
        self.md: list[str] = []
        self.shown = shown_runs(list(self.fd.currents), max_runs)
        self.units = "torque" if self.fd.experiment == "driven" else "theta"

    # -- output helpers
    def h2(self, sid: str) -> None:
        title = dict(SECTIONS)[sid]
        self.html.append(f'<h2 id="{_e(sid)}">{_e(title)}</h2>')
        self.md += ["", f"## {title}", ""]

    def p(self, text: str, md: bool = True, cls: str | None = None) -> None:
        c = f' class="{cls}"' if cls else ""
        self.html.append(f"<p{c}>{_e(text)}</p>")
        if md:
            self.md += [_md_line(text), ""]

    def table(self, header, rows, left: int | set[int] = 1, sel=None, md: bool = True) -> None:
        self.html.append(_html_table(header, rows, left, sel))
        if md:
            self.md += [_md_table(header, rows), ""]

    def figure(self, fig, caption: str | None = None) -> None:
        self.html.append(_png(fig, self.dpi))
        if caption:
            self.html.append(f'<p class="note">{_e(caption)}</p>')

    def pre(self, text: str) -> None:
        self.html.append(f"<pre>{_e(text)}</pre>")
        self.md += ["```", text, "```", ""]

    def shown_note(self) -> str:
        n = self.fd.n_runs
        if len(self.shown) >= n:
            return ""
        return f" (showing {len(self.shown)} of {n} runs: one per current first)"

    # -- sections
    def summary(self) -> None:
        d, disc = self.res, self.disc
        self.h2("summary")
        sel = "declared" if d.get("declared") else "selected"
        rows = [
            ["input", d.get("input", "")],
            ["experiment", d.get("experiment", "")],
            ["runs", f"{self.fd.n_runs} (currents {_currents(self.fd.currents)} A)"],
            ["noise (estimated)", _num(d.get("noise_std"), ".3g")],
            ["discovered structure", d.get("discovered", {}).get("name", "")],
            [f"{sel} family", d.get("family", "")],
        ]
        fin = d.get("final") or {}
        if fin:
            rows.append(
                [
                    "final model",
                    " + ".join([fin.get("family", ""), *fin.get("effects", [])])
                    + f", RMS {_num(fin.get('rms'))}",
                ]
            )
        res = d.get("residual") or {}
        if res:
            rows.append(["residual", _residual_sentence(res)])
        if d.get("unexplained"):
            rows.append(["unexplained", d.get("unexplained_text") or "structure remains"])
        rows.append(["hystdisc", d.get("version", __version__)])
        self.table(["item", "value"], rows, left=2)
        if d.get("equal_fits"):
            self.p(
                f"{', '.join(d['equal_fits'])} fit as well as {d['family']} (BIC within 6): "
                "the data cannot tell them apart; the simpler one is chosen."
            )
        self.html.append("<h3>Discovered equations</h3>")
        self.md += ["### Discovered equations", ""]
        self.pre(disc.equations())

    def data(self) -> None:
        fd, ds = self.fd, self.ds
        self.h2("data")
        meas = ds.measured()
        rows = []
        by_name = {r.name: r for r in ds.runs}
        for k, name in enumerate(fd.names):
            r = by_name.get(name)
            y = fd.y[k]
            rows.append(
                [
                    name,
                    f"{fd.currents[k]:g}",
                    r.n if r is not None else "–",
                    int(np.asarray(fd.mask[k]).sum()),
                    _num(fd.t[k][-1] - fd.t[k][0], ".3g"),
                    _num(1.0 / np.median(np.diff(fd.t[k])), ".4g"),
                    _num(np.ptp(y), ".3g"),
                ]
            )
        self.p(
            f"{len(ds.runs)} {ds.experiment} runs from {ds.source}; measured signal: {meas}; "
            f"estimated measurement noise {_num(self.disc.noise_std_, '.3g')} (data units)."
            + (
                " Release runs are trimmed where the motion has died below the noise."
                if fd.experiment == "release"
                else ""
            )
        )
        self.table(
            ["run", "current [A]", "samples", "fitted", "duration [s]", "fs [Hz]", f"{meas} range"],
            rows,
        )
        from hystdisc.plotting.core import plot_runs

        fig, axes = _new_figure(1, 1, 10, 3.6)
        shown = Dataset([ds.runs[k] for k in range(len(ds.runs))], ds.experiment, ds.source)
        plot_runs(shown, ax=axes[0, 0])
        axes[0, 0].set_title("measured runs", fontsize="medium")
        self.figure(fig)

    def time_series(self) -> None:
        from hystdisc.plotting.core import plot_fit

        self.h2("time-series")
        start = {
            "release": " (release runs from their fitted initial angle)",
            "forced": " (from their fitted initial state, driven by the recorded input)",
            "driven": " (on the recorded motion)",
        }[self.fd.experiment]
        self.p(
            f"Output-error fits: every run simulated with each fitted model{start}, dashed, "
            "over the measurement (grey); right, each model's residual (simulated - "
            "measured)." + self.shown_note(),
            md=False,
        )
        self.md += ["Figures: see the HTML report.", ""]
        signals = fit_signals(self.disc, self.shown)
        if not signals:
            return
        ylabel = "torque" if self.units == "torque" else "angle [rad]"
        # worst fit first, so that the best is drawn on top
        fits = _fits(self.disc)
        keys = sorted(signals[0]["predictions"], key=lambda k: -float(fits[k].rms))
        n = len(signals)
        fig, axes = _new_figure(n, 2, 11, 1.0 + 2.2 * n, width_ratios=[2.2, 1])
        for row, s in enumerate(signals):
            k = _thin(len(s["t"]))
            for j, key in enumerate(keys):
                plot_fit(
                    s["t"][k],
                    s["measured"][k],
                    s["predictions"][key][k],
                    ax=axes[row, 0],
                    residual_ax=axes[row, 1],
                    label=_fit_label(self.disc, key),
                    ylabel=ylabel,
                    title=f"run {s['name']}, {s['current']:g} A",
                    draw_measured=j == 0,
                    legend=False,
                    color=FAMILY_COLORS.get(key),
                )
        _figure_legend(fig, axes[0, 0])
        self.figure(fig)

    def loops(self) -> None:
        from hystdisc.plotting.core import loops_figure

        self.h2("loops")
        if self.fd.experiment == "driven":
            text = (
                "Measured torque against the smoothed imposed velocity and displacement "
                "(grey), with the torque each fitted model simulates on the same motion."
            )
        else:
            eq = (
                "-theta'' - k_s theta"
                if self.fd.experiment == "release"
                else ("u - J theta'' - k_s theta")
            )
            text = (
                f"The damper torque is not measured in a {self.fd.experiment} test: grey is "
                f"the torque the rig equation implies, {eq} from the smoothed angle (k_s"
                f"{'' if self.fd.experiment == 'release' else ' and J'} of the "
                f"{'final' if _final_fit(self.disc) else 'selected'} fit); dashed, each fitted "
                "model's damper torque against its own simulated velocity and angle."
            )
        self.p(text + self.shown_note(), md=False)
        self.md += ["Figures: see the HTML report.", ""]
        loops = model_loops(self.disc, self.shown)
        n = len(self.shown)
        fig, axes = _new_figure(n, 2, 11, 0.6 + 3.0 * n)
        for row, r in enumerate(self.shown):
            items = []
            for lp in loops:
                if lp["run"] != r:
                    continue
                k = _thin(len(lp["t"]))
                lp = {
                    **lp,
                    **{q: np.asarray(lp[q])[k] for q in ("t", "theta", "theta_dot", "torque")},
                }
                if lp["kind"] == "data":
                    lp["label"] = "data"
                items.append(lp)
            loops_figure(items, axes=list(axes[row]), legend=False)
            axes[row, 0].set_title(
                f"run {self.fd.names[r]}, {self.fd.currents[r]:g} A", fontsize="medium"
            )
        _figure_legend(fig, axes[0, 0])
        self.figure(fig)

    def families(self) -> None:
        from hystdisc.plotting.core import plot_family_comparison

        d = self.res
        self.h2("families")
        fams = d["families"]
        noise = d.get("noise_std") or float("nan")
        bmin = min(f["bic"] for f in fams.values() if f.get("bic") is not None)
        rows, sel = [], []
        for i, (name, f) in enumerate(fams.items()):
            if name == d.get("family"):
                sel.append(i)
            rows.append(
                [
                    name + (" *" if name == d.get("family") else ""),
                    f.get("n_params", "–"),
                    _num(f.get("rms")),
                    _num(f["rms"] / noise if f.get("rms") is not None else None, ".3f"),
                    _num(f.get("bic"), ".1f"),
                    _num(f["bic"] - bmin if f.get("bic") is not None else None, ".1f"),
                    _num(f.get("heldout_rms")),
                    ", ".join(f.get("missing_terms") or []) or "–",
                    ", ".join(f.get("extra_terms") or []) or "–",
                    "yes" if f.get("converged", True) else "no",
                ]
            )
        self.p(
            "Every family fitted by output error over all runs jointly; * marks the "
            f"{'declared' if d.get('declared') else 'selected'} family (lowest BIC; within "
            "2 of it, the fewest parameters). RMS in data units; held-out RMS is "
            "leave-one-run-out. 'lacks' lists discovered terms the family does not have, "
            "'adds' the family's terms that were not discovered."
        )
        self.table(
            [
                "family",
                "params",
                "RMS",
                "RMS/noise",
                "BIC",
                "ΔBIC",
                "held-out RMS",
                "lacks",
                "adds",
                "converged",
            ],
            rows,
            left={0, 7, 8},
            sel=sel,
        )
        fig, axes = _new_figure(1, 2, 11, 3.8)
        plot_family_comparison(
            fams, ax=list(axes[0]), noise_std=d.get("noise_std"), selected=d.get("family")
        )
        self.figure(fig, "Left: output-error RMS (and held-out RMS); right: BIC above the best.")

    def parameters(self) -> None:
        d = self.res
        self.h2("parameters")
        self.p(
            "95 % intervals from the Jacobian at the optimum. A parameter is flagged as not "
            "identifiable when its interval is wider than its value or it lies along a "
            "near-singular direction of the Jacobian."
        )
        blocks = list(d["families"].items())
        fin = d.get("final") or {}
        if fin.get("effects"):
            blocks.append((f"{fin['family']} + {' + '.join(fin['effects'])} (final)", fin))
        for name, f in blocks:
            fam = FAMILIES.get(name)
            units = {p.name: p.unit for p in fam.params} if fam else {}
            units.update({"k_s": "N*m/rad per unit J", "J": "kg*m^2"})
            title = name + (f" — {f['normalization']}" if f.get("normalization") else "")
            self.html.append(f"<h3>{_e(title)}</h3>")
            self.md += [f"### {_md(title)}", ""]
            rows = [
                [
                    k,
                    _num(p.get("value"), ".6g"),
                    _ci(p.get("ci95"), ".5g"),
                    units.get(k, ""),
                    "yes" if p.get("identifiable", True) else "NO",
                ]
                for k, p in f.get("parameters", {}).items()
            ]
            self.table(
                ["parameter", "value", "95 % interval", "unit", "identifiable"], rows, left={0, 3}
            )
            notes = f.get("notes") or []
            if notes:
                self.html.append("<ul>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>")
                self.md += [f"- {_md_line(n)}" for n in notes] + [""]

    def correspondence(self) -> None:
        d = self.res
        self.h2("correspondence")
        fams = d["families"]
        cols = [f for f in ("dahl", "bouc-wen", "bouc-wen-std", "lugre") if f in fams]
        self.p(
            "The seed's comparison of the torque equations (its section 5), filled with the "
            "fitted values and their 95 % intervals. The last column is the discovered "
            "structure in term form (coefficients of the torque terms on the discovered z "
            "scale). The z-multiplying parameters depend on each family's normalization of "
            "z (Dahl and Bouc-Wen: z saturates at 1; LuGre: z_sat = 1/(sigma_0 a_0)); the "
            "last two rows compare them on one scale, as torque at saturation."
        )
        rows_spec = [
            ("θ̇ (viscous)", ("k_x", "c_1", "c_1", "sigma_2"), "theta_dot"),
            ("z (hysteretic, 0 A)", ("k_wa", "alpha_1", "alpha_1", "sigma_a"), "z"),
            ("i·z (hysteretic, per A)", ("k_wb", "alpha_2", "alpha_2", "sigma_0"), "i*z"),
            ("i·θ̇ (viscous, per A)", (None, "c_2", "c_2", "sigma_b"), "i*theta_dot"),
            ("ż (LuGre sigma_1; term |θ̇|·z)", (None, None, None, "sigma_1"), "|theta_dot|*z"),
        ]
        order = ("dahl", "bouc-wen", "bouc-wen-std", "lugre")
        disc_tq = (d.get("discovered", {}).get("term_model") or {}).get("torque", {})
        header = ["torque term", *[_family_title(c) for c in cols], "discovered (term form)"]
        rows = []
        for label, names, term in rows_spec:
            row = [label]
            for c in cols:
                pname = names[order.index(c)]
                row.append(_param_cell(fams[c], pname))
            row.append(_num(disc_tq.get(term), ".5g") if term in disc_tq else "0")
            rows.append(row)
        # scale-free: hysteretic torque at saturation
        for label, which in (
            ("torque at z saturation, 0 A", "a"),
            ("torque at z saturation, per A", "b"),
        ):
            row = [label]
            for c in cols:
                row.append(_num(_saturation_torque(c, fams[c]["parameters"], which), ".5g"))
            row.append("–")
            rows.append(row)
        self.table(header, rows, left=len(header))

    def selection(self) -> None:
        from hystdisc.plotting.core import plot_inclusion, plot_selection_path

        disc = self.disc
        self.h2("selection")
        self.p(
            "Stage 1 (equation error): for each hysteresis shape the shape constants are "
            "found by variable projection and the torque-side terms by sequentially "
            "thresholded least squares (STLSQ) along a threshold path scored by BIC; the "
            "shape with the lowest BIC is the discovered structure."
        )
        rows, sel = [], []
        for i, (shape, sf) in enumerate(disc.stage1_.items()):
            if shape == disc.discovered_shape_:
                sel.append(i)
            rows.append(
                [
                    shape + (" *" if shape == disc.discovered_shape_ else ""),
                    ", ".join(sf.terms),
                    ", ".join(f"{v:.4g}" for v in np.atleast_1d(sf.s)) or "–",
                    _num(sf.bic, ".1f"),
                ]
            )
        self.table(
            ["hysteresis shape", "selected torque terms", "shape constants", "BIC"],
            rows,
            left=2,
            sel=sel,
        )
        best = disc.stage1_[disc.discovered_shape_]
        if best.path:
            fig, axes = _new_figure(2, 1, 10, 6.2, sharex=True, height_ratios=[3, 1.4])
            plot_selection_path(
                best.path,
                ax=list(axes[:, 0]),
                title=f"STLSQ path, hysteresis shape '{best.shape}'",
            )
            self.figure(
                fig,
                "Each coefficient divided by its largest magnitude along the path; a term "
                "leaves the model where its curve drops to 0. Dashed red: the threshold with "
                "the lowest BIC (the selected model).",
            )
        if best.inclusion:
            fig, axes = _new_figure(1, 1, 7, 0.9 + 0.35 * len(best.inclusion))
            plot_inclusion(best.inclusion, ax=axes[0, 0], title="ensemble inclusion")
            self.figure(fig)
            self.table(
                ["term", "inclusion probability"],
                [[k, _num(v, ".2f")] for k, v in best.inclusion.items()],
            )

    def closing(self) -> None:
        from hystdisc.plotting.core import plot_residual_spectrum

        d, disc, fd = self.res, self.disc, self.fd
        self.h2("closing")
        ran = "diagnosis" in d or bool(d.get("effects_tried"))
        if not ran:
            self.p("The closing loop was not run (close_loop=False or --no-effects).")
        tried = d.get("effects_tried") or []
        if tried:
            rows = []
            for e in tried:
                dbic = (
                    e["bic_after"] - e["bic_before"]
                    if e.get("bic_after") is not None and e.get("bic_before") is not None
                    else None
                )
                verdict = "accepted" if e.get("accepted") else "rejected"
                if not e.get("accepted") and e.get("note"):
                    verdict += f" ({e['note']})"
                rows.append(
                    [
                        e.get("name", ""),
                        ", ".join(e.get("terms") or []) or "–",
                        _num(e.get("evidence"), ".3g"),
                        _num(e.get("rms_before")),
                        _num(e.get("rms_after")),
                        _num(dbic, ".1f"),
                        verdict,
                    ]
                )
            self.table(
                ["effect tried", "terms", "evidence", "RMS before", "RMS after", "ΔBIC", "verdict"],
                rows,
                left=2,
            )
        elif ran:
            self.p("No catalogued effect had enough evidence to be refitted.")
        diag = d.get("diagnosis") or []
        names = {e.get("name") for e in tried}
        rest = [
            c for c in (diag[0].get("candidates", []) if diag else []) if c.get("name") not in names
        ]
        if rest:
            self.p(
                "Not refitted (too little evidence): "
                + ", ".join(f"{c['name']} {_num(c.get('evidence'), '.2g')}" for c in rest)
                + "."
            )
        for sk in d.get("effects_skipped") or []:
            self.p(f"Not applicable: {sk.get('name')} ({sk.get('reason')}).")
        effects = d.get("effects") or []
        if effects:
            self.html.append("<h3>Accepted effects</h3>")
            self.md += ["### Accepted effects", ""]
            rows = []
            for e in effects:
                for k, p in (e.get("parameters") or {}).items():
                    rows.append(
                        [
                            e.get("name", ""),
                            ", ".join(e.get("terms") or []),
                            k,
                            _num(p.get("value"), ".5g"),
                            _ci(p.get("ci95"), ".4g"),
                            _num(e.get("rms_before")),
                            _num(e.get("rms_after")),
                        ]
                    )
            self.table(
                [
                    "effect",
                    "terms",
                    "parameter",
                    "value",
                    "95 % interval",
                    "RMS before",
                    "RMS after",
                ],
                rows,
                left=3,
            )
        else:
            self.p("No effect was accepted.")
        res = d.get("residual") or {}
        if res:
            self.p("Final residual: " + _residual_sentence(res) + ".")
        if d.get("unexplained"):
            self.p("Unexplained: " + (d.get("unexplained_text") or "structure remains"), cls="bad")
        fs = _fs(fd)
        fig, axes = _new_figure(1, 1, 9, 3.8)
        ax = axes[0, 0]
        base = disc.family_fits_[disc.family_]
        final = _final_fit(disc)
        if final is not None:
            plot_residual_spectrum(
                _masked(base, fd),
                fs,
                ax=ax,
                label=f"{disc.family_} (before)",
                color=FAMILY_COLORS.get(disc.family_),
                alpha=0.6,
            )
        plot_residual_spectrum(
            _masked(final if final is not None else base, fd),
            fs,
            ax=ax,
            noise_std=disc.noise_std_,
            dominant_hz=res.get("dominant_hz"),
            label=_fit_label(disc, "final") + " (after)" if final is not None else disc.family_,
            color=FAMILY_COLORS["final" if final is not None else disc.family_],
        )
        ax.set_title(
            f"residual spectrum (Welch, averaged over runs); whiteness p = "
            f"{_num(res.get('whiteness_p'), '.3g')}",
            fontsize="medium",
        )
        self.figure(
            fig,
            "Dashed grey: the level of white noise with the estimated measurement noise; "
            "dotted red: the dominant frequency of a structured residual.",
        )


#: Samples per line in the report's figures (more are not visible at its resolution).
MAX_POINTS = 2500


def _thin(n: int) -> slice:
    """Every k-th sample so that at most MAX_POINTS remain (a figure-only decimation)."""
    return slice(None, None, max(1, math.ceil(n / MAX_POINTS)))


def _figure_legend(fig, ax) -> None:
    """One legend for the whole figure, outside the axes on the right."""
    handles, labels = ax.get_legend_handles_labels()
    if labels:
        labels = [textwrap.fill(lab, 34) for lab in labels]  # long discovered structures
        fig.legend(handles, labels, loc="outside right upper", fontsize="small")


def _md_line(text: str) -> str:
    return " ".join(str(text).split())


def _currents(cs) -> str:
    from hystdisc.data.io import distinct_currents

    return ", ".join(f"{c:g}" for c in distinct_currents(cs))


def _family_title(name: str) -> str:
    fam = FAMILIES.get(name)
    return fam.title if fam else name


def _param_cell(entry: Mapping[str, Any], pname: str | None) -> str:
    if pname is None:
        return "0"
    p = (entry.get("parameters") or {}).get(pname)
    if p is None:
        return "–"
    flag = "" if p.get("identifiable", True) else " (not identifiable)"
    return f"{pname} = {_num(p.get('value'), '.5g')} {_ci(p.get('ci95'), '.3g')}{flag}"


def _saturation_torque(family: str, params: Mapping[str, Any], which: str) -> float | None:
    """Hysteretic torque at z saturation, at 0 A (``which='a'``) or per A (``'b'``)."""
    v = {k: (p or {}).get("value") for k, p in params.items()}
    try:
        if family == "dahl":
            return v["k_wa"] if which == "a" else v["k_wb"]
        if family in ("bouc-wen", "bouc-wen-std"):
            return v["alpha_1"] if which == "a" else v["alpha_2"]
        if family == "lugre":
            zsat = 1.0 / (v["sigma_0"] * v["a_0"])
            return v["sigma_a"] * zsat if which == "a" else v["sigma_0"] * zsat
    except (KeyError, TypeError, ZeroDivisionError):
        return None
    return None


def _residual_sentence(res: Mapping[str, Any]) -> str:
    wp = res.get("whiteness_p")
    white = wp is not None and wp >= 0.01
    out = f"RMS {_num(res.get('rms'))}"
    if res.get("rms_over_noise") is not None:
        out += f" ({_num(res['rms_over_noise'], '.2f')}x the noise)"
    out += f", Ljung-Box whiteness p = {_num(wp, '.3g')} ({'white' if white else 'not white'})"
    if res.get("dominant_hz") is not None:
        out += f", dominant frequency {_num(res['dominant_hz'], '.3g')} Hz"
    return out


# ----------------------------------------------------------------------------- public API


def render_report(
    disc,
    dataset: Dataset,
    max_runs: int = 5,
    dpi: int = 90,
    progress: Callable[[str], None] | None = None,
) -> tuple[str, str]:
    """The report of a fitted discovery as text: ``(html, markdown)``.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    dataset : Dataset
        The dataset it was fitted on.
    max_runs : int
        Runs drawn in the per-run figures (one per current first).
    dpi : int
        Resolution of the embedded PNG figures.
    progress : callable, optional
        Called with a short message per section.

    Returns
    -------
    html : str
        A complete, self-contained HTML document.
    markdown : str
        The Markdown summary (tables only, no figures).
    """
    _check_fitted(disc)
    rep = _Report(disc, dataset, max_runs, dpi)
    d = rep.res
    title = f"hystdisc report — {d.get('input', '')}"
    for sid, _ in SECTIONS:
        if progress is not None:
            progress(f"report: {dict(SECTIONS)[sid].lower()}")
        getattr(rep, sid.replace("-", "_"))()
    nav = "".join(f'<a href="#{_e(s)}">{_e(t)}</a>' for s, t in SECTIONS)
    html_text = (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"<h1>{_e(title)}</h1>\n<nav>{nav}</nav>\n" + "\n".join(rep.html) + "\n</body>\n</html>\n"
    )
    md_text = "\n".join([f"# {_md_line(title)}", *rep.md]).rstrip() + "\n"
    return html_text, md_text


def markdown_path(path: str | os.PathLike[str]) -> Path:
    """The Markdown summary written beside an HTML report (``report.html`` -> ``report.md``)."""
    return Path(path).with_suffix(".md")


def check_report_path(
    path: str | os.PathLike[str], force: bool = False, markdown: bool = True
) -> None:
    """Refuse a report path before any work: a ``.md`` name, a folder, or existing files.

    Call it before a long discovery (``hystdisc report`` and ``discover --report`` do) so
    that nothing runs for an output that cannot be written.

    Raises
    ------
    HystdiscError
        One line naming the path and the fix.

    Examples
    --------
    >>> check_report_path("no/such/folder/report.html")
    >>> check_report_path("notes.md")
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: notes.md: the report is HTML (its Markdown summary goes beside it); fix: give a path ending in .html
    """
    target = Path(path)
    if target.suffix.lower() == ".md":
        raise HystdiscError(
            f"{target}: the report is HTML (its Markdown summary goes beside it); fix: give a "
            "path ending in .html"
        )
    if target.is_dir():
        raise HystdiscError(f"{target}: is a directory; fix: choose a file name with -o")
    if not force:
        for p in [target, markdown_path(target)] if markdown else [target]:
            if p.exists():
                raise HystdiscError(
                    f"{p}: already exists; fix: pass --force to overwrite or choose another -o"
                )


def write_report(
    disc,
    dataset: Dataset,
    path: str | os.PathLike[str],
    force: bool = False,
    markdown: bool = True,
    max_runs: int = 5,
    dpi: int = 90,
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Write the HTML report of a fitted discovery, and its Markdown summary beside it.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    dataset : Dataset
        The dataset it was fitted on.
    path : path-like
        The HTML file (``.html``); the Markdown summary goes to the same name with ``.md``.
    force : bool
        Overwrite existing files (otherwise an existing file is a one-line HystdiscError and
        nothing is written).
    markdown : bool
        Also write the Markdown summary.
    max_runs, dpi, progress
        See :func:`render_report`.

    Returns
    -------
    pathlib.Path
        The HTML file written.
    """
    target = Path(path)
    check_report_path(target, force, markdown)
    html_text, md_text = render_report(disc, dataset, max_runs, dpi, progress)
    out = atomic_write_text(target, html_text, force=force)
    if markdown:
        atomic_write_text(markdown_path(target), md_text, force=force)
    return out
