"""``hystdisc simulate``: write a synthetic dataset of a known model (long CSV).

Examples::

    hystdisc simulate --model bouc-wen --set k_s=158 --set c_1=0.8 --currents 0,0.5,1 -o bw.csv
    hystdisc simulate --model dahl --effect current_viscous:c_i=0.6 -o dahl_cv.csv
    hystdisc simulate --model dahl --effect series_compliance:k_w=900,c_w=3,m_w=0.3 -o w.csv
    hystdisc simulate --model bouc-wen --set k_s=0 --experiment driven --drive 0.3@1 -o d.csv
    hystdisc simulate --scenario data_synth/dahl.toml --seed 7 -o dahl_seed7.csv
    hystdisc simulate --model dahl --noise 1e-3 --spikes 6:0.05 -o dahl_spikes.csv
    hystdisc simulate --model dahl --experiment driven --prefilter period_fraction=0.1 -o f.csv
    hystdisc simulate --regenerate data_synth --force
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from hystdisc import registry
from hystdisc.errors import HystdiscError

HELP = "write a synthetic dataset of a known model (long CSV)"
DESCRIPTION = (
    "Simulate a model on the rig and write the measured signals as a long CSV "
    "(run,t,theta,current + torque for driven, input for forced). Unset parameters "
    "take the model's demo defaults; flags override the values of --scenario."
)
EPILOG = (
    "examples: hystdisc simulate --model bouc-wen --set k_s=158 --currents 0,0.5,1 "
    "-o bw.csv | hystdisc simulate --regenerate data_synth --force"
)


def add_model_options(p: argparse.ArgumentParser, set_help: str, effect_help: str) -> None:
    """The repeatable ``--set NAME=VALUE`` and ``--effect NAME[:P=V,...]`` (read with
    :func:`parse_assignments` and :func:`parse_effect`)."""
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help=set_help)
    p.add_argument(
        "--effect", action="append", default=[], metavar="NAME[:P=V,...]", help=effect_help
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc simulate``."""
    p.add_argument("--model", help=f"family: {', '.join(registry.family_names())}")
    add_model_options(
        p,
        "a model or rig parameter, e.g. k_s=158 (repeatable; or comma separated)",
        "add a catalogued effect, e.g. coulomb or coulomb:f_c=0.5 (repeatable); the beam "
        "on a compliant wheel (release): series_compliance:k_w=900,c_w=3,m_w=0.3 (per unit "
        "beam inertia); a driven damper behind a compliant mount: the same effect, with "
        "k_w, c_w, m_w in the units of the force and motion",
    )
    p.add_argument("--currents", metavar="LIST", help="coil currents in A, e.g. 0,0.25,0.5,0.75,1")
    release, *others = registry.experiment_names()
    p.add_argument(
        "--experiment", help=f"{release} (default), {', '.join(others[:-1])} or {others[-1]}"
    )
    for flag, metavar, text in (
        ("--theta0", "RAD", "initial angle of release/forced runs"),
        ("--duration", "S", "length of every run in s (default 6)"),
        ("--fs", "HZ", "sampling rate in Hz (default 1000)"),
        (
            "--noise",
            "STD",
            "noise std of the measured signal: rad (release/forced) or N*m (driven torque)",
        ),
        ("--theta-noise", "STD", "driven only: noise std of theta in rad"),
        (
            "--delay",
            "SECONDS",
            "driven/forced only: record the output channel (driven torque, forced angle) "
            "SECONDS late against the other (a channel delay; default 0)",
        ),
        ("--seed", "N", "random seed (default 0)"),
        ("--encoder-counts", "N", "quantize theta to 2*pi/N rad"),
        (
            "--spikes",
            "N:SIZE",
            "add N isolated glitches of +-SIZE (rad, or N*m on a driven torque) to single "
            "samples of the measured signal, at random over all runs (seeded by --seed)",
        ),
    ):
        p.add_argument(flag, metavar=metavar, help=text)
    p.add_argument(
        "--prefilter",
        metavar="window=N|period_fraction=F[,channels=A+B]",
        help="the recorded channels passed through a causal moving average of N samples or "
        "of F of each run's motion period (zero initial state; a rig's [filter], which a rig "
        "file given to discover --rig declares); channels default to all recorded, e.g. "
        "channels=theta+torque",
    )
    p.add_argument(
        "--drive",
        action="append",
        default=[],
        metavar="A@F",
        help="driven only: sine of amplitude A rad at F Hz (repeatable), e.g. 0.3@1.0",
    )
    p.add_argument(
        "--input",
        metavar="KIND[:K=V,...]",
        help="forced only: multisine:rms=10,f_min=0.5,f_max=5 or sine:amplitude=10,frequency=1",
    )
    p.add_argument("--scenario", metavar="FILE.toml", help="read the settings from a scenario")
    p.add_argument(
        "--regenerate",
        metavar="DIR",
        help=(
            "regenerate every DIR/*.toml scenario into its output CSV (beside the scenario, or "
            "into the folder given by -o); existing CSVs are only replaced with --force, and "
            "without it nothing is written when any of them exists"
        ),
    )
    p.add_argument("-o", "--output", metavar="FILE", help="output CSV (folder with --regenerate)")
    p.add_argument("--force", action="store_true", help="overwrite existing output")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


