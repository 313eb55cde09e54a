"""Benchmark (issue 7): how discover's time and memory grow with the size of the problem.

Three sweeps on simulated SAS release data (Bouc-Wen seed form, demo defaults, 1 mrad
noise, theta0 = 0.3 rad, 6 s per run), each from a base of 5 runs (currents 0..1 A) at
1 kHz with ``Discovery()``'s defaults (all families, held-out errors, closing loop):

- **samples per run**: the sampling rate is varied (6 s at 167 Hz .. 16.7 kHz, i.e. 1k to
  100k samples per run; a release decays, so longer runs would only add trimmed tail);
- **runs**: 1 .. 50 runs, currents evenly spaced over 0..1 A (one run, at 0.5 A, compares
  the families at one current: ``single_current=True``, current-dependent parameters 0);
- **library size**: the number of families fitted by output error (1, 2, 3, 5) and of
  hysteresis shapes searched in stage 1 (1 .. 4).

Every point runs in a forked child process (the imports and numba's compiled kernels are
inherited, so nothing is compiled inside a timing). Time is the child's wall and CPU time of
``Discovery(...).fit(data)``; memory is the child's peak resident set size above its size
at the start of the fit (``resource.getrusage``), so it includes numba and NumPy buffers,
and nothing is slowed by tracing. A log-log fit gives the exponent (slope) of each sweep;
the stage timings (from the progress messages) tell which step grows fastest.

The machine is shared (2 cores, other jobs): absolute times are noisy; the slopes are fitted
within this one run.

Run:  python benchmarks/scaling.py [--quick]
      (writes benchmarks/results/scaling.md, scaling.png and the raw scaling.json; their
      title says which grid; --render redraws the table and figure from scaling.json)
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_discover import machine_description  # noqa: E402

from hystdisc.data import atomic_write_bytes, atomic_write_text  # noqa: E402
from hystdisc.estimator import Discovery  # noqa: E402
from hystdisc.models import Model  # noqa: E402
from hystdisc.simulation.synth import generate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
DURATION = 6.0
ALL_SHAPES = ("none", "dahl", "bouc-wen", "bouc-wen-std")
ALL_FAMILIES = ("bingham", "dahl", "lugre", "bouc-wen", "bouc-wen-std")
FAMILY_SETS = {
    1: ("bouc-wen",),
    2: ("dahl", "bouc-wen"),
    3: ("dahl", "lugre", "bouc-wen"),
    5: ALL_FAMILIES,
}
SHAPE_SETS = {
    1: ("bouc-wen",),
    2: ("none", "bouc-wen"),
    3: ("none", "dahl", "bouc-wen"),
    4: ALL_SHAPES,
}


@dataclass
class Point:
    """One measured configuration."""

    sweep: str
    x: float
    runs: int
    samples_per_run: int
    wall: float
    cpu: float
    peak_mb: float
    stages: dict[str, float] = field(default_factory=dict)
    family: str = ""


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _child(conn, data, options) -> None:
    """Fit in a forked child; send back wall, CPU, peak extra RSS and stage times."""
    try:
        marks: list[tuple[float, str]] = []
        t0 = time.perf_counter()

        def progress(msg: str) -> None:
            marks.append((time.perf_counter() - t0, msg))

        rss0 = _rss_mb()
        c0 = time.process_time()
        t0 = time.perf_counter()
        disc = Discovery(**options).fit(data, progress=progress)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 - rss0
        stages: dict[str, float] = {}
        ends = [m[0] for m in marks[1:]] + [wall]
        for (start, msg), end in zip(marks, ends, strict=True):
            key = (
                "stage 1"
                if msg.startswith("stage 1")
                else "stage 2"
                if msg.startswith("stage 2")
                else "closing"
                if msg.startswith("closing")
                else "prepare"
            )
            stages[key] = stages.get(key, 0.0) + (end - start)
        conn.send((wall, cpu, peak, stages, disc.family_))
    except BaseException as exc:  # noqa: BLE001 - report any failure to the parent
        conn.send(exc)
    finally:
        conn.close()


def measure(data, options: dict) -> tuple[float, float, float, dict[str, float], str]:
    """Run ``Discovery(**options).fit(data)`` in a forked child process."""
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, data, options))
    proc.start()
    child.close()
    out = parent.recv()
    proc.join()
    if isinstance(out, BaseException):
        raise out
    return out


def dataset(runs: int = 5, fs: float = 1000.0, seed: int = 0):
    """Bouc-Wen release runs at evenly spaced currents over 0..1 A."""
    currents = tuple(np.linspace(0.0, 1.0, runs)) if runs > 1 else (0.5,)
    return generate(
        Model("bouc-wen"), currents=currents, duration=DURATION, fs=fs, noise=1e-3, seed=seed
    )


def slope(x, y) -> float:
    """Least-squares slope of log(y) against log(x)."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(lx, ly, 1)[0])


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced grid")
    ap.add_argument(
        "--render",
        action="store_true",
        help="only re-render scaling.md/png from the measurements saved in scaling.json",
    )
    args = ap.parse_args(argv)
    if args.render:
        saved = json.loads((RESULTS / "scaling.json").read_text())
        points = [Point(**p) for p in saved["points"]]
        return render(points, saved["header"], saved["quick"], saved["total"], saved["log"])
    if args.quick:
        samples = [1000, 10000, 100000]
        runs_grid = [1, 2, 10, 50]
        fam_grid = [1, 5]
        shape_grid = [1, 4]
    else:
        samples = [1000, 2000, 3000, 6000, 10000, 20000, 30000, 60000, 100000]
        runs_grid = [1, 2, 3, 5, 10, 20, 35, 50]
        fam_grid = [1, 2, 3, 5]
        shape_grid = [1, 2, 3, 4]
    log: list[str] = []

    def say(msg: str) -> None:
        print(msg, flush=True)
        log.append(msg)

    header = machine_description()
    say(header)
    # warm-up in this process: numba's kernels are loaded (or compiled) once, then inherited
    Discovery().fit(dataset(3, 500.0))
    points: list[Point] = []

    def run(sweep: str, x: float, runs: int, fs: float, options: dict) -> None:
        data = dataset(runs, fs)
        wall, cpu, peak, stages, fam = measure(data, options)
        n = int(round(DURATION * fs))
        points.append(Point(sweep, x, runs, n, wall, cpu, peak, stages, fam))
        st = ", ".join(f"{k} {v:.1f}" for k, v in stages.items())
        say(
            f"{sweep:<8} x={x:<8g} runs={runs:<3} samples/run={n:<7} wall {wall:7.2f} s  "
            f"cpu {cpu:7.2f} s  peak +{peak:7.1f} MB  [{st}]  -> {fam}"
        )

    t0 = time.perf_counter()
    for n in samples:
        run("samples", n, 5, n / DURATION, {})
    for r in runs_grid:
        run("runs", r, r, 1000.0, {"single_current": True} if r == 1 else {})
    for k in fam_grid:
        run("families", k, 5, 1000.0, {"families": list(FAMILY_SETS[k])})
    for k in shape_grid:
        run("shapes", k, 5, 1000.0, {"shapes": SHAPE_SETS[k]})
    total = time.perf_counter() - t0
    saved = {
        "header": header,
        "quick": args.quick,
        "total": total,
        "log": log,
        "points": [asdict(p) for p in points],
    }
    atomic_write_text(RESULTS / "scaling.json", json.dumps(saved, indent=1) + "\n", force=True)
    return render(points, header, args.quick, total, log)


