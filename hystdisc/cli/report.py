"""``hystdisc report``: write the model-comparison report of a fit, or of the data.

One self-contained HTML file (figures embedded, opens offline) and a Markdown summary of
its tables beside it (``report.html`` -> ``report.md``). Given the ``results.json`` of
``hystdisc discover`` it refits nothing: the signals it draws are kept beside it
(``results.report.npz``), and the report is the same as that of the data.

Examples::

    hystdisc report out/results.json -o out/report.html
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

HELP = "write the HTML model-comparison report of a results.json or of data (+ Markdown)"
DESCRIPTION = (
    "Given the results.json of hystdisc discover, draw its report without a refit (the "
    "signals are kept beside it, results.report.npz); given data, run the discovery (as "
    "hystdisc discover) first. Either way one self-contained HTML "
    "report: data, measured against simulated output, hysteresis loops per current, "
    "the family table, parameters with 95 % intervals, the seed's term "
    "correspondence, the term-selection path and the closing loop (with --design N, "
    "also the runs to record next). A Markdown summary of the tables is written beside "
    "it (same name, .md)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc report``."""
    p.add_argument(
        "files",
        nargs="+",
        metavar="FILE",
        help="a results.json of hystdisc discover (no refit), or data files or folders "
        "(CSV, .mat, tables)",
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
    say = progress_printer(args.quiet)
    if _is_results(args.files):
        from hystdisc.report import load_report_data

        _check_no_fit_options(args)
        rd = load_report_data(args.files[0])
    else:
        from hystdisc.report import report_data

        data = load_data(args, args.files)
        rd = report_data(discover(args, data, say), data)
    plan = None
    if args.design is not None:
        from hystdisc.design import design

        if say is not None:
            say("report: experiment design")
        try:
            plan = design(rd.results, budget=args.design)
        except HystdiscError as exc:  # a forced test, a model diverging on a candidate
            plan = str(exc).removeprefix("results: ")
    path = write_report(
        rd,
        None,
        out,
        force=args.force,
        markdown=markdown,
        max_runs=args.max_runs,
        progress=say,
        design=plan,
    )
    if not args.quiet:
        extra = f" and {markdown_path(path)}" if markdown else ""
        print(f"wrote {path}{extra} (family: {rd.results.family})")
    return 0


def _is_results(files: list[str]) -> bool:
    """One ``.json`` file: the results of a discovery, not data."""
    return len(files) == 1 and Path(files[0]).suffix.lower() == ".json"


#: Options of the fit, which a report of a results.json cannot apply (dest -> flag).
FIT_OPTIONS = {
    "model": "--model",
    "families": "--families",
    "experiment": "--experiment",
    "rig": "--rig",
    "column": "--column",
    "units": "--units",
    "ensemble": "--ensemble",
    "no_heldout": "--no-heldout",
    "single_current": "--single-current",
    "no_effects": "--no-effects",
    "staged": "--staged",
}


def _check_no_fit_options(args: argparse.Namespace) -> None:
    """A report of a results.json draws that fit: options of another fit are an error."""
    given = [flag for dest, flag in FIT_OPTIONS.items() if getattr(args, dest, None)]
    if args.seed != 0:
        given.append("--seed")
    if args.starts != 4:
        given.append("--starts")
    if args.input_hold != "cubic":
        given.append("--input-hold")
    if given:
        raise HystdiscError(
            f"{args.files[0]}: is the results of a fit, which the report draws as it is, so "
            f"{', '.join(given)} cannot apply; fix: drop {', '.join(given)}, or give the data "
            "(hystdisc report DATA ...) to fit again with them"
        )
