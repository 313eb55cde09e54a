"""``hystdisc design``: which runs to record next to shrink a fit's intervals.

Examples::

    hystdisc design results.json
    hystdisc design results.json --budget 2 --out design.json --force
    hystdisc design results.json --currents 0,0.5,1,1.5
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hystdisc.errors import HystdiscError

HELP = "suggest the next runs to record (experiment design from results.json)"
DESCRIPTION = (
    "From the fit of a results.json, compute the Fisher information of candidate runs "
    "(release: an angle and a current; driven: a sine's amplitude, frequency and current, "
    "or a multisine band) from the fitted model's sensitivities, and print the N runs that "
    "most shrink the widest 95 % interval, with the intervals expected after them; "
    "for families that fit about as well, the runs that best tell them apart."
)
EPILOG = (
    "--out FILE.json writes the design as JSON; any other name gets the printed text. "
    "Nothing is overwritten without --force."
)


def _currents(text: str) -> list[float]:
    """The ``--currents`` list (comma-separated amperes)."""
    try:
        out = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a list of currents (e.g. 0,0.5,1)"
        ) from None
    if not out or any(not (c >= 0 and c < float("inf")) for c in out):
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of currents >= 0 (e.g. 0,0.5,1)")
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc design``."""
    p.add_argument("results", metavar="RESULTS.json", help="the file written by discover --json")
    p.add_argument("--budget", type=int, default=3, metavar="N", help="runs to suggest (default 3)")
    p.add_argument(
        "--currents",
        type=_currents,
        metavar="I,I,...",
        help="currents of the candidate runs, A (default: 0 to the largest trained, 5 levels)",
    )
    p.add_argument(
        "--parameters",
        type=lambda text: [x.strip() for x in text.split(",") if x.strip()],
        metavar="P,P,...",
        help="parameters whose widest relative interval to shrink (default: every one not "
        "at a bound and told from 0)",
    )
    p.add_argument("--out", metavar="FILE", help="also write the design (.json: as JSON)")
    p.add_argument("--force", action="store_true", help="overwrite FILE")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc design``."""
    import json

    from hystdisc.data import atomic_write_text
    from hystdisc.design import design
    from hystdisc.results import Results

    if args.budget < 1:
        raise HystdiscError(f"--budget {args.budget} is below 1; fix: give 1 or more")
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not args.force:
        raise HystdiscError(
            f"{out}: already exists; fix: pass --force to overwrite or choose another --out"
        )
    res = Results.load(args.results)
    try:
        plan = design(res, budget=args.budget, currents=args.currents, parameters=args.parameters)
    except HystdiscError as exc:
        msg = str(exc)
        if msg.startswith("results: "):
            msg = f"{args.results}: {msg.removeprefix('results: ')}"
        raise HystdiscError(msg) from None
    text = plan.report()
    if out is not None:
        body = json.dumps(plan.summary(), indent=1) if out.suffix.lower() == ".json" else text
        atomic_write_text(out, body + "\n", force=args.force)
    if not args.quiet:
        print(text)
        if out is not None:
            print(f"wrote {out}")
    return 0
