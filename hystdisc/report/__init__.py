"""The model-comparison report: one self-contained HTML file and a Markdown summary beside it.

:func:`write_report` turns a fitted :class:`~hystdisc.Discovery` (or a ``results.json``
with the report data ``hystdisc discover`` keeps beside it, :mod:`~hystdisc.report.source`:
no refit) into
``report.html`` (figures embedded as base64 PNG, inline CSS, no script and no external
resource, so it opens offline in any browser) and ``report.md`` (the tables, for version
control and issue trackers). The sections, each an ``<h2>`` with the id in
:data:`SECTIONS`:

``summary``
    Input, experiment, discovered structure and equations, selected family, verdict.
``failed``
    The tasks of the fit that failed (families, starts, folds, effects), when any did.
``data``
    Runs, currents, samples, noise; the measured signals.
``time-series``
    Measured against simulated output over time, one figure per fit (the selected family
    first, marked), with residuals.
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
``current-laws``
    The staged fit's per-level values and chosen current laws (``--staged``), when run.
``correspondence``
    The seed's section-5 term correspondence (Dahl, Bouc-Wen, LuGre) with fitted values.
``selection``
    Stage 1: the hysteresis shapes compared and the STLSQ term-selection path.
``closing``
    The closing loop: effects tried, before/after RMS, the residual spectrum and whiteness.
``what-to-test-next``
    The runs to record next and the 95 % intervals expected after them
    (:func:`hystdisc.design.design`; ``hystdisc report --design N``), when asked for.

A section with nothing to say is left out (and out of the navigation bar).

Figures are drawn on :class:`matplotlib.figure.Figure` objects (no pyplot state, no change
to ``rcParams``) with the ``ax=`` functions of :mod:`hystdisc.plotting`.

The modules: :mod:`~hystdisc.report.signals` (what is drawn, from the estimator's public
fitted attributes), :mod:`~hystdisc.report.source` (all of it collected, kept beside
``results.json`` and read back), :mod:`~hystdisc.report.markup` (cells, tables, figures),
:mod:`~hystdisc.report.document` (the HTML and Markdown under construction), the sections
in :mod:`~hystdisc.report.overview`, :mod:`~hystdisc.report.comparison`,
:mod:`~hystdisc.report.stages` and :mod:`~hystdisc.report.design`, and :mod:`~hystdisc.report.writing`.

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
>>> [sid for sid, _ in SECTIONS if f'id="{sid}"' not in html_text]  # nothing to say there
['failed', 'current-laws', 'what-to-test-next']
>>> "| dahl *" in md_text
True
"""

from hystdisc.report.markup import SECTIONS, color_of
from hystdisc.report.signals import fit_residuals, fit_signals, model_loops, shown_runs
from hystdisc.report.source import ReportData, load_report_data, report_data, report_data_path
from hystdisc.report.writing import check_report_path, markdown_path, render_report, write_report

__all__ = [
    "color_of",
    "SECTIONS",
    "ReportData",
    "load_report_data",
    "report_data",
    "report_data_path",
    "check_report_path",
    "fit_residuals",
    "fit_signals",
    "markdown_path",
    "model_loops",
    "render_report",
    "shown_runs",
    "write_report",
]
