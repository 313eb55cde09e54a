"""Benchmark (issue 17): where a user waits, measured as ratios within one run.

1. **Imports.** Fresh interpreters (median of ``--repeats``): the third-party modules the
   discover path cannot avoid (numpy, scipy, scikit-learn through pysindy, pysindy, numba),
   everything ``hystdisc discover`` imports, and ``hystdisc.cli`` alone (what ``--help``
   and the light commands pay).
2. **The 5-run release set through the CLI** (``data_synth/bouc-wen.csv``: 5 runs x 6 s at
   1 kHz): ``hystdisc discover`` in a fresh interpreter, wall and CPU, median of
   ``--repeats`` after one warm-up (numba's on-disk cache loaded).
3. **Exact sensitivities against forward differences**, in process, one thread, the same
   data: a discovery (``hystdisc.pipeline.run``, ``n_jobs=1``) with the output-error
   Jacobian from the compiled sensitivity kernels (term models) and the lockstep integrator
   (state-space models, at its tolerances: ``Options(jacobian="lockstep",
   integration=LOCKSTEP_INTEGRATION)``), then with forward differences everywhere
   (``jacobian="forward"``, the fits' own tolerances), alternated, CPU
   time median of ``--repeats`` each; the answers of the two are compared (family,
   parameters to 6 significant digits and in standard errors).
4. With ``--mr DIR`` (the UTFSM MR damper folder): ``hystdisc discover DIR --rig
   data_synth/rigs/utfsm_mr_damper.toml --staged`` once, wall and CPU, with its progress
   log (the phases).

Run:  python benchmarks/bench_speed.py [--repeats 3] [--mr ../shared/data/utfsm_mr_damper]
      (writes benchmarks/results/bench_speed.md)
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
DATA = ROOT / "data_synth" / "bouc-wen.csv"
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"
THIRD_PARTY = "import numpy, scipy.sparse, scipy.stats, sklearn.base, pysindy, numba"
DISCOVER_IMPORTS = "import hystdisc.cli.discover, hystdisc.estimator, pysindy"


def _child(cmd: list[str], log: Path | None = None) -> tuple[float, float, str]:
    """Wall and CPU time (s) of a child process, and its stderr."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-500:]}")
    if log is not None:
        log.write_text(proc.stderr)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stderr


def _median_child(cmd: list[str], repeats: int) -> tuple[float, float]:
    runs = [_child(cmd)[:2] for _ in range(repeats)]
    return statistics.median(w for w, _ in runs), statistics.median(c for _, c in runs)