SWEEPS = {
    "samples": "samples per run (5 runs)",
    "runs": "runs (6000 samples each)",
    "families": "families fitted (5 runs x 6000)",
    "shapes": "stage-1 shapes (5 runs x 6000)",
}
STAGES = ("prepare", "stage 1", "stage 2", "closing")


def segment_slopes(x, y) -> list[float]:
    """Log-log slopes between consecutive points."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return [float(v) for v in np.diff(ly) / np.diff(lx)]


def render(points: list[Point], header: str, quick: bool, total: float, log: list[str]) -> str:
    """Write scaling.md (table, fitted and segment slopes, verdict) and scaling.png."""
    sweeps = SWEEPS
    lines = [
        f"# Scaling of hystdisc discover{' (quick grid)' if quick else ''}",
        "",
        f"Command: `python benchmarks/scaling.py{' --quick' if quick else ''}` "
        f"({total / 60:.0f} min). Machine: {header}. The machine is shared: absolute times "
        "are noisy; slopes are fitted within this one run. Time: wall and CPU of "
        "`Discovery().fit` (all families, held-out errors, closing loop unless the sweep "
        "restricts them) in a forked child; memory: the child's peak RSS above its size at "
        "the start of the fit. Bouc-Wen (seed form) release data, 1 mrad noise, 6 s per run; "
        "samples per run are varied through the sampling rate.",
        "",
        "| sweep | x | runs | samples/run | wall [s] | CPU [s] | peak memory [MB] | "
        "prepare [s] | stage 1 [s] | stage 2 [s] | closing [s] | selected |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for p in points:
        st = p.stages
        lines.append(
            f"| {p.sweep} | {p.x:g} | {p.runs} | {p.samples_per_run} | {p.wall:.2f} | "
            f"{p.cpu:.2f} | {p.peak_mb:.1f} | {st.get('prepare', 0):.2f} | "
            f"{st.get('stage 1', 0):.2f} | {st.get('stage 2', 0):.2f} | "
            f"{st.get('closing', 0):.2f} | {p.family} |"
        )
    lines += [
        "",
        "Log-log slopes (exponent b in cost ~ x^b): the least-squares fit over the sweep, and "
        "in brackets the slope of each segment between consecutive points (a fixed cost "
        "flattens the fit at small sizes; the last segment shows the asymptotic growth):",
        "",
        "| sweep | CPU time | peak memory | prepare | stage 1 | stage 2 | closing |",
        "|---|---|---|---|---|---|---|",
    ]
    slopes: dict[str, dict[str, float]] = {}
    segs: dict[str, dict[str, list[float]]] = {}
    for sw in sweeps:
        pts = [p for p in points if p.sweep == sw]
        if len(pts) < 2:
            continue
        xs = [p.x for p in pts]
        series = {
            "cpu": [p.cpu for p in pts],
            "wall": [p.wall for p in pts],
            "mem": [max(p.peak_mb, 0.1) for p in pts],
        }
        for st in STAGES:
            series[st] = [p.stages.get(st, 0.0) for p in pts]
        slopes[sw], segs[sw] = {}, {}
        for key, ys in series.items():
            ok = min(ys) > 0
            slopes[sw][key] = slope(xs, ys) if ok else float("nan")
            segs[sw][key] = segment_slopes(xs, ys) if ok else []

        def cell(key: str, sw: str = sw) -> str:
            seg = ", ".join(f"{v:.2f}" for v in segs[sw][key])
            return f"{slopes[sw][key]:.2f} [{seg}]"

        lines.append(
            f"| {sweeps[sw]} | {cell('cpu')} | {cell('mem')} | {cell('prepare')} | "
            f"{cell('stage 1')} | {cell('stage 2')} | {cell('closing')} |"
        )
    verdict = ["", "Verdict:", ""]
    if "samples" in segs:
        worst = max(
            ((st, max(segs["samples"][st] or [float("nan")])) for st in STAGES),
            key=lambda kv: kv[1] if np.isfinite(kv[1]) else -1.0,
        )
        bad = [
            f"{st} (segment slopes {', '.join(f'{v:.2f}' for v in segs['samples'][st])})"
            for st in STAGES
            if segs["samples"][st] and max(segs["samples"][st]) > 1.1
        ]
        verdict.append(
            "- Worse than linear in samples per run: "
            + (
                f"**yes**: {'; '.join(bad)}. Steepest: {worst[0]}, slope {worst[1]:.2f}."
                if bad
                else f"no (steepest segment: {worst[0]}, slope {worst[1]:.2f})."
            )
            + " A slope up to 1.1 is counted as linear within the noise of this machine."
        )
        wrong = [p for p in points if p.sweep in ("samples", "runs") and p.family != "bouc-wen"]
        if wrong:
            verdict.append(
                "- Selection changes with the data size: at "
                + ", ".join(f"{p.runs} runs x {p.samples_per_run} samples" for p in wrong)
                + " the Bouc-Wen data were attributed to "
                + ", ".join(sorted({p.family for p in wrong}))
                + "."
            )
    if "runs" in segs:
        verdict.append(
            f"- Runs: CPU slope {slopes['runs']['cpu']:.2f}, peak memory slope "
            f"{slopes['runs']['mem']:.2f} (segments "
            f"{', '.join(f'{v:.2f}' for v in segs['runs']['mem'])})."
        )
    lines += verdict
    lines += ["", "Log:", "", *[f"    {m}" for m in log], ""]
    text = "\n".join(lines)
    out_md = RESULTS / "scaling.md"
    atomic_write_text(out_md, text, force=True)
    png = _figure(points, slopes, sweeps)
    out_png = RESULTS / "scaling.png"
    atomic_write_bytes(out_png, png, force=True)
    print(text)
    print(f"wrote {out_md} and {out_png}")
    return text


def _xticks(ax, xs) -> None:
    """Label the measured x values only (log axes otherwise crowd minor labels)."""
    from matplotlib.ticker import FixedLocator, NullLocator

    ax.xaxis.set_major_locator(FixedLocator(list(xs)))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xticklabels([f"{v:g}" for v in xs])


def _figure(points: list[Point], slopes: dict, sweeps: dict) -> bytes:
    """Log-log panels (time and memory against each sweep's size) as PNG bytes."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5))
    for j, sw in enumerate(sweeps):
        pts = [p for p in points if p.sweep == sw]
        xs = np.array([p.x for p in pts], float)
        ax = axes[0, j]
        for key, lab, mk in (("cpu", "CPU", "o"), ("wall", "wall", "s")):
            ys = np.array([getattr(p, key) for p in pts])
            ax.loglog(xs, ys, mk + "-", label=f"{lab} (slope {slopes[sw][key]:.2f})")
        for st, col in (("stage 1", "C2"), ("stage 2", "C3"), ("closing", "C5")):
            ys = np.array([p.stages.get(st, np.nan) for p in pts])
            if np.all(ys > 0):
                ax.loglog(
                    xs, ys, "^--", color=col, ms=4, label=f"{st} (slope {slopes[sw][st]:.2f})"
                )
        if sw in ("samples", "runs"):
            ref = xs / xs[0] * pts[0].cpu
            ax.loglog(xs, ref, ":", color="grey", label="linear")
        ax.set_title(sweeps[sw], fontsize=10)
        _xticks(ax, xs)
        ax.set_ylabel("time [s]")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        ax = axes[1, j]
        ys = np.array([max(p.peak_mb, 0.1) for p in pts])
        ax.loglog(xs, ys, "o-", color="C4", label=f"peak memory (slope {slopes[sw]['mem']:.2f})")
        _xticks(ax, xs)
        ax.set_xlabel(sw)
        ax.set_ylabel("peak memory above start [MB]")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("hystdisc discover: scaling (log-log, one run on a shared 2-core machine)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


if __name__ == "__main__":
    main()
