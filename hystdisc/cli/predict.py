"""``hystdisc predict``: simulate a fitted model on new runs.

Example::

    hystdisc predict results.json new_runs.csv -o predicted.csv
"""

from __future__ import annotations

import argparse
import warnings

from hystdisc.cli.common import add_data_options, load_data
from hystdisc.errors import HystdiscError, HystdiscWarning

HELP = "simulate a fitted model (results.json) on new runs"
DESCRIPTION = (
    "Simulate the model of a results.json on the runs of DATA (release from each run's "
    "first angle, driven from its motion, forced from its input) and write "
    "run,t,current,<measured>,<measured>_pred. The final model includes the open "
    "library's terms when its refit accepted them (open_library.refit)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``hystdisc predict``."""
    p.add_argument("results", metavar="RESULTS.json")
    p.add_argument("data", nargs="+", metavar="DATA")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv")
    p.add_argument(
        "--family",
        help="use this family's fit (without effects or library terms) instead of the final model",
    )
    add_data_options(p)
    p.add_argument("--force", action="store_true", help="overwrite OUT.csv")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")


def _load_for(res, args: argparse.Namespace):
    """The data, read as the experiment the fit is of; a one-line error when they hold
    another kind of test (a release fit cannot say anything about a driven record)."""
    if args.experiment is not None:
        return load_data(args, args.data)
    try:  # what the files hold, from their columns
        data = load_data(args, args.data)
    except HystdiscError as exc:
        if "ambiguous" not in str(exc):  # both a torque and an input column
            raise
        args.experiment = res.experiment
        return load_data(args, args.data)
    if res.experiment and data.experiment != res.experiment:
        from hystdisc.registry import get_experiment

        held = get_experiment(data.experiment)
        what = {"driven": "a torque column", "forced": "an input column"}.get(
            data.experiment, "no torque or input column"
        )
        raise HystdiscError(
            f"{data.source}: holds {held.name} runs ({what}), but {args.results} is a fit of "
            f"{res.experiment} runs, which cannot predict them; fix: give runs of a "
            f"{res.experiment} test, or fit {held.name} runs first (hystdisc discover "
            f"{' '.join(args.data)}) and predict with that results.json"
        )
    return data


def run(args: argparse.Namespace) -> int:
    """Execute ``hystdisc predict``."""
    import numpy as np

    from hystdisc.apply.predict import beyond_envelope, predict_dataset
    from hystdisc.data import atomic_write_text, with_detected_filter
    from hystdisc.results import Results
    from hystdisc.simulation import HOLDS

    res = Results.load(args.results)
    if args.family and args.family not in res.families:
        raise HystdiscError(
            f"{args.results}: no fit of family '{args.family}'; fix: use one of "
            f"{', '.join(res.families)}"
        )
    refit = res.open_library.refit if res.open_library is not None else None
    extra = None
    if refit is not None and refit.accepted and not args.family:
        # the final model with the open library's accepted terms, as they were refitted
        tm, extra = res.simulation_model(refitted=True), dict(refit.coefficients)
    else:
        tm = res.simulation_model(args.family)
    data = _load_for(res, args)
    hold = res.input_hold or "cubic"
    if hold not in HOLDS:
        raise HystdiscError(
            f"{args.results}: unknown input_hold {hold!r}; fix: use one of {', '.join(HOLDS)}"
        )
    for line in beyond_envelope(res.envelope, data):
        warnings.warn(line, HystdiscWarning, stacklevel=1)
    data, found = with_detected_filter(data)
    if found is not None:  # the prediction goes through it, as the fit saw its own
        warnings.warn(
            f"{data.source}: {found.describe()}: the prediction goes through it",
            HystdiscWarning,
            stacklevel=1,
        )
    preds = predict_dataset(tm, data, res.experiment, hold, extra=extra)
    meas = data.measured()
    lines = [f"run,t,current,{meas},{meas}_pred"]
    rms = []
    for r, p in zip(data.runs, preds, strict=True):
        y = getattr(r, meas)
        rms.append(float(np.sqrt(np.mean((p - y) ** 2))))
        lines.extend(
            f"{r.name},{t:.10g},{r.current:.10g},{a:.10g},{b:.10g}"
            for t, a, b in zip(r.t, y, p, strict=True)
        )
    out = atomic_write_text(args.output, "\n".join(lines) + "\n", force=args.force)
    if not args.quiet:
        for r, e in zip(data.runs, rms, strict=True):
            print(f"run {r.name} ({r.current:g} A): RMS {meas} error {e:.4g}")
        if extra:
            left = f" (without {', '.join(refit.redundant)}, which only stood in for them)"
            print(
                f"with the open library's accepted terms: {refit.equation}"
                + (left if refit.redundant else "")
            )
        print(f"wrote {out} ({len(data.runs)} runs)")
    return 0
