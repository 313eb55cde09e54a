"""How the stages make a family's fit: its parametrization, its first fit, a state-space
family's fit from its base.

These are the few operations several stages share (the first fits, the helper families
fitted as starts, the more starts, the start of the state-space families).
"""

from __future__ import annotations

from hystdisc.discovery import family_start
from hystdisc.fitting import FamilyParametrization, OEFit, OutputErrorFitter
from hystdisc.fitting.multistart import system_fit
from hystdisc.models import FAMILIES
from hystdisc.pipeline.state import State


def current_fixed(state: State, name: str) -> dict[str, float]:
    """The parameters of family ``name`` held at 0: its current-dependent ones when every
    run has one current."""
    return {p: 0.0 for p in FAMILIES[name].current_params} if state.single_current else {}


def family_par(state: State, name: str, start: dict[str, float]) -> FamilyParametrization:
    """Family ``name`` started at ``start``: its z scale chosen there, the current terms
    held at 0 at a single current, the measurement chain's effects every family carries."""
    start, norm = FAMILIES[name].z_scale({**start, **state.chain})
    return FamilyParametrization(
        name, state.experiment, start, tuple(state.chain_effects), current_fixed(state, name),
        norm,
    )  # fmt: skip


def first_fit(state: State, name: str, s0=None) -> OEFit | None:
    """Family ``name`` fitted from its stage-1 start: the search of its shape from the
    shape's stage-1 constants ``s0`` (default: those stage 1 found; no second grid
    search); None when it fails (recorded)."""
    s0 = state.shape0(name) if s0 is None else s0

    def fit() -> OEFit:
        start, _ = family_start(state.eq, name, s0=s0, one_level=state.single_current)
        par = family_par(state, name, start)
        return OutputErrorFitter(state.fd, par, max_nfev=state.options.max_nfev).fit(heldout=False)

    return state.failures.guard(name, fit)


def system_family_fit(state: State, name: str, base: OEFit) -> OEFit:
    """State-space family ``name`` from its starts mapped from ``base``
    (:func:`~hystdisc.fitting.multistart.system_fit`), with its held-out error when asked."""
    opts = state.options
    fit = system_fit(
        name, base, state.fd, opts.max_nfev, current_fixed(state, name), mapper=state.map,
        say=state.say, failures=state.failures,
    )  # fmt: skip
    if opts.heldout:
        fit = OutputErrorFitter(state.fd, fit.par, max_nfev=opts.max_nfev).heldout_at(fit)
    return fit
