"""Check (issue 17 acceptance): the speed work leaves the answers unchanged.

``hystdisc discover`` on every ``data_synth/*.csv`` (default options, one fresh process
each); the answer of each file is its selected family, the final model's effects and
every final parameter with its 95 % interval. ``--record`` writes them as the reference
(run it on the commit before a speed change); without it, the answers are compared with
the reference and a table is written:

- family and effects must be equal;
- each parameter must agree to the printed digits (6 significant, as the console prints
  them), and its change is also given in units of its standard error (interval / 3.92):
  a change far below one standard error is a numerical difference, not a different answer.

Run:  python benchmarks/check_unchanged.py --record   (on the reference commit)
      python benchmarks/check_unchanged.py            (writes benchmarks/results/unchanged.md)
      ... --save answers.json                          (also keeps this run's answers)
Exit code 1 when a family, an effect or a parameter beyond 0.01 standard errors differs.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
REFERENCE = RESULTS / "unchanged_reference.json"
#: A parameter change below this many standard errors is a numerical difference.
SE_TOL = 0.01


def answer(csv: Path, work: Path) -> dict:
    """The answer of ``hystdisc discover`` on one file (see the module docstring)."""
    out = work / f"{csv.stem}.json"
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "hystdisc", "discover", str(csv), "--json", str(out)]
        + ["--force", "--quiet"],
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{csv.name}: discover failed: {proc.stderr.strip()[-400:]}")
    res = json.loads(out.read_text())
    final = res["final"]
    params = {
        k: {"value": v["value"], "ci95": v.get("ci95")} for k, v in final["parameters"].items()
    }
    return {
        "family": final["family"],
        "effects": sorted(final["effects"]),
        "params": params,
        "wall_s": round(wall, 2),
    }


def compare(ref: dict, new: dict) -> tuple[list[str], bool]:
    """Table rows of one file and whether it is unchanged."""
    rows = []
    ok = ref["family"] == new["family"] and ref["effects"] == new["effects"]
    if not ok:
        rows.append(
            f"| answer | {ref['family']} {ref['effects']} | {new['family']} {new['effects']} "
            "| | **different** |"
        )
        return rows, False
    for k, r in ref["params"].items():
        n = new["params"].get(k)
        if n is None:
            rows.append(f"| {k} | {r['value']:.6g} | missing | | **different** |")
            ok = False
            continue
        same = f"{r['value']:.6g}" == f"{n['value']:.6g}"
        ci = r.get("ci95")
        se = (ci[1] - ci[0]) / 3.92 if ci and all(c is not None for c in ci) else None
        dz = abs(n["value"] - r["value"]) / se if se else None
        good = same or (dz is not None and dz <= SE_TOL)
        ok &= good
        if not same:
            zs = f"{dz:.2g}" if dz is not None else "n/a"
            verdict = "same to 0.01 SE" if good else "**different**"
            rows.append(f"| {k} | {r['value']:.6g} | {n['value']:.6g} | {zs} | {verdict} |")
    return rows, ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--record", action="store_true", help="write the reference")
    ap.add_argument("--files", default="*.csv", help="glob in data_synth/ (default *.csv)")
    ap.add_argument("--out", default=str(RESULTS / "unchanged.md"))
    ap.add_argument(
        "--save", default=None, help="also write this run's answers (the reference's format)"
    )
    args = ap.parse_args(argv)
    files = sorted((ROOT / "data_synth").glob(args.files))
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    answers = {}
    with tempfile.TemporaryDirectory() as tmp:
        for f in files:
            answers[f.name] = answer(f, Path(tmp))
            print(f"{f.name}: {answers[f.name]['family']} ({answers[f.name]['wall_s']} s)")
    record = json.dumps({"commit": commit, "answers": answers}, indent=1) + "\n"
    if args.save:
        Path(args.save).write_text(record)
    if args.record:
        REFERENCE.write_text(record)
        print(f"wrote {REFERENCE}")
        return 0
    ref = json.loads(REFERENCE.read_text())
    lines = [
        "# Answers before and after the speed work (issue 17)",
        "",
        f"`python benchmarks/check_unchanged.py`: reference at commit {ref['commit']}, "
        f"this run at {commit}. Parameters are compared to the printed 6 significant digits; "
        f"a change that is not is given in standard errors (unchanged below {SE_TOL}).",
        "",
        "| file | family | unchanged |",
        "|---|---|---|",
    ]
    detail = []
    all_ok = True
    for name, new in answers.items():
        old = ref["answers"].get(name)
        if old is None:
            lines.append(f"| {name} | {new['family']} | no reference |")
            continue
        rows, ok = compare(old, new)
        all_ok &= ok
        lines.append(f"| {name} | {new['family']} | {'yes' if ok else '**no**'} |")
        if rows:
            detail += [f"\n{name}:\n", "| parameter | before | now | change (SE) | |"]
            detail += ["|---|---:|---:|---:|---|", *rows]
    Path(args.out).write_text("\n".join(lines + detail) + "\n")
    print(f"wrote {args.out}; {'all unchanged' if all_ok else 'SOME ANSWERS CHANGED'}")
    return 0 if all_ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
