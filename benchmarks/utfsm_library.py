"""The open library on the UTFSM damper's residual (issue 35 item 2).

For each family given, ``Discovery(model=F, close_loop=False)`` on the 30 sine tests read
with the rig file, then :func:`hystdisc.closing.open_library.regress_output_residual` on
its force residual; prints the stable terms (results in
``benchmarks/results/utfsm_floor_and_library.md``).

Run:  HYSTDISC_DATA=../shared/data python benchmarks/utfsm_library.py [FAMILY ...]
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

from hystdisc import Discovery
from hystdisc.closing.open_library import regress_output_residual
from hystdisc.data import load

ROOT = Path(__file__).resolve().parents[1]
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"


def main(families: list[str]) -> None:
    data = os.environ.get("HYSTDISC_DATA")
    if not data:
        raise SystemExit("set HYSTDISC_DATA to the folder that holds utfsm_mr_damper/")
    ds = load(Path(data) / "utfsm_mr_damper", rig=RIG)
    for fam in families:
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = Discovery(model=fam, close_loop=False).fit(ds)
        fit = d.family_fits_[fam]
        print(
            f"{fam}: RMS {fit.rms:.4g}, floor {d.noise_std_:.4g} ({time.perf_counter() - t0:.0f} s)"
        )
        print(regress_output_residual(d.fit_data_, fit).summary(), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["bouc-wen-std", "spencer"])
