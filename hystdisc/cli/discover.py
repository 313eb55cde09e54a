"""``hystdisc discover``: which hysteresis model is in the damper, with error bars.

Examples::

    hystdisc discover data_synth/bouc-wen.csv
    hystdisc discover run.csv --model dahl --json dahl.json --force
    hystdisc discover ../shared/data/utfsm_mr_damper --rig rig.toml
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hystdisc.cli.common import add_data_options, load_data, progress_printer
from hystdisc.discovery import ALL_FAMILIES, Discovery
from hystdisc.errors import HystdiscError
from hystdisc.models import FAMILIES


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "discover",
        help="discover the hysteresis model of the data and fit every family",
        description=(
            "Discover the active terms by sparse regression with a latent hysteretic state, "
            "fit every family (Bingham, Dahl, LuGre, Bouc-Wen) by output error with 95 %% "
            "intervals, select one by BIC, and write results.json."
        ),
    )
    p.add_argument(
        "files", nargs="+", metavar="FILE", help="data files or folders (CSV, .mat, tables)"
    )
    p.add_argument(
        "--model", help=f"declare the family instead of selecting one: {', '.join(FAMILIES)}"
    )
    p.add_argument(
        "--families",
        metavar="LIST",
        help=f"families to compare, comma separated (default: {','.join(ALL_FAMILIES)})",
    )
    add_data_options(p)
    p.add_argument("--out", metavar="DIR", default=".", help="folder for results.json (default: .)")
    p.add_argument("--json", metavar="PATH", help="results file (default: DIR/results.json)")
    p.add_argument("--seed", type=int, default=0, help="seed of the resampling (default 0)")
    p.add_argument("--threshold", type=float, help="fixed STLSQ threshold (default: chosen by BIC)")
    p.add_argument("--ensemble", action="store_true", help="inclusion probabilities by bagging")
    p.add_argument("--no-heldout", action="store_true", help="skip leave-one-run-out errors")
    p.add_argument(
        "--no-effects",
        action="store_true",
        help="skip the closing loop (residual -> catalogued effects)",
    )
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    return p


def run(args: argparse.Namespace) -> int:
    json_path = Path(args.json) if args.json else Path(args.out) / "results.json"
    if json_path.exists() and not args.force:
        raise HystdiscError(
            f"{json_path}: exists; fix: pass --force to overwrite or choose another --json/--out"
        )
    data = load_data(args, args.files)
    families = None
    if args.families:
        families = [f.strip() for f in args.families.split(",") if f.strip()]
    disc = Discovery(
        experiment=args.experiment,
        families=families,
        model=args.model,
        threshold=args.threshold,
        ensemble=args.ensemble,
        heldout=not args.no_heldout,
        seed=args.seed,
        progress=progress_printer(args.quiet),
        close_loop=not args.no_effects,
    ).fit(data)
    res = disc.results_
    json_path.parent.mkdir(parents=True, exist_ok=True)
    res.save(json_path, force=args.force)
    print(res.report())
    print(f"\nwrote {json_path}")
    return 0
