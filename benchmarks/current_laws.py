"""Current laws of the UTFSM MR damper by the seed's flowchart (issue 15 item 3).

1. ``bouc-wen-std`` (the family the full discovery selects) fitted jointly with linear
   laws on all 30 sine tests, then level by level (0 A first), each law chosen by leaving
   one level out, and refitted jointly with the chosen laws.
2. Leave one test condition out: for each of the six sine tests, the same on the other 25
   files (laws chosen again on them), then both joint fits (linear laws, chosen laws)
   predict the five left-out files. NRMSE = RMS force error / RMS force over those files
   (all samples after the first sweep of the motion: the fit's residual mask).

Run:  HYSTDISC_DATA=../shared/data PYTHONPATH=. python benchmarks/current_laws.py
      [--folds N] [--family bouc-wen-std]   (writes benchmarks/results/current_laws.md)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"


def nrmse(preds, fd) -> float:
    e2 = y2 = 0.0
    for r, p in enumerate(preds):
        m = fd.mask[r]
        e2 += float(np.sum((p - fd.y[r])[m] ** 2))
        y2 += float(np.sum(fd.y[r][m] ** 2))
    return float(np.sqrt(e2 / y2))


def main(argv=None) -> int:
    from hystdisc.data import load
    from hystdisc.estimator import Discovery
    from hystdisc.fitting import OutputErrorFitter
    from hystdisc.measurement import FitData
    from hystdisc.selection.staged import joint_fit, predict_runs, staged_fit

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("HYSTDISC_DATA", "../shared/data"))
    ap.add_argument("--family", default="bouc-wen-std")
    ap.add_argument("--folds", type=int, default=6)
    ap.add_argument(
        "--heldout",
        action="store_true",
        help="in each fold, judge the chosen laws by the held-out conditions of the 25 "
        "training files too (slower)",
    )
    ap.add_argument(
        "--compare-laws",
        action="store_true",
        help="also fit the full set jointly with each non-linear law forced (held-out RMS)",
    )
    ap.add_argument("--shape", default="shared", choices=("shared", "free"))
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "current_laws.md"))
    args = ap.parse_args(argv)
    folder = Path(args.data) / "utfsm_mr_damper"
    t0 = time.perf_counter()

    def say(msg):
        print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", file=sys.stderr, flush=True)

    ds = load([str(folder)], rig=str(RIG))
    d = Discovery(model=args.family, close_loop=False, heldout=True).fit(ds, progress=say)
    fd: FitData = d.fit_data_
    fit = d.family_fits_[args.family]
    st = staged_fit(fd, fit, progress=say, shape=args.shape)
    lines = [
        f"# Current laws of the UTFSM MR damper ({args.family}, 30 sine tests, 0-1 A)",
        "",
        "`HYSTDISC_DATA=../shared/data PYTHONPATH=. python benchmarks/current_laws.py "
        + " ".join(sys.argv[1:])
        + "`",
        "",
        "```",
        st.report(),
        "```",
        "",
    ]
    say("full set done:\n" + st.report())
    if args.compare_laws:
        lines += [
            "Joint fits of the full set with the laws forced (held-out RMS: leave one "
            "condition out inside the fit, as the family table):",
            "",
            "| laws (alpha, c) | RMS (N) | held-out RMS (N) |",
            "|---|---:|---:|",
            f"| linear, linear | {st.linear.rms:.2f} | {st.linear.heldout_rms:.2f} |",
        ]
        for forced in (
            ("saturating", "saturating"),
            ("quadratic", "quadratic"),
            ("saturating", "linear"),
        ):
            chosen = dict(zip(st.laws, forced, strict=True))
            j = joint_fit(fd, fit.par, fit.params, st.laws, chosen, 40, True)
            lines.append(f"| {', '.join(forced)} | {j.rms:.2f} | {j.heldout_rms:.2f} |")
            say(lines[-1])
        lines.append("")
    conds = list(dict.fromkeys(fd.conditions))
    rows = []
    for name in conds[: args.folds]:
        test = [r for r, c in enumerate(fd.conditions) if c == name]
        train = [r for r in range(fd.n_runs) if r not in test]
        say(f"leave out {name}")
        ftr, fte = fd.subset(train), fd.subset(test)
        lin = OutputErrorFitter(ftr, fit.par, max_nfev=40).fit(heldout=False)
        sf = staged_fit(ftr, lin, heldout=args.heldout, progress=say, shape=args.shape)
        row = {
            "test": name,
            "laws": ", ".join(f"{d_['parameter']} {d_['law']}" for d_ in sf.laws.values()),
            "linear": nrmse(predict_runs(lin, fte), fte),
            "laws_nrmse": nrmse(predict_runs(sf.joint, fte), fte),
        }
        rows.append(row)
        say(f"{row}")
    if rows:
        lines += [
            "Leave one test condition out (fit on the other 25 files, laws chosen again on "
            "them; NRMSE over the five left-out files):",
            "",
            "| left-out test | laws chosen | linear laws | chosen laws |",
            "|---|---|---:|---:|",
        ]
        for r in rows:
            lines.append(
                f"| {r['test']} | {r['laws']} | {r['linear']:.1%} | {r['laws_nrmse']:.1%} |"
            )
        ml = np.mean([r["linear"] for r in rows])
        mc = np.mean([r["laws_nrmse"] for r in rows])
        lines.append(f"| mean | | **{ml:.1%}** | **{mc:.1%}** |")
    lines += ["", f"{time.perf_counter() - t0:.0f} s wall."]
    text = "\n".join(lines) + "\n"
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
