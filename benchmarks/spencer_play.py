"""A Spencer damper behind a play (issue 35): does the loop find the play on a state-space
family? ``python benchmarks/spencer_play.py R_B FS DURATION SEED`` simulates Spencer et
al.'s (1997) damper in SI units behind a play of half-width ``R_B`` (m), driven at
0.01 m @ 1 Hz and 0.005 m @ 3 Hz at 0 and 1 A (15 N force noise, 1e-5 m motion noise),
runs ``Discovery(model="spencer")`` and prints the accepted effects with the loop's
report. Results: ``benchmarks/results/backlash.md``.
"""

import sys, time, warnings
import numpy as np
from hystdisc.models import Model
from hystdisc.simulation.synth import generate
from hystdisc.estimator import Discovery
SP = dict(alpha_a=90, alpha_b=448, c0_a=2100, c0_b=350, c1_a=28300, c1_b=295, k0=4690, k1=500,
          A=46700, beta=23350, n=2)
r_b = float(sys.argv[1]); fs=float(sys.argv[2]); dur=float(sys.argv[3])
data = generate(Model("spencer", SP, effects={"backlash": {"r_b": r_b}}), "driven", currents=(0.0, 1.0),
                duration=dur, fs=fs, noise=15.0, seed=int(sys.argv[4]), drives=["0.01@1.0", "0.005@3.0"], theta_noise=1e-5)
t=time.time()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    d = Discovery(model="spencer").fit(data)
res = d.results_
print("wall", time.time()-t, d.effects_)
for e in res.effects: print(e["name"], e["rms_before"], e["rms_after"], e["heldout_rms_before"], e["heldout_rms_after"], e["parameters"]["r_b"] if "r_b" in e["parameters"] else "")
print(res.final.admissible, res.unexplained)
print(res.report()[res.report().index("Families"):][:6000])
