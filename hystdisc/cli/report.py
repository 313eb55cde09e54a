"""``hystdisc report``: discover the model of the data and write the model-comparison report.

One self-contained HTML file (figures embedded, opens offline) and a Markdown summary of
its tables beside it (``report.html`` -> ``report.md``).

Examples::

    hystdisc report data_synth/bouc-wen.csv -o report.html
    hystdisc report run.csv --model dahl -o dahl.html --force --quiet
    hystdisc report run.csv --model bouc-wen --design 3 -o report.html
    hystdisc report ../shared/data/utfsm_mr_damper --rig rig.toml --families dahl,bouc-wen
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hystdisc.cli.common import (
    add_discovery_options,
    discover,
    load_data,
    progress_printer,
)
from hystdisc.errors import HystdiscError

HELP = "discover the model and write an HTML model-comparison report (+ Markdown summary)"
DESCRIPTION = (
    "Run the discovery (as hystdisc discover) and write one self-contained HTML "
    "report: data, measured against simulated output, hysteresis loops per current, "
    "the family table, parameters with 95 % intervals, the seed's term "
    "correspondence, the term-selection path and the closing loop (with --design N, "
    "also the runs to record next). A Markdown summary of the tables is written beside "
    "it (same name, .md)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc report``."""
    p.add_argument(
        "files", nargs="+", metavar="FILE", help="data files or folders (CSV, .mat, tables)"
    )
    p.add_argument(
        "-o",
        "--output",
        default="report.html",
        metavar="PATH",
        help="HTML report (default: report.html; the summary goes to PATH with .md)",
    )
    add_discovery_options(p)
    p.add_argument(
        "--max-runs",
        type=int,
        default=5,
        metavar="N",
        help="runs drawn in the per-run figures, one per current first (default 5)",
    )
    p.add_argument(
        "--design",
        type=int,
        metavar="N",
        help="add the section 'What to test next': the N runs hystdisc design suggests",
    )
    p.add_argument("--no-markdown", action="store_true", help="do not write the .md summary")
    p.add_argument("--force", action="store_true", help="overwrite existing report files")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc report``."""
    from hystdisc.report import check_report_path, markdown_path, write_report

    out = Path(args.output)
    markdown = not args.no_markdown
    check_report_path(out, args.force, markdown)
    if args.max_runs < 1:
        raise HystdiscError(f"--max-runs {args.max_runs} is below 1; fix: give 1 or more")
    if args.design is not None and args.design < 1:
        raise HystdiscError(f"--design {args.design} is below 1; fix: give 1 or more")
    data = load_data(args, args.files)
    say = progress_printer(args.quiet)
    disc = discover(args, data, say)
    plan = None
    if args.design is not None:
        from hystdisc.design import design

        if say is not None:
            say("report: experiment design")
        try:
            plan = design(disc.results_, budget=args.design)
        except HystdiscError as exc:  # a forced test, a model diverging on a candidate
            plan = str(exc).removeprefix("results: ")
    path = write_report(
        disc,
        data,
        out,
        force=args.force,
        markdown=markdown,
        max_runs=args.max_runs,
        progress=say,
        design=plan,
    )
    if not args.quiet:
        extra = f" and {markdown_path(path)}" if markdown else ""
        print(f"wrote {path}{extra} (family: {disc.family_})")
    return 0
