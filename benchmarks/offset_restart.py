"""Declared family, spring at rest off the sensor zero: is ``offset`` found? (issue 16)

The issue's case: ``--model bouc-wen`` on data whose spring rests at 0.02 rad must find
``offset``. Each case here: a stress-suite parameter set (``benchmarks/stress.py``'s
``sample_set``, sets the suite draws for that family) with an offset drawn at random
(``|theta_off|`` log-uniform in [0.01, 0.05] rad, either sign), simulated by ``hystdisc
simulate`` at 3 or 5 current levels (3 s, 1 mrad), then ``hystdisc discover --model
FAMILY`` with default settings. Success: the final model is the family plus ``offset``
and nothing else, the true ``theta_off`` inside its 95 % interval, and the held-out RMS
within 10 % of the noise.

With ``--undeclared`` the family is not declared (``hystdisc discover`` compares the
families, and the reselection compares them again with the accepted effects): success
also needs the true family selected.

Run:  python benchmarks/offset_restart.py --sets 3 --jobs 2 --out benchmarks/results/offset_restart.md
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from stress import sample_set  # noqa: E402

NOISE = 1e-3
LAYOUTS = {"3 levels": "0,0.5,1", "5 levels": "0,0.25,0.5,0.75,1"}


def draw_offset(family: str, index: int) -> float:
    """The offset of a case (deterministic): log-uniform in [0.01, 0.05] rad, either sign."""
    rng = np.random.default_rng([7, zlib.crc32(family.encode()), index])
    size = math.exp(rng.uniform(math.log(0.01), math.log(0.05)))
    return float(f"{size * rng.choice([-1.0, 1.0]):.4g}")


def run_case(family: str, index: int, layout: str, work: Path, declared: bool = True) -> dict:
    params, _ = sample_set(family, index, duration=3.0)
    off = draw_offset(family, index)
    name = f"{family}/{index}/{layout.split()[0]}"
    stem = name.replace("/", "_")
    csv, out = work / f"{stem}.csv", work / f"{stem}.json"
    seed = zlib.crc32(name.encode()) % 2**31
    sim = [
        "simulate",
        "--model",
        family,
        "--set",
        ",".join(f"{k}={v!r}" for k, v in params.items()),
    ]
    sim += ["--effect", f"offset:theta_off={off!r}", "--currents", LAYOUTS[layout]]
    sim += ["--duration", "3", "--noise", repr(NOISE), "--seed", str(seed)]
    sim += ["-o", str(csv), "--force", "--quiet"]
    disc = ["discover", str(csv), "--json", str(out), "--force", "--quiet"]
    disc += ["--model", family] if declared else []
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    for args in (sim, disc):
        cp = subprocess.run(
            [sys.executable, "-m", "hystdisc", *args], capture_output=True, text=True, env=env
        )
        if cp.returncode:
            return {"case": name, "theta_off": off, "error": cp.stderr.strip().splitlines()[-1:]}
    res = json.loads(out.read_text())
    final = res.get("final") or {}
    effects = list(final.get("effects") or [])
    par = (final.get("parameters") or {}).get("theta_off") or {}
    lo, hi = par.get("ci95") or [None, None]
    lo, hi = (math.nan if lo is None else lo), (math.nan if hi is None else hi)
    p = {"theta_off": par.get("value")}
    tried = {t["name"]: t for t in res.get("effects_tried") or []}
    rec = {
        "case": name,
        "theta_off": off,
        "family": final.get("family"),
        "effects": effects,
        "theta_off_fit": p.get("theta_off"),
        "inside": bool(lo < off < hi),
        "rms_ratio": (final.get("rms") or math.nan) / NOISE,
        "heldout_ratio": (final.get("heldout_rms") or math.nan) / NOISE,
        "restarted": bool(tried.get("offset", {}).get("restarted")),
        "seconds": round(time.perf_counter() - t0, 1),
    }
    rec["success"] = bool(
        rec["family"] == family
        and effects == ["offset"]
        and rec["inside"]
        and rec["heldout_ratio"] <= 1.1
    )
    if not declared:
        rec["reselection"] = (res.get("reselection") or {}).get("note")
    return rec


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="bouc-wen,bouc-wen-std,lugre,dahl")
    ap.add_argument("--sets", type=int, default=3)
    ap.add_argument("--first-set", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="markdown table (default: stdout)")
    ap.add_argument("--undeclared", action="store_true", help="compare the families (no --model)")
    a = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="offset_restart_"))
    cases = [
        (f, k, lay)
        for f in a.families.split(",")
        for k in range(a.first_set, a.first_set + a.sets)
        for lay in LAYOUTS
    ]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        recs = list(pool.map(lambda c: run_case(*c, work, declared=not a.undeclared), cases))
    for r in recs:
        print(r["case"], "ok" if r.get("success") else "FAIL", r, file=sys.stderr)
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    ok = sum(bool(r.get("success")) for r in recs)
    lines = [
        f"# {'Undeclared' if a.undeclared else 'Declared'} family with an offset: is `offset` "
        "found? (issue 16)",
        "",
        f"Command: `python benchmarks/offset_restart.py --families {a.families} --sets {a.sets} "
        f"--first-set {a.first_set} --jobs {a.jobs}{' --undeclared' if a.undeclared else ''}`  ",
        f"Commit: {commit}; wall time {time.perf_counter() - t0:.0f} s; {len(recs)} cases; "
        f"success {ok}/{len(recs)}.",
        "",
        "| case | theta_off | final family | final effects | fitted theta_off | truth inside | RMS/noise | held-out/noise | restarted | ok |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in recs:
        if "error" in r:
            lines.append(
                f"| {r['case']} | {r['theta_off']} | error: {r['error']} | | | | | | | no |"
            )
            continue
        fit = "-" if r["theta_off_fit"] is None else f"{r['theta_off_fit']:.4g}"
        lines.append(
            f"| {r['case']} | {r['theta_off']} | {r['family']} | {', '.join(r['effects']) or '-'} "
            f"| {fit} | "
            f"{'yes' if r['inside'] else 'no'} | {r['rms_ratio']:.3f} | {r['heldout_ratio']:.3f} | "
            f"{'yes' if r['restarted'] else ''} | {'yes' if r['success'] else 'no'} |"
        )
    notes = [f"- {r['case']}: {r['reselection']}" for r in recs if r.get("reselection")]
    if notes:
        lines += ["", "Reselection notes (results.json `reselection.note`):", "", *notes]
    text = "\n".join(lines) + "\n"
    if a.out:
        a.out.write_text(text)
        a.out.with_suffix(".json").write_text(json.dumps(recs, indent=1))
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
