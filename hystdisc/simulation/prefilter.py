"""A filter the recorded signals of a synthetic dataset pass through (``generate(prefilter=)``).

The same filter a rig's ``[filter]`` table declares (:func:`hystdisc.data.read_rig`): a
causal moving average with zero initial state, of ``window`` samples or of
``period_fraction`` of each run's motion period, on the named channels. A rig file that
declares the same table tells the fit what the data went through.

Examples
--------
>>> import numpy as np
>>> moving_average(np.arange(6.0), 3).tolist()
[0.0, 0.3333333333333333, 1.0, 2.0, 3.0, 4.0]
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hystdisc.data import Run, filter_windows
from hystdisc.data.rigs import normalize_rig
from hystdisc.errors import HystdiscError

__all__ = ["apply_prefilter", "check_prefilter", "moving_average"]


def check_prefilter(spec: Mapping[str, Any] | None, kind: Any) -> dict[str, Any] | None:
    """A ``prefilter`` checked as a rig's ``[filter]`` table (None without one); its
    channels default to every channel the experiment ``kind`` records."""
    if spec is None:
        return None
    if not isinstance(spec, Mapping):
        raise HystdiscError(
            f"prefilter {spec!r} is not a table; fix: give e.g. {{window = 10}} or "
            "{period_fraction = 0.1}"
        )
    recorded = ["theta"] + (
        [kind.output] if kind.motion_imposed else ["input"] if kind.has_input else []
    )
    filt = normalize_rig({"filter": {"channels": recorded, **spec}}, "prefilter")["filter"]
    extra = [c for c in filt["channels"] if c not in recorded]
    if extra:
        raise HystdiscError(
            f"prefilter: a {kind.name} experiment records no {extra[0]} channel; fix: filter "
            f"only {', '.join(recorded)}"
        )
    return filt


def moving_average(y: np.ndarray, window: int) -> np.ndarray:
    """Causal moving average of ``window`` samples, zero initial state."""
    c = np.cumsum(np.concatenate([np.zeros(window), np.asarray(y, dtype=float)]))
    return (c[window:] - c[:-window]) / window


def apply_prefilter(runs: list[Run], filt: Mapping[str, Any] | None, source: str) -> None:
    """Pass the channels of a checked ``filt`` of every run through its moving average, in
    place (a filtered ``theta`` filters the run's ``theta_dot`` too); nothing for None."""
    if filt is None:
        return
    windows = filter_windows(filt, runs, source)
    names = list(filt["channels"]) + (["theta_dot"] if "theta" in filt["channels"] else [])
    for r, w in zip(runs, windows, strict=True):
        for name in names:
            sig = getattr(r, name)
            if sig is not None:
                sig[:] = moving_average(sig, w)
