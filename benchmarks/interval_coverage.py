"""Are the 95 % intervals honest? Coverage over noise draws (issue 16: the stress suite's
``ci`` criterion measured where it means something).

One stress-suite case (a family, a parameter set, a condition) is a single noise draw: the
truth lands outside a correct 95 % interval in 5 % of draws, and outside one of ``k``
intervals far more often. Whether a miss is bad luck or a method that is too confident is
a question about the distribution over draws, which this benchmark samples: for each
parameter set of the stress suite's sampler (``benchmarks/stress.py``: same bounds, same
sets) it simulates ``--seeds`` noise draws with the package's simulator (the code behind
``hystdisc simulate``), fits the true family by output error (``Discovery(model=...)``,
the fit and its intervals exactly as ``hystdisc discover --model`` computes them; no
closing loop or held-out folds, which do not change the declared fit), and records each
identifiable parameter's z-score ``(estimate - truth) / SE``. A noise-free encoder
condition (``enc4096``, ``enc2048``) has no noise to draw: each draw is the encoder's zero,
uniform over one count (:func:`encoder_draw`).

Reported per family and condition:
    coverage
        the fraction of (draw, parameter) pairs with the truth inside the 95 % interval
        (0.95 for honest intervals; a binomial band is printed beside it);
    z rms
        the root mean square of the z-scores (1 for honest standard errors; above 1: the
        intervals are too narrow, below: too wide);
    all inside (simultaneous)
        the fraction of draws with every z below the stress suite's simultaneous bound
        (Bonferroni, ``stress.joint_z``): at least 0.95 for honest intervals.

Run:  python benchmarks/interval_coverage.py --families bouc-wen,bouc-wen-std --sets 4 --seeds 10 \
          --jobs 2 --out benchmarks/results/coverage.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import stress  # noqa: E402

#: Base of the noise seeds (draw ``d`` of a case uses ``SEED_BASE + d``; the stress suite's
#: own draws use other seeds).
SEED_BASE = 7000


def one_draw(family: str, index: int, condition: str, draw: int, duration: float) -> dict:
    """Simulate draw ``draw`` of a stress case and fit its family; the z-scores."""
    from hystdisc.estimator import Discovery
    from hystdisc.models import Model
    from hystdisc.simulation.synth import generate

    params, _ = stress.sample_set(family, index, duration)
    truth = stress.normalized_truth(family, params)
    cond = stress.CONDITIONS[condition]
    counts = cond["encoder"]
    noise_free_encoder = bool(counts) and not cond["noise"]
    ds = generate(
        Model(family, params),
        currents=stress.CURRENTS,
        duration=duration,
        noise=cond["noise"],
        theta0=stress.THETA0,
        seed=SEED_BASE + draw,
        encoder_counts=None if noise_free_encoder else counts,
        spikes=cond["spikes"],
    )
    if noise_free_encoder:  # the draw is the encoder's zero, uniform over one count
        ds = encoder_draw(ds, 2.0 * math.pi / counts, SEED_BASE + draw)
    fit = Discovery(model=family, close_loop=False, heldout=False, n_jobs=1).fit(ds).final_fit_
    z = {}
    for name, t in truth.items():
        if name not in fit.params or not fit.identifiable.get(name, True):
            continue
        se = fit.stderr[name]
        z[name] = (fit.params[name] - t) / se if se > 0 else math.inf
    return {"family": family, "index": index, "condition": condition, "draw": draw, "z": z}


def encoder_draw(ds, q: float, seed: int):
    """``ds`` read by an encoder of step ``q`` whose zero is drawn uniformly over one count
    (noise-free data have no noise to draw: the encoder's zero is what varies)."""
    from hystdisc.data.dataset import Dataset, Run

    u = np.random.default_rng(seed).uniform(0.0, q)
    runs = [Run(r.name, r.t, q * np.round((r.theta - u) / q) + u, r.current) for r in ds.runs]
    return Dataset(runs, ds.experiment, source=f"{ds.source}, encoder zero {u / q:.3f} counts")


def summarize(recs: list[dict]) -> dict:
    """Coverage, z rms and the simultaneous all-inside rate of some draws."""
    zs = np.array([v for r in recs for v in r["z"].values()], dtype=float)
    inside = np.abs(zs) <= stress.Z95
    joint = [all(abs(v) <= stress.joint_z(len(r["z"])) for v in r["z"].values()) for r in recs]
    n = zs.size
    band = 1.96 * math.sqrt(0.95 * 0.05 / max(n, 1))
    return {
        "draws": len(recs),
        "pairs": int(n),
        "coverage": float(inside.mean()) if n else float("nan"),
        "band": band,
        "z_rms": float(np.sqrt(np.mean(zs**2))) if n else float("nan"),
        "joint": float(np.mean(joint)) if recs else float("nan"),
    }


def render(recs: list[dict], meta: dict) -> str:
    """The markdown report."""
    lines = [
        *stress.report_header(
            "Coverage of the 95 % intervals over noise draws (issue 16)", meta, f"{len(recs)} fits"
        ),
        "Each fit: a stress-suite parameter set (`benchmarks/stress.py`), simulated with a "
        f"fresh noise draw (seeds {SEED_BASE}+), the true family fitted by output error. "
        "Honest intervals: coverage 0.95 (within the binomial band), z rms 1, all inside "
        "(simultaneous) >= 0.95.",
        "",
        "| condition | family | set | draws | coverage (95 %) | band | z rms | all inside (simultaneous) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    keys = sorted({(r["condition"], r["family"]) for r in recs})
    for c, f in keys:
        rs = [r for r in recs if r["condition"] == c and r["family"] == f]
        for k in sorted({r["index"] for r in rs}) + [None]:
            sel = [r for r in rs if k is None or r["index"] == k]
            s = summarize(sel)
            label = "**all**" if k is None else str(k)
            lines.append(
                f"| {c} | {f} | {label} | {s['draws']} | {s['coverage']:.3f} | "
                f"+-{s['band']:.3f} | {s['z_rms']:.2f} | {s['joint']:.2f} |"
            )
    worst = sorted(
        (
            (abs(v), r["family"], r["index"], r["condition"], r["draw"], n)
            for r in recs
            for n, v in r["z"].items()
        ),
        reverse=True,
    )[:8]
    lines += [
        "",
        "Largest |z| over all draws: "
        + ", ".join(f"{f}/{k}/{c} draw {d} {n} {z:.2f}" for z, f, k, c, d, n in worst)
        + ".",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="bouc-wen,bouc-wen-std")
    ap.add_argument("--sets", type=int, default=4, help="parameter sets per family")
    ap.add_argument(
        "--first-set",
        type=int,
        default=0,
        help="the first set (sets first-set, first-set + 1, ...)",
    )
    ap.add_argument("--seeds", type=int, default=10, help="noise draws per set")
    ap.add_argument("--conditions", default="white")
    ap.add_argument("--duration", type=float, default=stress.DURATION)
    ap.add_argument("--jobs", type=int, default=1, help="fits in parallel (processes)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "interval_coverage.md"))
    args = ap.parse_args(argv)
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()]
    for f in fams:
        if f not in stress.BOUNDS:
            ap.error(f"unknown family {f}; use {', '.join(stress.BOUNDS)}")
    for c in conds:
        if c not in stress.CONDITIONS:
            ap.error(f"unknown condition {c}; use {', '.join(stress.CONDITIONS)}")
    jobs = [
        (f, k, c, d, args.duration)
        for f in fams
        for k in range(args.first_set, args.first_set + args.sets)
        for c in conds
        for d in range(args.seeds)
    ]
    t0 = time.time()
    print(f"{len(jobs)} fits", flush=True)
    recs = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for i, rec in enumerate(pool.map(one_draw, *zip(*jobs, strict=True)), 1):
            recs.append(rec)
            zmax = max((abs(v) for v in rec["z"].values()), default=0.0)
            print(
                f"[{i}/{len(jobs)}] {rec['family']}/{rec['index']}/{rec['condition']} "
                f"draw {rec['draw']}: max |z| {zmax:.2f}",
                flush=True,
            )
    meta = {
        "command": "python benchmarks/interval_coverage.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "commit": stress._commit(),
        "when": time.strftime("%Y-%m-%d %H:%M"),
        "wall_s": time.time() - t0,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps({"meta": meta, "fits": recs}, indent=1))
    out.write_text(render(recs, meta))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
