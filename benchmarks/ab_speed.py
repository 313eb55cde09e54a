"""Benchmark (issue 17): two checkouts of hystdisc against each other, alternated in one run.

On a shared machine a single timing means little; this runs A and B in turn (A, B, A, B,
...) after one warm-up each (numba's on-disk cache), so both see the same load, and gives
the medians and their ratio A / B:

1. **Imports** of the discover path in a fresh interpreter (what ``hystdisc discover``
   imports before it reads data, with the commands' import options where the checkout
   has them), wall and CPU.
2. **The 5-run release set through the CLI**: ``hystdisc discover data_synth/bouc-wen.csv``
   in a fresh interpreter, wall and CPU (children's rusage).
3. **In process**: ``Discovery(n_jobs=1).fit`` on the same data in a fresh interpreter
   after a warm-up fit, CPU time (``time.process_time``), and the answer (family and
   parameters to 6 significant digits), which must be the same for A and B.
4. **A fresh install's first run**: ``hystdisc discover data_synth/driven_bouc-wen.csv``
   (term and state-space families, their exact sensitivities) with an empty numba cache
   of its own (``NUMBA_CACHE_DIR`` in a new folder, no warm-up): what the kernels' compile
   costs a new user and a fresh CI clone.

Run:  python benchmarks/ab_speed.py A_DIR B_DIR [--repeats 3] [--cases 1,2,3,4] [--out FILE.md]
      (A_DIR, B_DIR: repository checkouts, e.g. git worktrees of two commits)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data_synth" / "bouc-wen.csv"
DRIVEN = ROOT / "data_synth" / "driven_bouc-wen.csv"
IMPORTS = (
    "try:\n"
    "    from hystdisc.cli.common import skip_scipy_doc_notes\n"
    "    skip_scipy_doc_notes()\n"
    "except ImportError:\n"
    "    pass\n"
    "import hystdisc.cli.discover, hystdisc.estimator, pysindy\n"
)
IN_PROCESS = (
    "import json, sys, time\n"
    "from hystdisc.data import load\n"
    "from hystdisc.estimator import Discovery\n"
    "ds = load([sys.argv[1]])\n"
    "Discovery(n_jobs=1).fit(ds)\n"
    "t0 = time.process_time()\n"
    "d = Discovery(n_jobs=1).fit(ds)\n"
    "cpu = time.process_time() - t0\n"
    "p = {k: f'{v:.6g}' for k, v in d.final_fit_.params.items()}\n"
    "print(json.dumps({'cpu': cpu, 'answer': [d.family_, p]}))\n"
)


def _child(checkout: str, cmd: list[str], cold: bool = False) -> tuple[float, float, str]:
    """Wall and CPU time of a child running ``checkout``'s hystdisc, and its stdout;
    ``cold``: with an empty numba cache of its own."""
    env = {**os.environ, "PYTHONPATH": checkout}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [c.replace("{tmp}", tmp) for c in cmd]
        if cold:
            env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "numba")
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{checkout}: {' '.join(cmd)} failed: {proc.stderr.strip()[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _commit(checkout: str) -> str:
    out = subprocess.run(
        ["git", "-C", checkout, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    return out.stdout.strip() or "?"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a", help="checkout A (the reference)")
    ap.add_argument("b", help="checkout B")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--cases", default="1,2,3,4", help="which of the cases above (numbers, comma-separated)"
    )
    ap.add_argument("--out", default=None, help="write the table as Markdown here")
    args = ap.parse_args(argv)
    py = sys.executable
    sides = {"A": str(Path(args.a).resolve()), "B": str(Path(args.b).resolve())}
    cases = {
        "imports of the discover path": [py, "-c", IMPORTS],
        "`hystdisc discover data_synth/bouc-wen.csv` (CLI)": [
            *(py, "-m", "hystdisc", "discover", str(DATA)),
            *("--out", "{tmp}", "--force", "--quiet"),
        ],
        "`Discovery(n_jobs=1).fit` in process": [py, "-c", IN_PROCESS, str(DATA)],
        "first `hystdisc discover data_synth/driven_bouc-wen.csv`, empty numba cache": [
            *(py, "-m", "hystdisc", "discover", str(DRIVEN)),
            *("--out", "{tmp}", "--force", "--quiet"),
        ],
    }
    chosen = {int(k) for k in args.cases.split(",")}
    cases = {k: v for i, (k, v) in enumerate(cases.items(), 1) if i in chosen}
    lines = [
        f"`python benchmarks/ab_speed.py A B --repeats {args.repeats} --cases {args.cases}`: "
        f"A = {_commit(sides['A'])}"
        f", B = {_commit(sides['B'])}; {os.cpu_count()} cores; load average at start {_load()}.",
        "",
        "| what | A wall (s) | B wall (s) | A CPU (s) | B CPU (s) | A/B wall | A/B CPU |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    answers = {}
    for label, cmd in cases.items():
        cold = "empty numba cache" in label
        for side in "" if cold else "AB":  # warm-up (a cold run is its own)
            _child(sides[side], cmd)
        runs: dict[str, list[tuple[float, float]]] = {"A": [], "B": []}
        for _ in range(args.repeats):
            for side in "AB":
                wall, cpu, out = _child(sides[side], cmd, cold)
                if "in process" in label:
                    res = json.loads(out.strip().splitlines()[-1])
                    cpu, answers[side] = res["cpu"], res["answer"]
                    wall = float("nan")
                runs[side].append((wall, cpu))
                print(f"{label}: {side} wall {wall:.2f} CPU {cpu:.2f}", flush=True)
        w = {s: statistics.median(x for x, _ in runs[s]) for s in "AB"}
        c = {s: statistics.median(x for _, x in runs[s]) for s in "AB"}
        wall_cells = (
            ["", "", ""]
            if "in process" in label
            else [f"{w['A']:.2f}", f"{w['B']:.2f}", f"{w['A'] / w['B']:.2f}x"]
        )
        lines.append(
            f"| {label} | {wall_cells[0]} | {wall_cells[1]} | {c['A']:.2f} | {c['B']:.2f} "
            f"| {wall_cells[2]} | {c['A'] / c['B']:.2f}x |"
        )
        print(lines[-1], flush=True)
    same = answers.get("A") == answers.get("B")
    lines += [
        "",
        f"Medians of {args.repeats}, alternated, after a warm-up each (none for a first run); "
        f"load average at the end "
        f"{_load()}. In-process answer (family, parameters to 6 digits): "
        + (
            "not run (case 3 not chosen)."
            if not answers
            else "the same for A and B."
            if same
            else f"**different**: A {answers['A']}, B {answers['B']}."
        ),
    ]
    text = "\n".join(lines) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    print(text)
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
