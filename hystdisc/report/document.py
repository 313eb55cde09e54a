"""The report under construction: HTML and Markdown side by side, and the output helpers
the sections share."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hystdisc.registry import get_experiment
from hystdisc.report.markup import (
    SECTIONS,
    esc,
    html_table,
    md_line,
    md_table,
    png,
)
from hystdisc.report.signals import shown_runs
from hystdisc.results import Results


class _Runs:
    """The runs as fitted, from the report data (the attributes of ``FitData`` read)."""

    def __init__(self, rd) -> None:
        r = rd.runs
        self.names = list(r["names"])
        self.currents = np.asarray(r["currents"], dtype=float)
        self.t, self.y, self.mask = list(r["t"]), list(r["y"]), list(r["mask"])
        self.n_runs = len(self.names)
        self.experiment = rd.experiment


class _Raw:
    """The runs as read (decimated), for :func:`hystdisc.plotting.plot_runs`."""

    def __init__(self, rd) -> None:
        self.source, self.experiment, self._measured = rd.source, rd.experiment, rd.measured
        self.runs = [
            SimpleNamespace(
                name=r["name"], current=r["current"], n=r["n"], t=r["t"], **{rd.measured: r["y"]}
            )
            for r in rd.raw
        ]

    def measured(self) -> str:
        return self._measured


class Document:
    """Collects the HTML and Markdown of the report's sections.

    Attributes
    ----------
    rd : ReportData
        What the report draws (:mod:`hystdisc.report.source`).
    res : Results
        ``rd.results``.
    fd : object
        The runs as fitted: ``names, currents, t, y, mask, n_runs, experiment``.
    ds : object
        The runs as read: ``source, experiment, runs`` and ``measured()``.
    exp : Experiment
        The experiment object of the fit.
    max_runs, dpi : int
        Runs drawn per figure; resolution of the figures.
    html, md : list of str
        The HTML and Markdown written so far.
    present : list of str
        The ids of the sections written so far.
    shown : list of int
        The runs drawn (one per current first).
    units : str
        ``"torque"`` or ``"theta"``: the measured signal.
    """

    def __init__(self, rd, max_runs: int, dpi: int) -> None:
        self.rd = rd
        self.res: Results = rd.results
        self.fd = _Runs(rd)
        self.ds = _Raw(rd)
        self.exp = get_experiment(self.fd.experiment)
        self.max_runs = max_runs
        self.dpi = dpi
        self.html: list[str] = []
        self.md: list[str] = []
        self.present: list[str] = []  # the sections written (empty ones are left out)
        self.shown = shown_runs(list(self.fd.currents), max_runs)
        self.units = self.exp.output

    @property
    def released(self) -> bool:
        """A release test: no imposed motion and no input."""
        return not (self.exp.motion_imposed or self.exp.has_input)

    # -- output helpers
    def h2(self, sid: str) -> None:
        """Open the section ``sid`` (a key of ``SECTIONS``) with its heading."""
        title = dict(SECTIONS)[sid]
        self.present.append(sid)
        self.html.append(f'<h2 id="{esc(sid)}">{esc(title)}</h2>')
        self.md += ["", f"## {title}", ""]

    def p(self, text: str, md: bool = True, cls: str | None = None) -> None:
        """A paragraph (also in the Markdown summary unless ``md`` is False)."""
        c = f' class="{cls}"' if cls else ""
        self.html.append(f"<p{c}>{esc(text)}</p>")
        if md:
            self.md += [md_line(text), ""]

    def table(self, header, rows, left: int | set[int] = 1, sel=None, md: bool = True) -> None:
        """A table: ``left`` columns left-aligned, row ``sel`` highlighted."""
        self.html.append(html_table(header, rows, left, sel))
        if md:
            self.md += [md_table(header, rows), ""]

    def figure(self, fig, caption: str | None = None) -> None:
        """A figure as an embedded PNG, with an optional caption (HTML only)."""
        self.html.append(png(fig, self.dpi))
        if caption:
            self.html.append(f'<p class="note">{esc(caption)}</p>')

    def pre(self, text: str) -> None:
        """Preformatted text."""
        self.html.append(f"<pre>{esc(text)}</pre>")
        self.md += ["```", text, "```", ""]

    def shown_note(self) -> str:
        """A note when the figures show only some of the runs (empty otherwise)."""
        n = self.fd.n_runs
        if len(self.shown) >= n:
            return ""
        return f" (showing {len(self.shown)} of {n} runs: one per current first)"