# ----------------------------------------------------------------------------- parsing


def parse_float(text: str, what: str) -> float:
    """``text`` as a float, or a one-line error naming ``what``."""
    try:
        return float(text)
    except (TypeError, ValueError):
        raise HystdiscError(f"{what} {text!r} is not a number; fix: give a number") from None


def parse_int(text: str, what: str) -> int:
    """``text`` as an int, or a one-line error naming ``what``."""
    try:
        return int(text)
    except (TypeError, ValueError):
        raise HystdiscError(
            f"{what} {text!r} is not a whole number; fix: give an integer"
        ) from None


def parse_assignments(items: list[str], what: str) -> dict[str, float]:
    """``["k_s=158", "c_1=0.8,c_2=0.6"]`` -> ``{"k_s": 158.0, ...}``."""
    out: dict[str, float] = {}
    for item in items:
        for part in item.split(","):
            part = part.strip()
            if not part:
                continue
            if part.count("=") != 1:
                raise HystdiscError(
                    f"{what} {part!r} is not NAME=VALUE; fix: write e.g. --set k_s=158"
                )
            key, val = (s.strip() for s in part.split("="))
            if not key:
                raise HystdiscError(f"{what} {part!r} has no name; fix: write e.g. --set k_s=158")
            out[key] = parse_float(val, f"{what} {key} =")
    return out


def parse_effect(text: str) -> tuple[str, dict[str, float]]:
    """``"coulomb:f_c=0.5"`` -> ``("coulomb", {"f_c": 0.5})``; ``"coulomb"`` -> defaults."""
    name, _, rest = text.partition(":")
    name = name.strip()
    if not name:
        raise HystdiscError(
            f"--effect {text!r} has no effect name; fix: write e.g. --effect coulomb:f_c=0.5"
        )
    return name, parse_assignments([rest], f"--effect {name} parameter") if rest else {}


def parse_input(text: str) -> dict[str, Any]:
    """``"multisine:rms=10,f_min=0.5,f_max=5"`` -> input spec dict."""
    kind, _, rest = text.partition(":")
    spec: dict[str, Any] = {"kind": kind.strip()}
    spec.update(parse_assignments([rest], "--input setting") if rest else {})
    return spec


def parse_prefilter(text: str) -> dict[str, Any]:
    """``"period_fraction=0.1,channels=theta+torque"`` -> a ``[filter]`` table.

    Examples
    --------
    >>> parse_prefilter("window=5,channels=torque")
    {'window': 5, 'channels': ['torque']}
    """
    out: dict[str, Any] = {}
    for part in (s.strip() for s in text.split(",")):
        key, sep, val = (s.strip() for s in part.partition("="))
        if not sep or key not in ("window", "period_fraction", "channels"):
            raise HystdiscError(
                f"--prefilter {text!r} is not window=N, period_fraction=F or channels=A+B; "
                "fix: write e.g. --prefilter period_fraction=0.1"
            )
        if key == "window":
            out[key] = parse_int(val, "--prefilter window")
        elif key == "period_fraction":
            out[key] = parse_float(val, "--prefilter period_fraction")
        else:
            out[key] = [c.strip() for c in val.split("+") if c.strip()]
    return out


