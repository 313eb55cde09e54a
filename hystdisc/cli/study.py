"""``hystdisc study``: loops of a model while one parameter varies (the seed's figures 4-22).

Example::

    hystdisc study --model dahl --vary rho=2,15 --set k_x=5 --set k_wa=80 -o rho.png
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

from hystdisc import registry
from hystdisc.cli.simulate import (
    add_model_options,
    parse_assignments,
    parse_effect,
    parse_float,
    parse_int,
)
from hystdisc.errors import HystdiscError

HELP = "plot a model's hysteresis loops while one parameter varies"
DESCRIPTION = (
    "Impose theta = A sin(2 pi f t), let the loop settle, and overlay the damper "
    "torque of the last cycle against velocity and against displacement for each "
    "value of one parameter (or of the current: --vary current=0,0.5,1)."
)
FORMATS = (".png", ".pdf", ".svg")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc study``."""
    p.add_argument("--model", required=True, help=f"family: {', '.join(registry.family_names())}")
    p.add_argument(
        "--vary", required=True, metavar="NAME=V1,V2,...", help="parameter and its values"
    )
    add_model_options(p, "other parameters", "add an effect")
    p.add_argument("--current", default="0", metavar="A", help="coil current (default 0)")
    p.add_argument("--amplitude", default="0.3", metavar="RAD", help="sine amplitude (0.3)")
    p.add_argument("--frequency", default="1.0", metavar="HZ", help="sine frequency (1 Hz)")
    p.add_argument("--cycles", default="3", metavar="N", help="cycles simulated (last shown)")
    p.add_argument("--fs", default="2000", metavar="HZ", help="sampling rate (2000 Hz)")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="figure (.png/.pdf/.svg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing figure")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc study``."""
    from matplotlib.figure import Figure

    from hystdisc.data import atomic_write_bytes
    from hystdisc.plotting import plot_study
    from hystdisc.simulation.studies import parameter_study

    out = Path(args.output)
    if out.suffix.lower() not in FORMATS:
        raise HystdiscError(
            f"{out}: unknown figure format {out.suffix!r}; fix: end -o with {', '.join(FORMATS)}"
        )
    if out.exists() and not args.force:
        raise HystdiscError(
            f"{out}: already exists; fix: pass --force to overwrite or choose another -o"
        )
    name, sep, vals = args.vary.partition("=")
    name = name.strip()
    if not sep or not name or not vals.strip():
        raise HystdiscError(
            f"--vary {args.vary!r} is not NAME=V1,V2,...; fix: write e.g. --vary rho=2,15"
        )
    values = [parse_float(v, f"--vary {name} value") for v in vals.split(",") if v.strip()]
    effects = dict(parse_effect(e) for e in args.effect)
    study = parameter_study(
        args.model,
        name,
        values,
        current=parse_float(args.current, "--current"),
        base=parse_assignments(args.set, "--set"),
        effects=effects,
        amplitude=parse_float(args.amplitude, "--amplitude"),
        frequency=parse_float(args.frequency, "--frequency"),
        cycles=parse_int(args.cycles, "--cycles"),
        fs=parse_float(args.fs, "--fs"),
    )
    fig = Figure(figsize=(10, 4), layout="constrained")
    plot_study(study, ax=list(fig.subplots(1, 2)))
    buf = io.BytesIO()
    fig.savefig(buf, format=out.suffix.lower().lstrip("."), dpi=120)
    path = atomic_write_bytes(out, buf.getvalue(), force=args.force)
    if not args.quiet:
        shown = ", ".join(f"{v:g}" for v in values)
        print(f"wrote {len(values)} loops of {args.model} ({name} = {shown}) to {path}")
    return 0
