"""Compare two sets of results.json files: is a refactor or a speed-up free of numeric change?

Usage::

    python benchmarks/compare_results.py BEFORE_DIR AFTER_DIR [--digits 4]

Each directory holds one sub-folder per dataset with its ``results.json`` (as written by
``hystdisc discover FILE --out DIR/NAME``). For every dataset present in both, the script
compares the selected family, the accepted effects, and every family's parameter values,
RMS and BIC, at ``--digits`` significant digits (the console prints 4) and to the last
stored digit, and prints one row per dataset. Exit status 1 when any dataset differs at
``--digits``.

To make the two sets::

    for f in data_synth/*.csv; do n=$(basename "$f" .csv)
      hystdisc discover "$f" --out "DIR/$n" --force --quiet; done
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path


def _numbers(res: dict) -> dict[str, float]:
    """The numbers a user reads: per family parameters, rms, bic, heldout; the final model."""
    out: dict[str, float] = {}
    for name, fam in res.get("families", {}).items():
        for k, p in fam.get("parameters", {}).items():
            out[f"{name}.{k}"] = p.get("value")
        for k in ("rms", "bic", "heldout_rms"):
            out[f"{name}.{k}"] = fam.get(k)
    final = res.get("final") or {}
    for k, p in (final.get("parameters") or {}).items():
        out[f"final.{k}"] = p.get("value")
    for k in ("rms", "bic", "heldout_rms"):
        out[f"final.{k}"] = final.get(k)
    out["noise_std"] = res.get("noise_std")
    return out


def _same(a, b, digits: int | None) -> bool:
    if a is None or b is None:
        return a is b
    if digits is None:
        return a == b
    if a == b:
        return True
    if not (math.isfinite(a) and math.isfinite(b)):
        return False
    return f"{a:.{digits}g}" == f"{b:.{digits}g}"


def compare(before: dict, after: dict, digits: int) -> tuple[list[str], int]:
    """Differences at ``digits`` significant digits, and the count of last-digit ones."""
    diffs = []
    if before.get("family") != after.get("family"):
        diffs.append(f"family {before.get('family')} -> {after.get('family')}")
    eb = [e["name"] for e in before.get("effects", [])]
    ea = [e["name"] for e in after.get("effects", [])]
    if eb != ea:
        diffs.append(f"effects {eb} -> {ea}")
    nb, na = _numbers(before), _numbers(after)
    for k in sorted(set(nb) | set(na)):
        if not _same(nb.get(k), na.get(k), digits):
            diffs.append(f"{k} {nb.get(k)} -> {na.get(k)}")
    exact = sum(1 for k in set(nb) & set(na) if not _same(nb[k], na[k], None))
    return diffs, exact


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--digits", type=int, default=4, help="significant digits compared")
    args = ap.parse_args(argv)
    bad = 0
    print(
        f"| dataset | family | effects | numbers | differ at {args.digits} digits | differ at all |"
    )
    print("|---|---|---|---|---|---|")
    for d in sorted(p for p in args.before.iterdir() if (p / "results.json").exists()):
        other = args.after / d.name / "results.json"
        if not other.exists():
            print(f"| {d.name} | missing in {args.after} | | | | |")
            bad += 1
            continue
        b = json.loads((d / "results.json").read_text())
        a = json.loads(other.read_text())
        diffs, exact = compare(b, a, args.digits)
        eff = ",".join(e["name"] for e in a.get("effects", [])) or "-"
        print(
            f"| {d.name} | {a.get('family')} | {eff} | {len(_numbers(a))} | {len(diffs)} | {exact} |"
        )
        for line in diffs[:10]:
            print(f"|   | {line} | | | | |")
        bad += bool(diffs)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
