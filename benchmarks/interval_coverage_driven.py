"""Are the 95 % intervals honest when the imposed motion is measured? (issue 33 item 3)

A driven test measures its motion too. Before issue 33 the fit drove the model with a
Savitzky-Golay smoothing of the measured motion and its derivative, and the intervals knew
nothing of the motion's errors; now a periodic run's motion is a least-squares harmonic
series (unbiased), a motion that does not repeat is estimated by local seventh-order
polynomial fits, and the estimate's errors are propagated into the covariance
(``hystdisc/fitting/motion_error.py``). This benchmark measures both on the same draws
(A/B in one run):

``before``
    ``Options(motion="legacy", motion_errors=False)``: main before issue 33.
``after``
    ``Options(motion="auto", motion_errors=True)``: the default now.

Data (each draw): the driven test of issue 33's command — sines 0.2 rad at 0.5 Hz, 0.1 rad
at 2 Hz, 0.05 rad at 5 Hz, each at 0, 0.5 and 1 A, 4 s at 500 Hz, Gaussian force noise
:data:`FORCE_NOISE` — for a random admissible parameter set: every coefficient of the
family log-uniform in the stress suite's bounds (``benchmarks/stress.py``: 0.5x-2x the demo
value; the standard Bouc-Wen's ``n`` uniform in [1, 3]) and the rig spring ``k_s``
log-uniform in [0.05, 0.5] (a driven machine's spring is small; ``k_s = 0`` would put the
truth on its bound, where a 95 % interval has no stated coverage). A set whose noise-free
simulation diverges is redrawn. Set ``k`` of family ``F`` comes from
``np.random.default_rng([SEED, crc32(F), k])``; every draw has its own noise seed
(:func:`noise_seed`).

Conditions (:data:`CONDITIONS`)
    ``white``: the motion exact (the control). ``motion``: Gaussian noise 1e-4 rad on the
    measured motion. ``q16``: the motion on a 16-bit lattice over the dataset's range
    (``q = ptp / 2**16``; its zero drawn uniformly over one step), no other motion noise.
    ``ramp``: motion noise 1e-4 rad and each sine's amplitude ramped in over the first
    second (``(1 - cos(pi t))/2``): not periodic, so the harmonic series is rejected and
    the local polynomial fits (with their errors propagated) are what is measured.
    ``motion10``: motion noise 1e-3 rad (0.5-2 % of the amplitudes), periodic.

Fit: the true family by output error from the truth (``OutputErrorFitter`` on
``prepare_data``'s data, the intervals exactly as ``discover`` computes them at the
optimum; the start only saves stage 1's time). ``--discover`` fits with
``Discovery(model=...)`` instead (stage 1 and all). Each identifiable parameter's z-score
``(estimate - truth) / SE`` is recorded (the truth in the family's normalization).

Reported per family, condition and variant: coverage of the 95 % intervals (target 0.92-0.98;
the binomial band of 0.95 beside it), z rms (1 for honest standard errors), all inside the
simultaneous (Bonferroni) intervals, and per parameter; the motion noise estimate against
the truth (``motion``: 1e-4; ``q16``: ``q / sqrt(12)``) and how the runs' motion was
estimated.

Run:  nice -n 10 python benchmarks/interval_coverage_driven.py --families bouc-wen-std,dahl \\
          --sets 10 --seeds 3 --out benchmarks/results/interval_coverage_driven.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import stress  # noqa: E402

#: Base of the parameter-set seeds (not the stress suite's).
SEED = 33003
#: Base of the noise seeds.
SEED_BASE = 3300
FORCE_NOISE = 0.03
DRIVES = ("0.2@0.5", "0.1@2", "0.05@5")
CURRENTS = (0.0, 0.5, 1.0)
DURATION = 4.0
FS = 500.0
KS_BOUNDS = ("log", 0.05, 0.5)
CONDITIONS = {
    "white": {"theta_noise": 0.0, "bits": None, "ramp": 0.0},
    "motion": {"theta_noise": 1e-4, "bits": None, "ramp": 0.0},
    "q16": {"theta_noise": 0.0, "bits": 16, "ramp": 0.0},
    "ramp": {"theta_noise": 1e-4, "bits": None, "ramp": 1.0},
    "motion10": {"theta_noise": 1e-3, "bits": None, "ramp": 0.0},
}
#: The variants: name -> the pipeline's options (``motion``, ``motion_errors``).
VARIANTS = {"before": ("legacy", False), "after": ("auto", True)}


def sample_set(family: str, index: int) -> dict[str, float]:
    """Parameter set ``index`` of ``family`` (deterministic; redrawn while it diverges)."""
    from hystdisc.errors import HystdiscError
    from hystdisc.models import Model
    from hystdisc.simulation.synth import generate

    rng = np.random.default_rng([SEED, zlib.crc32(family.encode()), index])
    for _ in range(100):
        p = {k: stress.draw(rng, s) for k, s in {**stress.BOUNDS[family], "k_s": KS_BOUNDS}.items()}
        try:
            ds = generate(
                Model(family, p), "driven", CURRENTS, DURATION, FS, noise=0.0, drives=DRIVES
            )
        except HystdiscError:
            continue
        if all(np.all(np.isfinite(r.torque)) for r in ds.runs):
            return p
    raise RuntimeError(f"{family} set {index}: 100 draws diverged")


def make_dataset(
    family: str, params: dict, condition: str | dict, seed: int, force_noise: float = FORCE_NOISE
):
    """The driven dataset of one draw (``condition``: a name of :data:`CONDITIONS` or such
    a condition itself)."""
    from hystdisc.data.dataset import Dataset, Run
    from hystdisc.models import Model
    from hystdisc.simulation.runs import simulate_driven_runs
    from hystdisc.simulation.synth import generate
    from hystdisc.simulation.synth_checks import parse_drive

    cond = CONDITIONS[condition] if isinstance(condition, str) else condition
    model = Model(family, params)
    if not cond["ramp"]:
        ds = generate(
            model,
            "driven",
            CURRENTS,
            DURATION,
            FS,
            noise=force_noise,
            seed=seed,
            drives=DRIVES,
            theta_noise=cond["theta_noise"],
        )
    else:  # each sine ramped in: (1 - cos(pi t / T)) / 2 over the first T s
        rng = np.random.default_rng(seed)
        t = np.arange(int(round(DURATION * FS))) / FS
        tr = cond["ramp"]
        g = np.where(t < tr, 0.5 * (1 - np.cos(np.pi * t / tr)), 1.0)
        dg = np.where(t < tr, 0.5 * np.pi / tr * np.sin(np.pi * t / tr), 0.0)
        cases = [(parse_drive(d), c) for d in DRIVES for c in CURRENTS]
        ths, ws = [], []
        for d, _ in cases:
            a, om = d["amplitude"], 2 * np.pi * d["frequency"]
            ths.append(a * g * np.sin(om * t))
            ws.append(a * (dg * np.sin(om * t) + g * om * np.cos(om * t)))
        sims, _ = simulate_driven_runs(model, [t] * len(cases), [c for _, c in cases], ths, ws)
        runs = []
        for k, ((_, c), sim, th, w) in enumerate(zip(cases, sims, ths, ws, strict=True)):
            tq = sim.torque + force_noise * rng.standard_normal(t.size)
            thm = th + cond["theta_noise"] * rng.standard_normal(t.size)
            runs.append(Run(str(k), t.copy(), thm, c, torque=tq, theta_dot=w))
        ds = Dataset(runs, "driven", f"ramped driven data of {family}")
    if cond["bits"]:
        q = float(np.ptp(np.concatenate([r.theta for r in ds.runs]))) / 2 ** cond["bits"]
        u = np.random.default_rng([seed, 16]).uniform(0.0, q)
        runs = [
            Run(r.name, r.t, q * np.round((r.theta - u) / q) + u, r.current, torque=r.torque)
            for r in ds.runs
        ]
        ds = Dataset(runs, "driven", f"{ds.source}, 16-bit motion")
    return ds


def true_motion_noise(ds, condition: str) -> float:
    """The motion noise the data were made with (``q / sqrt(12)`` on a lattice)."""
    cond = CONDITIONS[condition]
    if cond["bits"]:
        return (
            float(np.ptp(np.concatenate([r.theta for r in ds.runs])))
            / 2 ** cond["bits"]
            / math.sqrt(12)
        )
    return cond["theta_noise"]


def fit_variant(family: str, params: dict, ds, variant: str, discover: bool) -> dict:
    """Fit ``ds`` with one variant; the z-scores and how the motion was estimated."""
    from threadpoolctl import threadpool_limits

    from hystdisc.fitting import FamilyParametrization, OutputErrorFitter
    from hystdisc.measurement.prepare import prepare_data
    from hystdisc.pipeline import Options, run

    motion, errors = VARIANTS[variant]
    truth = stress.normalized_truth(family, params)
    c0 = time.process_time()
    with threadpool_limits(limits=1), np.errstate(all="ignore"):
        if discover:  # Discovery(model=family, close_loop=False, heldout=False, n_jobs=1)
            opts = Options(model=family, close_loop=False, heldout=False, n_jobs=1)
            state = run(ds, opts.replace(motion=motion, motion_errors=errors))
            fit, fd = state.final_fit, state.fit_data
        else:
            _, fd, _, _ = prepare_data(ds, motion=motion, motion_errors=errors)
            par = FamilyParametrization(family, "driven", truth)
            fit = OutputErrorFitter(fd, par).fit(heldout=False)
    z = {}
    for name, t in truth.items():
        if name not in fit.params or not fit.identifiable.get(name, True):
            continue
        se = fit.stderr[name]
        z[name] = (fit.params[name] - t) / se if se > 0 else math.inf
    mn = fd.motion_noise
    kinds: dict[str, int] = {}
    if mn is not None:
        for v in mn.estimates.values():
            kinds[v["estimate"]] = kinds.get(v["estimate"], 0) + 1
    return {
        "z": z,
        "rms": fit.rms,
        "cpu_s": time.process_time() - c0,
        "motion_noise": None if mn is None else mn.std,
        "motion_method": None if mn is None else mn.method,
        "estimates": kinds,
    }


def noise_seed(family: str, index: int, condition: str, draw: int) -> int:
    """The noise seed of one draw: its own for every family, set, condition and draw (a
    draw shared by the sets would make their z-scores move together: measured, a first
    version that reused ``SEED_BASE + draw`` had per-draw z rms from 0.3 to 1.07 across
    all six sets alike, five effective draws instead of thirty)."""
    key = [SEED_BASE, zlib.crc32(family.encode()), index, zlib.crc32(condition.encode()), draw]
    return int(np.random.SeedSequence(key).generate_state(1)[0])


def one_draw(family: str, index: int, condition: str, draw: int, discover: bool) -> dict:
    """One draw of one case, fitted with every variant."""
    params = sample_set(family, index)
    ds = make_dataset(family, params, condition, noise_seed(family, index, condition, draw))
    out = {
        "family": family,
        "index": index,
        "condition": condition,
        "draw": draw,
        "params": params,
        "true_motion_noise": true_motion_noise(ds, condition),
    }
    for v in VARIANTS:
        out[v] = fit_variant(family, params, ds, v, discover)
    return out


def summarize(zsets: list[dict]) -> dict:
    """Coverage, z rms and the simultaneous all-inside rate of some draws' z-scores."""
    zs = np.array([v for z in zsets for v in z.values()], dtype=float)
    n = zs.size
    joint = [all(abs(v) <= stress.joint_z(len(z)) for v in z.values()) for z in zsets]
    return {
        "draws": len(zsets),
        "pairs": int(n),
        "coverage": float(np.mean(np.abs(zs) <= stress.Z95)) if n else float("nan"),
        "band": 1.96 * math.sqrt(0.95 * 0.05 / max(n, 1)),
        "z_rms": float(np.sqrt(np.mean(zs**2))) if n else float("nan"),
        "joint": float(np.mean(joint)) if zsets else float("nan"),
    }


