"""Two checks of a channel delay on the driven suite's cases (issue 33, session 25).

``interp``: each case's true model driven by its exactly delayed motion, against the same
model driven by the recorded motion shifted by linear interpolation and by the cubic of
:func:`hystdisc.measurement.chain.smoothly_delayed` (no noise); the RMS model error of
each after the first :data:`SKIP` samples (before its first sample a shifted record holds
its first value, and a hysteretic state remembers that), and the linear one over the
case's force noise.

``folds``: a Bingham case's leave-one-condition-out folds, each refitted on its own runs;
the fold's ``tau_d`` error in its own standard errors, and the held-out error of its
left-out runs over the noise at the fold's parameters, at the fold's parameters with the
true ``tau_d``, and at the truth.

Usage (``WORK`` is a ``stress_driven.py --work`` folder holding the cases' CSVs, results
and records)::

    python benchmarks/delay_checks.py interp WORK bouc-wen_15_delay dahl_15_delay
    python benchmarks/delay_checks.py folds WORK bingham_10_delay
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import stress_driven as sd  # puts this checkout first on the path

from hystdisc import load
from hystdisc.apply.predict import predict_dataset
from hystdisc.fitting import FamilyParametrization, OutputErrorFitter
from hystdisc.measurement.chain import delayed, smoothly_delayed
from hystdisc.measurement.prepare import prepare_data
from hystdisc.models import Model
from hystdisc.simulation import simulate_driven_runs
from hystdisc.simulation.scenarios import generate_from_scenario, scenario_model

#: Samples at the start of a run left out of both checks' errors (the fit leaves out a
#: run's start too).
SKIP = 200


def interp(work: Path, name: str) -> str:
    """The model error of linear and cubic shifts at the truth of case ``name``."""
    rec = json.loads((work / f"{name}.record.json").read_text())
    tau = rec["truth"]["tau_d"]
    sc = {
        "model": rec["family"], "params": rec["params_sampled"], "experiment": "driven",
        "currents": list(sd.CURRENTS), "drives": [f"{a}@{f}" for a, f in sd.DRIVES],
        "duration": sd.DURATION, "fs": sd.FS, "noise": 0.0, "delay": tau,
    }  # fmt: skip
    ds = generate_from_scenario(sc)
    mdl = scenario_model(sc)
    out = {}
    for how, shift in (("linear", delayed), ("cubic", smoothly_delayed)):
        ths = [shift(r.t, r.theta, tau) for r in ds.runs]
        ws = [shift(r.t, r.theta_dot, tau) for r in ds.runs]
        sims, _ = simulate_driven_runs(
            mdl, [r.t for r in ds.runs], [r.current for r in ds.runs], ths, ws
        )
        err = np.concatenate(
            [(s.torque - r.torque)[SKIP:] for s, r in zip(sims, ds.runs, strict=True)]
        )
        out[how] = float(np.sqrt(np.mean(err**2)))
    return (
        f"{rec['case']}: linear {out['linear']:.2e}, cubic {out['cubic']:.2e}, "
        f"linear / noise {out['linear'] / rec['noise']:.3f}"
    )


def folds(work: Path, name: str) -> list[str]:
    """Each fold of a Bingham delay case refitted on its own runs (module docstring)."""
    res = json.loads((work / f"{name}.json").read_text())
    rec = json.loads((work / f"{name}.record.json").read_text())
    ds = load(str(work / f"{name}.csv"))
    fd = prepare_data(ds)[1]
    start = {k: v["value"] for k, v in res["final"]["parameters"].items()}
    truth, tau0 = rec["truth"], rec["truth"]["tau_d"]

    def heldout(vals: dict, runs: list[int]) -> float:
        base = {k: v for k, v in vals.items() if k != "tau_d"}
        tm = Model("bingham", base, effects={"channel_delay": {"tau_d": vals["tau_d"]}})
        sub = dataclasses.replace(ds, runs=[ds.runs[k] for k in runs])
        pred = predict_dataset(tm.to_terms(), sub, detect_filter=False)
        e = np.concatenate([(y - r.torque)[SKIP:] for y, r in zip(pred, sub.runs, strict=True)])
        return float(np.sqrt(np.mean(e**2))) / rec["noise"]

    lines = []
    for held in fd.folds():
        keep = [k for k in range(fd.n_runs) if k not in held]
        par = FamilyParametrization("bingham", "driven", start, effects=("channel_delay",))
        fit = OutputErrorFitter(fd.subset(keep), par).fit(heldout=False)
        p, se = dict(fit.params), fit.stderr["tau_d"]
        lines.append(
            f"{rec['case']} without runs {held}: tau_d error {(p['tau_d'] - tau0) / se:+.2f} "
            f"s.e. (s.e. {se:.2e} s); held-out / noise {heldout(p, held):.3f}, with the "
            f"true tau_d {heldout({**p, 'tau_d': tau0}, held):.3f}, truth "
            f"{heldout(truth, held):.3f}"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("check", choices=["interp", "folds"])
    ap.add_argument("work", type=Path, help="the stress_driven.py --work folder")
    ap.add_argument("cases", nargs="+", help="case file stems, e.g. bingham_10_delay")
    args = ap.parse_args(argv)
    for name in args.cases:
        print(
            interp(args.work, name) if args.check == "interp" else "\n".join(folds(args.work, name))
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
