"""The report under construction: HTML and Markdown side by side, and the output helpers
the sections share."""

from __future__ import annotations

from hystdisc.data import Dataset
from hystdisc.registry import get_experiment
from hystdisc.report.markup import (
    SECTIONS,
    esc,
    html_table,
    md_line,
    md_table,
    png,
)
from hystdisc.report.signals import fit_data, shown_runs
from hystdisc.results import Results


class Document:
    """Collects the HTML and Markdown of the report's sections.

    Attributes
    ----------
    disc : Discovery
        The fitted discovery (its public fitted attributes are read).
    ds : Dataset
        The dataset it was fitted on.
    res : Results
        ``disc.results_``.
    fd : FitData
        ``disc.fit_data_``, the runs as fitted.
    exp : Experiment
        The experiment object of the fit.
    max_runs, dpi : int
        Runs drawn per figure; resolution of the figures.
    html, md : list of str
        The HTML and Markdown written so far.
    shown : list of int
        The runs drawn (one per current first).
    units : str
        ``"torque"`` or ``"theta"``: the measured signal.
    """

    def __init__(self, disc, dataset: Dataset, max_runs: int, dpi: int) -> None:
        self.disc = disc
        self.ds = dataset
        self.res: Results = disc.results_
        self.fd = fit_data(disc)
        self.exp = get_experiment(self.fd.experiment)
        self.max_runs = max_runs
        self.dpi = dpi
        self.html: list[str] = []
        self.md: list[str] = []
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
