"""The shear-thinning effect on the UTFSM MR damper (issue 15 item 2a).

The closing loop on ``--model bouc-wen-std`` (what it accepts, the exponent ``m`` and its
interval) on the full set, then leave one test condition out: discover on the other five
sine tests, predict the left-out one with the final model (pooled NRMSE over its five
currents). Run it once with this tree and once with a tree without the effect (e.g. the
main branch before it) to compare:

    HYSTDISC_DATA=../shared/data PYTHONPATH=. python benchmarks/mr_thinning.py \
        [--folds N | --tests 10mm1Hz,5mm3Hz] [--no-full]

NRMSE = RMS force error / RMS of the measured force over the same runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mr_damper import RIG, tests_of  # noqa: E402


def _fit(files):
    from hystdisc.data import load
    from hystdisc.estimator import Discovery

    t0 = time.perf_counter()
    disc = Discovery(model="bouc-wen-std", heldout=False).fit(load(files, rig=str(RIG)))
    return disc, time.perf_counter() - t0


def _loop_summary(disc) -> list[str]:
    res = disc.results_
    out = [f"family fit RMS {disc.family_fits_['bouc-wen-std'].rms:.1f} N"]
    for e in res.effects_tried or []:
        out.append(
            f"tried {e['name']}: accepted={e['accepted']} rms {e.get('rms_before')} -> "
            f"{e.get('rms_after')}; {e.get('note') or ''}"
        )
    for e in res.effects:
        ps = ", ".join(
            f"{k} = {v['value']:.4g} [{v['ci95'][0]:.4g}, {v['ci95'][1]:.4g}]"
            for k, v in e["parameters"].items()
        )
        out.append(f"accepted {e['name']}: {ps}; rms {e['rms_before']:.1f} -> {e['rms_after']:.1f}")
    out.append(f"final RMS {disc.final_fit_.rms:.1f} N")
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, default=6, help="how many left-out tests (of 6)")
    ap.add_argument("--tests", help="comma-separated left-out tests (default: the first N)")
    ap.add_argument("--no-full", action="store_true", help="skip the fit on all 30 files")
    args = ap.parse_args()
    from hystdisc.data import load

    folder = Path(os.environ.get("HYSTDISC_DATA", "../shared/data")) / "utfsm_mr_damper"
    groups = tests_of(folder)
    if not args.no_full:
        disc, wall = _fit([str(f) for fs in groups.values() for f in fs])
        print(f"full set ({wall:.0f} s):", *_loop_summary(disc), sep="\n  ", flush=True)
    rows = []
    names = args.tests.split(",") if args.tests else list(groups)[: args.folds]
    for name in names:
        train = [str(f) for k, fs in groups.items() if k != name for f in fs]
        disc, wall = _fit(train)
        ds = load([str(f) for f in groups[name]], rig=str(RIG))
        y = np.concatenate([r.torque for r in ds.runs])
        e = np.concatenate(disc.predict(ds)) - y
        nrmse = float(np.sqrt(np.mean(e**2) / np.mean(y**2)))
        rows.append(nrmse)
        extra = ""
        if "shear_thinning" in disc.effects_:
            p = disc.final_fit_.params
            extra = f" c_st = {p['c_st']:.4g}, m_st = {p['m_st']:.3f}"
        print(
            f"without {name}: effects {disc.effects_}, held-out NRMSE {nrmse:.4f}, "
            f"in-sample RMS {disc.final_fit_.rms:.1f} N ({wall:.0f} s){extra}",
            flush=True,
        )
    print(f"mean held-out NRMSE over {len(rows)} folds: {np.mean(rows):.4f}")


if __name__ == "__main__":
    main()
