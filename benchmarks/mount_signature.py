"""A first-order signature of a compliant mount on a driven Spencer fit (session 32,
``benchmarks/results/mount_spencer.md``).

A mount of compliance ``kappa = 1/k_w`` moves the damper's motion by ``-kappa F``; to first
order the measured force is the model's at the measured motion minus ``kappa g``, where
``g`` is the model's response to the motion change ``F`` (two simulations). The residual
regressed on ``g`` estimates ``kappa`` and the share of the residual's excess over the
noise a mount would explain, before any refit.

Run:  python benchmarks/mount_signature.py mount.csv
      (mount.csv: the device of mount_spencer.md, written by its ``hystdisc simulate``)
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from hystdisc import Discovery
from hystdisc.data import load
from hystdisc.fitting.output_error import OEFit, OutputErrorFitter
from hystdisc.measurement.fitdata import FitData

#: The motion change of the difference, as a share of the motion's spread.
STEP = 1e-4


def signature(fit: OEFit, data: FitData, floor: float) -> dict[str, float]:
    """``kappa``, the implied ``k_w`` and the shares of the RSS and of its excess over
    ``floor`` that ``kappa g`` explains."""
    forces = list(fit.predictions)
    eps = STEP * np.std(np.concatenate(data.theta)) / np.std(np.concatenate(forces))
    moved = dataclasses.replace(
        data,
        theta=[x - eps * f for x, f in zip(data.theta, forces, strict=True)],
        theta_dot=[
            w - eps * np.gradient(f, t)
            for w, f, t in zip(data.theta_dot, forces, data.t, strict=True)
        ],
    )
    v = np.concatenate([fit.x, np.ravel(fit.nuisance)])
    r = OutputErrorFitter(data, fit.par).residuals(v)  # simulated minus measured
    g = (r - OutputErrorFitter(moved, fit.par).residuals(v)) / eps
    kappa = float(r @ g / (g @ g))
    gain, rss = kappa**2 * float(g @ g), float(r @ r)
    excess = rss - r.size * floor**2
    return {
        "kappa": kappa,
        "k_w": 1.0 / kappa if kappa > 0 else np.inf,
        "rss_share": gain / rss,
        "excess_share": gain / excess if excess > 0 else np.nan,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("csv", help="a driven data file")
    args = ap.parse_args()
    d = Discovery(model="spencer", close_loop=False, heldout=False).fit(load(args.csv))
    fit, data = d.family_fits_["spencer"], d.fit_data_
    print(f"spencer: RMS {fit.rms:.4g} (noise {data.noise_std:.4g})")
    for k, val in signature(fit, data, data.noise_std).items():
        print(f"{k}: {val:.4g}")


if __name__ == "__main__":
    main()