def _fit_cpu(mode: str) -> tuple[float, dict]:
    """CPU time of one in-process discovery with the Jacobian ``mode``, and its answer."""
    from hystdisc.data import load
    from hystdisc.fitting.system_jacobian import LOCKSTEP_INTEGRATION
    from hystdisc.pipeline import Options, build_results, run

    # Discovery(n_jobs=1, jacobian=...); the integration is an option of the pipeline only
    opts = Options(n_jobs=1, jacobian="forward")
    if mode == "exact":
        opts = opts.replace(jacobian="lockstep", integration=LOCKSTEP_INTEGRATION)
    ds = load([str(DATA)])
    t0 = time.process_time()
    state = run(ds, opts)
    build_results(state)
    cpu = time.process_time() - t0
    fit = state.final_fit
    answer = {"family": state.family, "params": dict(fit.params), "ci95": dict(fit.ci95)}
    return cpu, answer


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mr", default=None, help="the UTFSM MR damper folder (optional)")
    ap.add_argument("--out", default=str(RESULTS / "bench_speed.md"))
    args = ap.parse_args(argv)
    py = sys.executable
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    lines = [
        "# Speed where users wait (issue 17)",
        "",
        f"`python benchmarks/bench_speed.py --repeats {args.repeats}"
        + (f" --mr {args.mr}`" if args.mr else "`"),
        f"commit {commit}; {os.cpu_count()} cores, {platform.machine()}, python "
        f"{platform.python_version()}; load average at start {_load()} (shared machine: "
        "the ratios within this run are the robust numbers).",
        "",
        "## 1. Imports (fresh interpreter, median)",
        "",
        "| what | wall (s) | CPU (s) |",
        "|---|---:|---:|",
    ]
    for label, code in [
        ("python alone", "pass"),
        ("third-party floor of discover: " + THIRD_PARTY[7:], THIRD_PARTY),
        ("everything `hystdisc discover` imports", DISCOVER_IMPORTS),
        ("`hystdisc.cli` (help, light commands)", "import hystdisc.cli"),
    ]:
        w, c = _median_child([py, "-c", code], args.repeats)
        lines.append(f"| {label} | {w:.2f} | {c:.2f} |")
        print(lines[-1])

    lines += ["", "## 2. The 5-run release set through the CLI", ""]
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [py, "-m", "hystdisc", "discover", str(DATA), "--out", tmp, "--force", "--quiet"]
        _child(cmd)  # warm-up: numba's cache
        w, c = _median_child(cmd, args.repeats)
    lines.append(
        f"`hystdisc discover data_synth/bouc-wen.csv`: **{w:.2f} s wall**, {c:.2f} s CPU "
        f"(median of {args.repeats}, after a warm-up; load {_load()})."
    )
    print(lines[-1])

    lines += ["", "## 3. Exact sensitivities against forward differences (in process)", ""]
    cpu = {"exact": [], "forward": []}
    answers = {}
    for _ in range(args.repeats):
        for mode in ("exact", "forward"):
            c, answers[mode] = _fit_cpu(mode)
            cpu[mode].append(c)
            print(f"{mode}: {c:.2f} s CPU")
    ce, cf = statistics.median(cpu["exact"]), statistics.median(cpu["forward"])
    lines += [
        "| Jacobian | CPU of a discovery, `n_jobs=1` (s), median | runs |",
        "|---|---:|---|",
        f"| exact (sensitivity kernels, lockstep) | {ce:.2f} | "
        + ", ".join(f"{x:.2f}" for x in cpu["exact"])
        + " |",
        f"| forward differences (before) | {cf:.2f} | "
        + ", ".join(f"{x:.2f}" for x in cpu["forward"])
        + " |",
        "",
        f"Ratio: **{cf / ce:.2f}x** less CPU with exact sensitivities.",
        "",
    ]
    a, b = answers["exact"], answers["forward"]
    lines.append(f"Selected family: exact {a['family']}, forward {b['family']}.")
    lines += ["", "| parameter | exact | forward | change (SE) |", "|---|---:|---:|---:|"]
    for k, v in a["params"].items():
        f = b["params"].get(k, float("nan"))
        lo, hi = a["ci95"].get(k, (float("nan"), float("nan")))
        se = (hi - lo) / 3.92
        dz = abs(v - f) / se if se > 0 else float("nan")
        lines.append(f"| {k} | {v:.6g} | {f:.6g} | {dz:.2g} |")

    if args.mr:
        lines += ["", "## 4. The UTFSM MR damper set (30 files), everything on", ""]
        with tempfile.TemporaryDirectory() as tmp:
            log = Path(tmp) / "mr.log"
            cmd = [py, "-m", "hystdisc", "discover", args.mr, "--rig", str(RIG)]
            cmd += ["--staged", "--out", tmp, "--force"]
            w, c, err = _child(cmd, log)
        phases = [ln for ln in err.splitlines() if ln.startswith("[")]
        lines.append(f"`hystdisc discover {args.mr} --rig {RIG.relative_to(ROOT)} --staged`: ")
        lines.append(f"**{w:.1f} s wall**, {c:.1f} s CPU (load at the end {_load()}).")
        lines += ["", "Progress log (the phases):", "", "```", *phases, "```"]
        print(lines[-len(phases) - 5])
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
