"""Leave-one-condition-out NRMSE of bouc-wen-std on the UTFSM set, with and without the
rig's declared [filter] (issue 15 item 4). Usage: python utfsm_lococv.py [filter|none]"""

import os
import re
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from hystdisc.data import load
from hystdisc.discovery import FAMILY_SHAPE
from hystdisc.estimator import Discovery
from hystdisc.fitting import OutputErrorFitter
from hystdisc.measurement.prepare import prepare_data

ROOT = Path(__file__).resolve().parents[1]
rig = ROOT / "data_synth/rigs/utfsm_mr_damper.toml"
folder = Path(os.environ.get("HYSTDISC_DATA", "../shared/data")) / "utfsm_mr_damper"
mode = sys.argv[1]
tests = sys.argv[2].split(",") if len(sys.argv) > 2 else None
ds = load([folder], rig=rig)
filt = ds.filter
TEST_RE = re.compile(r"^(\d+(?:x\d+)?mm\d+(?:x\d+)?Hz)")
groups = defaultdict(list)
for k, r in enumerate(ds.runs):
    groups[TEST_RE.match(r.name).group(1)].append(k)
if tests:
    keep = [k for g in tests for k in groups[g]]
    groups = {g: [keep.index(k) for k in groups[g]] for g in tests}
    ds = ds.subset(keep)
ds.filter = filt if mode == "filter" else None
withf = ds.subset(range(len(ds)))
withf.filter = filt  # the common evaluation mask
out = {}
sq_all = ms_all = 0.0
t0 = time.time()
for g, idx in groups.items():
    train = [k for k in range(len(ds)) if k not in idx]
    d = Discovery(
        model="bouc-wen-std",
        heldout=False,
        close_loop=False,
        shapes=(FAMILY_SHAPE["bouc-wen-std"],),
    ).fit(ds.subset(train))
    fit = d.final_fit_
    fd = prepare_data(ds.subset(idx))[1]
    fdm = prepare_data(withf.subset(idx))[1]
    f = OutputErrorFitter(fd, fit.par)
    v = np.concatenate([fit.x, fd.nuisance_start(f.state)])
    x, nu = f._split(v)
    preds = fit.par.simulate(fd, [fit.par.model(x)] * fd.n_runs, list(range(fd.n_runs)), list(nu))
    sq = ms = 0.0
    for k in range(fd.n_runs):
        m = fdm.mask[k]
        e = (preds[k] - fd.y[k])[m]
        sq += e @ e
        ms += fd.y[k][m] @ fd.y[k][m]
    out[g] = np.sqrt(sq / ms)
    sq_all += sq
    ms_all += ms
    print(
        f"{g}: NRMSE {out[g]:.4f} (train rms {fit.rms:.1f} N)  [{time.time() - t0:.0f} s]",
        flush=True,
    )
print(
    f"{mode}: mean NRMSE over conditions {np.mean(list(out.values())):.4f}; pooled {np.sqrt(sq_all / ms_all):.4f}"
)
