"""hystdisc: discover the hysteresis model of an MR damper from measured data.

The main entry points:

- :class:`hystdisc.Discovery` — the two-stage estimator (scikit-learn contract);
- :func:`hystdisc.load` — read runs (CSV, .mat, header-less tables with a rig file);
- :class:`hystdisc.Model` and :func:`hystdisc.generate` — families, effects and the rig
  simulator for synthetic data;
- :class:`hystdisc.Results` — the ``results.json`` contract.

Importing the package is cheap: only :mod:`hystdisc.errors` is loaded; every other public
name imports its module (numpy, numba, pysindy, ...) on first use, so ``hystdisc --help``
stays fast.

Examples
--------
>>> import hystdisc
>>> hystdisc.TermModel.__name__
'TermModel'
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

from hystdisc.errors import HystdiscError, HystdiscWarning  # noqa: E402

#: Public name -> ``module:attribute``; imported on first access (module ``__getattr__``).
_LAZY: dict[str, str] = {
    "Discovery": "hystdisc.estimator:Discovery",
    "Model": "hystdisc.models:Model",
    "Results": "hystdisc.results:Results",
    "TermModel": "hystdisc.models:TermModel",
    "generate": "hystdisc.simulation.synth:generate",
    "load": "hystdisc.data:load",
}


def __getattr__(name: str) -> Any:
    path = _LAZY.get(name)
    if path is None:
        raise AttributeError(f"module 'hystdisc' has no attribute {name!r}")
    module, _, attr = path.partition(":")
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


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