def settings_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """Scenario (if any) overridden by the command-line flags."""
    from hystdisc.simulation.scenarios import load_scenario
    from hystdisc.simulation.synth_checks import parse_drive

    sc: dict[str, Any] = load_scenario(args.scenario) if args.scenario else {}
    sc.setdefault("params", {})
    sc.setdefault("effects", {})
    if args.model is not None:
        sc["model"] = args.model
    sc.setdefault("model", None)
    sc["params"] = {**sc["params"], **parse_assignments(args.set, "--set")}
    for text in args.effect:
        name, ep = parse_effect(text)
        sc["effects"][name] = {**sc["effects"].get(name, {}), **ep}
    if args.currents is not None:
        parts = [s.strip() for s in args.currents.split(",") if s.strip()]
        if not parts:
            raise HystdiscError("--currents is empty; fix: give e.g. --currents 0,0.5,1")
        sc["currents"] = [parse_float(s, "current") for s in parts]
    if args.experiment is not None:
        sc["experiment"] = args.experiment
    for flag, key in (
        ("theta0", "theta0"),
        ("duration", "duration"),
        ("fs", "fs"),
        ("noise", "noise"),
        ("theta_noise", "theta_noise"),
        ("delay", "delay"),
    ):
        val = getattr(args, flag)
        if val is not None:
            sc[key] = parse_float(val, f"--{flag.replace('_', '-')}")
    if args.seed is not None:
        sc["seed"] = parse_int(args.seed, "--seed")
    if args.encoder_counts is not None:
        sc["encoder_counts"] = parse_int(args.encoder_counts, "--encoder-counts")
    if args.spikes is not None:
        count, sep, size = args.spikes.partition(":")
        if not sep:
            raise HystdiscError(
                f"--spikes {args.spikes!r} is not N:SIZE; fix: write e.g. --spikes 6:0.05"
            )
        sc["spikes"] = (parse_int(count, "--spikes count"), parse_float(size, "--spikes size"))
    if args.prefilter is not None:
        sc["prefilter"] = parse_prefilter(args.prefilter)
    if args.drive:
        sc["drives"] = [parse_drive(d) for d in args.drive]
    if args.input is not None:
        sc["input"] = parse_input(args.input)
    if args.output is not None:
        sc["output"] = args.output
    if not sc.get("model"):
        raise HystdiscError(
            f"no model given; fix: pass --model ({', '.join(registry.family_names())}) or "
            "--scenario FILE.toml"
        )
    return sc


def model_label(sc: dict[str, Any]) -> str:
    """``"dahl + current_viscous"``: the family and the effects of a scenario."""
    return " + ".join([str(sc["model"]), *sc.get("effects", {})])


def describe(ds, path: Path, model: str) -> str:
    """One line saying what was written."""
    import numpy as np

    samples = sum(r.n for r in ds.runs)
    cur = ", ".join(f"{c:g}" for c in sorted(set(np.round(ds.currents, 9))))
    return (
        f"wrote {len(ds)} {ds.experiment} runs of {model} ({samples} samples, currents "
        f"{cur} A) to {path}"
    )


# ----------------------------------------------------------------------------- run


def _regenerate(args: argparse.Namespace) -> int:
    from hystdisc.simulation.scenarios import generate_from_scenario, load_scenario
    from hystdisc.simulation.synth import write_dataset

    folder = Path(args.regenerate)
    if not folder.is_dir():
        raise HystdiscError(
            f"{folder}: is not a folder; fix: pass the folder holding the scenario *.toml files"
        )
    scen_files = sorted(folder.glob("*.toml"))
    if not scen_files:
        raise HystdiscError(f"{folder}: holds no *.toml scenarios; fix: check the folder")
    outdir = Path(args.output) if args.output else None
    if outdir is not None and not outdir.is_dir():
        raise HystdiscError(
            f"{outdir}: is not a folder; fix: with --regenerate, -o names an existing folder"
        )
    jobs = []
    for f in scen_files:
        sc = load_scenario(f)
        if not sc.get("output"):
            raise HystdiscError(f'{f}: no output file named; fix: add output = "NAME.csv"')
        out = Path(sc["output"]) if outdir is None else outdir / Path(sc["output"]).name
        jobs.append((sc, out))
    if not args.force:
        existing = [str(out) for _, out in jobs if out.exists()]
        if existing:
            more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
            raise HystdiscError(
                f"{existing[0]}: already exists{more}; fix: pass --force to regenerate over "
                "the existing files"
            )
    for sc, out in jobs:
        ds = generate_from_scenario(sc)
        path = write_dataset(ds, out, force=args.force)
        if not args.quiet:
            print(describe(ds, path, model_label(sc)))
    return 0


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc simulate``."""
    from hystdisc.simulation.scenarios import generate_from_scenario
    from hystdisc.simulation.synth import write_dataset

    if args.regenerate:
        if args.scenario:
            raise HystdiscError(
                "--regenerate and --scenario exclude each other; fix: use one of them"
            )
        return _regenerate(args)
    sc = settings_from_args(args)
    if not sc.get("output"):
        raise HystdiscError("no output file; fix: pass -o FILE.csv")
    out = Path(sc["output"])
    if out.exists() and not args.force:
        raise HystdiscError(
            f"{out}: already exists; fix: pass --force to overwrite or choose another -o"
        )
    ds = generate_from_scenario(sc)
    path = write_dataset(ds, out, force=args.force)
    if not args.quiet:
        print(describe(ds, path, model_label(sc)))
    return 0
