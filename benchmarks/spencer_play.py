"""A Spencer damper behind a play (issue 35): does the loop find the play on a state-space
family?

``python benchmarks/spencer_play.py R_B FS DURATION SEED`` simulates Spencer et al.'s
(1997) damper in SI units behind a play of half-width ``R_B`` (m), driven at
0.01 m @ 1 Hz and 0.005 m @ 3 Hz at 0 and 1 A (15 N force noise, 1e-5 m motion noise),
runs ``Discovery(model="spencer")`` and prints the accepted effects and the loop's part of
the report. Results: ``benchmarks/results/backlash.md``.
"""

from __future__ import annotations

import argparse
import time
import warnings

from hystdisc.estimator import Discovery
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

#: Spencer et al.'s damper in SI units, ``z`` saturating at 1.
SPENCER = dict(alpha_a=90, alpha_b=448, c0_a=2100, c0_b=350, c1_a=28300, c1_b=295, k0=4690,
               k1=500, A=46700, beta=23350, n=2)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("r_b", type=float, help="the play's half-width (m)")
    ap.add_argument("fs", type=float, help="sampling rate (Hz)")
    ap.add_argument("duration", type=float, help="length of each run (s)")
    ap.add_argument("seed", type=int, help="noise seed")
    a = ap.parse_args()
    model = Model("spencer", SPENCER, effects={"backlash": {"r_b": a.r_b}})
    data = generate(model, "driven", currents=(0.0, 1.0), duration=a.duration, fs=a.fs,
                    noise=15.0, seed=a.seed, drives=["0.01@1.0", "0.005@3.0"],
                    theta_noise=1e-5)  # fmt: skip
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disc = Discovery(model="spencer").fit(data)
    res = disc.results_
    print(f"wall {time.perf_counter() - t0:.1f} s; accepted: {disc.effects_}")
    for e in res.effects:
        par = e["parameters"].get("r_b")
        print(e["name"], e["rms_after"], e["heldout_rms_after"], "" if par is None else par)
    report = res.report()
    print(report[report.index("Closing the loop") :])


if __name__ == "__main__":
    main()
