"""``hystdisc discover``: which hysteresis model is in the damper, with error bars.

Examples::

    hystdisc discover data_synth/bouc-wen.csv
    hystdisc discover run.csv --model dahl --json dahl.json --force
    hystdisc discover ../shared/data/utfsm_mr_damper --rig rig.toml
    hystdisc discover rig1.csv rig2.csv rig3.csv --each --jobs 2 --out results/
    hystdisc discover data/*.csv --each --scheduler tcp://10.0.0.5:8786 --out results/
    hystdisc discover data_synth/bouc-wen.csv --scheduler tcp://10.0.0.5:8786

With ``--each``, ``--scheduler`` runs whole datasets on the cluster
(:mod:`hystdisc.cli.batch`); without it, the independent tasks of the one discovery
(:mod:`hystdisc.pipeline.tasks`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hystdisc import registry
from hystdisc.cli.common import (
    add_discovery_options,
    discover,
    discovery_options,
    load_data,
    name_value_pairs,
    progress_printer,
)
from hystdisc.errors import HystdiscError

HELP = "discover the hysteresis model of the data and fit every family"
DESCRIPTION = (
    "Discover the active terms by sparse regression with a latent hysteretic state, "
    f"fit every family ({', '.join(registry.family_names())}) by output error with "
    "95 % intervals, select one by BIC, and write results.json."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc discover``."""
    p.add_argument(
        "files", nargs="+", metavar="FILE", help="data files or folders (CSV, .mat, tables)"
    )
    add_discovery_options(p)
    p.add_argument("--out", metavar="DIR", default=".", help="folder for results.json (default: .)")
    p.add_argument("--json", metavar="PATH", help="results file (default: DIR/results.json)")
    p.add_argument("--threshold", type=float, help="fixed STLSQ threshold (default: chosen by BIC)")
    p.add_argument(
        "--report", metavar="PATH", help="also write an HTML report (and a .md summary beside it)"
    )
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    g = p.add_argument_group(
        "many datasets",
        "By default all FILEs form ONE dataset. With --each every FILE (or folder) is a "
        "dataset of its own, written to DIR/<stem>.results.json; --jobs and --scheduler "
        "run those datasets in parallel, with results byte-identical to the serial run. "
        "Without --each, --scheduler runs the independent fits of the one dataset on the "
        "cluster (the same results).",
    )
    g.add_argument(
        "--each",
        action="store_true",
        help="discover each FILE as its own dataset (writes DIR/<stem>.results.json)",
    )
    g.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="with --each: datasets discovered in parallel by N local processes "
        "(joblib; -1 = all cores; default 1)",
    )
    g.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on a Dask cluster (dask.distributed scheduler address, e.g. "
        "tcp://host:8786; needs pip install hystdisc[dask] and hystdisc on the workers): "
        "with --each the datasets (the files readable on the workers at the same paths), "
        "without it the independent fits of the one dataset (families, starts, held-out "
        "folds, effect refits; the data travel with them)",
    )


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc discover``."""
    if args.each:
        return run_each(args)
    if args.jobs != 1:
        raise HystdiscError(
            "--jobs runs several datasets in parallel, but without --each all FILEs form one "
            "dataset; fix: add --each (one dataset per FILE) or drop --jobs"
        )
    json_path = Path(args.json) if args.json else Path(args.out) / "results.json"
    from hystdisc.report.source import report_data_path

    for path in (json_path, report_data_path(json_path)):
        if path.exists() and not args.force:
            raise HystdiscError(
                f"{path}: exists; fix: pass --force to overwrite or choose another --json/--out"
            )
    if args.report:
        from hystdisc.report import check_report_path

        check_report_path(args.report, args.force)
    data = load_data(args, args.files)
    disc = discover(args, data, progress_printer(args.quiet), scheduler=args.scheduler)
    res = disc.results_
    json_path.parent.mkdir(parents=True, exist_ok=True)
    from hystdisc.report import report_data, report_data_path

    rd = report_data(disc, data)  # what hystdisc report results.json draws, kept beside it
    res.save(json_path, force=args.force)
    rd.save(report_data_path(json_path), force=args.force)
    print(res.report())
    if getattr(disc, "staged_", None) is not None:
        print("\n" + disc.staged_.report())
    print(f"\nwrote {json_path}")
    if args.report:
        from hystdisc.report import write_report

        path = write_report(
            rd, None, args.report, force=args.force, progress=progress_printer(args.quiet)
        )
        print(f"wrote {path}")
    return 0


def run_each(args: argparse.Namespace) -> int:
    """``--each``: every FILE is a dataset; serial, ``--jobs N`` or ``--scheduler ADDRESS``."""
    from hystdisc.cli.batch import discover_many, output_paths
    from hystdisc.data import atomic_write_text

    if args.json:
        raise HystdiscError(
            "--json names one results file, but --each writes one per FILE; fix: drop --json "
            "and use --out DIR (files are DIR/<stem>.results.json)"
        )
    paths = output_paths(args.files, args.out)
    if not args.force:
        for path in paths:
            if path.exists():
                raise HystdiscError(
                    f"{path}: exists; fix: pass --force to overwrite or choose another --out"
                )
    columns = name_value_pairs(args.column, "--column")
    load_options = {
        "experiment": args.experiment,
        "rig": args.rig,
        "columns": {k: int(v) if v.isdigit() else v for k, v in columns.items()} or None,
        "units": name_value_pairs(args.units, "--units") or None,
    }
    options = discovery_options(args)
    items = discover_many(
        args.files,
        load_options=load_options,
        discovery_options=options,
        jobs=args.jobs,
        scheduler=args.scheduler,
        progress=progress_printer(args.quiet),
    )
    failed = 0
    for item, path in zip(items, paths, strict=True):
        if item.error:
            failed += 1
            print(f"hystdisc: error: {item.error}", file=sys.stderr)
            continue
        atomic_write_text(path, item.results_json, force=args.force)
        print(item.report)
        print(f"\nwrote {path}\n")
    if failed:
        print(
            f"hystdisc: error: {failed} of {len(items)} datasets failed (messages above); "
            "fix: correct those files and rerun them",
            file=sys.stderr,
        )
        return 2
    return 0
