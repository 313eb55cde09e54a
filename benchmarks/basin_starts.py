"""Benchmark (issue 17): the stage-1 basin starts with and without a local search.

A term family above the noise floor gets up to two starts from other basins of its
shape's stage-1 grid (:func:`hystdisc.discovery.family_starts`). Each grid point's start
was refined by Nelder-Mead on the equation error before session 16; now it keeps the grid
point's shape constants and only the torque coefficients are fitted. For every family with
shape constants this times both on a dataset, and says where each start's shape constants
end: a refined start that ends where another one does is a duplicate start.

Run:  python benchmarks/basin_starts.py [--data ../shared/data/utfsm_mr_damper]
      [--rig data_synth/rigs/utfsm_mr_damper.toml] [--families bouc-wen-std,bouc-wen,dahl]
      (prints a table; writes nothing)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hystdisc.data import load
from hystdisc.discovery import family_start
from hystdisc.discovery.shapes import FAMILY_SHAPE, SHAPES
from hystdisc.discovery.varpro import grid_minima
from hystdisc.fitting.prepare import prepare_data
from hystdisc.registry import get_family

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "utfsm_mr_damper"
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--rig", default=str(RIG))
    ap.add_argument("--families", default="bouc-wen-std,bouc-wen,dahl")
    args = ap.parse_args()
    ds = load([args.data], rig=args.rig if Path(args.rig).exists() else None)
    eq, *_ = prepare_data(ds, None, "cubic")
    one_level = len(np.unique(eq.currents)) < 2
    n_eq = sum(t.size for t in eq.t)
    print(f"{args.data}: {n_eq} equation-error samples; the grid's 2nd and 3rd best points")
    print(
        "| family | basin start | refined by Nelder-Mead: parameters; time | kept: parameters; time |"
    )
    print("|---|---|---|---|")
    for fam in args.families.split(","):
        shape = FAMILY_SHAPE[fam]
        if not SHAPES[shape].shape_names:
            continue
        ft = [t for t in get_family(fam).torque_terms if not (one_level and t.startswith("i"))]
        lead = ["theta"] if eq.experiment_type.motion_imposed else ["theta", "1"]
        pts = grid_minima(eq, shape, [*lead, *ft], 3)
        for k, g in enumerate(pts[1:], start=2):
            row = []
            for refine in (True, False):
                t0 = time.perf_counter()
                p, _ = family_start(eq, fam, s0=g, one_level=one_level, refine=refine)
                dt = time.perf_counter() - t0
                shown = ", ".join(
                    f"{spec.name} {p[spec.name]:.4g}" for spec in get_family(fam).params
                )
                row.append(f"{shown}; {dt:.2f} s")
            print(f"| {fam} | grid point {k} {np.round(g, 3).tolist()} | {row[0]} | {row[1]} |")


if __name__ == "__main__":
    main()