def render(recs: list[dict], meta: dict) -> str:
    """The markdown report."""
    lines = [
        *stress.report_header(
            "Coverage of the 95 % intervals of driven fits with a measured motion (issue 33)",
            meta,
            f"{len(recs)} draws, each fitted {len(VARIANTS)} ways",
        ),
        "Each draw: issue 33's driven test (3 sines x 3 currents, 4 s at 500 Hz, force noise "
        f"{FORCE_NOISE}) of a random parameter set, fitted by output error; **before** = the "
        "smoothed motion, intervals from the force residual alone (main before issue 33); "
        "**after** = the harmonic motion where it fits (else the smoother), the motion "
        "estimate's errors propagated into the covariance. Target: coverage 0.92-0.98, z rms "
        "1, all inside (simultaneous) >= 0.95. See the script's docstring.",
        "",
        "| condition | family | variant | draws | coverage (95 %) | band | z rms | "
        "all inside (simultaneous) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    keys = sorted(
        {(r["condition"], r["family"]) for r in recs},
        key=lambda k: (list(CONDITIONS).index(k[0]), k[1]),
    )
    for c, f in keys:
        rs = [r for r in recs if r["condition"] == c and r["family"] == f]
        for v in VARIANTS:
            s = summarize([r[v]["z"] for r in rs])
            lines.append(
                f"| {c} | {f} | {v} | {s['draws']} | {s['coverage']:.3f} | +-{s['band']:.3f} | "
                f"{s['z_rms']:.2f} | {s['joint']:.2f} |"
            )
    lines += ["", "Per parameter (coverage / z rms / mean z), before -> after:", ""]
    for c, f in keys:
        rs = [r for r in recs if r["condition"] == c and r["family"] == f]
        names = list(rs[0]["after"]["z"]) if rs else []
        cells = []
        for n in names:
            part = []
            for v in VARIANTS:
                zs = np.array([r[v]["z"][n] for r in rs if n in r[v]["z"]])
                part.append(
                    f"{np.mean(np.abs(zs) <= stress.Z95):.2f}/{np.sqrt(np.mean(zs**2)):.2f}/"
                    f"{np.mean(zs):+.2f}"
                )
            cells.append(f"{n} {part[0]} -> {part[1]}")
        lines.append(f"- {c}, {f}: " + "; ".join(cells))
    lines += ["", "Motion noise estimate (after) against the truth, and the motion estimates:", ""]
    for c, f in keys:
        rs = [r for r in recs if r["condition"] == c and r["family"] == f]
        est = np.array([r["after"]["motion_noise"] for r in rs], dtype=float)
        tru = np.array([r["true_motion_noise"] for r in rs], dtype=float)
        kinds: dict[str, int] = {}
        methods: dict[str, int] = {}
        for r in rs:
            for k, n in r["after"]["estimates"].items():
                kinds[k] = kinds.get(k, 0) + n
            m = r["after"]["motion_method"]
            methods[m] = methods.get(m, 0) + 1
        ratio = (
            f"estimate / truth {np.median(est / tru):.3f} (range {np.min(est / tru):.3f}-"
            f"{np.max(est / tru):.3f})"
            if np.all(tru > 0)
            else f"estimate median {np.median(est):.3g} (truth 0)"
        )
        cpu = {v: np.mean([r[v]["cpu_s"] for r in rs]) for v in VARIANTS}
        lines.append(
            f"- {c}, {f}: {ratio}; method {methods}; runs' motion {kinds}; CPU per fit "
            + ", ".join(f"{v} {s:.2f} s" for v, s in cpu.items())
        )
    worst = sorted(
        (
            (abs(z), r["family"], r["index"], r["condition"], r["draw"], n)
            for r in recs
            for n, z in r["after"]["z"].items()
        ),
        reverse=True,
    )[:8]
    lines += [
        "",
        "Largest |z| after: "
        + ", ".join(f"{f}/{k}/{c} draw {d} {n} {z:.2f}" for z, f, k, c, d, n in worst)
        + ".",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="bouc-wen-std")
    ap.add_argument("--sets", type=int, default=6, help="parameter sets per family (0, 1, ...)")
    ap.add_argument("--seeds", type=int, default=6, help="noise draws per set and condition")
    ap.add_argument("--conditions", default=",".join(CONDITIONS))
    ap.add_argument("--discover", action="store_true", help="fit with Discovery(model=...)")
    ap.add_argument(
        "--out", default=str(ROOT / "benchmarks" / "results" / "interval_coverage_driven.md")
    )
    ap.add_argument("--no-run", action="store_true", help="re-render the markdown from the JSON")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.no_run:
        data = json.loads(out.with_suffix(".json").read_text())
        out.write_text(render(data["draws"], data["meta"]))
        return 0
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()]
    for f in fams:
        if f not in stress.BOUNDS:
            ap.error(f"unknown family {f}; use {', '.join(stress.BOUNDS)}")
    for c in conds:
        if c not in CONDITIONS:
            ap.error(f"unknown condition {c}; use {', '.join(CONDITIONS)}")
    jobs = [
        (f, k, c, d)
        for f in fams
        for k in range(args.sets)
        for c in conds
        for d in range(args.seeds)
    ]
    t0 = time.time()
    print(f"{len(jobs)} draws", flush=True)
    recs = []
    for i, job in enumerate(jobs, 1):
        rec = one_draw(*job, args.discover)
        recs.append(rec)
        zs = {v: max((abs(z) for z in rec[v]["z"].values()), default=0.0) for v in VARIANTS}
        print(
            f"[{i}/{len(jobs)}] {'/'.join(map(str, job))}: max |z| "
            + ", ".join(f"{v} {z:.2f}" for v, z in zs.items()),
            flush=True,
        )
    meta = {
        "command": "python benchmarks/interval_coverage_driven.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "commit": stress._commit(),
        "when": time.strftime("%Y-%m-%d %H:%M"),
        "wall_s": time.time() - t0,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps({"meta": meta, "draws": recs}, indent=1))
    out.write_text(render(recs, meta))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
