"""Rendering the report and writing it (HTML and the Markdown beside it), atomically."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from hystdisc.data import Dataset, atomic_write_text
from hystdisc.errors import HystdiscError
from hystdisc.report.comparison import ComparisonSections
from hystdisc.report.currents import CurrentSections
from hystdisc.report.design import DesignSections
from hystdisc.report.document import Document
from hystdisc.report.markup import CSS, SECTIONS, esc, md_line
from hystdisc.report.overview import OverviewSections
from hystdisc.report.signals import check_fitted
from hystdisc.report.source import ReportData, load_report_data, report_data
from hystdisc.report.stages import StageSections


class Report(
    Document, OverviewSections, ComparisonSections, CurrentSections, StageSections, DesignSections
):
    """The whole report: the document and every section (one method per section id)."""

    def __init__(self, rd: ReportData, max_runs: int, dpi: int, design=None) -> None:
        super().__init__(rd, max_runs, dpi)
        self.design = design


def as_report_data(source, dataset: Dataset | None = None) -> ReportData:
    """What a report is drawn from: a fitted discovery and its dataset, report data, or
    the path of a ``results.json`` with its report data beside it.

    Parameters
    ----------
    source : Discovery, ReportData or path-like
        A fitted discovery (with ``dataset``), report data, or a ``results.json``.
    dataset : Dataset, optional
        The dataset a discovery was fitted on.

    Returns
    -------
    ReportData
    """
    if isinstance(source, ReportData):
        return source
    if isinstance(source, (str, os.PathLike)):
        return load_report_data(source)
    if dataset is None:
        raise HystdiscError(
            "a report of a Discovery needs the dataset it was fitted on; fix: pass it as "
            "the second argument"
        )
    return report_data(source, dataset)


def render_report(
    disc,
    dataset: Dataset | None = None,
    max_runs: int = 5,
    dpi: int = 90,
    progress: Callable[[str], None] | None = None,
    design=None,
) -> tuple[str, str]:
    """The report of a fitted discovery as text: ``(html, markdown)``.

    Parameters
    ----------
    disc : Discovery, ReportData or path-like
        A fitted discovery, its report data (:func:`~hystdisc.report.source.report_data`),
        or a ``results.json`` with the report data beside it (no refit).
    dataset : Dataset, optional
        The dataset a discovery was fitted on (not needed otherwise).
    max_runs : int
        Runs drawn in the per-run figures (one per current first).
    dpi : int
        Resolution of the embedded PNG figures.
    progress : callable, optional
        Called with a short message per section.
    design : DesignResult or str, optional
        The runs to record next (:func:`hystdisc.design.design`) for the section "What
        to test next", or why there is none; None: the section is left out.

    Returns
    -------
    html : str
        A complete, self-contained HTML document.
    markdown : str
        The Markdown summary (tables only, no figures).
    """
    if not isinstance(disc, (ReportData, str, os.PathLike)):
        check_fitted(disc)
    rep = Report(as_report_data(disc, dataset), max_runs, dpi, design)
    title = f"hystdisc report — {rep.res.input}"
    for sid, _ in SECTIONS:
        if progress is not None:
            progress(f"report: {dict(SECTIONS)[sid].lower()}")
        getattr(rep, sid.replace("-", "_"))()
    titles = dict(SECTIONS)
    nav = "".join(f'<a href="#{esc(s)}">{esc(titles[s])}</a>' for s in rep.present)
    html_text = (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{esc(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        f"<h1>{esc(title)}</h1>\n<nav>{nav}</nav>\n" + "\n".join(rep.html) + "\n</body>\n</html>\n"
    )
    md_text = "\n".join([f"# {md_line(title)}", *rep.md]).rstrip() + "\n"
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
    dataset: Dataset | None,
    path: str | os.PathLike[str],
    force: bool = False,
    markdown: bool = True,
    max_runs: int = 5,
    dpi: int = 90,
    progress: Callable[[str], None] | None = None,
    design=None,
) -> Path:
    """Write the HTML report of a fitted discovery, and its Markdown summary beside it.

    Parameters
    ----------
    disc, dataset
        As in :func:`render_report`: a fitted discovery and its dataset, report data and
        None, or a ``results.json`` (with its report data beside it) and None.
    path : path-like
        The HTML file (``.html``); the Markdown summary goes to the same name with ``.md``.
    force : bool
        Overwrite existing files (otherwise an existing file is a one-line HystdiscError and
        nothing is written).
    markdown : bool
        Also write the Markdown summary.
    max_runs, dpi, progress, design
        See :func:`render_report`.

    Returns
    -------
    pathlib.Path
        The HTML file written.
    """
    target = Path(path)
    check_report_path(target, force, markdown)
    html_text, md_text = render_report(disc, dataset, max_runs, dpi, progress, design)
    out = atomic_write_text(target, html_text, force=force)
    if markdown:
        atomic_write_text(markdown_path(target), md_text, force=force)
    return out
