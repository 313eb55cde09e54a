"""The library refit's fresh device (``benchmarks/results/library_refit.md``).

Drawn before anything was looked at: bouc-wen-std, each demo parameter scaled by a factor
drawn in [0.6, 1.6] (seed 2026), driven; plus a force outside the catalogue: a friction that differs in tension and compression and grows with the current,
F_extra = 0.03 (1 + 2 i) [theta_dot > 0]. Training: 3 drives x 3 currents; new tests: 3
other drives at 5 currents (two never trained).

Usage: ``python benchmarks/library_refit_fresh.py`` writes ``fresh.csv`` and
``fresh_new.csv`` in the current folder; then ``hystdisc discover fresh.csv --out res`` and
``hystdisc predict res/results.json fresh_new.csv -o pred.csv``.
"""

import numpy as np

from hystdisc import Model
from hystdisc.data import Dataset, Run, write_csv
from hystdisc.simulation.synth import generate

rng = np.random.default_rng(2026)
base = Model("bouc-wen-std", {"k_s": 0.0})
params = {
    k: (v * rng.uniform(0.6, 1.6) if k not in ("k_s", "n") and v != 0 else v)
    for k, v in base.params.items()
}
print(params)
truth = Model("bouc-wen-std", params)


def make(currents, drives, seed, out):
    d = generate(
        truth,
        experiment="driven",
        currents=currents,
        drives=drives,
        duration=4.0,
        noise=0.01,
        seed=seed,
    )
    runs = [
        Run(
            r.name,
            r.t,
            r.theta,
            r.current,
            torque=r.torque + 0.03 * (1 + 2 * r.current) * (np.gradient(r.theta, r.t) > 0),
        )
        for r in d.runs
    ]
    write_csv(Dataset(runs, "driven", out), out, force=True)
    print(
        out,
        len(runs),
        "runs; force RMS",
        float(np.sqrt(np.mean(np.concatenate([r.torque for r in runs]) ** 2))),
    )


make((0, 0.5, 1), ["0.2@1.3", "0.1@2.7", "0.15@0.8"], 7, "fresh.csv")
make((0, 0.25, 0.5, 0.75, 1), ["0.12@1.9", "0.18@1.1", "0.08@3.3"], 8, "fresh_new.csv")
