"""Two runs of the stress suite, case by case: did a change alter any outcome?

Usage::

    python benchmarks/stress_compare.py BEFORE.json AFTER.json

Both files are ``benchmarks/stress.py`` JSON outputs of the same cases. For every case in
both it compares the selected family, the four success flags, the true family's RMS ratio
and every family's RMS ratio, and prints the cases that differ (a family's RMS ratio
counts when it moved by more than 1e-6) and the success counts of both runs. Exit status
1 when an outcome (selected family or a success flag) differs.
"""

from __future__ import annotations

import argparse
import json
import sys

FLAGS = ("success", "success_joint", "success_data", "success_data_equal")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    args = ap.parse_args(argv)
    load = lambda p: {c["case"]: c for c in json.load(open(p))["cases"]}  # noqa: E731
    a, b = load(args.before), load(args.after)
    common = [k for k in a if k in b]
    changed_outcome = 0
    for case in common:
        x, y = a[case], b[case]
        outcome = [k for k in ("selected", *FLAGS) if x[k] != y[k]]
        changed_outcome += bool(outcome)
        fam = {
            f: (x["family_rms_ratios"][f], y["family_rms_ratios"].get(f, float("nan")))
            for f in x["family_rms_ratios"]
            if not abs(x["family_rms_ratios"][f] - y["family_rms_ratios"].get(f, 0.0)) <= 1e-6
        }
        if outcome or fam or x["rms_ratio"] != y["rms_ratio"]:
            parts = [f"{k} {x[k]} -> {y[k]}" for k in outcome]
            parts.append(f"true family's RMS ratio {x['rms_ratio']:.6g} -> {y['rms_ratio']:.6g}")
            parts += [f"{f} {u:.4g} -> {v:.4g}" for f, (u, v) in fam.items()]
            print(f"{case}: " + "; ".join(parts))
    for k in FLAGS:
        print(f"{k}: {sum(bool(a[c][k]) for c in common)}/{len(common)} -> "
              f"{sum(bool(b[c][k]) for c in common)}/{len(common)}")  # fmt: skip
    print(f"{len(common)} cases in both; {changed_outcome} with a different outcome")
    return 1 if changed_outcome else 0


if __name__ == "__main__":
    sys.exit(main())
