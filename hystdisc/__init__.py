"""hystdisc: discover the hysteresis model of an MR damper from measured data.

The main entry points:

- :class:`hystdisc.Discovery` — the two-stage estimator (scikit-learn contract);
- :func:`hystdisc.load` — read runs (CSV, .mat, header-less tables with a rig file);
- :class:`hystdisc.Model` and :func:`hystdisc.generate` — families, effects and the rig
  simulator for synthetic data;
- :class:`hystdisc.Results` — the ``results.json`` contract.
"""

from __future__ import annotations

__version__ = "0.1.0"

from hystdisc.errors import HystdiscError, HystdiscWarning  # noqa: E402
from hystdisc.models import Model, TermModel  # noqa: E402


def __getattr__(name: str):
    # heavier modules (pysindy, the estimator) load on first use
    if name == "Discovery":
        from hystdisc.estimator import Discovery

        return Discovery
    if name == "Results":
        from hystdisc.results.core import Results

        return Results
    if name == "load":
        from hystdisc.data.io import load

        return load
    if name == "generate":
        from hystdisc.simulation.synth import generate

        return generate
    raise AttributeError(f"module 'hystdisc' has no attribute {name!r}")


__all__ = [
    "Discovery",
    "HystdiscError",
    "HystdiscWarning",
    "Model",
    "Results",
    "TermModel",
    "__version__",
    "generate",
    "load",
]
