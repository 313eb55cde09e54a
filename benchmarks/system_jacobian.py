"""Benchmark (issue 17 item 1): a state-space family's Jacobian, exact against differences.

Fits Spencer's family to the UTFSM MR damper set (30 files, driven; ``Discovery(
model="spencer", close_loop=False)``, the standard Bouc-Wen fit its starts come from
included) twice, each in a fresh process: with the exact Jacobian (the integrator's
forward sensitivities, :mod:`hystdisc.fitting.system_sensitivity`, the default) and with
forward differences of separately integrated runs (one simulation per column, as before:
``jacobian="terms"``, which keeps the term models' exact Jacobian).
Reports the CPU and wall time of each and how far the answers are apart: RMS, held-out
RMS, and every parameter's change in units of its standard error.

Run:  python benchmarks/system_jacobian.py [--data ../shared/data/utfsm_mr_damper]
      [--out benchmarks/results/system_jacobian.md]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"

CHILD = """
import glob, json, sys, time
from hystdisc.data import load
from hystdisc.estimator import Discovery
folder, rig, mode, out = sys.argv[1:5]
# "terms": the term models' exact Jacobian, the state-space model's forward differences
jacobian = "terms" if mode == "forward" else "exact"
files = sorted(glob.glob(folder + "/*.txt") + glob.glob(folder + "/*.csv"))
ds = load(files, rig=rig)
c0, w0 = time.process_time(), time.perf_counter()
disc = Discovery(model="spencer", close_loop=False, jacobian=jacobian).fit(ds)
cpu, wall = time.process_time() - c0, time.perf_counter() - w0
fam = json.loads(disc.results_.to_json())["families"]["spencer"]
json.dump({"cpu": cpu, "wall": wall, "fit": fam}, open(out, "w"))
"""


def _run(folder: str, mode: str, tmp: Path) -> dict:
    out = tmp / f"{mode}.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-c", CHILD, folder, str(RIG), mode, str(out)]
    subprocess.run(cmd, check=True, env=env, cwd=ROOT)
    return json.loads(out.read_text())


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "utfsm_mr_damper"))
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "system_jacobian.md"))
    args = ap.parse_args(argv)
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip()
    start = _load()
    with tempfile.TemporaryDirectory() as tmp:
        res = {m: _run(args.data, m, Path(tmp)) for m in ("exact", "forward")}
    ex, fd = res["exact"]["fit"], res["forward"]["fit"]
    lines = [
        "# A state-space family's Jacobian: exact sensitivities against forward differences",
        "",
        f"`python benchmarks/system_jacobian.py`: commit {commit}, "
        f"{time.strftime('%Y-%m-%d %H:%M')}; {os.cpu_count()} cores, {platform.machine()}; "
        f"load average {start} at the start, {_load()} at the end.",
        "",
        '`Discovery(model="spencer", close_loop=False).fit` on the UTFSM MR damper set (30 '
        "files), one fresh process each, in turn; numba's cache warm.",
        "",
        "| Jacobian | CPU (s) | wall (s) | RMS | held-out RMS |",
        "|---|---:|---:|---:|---:|",
    ]
    for m, fit in (("exact", ex), ("forward", fd)):
        r = res[m]
        lines.append(
            f"| {m} | {r['cpu']:.1f} | {r['wall']:.1f} | {fit['rms']:.7g} | "
            f"{fit['heldout_rms']:.7g} |"
        )
    lines += [
        "",
        f"Ratio forward / exact: **{res['forward']['cpu'] / res['exact']['cpu']:.2f}x CPU**, "
        f"{res['forward']['wall'] / res['exact']['wall']:.2f}x wall.",
        "",
        "| parameter | exact | forward | change (standard errors) |",
        "|---|---:|---:|---:|",
    ]
    for k, v in ex["parameters"].items():
        w = fd["parameters"][k]
        ci = w.get("ci95") or [None, None]
        se = (ci[1] - ci[0]) / 3.92 if ci[0] is not None else None
        dz = f"{(v['value'] - w['value']) / se:+.3f}" if se else "-"
        lines.append(f"| {k} | {v['value']:.6g} | {w['value']:.6g} | {dz} |")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
