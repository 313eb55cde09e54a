"""The open library's refit on the driven step sets of its tests (session 28).

A term family and a state-space one, fitted without the loop to driven data with a force
step outside the catalogue (``[theta_dot>0]``, 0.05) and to the same data without it; the
step's term is refitted into each model and judged on held-out conditions
(:func:`hystdisc.closing.library_refit.refit_terms`). Prints the table of
``benchmarks/results/library_refit.md``.

Usage (from the repository's root)::

    python benchmarks/library_refit.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from hystdisc.closing.library_refit import refit_terms

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' data sets
from tests.closing.test_open_library import FAMILY, NOISE, _fit  # noqa: E402


def main() -> None:
    print("| family | data | coefficient (truth 0.05) | held out before -> after | verdict | s |")
    print("|---|---|---|---|---|---:|")
    for fam in (FAMILY, "tanh"):
        for kind in ("step", "clean"):
            d = _fit(kind, fam)
            t0 = time.perf_counter()
            r = refit_terms(d.fit_data_, d.family_fits_[fam], ["[theta_dot>0]"], floor=NOISE)
            c, se = r.coefficients["[theta_dot>0]"], r.stderr["[theta_dot>0]"]
            print(
                f"| {fam} | {kind} | {c:.5g} ± {se:.2g} | {r.heldout_before:.4g} -> "
                f"{r.heldout_after:.4g} ({r.lower} of {len(r.fold_after)}) | "
                f"{'accepted' if r.accepted else 'not accepted: ' + r.note} | "
                f"{time.perf_counter() - t0:.1f} |"
            )


if __name__ == "__main__":
    main()
